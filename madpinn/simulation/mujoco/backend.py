"""MuJoCo Crazyflie backend implementing the :class:`~madpinn.simulation.backend.SimBackend` protocol.

All S × N drones of a job fly in MuJoCo worlds of at most ``drones_per_world`` drones (drone
``s·N + i`` is agent i of scenario s). Per ``sim.dt`` the backend runs ``substeps`` times:
setpoint (p_d, v_d, a_ff) → controller (``sim.mujoco.controller``, :mod:`readings`) → rotor thrusts → forces → ``mj_step``. The
planar state returned is read from the simulated drones after the last substep.

Setpoints: the policy acceleration ``a`` (clipped to the control box) drives a double-integrator
reference (``madpinn.dynamics.DoubleIntegrator``, exact ZOH with velocity saturation) at the
physics rate, so over one policy step the setpoint is the integral of ``a``; ``a`` itself is the
feed-forward. The reference lives on the agent model's axes (``dynamics.position_dim`` of MuJoCo's
x, y, z): a planar model holds the altitude setpoint ``altitude`` m with vertical velocity 0; the
3-D model's reference carries the policy's altitude setpoint (its z, kept in the model's altitude
band by the model's step), vertical velocity and acceleration. Yaw 0.

``contacts`` (``sim.contacts``): drones carry their collision cylinders and touch each other and
the floor; every world then holds whole scenarios, each at its own planar offset
(:func:`~madpinn.simulation.mujoco.model.scenario_offsets`), so only drones of one scenario ever
meet; positions in and out of the backend stay in the scenario's own frame. A drone that was hit
keeps its controller, and whatever the physics does follows.
"""

from __future__ import annotations

import math

import mujoco
import numpy as np
import torch

from madpinn.dynamics import AgentModel
from madpinn.simulation.mujoco.forces import apply_rotor_thrusts
from madpinn.simulation.mujoco.model import FREE_JOINT_DOFS, HORIZONTAL, ROTORS, compile_world, scenario_offsets
from madpinn.simulation.mujoco.readings import make_controller
from madpinn.simulation.mujoco.settings import MujocoSettings


class PhysicsDivergedError(RuntimeError):
    """The MuJoCo state became non-finite or MuJoCo flagged an unstable acceleration."""


