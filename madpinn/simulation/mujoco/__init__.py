"""MuJoCo Crazyflie 2.x backend (SPEC §7, issue 5): select it with ``sim.backend: mujoco``.

Modules: ``model`` (MJCF of the drone and of many-drone worlds), ``controller`` (cascaded
position → attitude controller), ``forces`` (rotor thrusts → MuJoCo forces), ``settings``
(``sim.mujoco`` config), ``backend`` (the :class:`MujocoBackend`), ``render`` (optional clip),
and the command ``render-clip`` in :mod:`madpinn.commands.mujoco`.

Importing this package selects MuJoCo's headless EGL context for offscreen rendering when
``MUJOCO_GL`` is unset and an EGL library exists (MuJoCo reads ``MUJOCO_GL`` once, at its first
import); rendering is optional and nothing else depends on it.
"""

import ctypes.util
import os
import sys

if "mujoco" not in sys.modules and "MUJOCO_GL" not in os.environ and ctypes.util.find_library("EGL"):
    os.environ["MUJOCO_GL"] = "egl"

from madpinn.simulation.mujoco.backend import MujocoBackend, PhysicsDivergedError
from madpinn.simulation.mujoco.controller import CascadedController, ControllerSettings
from madpinn.simulation.mujoco.model import CrazyflieSpec, compile_world, mixer_matrix, world_xml
from madpinn.simulation.mujoco.settings import MujocoSettings


def make_backend(sim, limits, device, dtype) -> MujocoBackend:
    """The MuJoCo backend for :class:`~madpinn.simulation.settings.SimSettings` ``sim`` (its ``mujoco``
    section) and :class:`~madpinn.settings.AgentSettings` ``limits`` (named by
    :data:`madpinn.simulation.backend.BACKEND_MODULES`)."""
    if sim.mujoco is None:
        raise ValueError("the mujoco backend needs sim.mujoco settings")
    return MujocoBackend(limits.dynamics(), dt=sim.dt, settings=sim.mujoco, device=device, dtype=dtype,
                         contacts=sim.contacts)


__all__ = [
    "MujocoBackend", "PhysicsDivergedError", "CascadedController", "ControllerSettings", "CrazyflieSpec",
    "MujocoSettings", "compile_world", "mixer_matrix", "world_xml", "make_backend",
]
