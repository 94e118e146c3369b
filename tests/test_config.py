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
        ({"studies": {"scaling": {"cost_horizons_s": [6.0]}}}, "studies.scaling.cost_horizons_s"),      # not before T = 6 s
        ({"studies": {"scaling": {"cost_horizons_s": [1.0001]}}}, "studies.scaling.cost_horizons_s"),   # not a whole step
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


@pytest.mark.parametrize(
    "overlay,key",
    [
        ({"sim": {"dt": float("nan")}}, "sim.dt"),
        ({"value_functions": {"vhat": {"lr": float("inf")}}}, "value_functions.vhat.lr"),
        ({"methods": {"mppi": {"margin": float("-inf")}}}, "methods.mppi.margin"),
        ({"arenas": {"small": {"half_width": float("nan")}}}, "arenas.small.half_width"),
    ],
)
def test_nan_and_inf_fail_validation_naming_the_key(overlay, key):
    cfg = deep_merge(load_yaml(REPO / "config.yaml"), overlay)
    with pytest.raises(ConfigError, match=rf"'{key}': -?(nan|inf) is not a finite number"):
        validate_config(cfg)


def test_yaml_nan_and_inf_are_caught_by_the_cli(tmp_path):
    bad = tmp_path / "bad.yaml"
    bad.write_text("sim: {dt: .nan}\nvalue_functions: {vhat: {lr: .inf}}\n")
    proc = subprocess.run(
        [sys.executable, "-m", "madpinn", "validate-config", "--config", str(REPO / "config.yaml"), str(bad)],
        capture_output=True, text=True, env=subprocess_env(),
    )
    assert proc.returncode != 0 and "config OK" not in proc.stdout
    assert "'sim.dt': nan is not a finite number" in proc.stderr
    assert "'value_functions.vhat.lr': inf is not a finite number" in proc.stderr


@pytest.mark.parametrize(
    "overlay,key",
    [
        ({"studies": {"main": {"agent_counts": [3, 5000]}}}, "studies.main.agent_counts"),
        ({"arenas": {"large": {"half_width": 0.5}}}, "studies.scaling.agent_counts"),
        ({"methods": {"safemarl": {"nominal": {"agent_counts": [3, 70]}}}}, "methods.safemarl.nominal.agent_counts"),
        ({"methods": {"defmarl": {"variants": {"n8": {"training": {"agent_counts": [500]}}}}}},
         "methods.defmarl.variants.n8.training.agent_counts"),
    ],
)
def test_infeasible_agent_count_fails_validation(overlay, key):
    cfg = deep_merge(load_yaml(REPO / "config.yaml"), overlay)
    with pytest.raises(ConfigError, match=rf"'{key}': \d+ agents do not fit in arena '\w+'.*at most \d+"):
        validate_config(cfg)


def test_conflict_pattern_is_checked_before_any_job():
    cfg = load_yaml(REPO / "config.yaml")
    with pytest.raises(ConfigError, match=r"'studies.conflict_lines.pattern'"):
        validate_config(deep_merge(cfg, {"studies": {"conflict_lines": {"pattern": "zigzag"}}}))
    # two facing lines of 32 agents do not fit the small arena 2r apart
    with pytest.raises(ConfigError, match=r"'studies.conflict_lines.agent_counts': head_on_lines: agents only .* apart"):
        validate_config(deep_merge(cfg, {"studies": {"conflict_lines": {"agent_counts": [64]}}}))


def _scenario_settings(cfg):
    from madpinn.config.rules import _agent_count_settings

    return sorted({(arena, n) for _, arena, counts in _agent_count_settings(cfg) for n in counts})


