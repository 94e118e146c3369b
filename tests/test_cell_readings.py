"""What every evaluation cell reads from its episodes beside the protocol's figures (issue 60): the
cost and safety at earlier horizons, the speed of each agent's hardest encounter, the job's CPU time."""

import numpy as np

from madpinn.config import load_config
from madpinn.evaluation.cell import CellSettings, run_cell


def _cell(horizons):
    cfg = load_config(["config.yaml"])
    cfg["sim"]["backend"] = "double_integrator"
    cfg["studies"]["main"]["scenarios"] = 4
    cfg["studies"]["main"]["cost_horizons_s"] = horizons
    return run_cell(CellSettings.from_config(cfg, "main", "nominal"), 12, 100, progress=False)


def test_earlier_horizons_are_read_from_the_same_episodes_and_change_nothing_else():
    plain, read = _cell([]), _cell([1.5, 2.0])
    for col in plain.frame.columns:   # the episode itself is the same: every protocol column bitwise
        if col.startswith("agent_"):
            np.testing.assert_array_equal(np.stack(plain.frame[col]), np.stack(read.frame[col]))
        else:
            np.testing.assert_array_equal(plain.frame[col].to_numpy(), read.frame[col].to_numpy())
    s = read.summary
    for h in ("1.5s", "2s"):
        assert 0.0 <= s[f"safety_rate_at_{h}"] <= 1.0
        assert s[f"safety_rate_at_{h}"] >= s["safety_rate"]   # collisions only accumulate with time
        assert s[f"cost_all_at_{h}"] > 0.0
    assert not any("_at_" in k for k in plain.summary)


def test_every_cell_records_encounter_speeds_cpu_time_and_its_cpu():
    cell = _cell([])
    speeds = np.concatenate(cell.frame["agent_encounter_speed"].to_list())
    finite = speeds[np.isfinite(speeds)]
    assert finite.size > 0 and (finite >= 0).all()
    assert (finite <= 2 * np.sqrt(2) * 4.0 + 1e-6).all()   # two agents at v_max = 4 m/s per axis
    assert np.isfinite(cell.summary["encounter_speed_mean"])
    assert cell.summary["cpu_s"] > 0.0
    from madpinn.machine import cpu_model

    assert cell.summary["cpu_model"] == cpu_model() and cpu_model() != ""   # the CPU behind cpu_s (benchmarks/zsearch_floor.py)