class MujocoBackend:
    """Batched Crazyflie simulation; ``dt`` (s) is the step of :meth:`step`."""

    def __init__(self, dynamics: AgentModel, dt: float, settings: MujocoSettings,
                 device: torch.device | str = "cpu", dtype: torch.dtype = torch.float32, contacts: bool = False):
        if not (math.isfinite(dt) and dt > 0):
            raise ValueError(f"sim.dt must be positive, got {dt}")
        settings.validate()
        dynamics.require_uniform_bounds("the MuJoCo backend")   # its arrays are [S·N, d]
        self.dynamics = dynamics
        self._axes = slice(0, dynamics.position_dim)   # the model's axes among MuJoCo's x, y, z
        self.dt = float(dt)
        self.settings = settings
        self.spec = settings.spec
        self.contacts = bool(contacts)
        self.h = self.dt / int(settings.substeps)
        self.controller = make_controller(settings.controller, settings.gains, self.spec, self.h)
        self.device, self.dtype = torch.device(device), dtype
        self._shape: tuple[int, int] | None = None
        self._worlds: list[tuple[mujoco.MjModel, mujoco.MjData, slice]] = []
        self._setpoint_buffers: tuple[np.ndarray, np.ndarray, np.ndarray] | None = None

    # ------------------------------------------------------------------ protocol
    def reset(self, positions: torch.Tensor, velocities: torch.Tensor) -> torch.Tensor:
        """Place S × N level drones at ``positions`` ``[S, N, d]`` (m; planar: at altitude ``altitude``), with
        ``velocities`` ``[S, N, d]`` (m/s) on the model's axes; returns the model's state ``[S, N, 2d]``."""
        d = self.dynamics.position_dim
        if positions.dim() != 3 or positions.shape[-1] != d or velocities.shape != positions.shape:
            raise ValueError(f"positions and velocities must both be [S, N, {d}], got {tuple(positions.shape)} and {tuple(velocities.shape)}")
        S, N, _ = positions.shape
        count = S * N
        if not 1 <= count <= self.settings.max_drones:
            raise ValueError(f"the MuJoCo backend simulates 1..{self.settings.max_drones} drones (sim.mujoco.max_drones), got S×N = {S}×{N} = {count}")
        p = positions.detach().to("cpu", torch.float64).reshape(count, d).numpy()
        v = velocities.detach().to("cpu", torch.float64).reshape(count, d).numpy()
        if not (np.isfinite(p).all() and np.isfinite(v).all()):
            raise ValueError("non-finite initial positions or velocities")
        self._shape = (S, N)
        self._build_worlds(count, N)
        self.qpos = np.zeros((count, 7))
        self.qvel = np.zeros((count, 6))
        self.qpos[:, 2] = self.settings.altitude   # a planar model's drones fly at sim.mujoco.altitude
        self.qpos[:, self._axes] = p                # a 3-D model's positions carry their own altitude
        self.qpos[:, 3] = 1.0
        self.qvel[:, self._axes] = v
        for model, data, sl in self._worlds:
            mujoco.mj_resetData(model, data)
            data.qpos[:] = self._to_world(self.qpos[sl], sl).reshape(-1)
            data.qvel[:] = self.qvel[sl].reshape(-1)
            mujoco.mj_forward(model, data)
        self.reference = self.dynamics.join(torch.from_numpy(p), torch.from_numpy(np.clip(v, -self.dynamics.v_max, self.dynamics.v_max))).numpy()
        self.accel = np.zeros((count, self.dynamics.control_dim))
        self.thrusts = np.zeros((count, 4))
        self.controller.reset(count)
        self.time = 0.0
        return self._planar_state()

    def command(self, accel: torch.Tensor, duration: float) -> None:
        """Hold policy acceleration ``accel`` ``[S, N, 2]`` (m/s², clipped to the control box) for
        the next ``duration`` s: the setpoint integrates it, and it is the feed-forward."""
        if self._shape is None:
            raise RuntimeError("reset() before command()")
        shape = self._shape + (self.dynamics.control_dim,)
        if tuple(accel.shape) != shape:
            raise ValueError(f"accel must be {shape}, got {tuple(accel.shape)}")
        if not (math.isfinite(duration) and duration > 0):
            raise ValueError(f"command duration must be positive, got {duration}")
        a = accel.detach().to("cpu", torch.float64).reshape(-1, self.dynamics.control_dim)
        if not torch.isfinite(a).all():
            raise ValueError("non-finite acceleration command (NaN/inf setpoint)")
        self.accel = self.dynamics.clip_control(a).numpy()

    def step(self) -> torch.Tensor:
        """Advance ``dt`` s (``substeps`` physics steps); returns the planar state ``[S, N, 4]``."""
        if self._shape is None:
            raise RuntimeError("reset() before step()")
        for _ in range(int(self.settings.substeps)):
            self._substep()
        self.time += self.dt
        if not (np.isfinite(self.qpos).all() and np.isfinite(self.qvel).all()):
            raise PhysicsDivergedError(f"MuJoCo state became non-finite at t = {self.time:.4f} s")
        for _, data, _ in self._worlds:
            if data.warning[mujoco.mjtWarning.mjWARN_BADQACC].number:
                raise PhysicsDivergedError(f"MuJoCo reported an unstable acceleration at t = {self.time:.4f} s (lower sim.dt or raise sim.mujoco.substeps)")
        return self._planar_state()

    def hold(self, positions: torch.Tensor) -> None:
        """Position-hold setpoint: hover at planar ``positions`` ``[S, N, 2]`` (m) until the next
        :meth:`command` (a setpoint step when far from the current position)."""
        if self._shape is None:
            raise RuntimeError("reset() before hold()")
        d = self.dynamics.position_dim
        if tuple(positions.shape) != self._shape + (d,):
            raise ValueError(f"positions must be {self._shape + (d,)}, got {tuple(positions.shape)}")
        p = positions.detach().to("cpu", torch.float64).reshape(-1, d).numpy()
        if not np.isfinite(p).all():
            raise ValueError("non-finite position setpoint")
        self.reference = self.dynamics.join(torch.from_numpy(p), torch.zeros(p.shape, dtype=torch.float64)).numpy()
        self.accel = np.zeros_like(p)

    # ------------------------------------------------------------------ internals
    def _build_worlds(self, count: int, group: int) -> None:
        """Worlds of at most ``drones_per_world`` drones; with contacts each holds whole scenarios
        of ``group`` drones (at least one, whatever its size) at their offsets."""
        per_world = int(self.settings.drones_per_world)
        if self.contacts:
            per_world = max(1, per_world // group) * group
        actuated = self.settings.force_application == "site"
        self._worlds = []
        for start in range(0, count, per_world):
            stop = min(count, start + per_world)
            model = compile_world(stop - start, self.h, self.spec, actuated, self.contacts, visual=False)
            self._worlds.append((model, mujoco.MjData(model), slice(start, stop)))
        self._offsets = np.zeros((count, 2))   # scenario offsets in the horizontal plane
        if self.contacts:
            for _, _, sl in self._worlds:
                self._offsets[sl] = scenario_offsets(sl.stop - sl.start, group)

    def _to_world(self, qpos: np.ndarray, sl: slice) -> np.ndarray:
        """Free-joint positions ``[M, 7]`` of drones ``sl`` in their world (scenario offsets added)."""
        if not self.contacts:
            return qpos
        out = qpos.copy()
        out[:, HORIZONTAL] += self._offsets[sl]
        return out

    def _setpoints(self) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """(p_d, v_d, a_ff) ``[M, 3]`` from the reference on the model's axes; a planar model's
        altitude is held at ``altitude`` with no vertical motion."""
        if self._setpoint_buffers is None or self._setpoint_buffers[0].shape[0] != self.reference.shape[0]:
            p_d, v_d, a_ff = (np.zeros((self.reference.shape[0], 3)) for _ in range(3))
            p_d[:, 2] = self.settings.altitude
            self._setpoint_buffers = (p_d, v_d, a_ff)
        p_d, v_d, a_ff = self._setpoint_buffers
        p_d[:, self._axes] = self.dynamics.position(self.reference)
        v_d[:, self._axes] = self.dynamics.velocity(self.reference)
        a_ff[:, self._axes] = self.accel
        return p_d, v_d, a_ff

    def _substep(self) -> None:
        quat = self.qpos[:, 3:7]
        self.thrusts = self.controller(self.qpos[:, 0:3], self.qvel[:, 0:3], quat, self.qvel[:, 3:6], *self._setpoints())
        mixer, mode = self.controller.mixer, self.settings.force_application
        for model, data, sl in self._worlds:
            apply_rotor_thrusts(mode, data, self.thrusts[sl], quat[sl], mixer)
            mujoco.mj_step(model, data)
            self.qpos[sl] = data.qpos.reshape(-1, 7)
            if self.contacts:
                self.qpos[sl, HORIZONTAL] -= self._offsets[sl]
            self.qvel[sl] = data.qvel.reshape(-1, FREE_JOINT_DOFS)
        ref = self.dynamics.step(torch.from_numpy(self.reference), torch.from_numpy(self.accel), self.h)
        self.reference = ref.numpy()

    def _planar_state(self) -> torch.Tensor:
        S, N = self._shape
        state = self.dynamics.join(torch.from_numpy(self.qpos[:, self._axes]), torch.from_numpy(self.qvel[:, self._axes]))
        return state.reshape(S, N, self.dynamics.state_dim).to(device=self.device, dtype=self.dtype)

    # ------------------------------------------------------------------ inspection
    @property
    def rotor_thrusts(self) -> np.ndarray:
        """Rotor thrusts ``[S, N, 4]`` (N) applied during the last physics step."""
        S, N = self._shape
        return self.thrusts.reshape(S, N, ROTORS)

    @property
    def poses(self) -> np.ndarray:
        """Full free-joint state ``[S, N, 7]``: position (m) and quaternion (w, x, y, z)."""
        S, N = self._shape
        return self.qpos.reshape(S, N, 7).copy()
