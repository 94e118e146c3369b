"""The SafeMARL CBVF filter: pass-through far from others, constraint satisfaction against a
brute-force grid, box, head-on avoidance on the double integrator, the policy factory.

The filter accepts any pairwise value with the V_s API. Until the learned V_s (issue 3) is in
this checkout these tests use an analytic braking-distance barrier for the double integrator,
``V = d − r − max(0, −ḋ)²/(2·a)`` (a: deceleration one agent alone can apply), a valid
control barrier function in its own right; the end-to-end test with the learned V_s lives in
``test_safemarl_vs.py``.
"""

from pathlib import Path

import pytest
import torch
import yaml

from madpinn.config import deep_merge, validate_config
from madpinn.dynamics import DoubleIntegrator
from madpinn.marl.checkpoint import CheckpointError, save_checkpoint
from madpinn.marl.env import EnvSettings, GoalReachingEnv
from madpinn.marl.trainer import PPOTrainer
from madpinn.policies import PolicyContext, make_policy, policy_settings
from madpinn.policies.nominal import NominalPD
from madpinn.policies.safemarl import CBVFFilter, SafetyFilteredPolicy
from madpinn.scenarios import Arena
from madpinn.simulation import DoubleIntegratorBackend, run_episode
from settings_helpers import observation_settings, pair_system, ppo_settings, reward_settings


pytestmark = pytest.mark.usefixtures("one_thread")


U_MAX, R = 4.0, 0.1
DYN = DoubleIntegrator(U_MAX, 4.0)


class BrakingBarrier:
    """Analytic pairwise barrier with the V_s API: x = [p_i − p_j, v_i − v_j] -> V (m); ``system``
    the pair system of the planar agents (the layout the filter reads)."""

    def __init__(self, r=R, decel=U_MAX):
        self.r, self.decel = r, decel
        self.system = pair_system()

    def value(self, x, t=0.0, reuse_buffers=False):   # reuse_buffers: the learned V_s's workspace option (no network here)
        p, v = x[..., :2], x[..., 2:]
        d = p.norm(dim=-1).clamp_min(1e-9)
        closing = (-(p * v).sum(-1) / d).clamp_min(0.0)
        return d - self.r - closing**2 / (2 * self.decel)

    def value_and_grad(self, x, t=0.0, reuse_buffers=False):
        with torch.enable_grad():
            x = x.detach().requires_grad_(True)
            V = self.value(x)
            (g,) = torch.autograd.grad(V.sum(), x)
        return V.detach(), g


def _filter(gamma=5.0, k=2, threshold=-1.0):
    return CBVFFilter(BrakingBarrier(), U_MAX, gamma, k, 6, threshold, sensing_radius=1.0)


def test_nominal_passes_unchanged_far_from_others():
    state = torch.tensor([[[-0.8, -0.8, 1.0, 0.0], [0.8, 0.8, -1.0, 0.5], [0.8, -0.8, 0.0, 0.0]]])
    u_nom = torch.tensor([[[3.0, -1.0], [-2.0, 0.5], [0.0, 4.0]]])
    flt = _filter()
    assert torch.equal(flt(state, u_nom), u_nom)
    # a neighbour inside the sensing radius but moving away: the constraint is slack
    state = torch.tensor([[[0.0, 0.0, -1.0, 0.0], [0.5, 0.0, 1.0, 0.0]]])
    u_nom = torch.tensor([[[1.0, 1.0], [-1.0, 2.0]]])
    assert torch.equal(flt(state, u_nom), u_nom)


