"""Shipped checkpoints: models/ + manifest.json, sha256-checked install, workflow overlay (issue 15)."""

import json

import pytest
import torch
import yaml

from conftest import REPO, SMOKE, run_snakemake
from madpinn.commands import main
from madpinn.config import load_config
from madpinn.marl_hash import is_marl_model, marl_training_hash
from madpinn.provenance import model_training_hash
from madpinn.value_functions import load_vs
from madpinn.value_functions.build import training_hash
from madpinn.value_functions.shipping import ShippedModelError, install, read_manifest, sha256, verify
from policy_models import tiny_model_dir


def _ship(tmp_path):
    models = tmp_path / "models"
    report = tmp_path / "vs_grid.json"
    report.write_text(json.dumps({"meets_target": False}))
    assert main(["ship-models", "--model", f"vs={tiny_model_dir() / 'vs.pt'}", "--validation", f"vs={report}",
                 "--out-dir", str(models), "--device", "cpu"]) == 0
    return models


def test_manifest_records_the_file_and_its_training(tmp_path):
    models = _ship(tmp_path)
    entry = read_manifest(models)["models"]["vs"]
    assert entry["file"] == "vs.pt" and entry["sha256"] == sha256(models / "vs.pt") == sha256(tiny_model_dir() / "vs.pt")
    assert entry["iterations"] == 30 and entry["device"] == "cpu"
    assert entry["validation"] == {"vs_grid": {"meets_target": False}}
    out = install(models, "vs", tmp_path / "results" / "vs.pt")
    assert load_vs(out).meta["iterations"] == 30


def test_changed_or_unknown_model_is_refused(tmp_path):
    models = _ship(tmp_path)
    with pytest.raises(ShippedModelError, match="no model 'vhat'"):
        verify(models, "vhat")
    with open(models / "vs.pt", "ab") as f:
        f.write(b"x")
    with pytest.raises(ShippedModelError, match="sha256"):
        install(models, "vs", tmp_path / "out.pt")
    assert not (tmp_path / "out.pt").exists()


def test_shipped_overlay_installs_instead_of_training(tmp_path):
    _ship(tmp_path)
    overlay = tmp_path / "shipped.yaml"
    overlay.write_text("shipped_models: {enabled: true, dir: models, names: [vs]}\n")
    proc = run_snakemake(tmp_path, "-n", "-j2", "all", configfiles=(SMOKE, overlay))
    out = proc.stdout + proc.stderr
    assert "install_shipped_model" in out and "train_vs" not in out and "train_vhat" in out
    run_snakemake(tmp_path, "-j1", "results/smoke/models/vs.pt", configfiles=(SMOKE, overlay))
    assert sha256(tmp_path / "results/smoke/models/vs.pt") == sha256(tmp_path / "models/vs.pt")
    from mlflow.tracking import MlflowClient                     # the install job is an MLflow run too

    c = MlflowClient(f"sqlite:///{tmp_path / 'mlflow' / 'mlflow.db'}")
    runs = c.search_runs([c.get_experiment_by_name("madpinn-smoke").experiment_id])
    install_runs = [r for r in runs if r.data.tags.get("madpinn.rule") == "install_shipped_model"]
    assert [r.data.tags["madpinn.job"] for r in install_runs] == ["install/vs"]
    assert install_runs[0].info.status == "FINISHED"
    # re-shipping another model rewrites manifest.json: vs's install (and so every cached cell that
    # uses V_s) stays done; a changed sha256 of vs's own entry reruns it
    manifest = tmp_path / "models" / "manifest.json"
    data = json.loads(manifest.read_text())
    data["models"]["other"] = {"file": "other.pt", "sha256": "0" * 64}
    manifest.write_text(json.dumps(data))
    proc = run_snakemake(tmp_path, "-n", "-j1", "results/smoke/models/vs.pt", configfiles=(SMOKE, overlay))
    assert "Nothing to be done" in proc.stdout + proc.stderr
    payload = torch.load(tiny_model_dir() / "vs.pt", weights_only=True)   # vs re-shipped: other bytes, same training
    payload["meta"]["note"] = "re-shipped"
    torch.save(payload, tmp_path / "vs2.pt")
    assert main(["ship-models", "--model", f"vs={tmp_path / 'vs2.pt'}", "--out-dir", str(tmp_path / "models")]) == 0
    proc = run_snakemake(tmp_path, "-n", "-j1", "results/smoke/models/vs.pt", configfiles=(SMOKE, overlay))
    assert "install_shipped_model" in proc.stdout + proc.stderr


def test_shipped_value_function_of_another_configuration_stops_the_workflow_before_any_job(tmp_path):
    _ship(tmp_path)
    overlay = tmp_path / "shipped.yaml"
    # a V_s setting the shipped model was not trained with
    overlay.write_text("shipped_models: {enabled: true, dir: models, names: [vs]}\n"
                       "value_functions: {vs: {iterations: 31}}\n")
    proc = run_snakemake(tmp_path, "-j2", "all", configfiles=(SMOKE, overlay), check=False)
    assert proc.returncode != 0
    assert "shipped model 'vs'" in proc.stderr and "training hash" in proc.stderr and "Traceback" not in proc.stderr
    assert not (tmp_path / "results").exists()


