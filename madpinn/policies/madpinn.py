"""MAD-PINN decentralized receding-horizon policy (SPEC §6, paper Sec. "Online deployment").

For all agents of all scenarios at once, at every policy step (simulation step ``k_sim``):

1. neighbours: re-selected when ``k_sim`` reaches the next multiple of ``update_every`` (k) — with
   a policy period of p simulation steps, the first policy step at or after each multiple of k;
   ``k = ∞`` keeps the neighbours chosen at t = 0 for the whole episode;
2. observation ``o`` ``[S·N, D]`` via :func:`madpinn.observation.build_observation` (phantom
   slots at distinct points of the trained box, so two phantoms never "collide");
3. ``z* = min{z ∈ [0, z_max] : V̂(0, o, z) ≤ 0}`` by batched bisection
   (:func:`madpinn.value_functions.min_feasible_z`, tolerance ``z_tolerance·z_max``, i.e.
   ``⌈log2(1/z_tolerance)⌉`` halvings); where ``V̂(0, o, z_max) > 0`` (unsafe) ``z* = z_max``;
4. ego control ``u = −u_max·sign(∂V̂/∂v_ego)`` at ``(t = 0, ô* = [o, z*])``.

Each agent's control depends only on its own observation; the batch is a computational device.

Extension, not in the paper: ``safety_filter`` passes the MAD-PINN control through the CBVF QP on
V_s (:mod:`madpinn.policies.safety_filter`, the filter SafeMARL uses), which changes it only
where a pair's V_s would fall too fast. Off by default; run ``madpinn-filtered`` in config.yaml.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from pathlib import Path

import torch

from madpinn.observation import ObservationSpec, build_observation
from madpinn.policies.base import PolicyContext, register_policy
from madpinn.policies.neighbours import STRATEGIES, make_selector
from madpinn.policies.safety_filter import CBVFFilter, SafetyFilteredPolicy, make_cbvf_filter
from madpinn.value_functions import load_vhat, load_vs, min_feasible_z
from madpinn.value_functions.symmetry import symmetrize

INF_UPDATE = "inf"


@dataclass(frozen=True)
class MadPinnSettings:
    """strategy: neighbour strategy; update_every: k in simulation steps (None = ∞);
    z_tolerance: bisection tolerance as a fraction of z_max; warm_start: start each row's
    search from its previous z* (:func:`warm_budget_search`); pair_batch: V_s states per call;
    symmetry: group V̂ is averaged over at inference (:mod:`madpinn.value_functions.symmetry`);
    safety_filter: CBVF filter parameters (None: the paper's policy, unfiltered)."""

    strategy: str = "value"
    update_every: int | None = 5
    z_tolerance: float = 1e-3
    warm_start: bool = True
    pair_batch: int = 65536
    symmetry: str = "none"
    safety_filter: dict | None = None

    @classmethod
    def from_method_config(cls, mcfg: dict) -> "MadPinnSettings":
        k = mcfg.get("update_every", 5)
        update_every = None if k == INF_UPDATE else int(k)
        if update_every is not None and update_every < 1:
            raise ValueError(f"methods.madpinn.update_every must be ≥ 1 or '{INF_UPDATE}', got {k}")
        strategy = str(mcfg.get("neighbours", "value"))
        if strategy not in STRATEGIES:
            raise ValueError(f"methods.madpinn.neighbours must be one of {STRATEGIES}, got '{strategy}'")
        return cls(strategy=strategy, update_every=update_every, z_tolerance=float(mcfg.get("z_tolerance", 1e-3)),
                   warm_start=bool(mcfg.get("warm_start", True)),
                   pair_batch=int(mcfg.get("pair_batch", 65536)), symmetry=str(mcfg.get("symmetry", "none")),
                   safety_filter=dict(mcfg["safety_filter"]) if mcfg.get("safety_filter") else None)


def bisection_steps(z_tolerance: float) -> int:
    """Halvings of ``[0, z_max]`` that leave a bracket ≤ ``z_tolerance·z_max`` (10 for 1e-3)."""
    return max(1, math.ceil(math.log2(1.0 / z_tolerance)))


def cold_budget_search(vhat, obs: torch.Tensor, steps: int):
    """``(z* [B], feasible [B])`` by ``steps`` halvings of ``[0, z_max]`` (SPEC §6)."""
    return min_feasible_z(vhat, obs, 0.0, tol=vhat.z_max / 2**steps * (1.0 + 1e-9))


def warm_budget_search(vhat, obs: torch.Tensor, z_prev: torch.Tensor, steps: int, warm_log2: int = 3):
    """Bisection for ``z*`` warm-started from the previous step's answers ``z_prev [B]``.

    The cold search (:func:`madpinn.value_functions.min_feasible_z` with ``steps`` halvings)
    returns a point of the dyadic grid ``z_max·i/2^steps``. Here each row first tests the aligned
    block of ``2^warm_log2`` grid cells whose upper end is nearest above ``z_prev``: if
    ``V̂(lo) > 0`` (or ``lo = 0``, which the cold search never evaluates either) and
    ``V̂(hi) ≤ 0``, ``warm_log2`` halvings inside the block finish the search; a row whose block
    is the top one and ``V̂(z_max) > 0`` is unsafe (``z_max``, exactly the cold answer); the other
    rows run the cold search. For V̂ non-increasing in z (the exact V̂ is) both give the same grid
    point, with 2 + warm_log2 (2 when unsafe) network evaluations instead of 1 + steps.
    Returns ``(z* [B], feasible [B], resolved_warm [B])``.
    """
    z_max = vhat.z_max
    cells = 2**steps
    width = 2 ** min(warm_log2, steps)
    h = z_max / cells
    k = torch.round(z_prev / h).clamp(1, cells)
    block = (torch.ceil(k / width) - 1).clamp(0, cells // width - 1)
    lo, hi = block * width * h, (block + 1) * width * h
    B = obs.shape[0]
    v = vhat.value(torch.cat([obs, obs]), torch.cat([lo, hi]), 0.0)
    v_lo, v_hi = v[:B], v[B:]
    hit = ((block == 0) | (v_lo > 0)) & (v_hi <= 0)
    unsafe = (block == cells // width - 1) & (v_hi > 0)  # V̂(0, o, z_max) > 0: the cold answer is z_max
    z = torch.full_like(z_prev, z_max)
    feasible = torch.zeros(B, dtype=torch.bool, device=obs.device)
    rows = hit.nonzero(as_tuple=True)[0]
    if rows.numel():
        o, lo_r, hi_r = obs[rows], lo[rows], hi[rows]
        for _ in range(min(warm_log2, steps)):
            mid = 0.5 * (lo_r + hi_r)
            ok = vhat.value(o, mid, 0.0) <= 0
            hi_r = torch.where(ok, mid, hi_r)
            lo_r = torch.where(ok, lo_r, mid)
        z[rows], feasible[rows] = hi_r, True
    miss = (~(hit | unsafe)).nonzero(as_tuple=True)[0]
    if miss.numel():
        z[miss], feasible[miss] = cold_budget_search(vhat, obs[miss], steps)
    return z, feasible, hit | unsafe


def check_compatible(vhat, vs, spec: ObservationSpec, u_max: float) -> None:
    """Fail early when the trained models do not match the deployment configuration."""
    m = vhat.obs_spec
    for name in ("n_neighbours", "goal_range", "offset_range", "collision_radius"):
        if getattr(m, name) != getattr(spec, name):
            raise ValueError(f"V̂ was trained with observation.{name} = {getattr(m, name)}, but the config has "
                             f"{getattr(spec, name)}; retrain V̂ or fix the config")
    if abs(vhat.system.u_max - u_max) > 1e-9:
        raise ValueError(f"V̂ was trained with u_max = {vhat.system.u_max}, config agents.u_max = {u_max}")
    if vs is not None and abs(vs.collision_radius - spec.collision_radius) > 1e-9:
        raise ValueError(f"V_s was trained with collision radius {vs.collision_radius}, config has {spec.collision_radius}")


class MadPinnPolicy:
    """Batched MAD-PINN policy over ``[S, N]`` agents (see module docstring).

    ``stats`` accumulates diagnostics over the episode: policy steps, neighbour updates, agent
    steps, infeasible agent steps (fallback ``z_max``), the sum of z* and warm-start hits.
    """

    def __init__(self, vhat, selector, spec: ObservationSpec, settings: MadPinnSettings, sim_dt: float):
        self.vhat = vhat
        self.selector = selector
        self.spec = spec
        self.settings = settings
        self.sim_dt = float(sim_dt)
        p = next(vhat.net.parameters())
        self.device, self.dtype = p.device, p.dtype
        self.neighbours: torch.Tensor | None = None
        self._z_prev: torch.Tensor | None = None
        self._next_update = 0
        self.stats: dict = {}

    def reset(self, state: torch.Tensor, goals: torch.Tensor) -> None:
        self.neighbours = None
        self._z_prev = None
        self._next_update = 0
        self.stats = {"policy_steps": 0, "neighbour_updates": 0, "agent_steps": 0, "infeasible": 0, "z_sum": 0.0,
                      "warm_hits": 0}

    @staticmethod
    def summarise_stats(stats: dict) -> dict:
        """Episode diagnostics from (summed) ``stats``: share of agent-steps in the infeasible
        branch (z* = z_max), mean z*, warm-start hit rate, neighbour updates."""
        n = max(1, stats["agent_steps"])
        return {"infeasible_fraction": stats["infeasible"] / n, "z_star_mean": stats["z_sum"] / n,
                "warm_hit_rate": stats["warm_hits"] / n, "neighbour_updates": int(stats["neighbour_updates"])}

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
        x = state.to(device=self.device, dtype=self.dtype)
        g = goals.to(device=self.device, dtype=self.dtype)
        self._update_neighbours(x, int(round(t / self.sim_dt)))
        obs = build_observation(x, g, self.neighbours, self.spec).reshape(S * N, -1)
        steps = bisection_steps(self.settings.z_tolerance)
        if self.settings.warm_start and self._z_prev is not None and self._z_prev.shape[0] == obs.shape[0]:
            z, feasible, hit = warm_budget_search(self.vhat, obs, self._z_prev, steps)
            self.stats["warm_hits"] += int(hit.sum())
        else:
            z, feasible = cold_budget_search(self.vhat, obs, steps)
        self._z_prev = z
        _, dv_dobs, _ = self.vhat.value_and_grad(obs, z, 0.0)
        u = self.vhat.system.optimal_control(dv_dobs, obs)[:, 0]
        st = self.stats
        st["policy_steps"] += 1
        st["agent_steps"] += S * N
        st["infeasible"] += int((~feasible).sum())
        st["z_sum"] += float(z.sum())
        return u.reshape(S, N, 2).to(device=state.device, dtype=state.dtype)


def model_path(ctx: PolicyContext, key: str) -> Path:
    """``methods.madpinn.<key>``: absolute, or relative to ``paths.results``."""
    p = Path(ctx.method_cfg[key])
    return p if p.is_absolute() else Path(ctx.cfg["paths"]["results"]) / p


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


@register_policy("madpinn")
def make_madpinn(ctx: PolicyContext) -> MadPinnPolicy | FilteredMadPinnPolicy:
    settings = MadPinnSettings.from_method_config(ctx.method_cfg)
    vhat = symmetrize(load_vhat(model_path(ctx, "vhat_model"), device=ctx.device, dtype=ctx.dtype), settings.symmetry)
    needs_vs = settings.strategy == "value" or settings.safety_filter is not None
    vs = load_vs(model_path(ctx, "vs_model"), device=ctx.device, dtype=ctx.dtype) if needs_vs else None
    check_compatible(vhat, vs, ctx.obs_spec, ctx.dynamics.u_max)
    gen = torch.Generator(device=ctx.device).manual_seed(int(ctx.seed))
    selector = make_selector(settings.strategy, ctx.obs_spec.n_neighbours, vs=vs, radius=ctx.obs_spec.sensing_radius,
                             generator=gen, chunk=settings.pair_batch)
    policy = MadPinnPolicy(vhat, selector, ctx.obs_spec, settings, ctx.sim_dt)
    if settings.safety_filter is None:
        return policy
    flt = make_cbvf_filter(vs, settings.safety_filter, ctx.dynamics.u_max, ctx.obs_spec.sensing_radius)
    return FilteredMadPinnPolicy(policy, flt)
