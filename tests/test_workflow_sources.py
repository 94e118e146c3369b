"""The workflow's source triggers cover what each job runs, and no more than that.

Every rule's ``source`` param is ``source_hash("<command>", *methods)`` of
``workflow/rules/common.smk``: the files of the import closure of the command's handler
(:mod:`madpinn.provenance`), with the policy module of each method it runs. A module a job runs
but its closure misses would let an edit change results silently; a closure too wide reruns hours
of cells for nothing (evaluation cells do not hash the tables, the report or the oracle; the MARL
trainings do not hash the simulation).
"""

from __future__ import annotations

import re
import subprocess
import sys

import pytest

from conftest import REPO
from madpinn.commands import COMMAND_MODULES, handler_entry
from madpinn.provenance import PACKAGE, closure, imports, plugin_module, reached, registry, source_files, source_hash

RULES = REPO / "workflow" / "rules"


def _files(command: str, *methods: str) -> set[str]:
    """Package-relative files a rule running ``command`` (and ``methods``' policies) hashes."""
    entries = [handler_entry(command)] + [plugin_module("madpinn.policies.base", m) for m in methods]
    return {str(f.relative_to(PACKAGE)) for f in source_files(entries)}


# Modules each job runs (imported at module level or lazily inside the functions it calls): the
# closure must keep every one of them. Dropping one from what a job hashes fails here.
RUNS = {
    ("train-value",): ["value_functions/train.py", "value_functions/build.py", "value_functions/problems.py",
                       "value_functions/siren.py", "value_functions/sampling.py", "value_functions/epigraph.py",
                       "dynamics/pair.py", "dynamics/system.py", "observation.py", "device.py"],
    ("verify-vhat",): ["value_functions/verification.py", "value_functions/z_search.py", "value_functions/model.py",
                       "value_functions/epigraph.py"],
    ("calibrate-vhat",): ["value_functions/calibration.py", "value_functions/conformal.py", "value_functions/safety_level.py",
                          "evaluation/calibration_table.py", "value_functions/verification.py",
                          "value_functions/z_search.py", "value_functions/model.py"],
    ("solve-vs-grid",): ["value_functions/grid_reference.py", "dynamics/pair.py"],
    ("train-safemarl-nominal",): ["marl/trainer.py", "marl/env.py", "marl/ppo.py", "marl/networks.py",
                                  "scenarios.py", "settings.py", "observation.py"],
    ("train-defmarl",): ["marl/defmarl/trainer.py", "marl/defmarl/epigraph.py", "marl/trainer.py", "marl/env.py"],
    ("evaluate", "nominal"): ["evaluation/cell.py", "evaluation/metrics.py", "policies/base.py", "policies/nominal.py",
                              "simulation/backend.py", "simulation/simulator.py", "simulation/recorder.py",
                              "simulation/mujoco/backend.py", "scenarios.py", "conflicts.py", "settings.py"],
    ("evaluate", "madpinn"): ["evaluation/collisions.py", "policies/madpinn.py", "policies/look_ahead.py", "policies/neighbours.py",
                              "policies/z_search.py", "value_functions/z_search.py", "policies/safety_filter.py",
                              "policies/leveled_neighbours.py", "value_functions/safety_level.py",
                              "value_functions/model.py", "value_functions/siren.py", "value_functions/epigraph.py"],
    ("evaluate", "safemarl"): ["policies/safemarl.py", "policies/safety_filter.py", "marl/deploy.py",
                               "value_functions/model.py"],
    ("evaluate", "defmarl"): ["policies/defmarl.py", "marl/defmarl/deploy.py"],
    ("evaluate", "mppi"): ["policies/mppi.py"],
    ("oracle",): ["evaluation/oracle.py", "scenarios.py", "conflicts.py"],
    ("table",): ["evaluation/tables.py", "evaluation/metrics.py"],
    ("figure",): ["figures/cost_safety.py", "figures/trajectories.py", "figures/style.py", "evaluation/tables.py"],
    ("reproduction",): ["evaluation/reproduction.py", "evaluation/paper_values.yaml", "evaluation/tables.py"],
    ("render-clip",): ["simulation/mujoco/render.py", "simulation/mujoco/model.py"],
    ("gap-decomposition",): ["evaluation/gap.py", "evaluation/collisions.py"],
    ("vhat-recipe",): ["evaluation/recipe_page.py", "evaluation/recipe_choice.py", "evaluation/recipe_settings.py",
                       "evaluation/tables.py", "evaluation/metrics.py"],
    ("claims",): ["evaluation/claims.py", "evaluation/recipe_choice.py"],   # the seed-provenance line
}


