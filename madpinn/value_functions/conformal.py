"""Certifying a safety level δ from scored, labelled samples (issue 62; the paper's stated future
work, Lin & Bansal, L4DC 2024): the statistics alone, no V̂ (:mod:`.calibration` feeds it).

Setting. A state ``o`` drawn i.i.d. from a distribution is *accepted at level δ* when the deployed
search finds a budget at that level, ``V̂(0, o, z_max) ≤ −δ`` (:mod:`.z_search`, ``level``), and
*violates* when the V̂ policy's rollout from the budget ``z*_δ`` of that level collides. The
candidate levels ``0 = δ_0 < δ_1 < … < δ_{K−1}`` are fixed before any sample is drawn (config
``value_functions.vhat.validation.calibration.levels``).

Decision rule (written before any run):

1. **Certificate.** For each candidate ``δ_k``, with ``m_k`` accepted calibration states of which
   ``k_k`` violate, the one-sided Clopper–Pearson bound ``ε̂_k`` at confidence ``1 − β/K``
   (:func:`madpinn.value_functions.verification.epsilon_bound`) bounds the violation probability of
   an accepted state (the accepted states are i.i.d. draws of the distribution restricted to the
   fixed set ``{V̂(0, o, z_max) ≤ −δ_k}``). By the union bound all K bounds hold together with
   probability ≥ 1 − β, so any data-dependent choice among them keeps its bound. The calibrated
   level is ``δ* = min{δ_k : ε̂_k ≤ ε}``; when no candidate qualifies the level is *none* (no
   state is certified: the deployed search then treats every state of that bin as infeasible).
   Claim: with confidence ≥ 1 − β, ``P[violation | accepted at δ*] ≤ ε``.
2. **Mondrian split.** The same rule inside each closing-speed bin (its own samples, its own δ*,
   its own confidence 1 − β; across B bins all hold together with confidence ≥ 1 − B·β).
3. **Held-out coverage.** On a test set drawn from another generator stream (disjoint from the
   calibration set, checked row by row: :func:`assert_disjoint`), with ``m`` accepted test states
   at δ* and ``k`` violations: *coverage met* when the exact binomial test of ``H0: p ≤ ε`` is not
   rejected at level β, i.e. ``P[Bin(m, ε) ≥ k] > β`` (:func:`coverage_met`). The plain rate
   ``k/m`` and its Clopper–Pearson upper bound are reported beside it. ``m = 0`` meets coverage
   vacuously and is reported as such (``accepted = 0``).
"""

from __future__ import annotations

import hashlib

import torch

from madpinn.value_functions.verification import epsilon_bound


def check_risk(epsilon: float, beta: float) -> None:
    """Fail early unless ``0 < ε < 1`` (violation rate) and ``0 < β < 1`` (miss probability)."""
    if not 0.0 < float(epsilon) < 1.0:
        raise ValueError(f"the violation rate ε must lie in (0, 1), got {epsilon}")
    if not 0.0 < float(beta) < 1.0:
        raise ValueError(f"the confidence parameter β must lie in (0, 1), got {beta}")


def check_levels(levels: torch.Tensor) -> None:
    """Candidate levels ``[K]``: finite, ≥ 0, strictly ascending, starting at 0 (today's policy)."""
    if levels.dim() != 1 or levels.numel() < 1:
        raise ValueError(f"candidate levels must be a non-empty vector, got shape {tuple(levels.shape)}")
    if not bool(torch.isfinite(levels).all()) or float(levels[0]) != 0.0 or not bool((levels.diff() > 0).all()):
        raise ValueError(f"candidate levels must be finite, start at 0 and ascend strictly, got {levels.tolist()}")


def certify(levels: torch.Tensor, accepted: torch.Tensor, violated: torch.Tensor, epsilon: float, beta: float) -> dict:
    """Rule 1 of the module docstring on calibration outcomes.

    ``levels [K]`` (ascending, from 0), ``accepted [K, M]`` and ``violated [K, M]`` (bool: sample
    ``j`` accepted at ``δ_k``; its rollout from ``z*_{δ_k}`` collides; ignored where not accepted).
    Returns ``index`` (of δ*, or None), ``level`` (δ* or None), and per candidate the accepted
    count, violations and bound ``ε̂_k`` (at confidence ``1 − β/K``)."""
    check_risk(epsilon, beta)
    check_levels(levels)
    if accepted.shape != violated.shape or accepted.dim() != 2 or accepted.shape[0] != levels.numel():
        raise ValueError(f"accepted and violated must both be [K={levels.numel()}, M], got "
                         f"{tuple(accepted.shape)} and {tuple(violated.shape)}")
    K = levels.numel()
    m = accepted.sum(1).tolist()
    k = (accepted & violated).sum(1).tolist()
    bounds = [epsilon_bound(int(kk), int(mm), beta / K) if mm > 0 else 1.0 for kk, mm in zip(k, m)]
    ok = [i for i, b in enumerate(bounds) if b <= epsilon]
    index = ok[0] if ok else None
    return {"index": index, "level": None if index is None else float(levels[index]),
            "accepted": [int(x) for x in m], "violations": [int(x) for x in k], "bounds": bounds}


def coverage_met(violations: int, accepted: int, epsilon: float, beta: float) -> bool:
    """Rule 3: the held-out count is not significantly above ε, ``P[Bin(m, ε) ≥ k] > β``."""
    from scipy.stats import binom

    check_risk(epsilon, beta)
    if not 0 <= violations <= accepted:
        raise ValueError(f"violations must lie in [0, accepted], got {violations} of {accepted}")
    return bool(binom.sf(violations - 1, accepted, epsilon) > beta) if accepted > 0 else True


def held_out(violations: int, accepted: int, samples: int, epsilon: float, beta: float) -> dict:
    """Held-out statistics of one level: accepted fraction, violation rate among accepted states,
    its Clopper–Pearson upper bound at ``1 − β`` and rule 3's verdict."""
    return {"samples": int(samples), "accepted": int(accepted),
            "accepted_fraction": accepted / samples if samples else 0.0, "violations": int(violations),
            "rate": violations / accepted if accepted else 0.0,
            "upper_bound": epsilon_bound(violations, accepted, beta) if accepted else 1.0,
            "coverage_met": coverage_met(violations, accepted, epsilon, beta)}


class LeakageError(RuntimeError):
    """The held-out set shares states (or its generator stream) with the calibration set."""


def assert_disjoint(calibration: torch.Tensor, test: torch.Tensor) -> None:
    """Raise :class:`LeakageError` when any row of ``test [M, D]`` equals a row of
    ``calibration [M', D]`` (exact equality of the stored values)."""
    if calibration.shape[1:] != test.shape[1:]:
        raise ValueError(f"calibration and test states differ in shape: {tuple(calibration.shape)} vs {tuple(test.shape)}")
    cal, tst = calibration.unique(dim=0), test.unique(dim=0)
    shared = cal.shape[0] + tst.shape[0] - torch.cat([cal, tst]).unique(dim=0).shape[0]
    if shared:
        raise LeakageError(f"{shared} held-out state(s) also lie in the calibration set: the coverage would be "
                           "measured on states the level was chosen on")


def fingerprint(states: torch.Tensor) -> str:
    """sha256 (16 hex) of a state set's float64 values: names the exact set in the report."""
    return hashlib.sha256(states.detach().to("cpu", torch.float64).contiguous().numpy().tobytes()).hexdigest()[:16]
