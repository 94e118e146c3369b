"""V̂'s recipe re-chosen on validation seeds (issue 61 item 4): the pre-registered rule
(docs/findings/2026-11-29-vhat-recipe-preregistered.md) judges each component against the training
band, the quorum and the degenerate band behave as written, bad declarations fail before any job,
the command writes its page from cell files and the claims page states the choice. Cells are built
with known safety, so every verdict follows by construction."""

from __future__ import annotations

import json
import subprocess
import sys

import pandas as pd
import pytest

from conftest import REPO
from madpinn.config import ConfigError, deep_merge, load_config, validate_config
from madpinn.evaluation.recipe_choice import HARMFUL, INDISTINGUISHABLE, NEEDED, cell_safety, choice_sentence, choose
from madpinn.evaluation.recipe_settings import RecipeSettings

OVERLAY = REPO / "workflow" / "configs" / "vhat_recipe.yaml"
DECIDING = [("vhat_budget_small", 12), ("vhat_budget_small", 16), ("vhat_budget_circle", 16)]
BAND = {"madpinn-cs": 0.95, "madpinn-s1": 0.96, "madpinn-s2": 0.97}   # the band: 95–97 %


@pytest.fixture(scope="module")
def cfg() -> dict:
    return load_config([REPO / "config.yaml", OVERLAY])


@pytest.fixture(scope="module")
def settings(cfg) -> RecipeSettings:
    return RecipeSettings.from_config(cfg)


def cell(study: str, run: str, n: int, safety: float, seed: int = 100, scenarios: int = 10) -> pd.DataFrame:
    """``scenarios`` scenario rows of one cell, each with this safety rate (the cell's safety exactly)."""
    return pd.DataFrame({"study": study, "run": run, "n_agents": n, "seed": seed, "scenario": range(scenarios),
                         "safety_rate": safety})


def cells(minus_f: list[float], minus_c: list[float], band: dict | None = None, reported: bool = False) -> pd.DataFrame:
    """Scenario rows of the deciding cells (and the reported ones): the band's models at ``band`` in
    every cell, −F and −C at the given safety per deciding cell."""
    band = BAND if band is None else band
    where = DECIDING + ([("vhat_budget", n) for n in (64, 128, 256)] if reported else [])
    f = minus_f + [minus_f[0]] * (len(where) - len(minus_f))
    c = minus_c + [minus_c[0]] * (len(where) - len(minus_c))
    frames = [cell(st, run, n, v) for st, n in where for run, v in band.items()]
    frames += [cell(st, "madpinn-b05", n, v) for (st, n), v in zip(where, f)]
    frames += [cell(st, "madpinn", n, v) for (st, n), v in zip(where, c)]
    return pd.concat(frames, ignore_index=True)


def verdicts(frame: pd.DataFrame, settings: RecipeSettings) -> dict:
    return {x: (c["verdict"], c["action"]) for x, c in choose(cell_safety(frame), settings)[1]["components"].items()}


def test_needed_harmful_and_indistinguishable_by_construction(settings):
    # −F 2 points below the band's minimum everywhere; −C 2 points above its maximum everywhere
    v = verdicts(cells([0.93] * 3, [0.99] * 3), settings)
    assert v == {"F": (NEEDED, "kept"), "C": (HARMFUL, "replaced by the paper's uniform states")}
    # the other way round: F harmful (dropped), C needed (kept)
    v = verdicts(cells([0.99] * 3, [0.93] * 3), settings)
    assert v == {"F": (HARMFUL, "dropped"), "C": (NEEDED, "kept")}
    # inside the band, or beyond it by less than the margin: training variance; F kept, C replaced
    v = verdicts(cells([0.951] * 3, [0.9899] * 3), settings)
    assert v == {"F": (INDISTINGUISHABLE, "kept"), "C": (INDISTINGUISHABLE, "replaced by the paper's uniform states")}


