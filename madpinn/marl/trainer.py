"""The shared multi-agent PPO loop: collect one episode per environment → advantages → update.

All agents of all environments act with one shared actor on their own local observation
(decentralised execution); the critic is shared too and sees the same local observation
(independent-learner PPO with parameter sharing, the IPPO/MAPPO setting).

Extension points for methods built on this trainer (DEF-MARL) — override in a subclass:

- ``extra_features`` / :meth:`augment`: extra per-agent actor/critic inputs (e.g. z), appended
  to the ego features before observation normalisation.
- ``critic_heads``: number of critic outputs (e.g. cost and constraint critics).
- :meth:`on_reset`, :meth:`reward`, :meth:`record`: per-episode state, the raw per-agent reward
  of a period, and per-step bookkeeping (e.g. z dynamics).
- :meth:`advantages`: advantages ``[T, E, N]`` and critic targets ``[T, E, N, H]`` from the
  rollout buffer (default: GAE on the normalised reward).
- :meth:`extra_modules`: further networks of the method (e.g. a team cost critic), saved in
  the checkpoint next to the actor and critic; :meth:`extra_optimizers`: their optimizers, saved
  in a resumable checkpoint (:meth:`training_state`).

Resuming: :meth:`training_state` / :meth:`load_training_state` carry everything besides the
weights and normalisers that the next iteration depends on (optimizer moments, the sampling
generator, torch's RNG, the scenario counters, the iteration and the history), so a run
trained in pieces ends with the uninterrupted run's weights.
"""

from __future__ import annotations

import math
import time
from typing import Callable, Sequence

import torch
from tqdm.auto import tqdm

from madpinn.marl.buffer import RolloutBuffer
from madpinn.marl.env import GoalReachingEnv, RewardSettings, StepInfo, goal_reward
from madpinn.marl.features import EGO_FEATURES, NEIGHBOUR_FEATURES, LocalObs
from madpinn.marl.gae import gae
from madpinn.marl.networks import DEFAULT_ENCODER, GaussianActor, ValueCritic
from madpinn.marl.normalize import ObsNormalizer, ReturnNormalizer
from madpinn.marl.ppo import PPOBatch, PPOSettings, ppo_update

REACHED_M = 0.05  # goal "reached" in the learning-curve statistics (m)


