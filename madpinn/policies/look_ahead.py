"""Actuator-lag compensation for deployment on a lagging plant (extension, not in the paper).

A drone reaches a commanded acceleration only after its attitude loop turns the thrust vector
(≈ 35–50 ms on the simulated Crazyflie, docs/reference/mujoco.md), so the state the policy measures is
already stale when its command takes effect. With look-ahead τ, each agent's observation is built
from its own state predicted τ seconds ahead under its last command (the double integrator,
constant acceleration) and every other agent's state predicted τ ahead at constant velocity
(an agent knows its own command, not the others'). τ = 0 is the paper's policy.

The observation itself is :func:`madpinn.observation.build_observation`, unchanged: the two
predictions are stacked as ``2N`` agents (own predictions first, the others' after) with the
neighbour indices pointing into the second half, and the first ``N`` rows are kept.
"""

from __future__ import annotations

import torch

from madpinn.dynamics import AgentModel
from madpinn.dynamics.double_integrator import hold_step
from madpinn.observation import ObservationSettings, build_observation


def predict_states(state: torch.Tensor, accel: torch.Tensor | None, horizon: float, agent: type[AgentModel]) -> torch.Tensor:
    """Double-integrator prediction (:func:`hold_step`, no saturation) of ``state`` ``[..., n]``
    (m, m/s; ``agent``'s layout) ``horizon`` seconds ahead under the constant acceleration
    ``accel`` ``[..., d]`` (m/s²; None: constant velocity)."""
    p, v = agent.position(state), agent.velocity(state)
    return agent.join(*hold_step(p, v, torch.zeros_like(v) if accel is None else accel, horizon))


def observation_with_own_state(
    own: torch.Tensor, others: torch.Tensor, goals: torch.Tensor, neighbours: torch.Tensor, spec: ObservationSettings
) -> torch.Tensor:
    """Observations ``[S, N, D]`` in which agent i sees itself at ``own[:, i]`` and its neighbours
    at ``others`` (both ``[S, N, 2d]``); goals ``[S, N, d]``, neighbour indices ``[S, N, n]``
    (−1 = phantom). ``own = others`` gives ``build_observation(others, …)`` exactly."""
    if own.shape != others.shape:
        raise ValueError(f"own and others must have the same shape, got {tuple(own.shape)} and {tuple(others.shape)}")
    N = own.shape[1]
    shifted = torch.where(neighbours >= 0, neighbours + N, neighbours)
    obs = build_observation(torch.cat([own, others], dim=1), torch.cat([goals, goals], dim=1),
                            torch.cat([shifted, shifted], dim=1), spec)
    return obs[:, :N]


def look_ahead_observation(
    state: torch.Tensor, last_command: torch.Tensor | None, goals: torch.Tensor, neighbours: torch.Tensor,
    spec: ObservationSettings, horizon: float,
) -> torch.Tensor:
    """Observations ``[S, N, D]`` τ = ``horizon`` s ahead: own state under ``last_command``
    ``[S, N, d]`` (None, e.g. at the first step: zero acceleration), the others' at constant
    velocity."""
    agent = spec.agent
    accel = torch.zeros_like(agent.velocity(state)) if last_command is None else last_command
    return observation_with_own_state(predict_states(state, accel, horizon, agent), predict_states(state, None, horizon, agent),
                                      goals, neighbours, spec)
