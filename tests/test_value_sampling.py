"""Conflict-focused V̂ training distribution: in the domain, on near-collision courses,
unchanged with fraction 0, deterministic, validated."""

import pytest
import torch

from conftest import REPO
from madpinn.config import ConfigError, deep_merge, load_config, load_yaml, validate_config
from madpinn.observation import split_observation
from madpinn.value_functions.build import problem_from_config
from madpinn.value_functions.sampling import ConflictSamplingSettings
from settings_helpers import pair_system


def problem(fraction, radius=0.3, **speed_aware):
    cfg = load_config([REPO / "config.yaml"])
    cfg["value_functions"]["vhat"]["conflict_sampling"] = {"fraction": fraction, "radius": radius, **speed_aware}
    validate_config(cfg)   # fills the keys left out with their schema defaults, as the loader does
    return problem_from_config(cfg, "vhat")


def closest_approach(obs, horizon):
    """Smallest constant-velocity closest approach over [0, T] among the 3 pairs ``[B]`` (m)."""
    pos, vel, _ = split_observation(obs, 2)
    out = []
    for a, c in ((0, 1), (0, 2), (1, 2)):
        x, v = pos[:, c] - pos[:, a], vel[:, c] - vel[:, a]
        tau = (-(x * v).sum(1) / (v * v).sum(1).clamp_min(1e-12)).clamp(0.0, horizon)
        out.append((x + v * tau[:, None]).norm(dim=1))
    return torch.stack(out, 1).min(1).values


def test_conflict_rows_are_on_near_collision_courses_inside_the_domain():
    p = problem(0.5, radius=0.3)
    s = p.sample_training_states(4000, torch.Generator().manual_seed(1), torch.float64)
    obs, z = s[:, :-1], s[:, -1]
    assert bool((obs.abs() <= p.system.half_widths() + 1e-12).all())
    assert bool(((z >= 0) & (z <= p.system.z_max)).all())
    ca = closest_approach(obs, p.horizon)
    assert float((ca[:2000] <= 0.3 + 1e-9).double().mean()) > 0.97      # clipping at the box edge excepted
    assert float((ca[2000:] <= 0.3).double().mean()) < 0.3               # the uniform half is not
    assert torch.equal(obs[:, 0:4], p.sample_states(4000, torch.Generator().manual_seed(1), torch.float64)[:, 0:4])


def test_fraction_zero_is_the_uniform_batch_and_sampling_is_deterministic():
    uni = problem(0.0).sample_training_states(512, torch.Generator().manual_seed(7), torch.float32)
    ref = problem(0.0).sample_states(512, torch.Generator().manual_seed(7), torch.float32)
    assert torch.equal(uni, ref)
    a = problem(0.5).sample_training_states(512, torch.Generator().manual_seed(7), torch.float32)
    b = problem(0.5).sample_training_states(512, torch.Generator().manual_seed(7), torch.float32)
    assert torch.equal(a, b) and not torch.equal(a, uni)


def near_miss(obs, horizon):
    """Per row, the pair (among 3) with the smallest constant-velocity closest approach over
    [0, T]: its relative speed ``[B]`` (m/s) and time of closest approach ``[B]`` (s)."""
    pos, vel, _ = split_observation(obs, 2)
    dist, speed, when = [], [], []
    for a, c in ((0, 1), (0, 2), (1, 2)):
        x, v = pos[:, c] - pos[:, a], vel[:, c] - vel[:, a]
        tau = (-(x * v).sum(1) / (v * v).sum(1).clamp_min(1e-12)).clamp(0.0, horizon)
        dist.append((x + v * tau[:, None]).norm(dim=1))
        speed.append(v.norm(dim=1))
        when.append(tau)
    k = torch.stack(dist, 1).argmin(1, keepdim=True)
    return torch.stack(speed, 1).gather(1, k)[:, 0], torch.stack(when, 1).gather(1, k)[:, 0]


