"""Import every module of a package: a package whose modules register plugins when they are
defined (the agent models of :mod:`madpinn.dynamics`) needs no list of them.

:mod:`madpinn.provenance` follows the call: a package ``__init__`` that calls
``import_submodules(__name__)`` reaches each of its modules whole, so a job's source hash covers
every module the call imports.
"""

from __future__ import annotations

import importlib
import pkgutil
import sys
from types import ModuleType


def import_submodules(package: str) -> list[ModuleType]:
    """Import each module and sub-package of ``package`` (dotted name, already being imported),
    in name order; returns them."""
    path = sys.modules[package].__path__
    return [importlib.import_module(f"{package}.{info.name}") for info in sorted(pkgutil.iter_modules(path), key=lambda i: i.name)]