def test_committed_models_were_trained_for_config_yaml(paper_cfg):
    """`models/` is what `workflow/configs/shipped.yaml` installs: every shipped V̂ / V_s must carry
    config.yaml's training hash (else the shipped overlay stops, see the test above) and its sha256."""
    shipped = read_manifest(REPO / "models")["models"]
    names = yaml.safe_load((REPO / "workflow" / "configs" / "shipped.yaml").read_text())["shipped_models"]["names"]
    assert set(names) <= set(shipped)
    for name in names:
        expected = marl_training_hash(paper_cfg, name) if is_marl_model(name) else model_training_hash(paper_cfg, name)
        assert shipped[name]["training_config_hash"] == expected, name
        assert verify(REPO / "models", name).stat().st_size == shipped[name]["bytes"]
    assert {"safemarl_nominal", "defmarl_n3", "defmarl_n8"} <= set(names)   # the baselines' policies too
    assert {"vhat_h04", "vhat_h03", "vhat_speed"} <= set(names)   # V̂ variants (issue 33): their merged settings' hashes
    assert model_training_hash(paper_cfg, "vhat") == training_hash(paper_cfg, "vhat") != shipped["vhat_h04"]["training_config_hash"]


def _ship_policy(tmp_path, configs, extra=()):
    """The committed DEF-MARL(3) checkpoint shipped into tmp_path/models for ``configs``."""
    models = tmp_path / "models"
    args = ["ship-models", "--model", f"defmarl_n3={REPO / 'models' / 'defmarl_n3.pt'}", "--out-dir", str(models), *extra]
    if configs:
        args += ["--config", *map(str, configs)]
    return main(args), models


def test_shipped_policy_records_the_training_hash_of_its_configuration(tmp_path):
    # a MARL checkpoint records no training hash itself: without --config the command refuses
    code, models = _ship_policy(tmp_path, None)
    assert code != 0
    code, models = _ship_policy(tmp_path, [REPO / "config.yaml", SMOKE], ["--git-commit", "abc123"])
    assert code == 0 and is_marl_model("defmarl_n3") and not is_marl_model("vs")
    entry = read_manifest(models)["models"]["defmarl_n3"]
    smoke_hash = marl_training_hash(load_config([REPO / "config.yaml", SMOKE]), "defmarl_n3")
    assert entry["training_config_hash"] == smoke_hash != marl_training_hash(load_config([REPO / "config.yaml"]), "defmarl_n3")
    trained = torch.load(REPO / "models" / "defmarl_n3.pt", weights_only=True)["meta"]["iterations"]
    assert entry["git_commit"] == "abc123" and entry["iterations"] == trained > 0


def test_shipped_policy_replaces_its_training_or_stops_the_workflow_when_trained_for_another_configuration(tmp_path):
    overlay = tmp_path / "shipped.yaml"
    overlay.write_text("shipped_models: {enabled: true, dir: models, names: [defmarl_n3]}\n")
    assert _ship_policy(tmp_path, [REPO / "config.yaml", SMOKE])[0] == 0
    out = run_snakemake(tmp_path, "-n", "-j2", "all", configfiles=(SMOKE, overlay))
    text = out.stdout + out.stderr
    assert "install_shipped_defmarl_n3.log" in text and "train_defmarl_n3.log" not in text and "train_defmarl_n8.log" in text
    # the paper configuration's policy with the smoke configuration: stopped before any job
    assert _ship_policy(tmp_path, [REPO / "config.yaml"])[0] == 0
    proc = run_snakemake(tmp_path, "-j2", "all", configfiles=(SMOKE, overlay), check=False)
    assert proc.returncode != 0
    assert "shipped policy 'defmarl_n3'" in proc.stderr and "Traceback" not in proc.stderr
    assert not (tmp_path / "results").exists()


def test_shipping_knows_the_checkpoint_formats():
    from madpinn.marl import checkpoint
    from madpinn.value_functions import model, shipping

    assert (shipping.VALUE_FORMAT, shipping.MARL_FORMAT) == (model.FORMAT, checkpoint.FORMAT)


def _snapshot(directory):
    return {p.name: p.read_bytes() for p in sorted(directory.iterdir())}


