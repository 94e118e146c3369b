"""Trained value functions (public API) and their checkpoint files.

    vhat = load_vhat(path)            # V̂(t, o, z): vhat.value(obs, z, t), vhat.value_and_grad(obs, z, t)
    vs = load_vs(path)                # V_s(x, t): vs.value(x_rel, t), vs.value_and_grad(x_rel, t)

Checkpoints are plain dicts of tensors and primitives, written atomically and read with
``torch.load(..., weights_only=True)``. A missing, truncated or mismatched file raises
:class:`CheckpointError` naming the file and the problem.
"""

from __future__ import annotations

from pathlib import Path

import torch

from madpinn.atomic import save_torch
from madpinn.hints import build_hint, unreadable_reason
from madpinn.value_functions.problems import PROBLEMS, PINNProblem, as_time, assemble
from madpinn.value_functions.siren import Siren

FORMAT = "madpinn-value-function"
VERSION = 1


class CheckpointError(RuntimeError):
    """A value-function checkpoint is missing, unreadable or of the wrong kind."""


class PINNValueFunction:
    """``V(s, t) = B(s) + (T − t)·σ·N(x̃)`` for one problem; inference without autograd."""

    def __init__(self, problem: PINNProblem, net: Siren, output_scale: float, meta: dict | None = None):
        self.problem = problem
        self.net = net
        self.output_scale = float(output_scale)
        self.meta = dict(meta or {})

    @property
    def horizon(self) -> float:
        return self.problem.horizon

    def _param(self):
        return next(self.net.parameters())

    def _prepare(self, s: torch.Tensor, t):
        p = self._param()
        s = s.to(device=p.device, dtype=p.dtype)
        if s.dim() != 2 or s.shape[-1] != self.problem.state_dim:
            raise ValueError(f"{self.problem.kind}: expected state [B, {self.problem.state_dim}], got {tuple(s.shape)}")
        return s, as_time(t, s.shape[0], s).to(dtype=p.dtype)

    def state_value(self, s: torch.Tensor, t=0.0, reuse_buffers: bool = False) -> torch.Tensor:
        """``V [B]`` of states ``s [B, S]`` at ``t`` (s). ``reuse_buffers``: the network runs on
        reused workspace buffers (:meth:`Siren.forward_reusing_buffers`, bitwise the same values)."""
        s, t = self._prepare(s, t)
        with torch.no_grad():
            x = self.problem.normalise(s, t)
            n = self.net.forward_reusing_buffers(x) if reuse_buffers else self.net(x)
            return self._boundary(s) + (self.horizon - t) * self.output_scale * n

    def _boundary(self, s):
        if self.problem.kind == "vhat":
            return self.problem.system.terminal_value(s[:, :-1], s[:, -1])
        return self.problem.system.target(s)

    def state_value_and_grads(self, s: torch.Tensor, t=0.0, reuse_buffers: bool = False):
        """``(V [B], ∂_t V [B], ∇_s V [B, S])``; works under ``torch.no_grad()``. ``reuse_buffers``:
        the network's intermediates in reused workspace buffers (bitwise the same values)."""
        s, t = self._prepare(s, t)
        n, gn = self.net.value_and_input_grad(self.problem.normalise(s, t), reuse=reuse_buffers)
        b, gb = self.problem.boundary_and_grad(s)
        return assemble(self.problem, s, t, n, gn, b, gb, self.output_scale)


class VHat(PINNValueFunction):
    """Auxiliary epigraph value V̂(t, o, z) (SPEC §4)."""

    @property
    def z_max(self) -> float:
        return self.problem.system.z_max

    @property
    def obs_spec(self):
        return self.problem.system.spec

    @property
    def system(self):
        return self.problem.system

    def _state(self, obs, z):
        if obs.shape[:-1] != z.shape:
            raise ValueError(f"obs [B, D] and z [B] disagree: {tuple(obs.shape)} vs {tuple(z.shape)}")
        return torch.cat([obs, z[..., None].to(obs.dtype)], dim=-1)

    def value(self, obs: torch.Tensor, z: torch.Tensor, t=0.0) -> torch.Tensor:
        """V̂ ``[B]`` for obs ``[B, D]`` (observation layout), z ``[B]``, t float or ``[B]`` (s)."""
        return self.state_value(self._state(obs, z), t)

    def value_and_grad(self, obs: torch.Tensor, z: torch.Tensor, t=0.0):
        """``(V̂ [B], ∂V̂/∂obs [B, D], ∂V̂/∂z [B])``."""
        v, _, g = self.state_value_and_grads(self._state(obs, z), t)
        return v, g[:, :-1], g[:, -1]

    def velocity_grad(self, obs: torch.Tensor, z: torch.Tensor, t=0.0) -> torch.Tensor:
        """``∂V̂/∂v_a`` ``[B, n+1, d]`` (every observed agent's velocity: what the control reads),
        bitwise ``system.velocity_grad`` of :meth:`value_and_grad`'s ``∂V̂/∂obs``, at the cost of the
        network's input gradient alone (:meth:`Siren.input_grad_reusing_buffers`): the terminal term
        ``max(φ_d − z, g_d)`` reads positions and goals only, so its velocity gradient is +0, added
        as such (+0 + −0 = +0, as in the sum of :func:`assemble`)."""
        s, tt = self._prepare(self._state(obs, z), t)
        grad_n = self.net.input_grad_reusing_buffers(self.problem.normalise(s, tt))
        idx = self.system.velocity_index().to(grad_n.device)
        tau = (self.horizon - tt) * self.output_scale
        return (tau[:, None, None] * grad_n[:, idx] * self.problem.input_scale(grad_n)[idx]).add_(0.0)

    def at_observations(self, obs: torch.Tensor, t=0.0) -> "ObservationValues":
        """V̂ of the fixed observations ``obs [B, D]`` at time ``t``, as a function of z (for a z search)."""
        return ObservationValues.of(self, obs, t)


