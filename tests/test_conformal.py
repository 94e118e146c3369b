"""Issue 62: the certificate of a safety level (conformal.py) on a case whose answer is known by
construction, the held-out coverage, leakage detection and early errors; the calibration of a
tiny V̂ through the command's code path (calibration.py), its table and the level read back."""

import json
import math

import pytest
import torch

from madpinn.value_functions.calibration import CalibrationSettings, calibrate, draw_states, stream_seeds
from madpinn.evaluation.calibration_table import write_calibration_table
from madpinn.value_functions.conformal import LeakageError, assert_disjoint, certify, coverage_met, held_out
from madpinn.value_functions.safety_level import read_level
from madpinn.value_functions.verification import ScenarioSettings
from policy_models import tiny_models

EPS, BETA = 0.05, 1e-3
LEVELS = torch.linspace(0.0, 0.6, 13, dtype=torch.float64)   # step 0.05
TRUE_LEVEL = 1.0 / 3.0
"""synthetic case: score s ~ U(−1, 1); a state violates with probability 0.2 where s > −0.5, never
below. Accepted at δ: s ≤ −δ, violation rate 0.2·(0.5 − δ)/(1 − δ) for δ < 0.5 (0 beyond), which
is ≤ ε = 0.05 exactly from δ = 1/3 on."""


def _synthetic(m: int, seed: int):
    g = torch.Generator().manual_seed(seed)
    s = 2 * torch.rand(m, generator=g, dtype=torch.float64) - 1
    violates = (s > -0.5) & (torch.rand(m, generator=g, dtype=torch.float64) < 0.2)
    accepted = s[None, :] <= -LEVELS[:, None]                     # [K, M]
    return accepted, violates[None, :].expand_as(accepted)


def _true_rate(delta: float) -> float:
    return 0.2 * (0.5 - delta) / (1 - delta) if delta < 0.5 else 0.0


def test_certified_level_is_at_least_the_true_one_and_covers_held_out_states():
    """With 20 000 calibration samples the certified δ lies in [1/3, 0.5]: at least the true level
    (what the certificate promises, with confidence 1 − β) and at most where no state violates; on
    20 000 fresh states its held-out rate meets the coverage rule and the exact rate is ≤ ε."""
    acc, vio = _synthetic(20_000, seed=1)
    cert = certify(LEVELS, acc, vio, EPS, BETA)
    assert cert["level"] is not None and TRUE_LEVEL <= cert["level"] <= 0.5 + 1e-12
    assert cert["bounds"][cert["index"]] <= EPS and all(b > EPS for b in cert["bounds"][:cert["index"]])
    assert _true_rate(cert["level"]) <= EPS
    t_acc, t_vio = _synthetic(20_000, seed=2)
    k = cert["index"]
    out = held_out(int((t_acc[k] & t_vio[k]).sum()), int(t_acc[k].sum()), 20_000, EPS, BETA)
    assert out["coverage_met"] and out["accepted_fraction"] > 0.2


def test_no_level_when_too_few_samples_and_coverage_rule():
    """30 samples cannot certify ε = 0.05 at β = 10⁻³ (even 0 of 30 bounds at ≈ 0.2 after the union
    bound): no level. The coverage rule rejects a count far above ε and accepts one at ε."""
    acc, vio = _synthetic(30, seed=3)
    assert certify(LEVELS, acc, vio, EPS, BETA)["level"] is None
    assert not coverage_met(60, 400, EPS, BETA)          # 15 % of 400 against ε = 5 %
    assert coverage_met(20, 400, EPS, BETA)              # exactly ε
    assert held_out(0, 0, 10, EPS, BETA)["coverage_met"]   # vacuous, reported with accepted = 0


@pytest.mark.parametrize("eps,beta", [(0.0, 1e-3), (1.0, 1e-3), (0.1, 0.0), (0.1, 1.0), (-0.1, 0.5), (0.1, float("nan"))])
def test_bad_risk_parameters_fail_early(eps, beta):
    acc, vio = _synthetic(10, seed=0)
    with pytest.raises(ValueError, match="ε|β"):
        certify(LEVELS, acc, vio, eps, beta)
    with pytest.raises(ValueError, match="ε|β"):
        CalibrationSettings(samples=4, test_samples=4, seed=100, epsilons=(eps,), betas=(beta,), level_max=0.2,
                            level_count=3, speed_edges=(), distributions=("uniform",))


def test_bad_calibration_settings_fail_early():
    good = dict(samples=4, test_samples=4, seed=100, epsilons=(0.1,), betas=(1e-3,), level_max=0.2, level_count=3,
                speed_edges=(2.0,), distributions=("uniform",))
    for change, match in (({"seed": 4}, "validation seeds"), ({"level_count": 1}, "level_count"),
                          ({"speed_edges": (3.0, 1.0)}, "ascend"), ({"distributions": ("grid",)}, "distributions")):
        with pytest.raises(ValueError, match=match):
            CalibrationSettings(**{**good, **change})
    with pytest.raises(ValueError, match="start at 0"):
        certify(torch.tensor([0.1, 0.2]), torch.ones(2, 3, dtype=torch.bool), torch.zeros(2, 3, dtype=torch.bool), 0.1, 1e-3)


