"""3-D double integrator (issue 63 item 2): drones free to change altitude within a band.

State ``s = [x, y, z, vx, vy, vz]`` (m, m/s), control ``u = [ax, ay, az]`` (m/s²): the planar
model's ``ṗ = v, v̇ = u`` on three axes (:func:`~madpinn.dynamics.double_integrator.hold_step`,
the same exact step), and the altitude ``z`` kept inside ``[z_lo, z_hi]`` (m): after each step an
altitude outside the band is put back on its edge and the vertical velocity pointing out of the
band is zeroed (an inelastic floor and ceiling). The planar scenario generators' points are
placed at the band's middle altitude (:meth:`DoubleIntegrator3D.place`), so a 3-D scenario is a
planar one whose agents may pass over each other.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import ClassVar

import torch

from madpinn.dynamics.double_integrator import DoubleIntegrator


@dataclass(frozen=True)
class DoubleIntegrator3D(DoubleIntegrator):
    """ṗ = v, v̇ = u on x, y, z; ``u ∈ [-u_max, u_max]³``, velocity components saturated to
    ``[-v_max, v_max]`` (per agent where given), altitude in ``altitude_band = (z_lo, z_hi)`` (m).
    No defaults: built from ``agents`` (:meth:`madpinn.settings.AgentSettings.dynamics`)."""

    altitude_band: tuple[float, float]

    name: ClassVar[str] = "double_integrator_3d"
    position_dim: ClassVar[int] = 3
    control_dim: ClassVar[int] = 3
    state_dim: ClassVar[int] = 6
    ALTITUDE: ClassVar[int] = 2
    """the altitude's index among the position (and velocity) coordinates"""

    def __post_init__(self):
        lo, hi = (float(b) for b in self.altitude_band)
        if not (math.isfinite(lo) and math.isfinite(hi) and lo < hi):
            raise ValueError(f"agents.altitude_band must be (z_lo, z_hi) with z_lo < z_hi (m), got {self.altitude_band}")

    def place(self, points: torch.Tensor) -> torch.Tensor:
        """Planar points ``[..., 2]`` at the band's middle altitude: ``[..., 3]`` (m)."""
        if points.shape[-1] != self.position_dim - 1:
            raise ValueError(f"expected planar points [..., {self.position_dim - 1}], got {tuple(points.shape)}")
        lo, hi = self.altitude_band
        z = torch.full_like(points[..., :1], 0.5 * (float(lo) + float(hi)))
        return torch.cat([points, z], dim=-1)

    def clip_state(self, state: torch.Tensor) -> torch.Tensor:
        """Velocities clipped to ±v_max, the altitude to the band (outward vertical velocity zeroed)."""
        return self._into_band(super().clip_state(state))

    def step(self, state: torch.Tensor, u: torch.Tensor, dt: float) -> torch.Tensor:
        """The planar model's exact step on three axes, then the altitude put back into the band."""
        return self._into_band(super().step(state, u, dt))

    def _into_band(self, state: torch.Tensor) -> torch.Tensor:
        lo, hi = (float(b) for b in self.altitude_band)
        k, d = self.ALTITUDE, self.position_dim
        z, vz = state[..., k], state[..., d + k]
        below, above = z < lo, z > hi
        out = state.clone()
        out[..., k] = z.clamp(lo, hi)
        out[..., d + k] = torch.where((below & (vz < 0)) | (above & (vz > 0)), torch.zeros_like(vz), vz)
        return out
