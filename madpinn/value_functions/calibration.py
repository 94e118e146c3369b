"""Calibrating the safety level δ of V̂ (issue 62; the paper's stated future work, "not in the paper").

For each state distribution of the verification (uniform, conflict: :mod:`.verification`), a
calibration set and a held-out test set are drawn from two generator streams of the validation
seed (:func:`stream_seeds`; the sets are checked disjoint row by row,
:func:`~madpinn.value_functions.conformal.assert_disjoint`). Every state is searched at each
candidate level δ_k with the deployed search (:func:`~madpinn.value_functions.z_search.cold_search`
on the grid of ``methods.madpinn.z_tolerance``, on V̂ at level δ_k: :func:`.safety_level.at_level`):
*accepted* when feasible, and then
rolled out from its budget ``z*_{δ_k}`` under V̂'s own policy in V̂'s model
(:func:`~madpinn.value_functions.verification.rollout`, the verification's exact zero-order-hold
rollout, its ``dt`` and ``substeps``); it *violates* when a pair comes closer than the collision
radius. The level δ* per (ε, β) follows the decision rule of :mod:`.conformal` (certificate by
Clopper–Pearson with a union bound over the candidates; pooled and per closing-speed bin,
:mod:`.safety_level`), and the held-out set measures its coverage.

The guarantee covers one encounter in V̂'s model (3 agents, double integrators, horizon T) drawn
from the calibration distribution, not a crowd in MuJoCo.
"""

from __future__ import annotations

from dataclasses import dataclass

import torch

from madpinn.value_functions.conformal import assert_disjoint, certify, check_levels, check_risk, fingerprint, held_out
from madpinn.value_functions.safety_level import SafetyLevel, at_level, bin_labels, check_edges, closing_speed, speed_bin
from madpinn.value_functions.verification import ScenarioSettings, rollout, verification_sampling
from madpinn.value_functions.verification import draw_states as verification_states
from madpinn.value_functions.z_search import ZGrid, cold_search

DISTRIBUTIONS = ("uniform", "conflict")
STREAMS = {"calibration": 11, "test": 23}
"""generator stream of each set: seed = validation seed · 7919 + stream + distribution index (distinct
from the verification's streams 0 and 1)"""


@dataclass(frozen=True)
class CalibrationSettings:
    """samples / test_samples: calibration and held-out states per distribution; seed: validation
    seed (≥ 100); epsilons (violation rates) and betas (miss probabilities), each in (0, 1);
    level_max and level_count: the candidate levels ``δ_k = k·level_max/(level_count − 1)`` (V̂'s
    units); speed_edges: interior closing-speed bin edges (m/s) of the Mondrian split;
    distributions: a subset of :data:`DISTRIBUTIONS`. Rollout ``dt``, ``substeps`` and the conflict
    radius are the verification's (``validation.scenario``)."""

    samples: int
    test_samples: int
    seed: int
    epsilons: tuple[float, ...]
    betas: tuple[float, ...]
    level_max: float
    level_count: int
    speed_edges: tuple[float, ...]
    distributions: tuple[str, ...]

    def __post_init__(self):
        if self.samples < 1 or self.test_samples < 1:
            raise ValueError(f"calibration needs samples ≥ 1 and test_samples ≥ 1, got {self.samples}, {self.test_samples}")
        if self.seed < 100:
            raise ValueError(f"calibration runs on validation seeds (≥ 100, never the protocol seeds 0–4), got {self.seed}")
        if not self.epsilons or not self.betas:
            raise ValueError("calibration needs at least one ε and one β")
        for e in self.epsilons:
            for b in self.betas:
                check_risk(e, b)
        if not self.level_max > 0.0 or self.level_count < 2:
            raise ValueError(f"candidate levels need level_max > 0 and level_count ≥ 2, got {self.level_max}, {self.level_count}")
        check_edges(self.speed_edges)
        unknown = set(self.distributions) - set(DISTRIBUTIONS)
        if not self.distributions or unknown:
            raise ValueError(f"calibration distributions must be among {DISTRIBUTIONS}, got {list(self.distributions)}")

    @classmethod
    def from_config(cls, d: dict) -> "CalibrationSettings":
        """From ``value_functions.vhat.validation.calibration`` (validated)."""
        return cls(samples=int(d["samples"]), test_samples=int(d["test_samples"]), seed=int(d["seed"]),
                   epsilons=tuple(float(e) for e in d["epsilons"]), betas=tuple(float(b) for b in d["betas"]),
                   level_max=float(d["levels"]["max"]), level_count=int(d["levels"]["count"]),
                   speed_edges=tuple(float(x) for x in d["speed_edges"]), distributions=tuple(d["distributions"]))

    def levels(self) -> torch.Tensor:
        """Candidate levels ``[K]`` (float64), from 0 to ``level_max``."""
        lv = torch.linspace(0.0, self.level_max, self.level_count, dtype=torch.float64)
        check_levels(lv)
        return lv


