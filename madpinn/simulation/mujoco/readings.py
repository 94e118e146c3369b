"""The controller readings of the paper's tracking loop (``sim.mujoco.controller``, issue 46):
the paper sends ``(p_d, v_d)`` to "the onboard cascaded position–attitude controller (identical to
the Crazyflie firmware loop)" and cites Mellinger & Kumar; which firmware controller it means is
open, so each reading is a setting (``docs/reference/mujoco.md``, "Controller readings"):

- ``cascaded``: the firmware PID's structure with ``v_d`` and ``a_ff`` fed forward, raised gains
  and a 45° tilt limit (:class:`~madpinn.simulation.mujoco.controller.CascadedController`, the
  gains of ``sim.mujoco.gains``);
- ``mellinger``: the firmware's Mellinger controller with its gains
  (:class:`~madpinn.simulation.mujoco.mellinger.MellingerController`);
- ``firmware_pid``: the firmware's PID stack in absolute-position mode with its gains and limits
  (1.1 m/s, 20°; :class:`~madpinn.simulation.mujoco.firmware_pid.FirmwarePidController`).
"""

from __future__ import annotations

CONTROLLERS = ("cascaded", "mellinger", "firmware_pid")


def make_controller(name: str, gains, spec, dt: float):
    """The controller of reading ``name`` for drones of ``spec`` stepped every ``dt`` s; every one
    maps ``(pos, vel, quat, omega, p_d, v_d, a_ff)`` to rotor thrusts and has ``reset(count)``."""
    if name == "cascaded":
        from madpinn.simulation.mujoco.controller import CascadedController as cls
    elif name == "mellinger":
        from madpinn.simulation.mujoco.mellinger import MellingerController as cls
    elif name == "firmware_pid":
        from madpinn.simulation.mujoco.firmware_pid import FirmwarePidController as cls
    else:
        raise ValueError(f"sim.mujoco.controller must be one of {CONTROLLERS}, got '{name}'")
    return cls(gains, spec, dt)