def test_ship_models_checks_the_new_file_before_writing_anything(tmp_path, capsys):
    """Issue 35 item 1: ``ship-models`` copied the new file into models/ before reading it, so a
    truncated file replaced the shipped model and left the manifest stale. Every bad file (truncated,
    another kind, a blocked pickle, a MARL policy without its training configuration) is now refused
    with one line, and models/ with its manifest stays byte-identical."""
    models = tmp_path / "models"
    assert main(["ship-models", "--model", f"vs={tiny_model_dir() / 'vs.pt'}", f"vhat={tiny_model_dir() / 'vhat.pt'}",
                 "--out-dir", str(models)]) == 0
    before = _snapshot(models)
    data = (models / "vhat.pt").read_bytes()
    (tmp_path / "t.pt").write_bytes(data[:len(data) // 2])
    torch.save({"x": __import__("pathlib").PurePosixPath("a")}, tmp_path / "pickle.pt")
    cases = {f"vhat={tmp_path / 't.pt'}": "corrupted or truncated",
             f"vhat={models / 'vs.pt'}": "holds a 'vs' model, expected a 'vhat' model",
             f"vs={REPO / 'models' / 'defmarl_n3.pt'}": "holds a 'defmarl' model",
             f"vs={tmp_path / 'pickle.pt'}": "pickled Python objects",
             f"defmarl_n3={REPO / 'models' / 'defmarl_n3.pt'}": "pass --config"}
    capsys.readouterr()
    for model, words in cases.items():
        assert main(["ship-models", "--model", model, "--out-dir", str(models)]) != 0
        lines = capsys.readouterr().err.strip().splitlines()
        assert len(lines) == 1 and lines[0].startswith("madpinn: ") and words in lines[0], lines
        assert _snapshot(models) == before, model


@pytest.mark.parametrize("fault", ["truncated", "swapped", "swapped with the manifest"])
def test_corrupted_or_swapped_shipped_model_stops_a_dry_run_in_one_line(tmp_path, fault):
    """Issue 35 item 2: the check before any job compared only the manifest's training hash, so a
    truncated or swapped models/*.pt passed the dry run and failed mid-run with a traceback. Every
    shipped file's kind (read with weights_only=True) and sha256 are checked now, dry runs included."""
    models = tmp_path / "models"
    assert main(["ship-models", "--model", f"vs={tiny_model_dir() / 'vs.pt'}", f"vhat={tiny_model_dir() / 'vhat.pt'}",
                 "--out-dir", str(models)]) == 0
    vhat, vs = (models / "vhat.pt").read_bytes(), (models / "vs.pt").read_bytes()
    if fault == "truncated":
        (models / "vhat.pt").write_bytes(vhat[:len(vhat) // 2])
    else:
        (models / "vhat.pt").write_bytes(vs)
        (models / "vs.pt").write_bytes(vhat)
    if fault == "swapped with the manifest":   # sha256 then matches: only the kind check sees it
        manifest = json.loads((models / "manifest.json").read_text())
        for key in ("sha256", "bytes"):
            m = manifest["models"]
            m["vhat"][key], m["vs"][key] = m["vs"][key], m["vhat"][key]
        (models / "manifest.json").write_text(json.dumps(manifest))
    overlay = tmp_path / "shipped.yaml"
    overlay.write_text("shipped_models: {enabled: true, dir: models, names: [vhat, vs]}\n")
    proc = run_snakemake(tmp_path, "-n", "-j1", "all", configfiles=(SMOKE, overlay), check=False)
    lines = [line for line in proc.stderr.splitlines() if line.startswith("madpinn: ")]
    assert proc.returncode != 0 and "Traceback" not in proc.stderr, proc.stderr[-3000:]
    assert len(lines) == 1 and "models/vhat.pt" in lines[0] and "fix:" in lines[0], proc.stderr[-3000:]
    assert ("corrupted or truncated" if fault == "truncated" else "holds a 'vs' model") in lines[0]
    assert not (tmp_path / "results").exists()


def test_ship_models_into_a_directory_it_cannot_write_is_one_line(tmp_path):
    """Issue 50 item 5: a read-only models/ gave 38 lines of chained OSError tracebacks. The
    directory is checked before anything is written: one line, exit 2. (A regular file in the
    path stands for any unwritable directory, also for root; a read-only one is tried unless root,
    whom permissions do not stop.)"""
    import os
    import subprocess
    import sys

    from conftest import REPO, subprocess_env

    (tmp_path / "a_file").write_text("")
    targets = [tmp_path / "a_file" / "models"]
    if os.geteuid() != 0:
        ro = tmp_path / "ro"
        ro.mkdir()
        ro.chmod(0o555)
        targets.append(ro)
    for out in targets:
        proc = subprocess.run([sys.executable, "-m", "madpinn", "ship-models", "--model", f"vs={REPO / 'models' / 'vs.pt'}",
                               "--out-dir", str(out)], capture_output=True, text=True, env=subprocess_env())
        assert proc.returncode == 2 and proc.stderr.count("\n") == 1, proc.stderr[-3000:]
        assert proc.stderr.startswith(f"madpinn: cannot ship into {out}:") and "nothing was written" in proc.stderr
    assert sorted(p.name for p in tmp_path.rglob("*")) == sorted(["a_file"] + (["ro"] if len(targets) > 1 else []))