def draw_states(system, n: int, conflict: bool, radius: float, generator: torch.Generator, dtype) -> torch.Tensor:
    """``n`` observations ``[n, D]`` of the verification's distributions (``verify`` in
    :mod:`.verification` draws the same ones before its rejection step): uniform over V̂'s domain,
    or (``conflict``) every state with one pair on a near-collision course reaching the disk of
    ``radius`` (m) within the horizon."""
    return verification_states(system, n, verification_sampling(conflict, radius), generator, dtype)


def stream_seeds(seed: int, distribution: str) -> dict[str, int]:
    """Generator seed of each set (:data:`STREAMS`) of ``distribution``: distinct by construction."""
    d = DISTRIBUTIONS.index(distribution)
    seeds = {name: int(seed) * 7919 + stream + d for name, stream in STREAMS.items()}
    if len(set(seeds.values())) != len(seeds):
        raise RuntimeError(f"calibration and test streams coincide: {seeds}")
    return seeds


@torch.no_grad()
def level_outcomes(vhat, obs: torch.Tensor, levels: torch.Tensor, z_tolerance: float, dt: float, substeps: int,
                   chunk: int = 4096) -> tuple[torch.Tensor, torch.Tensor]:
    """``(accepted [K, M], violated [K, M])`` (bool) of states ``obs [M, D]`` at each level
    ``levels [K]``: feasible in the deployed search at δ_k; rollout from ``z*_{δ_k}`` closer than
    the collision radius (False where not accepted)."""
    grid = ZGrid.of(vhat.z_max, z_tolerance)
    r_col = vhat.system.spec.collision_radius
    n = vhat.system.spec.n_neighbours
    K, M = levels.numel(), obs.shape[0]
    accepted = torch.zeros(K, M, dtype=torch.bool)
    violated = torch.zeros(K, M, dtype=torch.bool)
    for k, delta in enumerate(levels.tolist()):
        for i in range(0, M, chunk):
            o = obs[i:i + chunk]
            res = cold_search(at_level(vhat, SafetyLevel((), (float(delta),), n)), o, grid, with_grad=False)
            acc = res.feasible.cpu()
            accepted[k, i:i + o.shape[0]] = acc
            rows = acc.nonzero(as_tuple=True)[0]
            if rows.numel():
                out = rollout(vhat, o[rows.to(o.device)], res.z[rows.to(o.device)], dt, substeps)
                violated[k, i + rows] = (out["min_distance"] < r_col).cpu()
    return accepted, violated


def _rows(levels, acc, vio, bins, n_bins, test_at, test_bins, settings: CalibrationSettings, split: str) -> list[dict]:
    """Rule 1 and rule 3 (:mod:`.conformal`) for every (ε, β) and bin of ``split`` (``pooled``: one bin)."""
    labels = bin_labels(settings.speed_edges) if split == "binned" else bin_labels(())
    out = []
    for eps in settings.epsilons:
        for beta in settings.betas:
            for b in range(n_bins):
                cols = (bins == b) if split == "binned" else torch.ones_like(bins, dtype=torch.bool)
                cert = certify(levels, acc[:, cols], vio[:, cols], eps, beta)
                k = cert["index"]
                tcols = (test_bins == b) if split == "binned" else torch.ones_like(test_bins, dtype=torch.bool)
                if k is None:
                    test = held_out(0, 0, int(tcols.sum()), eps, beta)
                else:
                    t_acc, t_vio = test_at(k)
                    a = t_acc & tcols
                    test = held_out(int((a & t_vio).sum()), int(a.sum()), int(tcols.sum()), eps, beta)
                n_cal = int(cols.sum())
                out.append({"epsilon": eps, "beta": beta, "bin": b, "bin_label": labels[b], "delta": cert["level"],
                            "level_index": k,
                            "calibration": {"samples": n_cal,
                                            "accepted": cert["accepted"][k] if k is not None else 0,
                                            "accepted_fraction": (cert["accepted"][k] / n_cal if n_cal else 0.0) if k is not None else 0.0,
                                            "violations": cert["violations"][k] if k is not None else 0,
                                            "bound": cert["bounds"][k] if k is not None else None},
                            "test": test})
    return out