def test_speed_aware_conflicts_close_fast_and_late_in_the_horizon():
    """closing_speed [4, 11.3] m/s and tau [0.5, 1]: the conflict pairs close at ≥ 4 m/s unless
    the ±v_max box clipped them, and their near miss lies in the late half of the horizon
    (the disk of radius ρ shifts the closest approach by at most ρ / speed)."""
    plain = problem(0.5)
    fast = problem(0.5, tau=[0.5, 1.0], closing_speed=[4.0, 11.3])
    gen = lambda: torch.Generator().manual_seed(3)
    s_plain = plain.sample_training_states(4000, gen(), torch.float64)[:2000, :-1]
    s_fast = fast.sample_training_states(4000, gen(), torch.float64)
    obs = s_fast[:, :-1]
    assert bool((obs.abs() <= fast.system.half_widths() + 1e-12).all())
    assert float((closest_approach(obs[:2000], fast.horizon) <= 0.3 + 1e-9).double().mean()) > 0.95
    speed, when = near_miss(obs[:2000], fast.horizon)
    speed0, when0 = near_miss(s_plain, plain.horizon)
    assert float((speed >= 4.0 - 1e-9).double().mean()) > 0.8          # the box clips a few
    assert float((speed0 >= 4.0).double().mean()) < 0.7
    late = when >= 0.5 * fast.horizon - 0.3 / speed.clamp_min(4.0) - 1e-9
    assert float(late.double().mean()) > 0.9
    assert float((when0 < 0.4 * plain.horizon).double().mean()) > 0.25   # the plain sampler is not late
    assert torch.equal(s_fast[2000:], plain.sample_training_states(4000, gen(), torch.float64)[2000:])   # uniform half untouched


def test_invalid_conflict_sampling_is_rejected():
    with pytest.raises(ValueError, match="tau"):
        ConflictSamplingSettings(fraction=0.5, radius=0.3, tau=(0.8, 0.2), closing_speed=None)
    with pytest.raises(ValueError, match="closing_speed"):
        ConflictSamplingSettings(fraction=0.5, radius=0.3, tau=(0.0, 1.0), closing_speed=(5.0, 1.0))
    with pytest.raises(ValueError, match="fraction"):
        ConflictSamplingSettings(fraction=1.5, radius=0.3, tau=(0.0, 1.0), closing_speed=None)
    with pytest.raises(ValueError, match="radius"):
        ConflictSamplingSettings(fraction=0.5, radius=0.0, tau=(0.0, 1.0), closing_speed=None)
    cfg = deep_merge(load_yaml(REPO / "config.yaml"), {"value_functions": {"vhat": {"conflict_sampling": {"fraction": 2.0}}}})
    with pytest.raises(ConfigError, match="conflict_sampling"):
        validate_config(cfg)


def test_pair_conflicts_put_the_relative_state_on_a_near_collision_course():
    import math

    from madpinn.dynamics.pair import PairSystem
    from madpinn.value_functions.sampling import ConflictSamplingSettings, place_pair_conflicts

    system = pair_system()
    x = system.sample(4000, torch.Generator().manual_seed(101))
    assert torch.equal(place_pair_conflicts(x, 1.0, 2.0, ConflictSamplingSettings(0.0, 0.3, (0.0, 1.0), None), torch.Generator(), system.agent), x)
    out = place_pair_conflicts(x, system.horizon, system.p_range, ConflictSamplingSettings(1.0, 0.3, (0.0, 1.0), None), torch.Generator().manual_seed(7), system.agent)
    assert torch.equal(out[:, 2:], x[:, 2:]) and out[:, :2].abs().max() <= system.p_range
    unclipped = out[:, :2].abs().amax(-1) < system.p_range
    # constant-velocity closest approach within [0, T] of the unclipped rows is inside the 0.3-m disk
    p, v = out[unclipped, :2].double(), out[unclipped, 2:].double()
    tau = (-(p * v).sum(-1) / (v * v).sum(-1).clamp_min(1e-12)).clamp(0.0, system.horizon)
    closest = torch.linalg.vector_norm(p + v * tau[:, None], dim=-1)
    assert unclipped.sum() > 400 and bool((closest <= 0.3 + 1e-5).all()) and not math.isnan(float(closest.max()))


