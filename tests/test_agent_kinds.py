"""Two kinds of agents in one scenario (issue 63): per-agent bounds of the agent model
(u_max, v_max) and per-agent collision radii, under the policies that can use them: the nominal PD
(clips to each agent's box) and MAD-PINN (its bang-bang command clipped by each agent's box in
the backend). Real backend, real recorder, tiny real V̂ for MAD-PINN."""

import pytest
import torch

from madpinn.dynamics import DoubleIntegrator
from madpinn.policies.madpinn import MadPinnPolicy
from madpinn.policies.neighbours import make_selector
from madpinn.policies.nominal import NominalPD
from madpinn.simulation import DoubleIntegratorBackend, run_episode
from policy_models import tiny_models
from settings_helpers import madpinn_settings, observation_settings

DT, STEPS = 0.0025, 200                      # 0.5 s
FAST, SLOW = (4.0, 4.0, 0.1), (1.0, 0.5, 0.3)   # (u_max m/s², v_max m/s, collision radius m)
KINDS = [FAST, FAST, SLOW, SLOW]
MODEL = DoubleIntegrator(u_max=tuple(k[0] for k in KINDS), v_max=tuple(k[1] for k in KINDS))
RADII = tuple(k[2] for k in KINDS)


def _scenario():
    """Fast pair 0.25 m apart flying apart to goals 3 m out (outside their 0.1 m radius), slow pair 0.25 m apart
    (inside their 0.3 m radius from the start); the pairs 3 m from each other."""
    starts = torch.tensor([[[-1.5, -0.125], [-1.5, 0.125], [1.5, -0.125], [1.5, 0.125]]], dtype=torch.float64)
    goals = torch.tensor([[[-1.5, -3.0], [-1.5, 3.0], [1.5, -1.0], [1.5, 1.0]]], dtype=torch.float64)
    return starts, goals


def _check(result):
    steps = torch.from_numpy(result.positions).diff(dim=0).abs()       # [T, 1, N, 2] per-step moves
    bound = torch.tensor([k[1] for k in KINDS], dtype=torch.float64)[:, None] * DT
    assert (steps <= bound + 1e-12).all()                               # each agent within its own v_max
    assert steps[:, 0, :2].max() > 2 * SLOW[1] * DT                     # the fast kind goes beyond the slow bound
    assert result.collided.tolist() == [[False, False, True, True]]     # each pair at its own radius


def test_two_kinds_under_the_nominal_pd():
    starts, goals = _scenario()
    res, _ = run_episode(DoubleIntegratorBackend(MODEL, DT), NominalPD(MODEL, 6.0, 4.9), starts, goals, STEPS, RADII,
                         record_every=1, progress=False)
    _check(res)


def test_two_kinds_under_madpinn():
    vhat, vs = tiny_models(torch.float64)
    spec = observation_settings()
    selector = make_selector("nearest", spec.n_neighbours, vs=vs, radius=spec.sensing_radius,
                             generator=torch.Generator().manual_seed(0))
    pol = MadPinnPolicy(vhat, selector, spec, madpinn_settings(), sim_dt=DT)
    starts, goals = _scenario()
    res, _ = run_episode(DoubleIntegratorBackend(MODEL, DT), pol, starts, goals, STEPS, RADII, record_every=1, progress=False)
    _check(res)


def test_a_scalar_radius_is_the_old_recorder():
    starts, goals = _scenario()
    res, _ = run_episode(DoubleIntegratorBackend(MODEL, DT), NominalPD(MODEL, 6.0, 4.9), starts, goals, 4, 0.3,
                         progress=False)
    assert res.collided.tolist() == [[True, True, True, True]] and res.collision_radius == pytest.approx(0.3)


def test_policies_and_backends_with_one_box_refuse_per_agent_bounds():
    from madpinn.policies.mppi import MPPIPlanner

    from madpinn.policies.safety_filter import CBVFFilter

    with pytest.raises(ValueError, match="MPPI needs one u_max and v_max"):
        MPPIPlanner(None, MODEL, 0.1, torch.Generator())
    with pytest.raises(ValueError, match="the CBVF filter needs one u_max"):
        CBVFFilter(None, MODEL.u_max, 3.0, 2, 4, 0.0, sensing_radius=1.0)
