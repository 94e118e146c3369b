"""DEF-MARL training on the shared PPO trainer (:class:`madpinn.marl.trainer.PPOTrainer`).

What the subclass changes, through the trainer's extension points:

- the budget z is an extra actor/critic input (``extra_features = 1``): ``π(a | o_i, z)`` and
  the per-agent constraint critic ``V_h(o_i, z)`` (the trainer's critic, one head);
- ``on_reset`` samples z per environment (:func:`epigraph.sample_z`), ``record`` applies
  ``z' = z − l`` and stores the constraint h and the team cost l of every period;
- ``advantages`` computes the Dec-EFOCP λ-returns (discounted-max targets for V_h, cost targets
  for V_l, total Q) and the epigraph advantage ``max(max V_h, V_l − z) − Q`` per agent;
- the centralised team cost critic ``V_l(x, z)`` (:class:`critics.TeamCostCritic`) is fitted
  after each PPO update on whole-team minibatches.

The PPO update itself (clipped surrogate on the epigraph advantage, V_h regression, entropy,
gradient clipping, NaN guard) is the shared :func:`madpinn.marl.ppo.ppo_update`.
"""

from __future__ import annotations

from typing import Sequence

import torch
from torch import nn

from madpinn.marl.buffer import RolloutBuffer
from madpinn.marl.defmarl.critics import TeamCostCritic, team_rows
from madpinn.marl.defmarl.epigraph import (
    EpigraphSettings, collision_constraint, epigraph_lambda_returns, epigraph_value, sample_z, update_z,
)
from madpinn.marl.env import GoalReachingEnv, RewardSettings, StepInfo, goal_reward
from madpinn.marl.features import EGO_FEATURES, NEIGHBOUR_FEATURES, LocalObs
from madpinn.marl.networks import DEFAULT_ENCODER
from madpinn.marl.ppo import PPOSettings
from madpinn.marl.trainer import PPOTrainer


def _cat_obs(a: LocalObs, b: LocalObs) -> LocalObs:
    return LocalObs(torch.cat([a.ego, b.ego]), torch.cat([a.neighbours, b.neighbours]), torch.cat([a.mask, b.mask]))


