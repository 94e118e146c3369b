"""Crazyflie MJCF and world builder: physical facts, mixer, no contacts, bounds."""

import math

import mujoco
import numpy as np
import pytest

from madpinn.simulation.mujoco import CrazyflieSpec, compile_world, mixer_matrix, world_xml
from madpinn.simulation.mujoco.model import GRAVITY, MAX_DRONES_PER_WORLD
from madpinn.simulation.mujoco.settings import MujocoSettings
from settings_helpers import mujoco_section

SPEC = MujocoSettings.from_config(mujoco_section()).spec   # thrust_to_weight from config.yaml


def test_compiled_drone_has_the_public_physical_facts():
    spec = SPEC
    model = compile_world(3, 0.00125, spec)
    assert model.nbody == 4 and model.nv == 18 and model.nu == 0
    np.testing.assert_allclose(model.body_mass[1:], 0.027)
    np.testing.assert_allclose(model.body_inertia[1:], [[1.4e-5, 1.4e-5, 2.17e-5]] * 3)
    np.testing.assert_allclose(model.body_ipos[1:], 0.0)  # centre of mass at the body origin
    assert model.opt.timestep == pytest.approx(0.00125)
    assert model.opt.disableflags & mujoco.mjtDisableBit.mjDSBL_CONTACT
    assert not model.geom_contype.any() and not model.geom_conaffinity.any()
    arm = np.linalg.norm(spec.rotor_positions, axis=1)
    np.testing.assert_allclose(arm, 0.0397)
    assert spec.max_rotor_thrust * 4 / (spec.mass * GRAVITY) == pytest.approx(2.25)


def test_mixer_maps_hover_and_torques():
    spec = SPEC
    mix = mixer_matrix(spec)
    hover = np.full(4, spec.mass * GRAVITY / 4)
    np.testing.assert_allclose(mix @ hover, [spec.mass * GRAVITY, 0, 0, 0], atol=1e-15)
    # more thrust on the left rotors (y > 0) rolls right-side-down: positive τx
    left = spec.rotor_positions[:, 1] > 0
    assert (mix @ (hover + 0.01 * left))[1] > 0
    # yaw moment per newton is km/kf, alternating with the spin direction
    np.testing.assert_allclose(np.abs(mix[3]), spec.km_over_kf)
    assert mix[3].sum() == 0
    assert abs(np.linalg.det(mix)) > 0


def test_site_actuators_are_rotor_thrusts():
    spec = SPEC
    model = compile_world(2, 0.0025, spec, actuated=True)
    assert model.nu == 8
    np.testing.assert_allclose(model.actuator_ctrlrange, [[0.0, spec.max_rotor_thrust]] * 8)
    np.testing.assert_allclose(model.actuator_gear[:, 2], 1.0)
    np.testing.assert_allclose(model.actuator_gear[:, 5], np.tile(spec.rotor_spin * spec.km_over_kf, 2))


@pytest.mark.parametrize("count", [0, -1, MAX_DRONES_PER_WORLD + 1])
def test_out_of_range_drone_count_is_rejected(count):
    with pytest.raises(ValueError, match="drones"):
        world_xml(count, 0.0025, SPEC)


@pytest.mark.parametrize("timestep", [0.0, -1e-3, math.nan])
def test_bad_timestep_is_rejected(timestep):
    with pytest.raises(ValueError, match="timestep"):
        world_xml(2, timestep, SPEC)


def test_bad_physical_parameters_are_rejected():
    with pytest.raises(ValueError, match="thrust_to_weight"):
        world_xml(1, 0.0025, CrazyflieSpec(thrust_to_weight=0.9))
