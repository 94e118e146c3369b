"""Scenario-based verification of V̂ (issue 15; the paper's stated future work).

For ``N`` i.i.d. 3-agent states that V̂ calls safe at the budget ``z*`` (``V̂(0, o, z*) ≤ 0``,
drawn by rejection from a sampling distribution; ``z*`` from the deployed policy's cold search on
its grid, :mod:`.z_search` with ``methods.madpinn.z_tolerance``, so the certified budgets are the
deployed ones, to the deployed tolerance), every observed agent follows the V̂ policy
``u_a = −u_max·sign(∂V̂/∂v_a)(τ, o(τ), z(τ))`` re-evaluated every ``dt`` over the horizon
``[0, T]`` in the exact dynamics of V̂'s model (planar double integrators, exact zero-order-hold
steps, no velocity clipping; ``ż = −l_d``). A *safety violation* is a pair closer than the
collision radius at any time (checked at ``substeps`` points per step); a *budget violation* a
final ``φ_d > z(T)`` (cost above the promised budget). With ``k`` violations out of ``N``, the
scenario approach (Campi & Garatti; DeepReach's verification; the conformal work the paper cites)
gives: with confidence ``1 − β`` the violation probability is at most ``ε``, where ``ε`` is the
one-sided Clopper–Pearson bound ``P[Bin(N, ε) ≤ k] = β``.
"""

from __future__ import annotations

from dataclasses import dataclass

import torch

from madpinn.dynamics.double_integrator import hold_step
from madpinn.observation import join_observation, split_observation
from madpinn.value_functions.sampling import ConflictSamplingSettings, place_conflicts
from madpinn.value_functions.z_search import min_feasible_z


@dataclass(frozen=True)
class ScenarioSettings:
    """samples: N accepted (V̂-safe) states per distribution; dt: control period (s); substeps:
    collision checks per step; seed: validation seed (≥ 100, never the protocol seeds 0–4);
    betas: confidence parameters β; conflict_radius: ρ (m) of the conflict distribution;
    max_draws_factor: give up after drawing this many × samples candidates."""

    samples: int
    dt: float
    substeps: int
    seed: int
    betas: tuple
    conflict_radius: float
    max_draws_factor: int = 50   # not a config key

    def __post_init__(self):
        if self.samples < 1 or self.dt <= 0 or self.substeps < 1:
            raise ValueError("scenario verification needs samples ≥ 1, dt > 0 and substeps ≥ 1")
        if self.seed < 100:
            raise ValueError(f"scenario verification runs on validation seeds (≥ 100), got {self.seed}")
        if not all(0.0 < b < 1.0 for b in self.betas):
            raise ValueError(f"every β must lie in (0, 1), got {self.betas}")

    @classmethod
    def from_config(cls, d: dict) -> "ScenarioSettings":
        d = dict(d)
        if "betas" in d:
            d["betas"] = tuple(float(b) for b in d["betas"])
        return cls(**d)


def epsilon_bound(violations: int, samples: int, beta: float) -> float:
    """Smallest ε with ``P[Bin(N, ε) ≤ k] ≤ β`` (one-sided Clopper–Pearson upper bound): with
    confidence ``1 − β`` the violation probability is ≤ ε. ``k = N`` gives 1."""
    from scipy.stats import beta as beta_dist

    if not 0 <= violations <= samples:
        raise ValueError(f"violations must lie in [0, samples], got {violations} of {samples}")
    if violations == samples:
        return 1.0
    return float(beta_dist.ppf(1.0 - beta, violations + 1, samples - violations))


def verification_sampling(conflict: bool, radius: float) -> ConflictSamplingSettings:
    """The verification's distribution: uniform over V̂'s domain, or (``conflict``) every state with
    one pair on a near-collision course reaching the disk of ``radius`` (m) within the horizon."""
    return ConflictSamplingSettings(fraction=1.0 if conflict else 0.0, radius=radius, tau=(0.0, 1.0), closing_speed=None)


def draw_states(system, n: int, sampling: ConflictSamplingSettings, generator: torch.Generator, dtype) -> torch.Tensor:
    """``n`` observations ``[n, D]`` uniform over V̂'s domain, rewritten by ``sampling``
    (:func:`verification_sampling`)."""
    obs, _ = system.sample(n, generator, dtype=dtype)
    return place_conflicts(obs, system.spec.n_neighbours, system.horizon, system.spec.offset_range, sampling, generator)