def test_agent_count_bound_admits_every_shipped_config_and_the_sampler_meets_it(paper_cfg, smoke_cfg):
    from madpinn.scenarios import Arena, generate_scenario, max_agents

    sep = paper_cfg["sim"]["start_separation"]
    # the bound is the sampler's own limit: validation accepts N = limit and rejects limit + 1 ...
    limit = max_agents(paper_cfg["arenas"]["small"]["half_width"], sep)
    ablation = {"studies": {"ablation_update": {"agent_counts": [limit]}}}
    validate_config(deep_merge(paper_cfg, ablation))
    ablation["studies"]["ablation_update"]["agent_counts"] = [limit + 1]
    with pytest.raises(ConfigError, match=f"at most {limit}"):
        validate_config(deep_merge(paper_cfg, ablation))
    # ... and at that limit the sampler finds a scenario within its attempt budget
    starts, goals = generate_scenario(Arena.from_config(paper_cfg, "small"), limit, seed=0, index=0, min_separation=sep)
    assert starts.shape == goals.shape == (limit, 2)
    # every configured (arena, N) of the shipped configs is within the bound and sampled at once
    for cfg in (paper_cfg, smoke_cfg):
        for arena, n in _scenario_settings(cfg):
            assert n <= max_agents(cfg["arenas"][arena]["half_width"], sep)
            starts, _ = generate_scenario(Arena.from_config(cfg, arena), n, seed=0, index=0, min_separation=sep)
            assert starts.shape == (n, 2)


def test_malformed_yaml_names_file_and_line_in_cli_and_workflow(tmp_path):
    bad_text = "sim:\n  dt: 0.01\n  record_every: [1, 2\nagents: {}\n"
    bad = tmp_path / "bad.yaml"
    bad.write_text(bad_text)
    with pytest.raises(ConfigError, match=rf"{bad}:4:\d+ is not valid YAML: .*at line 3"):
        load_config([bad])
    # the workflow's own config.yaml (read by the Snakefile's `configfile:`): a copy of the
    # workflow whose config.yaml is malformed
    import shutil

    wf = tmp_path / "wf"
    shutil.copytree(REPO / "workflow", wf / "workflow")
    shutil.copy(REPO / "Snakefile", wf / "Snakefile")
    (wf / "config.yaml").write_text(bad_text)
    proc = subprocess.run(
        [sys.executable, "-m", "snakemake", "-n", "-s", str(wf / "Snakefile"), "-d", str(tmp_path / "run")],
        capture_output=True, text=True, env=subprocess_env(), timeout=600,
    )
    assert proc.returncode != 0
    assert f"madpinn: config file {wf / 'config.yaml'}:4:" in proc.stderr, proc.stderr[-2000:]


def test_paper_scale_overlay_trains_at_the_papers_budget_apart_from_the_default_run(paper_cfg):
    """workflow/configs/paper_scale.yaml: valid, 65 536 × 100 000 samples at the paper's lr for both
    value functions (new training hashes, so nothing of the CPU budget's models is reused), and its
    own results folder and MLflow experiment."""
    from madpinn.value_functions.build import training_hash

    cfg = load_config([REPO / "config.yaml", REPO / "workflow" / "configs" / "paper_scale.yaml"])
    validate_config(cfg)
    for kind in ("vhat", "vs"):
        v = cfg["value_functions"][kind]
        assert v["batch_size"] * v["iterations"] == 65536 * 100_000 and v["lr"] == v["lr_final"] == 2e-5
        assert not v["fine_tune"] and training_hash(cfg, kind) != training_hash(paper_cfg, kind)
    assert cfg["paths"]["results"] != paper_cfg["paths"]["results"] and cfg["experiment"] != paper_cfg["experiment"]
    assert cfg["studies"] == paper_cfg["studies"]


@pytest.mark.parametrize("kind", ["vhat", "vs"])
def test_bad_value_under_a_value_function_names_only_that_key(kind):
    """Issue 35 item 4: a bad value inside ``value_functions.<kind>`` (its keys come through
    ``allOf`` + ``unevaluatedProperties``) used to also call every valid key of the block
    unexpected; now only the offending key is named, and a real unknown key alone."""
    base = load_yaml(REPO / "config.yaml")
    with pytest.raises(ConfigError) as exc:
        validate_config(deep_merge(base, {"value_functions": {kind: {"iterations": 0}}}))
    lines = str(exc.value).splitlines()[1:]
    assert lines == [f"  - 'value_functions.{kind}.iterations': 0 is less than the minimum of 1"], lines
    with pytest.raises(ConfigError) as exc:
        validate_config(deep_merge(base, {"value_functions": {kind: {"iterations": 0, "iteratoins": 5}}}))
    lines = str(exc.value).splitlines()[1:]
    assert len(lines) == 2 and "'iteratoins' was unexpected" in lines[0] and "batch_size" not in str(exc.value), lines