def test_near_rows_fill_the_inner_box_and_leave_the_rest():
    from madpinn.value_functions.sampling import NearSamplingSettings, place_near

    cfg = load_config([REPO / "config.yaml"])
    cfg["value_functions"]["vs"]["conflict_sampling"] = {"fraction": 0.25, "radius": 0.3}
    cfg["value_functions"]["vs"]["near_sampling"] = {"fraction": 0.5, "p_range": 1.0, "v_range": 3.0}
    validate_config(cfg)
    p = problem_from_config(cfg, "vs")
    s = p.sample_training_states(4000, torch.Generator().manual_seed(3), torch.float64)
    near, rest = s[2000:], s[:2000]
    assert bool((near[:, :2].abs() <= 1.0).all()) and bool((near[:, 2:].abs() <= 3.0).all())
    # uniform in the inner box: each half of each axis holds about half of the rows
    assert bool(((near > 0).double().mean(0) - 0.5).abs().max() < 0.05)
    assert float(near[:, 2:].abs().max()) > 2.9
    # the other rows are the uniform + conflict batch of the same generator stream (v beyond the box)
    assert float(rest[:, 2:].abs().max()) > 7.0
    x = p.system.sample(64, torch.Generator().manual_seed(1))
    assert torch.equal(place_near(x, 2.0, 8.0, NearSamplingSettings(0.0, 1.0, 3.0), torch.Generator(), pair_system().agent), x)
    a = p.sample_training_states(256, torch.Generator().manual_seed(9), torch.float32)
    assert torch.equal(a, p.sample_training_states(256, torch.Generator().manual_seed(9), torch.float32))
    with pytest.raises(ValueError, match="fraction"):
        NearSamplingSettings(fraction=-0.1, p_range=1.0, v_range=3.0)
    bad = deep_merge(load_yaml(REPO / "config.yaml"), {"value_functions": {"vs": {"near_sampling": {"p_range": 0}}}})
    with pytest.raises(ConfigError, match="near_sampling"):
        validate_config(bad)


def test_speed_aware_pair_conflicts_close_at_the_drawn_speed_late_in_the_horizon():
    """V_s's pair sampler with tau [0.5, 1] and closing_speed [4, 8] m/s: relative speed in [4, 8]
    (never clipped by the ±8 m/s box per axis), and the near miss at τ ≥ T/2 up to ρ / speed."""
    from madpinn.value_functions.sampling import ConflictSamplingSettings, place_pair_conflicts

    x = torch.rand(2000, 4, generator=torch.Generator().manual_seed(2), dtype=torch.float64) * 2 - 1
    s = ConflictSamplingSettings(1.0, 0.3, (0.5, 1.0), (4.0, 8.0))
    out = place_pair_conflicts(x, 1.0, 10.0, s, torch.Generator().manual_seed(3), pair_system().agent, v_range=8.0)
    speed = out[:, 2:4].norm(dim=1)
    assert bool(((speed >= 4.0 - 1e-9) & (speed <= 8.0 + 1e-9)).all())
    p, v = out[:, 0:2], out[:, 2:4]
    when = -(p * v).sum(1) / (v * v).sum(1)
    assert bool((when >= 0.5 - 0.3 / 4.0 - 1e-9).all()) and bool((when <= 1.0 + 0.3 / 4.0 + 1e-9).all())
    with pytest.raises(ValueError, match="v_range"):
        place_pair_conflicts(x, 1.0, 10.0, s, torch.Generator(), pair_system().agent)
