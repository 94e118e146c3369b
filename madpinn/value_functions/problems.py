"""The two PINN problems (V̂ and V_s): input normalisation, exact terminal-condition
parameterisation and HJB residual, on top of the systems in :mod:`madpinn.dynamics`.

A problem works on a flat state ``s [B, S]`` and time ``t [B]`` (s). The value is

    V(s, t) = B(s) + (T − t) · σ · N(x̃),    x̃ = normalise(s, t) ∈ [−1, 1]^(S+1),

with ``B`` the exact terminal value (V̂: ``max(φ_d − z, g_d)``; V_s: ``ψ``), ``N`` the SIREN and
``σ`` a fixed output scale, so ``V(s, T) = B(s)`` for any network. :func:`assemble` turns
``(N, ∇_x̃ N)`` into ``(V, ∂_t V, ∇_s V)``; it is used both for inference and inside the training
loss (where autograd differentiates only this cheap per-sample head).
"""

from __future__ import annotations

from dataclasses import asdict

import torch

from madpinn.dynamics import PAPER_MODEL
from madpinn.value_functions.epigraph import EpigraphSystem
from madpinn.dynamics.pair import PairSystem
from madpinn.observation import TRAINING_MAPPING, ObservationSettings
from madpinn.value_functions.sampling import (
    ConflictSamplingSettings, NearSamplingSettings, place_conflicts, place_near, place_pair_conflicts,
)


class PINNProblem:
    """Common part: normalisation with per-coordinate centre/half-width, time to [−1, 1]."""

    kind: str
    horizon: float

    def __init__(self, centre: torch.Tensor, half: torch.Tensor):
        self._centre = centre.to(torch.float64)
        self._half = half.to(torch.float64)

    @property
    def state_dim(self) -> int:
        return self._centre.numel()

    @property
    def in_features(self) -> int:
        return self.state_dim + 1

    def _constants(self, like: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor, torch.Tensor]:
        """``(centre [S], half-width [S], input scale [S + 1])`` in ``like``'s dtype and device
        (converted once per dtype and device, read-only)."""
        kept = self.__dict__.setdefault("_constants_kept", {})
        key = (like.dtype, like.device)
        if key not in kept:
            scale = torch.cat([1.0 / self._half, torch.tensor([2.0 / self.horizon], dtype=torch.float64)])
            kept[key] = tuple(v.to(dtype=like.dtype, device=like.device) for v in (self._centre, self._half, scale))
        return kept[key]

    def input_scale(self, like: torch.Tensor) -> torch.Tensor:
        """``dx̃/d(s, t)`` ``[S + 1]`` (diagonal)."""
        return self._constants(like)[2]

    def normalise(self, s: torch.Tensor, t: torch.Tensor) -> torch.Tensor:
        c, h, _ = self._constants(s)
        return torch.cat([(s - c) / h, (2.0 * t / self.horizon - 1.0)[:, None]], dim=-1)

    def coordinate_normaliser(self, i: int, like: torch.Tensor):
        """``values [B] ↦`` column ``i`` of :meth:`normalise` for values of state coordinate ``i``
        (``like``'s dtype and device): the same float operations, so bitwise the same numbers."""
        c, h, _ = self._constants(like)
        c, h = c[i : i + 1], h[i : i + 1]
        return lambda values: ((values[:, None] - c) / h)[:, 0]

    def sample_times(self, batch: int, alpha: float, generator: torch.Generator, dtype) -> torch.Tensor:
        """Curriculum times uniform on ``[T − α·T, T]`` ``[B]``."""
        return self.horizon - alpha * self.horizon * torch.rand(batch, generator=generator, dtype=dtype)

    def sample_states(self, batch: int, generator: torch.Generator, dtype) -> torch.Tensor:
        """Uniform states ``[B, S]`` over the domain (held-out statistics, validation)."""
        raise NotImplementedError

    def sample_training_states(self, batch: int, generator: torch.Generator, dtype) -> torch.Tensor:
        """States ``[B, S]`` of the training distribution (uniform unless a problem refines it)."""
        return self.sample_states(batch, generator, dtype)

    def boundary_and_grad(self, s: torch.Tensor):
        raise NotImplementedError

    def residual(self, s, t, value, dv_dt, dv_ds) -> torch.Tensor:
        raise NotImplementedError

    def obstacle_violation(self, s, value) -> torch.Tensor:
        """``[B]`` ≥ 0: how far ``value`` breaks the VI's obstacle inequality (0 where it holds)."""
        raise NotImplementedError

    def describe(self) -> dict:
        raise NotImplementedError