class PPOTrainer:
    extra_features = 0
    critic_heads = 1

    def __init__(
        self,
        env: GoalReachingEnv,
        ppo: PPOSettings,
        reward: RewardSettings,
        agent_counts: Sequence[int],
        hidden: int,
        seed: int,
        encoder: str = DEFAULT_ENCODER,
    ):
        if not agent_counts or min(agent_counts) < 1:
            raise ValueError(f"agent_counts must be non-empty positive integers, got {agent_counts}")
        self.env = env
        self.ppo = ppo
        self.reward_cfg = reward
        self.agent_counts = [int(n) for n in agent_counts]
        self.hidden = int(hidden)
        self.encoder = str(encoder)
        self.seed = int(seed)
        self.device = env.device
        self.u_max = env.dynamics.u_max
        self.generator = torch.Generator().manual_seed(self.seed)
        torch.manual_seed(self.seed)  # network initialisation
        ego = EGO_FEATURES + self.extra_features
        self.actor = GaussianActor(ego, NEIGHBOUR_FEATURES, self.hidden, init_log_std=ppo.init_log_std,
                                   encoder=self.encoder).to(self.device, env.dtype)
        self.critic = ValueCritic(ego, NEIGHBOUR_FEATURES, self.hidden, heads=self.critic_heads,
                                  encoder=self.encoder).to(self.device, env.dtype)
        self.obs_norm = ObsNormalizer(ego, NEIGHBOUR_FEATURES)
        self.ret_norm = ReturnNormalizer(ppo.discount)
        self.optimizer = torch.optim.Adam(list(self.actor.parameters()) + list(self.critic.parameters()), lr=ppo.lr, eps=1e-5)
        self.iteration = 0
        self.history: list[dict] = []

    # ---- extension points -------------------------------------------------------------------
    def augment(self, obs: LocalObs) -> LocalObs:
        return obs

    def on_reset(self, n_envs: int, n_agents: int) -> None:
        pass

    def reward(self, info: StepInfo) -> torch.Tensor:
        return goal_reward(info, self.reward_cfg, self.env.cfg.train_dt, self.u_max)

    def record(self, info: StepInfo) -> None:
        pass

    def extra_modules(self) -> dict[str, torch.nn.Module]:
        return {}

    def extra_optimizers(self) -> dict[str, torch.optim.Optimizer]:
        return {}

    # ---- resumable state ----------------------------------------------------------------------
    def training_state(self) -> dict:
        """The state a resumed run needs beyond the modules and normalisers (plain tensors and
        containers: loadable with ``weights_only=True``)."""
        return {
            "iteration": int(self.iteration),
            "optimizers": {"main": self.optimizer.state_dict(),
                           **{k: o.state_dict() for k, o in self.extra_optimizers().items()}},
            "generator": self.generator.get_state(),
            "torch_rng": torch.get_rng_state(),
            "drawn": {int(k): int(v) for k, v in self.env._drawn.items()},
            "history": [dict(h) for h in self.history],
        }

    def load_training_state(self, state: dict) -> None:
        """Inverse of :meth:`training_state` (modules and normalisers are loaded separately)."""
        optimizers = {"main": self.optimizer, **self.extra_optimizers()}
        if set(state["optimizers"]) != set(optimizers):
            raise ValueError(f"training state has optimizers {sorted(state['optimizers'])}, this trainer {sorted(optimizers)}")
        for k, opt in optimizers.items():
            opt.load_state_dict(state["optimizers"][k])
        self.generator.set_state(state["generator"])
        torch.set_rng_state(state["torch_rng"])
        self.env._drawn = {int(k): int(v) for k, v in state["drawn"].items()}
        self.iteration = int(state["iteration"])
        self.history = [dict(h) for h in state["history"]]

    def skip_to(self, iteration: int) -> None:
        """Continue weights trained for ``iteration`` iterations whose training state is lost (a
        shipped model): count the scenarios those iterations drew (the next rollouts draw new
        ones) and reseed the sampling generator from ``(seed, iteration)``; optimizers stay fresh."""
        for it in range(self.iteration, int(iteration)):
            n = self.agent_counts[it % len(self.agent_counts)]
            self.env._drawn[n] = self.env._drawn.get(n, 0) + max(1, self.ppo.agents_per_batch // n)
        self.iteration = int(iteration)
        self.generator.manual_seed(self.seed * 1_000_003 + self.iteration)

    def advantages(self, buf: RolloutBuffer, last_values: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor]:
        adv, ret = gae(buf.get("reward"), buf.get("value")[..., 0], last_values[..., 0], self.ppo.discount, self.ppo.gae_lambda)
        return adv, ret.unsqueeze(-1)

    # ---- loop ---------------------------------------------------------------------------------
    def _sample(self, obs: LocalObs) -> tuple[torch.Tensor, torch.Tensor, torch.Tensor]:
        dist = self.actor.distribution(obs)
        noise = torch.randn(dist.mean.shape, generator=self.generator, dtype=dist.mean.dtype).to(self.device)
        action = dist.mean + dist.stddev * noise
        return action, dist.log_prob(action).sum(-1), self.critic(obs)

    def collect(self, n_agents: int) -> tuple[RolloutBuffer, torch.Tensor, dict]:
        """One episode in ``agents_per_batch // n_agents`` environments; returns the buffer, the
        bootstrap values ``[E, N, H]`` of the final observation and episode statistics."""
        n_envs = max(1, self.ppo.agents_per_batch // n_agents)
        obs = self.env.reset(n_envs, n_agents)
        self.on_reset(n_envs, n_agents)
        self.ret_norm.reset((n_envs, n_agents), self.device)
        buf = RolloutBuffer()
        ep_return = torch.zeros(n_envs, n_agents, dtype=torch.float64, device=self.device)
        collided = torch.zeros(n_envs, n_agents, dtype=torch.bool, device=self.device)
        H = self.critic_heads
        with torch.no_grad():
            while not self.env.done:
                x = self.augment(obs)
                self.obs_norm.update(x)
                xn = self.obs_norm(x)
                action, logp, value = self._sample(xn.flatten())
                obs, info = self.env.step(action.clamp(-1.0, 1.0).view(n_envs, n_agents, self.env.dynamics.control_dim) * self.u_max)
                r = self.reward(info)
                ep_return += r
                collided |= info.collided
                buf.add(xn, action=action.view(n_envs, n_agents, -1), logp=logp.view(n_envs, n_agents),
                        value=value.view(n_envs, n_agents, H), reward=self.ret_norm(r), raw_reward=r)
                self.record(info)
            last = self.critic(self.obs_norm(self.augment(obs)).flatten()).view(n_envs, n_agents, H)
        final = self.env.goal_distance()
        stats = {
            "n_agents": n_agents,
            "episode_return": ep_return.mean().item(),
            "final_distance": final.mean().item(),
            "reached_rate": (final < REACHED_M).float().mean().item(),
            "collision_rate": collided.float().mean().item(),
        }
        return buf, last, stats

    @torch.no_grad()
    def evaluate(self, n_envs: int, n_agents: int, scenario_seed: int = 2 * 10**6) -> dict:
        """Deterministic (mean-action) episodes on a fixed scenario set: mean raw return, final
        goal distance (m) and fraction of agents that collided."""
        obs = self.env.reset(n_envs, n_agents, fixed_seed=scenario_seed)
        self.on_reset(n_envs, n_agents)
        ret = torch.zeros(n_envs, n_agents, dtype=torch.float64, device=self.device)
        collided = torch.zeros(n_envs, n_agents, dtype=torch.bool, device=self.device)
        while not self.env.done:
            mean = self.actor(self.obs_norm(self.augment(obs)).flatten())
            obs, info = self.env.step(mean.clamp(-1.0, 1.0).view(n_envs, n_agents, self.env.dynamics.control_dim) * self.u_max)
            ret += self.reward(info)
            collided |= info.collided
            self.record(info)
        return {"return": ret.mean().item(), "final_distance": self.env.goal_distance().mean().item(),
                "collision_rate": collided.float().mean().item()}

    def step(self) -> dict:
        """One training iteration (rollout + PPO update); agent counts cycle over iterations."""
        t0 = time.perf_counter()
        n_agents = self.agent_counts[self.iteration % len(self.agent_counts)]
        buf, last, stats = self.collect(n_agents)
        adv, ret = self.advantages(buf, last)
        H = ret.shape[-1]
        batch = PPOBatch(
            obs=buf.flat_obs(), actions=buf.get("action").reshape(-1, self.env.dynamics.control_dim), logp_old=buf.get("logp").reshape(-1),
            advantages=adv.reshape(-1), returns=ret.reshape(-1, H),
        )
        stats.update(ppo_update(self.actor, self.critic, self.optimizer, batch, self.ppo, self.generator))
        stats["iteration"] = self.iteration
        stats["samples"] = len(batch)
        stats["wall_s"] = time.perf_counter() - t0
        self.iteration += 1
        self.history.append(stats)
        return stats

    def train(self, iterations: int | None = None, progress: bool = True, desc: str = "PPO",
              on_iteration: Callable[[dict], bool | None] | None = None, deadline: float | None = None) -> list[dict]:
        """Train from the current iteration until ``iterations`` in all (default
        ``ppo.iterations``). ``on_iteration(stats)`` after each (e.g. live curves); a true return
        value ends training there (e.g. a validation plateau). ``deadline`` (a
        :func:`time.monotonic` instant): stop after the first iteration that ends past it."""
        iterations = self.ppo.iterations if iterations is None else int(iterations)
        bar = tqdm(range(self.iteration, iterations), initial=self.iteration, total=iterations, desc=desc,
                   disable=not progress, mininterval=2.0)
        for _ in bar:
            s = self.step()
            if not math.isfinite(s["episode_return"]):
                raise FloatingPointError(f"non-finite episode return at iteration {s['iteration']}")
            stop = on_iteration(s) if on_iteration is not None else None
            bar.set_postfix(N=s["n_agents"], ret=f"{s['episode_return']:.3f}", dist=f"{s['final_distance']:.3f}",
                            coll=f"{s['collision_rate']:.3f}")
            if stop or (deadline is not None and time.monotonic() >= deadline):
                break
        return self.history
