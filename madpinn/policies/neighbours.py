"""Neighbour selection for decentralized deployment (SPEC §6): ``value``, ``nearest``, ``random``.

Every selector maps the global state ``[S, N, 4]`` to neighbour indices ``[S, N, n]`` (long,
``PHANTOM = −1`` where fewer than n candidates exist; :func:`madpinn.observation.build_observation`
pads those with the far, motionless phantom). All agents of all scenarios are handled in one batch.

Sensing (issue 47, docs/reference/protocol.md §8): every strategy, like every baseline, considers only the
agents within the one sensing radius ``observation.sensing_radius`` (centre distance ``d_ij ≤
radius``, the same test as :func:`madpinn.observation.nearest_neighbours`); agents beyond it are
never read. ``radius=None`` (library default, benchmarks) lifts the limit.

``value`` — the n sensed agents with the lowest pairwise safety value ``V_s(x_ij, t = 0)``,
``x_ij = [p_i − p_j, v_i − v_j]``. Brute-force definition (:func:`pair_scores_brute_force`): the
score of every ordered pair ``(i, j ≠ i)`` is ``V_s(x_ij)`` if ``j`` is sensed and ``x_ij`` lies in
the V_s training domain (``|p_i − p_j| ≤ p_range`` and ``|v_i − v_j| ≤ v_range`` per axis, where
the learned V_s is defined), and ``+∞`` otherwise (unsensed, or no learned evidence of risk: such a
pair is treated like an absent one). The n lowest finite scores are selected (ascending); ``+∞``
slots become phantoms.

Pruning (:func:`pair_scores`): since out-of-domain pairs score ``+∞`` by definition, only
in-domain pairs need a network evaluation; they are found with cheap coordinate tests (an
``O(N²)`` boolean mask, no network work) and evaluated in one batch (chunked to bound memory).
Every in-domain pair gets exactly the brute-force score and every other pair ``+∞`` in both
paths, so the selections are identical. At 256 agents in the large arena (4 agents/m²; 64 and 128 agents are 1 and 2/m²) an agent has
about ``(2·p_range)² · 4 ≈ 64`` in-domain partners whatever N, so the network work per agent is
constant instead of ``N − 1``.

Bounds (:func:`pair_scores_bounded`, the default of the ``value`` strategy, issue 37): of those
in-domain pairs only the ones that could be among an ego's n lowest get a network evaluation —
first its n partners with the smallest ``ψ = ‖p‖ − r``, then every partner whose free-drift lower
bound (minus a margin measured for the loaded V_s, :func:`calibrate_drift_margins`) does not exceed
the largest of those n values. At 256 agents in the large arena that is ≈ 17 % of the in-domain
pairs, with the same selections as exhaustive scoring (``benchmarks/bench_neighbours.py``).
Exact ties are broken by the lower partner index in every ``value`` path (``exact_ties``), so the
selection does not depend on the scores of pairs that are not selected.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Callable

import torch

from madpinn.dynamics import AgentModel
from madpinn.dynamics.pair import closest_free_drift_offset
from madpinn.observation import PHANTOM, nearest_neighbours, pairwise_distances

STRATEGIES = ("value", "nearest", "random")

Selector = Callable[[torch.Tensor], torch.Tensor]


def select_lowest(scores: torch.Tensor, n: int, exact_ties: bool = False) -> torch.Tensor:
    """Indices ``[S, N, n]`` of the n lowest scores per row of ``[S, N, N]`` (``+∞`` -> phantom).

    ``O(N²)`` ``topk``, no full sort. Exact ties among finite scores (measure zero for continuous
    states) are resolved by ``torch.topk``, whose choice among equal scores can depend on the
    other (larger) scores of the row. ``exact_ties``: order by ``(score, index)`` instead (lower
    index first among equal scores), so the result depends only on the selected scores and the
    scores equal to them — what makes pruned scoring (:func:`pair_scores_bounded`) select exactly
    what exhaustive scoring selects. The ``value`` strategy uses it.
    """
    S, N, _ = scores.shape
    k = min(n, N)
    if exact_ties:
        idx = _lexicographic_topk(scores, k)
        vals = torch.gather(scores, -1, idx)
    else:
        vals, idx = torch.topk(scores, k, dim=-1, largest=False)
    idx = torch.where(torch.isinf(vals), torch.full_like(idx, PHANTOM), idx)
    if k < n:
        idx = torch.cat([idx, torch.full((S, N, n - k), PHANTOM, dtype=idx.dtype, device=idx.device)], dim=-1)
    return idx


def _lexicographic_topk(scores: torch.Tensor, k: int) -> torch.Tensor:
    """Indices ``[..., k]`` of the k smallest ``(score, index)`` pairs per row, ascending.

    float32 scores: one ``topk`` on unique int64 keys ``order(score)·2³² + index`` (``order`` maps
    float32 bits monotonically to integers, −0 = +0); other dtypes: a stable sort.
    """
    N = scores.shape[-1]
    if scores.dtype != torch.float32 or N >= 2**31:
        return torch.sort(scores, dim=-1, stable=True).indices[..., :k]
    bits = scores.contiguous().view(torch.int32).to(torch.int64)
    order = torch.where(bits >= 0, bits, -(bits & 0x7FFFFFFF))
    keys = order * 2**32 + torch.arange(N, dtype=torch.int64, device=scores.device)
    return torch.topk(keys, k, dim=-1, largest=False).indices


def relative_states(state: torch.Tensor) -> torch.Tensor:
    """All ordered pair states ``x_ij = s_i − s_j`` ``[S, N, N, n]`` (row i = ego)."""
    return state.unsqueeze(2) - state.unsqueeze(1)


def in_domain(state: torch.Tensor, p_range: float, v_range: float, agent: type[AgentModel],
              radius: float | None = None) -> torch.Tensor:
    """``[S, N, N]`` bool: pair state of agents of model ``agent`` inside the V_s training box and,
    with ``radius`` (m), partner within the sensing radius (``d_ij ≤ radius``); self-pairs excluded."""
    S, N, _ = state.shape
    p, v = agent.position(state), agent.velocity(state)
    ok = ~torch.eye(N, dtype=torch.bool, device=state.device)
    for q, half in ((p, p_range), (v, v_range)):
        for k in range(q.shape[-1]):   # axis by axis: [S, N, N] passes, no reduction over a short last axis
            ok = ok & ((q[..., k].unsqueeze(2) - q[..., k].unsqueeze(1)).abs() <= half)
    if radius is not None:
        ok &= pairwise_distances(p) <= radius
    return ok


ROW_MULTIPLE = 16  # network calls get a multiple of this many rows (padded): see _vs_in_chunks


def _vs_in_chunks(vs, x: torch.Tensor, chunk: int, reuse_buffers: bool = True) -> torch.Tensor:
    """V_s(x, 0) ``[B]`` for pair states ``[B, 2d]``, ``chunk`` states per network call
    (``reuse_buffers``: on the network's reused workspace, bitwise the same values, see
    :meth:`~madpinn.value_functions.PairValue.value`; off for one-off calls of many rows, whose
    buffers would stay allocated).

    Every call is padded to a multiple of :data:`ROW_MULTIPLE` rows (repeating its last state):
    CPU GEMM kernels compute the rows of a ragged tail by a different code path, whose result can
    differ in the last bits (measured: 1 in 2 tail rows off by ≤ 1e-6 m), so a pair's score would
    depend on how the pairs are batched. Padded, every row's value is bitwise the same in any
    batch (measured on this CPU; ``tests/test_neighbours.py``), which bounded and exhaustive
    scoring need to break exact ties the same way.
    """
    if x.shape[0] == 0:
        return x.new_empty(0)
    chunk = max(ROW_MULTIPLE, chunk - chunk % ROW_MULTIPLE)
    out = []
    for i in range(0, x.shape[0], chunk):
        part = x[i : i + chunk]
        pad = -part.shape[0] % ROW_MULTIPLE
        if pad:
            part = torch.cat([part, part[-1:].expand(pad, -1)])
        out.append(vs.value(part, 0.0, reuse_buffers)[: part.shape[0] - pad].to(x.dtype))
    return torch.cat(out)


def pair_scores_brute_force(state: torch.Tensor, vs, chunk: int = 65536, radius: float | None = None) -> torch.Tensor:
    """Reference definition: V_s on all ``S·N·(N−1)`` ordered pairs, ``+∞`` out of domain or
    beyond ``radius`` ``[S, N, N]``."""
    S, N, _ = state.shape
    x = relative_states(state).reshape(S * N * N, -1)
    values = _vs_in_chunks(vs, x, chunk).reshape(S, N, N)
    mask = in_domain(state, vs.system.p_range, vs.system.v_range, vs.system.agent, radius)
    return values.masked_fill(~mask, float("inf"))


def pair_scores(state: torch.Tensor, vs, chunk: int = 65536, radius: float | None = None) -> torch.Tensor:
    """Same scores as :func:`pair_scores_brute_force`, evaluating V_s only on in-domain pairs."""
    S, N, _ = state.shape
    mask = in_domain(state, vs.system.p_range, vs.system.v_range, vs.system.agent, radius)
    s_idx, i_idx, j_idx = mask.nonzero(as_tuple=True)
    x = state[s_idx, i_idx] - state[s_idx, j_idx]
    scores = torch.full((S, N, N), float("inf"), dtype=state.dtype, device=state.device)
    scores[s_idx, i_idx, j_idx] = _vs_in_chunks(vs, x, chunk)
    return scores


def free_drift_lower_bound(x: torch.Tensor, horizon: float, radius: float, agent: type[AgentModel]) -> torch.Tensor:
    """``min_{τ∈[0,T]} ‖p + v·τ‖ − r`` ``[B]`` for pair states ``x [B, 2d]`` of agents of model
    ``agent``: the pair's safety margin with no relative control
    (:func:`madpinn.dynamics.pair.free_drift_and_grad`, without the gradient)."""
    return torch.linalg.vector_norm(closest_free_drift_offset(x, horizon, agent)[0], dim=-1) - radius


@dataclass(frozen=True)
class DriftMargins:
    """How far the learned V_s may fall below the free-drift bound, per relative-speed bin.

    ``margin(x) = margins[b]`` for ``‖v‖`` in bin ``b`` of ``edges`` (m/s, ascending upper edges;
    the last covers the domain). Measured by :func:`calibrate_drift_margins`.
    """

    edges: tuple[float, ...]
    margins: tuple[float, ...]

    def of(self, x: torch.Tensor, agent: type[AgentModel]) -> torch.Tensor:
        """Margin ``[B]`` (m) of pair states ``x [B, 2d]`` of agents of model ``agent``."""
        speed = torch.linalg.vector_norm(agent.velocity(x), dim=-1)
        edges = torch.tensor(self.edges, dtype=x.dtype, device=x.device)
        b = torch.bucketize(speed, edges).clamp(max=len(self.margins) - 1)
        return torch.tensor(self.margins, dtype=x.dtype, device=x.device)[b]


# Calibration of the lower-bound margin (one source of truth; see docs/reference/performance.md, issue 37).
MARGIN_SAMPLES = 2**17     # uniform states of the V_s domain at t = 0 (fixed seed)
MARGIN_SEED = 37
MARGIN_BINS = 16           # relative-speed bins over [0, √2·v_range]
MARGIN_FACTOR = 2.0        # margin = factor × measured excess (running max over slower bins) + pad
MARGIN_PAD = 0.05          # m


def calibrate_drift_margins(vs, samples: int = MARGIN_SAMPLES, seed: int = MARGIN_SEED, bins: int = MARGIN_BINS,
                            factor: float = MARGIN_FACTOR, pad: float = MARGIN_PAD, chunk: int = 65536) -> DriftMargins:
    """Measure ``max(free-drift bound − V_s)`` on ``samples`` uniform domain states per speed bin
    and widen it: ``factor ×`` (running max over the slower bins) ``+ pad``."""
    system = vs.system
    g = torch.Generator().manual_seed(seed)
    x = system.sample(samples, g, dtype=torch.float64).to(torch.float32)
    excess = free_drift_lower_bound(x, vs.horizon, vs.collision_radius, system.agent) - _vs_in_chunks(vs, x, chunk, reuse_buffers=False).to("cpu", x.dtype)
    top = float(system.v_range) * 2**0.5
    edges = torch.linspace(0.0, top, bins + 1)[1:]
    b = torch.bucketize(torch.linalg.vector_norm(system.agent.velocity(x), dim=-1), edges).clamp(max=bins - 1)
    worst = torch.full((bins,), 0.0).scatter_reduce(0, b, excess.clamp_min(0.0), reduce="amax")
    worst = torch.cummax(worst, 0).values
    return DriftMargins(tuple(edges.tolist()), tuple((factor * worst + pad).tolist()))


def pair_scores_bounded(state: torch.Tensor, vs, n: int, margins: DriftMargins, chunk: int = 65536,
                        counts: dict | None = None, radius: float | None = None) -> torch.Tensor:
    """Scores ``[S, N, N]`` whose n lowest per row (:func:`select_lowest` with ``exact_ties``) are
    exactly those of :func:`pair_scores_brute_force`, evaluating V_s on fewer pairs.

    1. In-domain pairs as in :func:`pair_scores`. Per ego, the ``n`` with the smallest
       ``ψ = ‖p‖ − r`` (V_s's upper bound) are evaluated; ``τ`` = the largest of those n values (the
       n-th smallest value is ≤ τ; an ego with fewer than n in-domain partners gets ``τ = +∞``).
    2. Every other in-domain pair gets a lower bound ``λ = free-drift bound − margin(‖v‖)``; pairs
       with ``λ ≤ τ`` are evaluated, those with ``λ > τ`` get ``+∞`` without a network call: their
       V_s exceeds τ, so n evaluated partners lie strictly below them and they are never selected
       (ties included, since the selection orders by ``(score, index)``). Using the evaluated τ
       instead of ``ψ_(n)`` + a margin needs no bound on V_s − ψ.

    Exactness rests on ``V_s ≥ free-drift bound − margin`` for the pruned pairs; ``margins`` come
    from :func:`calibrate_drift_margins` (measured, widened). ``counts`` (optional) accumulates
    ``in_domain`` and ``evaluated`` pairs. ``radius``: only sensed partners are in the domain.
    """
    S, N, _ = state.shape
    mask = in_domain(state, vs.system.p_range, vs.system.v_range, vs.system.agent, radius)
    s_idx, i_idx, j_idx = mask.nonzero(as_tuple=True)
    x = state[s_idx, i_idx] - state[s_idx, j_idx]
    P = x.shape[0]
    scores = torch.full((S, N, N), float("inf"), dtype=state.dtype, device=state.device)
    if P == 0:
        return scores
    r = vs.collision_radius
    psi = torch.full((S, N, N), float("inf"), dtype=state.dtype, device=state.device)
    agent = vs.system.agent
    psi[s_idx, i_idx, j_idx] = torch.linalg.vector_norm(agent.position(x), dim=-1) - r
    k = min(n, N)
    psi_k, first = torch.topk(psi, k, dim=-1, largest=False)           # [S, N, k]
    pos = torch.full((S, N, N), -1, dtype=torch.long, device=state.device)
    pos[s_idx, i_idx, j_idx] = torch.arange(P, device=state.device)
    first_pos = torch.gather(pos, -1, first)[torch.isfinite(psi_k)]    # stage-1 pairs (compact)
    values = torch.full((P,), float("inf"), dtype=state.dtype, device=state.device)
    values[first_pos] = _vs_in_chunks(vs, x[first_pos], chunk)
    full = torch.isfinite(psi_k).all(-1) if k == n else torch.zeros((S, N), dtype=torch.bool, device=state.device)
    tau_ego = torch.where(full, values[torch.gather(pos, -1, first).clamp_min(0)].amax(-1),
                          torch.full((S, N), float("inf"), dtype=state.dtype, device=state.device))
    lower = free_drift_lower_bound(x, vs.horizon, r, agent) - margins.of(x, agent)
    todo = lower <= tau_ego[s_idx, i_idx]
    todo[first_pos] = False
    rest = todo.nonzero(as_tuple=True)[0]
    values[rest] = _vs_in_chunks(vs, x[rest], chunk)
    scores[s_idx, i_idx, j_idx] = values
    if counts is not None:
        counts["in_domain"] = counts.get("in_domain", 0) + P
        counts["evaluated"] = counts.get("evaluated", 0) + int(first_pos.numel() + rest.numel())
    return scores


def value_selector(vs, n: int, chunk: int = 65536, pruned: bool = True, bounded: bool = True,
                   margins: DriftMargins | None = None, radius: float | None = None) -> Selector:
    """``value`` strategy: n lowest V_s among the agents within ``radius`` (m; None: any distance;
    see module docstring), ties broken by the lower index. ``pruned``: in-domain pairs only;
    ``bounded`` (with ``pruned``): also skip pairs the bounds exclude (:func:`pair_scores_bounded`;
    ``margins`` default: :func:`calibrate_drift_margins`)."""
    if pruned and bounded:
        m = margins if margins is not None else calibrate_drift_margins(vs, chunk=chunk)
        return lambda state: select_lowest(pair_scores_bounded(state, vs, n, m, chunk, radius=radius), n, exact_ties=True)
    scorer = pair_scores if pruned else pair_scores_brute_force
    return lambda state: select_lowest(scorer(state, vs, chunk, radius=radius), n, exact_ties=True)


def nearest_selector(n: int, agent: type[AgentModel], radius: float | None = None) -> Selector:
    """``nearest`` strategy: the n nearest other agents within ``radius`` (m; None: any distance)."""
    return lambda state: nearest_neighbours(agent.position(state), n, radius=radius)


def random_selector(n: int, radius: float, generator: torch.Generator, agent: type[AgentModel]) -> Selector:
    """``random`` strategy: n agents drawn uniformly without replacement among those within
    ``radius`` (m) of the ego; fewer -> phantoms. Draws from ``generator`` (seeded per job)."""

    def select(state: torch.Tensor) -> torch.Tensor:
        d = pairwise_distances(agent.position(state))
        keys = torch.rand(d.shape, generator=generator, device=generator.device, dtype=state.dtype).to(state.device)
        return select_lowest(keys.masked_fill(d > radius, float("inf")), n)

    return select


def make_selector(strategy: str, n: int, *, vs=None, radius: float | None = None,
                  generator: torch.Generator | None = None, chunk: int = 65536,
                  agent: type[AgentModel] | None = None) -> Selector:
    """Build the selector of ``strategy`` (one of :data:`STRATEGIES`); every strategy reads only
    the agents within the sensing ``radius`` (m). The states it reads have the layout of ``agent``
    (the agents' model class), or of V_s's model where ``agent`` is not given."""
    if agent is None and vs is not None:
        agent = vs.system.agent
    if agent is None and strategy in STRATEGIES and strategy != "value":
        raise ValueError(f"the '{strategy}' neighbour strategy needs the agents' model (agent=) or V_s")
    if strategy == "value":
        if vs is None:
            raise ValueError("the 'value' neighbour strategy needs the pairwise safety value V_s")
        return value_selector(vs, n, chunk, radius=radius)
    if strategy == "nearest":
        return nearest_selector(n, agent, radius)
    if strategy == "random":
        if radius is None or generator is None:
            raise ValueError("the 'random' neighbour strategy needs a sensing radius and a torch.Generator")
        return random_selector(n, radius, generator, agent)
    raise ValueError(f"unknown neighbour strategy '{strategy}' (have {STRATEGIES})")