class EpigraphProblem(PINNProblem):
    """V̂ on ``s = [o (D), z]``; ``t ∈ [0, T]``."""

    kind = "vhat"

    def __init__(self, system: EpigraphSystem, conflict: ConflictSamplingSettings | None = None):
        self.system = system
        self.conflict = conflict   # None: no share of the batch on conflicts
        self.horizon = system.horizon
        hw = system.half_widths()
        centre = torch.cat([torch.zeros_like(hw), torch.tensor([system.z_max / 2.0], dtype=torch.float64)])
        half = torch.cat([hw, torch.tensor([system.z_max / 2.0], dtype=torch.float64)])
        super().__init__(centre, half)

    def sample_states(self, batch, generator, dtype):
        obs, z = self.system.sample(batch, generator, dtype)
        return torch.cat([obs, z[:, None]], dim=-1)

    def sample_training_states(self, batch, generator, dtype):
        """Uniform states with ``conflict.fraction`` of them on near-collision courses
        (:mod:`madpinn.value_functions.sampling`)."""
        s = self.sample_states(batch, generator, dtype)
        sy = self.system
        obs = s[:, :-1]
        if self.conflict is not None:
            obs = place_conflicts(obs, sy.spec.n_neighbours, sy.horizon, sy.spec.offset_range, self.conflict, generator,
                                  v_max=sy.v_max)
        return torch.cat([obs, s[:, -1:]], dim=-1)

    def boundary_and_grad(self, s):
        val, go, gz = self.system.terminal_value_and_grad(s[:, :-1], s[:, -1])
        return val, torch.cat([go, gz[:, None]], dim=-1)

    def residual(self, s, t, value, dv_dt, dv_ds):
        return self.system.hjb_residual(s[:, :-1], s[:, -1], value, dv_dt, dv_ds[:, :-1], dv_ds[:, -1])

    def obstacle_violation(self, s, value):
        """``relu(g_d − V̂)``: the exact V̂ never falls below the constraint ``g_d``."""
        return torch.relu(self.system.constraint(s[:, :-1]) - value)

    def describe(self) -> dict:
        sy = self.system
        d = {"spec": _without_paper_model(asdict(sy.spec)), "u_max": sy.u_max, "v_max": sy.v_max, "horizon": sy.horizon, "z_max": sy.z_max}
        if sy.velocity_saturation:   # absent = the unbounded dynamics of every earlier checkpoint
            d["velocity_saturation"] = True
        return d

    @classmethod
    def from_description(cls, d: dict) -> "EpigraphProblem":
        return cls(EpigraphSystem(spec=ObservationSettings(**{**TRAINING_MAPPING, "model": PAPER_MODEL, **d["spec"]}), u_max=d["u_max"], v_max=d["v_max"],
                                  horizon=d["horizon"], z_max=d["z_max"], velocity_saturation=bool(d.get("velocity_saturation", False))))


class PairProblem(PINNProblem):
    """V_s on the relative pair state ``s = x [4]``; ``t ∈ [0, T]``."""

    kind = "vs"

    def __init__(self, system: PairSystem, conflict: ConflictSamplingSettings | None = None, near: NearSamplingSettings | None = None):
        self.system = system
        self.conflict = conflict   # None: none of the batch on conflicts / from the inner box
        self.near = near
        self.horizon = system.horizon
        hw = system.half_widths()
        super().__init__(torch.zeros_like(hw), hw)

    def sample_states(self, batch, generator, dtype):
        return self.system.sample(batch, generator, dtype)

    def sample_training_states(self, batch, generator, dtype):
        """Uniform states with ``conflict.fraction`` of them on near-collision courses
        (:func:`madpinn.value_functions.sampling.place_pair_conflicts`) and ``near.fraction`` of them
        from the inner box (:func:`madpinn.value_functions.sampling.place_near`)."""
        sy = self.system
        s = self.sample_states(batch, generator, dtype)
        if self.conflict is not None:
            s = place_pair_conflicts(s, sy.horizon, sy.p_range, self.conflict, generator, sy.agent, v_range=sy.v_range)
        return s if self.near is None else place_near(s, sy.p_range, sy.v_range, self.near, generator, sy.agent)

    def boundary_and_grad(self, s):
        return self.system.target_and_grad(s)

    def residual(self, s, t, value, dv_dt, dv_ds):
        return self.system.hjb_residual(s, value, dv_dt, dv_ds)

    def obstacle_violation(self, s, value):
        """``relu(V_s − ψ)``: the exact V_s never exceeds the current separation margin ψ."""
        return torch.relu(value - self.system.target(s))

    def describe(self) -> dict:
        return _without_paper_model(asdict(self.system))

    @classmethod
    def from_description(cls, d: dict) -> "PairProblem":
        return cls(PairSystem(**{"model": PAPER_MODEL, **d}))


def _without_paper_model(d: dict) -> dict:
    """A description without its ``model`` when that is the paper's planar model: descriptions
    written before agent models had names (every checkpoint so far) stay equal; absent reads as
    :data:`~madpinn.dynamics.PAPER_MODEL`."""
    return {k: v for k, v in d.items() if not (k == "model" and v == PAPER_MODEL)}


PROBLEMS = {"vhat": EpigraphProblem, "vs": PairProblem}


def as_time(t, batch: int, like: torch.Tensor) -> torch.Tensor:
    """Float or ``[B]`` time -> ``[B]`` tensor."""
    t = torch.as_tensor(t, dtype=like.dtype, device=like.device)
    return t.expand(batch) if t.dim() == 0 else t


def assemble(problem: PINNProblem, s, t, n, grad_n, boundary, grad_boundary, output_scale: float):
    """``(V [B], ∂_t V [B], ∇_s V [B, S])`` from the network value ``n [B]`` and its input
    gradient ``grad_n [B, S+1]`` (w.r.t. normalised inputs)."""
    scale = problem.input_scale(grad_n)
    tau = (problem.horizon - t) * output_scale
    value = boundary + tau * n
    dv_ds = grad_boundary + tau[:, None] * grad_n[:, :-1] * scale[:-1]
    dv_dt = -output_scale * n + tau * grad_n[:, -1] * scale[-1]
    return value, dv_dt, dv_ds