def test_filtered_control_satisfies_cbvf_rows_when_feasible_against_grid():
    gen = torch.Generator().manual_seed(0)
    S, N = 40, 4
    pos = (torch.rand(S, N, 2, generator=gen) * 2 - 1) * 0.6
    vel = (torch.rand(S, N, 2, generator=gen) * 2 - 1) * 3.0
    state = torch.cat([pos, vel], dim=-1)
    u_nom = (torch.rand(S, N, 2, generator=gen) * 2 - 1) * 6.0
    flt = _filter(k=2, threshold=-10.0)
    u = flt(state, u_nom)
    assert (u.abs() <= U_MAX).all()
    a, b, active, V, _ = flt.constraint_rows(state)
    a, b, active = a.reshape(-1, 2, 2).double(), b.reshape(-1, 2).double(), active.reshape(-1, 2)
    u, u_nom = u.reshape(-1, 2).double(), u_nom.reshape(-1, 2).clamp(-U_MAX, U_MAX).double()
    g = torch.linspace(-U_MAX, U_MAX, 161, dtype=torch.float64)
    grid = torch.cartesian_prod(g, g)
    slack = torch.einsum("gc,bkc->bgk", grid, a) - b.unsqueeze(1)
    slack = torch.where(active.unsqueeze(1), slack, torch.ones_like(slack))
    grid_ok = (slack >= 0).all(-1)  # [B, G]
    d_grid = ((grid.unsqueeze(0) - u_nom.unsqueeze(1)) ** 2).sum(-1).masked_fill(~grid_ok, float("inf")).amin(1)
    rows = torch.einsum("bc,bkc->bk", u, a) - b
    rows = torch.where(active, rows, torch.zeros_like(rows))
    feasible_cases = grid_ok.any(1)
    assert feasible_cases.sum() > 20 and (active.any(1) & feasible_cases).sum() > 20
    assert (rows[feasible_cases] >= -1e-4).all(), "filtered control violates a feasible CBVF constraint"
    d_u = ((u - u_nom) ** 2).sum(-1)
    assert (d_u[feasible_cases] <= d_grid[feasible_cases] + 1e-4).all(), "filter is farther from u_nom than a feasible grid point"
    # infeasible cases fall back to the safest control u_max·sign(∂V/∂v) of the most critical neighbour
    infeasible = ~feasible_cases & active.any(1)
    if infeasible.any():
        safest = U_MAX * torch.sign(a[:, 0])
        assert torch.allclose(u[infeasible], safest[infeasible])


def test_threshold_triggers_the_safest_control():
    state = torch.tensor([[[0.0, 0.0, 1.0, 0.0], [0.3, 0.0, -1.0, 0.0]]])
    u_nom = torch.zeros(1, 2, 2)
    u = _filter(threshold=10.0)(state, u_nom)
    assert torch.allclose(u, torch.tensor([[[-4.0, 0.0], [4.0, 0.0]]]))  # brake apart along x


def _head_on(policy, steps=800):
    starts = torch.tensor([[[-0.6, 0.01], [0.6, -0.01]]])
    goals = torch.tensor([[[0.6, 0.0], [-0.6, 0.0]]])
    res, _ = run_episode(DoubleIntegratorBackend(DYN, 0.0025), policy, starts, goals, steps, R, progress=False)
    return res


def test_head_on_agents_do_not_collide_under_the_filter():
    nominal = NominalPD(DYN, kp=6.0, kd=4.9)
    assert _head_on(SafetyFilteredPolicy(nominal, None)).collided.all()  # the nominal alone collides
    res = _head_on(SafetyFilteredPolicy(nominal, _filter()))
    assert not res.collided.any() and res.min_separation.min() > R


def _tiny_model(models_dir: Path):
    env = GoalReachingEnv(DYN, Arena("small", 1.0, 0.2), observation_settings(), EnvSettings(0.05, 1, 2), seed=0)
    ppo = ppo_settings(iterations=1, agents_per_batch=12, epochs=1, minibatch=64)
    tr = PPOTrainer(env, ppo, reward_settings(), (3,), hidden=8, seed=0)
    tr.train(progress=False)
    save_checkpoint(models_dir / "safemarl_nominal.pt", tr)


def test_unfiltered_variant_evaluates_end_to_end_and_missing_model_errors(tmp_path):
    from madpinn.commands.evaluate import evaluate

    root = Path(__file__).resolve().parents[1]
    cfg = yaml.safe_load((root / "config.yaml").read_text())
    cfg = deep_merge(cfg, yaml.safe_load((root / "workflow/configs/smoke.yaml").read_text()))
    cfg["paths"] = {"results": str(tmp_path), "figures": str(tmp_path / "figs")}
    cfg["tracking"]["enabled"] = False
    validate_config(cfg)
    ctx = PolicyContext(method=policy_settings("safemarl", cfg["methods"]["safemarl"]), dynamics=DYN, obs_spec=observation_settings(),
                        device=torch.device("cpu"), dtype=torch.float32, seed=0, sim_dt=0.0025, policy_period=1,
                        models={"nominal": tmp_path / "models" / "safemarl_nominal.pt"})
    with pytest.raises(CheckpointError, match="not found"):
        make_policy("safemarl", ctx)
    _tiny_model(tmp_path / "models")
    summary = evaluate(cfg, "main", "safemarl-unfiltered", 3, 0, tmp_path / "out.parquet", models=ctx.models,
                       progress=False, track=False)
    assert summary["n_scenarios"] == cfg["studies"]["main"]["scenarios"] and 0.0 <= summary["safety_rate"] <= 1.0