def draw_safe_states(vhat, n: int, conflict: ConflictSamplingSettings, generator: torch.Generator, max_draws: int,
                     z_tolerance: float):
    """Rejection sampling: ``(obs [n, D], z* [n], acceptance rate)`` of states with
    ``V̂(0, o, z*) ≤ 0`` from the uniform domain, rewritten by ``conflict`` (fraction 1: every
    state on a near-collision course); z* by the deployed search on the grid of ``z_tolerance``."""
    system = vhat.system
    p = next(vhat.net.parameters())
    kept_o, kept_z, drawn = [], [], 0
    while sum(o.shape[0] for o in kept_o) < n:
        if drawn >= max_draws:
            raise RuntimeError(f"only {sum(o.shape[0] for o in kept_o)} of {n} V̂-safe states in {drawn} draws: "
                               "V̂ calls almost nothing safe; check the model")
        b = max(1024, n)
        obs = draw_states(system, b, conflict, generator, p.dtype).to(p.device)
        z_star, feasible = min_feasible_z(vhat, obs, z_tolerance)
        kept_o.append(obs[feasible])
        kept_z.append(z_star[feasible])
        drawn += b
    accepted = sum(o.shape[0] for o in kept_o)
    obs, z = torch.cat(kept_o)[:n], torch.cat(kept_z)[:n]
    return obs, z, accepted / drawn


def _observation(pos, vel, goal):
    """Global ``[B, A, d]`` arrays -> observation relative to agent 0 ``[B, D]``."""
    return join_observation(pos - pos[:, :1], vel, goal - pos[:, :1])


@torch.no_grad()
def rollout(vhat, obs: torch.Tensor, z: torch.Tensor, dt: float, substeps: int) -> dict:
    """Closed-loop rollout of the V̂ policy over ``[0, T]`` from ``(obs [B, D], z [B])``.
    Returns ``min_distance [B]`` (m, over all pairs and times), ``final_cost [B]`` (φ_d at T),
    ``final_z [B]`` (budget left at T) and ``steps``."""
    system = vhat.system
    n = system.spec.n_neighbours
    pos, vel, goal = (a.clone() for a in split_observation(obs, n))       # ego at the origin
    steps = max(1, round(vhat.horizon / dt))
    h = vhat.horizon / steps
    iu, ju = torch.triu_indices(n + 1, n + 1, offset=1)
    fr = torch.linspace(0.0, 1.0, substeps + 1, dtype=obs.dtype, device=obs.device)[1:]
    d0 = torch.linalg.vector_norm(pos[:, iu] - pos[:, ju], dim=-1).amin(-1)
    min_d, z = d0, z.clone()
    for k in range(steps):
        o = _observation(pos, vel, goal)
        _, dv_dobs, _ = vhat.value_and_grad(o, z, k * h)
        u = system.optimal_control(dv_dobs)                                 # [B, n+1, 2]
        l0 = system.running_cost(o)
        s = fr[:, None, None, None] * h                                      # [S, 1, 1, 1]
        traj, vels = hold_step(pos[None], vel[None], u[None], s)             # [S, B, A, d] each
        d = torch.linalg.vector_norm(traj[..., iu, :] - traj[..., ju, :], dim=-1).amin(-1).amin(0)
        min_d = torch.minimum(min_d, d)
        pos, vel = traj[-1], vels[-1]                                        # s[-1] = h
        l1 = system.running_cost(_observation(pos, vel, goal))
        z = z - 0.5 * (l0 + l1) * h                                          # trapezoid of ż = −l_d
    final_cost = system.running_cost(_observation(pos, vel, goal))
    return {"min_distance": min_d, "final_cost": final_cost, "final_z": z, "steps": steps}


def verify(vhat, settings: ScenarioSettings, conflict: bool, z_tolerance: float, chunk: int = 4096) -> dict:
    """Scenario verification of ``vhat`` on the uniform (``conflict=False``) or the conflict
    distribution (every state on a near-collision course of radius ``settings.conflict_radius``),
    at the budgets of the deployed search on the grid of ``z_tolerance`` (the policy's
    ``z_tolerance``, a fraction of z_max)."""
    sampling = verification_sampling(conflict, settings.conflict_radius)
    gen = torch.Generator().manual_seed(int(settings.seed) * 7919 + (1 if conflict else 0))
    obs, z, acceptance = draw_safe_states(vhat, settings.samples, sampling, gen,
                                          settings.max_draws_factor * settings.samples, z_tolerance)
    parts = [rollout(vhat, obs[i:i + chunk], z[i:i + chunk], settings.dt, settings.substeps)
             for i in range(0, obs.shape[0], chunk)]
    min_d = torch.cat([p["min_distance"] for p in parts])
    over = torch.cat([p["final_cost"] - p["final_z"] for p in parts])
    r = vhat.system.spec.collision_radius
    unsafe = min_d < r
    budget = over > 1e-3 * vhat.z_max
    n = int(min_d.numel())
    out = {"distribution": "conflict" if conflict else "uniform", "samples": n, "acceptance_rate": acceptance,
           "dt": settings.dt, "seed": settings.seed, "z_tolerance": z_tolerance}
    for name, mask in (("safety", unsafe), ("budget", budget), ("any", unsafe | budget)):
        k = int(mask.sum())
        out[name] = {"violations": k, "rate": k / n,
                     "epsilon": {f"{b:g}": epsilon_bound(k, n, b) for b in settings.betas}}
    out["min_distance_p01"] = float(torch.quantile(min_d.double(), 0.01))
    return out