def _curve(acc: torch.Tensor, vio: torch.Tensor) -> dict:
    """Per candidate level (rows of ``acc``/``vio`` ``[K, M]``): accepted states, their share of
    the M samples, violations among them and their rate (0 where none is accepted)."""
    m, k = acc.sum(1), (acc & vio).sum(1)
    return {"accepted": m.tolist(), "accepted_fraction": (m / max(1, acc.shape[1])).tolist(), "violations": k.tolist(),
            "violation_rate": torch.where(m > 0, k / m.clamp_min(1), torch.zeros(m.shape, dtype=torch.float64)).tolist()}


def calibrate_distribution(vhat, settings: CalibrationSettings, scenario: ScenarioSettings, distribution: str,
                           z_tolerance: float) -> dict:
    """The calibration of one distribution (module docstring): seeds and fingerprints of both sets,
    the per-level curve of the calibration set, and the pooled and binned rows."""
    p = next(vhat.net.parameters())
    n = vhat.system.spec.n_neighbours
    seeds = stream_seeds(settings.seed, distribution)
    sets = {name: draw_states(vhat.system, size, distribution == "conflict", scenario.conflict_radius,
                              torch.Generator().manual_seed(seeds[name]), p.dtype).to(p.device)
            for name, size in (("calibration", settings.samples), ("test", settings.test_samples))}
    assert_disjoint(sets["calibration"].cpu(), sets["test"].cpu())
    levels = settings.levels()
    acc, vio = level_outcomes(vhat, sets["calibration"], levels, z_tolerance, scenario.dt, scenario.substeps)
    edges = settings.speed_edges
    bins = speed_bin(closing_speed(sets["calibration"], n), edges).cpu()
    test_bins = speed_bin(closing_speed(sets["test"], n), edges).cpu()
    cache: dict[int, tuple[torch.Tensor, torch.Tensor]] = {}

    def test_at(k: int):
        if k not in cache:
            a, v = level_outcomes(vhat, sets["test"], levels[k:k + 1], z_tolerance, scenario.dt, scenario.substeps)
            cache[k] = (a[0], v[0])
        return cache[k]

    return {"seeds": seeds, "samples": {k: int(v.shape[0]) for k, v in sets.items()},
            "fingerprints": {k: fingerprint(v) for k, v in sets.items()}, "speed_edges": list(edges),
            "bin_labels": bin_labels(edges), "calibration_bin_counts": torch.bincount(bins, minlength=len(edges) + 1).tolist(),
            "curve": _curve(acc, vio), "bin_curves": [_curve(acc[:, bins == b], vio[:, bins == b]) for b in range(len(edges) + 1)],
            "pooled": _rows(levels, acc, vio, bins, 1, test_at, test_bins, settings, "pooled"),
            "binned": _rows(levels, acc, vio, bins, len(edges) + 1, test_at, test_bins, settings, "binned")}


def calibrate(vhat, settings: CalibrationSettings, scenario: ScenarioSettings, z_tolerance: float) -> dict:
    """The calibration report of ``vhat`` on every configured distribution (JSON-ready)."""
    return {"horizon": vhat.horizon, "z_tolerance": z_tolerance, "dt": scenario.dt, "substeps": scenario.substeps,
            "seed": settings.seed, "levels": settings.levels().tolist(),
            "distributions": {d: calibrate_distribution(vhat, settings, scenario, d, z_tolerance) for d in settings.distributions}}
