"""A trained DEF-MARL model as a :class:`madpinn.policies.Policy`.

Every policy step: the local observations of all agents ``[S, N]`` are built once; each
agent's smallest safe budget comes from bisection on its constraint critic ``V_h(o_i, z)``
(:mod:`root`), the team budget is the maximum over the scenario's agents, and the actor's
mean action ``π(o_i, z)`` is applied, clipped to the box. The critic's neighbour encoding
does not depend on z, so it is computed once per step and only the trunk is re-evaluated
during the search.
"""

from __future__ import annotations

from dataclasses import dataclass, replace

import torch

from madpinn.marl.checkpoint import CheckpointError, load_actor, load_checkpoint
from madpinn.marl.defmarl.root import smallest_safe_z, team_budget
from madpinn.marl.features import EGO_FEATURES, local_observation
from madpinn.marl.networks import GaussianActor, ValueCritic
from madpinn.marl.normalize import CLIP, ObsNormalizer
from madpinn.observation import ObservationSpec

FORMAT_METHOD = "defmarl"


@dataclass
class BudgetStats:
    """Counts over agent-steps: root found, all-safe fallback (z_min), none-safe fallback (z_max);
    sum of the team budgets (for the mean)."""

    steps: int = 0
    all_safe: int = 0
    none_safe: int = 0
    z_sum: float = 0.0


class DefMarlPolicy:
    def __init__(self, actor: GaussianActor, critic: ValueCritic, obs_norm: ObsNormalizer, obs_spec: ObservationSpec,
                 neighbours: int, u_max: float, z_min: float, z_max: float, iterations: int = 20, level: float = 0.0):
        self.actor, self.critic, self.obs_norm = actor, critic, obs_norm
        self.obs_spec, self.neighbours, self.u_max = obs_spec, int(neighbours), float(u_max)
        self.z_min, self.z_max, self.iterations, self.level = float(z_min), float(z_max), int(iterations), float(level)
        self.stats = BudgetStats()

    def reset(self, state: torch.Tensor, goals: torch.Tensor) -> None:
        pass

    def _normalised_z(self, z: torch.Tensor) -> torch.Tensor:
        """z as the networks see it: the ego normaliser's statistics of the z column."""
        rms = self.obs_norm.ego
        m = float(rms.mean[EGO_FEATURES])
        s = max(float(rms.var[EGO_FEATURES].sqrt()), 1e-6)
        return ((z - m) / s).clamp(-CLIP, CLIP)

    @torch.no_grad()
    def budgets(self, state: torch.Tensor, goals: torch.Tensor):
        """-> (normalised observation ``[S·N]`` with z = 0, team budget ``[S, N]``, RootResult)."""
        S, N, _ = state.shape
        obs = local_observation(state, goals, self.obs_spec, self.neighbours)
        xn = self.obs_norm(obs.with_extra(torch.zeros(S, N, 1, dtype=state.dtype, device=state.device))).flatten()
        enc = self.critic.encoder(xn)  # [B, ego + 2H]; column EGO_FEATURES is the normalised z

        def vh(z: torch.Tensor) -> torch.Tensor:
            e = enc.clone()
            e[:, EGO_FEATURES] = self._normalised_z(z)
            return self.critic.trunk(e)[:, 0]

        root = smallest_safe_z(vh, S * N, self.z_min, self.z_max, self.iterations, self.level, state.device, state.dtype)
        return xn, team_budget(root.z.view(S, N)), root

    @torch.no_grad()
    def act(self, state: torch.Tensor, goals: torch.Tensor, t: float) -> torch.Tensor:
        S, N, _ = state.shape
        xn, z, root = self.budgets(state, goals)
        xn.ego[:, EGO_FEATURES] = self._normalised_z(z.reshape(-1))
        self.stats.steps += S * N
        self.stats.all_safe += int(root.all_safe.sum())
        self.stats.none_safe += int(root.none_safe.sum())
        self.stats.z_sum += float(z.sum())
        return self.actor(xn).view(S, N, 2).clamp(-1.0, 1.0) * self.u_max


def load_defmarl(path, obs_spec: ObservationSpec, u_max: float, collision_radius: float, device="cpu",
                 dtype=torch.float32, iterations: int = 20, level: float = 0.0) -> DefMarlPolicy:
    """Policy from a ``train-defmarl`` checkpoint; refuses a model trained for other limits or radius."""
    actor, norm, meta = load_actor(path, device, dtype)
    if meta.get("method") != FORMAT_METHOD or "epigraph" not in meta:
        raise CheckpointError(f"{path} is not a DEF-MARL checkpoint (method {meta.get('method')!r})")
    ck = load_checkpoint(path, device)
    critic = ValueCritic(meta["ego_features"], meta["neighbour_features"], meta["hidden"], heads=meta["critic_heads"])
    try:
        critic.load_state_dict(ck["modules"]["critic"])
    except (RuntimeError, KeyError) as exc:
        raise CheckpointError(f"{path}: constraint-critic weights do not match its metadata: {exc}") from exc
    spec = meta["obs_spec"]
    if abs(meta["u_max"] - u_max) > 1e-9 or abs(spec["collision_radius"] - collision_radius) > 1e-9:
        raise ValueError(
            f"{path} was trained with u_max={meta['u_max']}, r={spec['collision_radius']}, but the config has "
            f"u_max={u_max}, r={collision_radius}; retrain DEF-MARL"
        )
    obs_spec = replace(obs_spec, **{k: spec[k] for k in ("goal_range", "offset_range", "sensing_radius")})
    epi = meta["epigraph"]
    return DefMarlPolicy(actor, critic.to(device=device, dtype=dtype).eval(), norm, obs_spec, meta["neighbours"], u_max,
                         epi["z_min"], epi["z_max"], iterations, level)
