"""DEF-MARL epigraph pieces: z sampling and dynamics, constraint h, discounted-max and
λ-return targets, the deployment-time root finder."""

import math

import pytest
import torch

from madpinn.marl.defmarl.epigraph import (
    EpigraphSettings, collision_constraint, discounted_max_return, epigraph_lambda_returns, epigraph_value, sample_z, update_z,
)
from madpinn.marl.defmarl.root import smallest_safe_z, team_budget
from settings_helpers import epigraph_settings


def test_discounted_max_target_on_hand_built_sequence():
    h = torch.tensor([-1.0, 0.5, -0.5])
    g = 0.9
    v = discounted_max_return(h, torch.tensor(-1.0), g)
    v2 = max(-0.5, 0.1 * -0.5 + g * -1.0)
    v1 = max(0.5, 0.1 * 0.5 + g * v2)
    v0 = max(-1.0, 0.1 * -1.0 + g * v1)
    assert torch.allclose(v, torch.tensor([v0, v1, v2]))
    assert v0 == pytest.approx(0.35)  # a later violation shows up earlier, discounted towards h_t
    # γ → 1: the running maximum of h
    assert torch.allclose(discounted_max_return(h, torch.tensor(-1.0), 1.0), torch.tensor([0.5, 0.5, -0.5]))


def _episode(T=5, E=2, N=3, seed=0):
    g = torch.Generator().manual_seed(seed)
    h = torch.rand(T, E, N, generator=g) * 2 - 1
    cost = torch.rand(T, E, generator=g)
    z = torch.rand(T, E, generator=g) * 3 - 1
    vh = torch.rand(T + 1, E, N, generator=g) * 2 - 1
    vl = torch.rand(T + 1, E, generator=g) * 2
    return h, cost, z, vh, vl


def test_lambda_returns_limits():
    h, cost, z, vh, vl = _episode()
    T, gm = h.shape[0], 0.9
    # λ = 0: one-step backups on the critics
    qh, ql, q = epigraph_lambda_returns(h, cost, z, vh, vl, gm, 0.0)
    qh1 = torch.maximum(h, (1 - gm) * h + gm * vh[1:])
    ql1 = cost + gm * vl[1:]
    assert torch.allclose(qh, qh1) and torch.allclose(ql, ql1)
    assert torch.allclose(q, epigraph_value(qh1, ql1, z))
    # λ = 1: full-episode backups bootstrapped at T only
    qh, ql, q = epigraph_lambda_returns(h, cost, z, vh, vl, gm, 1.0)
    mc_h = discounted_max_return(h, vh[T], gm)
    mc_l = torch.stack([sum(gm**k * cost[t + k] for k in range(T - t)) + gm ** (T - t) * vl[T] for t in range(T)])
    assert torch.allclose(qh, mc_h) and torch.allclose(ql, mc_l, atol=1e-6)
    assert torch.allclose(q, epigraph_value(mc_h, mc_l, z), atol=1e-6)


def test_lambda_returns_mix_n_step_backups():
    h, cost, z, vh, vl = _episode(T=4, E=1, N=1)
    gm, lam = 0.8, 0.6
    qh, ql, q = epigraph_lambda_returns(h, cost, z, vh, vl, gm, lam)
    T, t = 4, 1  # check t = 1 by hand: backups of n = 1, 2, 3 steps
    nh, nl = [], []
    for n in (1, 2, 3):
        vh_n, vl_n = vh[t + n], vl[t + n]
        for s in range(t + n - 1, t - 1, -1):
            vh_n = torch.maximum(h[s], (1 - gm) * h[s] + gm * vh_n)
            vl_n = cost[s] + gm * vl_n
        nh.append(vh_n)
        nl.append(vl_n)
    w = [(1 - lam), (1 - lam) * lam, lam**2]
    assert torch.allclose(qh[t], sum(wi * x for wi, x in zip(w, nh)))
    assert torch.allclose(ql[t], sum(wi * x for wi, x in zip(w, nl)))
    assert torch.allclose(q[t], sum(wi * epigraph_value(a, b, z[t]) for wi, a, b in zip(w, nh, nl)))
    with pytest.raises(ValueError, match="shape mismatch"):
        epigraph_lambda_returns(h, cost, z, vh[:-1], vl, gm, lam)


def test_z_sampling_and_dynamics():
    cfg = EpigraphSettings(z_min=-1.0, z_max=2.0, end_mass=0.4, h_clip=0.2, cost_lr=1e-3, h_margin=0.5)
    z = sample_z(20000, cfg, torch.Generator().manual_seed(0))
    assert z.min() >= -1.0 and z.max() <= 2.0
    assert (z == -1.0).float().mean().item() == pytest.approx(0.2, abs=0.02)
    assert (z == 2.0).float().mean().item() == pytest.approx(0.2, abs=0.02)
    inner = z[(z > -1.0) & (z < 2.0)]
    assert inner.mean().item() == pytest.approx(0.5, abs=0.05)  # uniform in between
    assert torch.equal(sample_z(10, cfg, torch.Generator().manual_seed(3)), sample_z(10, cfg, torch.Generator().manual_seed(3)))
    # z' = z − l, clipped to the range
    out = update_z(torch.tensor([1.0, 0.0, 1.5]), torch.tensor([0.25, 2.0, -1.0]), cfg)
    assert torch.allclose(out, torch.tensor([0.75, -1.0, 2.0]))
    with pytest.raises(ValueError):
        epigraph_settings(z_min=1.0, z_max=1.0)