@pytest.mark.parametrize("job", sorted(RUNS), ids="-".join)
def test_every_module_a_job_runs_is_hashed(job):
    missing = sorted(set(RUNS[job]) - _files(*job))
    assert not missing, f"source_hash{job} misses {missing}"


@pytest.mark.parametrize("method", sorted(registry("madpinn.policies.base")))
def test_every_policy_module_is_hashed_into_its_methods_cells(method):
    """Each registered method's policy module (imported by name per run) is in its cells' hash."""
    module = plugin_module("madpinn.policies.base", method)
    assert f"policies/{module.rsplit('.', 1)[1]}.py" in _files("evaluate", method)


def test_lazy_imports_and_named_modules_are_followed():
    """A function-level import, a module named by a string (the optional MuJoCo backend) and a lazy
    package's ``_HOMES`` are part of the closure; ``if TYPE_CHECKING:`` imports are not."""
    assert "madpinn.evaluation.oracle:write_bounds" in imports("madpinn.commands.outputs:_oracle")   # in the handler
    assert "madpinn.simulation.mujoco" in closure(["madpinn.simulation.backend:make_backend"])   # by name
    assert "madpinn.value_functions.model" in closure(["madpinn.value_functions"])   # PEP 562 _HOMES
    assert "madpinn.simulation.recorder" not in closure(["madpinn.evaluation.metrics"])   # TYPE_CHECKING only


def test_a_name_imported_from_a_module_follows_that_definition_only():
    """``from madpinn.settings import AgentSettings`` runs settings' module-level code and AgentSettings
    only; ``sim``'s settings live under the simulation package (issue 48), so the MARL trainings
    (double-integrator physics) do not rerun for a backend edit."""
    assert "madpinn.simulation.mujoco.settings" not in closure(["madpinn.settings:AgentSettings"])
    assert "madpinn.simulation.mujoco.settings" not in closure(["madpinn.settings"])
    assert "madpinn.simulation.mujoco.settings" in closure(["madpinn.simulation.settings:SimSettings"])
    # (train-defmarl runs evaluation cells for its validation curve, so it does reach the simulation)
    assert not any(f.startswith("simulation/") for f in _files("train-safemarl-nominal"))
    assert any(f.startswith("simulation/") for f in _files("train-defmarl"))


def _reached_defs(command: str, *methods: str) -> dict[str, frozenset[str] | None]:
    """Package-relative file -> the definitions of it a rule running ``command`` hashes (None: all)."""
    entries = [handler_entry(command)] + [plugin_module("madpinn.policies.base", m) for m in methods]
    from madpinn.provenance import module_path

    return {str(module_path(m).relative_to(PACKAGE)): defs for m, defs in reached(entries).items()}


def test_evaluation_cells_do_not_rerun_for_tables_report_oracle_or_training_edits():
    """Cells hash the value-function modules they run (loading and evaluating a trained network), not
    its training, grid reference or verification: those reach a cell through the model file."""
    for method in registry("madpinn.policies.base"):
        files = _files("evaluate", method)
        for module in ("evaluation/tables.py", "evaluation/reproduction.py", "evaluation/oracle.py",
                       "evaluation/paper_values.yaml", "figures/style.py", "value_functions/train.py",
                       "value_functions/grid_reference.py", "value_functions/verification.py",
                       "value_functions/shipping.py", "commands/value_functions.py", "commands/outputs.py"):
            assert module not in files, (method, module)


def test_editing_one_method_does_not_rerun_another_methods_cells():
    """A cell hashes its own method's policy module, never another method's (nor MAD-PINN's helpers)."""
    methods = registry("madpinn.policies.base")
    for method in methods:
        files = _files("evaluate", method)
        others = {f"policies/{m.rsplit('.', 1)[1]}.py" for k, m in methods.items() if k != method}
        if method != "madpinn":
            others |= {"policies/look_ahead.py", "policies/z_search.py", "policies/neighbours.py"}
        assert not others & files, (method, sorted(others & files))


