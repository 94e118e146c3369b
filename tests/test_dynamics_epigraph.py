"""Epigraph (n+1)-agent system: kinematics, closed-form Hamiltonian and control vs brute force."""

import itertools

import pytest
import torch

from madpinn.value_functions.epigraph import EpigraphSystem
from madpinn.observation import build_observation, constraint, running_cost, terminal_cost
from settings_helpers import observation_settings

SPEC = observation_settings()


def system():
    return EpigraphSystem(SPEC, u_max=4.0, v_max=4.0, horizon=0.2, z_max=EpigraphSystem.default_z_max(SPEC, 4.0, 4.0, 0.2),
                          velocity_saturation=False)


def test_layout_and_bounds():
    sy = system()
    assert sy.obs_dim == 16 and sy.state_dim == 17
    assert sy.velocity_index().tolist() == [[0, 1], [6, 7], [12, 13]]
    obs, z = sy.sample(4096, torch.Generator().manual_seed(0))
    hw = sy.half_widths().float()
    assert (obs.abs() <= hw + 1e-6).all() and (z >= 0).all() and (z <= sy.z_max).all()
    # every coordinate range is used
    assert (obs.abs().amax(0) > 0.95 * hw).all()


def test_z_max_bounds_the_cost_over_the_horizon():
    sy = system()
    obs, _ = sy.sample(20000, torch.Generator().manual_seed(1), dtype=torch.float64)
    # cost of a trajectory is at most (T + 1) · max over the horizon of l_d; l_d grows at most by the displacement
    bound = (1 + sy.horizon) * (running_cost(obs, 2) + 3 * 2**0.5 * (sy.v_max * sy.horizon + 0.5 * sy.u_max * sy.horizon**2))
    assert bound.max() <= sy.z_max + 1e-9


def test_transport_matches_global_double_integrators():
    """f(obs, u) equals the time derivative of the observation of the moving global state."""
    torch.manual_seed(0)
    S = 64
    pos = 0.4 * torch.rand(S, 3, 2) - 0.2
    vel = 8 * torch.rand(S, 3, 2) - 4
    goals = 0.8 * torch.rand(S, 3, 2) - 0.4
    u = 8 * torch.rand(S, 3, 2) - 4
    nbrs = torch.tensor([[1, 2], [0, 2], [0, 1]]).expand(S, 3, 2)
    state = torch.cat([pos, vel], -1).double()
    goals, u = goals.double(), u.double()
    sy = system()
    obs = build_observation(state, goals, nbrs, SPEC)[:, 0]
    # the ego's own control u_0 and its neighbours' controls u_1, u_2 in the observation order
    do, dz = sy.f(obs, torch.zeros(S, dtype=obs.dtype), u)
    eps = 1e-6
    state2 = state + eps * torch.cat([vel.double(), u], -1)
    fd = (build_observation(state2, goals, nbrs, SPEC)[:, 0] - obs) / eps
    assert torch.allclose(do, fd, atol=1e-5)
    assert torch.allclose(dz, -running_cost(obs, 2))


def test_terminal_value_and_grad():
    sy = system()
    obs, z = sy.sample(256, torch.Generator().manual_seed(2), dtype=torch.float64)
    val, go, gz = sy.terminal_value_and_grad(obs, z)
    expect = torch.maximum(terminal_cost(obs, 2) - z, constraint(obs, 2, 0.1))
    assert torch.equal(val, expect)
    eps = 1e-7
    for k in (2, 4, 9, 14):
        o2 = obs.clone()
        o2[:, k] += eps
        fd = (sy.terminal_value(o2, z) - val) / eps
        assert torch.allclose(go[:, k], fd, atol=1e-4)
    assert set(gz.unique().tolist()) <= {-1.0, 0.0}


@pytest.mark.parametrize("seed", [0, 1])
def test_hamiltonian_and_control_match_brute_force(seed):
    """min over a control grid (per axis 5 points, corners included) of ⟨∇V, f̂⟩ for all 3 agents."""
    sy = system()
    g = torch.Generator().manual_seed(seed)
    B = 32
    obs, z = sy.sample(B, g, dtype=torch.float64)
    dv_do = torch.randn(B, sy.obs_dim, generator=g, dtype=torch.float64)
    dv_dz = torch.rand(B, generator=g, dtype=torch.float64)
    grid = torch.linspace(-sy.u_max, sy.u_max, 5, dtype=torch.float64)
    combos = torch.tensor(list(itertools.product(grid.tolist(), repeat=6)), dtype=torch.float64).reshape(-1, 3, 2)
    K = combos.shape[0]
    o = obs.repeat_interleave(K, 0)
    u = combos.repeat(B, 1, 1)
    do, dz = sy.f(o, z.repeat_interleave(K), u)
    inner = (dv_do.repeat_interleave(K, 0) * do).sum(-1) + dv_dz.repeat_interleave(K) * dz
    brute = inner.reshape(B, K).min(1).values
    assert torch.allclose(sy.hamiltonian(obs, dv_do, dv_dz), brute, atol=1e-9)
    ustar = sy.optimal_control(dv_do)
    do, dz = sy.f(obs, z, ustar)
    assert torch.allclose((dv_do * do).sum(-1) + dv_dz * dz, brute, atol=1e-9)


