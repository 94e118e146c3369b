"""Closed-loop episode: one policy, one backend, all scenarios × agents at once."""

from __future__ import annotations

import time

import torch
from tqdm.auto import tqdm

from madpinn.dynamics.agent_model import Bound
from madpinn.simulation.backend import SimBackend
from madpinn.simulation.recorder import EpisodeRecorder, EpisodeResult


def run_episode(
    backend: SimBackend,
    policy,
    starts: torch.Tensor,
    goals: torch.Tensor,
    n_steps: int,
    collision_radius: Bound,
    policy_period: int = 1,
    record_every: int = 0,
    progress: bool = True,
    desc: str = "episode",
    horizon_steps: tuple[int, ...] = (),
) -> tuple[EpisodeResult, dict]:
    """Simulate ``n_steps`` steps of ``backend.dt`` from rest at ``starts`` ``[S, N, d]``.

    The policy (``reset(state, goals)``, ``act(state, goals, t) -> accel [S, N, m]``) is queried
    every ``policy_period`` simulation steps. ``collision_radius``: r (m) or one per agent;
    ``horizon_steps``: steps at which the cost so far is also kept (``EpisodeResult.cost_at``). The
    state layout (d, positions) is the backend's agent model's (``backend.dynamics``).
    Returns the episode result and timing statistics.
    """
    agent = backend.dynamics
    d = agent.position_dim
    if starts.shape != goals.shape or starts.dim() != 3 or starts.shape[-1] != d:
        raise ValueError(f"starts and goals must both be [S, N, {d}], got {tuple(starts.shape)} and {tuple(goals.shape)}")
    if n_steps < 1 or policy_period < 1:
        raise ValueError("n_steps and policy_period must be ≥ 1")
    dt = backend.dt
    state = backend.reset(starts, torch.zeros_like(starts))
    policy.reset(state, goals)
    rec = EpisodeRecorder(goals, dt, collision_radius, record_every, horizon_steps)
    rec.update(agent.position(state), agent.velocity(state))
    policy_time = 0.0
    t0 = time.perf_counter()
    with torch.no_grad():
        for k in tqdm(range(n_steps), desc=desc, disable=not progress, mininterval=2.0, leave=False):
            if k % policy_period == 0:
                tp = time.perf_counter()
                accel = policy.act(state, goals, k * dt)
                policy_time += time.perf_counter() - tp
                backend.command(accel, policy_period * dt)
            state = backend.step()
            rec.update(agent.position(state), agent.velocity(state))
    wall = time.perf_counter() - t0
    result = rec.finish(agent.position(state))
    S, N, _ = starts.shape
    stats = {
        "wall_s": wall,
        "policy_s": policy_time,
        "steps": n_steps,
        "us_per_agent_step": 1e6 * wall / (n_steps * S * N),
    }
    return result, stats