def test_the_quorum_and_the_other_side(settings):
    # below in one deciding cell only: short of the quorum of 2
    assert verdicts(cells([0.90, 0.96, 0.96], [0.96] * 3), settings)["F"][0] == INDISTINGUISHABLE
    # below in two: needed
    assert verdicts(cells([0.90, 0.90, 0.96], [0.96] * 3), settings)["F"][0] == NEEDED
    # below in two but above in the third: neither
    assert verdicts(cells([0.90, 0.90, 0.995], [0.96] * 3), settings)["F"][0] == INDISTINGUISHABLE
    # the quorum is the config's: 3 makes two cells too few
    strict = RecipeSettings(**{**settings.__dict__, "quorum": 3})
    assert verdicts(cells([0.90, 0.90, 0.96], [0.96] * 3), strict)["F"][0] == INDISTINGUISHABLE


def test_reported_cells_decide_nothing(settings):
    frame = cells([0.96] * 3, [0.96] * 3, reported=True)
    large = frame["study"] == "vhat_budget"
    frame.loc[large & (frame["run"] == "madpinn"), "safety_rate"] = 0.50   # far below the band at 64 / 128 / 256
    table, choice = choose(cell_safety(frame), settings)
    assert choice["components"]["C"]["verdict"] == INDISTINGUISHABLE
    assert table.loc[table["role"] == "reported", "below_C"].all() and len(choice["reported"]) == 3


def test_a_degenerate_band_is_provisional_and_rereading_with_s2_can_flip_the_verdict(settings):
    without_s2 = {"madpinn-cs": 0.95, "madpinn-s1": 0.96}
    frame = cells([0.93] * 3, [0.96] * 3, band=without_s2)       # −F 2 points below the band over base and s1
    table, choice = choose(cell_safety(frame), settings)
    assert choice["provisional"] and choice["missing_replicates"] == ["madpinn-s2"]
    assert choice["band_runs"] == ["madpinn-cs", "madpinn-s1"] and choice["components"]["F"]["verdict"] == NEEDED
    assert "provisional" in choice_sentence(choice)
    # s2's cells arrive at 94 %: the band widens to 94–96 and −F's 93 % is within training variance
    later = pd.concat([frame, *[cell(st, "madpinn-s2", n, 0.94) for st, n in DECIDING]], ignore_index=True)
    _, choice = choose(cell_safety(later), settings)
    assert not choice["provisional"] and choice["components"]["F"]["verdict"] == INDISTINGUISHABLE


def test_cells_the_rule_cannot_read_are_refused(settings):
    frame = cells([0.93] * 3, [0.99] * 3)
    with pytest.raises(ValueError, match=r"vhat_budget_circle N=16 madpinn'"):
        choose(cell_safety(frame[~((frame["study"] == "vhat_budget_circle") & (frame["run"] == "madpinn"))]), settings)
    with pytest.raises(ValueError, match="no training-seed replicate"):
        choose(cell_safety(frame[~frame["run"].isin(["madpinn-s1", "madpinn-s2"])]), settings)
    with pytest.raises(ValueError, match=r"protocol seeds \[0\]"):
        choose(cell_safety(pd.concat([frame, cell("vhat_budget_small", "madpinn-cs", 12, 0.9, seed=0)])), settings)
    with pytest.raises(ValueError, match="outside vhat_recipe: \\['main'\\]"):
        choose(cell_safety(pd.concat([frame, cell("main", "madpinn-cs", 12, 0.9)])), settings)