def test_leakage_is_detected():
    """Sets drawn from the same stream share every state: the check fails; one shared row is
    enough; the calibration's own streams are distinct and give disjoint sets."""
    vhat, _ = tiny_models()
    draw = lambda seed: draw_states(vhat.system, 64, True, 0.3, torch.Generator().manual_seed(seed), torch.float32)
    seeds = stream_seeds(100, "conflict")
    cal, test = draw(seeds["calibration"]), draw(seeds["test"])
    assert_disjoint(cal, test)
    with pytest.raises(LeakageError, match="64 held-out"):
        assert_disjoint(cal, draw(seeds["calibration"]))
    with pytest.raises(LeakageError, match="1 held-out"):
        assert_disjoint(cal, torch.cat([test[:-1], cal[5:6]]))
    assert len({s for d in ("uniform", "conflict") for s in stream_seeds(100, d).values()}) == 4


def test_smoke_calibration_through_the_command_path(tmp_path):
    """A tiny V̂, tiny sets: the report has every (distribution, split, ε, β, bin) row, disjoint
    sets named by fingerprint, accepted fractions in [0, 1]; the table is written; the policy's
    reader returns one δ pooled and one per bin."""
    vhat, _ = tiny_models()
    settings = CalibrationSettings(samples=48, test_samples=48, seed=100, epsilons=(0.5, 0.1), betas=(0.05,),
                                   level_max=0.2, level_count=3, speed_edges=(2.0,), distributions=("uniform", "conflict"))
    scenario = ScenarioSettings(samples=1, dt=0.02, substeps=2, seed=100, betas=(1e-3,), conflict_radius=0.3)
    report = calibrate(vhat, settings, scenario, 1e-3)
    for dist, block in report["distributions"].items():
        assert block["fingerprints"]["calibration"] != block["fingerprints"]["test"]
        assert len(block["pooled"]) == 2 and len(block["binned"]) == 2 * 2
        for row in block["pooled"] + block["binned"]:
            assert 0.0 <= row["test"]["accepted_fraction"] <= 1.0
            assert row["delta"] is None or 0.0 <= row["delta"] <= 0.2
    path = tmp_path / "cal.json"
    path.write_text(json.dumps(report))
    paths = write_calibration_table(report, tmp_path / "t.csv", tmp_path / "t.md", tmp_path / "t.html")
    assert all(p.stat().st_size > 0 for p in paths) and "Coverage met" in paths[1].read_text()
    n = vhat.system.spec.n_neighbours
    pooled = read_level(path, "conflict", 0.5, 0.05, False, n)
    binned = read_level(path, "conflict", 0.5, 0.05, True, n)
    assert pooled.edges == () and len(pooled.deltas) == 1 and binned.edges == (2.0,) and len(binned.deltas) == 2
    assert all(d >= 0.0 or math.isinf(d) for d in binned.deltas)
    with pytest.raises(ValueError, match="no pooled level for ε = 0.02"):
        read_level(path, "conflict", 0.02, 0.05, False, n)


def test_calibrate_vhat_command_at_smoke_size(tmp_path):
    """`calibrate-vhat` with the smoke overlay's sizes on the tiny V̂: the JSON report (its
    calibration and held-out sets disjoint, named by seed and fingerprint) and the three tables."""
    from conftest import REPO, SMOKE
    from madpinn.commands import main
    from policy_models import tiny_model_dir

    out = {k: tmp_path / f"cal.{k}" for k in ("json", "csv", "md", "html")}
    assert main(["calibrate-vhat", "--config", str(REPO / "config.yaml"), str(SMOKE), "--model",
                 f"vhat={tiny_model_dir() / 'vhat.pt'}", "--out", str(out["json"]), "--table-csv", str(out["csv"]),
                 "--table-md", str(out["md"]), "--table-html", str(out["html"]), "--no-track"]) == 0
    report = json.loads(out["json"].read_text())
    for block in report["distributions"].values():
        assert block["samples"] == {"calibration": 48, "test": 48}
        assert block["seeds"]["calibration"] != block["seeds"]["test"]
        assert block["fingerprints"]["calibration"] != block["fingerprints"]["test"]
    assert all(p.stat().st_size > 0 for p in out.values())


@pytest.mark.parametrize("bad,key", [({"value_functions": {"vhat": {"validation": {"calibration": {"epsilons": [0.0]}}}}},
                                      "calibration.epsilons"),
                                     ({"value_functions": {"vhat": {"validation": {"calibration": {"betas": [1.5]}}}}},
                                      "calibration.betas"),
                                     ({"value_functions": {"vhat": {"validation": {"calibration": {"seed": 3}}}}},
                                      "calibration.seed"),
                                     ({"methods": {"madpinn": {"variants": {"cp": {"label": "x", "conformal": {
                                         "distribution": "conflict", "epsilon": 1.0, "beta": 1e-3, "binned": False}}}}}},
                                      "conformal.epsilon")])
def test_bad_settings_fail_at_config_validation(bad, key):
    """Bad ε, β or seed stop the config check (every job's first step), naming the key."""
    from conftest import REPO
    from madpinn.config import ConfigError, deep_merge, load_yaml, validate_config

    with pytest.raises(ConfigError, match=key.replace(".", r"\.")):
        validate_config(deep_merge(load_yaml(REPO / "config.yaml"), bad))
