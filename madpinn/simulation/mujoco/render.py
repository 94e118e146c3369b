"""Optional rendered clip of a MuJoCo episode (offscreen GL), skipped cleanly without a GL context.

The clip replays an evaluation job's stored trajectory (``*_traj.npz``: planar positions every
``sim.record_every`` steps, goals, collisions) in the Crazyflie world: drones at the altitude
setpoint (attitude is not stored, so they are drawn level), goals as small spheres, the drones
of agents that collide tinted red from their first collision on. Written as an animated GIF
(Pillow, already a dependency of matplotlib).

Offscreen GL is selected by MuJoCo from ``MUJOCO_GL`` when ``mujoco`` is first imported;
``madpinn.simulation.mujoco`` defaults it to ``egl`` when unset and libEGL exists.
"""

from __future__ import annotations

import os
from pathlib import Path

import numpy as np

SIZE = (480, 360)  # width, height (pixels)


def gl_context_available(spec) -> tuple[bool, str]:
    """Try to open an offscreen renderer on one drone of ``spec`` (a ``CrazyflieSpec``); returns
    ``(ok, description or reason)``."""
    try:
        import mujoco

        from madpinn.simulation.mujoco.model import compile_world

        renderer = mujoco.Renderer(compile_world(1, 0.01, spec), 32, 32)
        renderer.close()
        return True, f"MUJOCO_GL={os.environ.get('MUJOCO_GL', '<unset>')}"
    except Exception as exc:  # noqa: BLE001 - any GL failure means: no clip
        return False, f"no offscreen GL context (MUJOCO_GL={os.environ.get('MUJOCO_GL', '<unset>')}): {type(exc).__name__}: {exc}"


def render_clip(traj_path: str | Path, out_path: str | Path, settings, max_frames: int = 300) -> Path:
    """Render ``traj_path`` (an evaluation ``*_traj.npz``) to the GIF ``out_path``; ``settings``
    (:class:`~madpinn.simulation.mujoco.settings.MujocoSettings`) give the drones and their altitude (m)."""
    import mujoco
    from PIL import Image

    from madpinn.simulation.mujoco.model import compile_world

    traj = np.load(traj_path)
    positions, goals = traj["positions"], traj["goals"]  # [T, N, 2], [N, 2]
    if positions.ndim != 3 or positions.shape[0] == 0 or positions.shape[-1] != 2:
        raise ValueError(f"{traj_path}: positions must be [T, N, 2] with T ≥ 1, got {positions.shape}")
    first_hit = traj["first_collision_step"] if "first_collision_step" in traj else np.full(positions.shape[1], -1)
    times = traj["times"]
    step_dt = float(traj["dt"])
    frames_idx = np.unique(np.linspace(0, len(positions) - 1, min(max_frames, len(positions))).round().astype(int))
    n = positions.shape[1]
    model = compile_world(n, 0.01, settings.spec)
    altitude = settings.altitude
    data = mujoco.MjData(model)
    width, height = SIZE
    renderer = mujoco.Renderer(model, height, width)
    camera = mujoco.MjvCamera()
    camera.lookat[:] = [0.0, 0.0, altitude]
    camera.distance = 2.6 * float(traj["half_width"]) + 1.0
    camera.elevation, camera.azimuth = -70.0, 90.0
    body_geoms = [np.flatnonzero(model.geom_bodyid == b + 1) for b in range(n)]
    base_rgba = model.geom_rgba.copy()
    images = []
    try:
        for k in frames_idx:
            qpos = data.qpos.reshape(n, 7)
            qpos[:, : positions.shape[-1]] = positions[k]   # the recorded axes
            qpos[:, 2] = altitude
            qpos[:, 3:7] = [1.0, 0.0, 0.0, 0.0]
            hit = (first_hit >= 0) & (first_hit * step_dt <= times[k] + 1e-9)
            model.geom_rgba[:] = base_rgba
            for b in np.flatnonzero(hit):
                model.geom_rgba[body_geoms[b]] = [0.9, 0.1, 0.1, 1.0]
            mujoco.mj_kinematics(model, data)
            renderer.update_scene(data, camera)
            for g in goals:
                _add_sphere(renderer.scene, [g[0], g[1], altitude], 0.02, [0.1, 0.6, 0.1, 0.8])
            images.append(Image.fromarray(renderer.render()))
    finally:
        renderer.close()
        model.geom_rgba[:] = base_rgba
    out_path = Path(out_path)
    out_path.parent.mkdir(parents=True, exist_ok=True)
    frame_ms = 1000.0 * (times[-1] - times[0]) / max(1, len(frames_idx) - 1) if len(frames_idx) > 1 else 100.0
    images[0].save(out_path, save_all=True, append_images=images[1:], duration=max(20, int(frame_ms)), loop=0)
    return out_path


def _add_sphere(scene, pos, radius: float, rgba) -> None:
    import mujoco

    if scene.ngeom >= scene.maxgeom:
        return
    mujoco.mjv_initGeom(scene.geoms[scene.ngeom], mujoco.mjtGeom.mjGEOM_SPHERE, np.array([radius, 0, 0]),
                        np.asarray(pos, dtype=np.float64), np.eye(3).reshape(-1), np.asarray(rgba, dtype=np.float32))
    scene.ngeom += 1