def test_collision_constraint():
    h = collision_constraint(torch.tensor([math.inf, 0.5, 0.1, 0.05, 0.0]), radius=0.1, h_clip=0.2)
    assert torch.allclose(h, torch.tensor([-1.0, -1.0, 0.0, 0.25, 0.5]))
    assert ((h > 0) == torch.tensor([False, False, False, True, True])).all()  # h > 0 ⇔ separation < r


def test_collision_constraint_margin_separates_contact_from_collision():
    # public def-marl's cost margin: safe h in [−1, −m], a collision h > m, graded in between
    sep = torch.tensor([math.inf, 0.3, 0.2, 0.1, 0.0999, 0.05, 0.0])
    h = collision_constraint(sep, radius=0.1, h_clip=0.2, margin=0.5)
    assert torch.allclose(h, torch.tensor([-1.0, -1.0, -0.75, -0.5, 0.50025, 0.625, 0.75]), atol=1e-5)
    assert h[4] - h[3] > 0.99  # a grazing collision is a full unit above contact
    assert ((h > 0) == (sep < 0.1)).all()
    with pytest.raises(ValueError):
        epigraph_settings(h_margin=1.0)


def test_root_finder_smallest_safe_z_and_fallbacks():
    # synthetic monotone critics V_h(z) = c·(a − z): safe from z = a on
    a = torch.tensor([-0.5, 0.3, 1.7, -5.0, 9.0, 0.0])
    c = torch.tensor([1.0, 2.0, 0.5, 1.0, 1.0, 3.0])
    calls = []

    def vh(z):
        calls.append(z.clone())
        return c * (a - z)

    res = smallest_safe_z(vh, 6, z_min=-2.0, z_max=3.0, iterations=20)
    tol = 5.0 / 2**20
    for i in (0, 1, 2, 5):
        assert a[i] <= res.z[i] <= a[i] + tol  # smallest safe z (bracketed from the safe side)
        assert vh(res.z[i:i + 1].expand(6))[i] <= 0
    assert res.z[3] == -2.0 and res.all_safe[3] and not res.none_safe[3]  # safe everywhere → z_min
    assert res.z[4] == 3.0 and res.none_safe[4] and not res.all_safe[4]  # never safe → z_max
    assert not res.all_safe[[0, 1, 2, 5]].any() and not res.none_safe[[0, 1, 2, 5]].any()
    assert len(calls) == 2 + 20 + 4  # two bracket ends + 20 bisections (+ the checks above)
    # a stricter safety level asks for a larger budget
    strict = smallest_safe_z(vh, 6, -2.0, 3.0, 20, level=-0.5)
    assert (strict.z[[0, 1, 2]] > res.z[[0, 1, 2]]).all()
    # the team uses its agents' maximum
    zt = team_budget(torch.tensor([[0.1, 0.7, -1.0], [2.0, 0.0, 0.0]]))
    assert torch.equal(zt, torch.tensor([[0.7, 0.7, 0.7], [2.0, 2.0, 2.0]]))
    with pytest.raises(ValueError):
        smallest_safe_z(vh, 6, 1.0, 0.0)


def test_z_consensus_over_the_communication_graph():
    """``graph``: max-consensus to its fixed point = the maximum over each connected component of
    the agents within the radius (a chain relays it); ``global``: over all; ``none``: own z."""
    from madpinn.marl.defmarl.root import agree, graph_budget

    # two components: a chain 0-1-2 (0.8 m links, 0 and 2 are 1.6 m apart) and a pair 3-4
    pos = torch.tensor([[[0.0, 0.0], [0.8, 0.0], [1.6, 0.0], [5.0, 5.0], [5.5, 5.0]]])
    z = torch.tensor([[2.0, -1.0, -2.0, 0.5, -0.5]])
    assert graph_budget(z, pos, 1.0).tolist() == [[2.0, 2.0, 2.0, 0.5, 0.5]]
    assert agree(z, pos, 1.0, "global").tolist() == [[2.0] * 5]
    assert agree(z, pos, 1.0, "none").tolist() == z.tolist()
    assert graph_budget(z, pos, 10.0).tolist() == [[2.0] * 5]   # connected: the global maximum
    assert graph_budget(z, pos, 0.1).tolist() == z.tolist()     # isolated agents keep their own
    with pytest.raises(ValueError, match="consensus"):
        agree(z, pos, 1.0, "mean")