def test_glue_is_not_hashed_and_the_command_layer_is():
    """Tracking (MLflow logging) writes no result and is not hashed; the command layer and the config
    loading are, down to the definitions a job reaches (issue 63: seeds, written values and filled
    defaults live there): ``evaluate`` hashes its handler, not ``train-value``'s."""
    for command in ("evaluate", "train-value", "table"):
        files = _files(command)
        assert not any(f.startswith("tracking/") or f == "provenance.py" for f in files), command
        assert any(f.startswith("commands/") for f in files) and "config/loading.py" in files, command
    evaluate = _reached_defs("evaluate")
    assert "commands/value_functions.py" not in evaluate
    train = _reached_defs("train-value")["commands/value_functions.py"]
    assert "_train" in train and "_validate_vhat" not in train


def test_the_source_hash_follows_the_files():
    """Editing a hashed file changes the hash; the hash is stable otherwise."""
    entries = ["madpinn.commands.outputs:_oracle"]
    before = source_hash(*entries)
    assert source_hash(*entries) == before
    path = PACKAGE / "evaluation" / "oracle.py"
    text = path.read_text()
    try:
        path.write_text(text + "\n# edited by test_workflow_sources\n")
        assert source_hash(*entries) != before
    finally:
        path.write_text(text)


def test_every_rule_hashes_the_command_it_runs():
    """A rule's ``source=source_hash("<command>", ...)`` names the command of its ``shell:`` line."""
    checked = 0
    for smk in sorted(RULES.glob("*.smk")):
        text = smk.read_text()
        for block in re.split(r"\n\s*rule\b", text)[1:]:
            shell = re.search(r"python -m madpinn ([a-z-]+)", block)
            source = re.search(r"source=(\w+)(?:\(\"([a-z-]+)\")?", block)
            if shell is None or source is None:
                continue
            command = "evaluate" if source.group(1) == "eval_source_hash" else source.group(2)
            assert command == shell.group(1), (smk.name, shell.group(1), source.group(0))
            checked += 1
    assert checked >= 15, checked


# runs `python -m madpinn ARGS`, then prints the package modules loaded (sys.modules: also those
# imported by name through importlib, which `-X importtime` does not show)
_LOADED = ("import atexit, sys; atexit.register(lambda: print('LOADED', *sorted(m for m in sys.modules "
           "if m.startswith('madpinn')), file=sys.stderr)); from madpinn.commands import main; "
           "sys.exit(main(sys.argv[1:]))")


def test_the_closure_covers_what_a_real_job_imports(tmp_path):
    """A real tiny evaluation cell (nominal policy, smoke config): every package module loaded by the
    time it ends is hashed into its cells, except the glue and what the command line's parser loads."""
    from madpinn.provenance import is_glue

    out = tmp_path / "cell.parquet"
    proc = subprocess.run(
        [sys.executable, "-c", _LOADED, "evaluate", "--config", str(REPO / "config.yaml"),
         str(REPO / "workflow" / "configs" / "smoke.yaml"), "--study", "main", "--run", "nominal",
         "--n-agents", "3", "--seed", "100", "--backend", "double_integrator", "--out", str(out), "--no-track",
         "--no-progress"], capture_output=True, text=True, cwd=tmp_path, timeout=600, env=_env())
    assert proc.returncode == 0 and out.is_file(), proc.stderr[-3000:]
    loaded = {m for m in re.search(r"^LOADED (.*)$", proc.stderr, re.M).group(1).split() if not is_glue(m)}
    hashed = closure([handler_entry("evaluate"), plugin_module("madpinn.policies.base", "nominal")])
    # the command line imports every command module to build its parser: their module-level imports
    # (e.g. value_functions.build for the choices of train-value) define names, run no job code
    # (a plugin registry: each job hashes its own); calibrate-vhat's module is registered from inside
    # value_functions.register (issue 62: its own module, so no other value-function job's hash moves),
    # vhat-recipe's and conformal-page's from inside outputs.register (issues 61, 62: likewise for the output jobs)
    parser = closure([f"{m}:" for m in (*COMMAND_MODULES, "madpinn.commands.calibration", "madpinn.commands.recipe",
                                                                  "madpinn.commands.conformal")])
    assert {"madpinn.evaluation.cell", "madpinn.policies.nominal", "madpinn.simulation.simulator"} <= loaded, loaded
    assert not loaded - hashed - parser, sorted(loaded - hashed - parser)


def _env():
    from conftest import subprocess_env

    return subprocess_env({"MADPINN_TRACKING_SOURCE": "manual"})


