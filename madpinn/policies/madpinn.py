"""MAD-PINN decentralized receding-horizon policy (SPEC §6, paper Sec. "Online deployment").

For all agents of all scenarios at once, at every policy step (simulation step ``k_sim``):

1. neighbours: re-selected when ``k_sim`` reaches the next multiple of ``update_every`` (k) — with
   a policy period of p simulation steps, the first policy step at or after each multiple of k;
   ``k = ∞`` keeps the neighbours chosen at t = 0 for the whole episode;
2. observation ``o`` ``[S·N, D]`` via :func:`madpinn.observation.build_observation` (phantom
   slots at distinct points of the trained box, so two phantoms never "collide");
3. ``z* = min{z ∈ [0, z_max] : V̂(0, o, z) ≤ 0}`` on the grid ``z_max·i/2^steps``
   (:mod:`madpinn.value_functions.z_search`, the search ``verify-vhat`` certifies; tolerance
   ``z_tolerance·z_max``, i.e. ``⌈log2(1/z_tolerance)⌉`` halvings); where ``V̂(0, o, z_max) > 0`` (unsafe) ``z* = z_max``.
   With ``warm_start`` each agent's search is bracketed around the linear extrapolation of its
   last two answers (same z* as the cold bisection wherever V̂ is monotone in z, ≈ 2–3 network
   rows per agent-step instead of 12; see :mod:`madpinn.policies.z_search`);
4. ego control ``u = −u_max·sign(∂V̂/∂v_ego)`` at ``(t = 0, ô* = [o, z*])``; where no budget is
   feasible (``V̂(0, o, z_max) > 0``, the paper: ``V_d = +∞``) ``infeasible`` chooses the control:
   ``gradient`` (the same formula at ``z_max``) or ``brake`` (``u = −u_max·sign(v_ego)`` per axis,
   not in the paper: a measured alternative, issue 46).

Each agent's control depends only on its own observation; the batch is a computational device.

Extension, not in the paper: ``safety_filter`` passes the MAD-PINN control through the CBVF QP on
V_s (:mod:`madpinn.policies.safety_filter`, the filter SafeMARL uses), which changes it only
where a pair's V_s would fall too fast. Off by default; run ``madpinn-filtered`` in config.yaml.

Extension, not in the paper (issue 62): ``conformal`` deploys a calibrated safety level δ of V̂
(:mod:`madpinn.value_functions.safety_level`): step 3 runs on V̂ + δ, so z* is the least grid z
with ``V̂(0, o, z) ≤ −δ`` and an agent is infeasible where ``V̂(0, o, z_max) > −δ``; δ is read
from the ``calibrate-vhat`` report of the loaded V̂ (``--model calibration=PATH``), one δ or one
per closing-speed bin. The ``value`` neighbour ranking uses the same level: with one δ the order
of the scores ``V_s − δ`` is the order of ``V_s`` (the plain ranking, exactly); per bin each pair
is ranked by ``V_s − δ`` of its own closing-speed bin (:mod:`madpinn.policies.leveled_neighbours`).
Absent (the default): δ = 0, this policy bit for bit.

Deployment adaptation, not in the paper: ``look_ahead`` τ > 0 builds step 2's observation from
the states predicted τ ahead (own state under the agent's last command, the others' at constant
velocity; :mod:`madpinn.policies.look_ahead`), which compensates the drones' actuator lag.
``look_ahead: 0`` is the paper's policy.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import torch

from madpinn.observation import ObservationSettings, build_observation
from madpinn.policies.base import PolicyContext, register_policy
from madpinn.policies.look_ahead import look_ahead_observation
from madpinn.policies.neighbours import make_selector
from madpinn.policies.safety_filter import CBVFFilter, CBVFSettings, SafetyFilteredPolicy, make_cbvf_filter
from madpinn.policies.z_search import predict_index, warm_search
from madpinn.value_functions import load_vhat, load_vs
from madpinn.value_functions.symmetry import symmetrize
from madpinn.value_functions.z_search import ZGrid, cold_search

INF_UPDATE = "inf"
INFEASIBLE = ("gradient", "brake")
"""controls where no budget is feasible: ∇V̂ at z_max (the paper's formula) | brake per axis"""


@dataclass(frozen=True)
class MadPinnSettings:
    """strategy: neighbour strategy; update_every: k in simulation steps (None = ∞);
    z_tolerance: bisection tolerance as a fraction of z_max; warm_start: start each row's
    search around the extrapolation of its previous answers (:func:`warm_search`); pair_batch: V_s states per call;
    symmetry: group V̂ is averaged over at inference (:mod:`madpinn.value_functions.symmetry`);
    safety_filter: CBVF filter parameters (None: the paper's policy, unfiltered);
    look_ahead: τ (s) of the actuator-lag compensation: V̂ sees each agent's own state predicted
    τ ahead under its last command and the others' at constant velocity (0: the paper's policy,
    the measured state); vs_band: V_s clamped into its exact band [free-drift bound, ψ]
    (:meth:`madpinn.value_functions.PairValue.banded`, issue 37); infeasible: the control where no
    budget is feasible (:data:`INFEASIBLE`); conformal: the calibrated safety level to deploy,
    ``{distribution, epsilon, beta, binned}`` (None: δ = 0, the paper's rule)."""

    strategy: str
    update_every: int | None
    z_tolerance: float
    warm_start: bool
    pair_batch: int
    symmetry: str
    safety_filter: CBVFSettings | None
    look_ahead: float
    vs_band: bool
    infeasible: str
    conformal: dict | None

    @classmethod
    def from_config(cls, mcfg: dict) -> "MadPinnSettings":
        """Every key from the validated ``methods.madpinn`` (variant merged); its bounds are the schema's."""
        k = mcfg["update_every"]
        return cls(strategy=str(mcfg["neighbours"]), update_every=None if k == INF_UPDATE else int(k),
                   z_tolerance=float(mcfg["z_tolerance"]), warm_start=bool(mcfg["warm_start"]),
                   pair_batch=int(mcfg["pair_batch"]), symmetry=str(mcfg["symmetry"]),
                   safety_filter=CBVFSettings.from_config(mcfg["safety_filter"]) if mcfg["safety_filter"] else None,
                   look_ahead=float(mcfg["look_ahead"]), vs_band=bool(mcfg["vs_band"]),
                   infeasible=str(mcfg["infeasible"]), conformal=dict(mcfg["conformal"]) if mcfg["conformal"] else None)


def check_compatible(vhat, vs, spec: ObservationSettings, u_max: float) -> None:
    """Fail early when the trained models do not match the deployment configuration."""
    m = vhat.obs_spec
    for name in ("n_neighbours", "goal_range", "offset_range", "collision_radius", "model"):
        if getattr(m, name) != getattr(spec, name):
            raise ValueError(f"V̂ was trained with observation.{name} = {getattr(m, name)}, but the config has "
                             f"{getattr(spec, name)}; retrain V̂ or fix the config")
    if abs(vhat.system.u_max - u_max) > 1e-9:
        raise ValueError(f"V̂ was trained with u_max = {vhat.system.u_max}, config agents.u_max = {u_max}")
    if vs is not None and vs.system.model != spec.model:
        raise ValueError(f"V_s was trained for agents.model = {vs.system.model}, the config has {spec.model}; retrain V_s or fix the config")
    if vs is not None and abs(vs.collision_radius - spec.collision_radius) > 1e-9:
        raise ValueError(f"V_s was trained with collision radius {vs.collision_radius}, config has {spec.collision_radius}")


class MadPinnPolicy:
    """Batched MAD-PINN policy over ``[S, N]`` agents (see module docstring).

    ``stats`` accumulates diagnostics over the episode: policy steps, neighbour updates, agent
    steps, infeasible agent steps (fallback ``z_max``), the sum of z*, warm-start hits (answer =
    prediction) and the V̂ network rows of the z search and control (value only / with gradient).
    """

    def __init__(self, vhat, selector, spec: ObservationSettings, settings: MadPinnSettings, sim_dt: float):
        self.vhat = vhat
        self.selector = selector
        self.spec = spec
        self.settings = settings
        self.sim_dt = float(sim_dt)
        p = next(vhat.net.parameters())
        self.device, self.dtype = p.device, p.dtype
        self.neighbours: torch.Tensor | None = None
        self._k_last: torch.Tensor | None = None   # last two answers' grid indices (warm start)
        self._k_before: torch.Tensor | None = None
        self._next_update = 0
        self._u_last: torch.Tensor | None = None   # last command [S, N, d] (look-ahead)
        self.last_search = None   # ZSearchResult of the last step (diagnostics)
        self.stats: dict = {}

    def reset(self, state: torch.Tensor, goals: torch.Tensor) -> None:
        self.neighbours = None
        self._u_last = None
        self._k_last = self._k_before = None
        self._next_update = 0
        self.stats = {"policy_steps": 0, "neighbour_updates": 0, "agent_steps": 0, "infeasible": 0, "z_sum": 0.0,
                      "warm_hits": 0, "vhat_value_rows": 0, "vhat_grad_rows": 0}

    @staticmethod
    def summarise_stats(stats: dict) -> dict:
        """Episode diagnostics from (summed) ``stats``: share of agent-steps in the infeasible
        branch (z* = z_max), mean z*, warm-start hit rate, neighbour updates, V̂ network rows per
        agent-step (all; of which with gradient)."""
        n = max(1, stats["agent_steps"])
        value, grad = stats.get("vhat_value_rows", 0), stats.get("vhat_grad_rows", 0)
        return {"infeasible_fraction": stats["infeasible"] / n, "z_star_mean": stats["z_sum"] / n,
                "warm_hit_rate": stats["warm_hits"] / n, "neighbour_updates": int(stats["neighbour_updates"]),
                "vhat_evals_per_agent_step": (value + grad) / n, "vhat_grad_evals_per_agent_step": grad / n}

    def _update_neighbours(self, state: torch.Tensor, sim_step: int) -> None:
        k = self.settings.update_every
        if self.neighbours is not None and (k is None or sim_step < self._next_update):
            return
        self.neighbours = self.selector(state)
        self.stats["neighbour_updates"] += 1
        if k is not None:
            self._next_update = (sim_step // k + 1) * k

    def act(self, state: torch.Tensor, goals: torch.Tensor, t: float) -> torch.Tensor:
        S, N, _ = state.shape
        agent = self.spec.agent
        x = state.to(device=self.device, dtype=self.dtype)
        g = goals.to(device=self.device, dtype=self.dtype)
        self._update_neighbours(x, int(round(t / self.sim_dt)))
        tau = self.settings.look_ahead
        if tau > 0.0:
            u_last = self._u_last if self._u_last is not None and self._u_last.shape == agent.velocity(x).shape else None
            obs = look_ahead_observation(x, u_last, g, self.neighbours, self.spec, tau)
        else:
            obs = build_observation(x, g, self.neighbours, self.spec)
        obs = obs.reshape(S * N, -1)
        grid = ZGrid.of(self.vhat.z_max, self.settings.z_tolerance)
        if self.settings.warm_start and self._k_last is not None and self._k_last.shape[0] == obs.shape[0]:
            r = warm_search(self.vhat, obs, grid, predict_index(self._k_last, self._k_before, grid.cells))
        else:
            r = cold_search(self.vhat, obs, grid)
            self._k_last = None
        self._k_before, self._k_last = self._k_last, r.index
        self.last_search = r
        z, feasible = r.z, r.feasible
        u = self.vhat.system.velocity_control(r.velocity_grad, obs)[:, 0]
        if self.settings.infeasible == "brake":
            brake = -self.vhat.system.u_max * torch.sign(agent.velocity(x).reshape(S * N, -1))
            u = torch.where(feasible.unsqueeze(-1), u, brake)
        st = self.stats
        st["policy_steps"] += 1
        st["agent_steps"] += S * N
        st["infeasible"] += int((~feasible).sum())
        st["z_sum"] += float(z.sum())
        st["warm_hits"] += int(r.hit.sum())
        st["vhat_value_rows"] += r.value_rows
        st["vhat_grad_rows"] += r.grad_rows
        self._u_last = u.reshape(S, N, agent.control_dim)
        return self._u_last.to(device=state.device, dtype=state.dtype)


class FilteredMadPinnPolicy(SafetyFilteredPolicy):
    """:class:`MadPinnPolicy` followed by a :class:`CBVFFilter` (extension, see module docstring);
    ``stats`` adds the filter's counts to the policy's."""

    nominal: MadPinnPolicy
    filter: CBVFFilter

    @property
    def stats(self) -> dict:
        f = self.filter.stats
        return {**self.nominal.stats, "filter_steps": f.steps, "filter_active": f.active, "filter_fallback": f.fallback}

    @staticmethod
    def summarise_stats(stats: dict) -> dict:
        """:meth:`MadPinnPolicy.summarise_stats` plus the share of agent-steps whose control the
        filter changed and the share that took the V_s-optimal fallback."""
        n = max(1, stats["filter_steps"])
        return {**MadPinnPolicy.summarise_stats(stats), "filter_active_fraction": stats["filter_active"] / n,
                "filter_fallback_fraction": stats["filter_fallback"] / n}


@register_policy("madpinn", MadPinnSettings)
def make_madpinn(ctx: PolicyContext) -> MadPinnPolicy | FilteredMadPinnPolicy:
    settings = ctx.method
    vhat = symmetrize(load_vhat(ctx.model("vhat", "madpinn"), device=ctx.device, dtype=ctx.dtype), settings.symmetry)
    needs_vs = settings.strategy == "value" or settings.safety_filter is not None
    vs = load_vs(ctx.model("vs", "madpinn"), device=ctx.device, dtype=ctx.dtype, band=settings.vs_band) if needs_vs else None
    check_compatible(vhat, vs, ctx.obs_spec, ctx.dynamics.u_max)
    gen = torch.Generator(device=ctx.device).manual_seed(int(ctx.seed))
    selector = make_selector(settings.strategy, ctx.obs_spec.n_neighbours, vs=vs, radius=ctx.obs_spec.sensing_radius,
                             generator=gen, chunk=settings.pair_batch, agent=ctx.obs_spec.agent)
    if settings.conformal is not None:   # issue 62: the calibrated level (module docstring)
        from madpinn.policies.leveled_neighbours import deploy_level

        vhat, selector = deploy_level(vhat, selector, settings.strategy, vs, ctx.model("calibration", "madpinn"),
                                      settings.conformal, ctx.obs_spec, settings.pair_batch)
    policy = MadPinnPolicy(vhat, selector, ctx.obs_spec, settings, ctx.sim_dt)
    if settings.safety_filter is None:
        return policy
    flt = make_cbvf_filter(vs, settings.safety_filter, ctx.dynamics.u_max, ctx.obs_spec.sensing_radius)
    return FilteredMadPinnPolicy(policy, flt)