class ObservationValues:
    """``z ↦ V̂(t, o, z)`` for fixed observations ``o [B, D]``: bitwise :meth:`VHat.value` (the same
    float operations on every row), with the z-independent parts computed once — the normalised
    observation and time, ``φ_d(o)`` and ``g_d(o)`` of the terminal term ``max(φ_d − z, g_d)``, and
    ``(T − t)·σ`` — so a call costs the network rows and a few ``[B]`` operations.
    :meth:`rows` gives the same function on a subset of the observations."""

    def __init__(self, vhat: VHat, x: torch.Tensor, phi: torch.Tensor, g: torch.Tensor, tau: torch.Tensor):
        self.vhat, self._x, self._phi, self._g, self._tau = vhat, x, phi, g, tau
        self._z_col = vhat.problem.state_dim - 1   # z is the last state coordinate
        self._z_input = vhat.problem.coordinate_normaliser(self._z_col, x)

    @classmethod
    def of(cls, vhat: VHat, obs: torch.Tensor, t=0.0) -> "ObservationValues":
        s, tt = vhat._prepare(vhat._state(obs, obs.new_zeros(obs.shape[0])), t)
        phi, g = vhat.system.terminal_parts(s[:, :-1])
        # the network input; its z column is written at each call
        return cls(vhat, vhat.problem.normalise(s, tt), phi, g, (vhat.horizon - tt) * vhat.output_scale)

    def __len__(self) -> int:
        return self._x.shape[0]

    def rows(self, idx: torch.Tensor) -> "ObservationValues":
        """The observations ``idx [M]`` (long) only."""
        return ObservationValues(self.vhat, self._x[idx], self._phi[idx], self._g[idx], self._tau[idx])

    def z_input(self, z: torch.Tensor) -> torch.Tensor:
        """The network's input column of budgets ``z [K]`` (normalised; for :meth:`__call__`)."""
        return self._z_input(z.to(dtype=self._x.dtype, device=self._x.device))

    def __call__(self, z: torch.Tensor, z_input: torch.Tensor | None = None) -> torch.Tensor:
        """V̂ ``[B]`` at budgets ``z [B]``; ``z_input``: their :meth:`z_input`, where the caller has it."""
        z = z.to(dtype=self._x.dtype, device=self._x.device)
        self._x[:, self._z_col] = self._z_input(z) if z_input is None else z_input
        n = self.vhat.net.forward_reusing_buffers(self._x)
        return torch.maximum(self._phi - z, self._g) + self._tau * n


class PairValue(PINNValueFunction):
    """Pairwise safety value V_s(x, t) (SPEC §5), m; ≤ 0 means collision unavoidable.

    ``band``: the network's value is clamped into ``[free-drift bound, ψ]`` (issue 37), the band
    the exact V_s lies in — doing nothing is one admissible relative control, so V_s is at least
    the free-drift margin over the remaining horizon, and the minimum over the horizon includes
    τ = t, so V_s ≤ ψ = ‖p‖ − r. The clamp can only move the network toward the exact value (grid
    reference: −35 % mean error, docs/reference/performance.md); the gradient is the active bound's where
    the clamp acts. Set by :meth:`banded`, a deployment choice (no retraining)."""

    band: bool = False

    def banded(self) -> "PairValue":
        """This V_s with its value clamped into the exact band (see the class docstring)."""
        self.band = True
        return self

    @property
    def collision_radius(self) -> float:
        return self.problem.system.collision_radius

    @property
    def system(self):
        return self.problem.system

    def value(self, x_rel: torch.Tensor, t=0.0, reuse_buffers: bool = False) -> torch.Tensor:
        """V_s ``[B]`` of relative states ``x_rel [B, 2d]`` at ``t`` (s); ``reuse_buffers``: as in
        :meth:`PINNValueFunction.state_value` (the deployed neighbour scoring)."""
        v = self.state_value(x_rel, t, reuse_buffers)
        if not self.band:
            return v
        x = x_rel.to(v.dtype)
        lo, _ = self.system.free_drift_and_grad(x, self.horizon - as_time(t, x.shape[0], x))
        return torch.minimum(torch.maximum(v, lo), self.system.target(x))

    def value_and_grad(self, x_rel: torch.Tensor, t=0.0, reuse_buffers: bool = False):
        """``(V_s [B], ∂V_s/∂x [B, 2d])``; ``reuse_buffers``: as in :meth:`value`."""
        v, _, g = self.state_value_and_grads(x_rel, t, reuse_buffers)
        if not self.band:
            return v, g
        x = x_rel.to(v.dtype)
        lo, glo = self.system.free_drift_and_grad(x, self.horizon - as_time(t, x.shape[0], x))
        hi, ghi = self.system.target_and_grad(x)
        below, above = v < lo, v > hi
        v = torch.where(below, lo, torch.where(above, hi, v))
        g = torch.where(below[:, None], glo, torch.where(above[:, None], ghi, g))
        return v, g