def test_unwritable_results_path_is_one_line_before_any_job_dry_run_too(tmp_path):
    """Issue 35 item 3: ``paths.results: /proc/r`` passed the dry run and the real run ended in a
    traceback from common.smk (onstart / start_tracking). Both now stop while parsing, with one line
    naming the key, and write nothing."""
    from conftest import SMOKE, run_snakemake

    (tmp_path / "a_file").write_text("")
    for results in ("/proc/r", "a_file/r"):
        bad = tmp_path / "bad.yaml"
        bad.write_text(f"paths: {{results: {results}}}\ntracking: {{enabled: false}}\n")
        for dry in (["-n"], []):
            before = sorted(p.name for p in tmp_path.iterdir())
            proc = run_snakemake(tmp_path, *dry, "-j1", "all", configfiles=(SMOKE, bad), check=False)
            lines = [line for line in proc.stderr.splitlines() if line.startswith("madpinn: ")]
            assert proc.returncode != 0 and "Traceback" not in proc.stderr, proc.stderr[-3000:]
            assert len(lines) == 1 and "'paths.results'" in lines[0] and "cannot be written" in lines[0], lines
            assert sorted(p.name for p in tmp_path.iterdir() if p.name != ".snakemake") == \
                [n for n in before if n != ".snakemake"]
    from madpinn.config import unwritable_reason

    assert "is not a directory" in unwritable_reason(tmp_path / "a_file" / "r")
    assert unwritable_reason(tmp_path / "new" / "r") is None


def test_explicit_targets_outside_the_configuration_stop_the_dry_run_in_one_line(tmp_path):
    """Issue 35 item 8: targets named by path skipped the config checks: an unknown study gave a
    KeyError traceback, 99 agents in the small arena (at most 69) passed the dry run. Each now stops
    while the DAG is built, dry runs included, with one line."""
    from conftest import SMOKE, run_snakemake

    targets = {"results/smoke/eval/double_integrator/nosuch/nominal/n3_seed0.parquet": "unknown study 'nosuch'",
               "results/smoke/eval/double_integrator/main/nominal/n99_seed0.parquet": "99 agents do not fit in arena 'small'",
               "results/smoke/oracle/small/n99_seed0_s5.parquet": "99 agents do not fit in arena 'small'"}
    for target, words in targets.items():
        proc = run_snakemake(tmp_path, "-n", "-j1", target, check=False)
        lines = [line for line in proc.stderr.splitlines() if line.startswith("madpinn: ")]
        assert proc.returncode != 0 and "Traceback" not in proc.stderr and "KeyError" not in proc.stderr, proc.stderr[-3000:]
        assert len(lines) == 1 and words in lines[0] and "fix:" in lines[0], proc.stderr[-3000:]
    from madpinn.config import TargetError, check_cell

    cfg = load_config([REPO / "config.yaml", SMOKE])
    check_cell(cfg, 69, 0, study="main", run="nominal")   # the limit itself, and a pattern's cell, pass
    check_cell(cfg, 8, 0, arena="small", pattern="circle_swap")
    with pytest.raises(TargetError, match="1 to 69"):
        check_cell(cfg, 70, 0, arena="small")


@pytest.mark.parametrize("overlay", sorted(p.name for p in (REPO / "workflow" / "configs").glob("*.yaml")))
def test_every_shipped_overlay_validates_on_the_protocol(overlay):
    """Each overlay under workflow/configs/ merges onto config.yaml into a valid configuration
    (the collision-readings, episode-length, sweep and training overlays go stale otherwise)."""
    stack = [REPO / "config.yaml"]
    if overlay.startswith("episode_"):   # an episode overlay sits on the collision-readings one
        stack += [REPO / "workflow" / "configs" / "shipped.yaml", REPO / "workflow" / "configs" / "collision_readings.yaml"]
    cfg = load_config([*stack, REPO / "workflow" / "configs" / overlay])
    assert cfg["experiment"]