# --- issue 63: lines of the command layer and the config loading that change a result -------------------------------
# Each edit, in a copy of the package, must change the source hash of exactly the commands that run
# it (a rule's `source` param is its command's hash: test_every_rule_hashes_the_command_it_runs; the
# dry run then plans those jobs: tests/test_moved_code_reruns.py shows it end to end for one line).

_HASHES = ("import json, sys; from madpinn.commands import _handlers, handler_entry; "
           "from madpinn.provenance import source_hash; "
           "print(json.dumps({c: source_hash(handler_entry(c)) for c in _handlers()}))")


@pytest.fixture(scope="module")
def package_copy(tmp_path_factory):
    import shutil

    root = tmp_path_factory.mktemp("package")
    shutil.copytree(PACKAGE, root / "madpinn", ignore=shutil.ignore_patterns("__pycache__"))
    return root, _command_hashes(root)


def _command_hashes(root) -> dict[str, str]:
    import json

    proc = subprocess.run([sys.executable, "-c", _HASHES], capture_output=True, text=True, cwd=root, timeout=300,
                          env=_env() | {"PYTHONPATH": str(root)})
    assert proc.returncode == 0, proc.stderr[-2000:]
    return json.loads(proc.stdout)


@pytest.mark.parametrize("rel, old, new, commands", [
    ("commands/value_functions.py", 'seed=int(cfg["value_functions"]["seed"]) + 1)', 'seed=int(cfg["value_functions"]["seed"]) + 2)',
     {"validate-vhat"}),                                       # a validation seed
    ("commands/value_functions.py", 'stats["target_false_safe_rate"] = 0.01', 'stats["target_false_safe_rate"] = 0.02',
     {"validate-vs"}),                                          # a value written into a result JSON
    ("commands/outputs.py", 'args.scenarios, cfg["sim"]["start_separation"],', 'args.scenarios, 0.5 * cfg["sim"]["start_separation"],',
     {"oracle"}),                                               # the oracle's start separation
    ("commands/outputs.py", 'files = _vhat_budget_figure(cfg, args)', 'files = _vhat_budget_figure(cfg, args)[:1]',
     {"figure"}),                                               # fig_vhat_budget's inputs
    ("commands/defmarl.py", "    from madpinn.marl_hash import marl_training_hash\n",
     "    from madpinn.marl_hash import marl_training_hash\n    variant = variant.strip()\n", {"train-defmarl"}),   # DEF-MARL's resume hash
    ("value_functions/build.py", 'return int(cfg["value_functions"]["seed"] if own is None else own)',
     'return int(cfg["value_functions"]["seed"] + 1 if own is None else own)', {"train-value"}),   # a training seed
    ("config/schema.py", "def fill_defaults(", "def fill_defaults(  # edited\n", None),   # defaults filled: every job
])
def test_each_result_line_of_the_command_layer_reruns_the_jobs_that_run_it(package_copy, rel, old, new, commands):
    root, before = package_copy
    path = root / "madpinn" / rel
    text = path.read_text()
    assert text.count(old) == 1, (rel, old)
    path.write_text(text.replace(old, new))
    try:
        after = _command_hashes(root)
    finally:
        path.write_text(text)
    changed = {c for c in before if before[c] != after[c]}
    if commands is None:   # read by every job that loads a config
        assert {"evaluate", "train-value", "oracle", "table", "train-defmarl"} <= changed, sorted(changed)
    else:
        assert changed == commands, sorted(changed)


def test_a_new_command_family_re_keys_no_job(package_copy):
    """Adding a job family to the command registry (``madpinn/commands/__init__.py:_MODULES``) leaves
    every existing command's source hash as it was: a job follows its own handler, not the registry's
    other lines (before 2026-12-02 one new entry moved every job's hash)."""
    root, before = package_copy
    init, family = root / "madpinn" / "commands" / "__init__.py", root / "madpinn" / "commands" / "extra_family.py"
    text = init.read_text()
    old = '    "timing": "madpinn.commands.timing",  # neighbour-timing\n'
    assert text.count(old) == 1
    family.write_text("def _run(args):\n    return 0\n\n\ndef register(sub):\n"
                      "    sub.add_parser('extra-command').set_defaults(func=_run)\n")
    init.write_text(text.replace(old, old + '    "extra_family": "madpinn.commands.extra_family",  # extra-command\n'))
    try:
        after = _command_hashes(root)
    finally:
        init.write_text(text)
        family.unlink()
    assert "extra-command" in after and set(before) < set(after)
    assert {c: after[c] for c in before} == before