def test_settings_come_from_the_config_and_bad_declarations_fail_early(cfg, settings):
    assert settings.band_runs == ("madpinn-cs", "madpinn-s1", "madpinn-s2")
    assert settings.components == {"F": "madpinn-b05", "C": "madpinn"}
    assert settings.deciding == tuple(DECIDING) and settings.margin_points == 2.0 and settings.quorum == 2
    bare = load_config([REPO / "config.yaml"])
    assert bare["vhat_recipe"] is None   # off unless configured
    with pytest.raises(ConfigError, match="'vhat_recipe': not configured"):
        RecipeSettings.from_config(bare)
    for change, message in [
        ({"vhat_recipe": {"replicates": ["madpinn-s9"]}}, "'vhat_recipe.replicates': unknown run 'madpinn-s9'"),
        ({"vhat_recipe": {"components": {"C": "madpinn-s1"}}}, "must be distinct runs"),
        ({"vhat_recipe": {"deciding": {"nope": [12]}}}, "'vhat_recipe.deciding': unknown study 'nope'"),
        ({"vhat_recipe": {"deciding": {"vhat_budget_circle": [12]}}}, "study 'vhat_budget_circle' has no agent counts \\[12\\]"),
        ({"vhat_recipe": {"reported": {"vhat_budget": [100]}}}, "'vhat_recipe.reported.vhat_budget': study 'vhat_budget' has no agent counts"),
        ({"studies": {"vhat_budget_circle": {"runs": ["madpinn-cs", "madpinn-s1", "madpinn-s2", "madpinn-b05"]}}},
         "study 'vhat_budget_circle' does not run \\['madpinn'\\]"),
        ({"studies": {"vhat_budget_small": {"seeds": [0]}}}, "validation seeds ≥ 100 only"),
        ({"vhat_recipe": {"quorum": 4}}, "'vhat_recipe.quorum': 4 exceeds the 3 deciding cells"),
        ({"vhat_recipe": {"margin_points": 0}}, "vhat_recipe.margin_points"),
    ]:
        changed = deep_merge(cfg, change)
        with pytest.raises(ConfigError, match=message):
            validate_config(changed)   # the schema's bounds
            RecipeSettings.from_config(changed)   # the section's rules


def _write_cells(frame: pd.DataFrame, root) -> list[str]:
    paths = []
    for (study, run, n, seed), g in frame.groupby(["study", "run", "n_agents", "seed"]):
        p = root / "eval" / study / run / f"n{n}_seed{seed}.parquet"
        p.parent.mkdir(parents=True, exist_ok=True)
        g.to_parquet(p)
        paths.append(str(p))
    return paths


def test_the_command_writes_the_page_the_choice_and_the_rows(tmp_path):
    paths = _write_cells(cells([0.93] * 3, [0.96] * 3, reported=True), tmp_path)
    out = tmp_path / "out"
    cmd = [sys.executable, "-m", "madpinn", "vhat-recipe", "--config", str(REPO / "config.yaml"), str(OVERLAY),
           "--inputs", *paths, "--out-dir", str(out), "--no-track"]
    proc = subprocess.run(cmd, cwd=REPO, capture_output=True, text=True, timeout=300)
    assert proc.returncode == 0, proc.stderr[-2000:]
    choice = json.loads((out / "vhat_recipe.json").read_text())
    assert choice["components"]["F"]["verdict"] == NEEDED and choice["components"]["C"]["verdict"] == INDISTINGUISHABLE
    assert choice["seeds"] == [100] and not choice["provisional"]
    rows = pd.read_csv(out / "vhat_recipe.csv")
    assert len(rows) == 6 * 5   # six cells, five models
    minus_f = rows[(rows["model"] == "−F") & (rows["role"] == "deciding")]
    assert minus_f["below_band"].all() and (minus_f["band_lo"] == 95.0).all() and (minus_f["band_hi"] == 97.0).all()
    md = (out / "vhat_recipe.md").read_text()
    assert "the fine-tuning stage (F) is needed, so kept" in md and "| vhat_budget_small N=12 | 95.0–97.0 (3 models) |" in md
    assert "## Reported beside (decide nothing)" in md and "93.0 ▼" in md
    # without the section the command says what is missing
    bare = subprocess.run(cmd[:6] + cmd[7:], cwd=REPO, capture_output=True, text=True, timeout=300)
    assert bare.returncode != 0 and "'vhat_recipe': not configured" in bare.stderr


def test_the_claims_page_states_the_choice_or_that_it_is_being_remade(settings):
    from madpinn.evaluation.claims import build_claims

    report = json.loads((REPO / "paper_figures" / "reproduction.json").read_text())
    before = build_claims(report)["provenance"]["vhat_recipe"]
    assert "protocol seeds 0 and 1" in before and "being re-made" in before
    assert "docs/findings/2026-11-21-vhat-training-results.md" in before
    _, choice = choose(cell_safety(cells([0.99] * 3, [0.93] * 3)), settings)
    line = build_claims(report, recipe=choice)["provenance"]["vhat_recipe"]
    assert line.startswith("the V̂ recipe was re-chosen on validation seed 100 (vhat_budget_small at 12 and 16 agents, "
                           "vhat_budget_circle at 16 agents)")
    assert "the fine-tuning stage (F) is harmful, so dropped; conflict sampling (C) is needed, so kept" in line
    assert "provisional" not in line


