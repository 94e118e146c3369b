"""README's generated blocks (headline numbers, claims verdicts) equal their rendering from the
committed report, and the rendering follows the report (madpinn/evaluation/readme_blocks.py)."""

from __future__ import annotations

import copy
import json
import shutil
import subprocess
import sys
from pathlib import Path

import pytest

from madpinn.evaluation.readme_blocks import BLOCKS, block, headline_lines, render_readme, rendered

REPO = Path(__file__).resolve().parents[1]
FIGURES = REPO / "paper_figures"


@pytest.mark.parametrize("name", sorted(BLOCKS))
def test_readme_blocks_are_generated(name):
    lines = block((REPO / "README.md").read_text(), name)
    assert lines is not None, f"README.md lacks the {name} block"
    assert lines == rendered(name, FIGURES), (
        f"README's {name} block is stale: run python scripts/update_readme.py")


def test_a_changed_cell_changes_the_headline_and_the_rewrite_is_idempotent(tmp_path):
    report = json.loads((FIGURES / "reproduction.json").read_text())
    changed = copy.deepcopy(report)
    cell = changed["table_ours_scaling"]["madpinn"]["64"]
    cell["safety"] = 0.123456
    before, after = headline_lines(report), headline_lines(changed)
    diff = [line for line in after if line not in before]
    assert len(diff) == 1 and "12.3 (100)" in diff[0] and "Table II" in diff[0]

    figures = tmp_path / "figures"
    figures.mkdir()
    for source in {s for sources, _ in BLOCKS.values() for s in sources}:   # every page a block reads
        (figures / source).parent.mkdir(parents=True, exist_ok=True)
        shutil.copy(FIGURES / source, figures / source)
    (figures / "reproduction.json").write_text(json.dumps(changed))
    readme = tmp_path / "README.md"
    readme.write_text((REPO / "README.md").read_text())
    script = [sys.executable, str(REPO / "scripts" / "update_readme.py"), "--readme", str(readme), "--figures", str(figures)]
    check = subprocess.run([*script, "--check"], capture_output=True, text=True)
    assert check.returncode == 1 and readme.read_text() == (REPO / "README.md").read_text()   # --check writes nothing
    assert subprocess.run(script, capture_output=True, text=True).returncode == 0
    text = readme.read_text()
    assert "12.3 (100)" in text and render_readme(text, figures) == text
    outside = lambda t: t.split("<!-- headline:start")[0] + t.split("<!-- headline:end -->")[1]
    assert outside(text) == outside((REPO / "README.md").read_text())   # nothing outside the blocks moves


def test_a_readme_without_a_block_is_refused(tmp_path):
    with pytest.raises(ValueError, match="lacks the block <!-- headline:start"):
        render_readme("# no blocks here\n", FIGURES)


def test_the_table_ii_block_follows_the_published_readings_verdict():
    """README's Table II sentence is the readings page's verdict (issue 61 item 5: no typed verdict)."""
    from madpinn.evaluation.readme_blocks import table_ii_lines
    from madpinn.evaluation.table_ii_readings import VERDICTS

    verdict = json.loads((FIGURES / "table_ii_final" / "table_ii_readings" / "verdict.json").read_text())   # seed 0, final
    lines = table_ii_lines(verdict)
    assert f"**Table II {verdict['verdict']}.**" in lines[0] and verdict["baselines"]["reading"] in lines[1]
    assert lines[0].startswith("- The final readings on protocol seed 0") and verdict["chosen_on"]["closest"] in lines[0]
    validation = json.loads((FIGURES / "table_ii_readings" / "verdict.json").read_text())   # where they were chosen
    assert table_ii_lines(validation)[0].startswith(f"- Over {validation['readings_judged']} readings")
    changed = copy.deepcopy(verdict)
    changed.update(verdict=VERDICTS[1],
                   reproducing=[{**verdict["closest"], "cost_reading": "÷T"}])
    text = table_ii_lines(changed)[0]
    assert f"**Table II {VERDICTS[1]}.**" in text and "Readings that reproduce it" in text
    assert verdict["closest"]["study"] in text and "The closest reading" not in text
    # the deployed V̂'s training-seed band comes from the recipe page's reported cells, in their order
    recipe = json.loads((FIGURES / "vhat_recipe" / "vhat_recipe.json").read_text())
    cells = [c for c in recipe["adopted_band"]["cells"] if c["role"] == "reported"]
    band = table_ii_lines(verdict, recipe)[1]
    assert band.startswith(lines[1]) and " / ".join(f"{c['lo']:.1f}–{c['hi']:.1f}" for c in cells) in band
    assert table_ii_lines(verdict, {**recipe, "adopted_band": None})[1] == lines[1]   # no band: the line as before