def test_residual_is_the_papers_min():
    sy = system()
    obs, z = sy.sample(64, torch.Generator().manual_seed(3), dtype=torch.float64)
    v = torch.randn(64, dtype=torch.float64)
    dvdt = torch.randn(64, dtype=torch.float64)
    go = torch.randn(64, 16, dtype=torch.float64)
    gz = torch.randn(64, dtype=torch.float64)
    r = sy.hjb_residual(obs, z, v, dvdt, go, gz)
    expect = torch.minimum(-dvdt - sy.hamiltonian(obs, go, gz), v - constraint(obs, 2, 0.1))
    assert torch.equal(r, expect)


# --- issue 14: velocity saturation as an option of V̂'s dynamics -------------------------------

def test_velocity_saturation_removes_outward_control_from_hamiltonian_and_control():
    from dataclasses import replace

    free, sat = system(), replace(system(), velocity_saturation=True)
    gen = torch.Generator().manual_seed(100)
    obs, z = free.sample(2048, gen, dtype=torch.float64)
    vidx = free.velocity_index().flatten()
    # half of the samples: some velocity coordinates pinned at ±v_max
    pin = torch.rand(2048, vidx.numel(), generator=gen, dtype=torch.float64) < 0.3
    signs = torch.where(torch.rand(2048, vidx.numel(), generator=gen, dtype=torch.float64) < 0.5, -1.0, 1.0)
    obs[:, vidx] = torch.where(pin, 4.0 * signs, obs[:, vidx].clamp(-3.99, 3.99))
    grad = torch.randn(2048, free.obs_dim, generator=gen, dtype=torch.float64)
    dz = torch.rand(2048, generator=gen, dtype=torch.float64)
    h_free, h_sat = free.hamiltonian(obs, grad, dz), sat.hamiltonian(obs, grad, dz)
    # less control authority: the minimum can only rise; unchanged where nothing is pinned
    assert (h_sat >= h_free - 1e-12).all()
    none_pinned = ~pin.any(-1)
    assert torch.allclose(h_sat[none_pinned], h_free[none_pinned])
    assert (h_sat[pin.any(-1)] > h_free[pin.any(-1)] + 1e-9).any()
    # the closed form is attained by the optimal control through the saturated dynamics ...
    u = sat.optimal_control(grad, obs)
    do, dzdt = sat.f(obs, z, u)
    assert torch.allclose((grad * do).sum(-1) + dz * dzdt, h_sat, atol=1e-9)
    # ... and no corner control does better (brute force over 2^6 bang-bang choices on 256 rows)
    rows = slice(0, 256)
    best = torch.full((256,), float("inf"), dtype=torch.float64)
    for corner in itertools.product((-4.0, 4.0), repeat=6):
        uc = torch.tensor(corner, dtype=torch.float64).reshape(1, 3, 2).expand(256, 3, 2)
        do_c, dz_c = sat.f(obs[rows], z[rows], uc)
        best = torch.minimum(best, (grad[rows] * do_c).sum(-1) + dz[rows] * dz_c)
    assert torch.allclose(best, h_sat[rows], atol=1e-9)
    # the optimal control never pushes a pinned velocity further out
    v = obs[:, vidx].reshape(2048, 3, 2)
    assert not (((v >= 4.0) & (u > 0)) | ((v <= -4.0) & (u < 0))).any()
    with pytest.raises(ValueError, match="observation"):
        sat.optimal_control(grad)


def test_velocity_saturation_is_off_by_default_and_read_from_the_config(paper_cfg):
    import copy

    assert EpigraphSystem.from_config(paper_cfg).velocity_saturation is False
    cfg = copy.deepcopy(paper_cfg)
    cfg["value_functions"]["vhat"]["velocity_saturation"] = True
    assert EpigraphSystem.from_config(cfg).velocity_saturation is True