CLASSES = {"vhat": VHat, "vs": PairValue}


def network_config(net: Siren) -> dict:
    return {"hidden": net.hidden, "layers": net.n_layers, "first_omega": net.omegas[0],
            "hidden_omega": net.omegas[-1] if net.n_layers > 1 else 30.0}


def build_network(problem: PINNProblem, ncfg: dict) -> Siren:
    return Siren(problem.in_features, hidden=int(ncfg["hidden"]), layers=int(ncfg["layers"]),
                 first_omega=float(ncfg["first_omega"]), hidden_omega=float(ncfg["hidden_omega"]))


def model_payload(problem: PINNProblem, net: Siren, output_scale: float, meta: dict) -> dict:
    return {
        "format": FORMAT, "version": VERSION, "kind": problem.kind,
        "problem": problem.describe(), "network": network_config(net), "output_scale": float(output_scale),
        "state_dict": {k: v.detach().cpu().clone() for k, v in net.state_dict().items()},
        "meta": meta,
    }


def save_atomic(payload: dict, path: str | Path) -> Path:
    """Write a value-function payload atomically (:func:`madpinn.atomic.save_torch`)."""
    return save_torch(payload, path)


def read_checkpoint(path: str | Path, kind: str | None = None) -> dict:
    """Load and check a checkpoint dict (weights_only); clear :class:`CheckpointError` otherwise."""
    path = Path(path)
    if not path.is_file():
        raise CheckpointError(f"value-function checkpoint not found: {path}; {build_hint(path)}")
    try:
        data = torch.load(path, map_location="cpu", weights_only=True)
    except Exception as exc:  # noqa: BLE001 - truncated zip, garbage, pickled objects, ...
        raise CheckpointError(f"value-function checkpoint {path} was refused: {unreadable_reason(exc)}") from exc
    if not isinstance(data, dict) or data.get("format") != FORMAT:
        raise CheckpointError(f"{path} is not a madpinn value-function checkpoint")
    if data.get("version") != VERSION:
        raise CheckpointError(f"{path} has checkpoint version {data.get('version')}, expected {VERSION}")
    if kind is not None and data.get("kind") != kind:
        raise CheckpointError(f"{path} holds a '{data.get('kind')}' value function, expected '{kind}'")
    for key in ("problem", "network", "output_scale", "state_dict", "meta"):
        if key not in data:
            raise CheckpointError(f"{path} lacks '{key}'")
    return data


def model_from_payload(data: dict, device="cpu", dtype=torch.float32, path="<memory>") -> PINNValueFunction:
    kind = data["kind"]
    problem = PROBLEMS[kind].from_description(data["problem"])
    net = build_network(problem, data["network"])
    try:
        net.load_state_dict(data["state_dict"])
    except RuntimeError as exc:
        raise CheckpointError(f"{path}: weights do not match the stored network shape: {exc}") from exc
    net = net.to(device=torch.device(device), dtype=dtype).eval()
    for p in net.parameters():
        p.requires_grad_(False)
    return CLASSES[kind](problem, net, data["output_scale"], data["meta"])


def load_value_function(path, kind: str, device="cpu", dtype=torch.float32) -> PINNValueFunction:
    return model_from_payload(read_checkpoint(path, kind), device=device, dtype=dtype, path=path)


def load_vhat(path, device="cpu", dtype=torch.float32) -> VHat:
    """Load a trained V̂ (``results/models/vhat.pt``)."""
    return load_value_function(path, "vhat", device, dtype)


def load_vs(path, device="cpu", dtype=torch.float32, band: bool = False) -> PairValue:
    """Load a trained V_s (``results/models/vs.pt``); ``band``: clamp it into the exact band
    (:meth:`PairValue.banded`)."""
    vs = load_value_function(path, "vs", device, dtype)
    return vs.banded() if band else vs