def test_the_overlay_plans_the_page_and_hands_it_to_the_claims(tmp_path):
    """Dry run of config.yaml + the overlay: the page's rule reads the s2 and nocs cells of the budget
    studies, and the claims job reads its choice."""
    from conftest import run_snakemake

    proc = run_snakemake(tmp_path, "-n", "-j1", "vhat_recipe", "claims_table", configfiles=(OVERLAY,))
    out = proc.stdout + proc.stderr
    assert "python -m madpinn vhat-recipe" in out and "--vhat-recipe results/paper_figures/vhat_recipe/vhat_recipe.json" in out
    for study in ("vhat_budget_small", "vhat_budget_circle"):
        for run in ("madpinn-s2", "madpinn"):
            assert f"eval/mujoco/{study}/{run}/n16_seed100.parquet" in out, (study, run)
    # a broken section stops the plan in one line, before any job
    bad = tmp_path / "bad.yaml"
    bad.write_text("vhat_recipe: {quorum: 4}\n")
    proc = run_snakemake(tmp_path, "-n", "-j1", "vhat_recipe", configfiles=(OVERLAY, bad), check=False)
    assert proc.returncode != 0 and "'vhat_recipe.quorum': 4 exceeds the 3 deciding cells" in proc.stderr
    assert "Traceback" not in proc.stderr


def test_the_adopted_recipes_band_is_reported_beside_and_decides_nothing(settings, cfg, tmp_path):
    """Issue 60 item 3: the deployed V̂ (−C since the choice) and its training-seed replicates span a
    second band per cell, written on the page, in the choice and in the claims page's provenance line;
    the verdicts are those without it."""
    from madpinn.evaluation.recipe_page import write_recipe_page

    assert settings.adopted_band == ("madpinn", "madpinn-us1", "madpinn-us2")
    frame = cells([0.96] * 3, [0.90] * 3, reported=True)   # −C at 90 % everywhere: needed by the rule
    where = DECIDING + [("vhat_budget", n) for n in (64, 128, 256)]
    seeds = pd.concat([cell(st, run, n, v) for st, n in where for run, v in (("madpinn-us1", 0.92), ("madpinn-us2", 0.95))],
                      ignore_index=True)
    _, alone = choose(cell_safety(frame), settings)
    table, choice = choose(cell_safety(pd.concat([frame, seeds], ignore_index=True)), settings)
    assert choice["components"] == alone["components"]   # the band decides nothing
    band = choice["adopted_band"]
    assert band["runs"] == list(settings.adopted_band) and len(band["cells"]) == 6
    first = band["cells"][0]
    assert (first["lo"], first["hi"], first["models"]) == (pytest.approx(90.0), pytest.approx(95.0), 3)
    assert first["mean"] == pytest.approx((90 + 92 + 95) / 3)
    assert alone["adopted_band"]["cells"][0]["models"] == 1   # only the deployed run's cells: a one-model band, said so
    line = choice_sentence(choice)
    assert "Since: the adopted recipe's training band over madpinn, madpinn-us1, madpinn-us2, deciding nothing" in line
    assert "vhat_budget N=256 90.0–95.0 % (3 models)" in line
    paths = _write_cells(pd.concat([frame, seeds], ignore_index=True), tmp_path)
    md = write_recipe_page(paths, settings, tmp_path / "page")[1].read_text()
    assert "## The adopted recipe's training band" in md and "| 90.0–95.0 (92.3; 3 models) |" in md and "| 95.0–97.0 |" in md
    # a run the config does not know is refused before any job
    bad = deep_merge(cfg, {"vhat_recipe": {"adopted_band": ["madpinn-nosuch"]}})
    with pytest.raises(ConfigError, match="'vhat_recipe.adopted_band': unknown run 'madpinn-nosuch'"):
        RecipeSettings.from_config(bad)
