"""A new agent model is one module in ``madpinn/dynamics/`` plus its schema entry (issue 63): no list
names it. Its class registers itself (``AgentModel.__init_subclass__``), the package imports every
one of its modules (``import_submodules``), and a job's source hash follows that import, so an edit
to the new module re-keys the cells that could fly it.

The new module is written into a copy of the package (never into the package under test: other
test workers hash it), and read there by a subprocess.
"""

from __future__ import annotations

import shutil
import subprocess
import sys
import textwrap
from pathlib import Path

import pytest

from madpinn.dynamics import MODELS, PAPER_MODEL, DoubleIntegrator
from madpinn.provenance import PACKAGE, imports, package_modules

TOY = textwrap.dedent('''
    """A toy agent model for the registry test: the planar double integrator under another name."""
    from dataclasses import dataclass
    from typing import ClassVar

    from madpinn.dynamics.double_integrator import DoubleIntegrator


    @dataclass(frozen=True)
    class ToyModel(DoubleIntegrator):
        name: ClassVar[str] = "toy_model"
''')

PROBE = textwrap.dedent('''
    import sys
    from madpinn.dynamics import MODELS, model_class
    from madpinn.commands import handler_entry
    from madpinn.provenance import source_hash
    print(sorted(MODELS))
    print(model_class("toy_model").__module__)
    print(source_hash(handler_entry("evaluate")))
''')


def _probe(root: Path) -> list[str]:
    out = subprocess.run([sys.executable, "-c", PROBE], cwd=root, env={"PYTHONPATH": str(root), "PATH": "/usr/bin:/bin"},
                         capture_output=True, text=True, timeout=120)
    assert out.returncode == 0, out.stderr[-2000:]
    return out.stdout.splitlines()


def test_a_module_in_the_dynamics_package_is_a_model_and_is_hashed(tmp_path):
    copy = tmp_path / "madpinn"
    shutil.copytree(PACKAGE, copy, ignore=shutil.ignore_patterns("__pycache__"))
    module = copy / "dynamics" / "toy_model.py"
    module.write_text(TOY)
    models, home, first = _probe(tmp_path)
    assert models == str(sorted([*MODELS, "toy_model"])) and home == "madpinn.dynamics.toy_model"
    module.write_text(TOY + "\n# an edit that changes nothing but the bytes\n")
    assert _probe(tmp_path)[2] != first   # the evaluate job re-keys: the package's import of it is followed


def test_the_package_reaches_each_of_its_modules_whole():
    reached = imports("madpinn.dynamics")
    assert set(package_modules("madpinn.dynamics")) <= reached
    assert "madpinn.dynamics.double_integrator_3d" in reached and PAPER_MODEL == DoubleIntegrator.name in MODELS


def test_two_models_of_one_name_are_refused():
    from dataclasses import dataclass
    from typing import ClassVar

    with pytest.raises(ValueError, match="two agent models are named 'double_integrator'"):
        @dataclass(frozen=True)
        class Again(DoubleIntegrator):
            name: ClassVar[str] = "double_integrator"