def test_unknown_backend_or_bad_agent_count_is_one_line_in_the_workflow_and_by_hand(tmp_path):
    """Issue 50 items 4 and 9: an unknown backend in a target path passed the dry run (two trainings
    planned) and was a 28-line ValueError traceback by hand; `evaluate --n-agents -3` got the hint
    "use fewer agents". The workflow and the command check a cell alike (config.check_cell)."""
    from conftest import SMOKE, run_snakemake

    proc = run_snakemake(tmp_path, "-n", "-j1", "results/smoke/eval/nosuchbackend/main/madpinn/n3_seed0.parquet",
                         check=False)
    lines = [line for line in proc.stderr.splitlines() if line.startswith("madpinn: ")]
    assert proc.returncode != 0 and "Traceback" not in proc.stderr and "train_" not in proc.stdout, proc.stderr[-3000:]
    assert len(lines) == 1 and "unknown simulation backend 'nosuchbackend'" in lines[0], proc.stderr[-3000:]
    base = [sys.executable, "-m", "madpinn", "evaluate", "--config", str(REPO / "config.yaml"), str(SMOKE),
            "--study", "main", "--run", "nominal", "--seed", "0", "--out", str(tmp_path / "x.parquet"), "--no-track"]
    cases = {("--n-agents", "3", "--backend", "nosuchbackend"): "unknown simulation backend 'nosuchbackend'",
             ("--n-agents", "-3"): "-3 agents: a cell has at least 1 agent"}
    for extra, words in cases.items():
        proc = subprocess.run(base + list(extra), capture_output=True, text=True, env=subprocess_env(), cwd=tmp_path)
        assert proc.returncode == 2 and proc.stderr.count("\n") == 1, proc.stderr[-3000:]
        assert proc.stderr.startswith("madpinn: ") and words in proc.stderr and "fewer agents" not in proc.stderr
    assert list(tmp_path.glob("x*")) == []


def test_validate_config_refuses_what_the_workflow_refuses(tmp_path):
    """Issue 50 item 7: `validate-config` said "config OK" for `paths.results: /proc/r`, which the
    workflow refuses: the two used different validators. validate_config is now the one validator
    (Snakefile, validate-config, every job's load_config)."""
    bad = tmp_path / "bad.yaml"
    bad.write_text("paths: {results: /proc/r}\n")
    proc = subprocess.run([sys.executable, "-m", "madpinn", "validate-config", "--config", str(REPO / "config.yaml"),
                           str(bad)], capture_output=True, text=True, env=subprocess_env(), cwd=tmp_path)
    assert proc.returncode == 2 and "config OK" not in proc.stdout, proc.stdout
    assert proc.stderr.count("\n") == 1 and "'paths.results': '/proc/r' cannot be written" in proc.stderr
    with pytest.raises(ConfigError, match="cannot be written"):
        validate_config(deep_merge(load_config([REPO / "config.yaml"]), {"paths": {"figures": "/proc/f"}}))


def test_workflow_run_outside_the_repository_or_without_config_yaml_is_one_line(tmp_path):
    """Issue 50 item 8: `snakemake -s <clone>/Snakefile` from another directory planned everything
    into <cwd>/results/ (now refused, unless --directory names the directory on purpose); a missing
    config.yaml got the hint "correct the named key(s)"."""
    from workflow_helpers import copy_repo

    proc = subprocess.run([sys.executable, "-m", "snakemake", "-n", "-j1", "-s", str(REPO / "Snakefile")],
                          capture_output=True, text=True, env=subprocess_env(), cwd=tmp_path)
    lines = [line for line in proc.stderr.splitlines() if line.startswith("madpinn: ")]
    assert proc.returncode != 0 and "Traceback" not in proc.stderr, proc.stderr[-3000:]
    assert len(lines) == 1 and f"snakemake runs in {tmp_path}, not in the repository" in lines[0], proc.stderr[-3000:]
    assert "--directory" in lines[0] and [p.name for p in tmp_path.iterdir() if p.name != ".snakemake"] == []

    copy = copy_repo(tmp_path / "clone")
    (copy / "config.yaml").unlink()
    proc = subprocess.run([sys.executable, "-m", "snakemake", "-n", "-j1"], capture_output=True, text=True,
                          env={**subprocess_env(), "PYTHONPATH": str(copy)}, cwd=copy)
    lines = [line for line in proc.stderr.splitlines() if line.startswith("madpinn: ")]
    assert proc.returncode != 0 and len(lines) == 1, proc.stderr[-3000:]
    assert "config file not found" in lines[0] and "git checkout -- config.yaml" in lines[0]
    assert "correct the named key" not in lines[0]
