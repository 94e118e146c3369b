import numpy as np
import pandas as pd
import pytest

from madpinn.evaluation.encounter_hazard import cell_hazard, hazard_by_speed, wilson


def test_cell_hazard_is_the_ratio_of_means_with_an_interval_around_it():
    frame = pd.DataFrame({"safety_rate": [0.9, 0.8, 1.0, 0.7], "encounters_per_agent": [2.0, 2.0, 1.0, 3.0]})
    h = cell_hazard(frame)
    assert h["hazard"] == pytest.approx(0.15 / 2.0)
    assert h["low"] <= h["hazard"] <= h["high"]
    with pytest.raises(ValueError, match="encounters_per_agent"):
        cell_hazard(frame.drop(columns="encounters_per_agent"))


def test_agents_are_binned_by_encounter_speed_and_counted_collided_within_r():
    frame = pd.DataFrame({"agent_encounter_speed": [np.array([0.5, 3.0, np.nan]), np.array([5.0, 2.5, 7.0])],
                          "agent_min_separation": [np.array([0.5, 0.05, 1.0]), np.array([0.08, 0.3, 0.1])]})
    t = hazard_by_speed(frame, [0, 2, 4], collision_radius=0.1)
    assert t["agents"].tolist() == [1, 2, 2] and t["collided"].tolist() == [0, 1, 2]   # the NaN agent is left out
    assert t.loc[2, "hazard"] == 1.0 and t.loc[2, "speed_high"] == float("inf")
    low, high = wilson(1, 2)
    assert 0.0 < low < 0.5 < high < 1.0
