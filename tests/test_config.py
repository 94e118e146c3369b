import subprocess
import sys

import pytest
import yaml

from madpinn.config import ConfigError, deep_merge, load_config, load_yaml, method_config, validate_config

from conftest import REPO, subprocess_env


@pytest.mark.parametrize(
    "overlay,key",
    [
        ({"sim": {"dt": -0.1}}, "sim.dt"),
        ({"sim": {"backend": "bullet"}}, "sim.backend"),
        ({"studies": {"main": {"scenarios": "many"}}}, "studies.main.scenarios"),
        ({"studies": {"main": {"agent_counts": [3, 0]}}}, "studies.main.agent_counts.1"),
        ({"methods": {"nominal": {"kq": 1.0}}}, "methods.nominal"),
        ({"typo_key": 1}, "<top level>"),
        ({"studies": {"main": {"arena": "huge"}}}, "studies.main.arena"),
        ({"studies": {"main": {"runs": ["nominal-fast"]}}}, "studies.main.runs"),
        ({"studies": {"main": {"runs": ["nosuchmethod"]}}}, "studies.main.runs"),
    ],
)
def test_invalid_config_names_the_key(overlay, key):
    cfg = deep_merge(load_yaml(REPO / "config.yaml"), overlay)
    with pytest.raises(ConfigError) as exc:
        validate_config(cfg)
    assert f"'{key}'" in str(exc.value)


def test_shipped_configs_are_valid(paper_cfg, smoke_cfg):
    assert paper_cfg["studies"]["main"]["agent_counts"] == [3, 8, 12, 16]
    assert paper_cfg["studies"]["scaling"]["agent_counts"] == [64, 128, 256]
    assert smoke_cfg["experiment"] != paper_cfg["experiment"]


def test_variants_merge_into_method_config(paper_cfg):
    cfg = deep_merge(paper_cfg, {"methods": {"nominal": {"variants": {"soft": {"kp": 2.0, "label": "Soft"}}}}})
    validate_config(cfg)
    method, mcfg = method_config(cfg, "nominal-soft")
    assert method == "nominal" and mcfg["kp"] == 2.0 and mcfg["kd"] == paper_cfg["methods"]["nominal"]["kd"]
    assert "variants" not in mcfg


def test_missing_config_file_is_a_clear_error(tmp_path):
    with pytest.raises(ConfigError, match="not found"):
        load_config([tmp_path / "nope.yaml"])
    bad = tmp_path / "bad.yaml"
    bad.write_text("sim: [unclosed")
    with pytest.raises(ConfigError, match="not valid YAML"):
        load_config([bad])


def test_cli_reports_invalid_config_and_exits_2(tmp_path):
    bad = tmp_path / "bad.yaml"
    bad.write_text(yaml.safe_dump({"agents": {"collision_radius": "wide"}}))
    proc = subprocess.run(
        [sys.executable, "-m", "madpinn", "validate-config", "--config", str(REPO / "config.yaml"), str(bad)],
        capture_output=True, text=True, env=subprocess_env(),
    )
    assert proc.returncode == 2
    assert "'agents.collision_radius'" in proc.stderr and "Traceback" not in proc.stderr


def test_trajectory_figure_cell_must_exist(paper_cfg):
    cfg = deep_merge(paper_cfg, {"figures": {"trajectories": {"study": "main", "n_agents": 5, "seed": 0}}})
    with pytest.raises(ConfigError, match="'figures.trajectories.n_agents'"):
        validate_config(cfg)


def test_job_hash_ignores_the_study_fan_out_but_not_the_cell_settings():
    import copy

    from madpinn.config import config_hash, job_config

    cfg = load_config([REPO / "config.yaml"])
    base = config_hash(job_config(cfg, "main", "nominal"))
    more = copy.deepcopy(cfg)
    more["studies"]["main"]["runs"].append("madpinn-nearest")
    more["studies"]["main"]["seeds"].append(7)
    assert config_hash(job_config(more, "main", "nominal")) == base
    fewer = copy.deepcopy(cfg)
    fewer["studies"]["main"]["scenarios"] = 40
    assert config_hash(job_config(fewer, "main", "nominal")) != base
    assert config_hash(job_config(cfg, "main", "madpinn")) != config_hash(job_config(cfg, "main", "madpinn-filtered"))
