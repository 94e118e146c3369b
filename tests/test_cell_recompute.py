"""scripts/cell_recompute.py (issue 66 item 2, issue 63 item 1): a recomputed cell against a committed
entry or against the same cell computed by the code at another commit. Small frames written here;
the comparison itself is the script's."""

from __future__ import annotations

import importlib.util
import json
from pathlib import Path

import pandas as pd
import pytest

REPO = Path(__file__).resolve().parents[1]


@pytest.fixture(scope="module")
def script():
    spec = importlib.util.spec_from_file_location("cell_recompute", REPO / "scripts" / "cell_recompute.py")
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def write_cell(path: Path, frame: pd.DataFrame) -> Path:
    """A cell as the evaluate job writes it: the frame and its summary beside it (the figures are
    the frame's means)."""
    path.parent.mkdir(parents=True, exist_ok=True)
    frame.to_parquet(path)
    summary = {"study": "main", "run": "mppi", "n_agents": 4, "seed": 0, "elapsed_s": 1.0,
               "safety_rate": float(frame.safety_rate.mean()), "safe_scenarios": float(frame.safe.mean()),
               "cost_all_time_avg": float(frame.cost_all_time_avg.mean())}
    path.with_suffix(".json").write_text(json.dumps(summary))
    return path


FRAME = pd.DataFrame({"scenario": [0, 1, 2, 3], "safety_rate": [1.0, 0.75, 1.0, 0.5], "safe": [1.0, 0.0, 1.0, 0.0],
                      "cost_all_time_avg": [0.5, 0.75, 0.625, 1.0]})


def compare(script, tmp_path: Path, now: pd.DataFrame) -> dict:
    ref = write_cell(tmp_path / "ref" / "n4_seed0.parquet", FRAME)
    cell = write_cell(tmp_path / "now" / "n4_seed0.parquet", now)
    return script.compare_with(cell, [("ref", ref.with_suffix(".json"), ref)])


def test_the_same_frame_is_bit_equal(script, tmp_path):
    row = compare(script, tmp_path, FRAME.copy())
    assert row["frame_equal"] and row["figures_equal"] and row["scenarios_differing"] == 0
    assert script.frame_verdict(row) == "yes"


def test_a_new_column_leaves_the_shared_columns_compared_bit_for_bit(script, tmp_path):
    row = compare(script, tmp_path, FRAME.assign(encounters_per_agent=[1.0, 2.0, 0.0, 3.0]))
    assert not row["frame_equal"] and row["shared_columns_equal"] and row["figures_equal"]
    assert row["columns_added"] == ["encounters_per_agent"] and row["columns_removed"] == []
    assert script.frame_verdict(row) == "yes on the shared columns (+encounters_per_agent)"


def test_a_changed_scenario_is_counted_and_scaled_by_the_cells_half_width(script, tmp_path):
    moved = FRAME.copy()
    moved.loc[1, "safety_rate"] = 1.0          # one scenario: 0.75 -> 1.0, the mean +0.0625
    row = compare(script, tmp_path, moved)
    assert not row["frame_equal"] and not row["shared_columns_equal"] and not row["figures_equal"]
    assert row["scenarios_differing"] == 1
    assert row["delta"]["safety_rate"] == pytest.approx(0.0625)
    half_width = 1.96 * FRAME.safety_rate.std(ddof=1) / 2          # √4 scenarios
    assert row["delta_over_half_width"]["safety_rate"] == pytest.approx(0.0625 / half_width)
    assert row["delta_over_half_width"]["safe_scenarios"] == 0
    assert script.frame_verdict(row) == "no"
