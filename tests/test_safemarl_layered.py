"""The layered SafeMARL filter (run ``safemarl-layered``: the authors' design on our V_s and
nominal policy): the single most critical neighbour, the joint-QP row with the neighbour's
nominal control, the coordination-range gate, the safest-control switch below the threshold,
and a head-on pair kept apart with the shipped V_s and SafeMARL nominal actor."""

from pathlib import Path

import pytest
import torch

from madpinn.config import load_config, method_config
from madpinn.dynamics import DoubleIntegrator
from madpinn.policies import PolicyContext, make_policy, policy_settings
from madpinn.policies.nominal import NominalPD
from madpinn.policies.safety_filter import CBVFFilter, SafetyFilteredPolicy
from madpinn.simulation import DoubleIntegratorBackend, run_episode
from test_safemarl_filter import BrakingBarrier
from settings_helpers import observation_settings

pytestmark = pytest.mark.usefixtures("one_thread")

REPO = Path(__file__).resolve().parents[1]
U_MAX, R = 4.0, 0.1
DYN = DoubleIntegrator(U_MAX, 4.0)


def _layered(threshold=-10.0, rng=None, critical=1, gamma=3.0):
    return CBVFFilter(BrakingBarrier(), U_MAX, gamma, critical, 6, threshold, sensing_radius=1.0,
                      neighbour_control="joint", coordination_range=rng)


def test_one_row_for_the_most_critical_neighbour():
    # agent 0 at rest; agent 1 close but leaving, agent 2 farther but closing fast: 2 is the most critical
    state = torch.tensor([[[0.0, 0.0, 0.0, 0.0], [0.3, 0.0, 2.0, 0.0], [0.0, 0.6, 0.0, -3.0]]])
    flt = _layered()
    a, b, active, V, _ = flt.constraint_rows(state, torch.zeros(1, 3, 2))
    assert a.shape == (1, 3, 1, 2) and active.all()
    x_rel = state[0, 0] - state[0, 1:]  # [2, 4]
    v_all = BrakingBarrier().value(x_rel)
    assert v_all[1] < v_all[0] - 0.1  # the fast closer has the lower V_s
    assert torch.allclose(V[0, 0, 0], v_all[1])
    _, g = BrakingBarrier().value_and_grad(x_rel[1:2])
    assert torch.allclose(a[0, 0, 0], g[0, 2:4])


def test_joint_row_gives_agent_i_its_share_of_the_pair_joint_qp():
    gen = torch.Generator().manual_seed(1)
    S = 200
    pos = (torch.rand(S, 2, 2, generator=gen) * 2 - 1) * 0.4
    state = torch.cat([pos, (torch.rand(S, 2, 2, generator=gen) * 2 - 1) * 3.0], dim=-1)
    u_nom = (torch.rand(S, 2, 2, generator=gen) * 2 - 1) * 3.0
    flt = _layered()
    u = flt(state, u_nom).double()
    zero = CBVFFilter(BrakingBarrier(), U_MAX, 3.0, 1, 6, -10.0, sensing_radius=1.0)
    a0, b0, active, _, _ = zero.constraint_rows(state)  # u_j = 0 rows: a·u_i ≥ b
    a0, b0, w0 = a0[:, :, 0].double(), b0[:, :, 0].double(), u_nom.double()
    # the 4-D joint QP  min ‖w − w0‖²  s.t.  [a, −a]·w ≥ b, unboxed: w = w0 + λ·[a, −a]
    c = torch.cat([a0[:, 0], -a0[:, 0]], dim=-1)  # agent 0's pair row, [S, 4]
    w_ref = torch.cat([w0[:, 0], w0[:, 1]], dim=-1)
    lam = ((b0[:, 0] - (c * w_ref).sum(-1)) / (c * c).sum(-1)).clamp_min(0.0)
    w = w_ref + lam.unsqueeze(-1) * c
    interior = active[:, 0, 0] & (w[:, 0:2].abs() < U_MAX - 1e-3).all(-1) & (w[:, 2:4].abs() < U_MAX - 1e-3).all(-1)
    moved = interior & (lam > 1e-3)
    assert moved.sum() > 10
    assert torch.allclose(u[interior, 0], w[interior, 0:2], atol=1e-4)
    # the pair (each agent is the other's only neighbour, V_s symmetric) meets the pair row together
    both = interior & (u.abs() < U_MAX - 1e-3).flatten(1).all(-1)
    pair_row = (a0[:, 0] * (u[:, 0] - u[:, 1])).sum(-1) - b0[:, 0]
    assert (pair_row[both] >= -1e-4).all()
    # against a neighbour whose nominal control is 0, agent i makes half the u_j = 0 filter's correction
    u_nom0 = torch.stack([u_nom[:, 0], torch.zeros_like(u_nom[:, 1])], 1)
    joint, alone = flt(state, u_nom0)[:, 0].double(), zero(state, u_nom0)[:, 0].double()
    inner = active[:, 0, 0] & (alone.abs() < U_MAX - 1e-3).all(-1) & ((alone - w0[:, 0]).norm(dim=-1) > 1e-2)
    assert inner.sum() > 10
    assert torch.allclose((joint - w0[:, 0]).norm(dim=-1)[inner], 0.5 * (alone - w0[:, 0]).norm(dim=-1)[inner], atol=1e-4)