class DefMarlTrainer(PPOTrainer):
    extra_features = 1  # z
    critic_heads = 1  # V_h(o_i, z)

    def __init__(
        self, env: GoalReachingEnv, ppo: PPOSettings, reward: RewardSettings, agent_counts: Sequence[int], hidden: int,
        seed: int, epigraph: EpigraphSettings, encoder: str = DEFAULT_ENCODER,
    ):
        if reward.collision != 0.0:
            raise ValueError(
                f"DEF-MARL treats collisions as the constraint h, not as a cost: set reward.collision to 0 (got {reward.collision})"
            )
        super().__init__(env, ppo, reward, agent_counts, hidden, seed, encoder)
        self.epi = epigraph
        self.radius = float(env.obs_spec.collision_radius)
        self.cost_critic = TeamCostCritic(EGO_FEATURES + 1, NEIGHBOUR_FEATURES, self.hidden, self.encoder).to(self.device, env.dtype)
        self.cost_optimizer = torch.optim.Adam(self.cost_critic.parameters(), lr=epigraph.cost_lr, eps=1e-5)
        self.fixed_z: float | None = None  # evaluation: start every episode at this budget
        self.z: torch.Tensor | None = None

    def extra_modules(self) -> dict[str, nn.Module]:
        return {"cost_critic": self.cost_critic}

    def extra_optimizers(self) -> dict[str, torch.optim.Optimizer]:
        return {"cost": self.cost_optimizer}

    # ---- per-episode epigraph state -----------------------------------------------------------
    def on_reset(self, n_envs: int, n_agents: int) -> None:
        if self.fixed_z is None:
            z = sample_z(n_envs, self.epi, self.generator, self.env.dtype)
        else:
            z = torch.full((n_envs,), float(self.fixed_z), dtype=self.env.dtype)
        self.z = z.to(self.device)
        self._z, self._h, self._cost = [], [], []

    def augment(self, obs: LocalObs) -> LocalObs:
        E, N = obs.mask.shape[:2]
        return obs.with_extra(self.z.view(E, 1, 1).expand(E, N, 1).to(obs.ego.dtype))

    def reward(self, info: StepInfo) -> torch.Tensor:
        """−(per-agent cost) ``[E, N]``: the goal reward without a collision term."""
        self._last_reward = goal_reward(info, self.reward_cfg, self.env.cfg.train_dt, self.u_max)
        return self._last_reward

    def record(self, info: StepInfo) -> None:
        cost = -self._last_reward.mean(-1)  # team cost l [E]
        self._z.append(self.z)
        self._h.append(collision_constraint(info.min_sep, self.radius, self.epi.h_clip, self.epi.h_margin))
        self._cost.append(cost)
        self.z = update_z(self.z, cost, self.epi)

    def episode_tensors(self) -> tuple[torch.Tensor, torch.Tensor, torch.Tensor]:
        """h ``[T, E, N]``, team cost ``[T, E]``, z ``[T, E]`` of the last episode."""
        return torch.stack(self._h), torch.stack(self._cost), torch.stack(self._z)

    def episode_statistics(self) -> dict:
        """Constraint-violation rate (agent-periods with h > 0), z statistics, team cost and the
        undiscounted epigraph objective ``max(max_{t,i} h, Σ_t l − z_0)`` (mean over envs)."""
        h, cost, z = self.episode_tensors()
        total = cost.sum(0)
        objective = torch.maximum(h.amax(dim=(0, 2)), total - z[0])
        return {
            "violation_rate": (h > 0).float().mean().item(),
            "team_cost": total.mean().item(),
            "epigraph_objective": objective.mean().item(),
            "z_start_mean": z[0].mean().item(),
            "z_end_mean": self.z.mean().item(),
            "z_end_at_min": (self.z <= self.epi.z_min).float().mean().item(),
        }

    # ---- training -----------------------------------------------------------------------------
    def collect(self, n_agents: int):
        buf, last, stats = super().collect(n_agents)
        self._final_obs = self.obs_norm(self.augment(self.env.observe())).flatten()
        stats.update(self.episode_statistics())
        return buf, last, stats

    def advantages(self, buf: RolloutBuffer, last_values: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor]:
        h, cost, z = self.episode_tensors()
        T, E, N = h.shape
        vh = torch.cat([buf.get("value")[..., 0], last_values[..., 0].unsqueeze(0)])  # [T+1, E, N]
        obs = buf.flat_obs()
        with torch.no_grad():
            vl = self.cost_critic(_cat_obs(obs, self._final_obs), N).view(T + 1, E)
        qh, ql, q = epigraph_lambda_returns(h, cost, z, vh, vl, self.ppo.discount, self.ppo.gae_lambda)
        adv = epigraph_value(vh[:-1], vl[:-1], z) - q  # a cost: positive = better than expected
        self._cost_batch = (obs, ql.reshape(-1), N)
        self._value_stats = {"vh_mean": vh[:-1].mean().item(), "vl_mean": vl[:-1].mean().item(),
                             "q_mean": q.mean().item()}
        return adv, qh.unsqueeze(-1)

    def update_cost_critic(self) -> dict:
        """Fit ``V_l(x, z)`` to the cost λ-returns on shuffled whole-team minibatches."""
        obs, target, N = self._cost_batch
        G = target.shape[0]
        per_batch = max(1, self.ppo.minibatch // N)
        total, n = 0.0, 0
        for _ in range(self.ppo.epochs):
            perm = torch.randperm(G, generator=self.generator).to(target.device)
            for start in range(0, G, per_batch):
                g = perm[start : start + per_batch]
                loss = ((self.cost_critic(obs.index(team_rows(g, N)), N) - target[g]) ** 2).mean()
                if not torch.isfinite(loss):
                    raise FloatingPointError(f"non-finite DEF-MARL cost-critic loss at iteration {self.iteration}; lower methods.defmarl.epigraph.cost_lr")
                self.cost_optimizer.zero_grad(set_to_none=True)
                loss.backward()
                nn.utils.clip_grad_norm_(self.cost_critic.parameters(), self.ppo.max_grad_norm)
                self.cost_optimizer.step()
                total += loss.item()
                n += 1
        return {"loss_cost": total / max(n, 1)}

    def step(self) -> dict:
        stats = super().step()  # rollout, epigraph advantages, shared PPO update of actor and V_h
        stats.update(self._value_stats)
        stats.update(self.update_cost_critic())
        return stats

    # ---- evaluation ---------------------------------------------------------------------------
    @torch.no_grad()
    def evaluate_epigraph(self, n_envs: int, n_agents: int, z: float, scenario_seed: int = 2 * 10**6) -> dict:
        """Deterministic episodes on a fixed scenario set, every team starting at budget ``z``."""
        self.fixed_z = float(z)
        try:
            out = self.evaluate(n_envs, n_agents, scenario_seed)
            out.update(self.episode_statistics())
        finally:
            self.fixed_z = None
        return out
