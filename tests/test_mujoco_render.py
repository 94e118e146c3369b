"""Optional rendered clip: runs where an offscreen GL context exists, skipped cleanly otherwise."""

import numpy as np
import pytest

from madpinn.simulation.mujoco.render import gl_context_available, render_clip
from madpinn.simulation.mujoco.settings import MujocoSettings
from settings_helpers import mujoco_section

SETTINGS = MujocoSettings.from_config(mujoco_section())


def test_clip_of_a_stored_trajectory(tmp_path):
    ok, detail = gl_context_available(SETTINGS.spec)
    if not ok:
        pytest.skip(detail)
    t = np.arange(6) * 0.02
    positions = np.stack([np.stack([t, -t], axis=1), np.stack([-t, 0 * t], axis=1)], axis=1)  # [6, 2, 2]
    traj = tmp_path / "x_traj.npz"
    np.savez(traj, times=t, positions=positions, goals=np.array([[0.5, 0.5], [-0.5, 0.0]]),
             collided=np.array([False, True]), first_collision_step=np.array([-1, 16]), dt=0.0025,
             collision_radius=0.1, half_width=1.0)
    out = render_clip(traj, tmp_path / "clip.gif", SETTINGS)
    from PIL import Image

    with Image.open(out) as im:
        assert im.n_frames == 6 and im.size == (480, 360)
        im.seek(5)
        rgb = np.asarray(im.convert("RGB")).astype(int)
    assert ((rgb[..., 0] > 80) & (rgb[..., 0] > 3 * rgb[..., 1])).any()  # the collided drone is drawn red


def test_bad_trajectory_is_rejected(tmp_path):
    ok, detail = gl_context_available(SETTINGS.spec)
    if not ok:
        pytest.skip(detail)
    traj = tmp_path / "bad_traj.npz"
    np.savez(traj, times=np.zeros(0), positions=np.zeros((0, 2, 2)), goals=np.zeros((2, 2)), dt=0.0025, half_width=1.0)
    with pytest.raises(ValueError, match="positions"):
        render_clip(traj, tmp_path / "clip.gif", SETTINGS)