def test_coordination_range_gates_the_filter():
    state = torch.tensor([[[0.0, 0.0, 2.0, 0.0], [0.6, 0.0, -2.0, 0.0]]])  # 0.6 m apart, closing at 4 m/s
    u_nom = torch.tensor([[[3.0, 0.5], [-3.0, -0.5]]])
    assert torch.equal(_layered(rng=0.5)(state, u_nom), u_nom)  # nearest neighbour beyond the range
    assert not torch.equal(_layered(rng=0.7)(state, u_nom), u_nom)
    with pytest.raises(ValueError, match="sensing radius"):
        _layered(rng=1.5)
    with pytest.raises(ValueError, match="neighbour_control"):
        CBVFFilter(BrakingBarrier(), U_MAX, 3.0, 1, 6, 0.0, sensing_radius=1.0, neighbour_control="both")


def test_threshold_switches_to_the_safest_control():
    state = torch.tensor([[[0.0, 0.0, 0.5, 0.0], [0.35, 0.0, -0.5, 0.0]]])
    u_nom = torch.zeros(1, 2, 2)
    _, _, _, V, _ = _layered().constraint_rows(state, u_nom)
    assert (V > 0.1).all() and (V < 0.4).all()
    u = _layered(threshold=0.4)(state, u_nom)
    assert torch.allclose(u, torch.tensor([[[-4.0, 0.0], [4.0, 0.0]]]))  # full braking apart along x
    u = _layered(threshold=0.0)(state, u_nom)
    assert (u.abs() < U_MAX - 0.5).all()  # above the threshold: the QP's gentler correction


def test_layered_variant_keeps_a_head_on_pair_apart_with_the_shipped_models():
    cfg = load_config([REPO / "config.yaml"])
    method, mcfg = method_config(cfg, "safemarl-layered")
    settings = policy_settings(method, mcfg)
    assert settings.cbvf.neighbour_control == "joint" and settings.cbvf.critical_neighbours == 1
    spec = observation_settings()
    ctx = PolicyContext(method=settings, dynamics=DYN, obs_spec=spec, device=torch.device("cpu"), dtype=torch.float32,
                        seed=0, sim_dt=0.0025, policy_period=4,
                        models={"nominal": REPO / "models" / "safemarl_nominal.pt", "vs": REPO / "models" / "vs.pt"})
    policy = make_policy(method, ctx)
    starts = torch.tensor([[[-0.6, 0.0], [0.6, 0.0]], [[-0.6, 0.02], [0.6, -0.02]]])
    goals = torch.tensor([[[0.6, 0.0], [-0.6, 0.0]], [[0.6, 0.0], [-0.6, 0.0]]])
    res, _ = run_episode(DoubleIntegratorBackend(DYN, 0.0025), policy, starts, goals, 1200, R, policy_period=4, progress=False)
    nominal, _ = run_episode(DoubleIntegratorBackend(DYN, 0.0025), policy.nominal, starts, goals, 1200, R, policy_period=4, progress=False)
    # measured: 0.49-0.50 m filtered, 0.30 m for the nominal actor alone (it dodges by itself)
    assert not res.collided.any() and res.min_separation.min() > 0.4
    assert res.min_separation.min() > nominal.min_separation.min() + 0.1
    assert policy.filter.stats.fallback > 0  # the safest-control switch acted
    # the same filter behind the PD controller, which alone collides head-on (measured: 0.49 m apart)
    pd = SafetyFilteredPolicy(NominalPD(DYN, kp=6.0, kd=4.9), policy.filter)
    res, _ = run_episode(DoubleIntegratorBackend(DYN, 0.0025), pd, starts, goals, 1200, R, policy_period=4, progress=False)
    alone, _ = run_episode(DoubleIntegratorBackend(DYN, 0.0025), pd.nominal, starts, goals, 1200, R, policy_period=4, progress=False)
    assert alone.collided.all() and not res.collided.any() and res.min_separation.min() > 0.3
