"""Exact symmetries of V̂ and their use at inference (group averaging).

The decentralized epigraph problem of SPEC §4 is invariant under

- the dihedral group D4 of the square acting on the plane (signed permutations of the axes):
  every cost and constraint is a Euclidean distance, and the control box ``[−u_max, u_max]²`` is
  mapped onto itself, so for every ``M ∈ D4`` applied to all 2-vectors of the observation at
  once, ``V̂(M·o, z, t) = V̂(o, z, t)``;
- permutations of the neighbour slots (``l_d``, ``φ_d`` and ``g_d`` are symmetric in them).

A trained network only approximates these invariances. Averaging it over a group ``G``,
``V̄(o) = mean_{g∈G} V̂(g·o)``, is the orthogonal projection onto G-invariant functions: it is
exactly invariant and its mean-square error on any G-invariant distribution is never larger than
the network's (Jensen). It also makes mirror-image encounters get mirror-image controls: two
agents in a head-on encounter see observations related by the 180° rotation ``o → −o``, so with
``point`` (or ``d4``) symmetry their swerves are exactly opposite instead of both following the
same sign of a tiny, noisy ``∂V̂/∂v_y``. The gradient is ``∇V̄(o) = mean_g gᵀ ∇V̂(g·o)``.

Groups: ``none`` (1 element), ``point`` ({I, −I}, 2), ``d4`` (8), ``full`` (D4 × neighbour
permutations, 8·n!). Cost: |G| network evaluations per query. The group is planar by design: for
agents with more position axes (the 3-D model) it acts on the horizontal plane and leaves the
further axes alone (still an exact symmetry: the plane's distances and box are unchanged).
"""

from __future__ import annotations

import itertools

import torch

from madpinn.observation import ObservationLayout

GROUPS = ("none", "point", "d4", "full")


def _planar_group(name: str) -> list[torch.Tensor]:
    eye = torch.eye(2, dtype=torch.float64)
    if name == "none":
        return [eye]
    if name == "point":
        return [eye, -eye]
    swap = torch.tensor([[0.0, 1.0], [1.0, 0.0]], dtype=torch.float64)
    out = []
    for p in (eye, swap):
        for sx, sy in itertools.product((1.0, -1.0), repeat=2):
            out.append(torch.diag(torch.tensor([sx, sy], dtype=torch.float64)) @ p)
    return out


def observation_transforms(name: str, n_neighbours: int, layout: ObservationLayout) -> torch.Tensor:
    """Group elements as matrices ``[G, D, D]`` acting on observations of ``layout`` (``o' = g·o``),
    float64; on d > 2 position axes the planar element acts on the first two, the rest fixed."""
    if name not in GROUPS:
        raise ValueError(f"symmetry group must be one of {GROUPS}, got '{name}'")
    lay = layout
    n_vec = lay.dim(n_neighbours) // lay.d
    perms = list(itertools.permutations(range(n_neighbours))) if name == "full" else [tuple(range(n_neighbours))]
    mats = []
    for m in _planar_group(name):
        k = m.shape[0]
        axes = torch.block_diag(m, torch.eye(lay.d - k, dtype=torch.float64)) if lay.d > k else m
        planar = torch.kron(torch.eye(n_vec, dtype=torch.float64), axes)
        for perm in perms:
            blocks = [torch.arange(lay.ego_dim)] + [lay.ego_dim + lay.neighbour_dim * j + torch.arange(lay.neighbour_dim) for j in perm]
            p = torch.eye(planar.shape[0], dtype=torch.float64)[torch.cat(blocks)]   # row i of p·o = o[src(i)]
            mats.append(p @ planar)
    return torch.stack(mats)


class SymmetrizedVHat:
    """A :class:`~madpinn.value_functions.model.VHat` averaged over a symmetry group; same
    ``value`` / ``value_and_grad`` interface, every other attribute delegated to the base model."""

    def __init__(self, base, group: str):
        self.base = base
        self.group = group
        p = next(base.net.parameters())
        self._g = observation_transforms(group, base.obs_spec.n_neighbours, base.obs_spec.layout).to(device=p.device, dtype=p.dtype)

    def __getattr__(self, name):
        return getattr(self.base, name)

    def _expand(self, obs, z, t):
        g = self._g.to(obs.dtype)
        G, B = g.shape[0], obs.shape[0]
        og = torch.einsum("gde,be->gbd", g, obs).reshape(G * B, -1)
        tt = t.repeat(G) if torch.is_tensor(t) and t.dim() > 0 else t
        return og, z.repeat(G), tt, G, B

    def value(self, obs: torch.Tensor, z: torch.Tensor, t=0.0) -> torch.Tensor:
        """Group mean of V̂ ``[B]``; obs ``[B, D]``, z ``[B]``."""
        og, zg, tg, G, B = self._expand(obs, z, t)
        return self.base.value(og, zg, tg).reshape(G, B).mean(0)

    def value_and_grad(self, obs: torch.Tensor, z: torch.Tensor, t=0.0):
        """``(V̄ [B], ∂V̄/∂obs [B, D], ∂V̄/∂z [B])`` with ``∇V̄ = mean_g gᵀ ∇V̂(g·o)``."""
        og, zg, tg, G, B = self._expand(obs, z, t)
        v, go, gz = self.base.value_and_grad(og, zg, tg)
        grad = torch.einsum("gde,gbd->be", self._g.to(go.dtype), go.reshape(G, B, -1)) / G
        return v.reshape(G, B).mean(0), grad, gz.reshape(G, B).mean(0)


def symmetrize(vhat, group: str):
    """``vhat`` itself for ``none``, else the group-averaged wrapper."""
    if group not in GROUPS:
        raise ValueError(f"symmetry group must be one of {GROUPS}, got '{group}'")
    return vhat if group == "none" else SymmetrizedVHat(vhat, group)
