"""A trained DEF-MARL model as a :class:`madpinn.policies.Policy`.

Every ``root_period`` policy steps (and at the first), each agent's smallest safe budget
comes from bisection on its constraint critic ``V_h(o_i, z)`` (:mod:`root`) and the team
agrees on a budget (``consensus``, :func:`root.agree`; default and the deployed runs: the
maximum over the scenario's agents); it is held in between. Every policy step
the actor's mean action ``π(o_i, z)`` is applied, clipped to the box. The critic's neighbour
encoding and first trunk layer are computed once per search; only the z column varies.
"""

from __future__ import annotations

from dataclasses import dataclass, replace

import torch

from madpinn.marl.checkpoint import CheckpointError, load_actor, load_checkpoint
from madpinn.marl.defmarl.root import CONSENSUS, agree, smallest_safe_z
from madpinn.marl.features import EGO_FEATURES, local_observation
from madpinn.marl.networks import DEFAULT_ENCODER, GaussianActor, ValueCritic
from madpinn.marl.normalize import CLIP, ObsNormalizer
from madpinn.observation import ObservationSettings

FORMAT_METHOD = "defmarl"


@dataclass
class BudgetStats:
    """Counts over agent-searches: searches, all-safe fallback (z_min), none-safe fallback
    (z_max); sum of the team budgets (for the mean)."""

    steps: int = 0
    all_safe: int = 0
    none_safe: int = 0
    z_sum: float = 0.0
    below_team_max: int = 0
    """agents whose agreed z is below their scenario's maximum (graph consensus, split graph)"""


class DefMarlPolicy:
    def __init__(self, actor: GaussianActor, critic: ValueCritic, obs_norm: ObsNormalizer, obs_spec: ObservationSettings,
                 neighbours: int, u_max: float, z_min: float, z_max: float, iterations: int = 20, level: float = 0.0,
                 root_period: int = 1, consensus: str = "global"):
        if root_period < 1:
            raise ValueError(f"root_period must be ≥ 1 policy step, got {root_period}")
        if consensus not in CONSENSUS:
            raise ValueError(f"z consensus must be one of {CONSENSUS}, got {consensus!r}")
        self.consensus = consensus
        self.actor, self.critic, self.obs_norm = actor, critic, obs_norm
        self.obs_spec, self.neighbours, self.u_max = obs_spec, int(neighbours), float(u_max)
        self.z_min, self.z_max, self.iterations, self.level = float(z_min), float(z_max), int(iterations), float(level)
        self.root_period = int(root_period)
        self.stats = BudgetStats()
        self._z: torch.Tensor | None = None
        self._calls = 0

    def reset(self, state: torch.Tensor, goals: torch.Tensor) -> None:
        self._z, self._calls = None, 0

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
        # only the z column changes during the search: the trunk's first layer is affine in it
        first, rest = self.critic.trunk[0], self.critic.trunk[1:]
        base = first(enc)
        w_z = first.weight[:, EGO_FEATURES] * 1.0
        z0 = enc[:, EGO_FEATURES : EGO_FEATURES + 1]

        def vh(z: torch.Tensor) -> torch.Tensor:
            return rest(base + (self._normalised_z(z).unsqueeze(-1) - z0) * w_z)[:, 0]

        root = smallest_safe_z(vh, S * N, self.z_min, self.z_max, self.iterations, self.level, state.device, state.dtype)
        z = agree(root.z.view(S, N), self.obs_spec.agent.position(state), self.obs_spec.sensing_radius, self.consensus)
        return xn, z, root

    @torch.no_grad()
    def act(self, state: torch.Tensor, goals: torch.Tensor, t: float) -> torch.Tensor:
        S, N, _ = state.shape
        if self._z is None or self._z.shape != (S, N) or self._calls % self.root_period == 0:
            xn, self._z, root = self.budgets(state, goals)
            self.stats.steps += S * N
            self.stats.all_safe += int(root.all_safe.sum())
            self.stats.none_safe += int(root.none_safe.sum())
            self.stats.z_sum += float(self._z.sum())
            self.stats.below_team_max += int((self._z < self._z.amax(-1, keepdim=True)).sum())
        else:
            obs = local_observation(state, goals, self.obs_spec, self.neighbours)
            xn = self.obs_norm(obs.with_extra(torch.zeros(S, N, 1, dtype=state.dtype, device=state.device))).flatten()
        self._calls += 1
        xn.ego[:, EGO_FEATURES] = self._normalised_z(self._z.reshape(-1))
        return self.actor(xn).view(S, N, self.obs_spec.agent.control_dim).clamp(-1.0, 1.0) * self.u_max


def load_defmarl(path, obs_spec: ObservationSettings, u_max: float, collision_radius: float, device="cpu",
                 dtype=torch.float32, iterations: int = 20, level: float = 0.0, root_period: int = 1,
                 consensus: str = "global") -> DefMarlPolicy:
    """Policy from a ``train-defmarl`` checkpoint; refuses a model trained for other limits or radius."""
    actor, norm, meta = load_actor(path, device, dtype)
    if meta.get("method") != FORMAT_METHOD or "epigraph" not in meta:
        raise CheckpointError(f"{path} is not a DEF-MARL checkpoint (method {meta.get('method')!r})")
    ck = load_checkpoint(path, device)
    critic = ValueCritic(meta["ego_features"], meta["neighbour_features"], meta["hidden"], heads=meta["critic_heads"],
                         encoder=meta.get("encoder", DEFAULT_ENCODER))
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
                         epi["z_min"], epi["z_max"], iterations, level, root_period, consensus)
