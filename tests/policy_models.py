"""Tiny real value functions for the policy tests, trained once per test process through the
same trainer as the workflow (smoke network and budget: a few seconds)."""

from __future__ import annotations

import functools
import tempfile
from pathlib import Path

import torch

from conftest import REPO, SMOKE
from madpinn.config import load_config
from madpinn.value_functions import load_vhat, load_vs
from madpinn.value_functions.build import problem_from_config, training_hash
from madpinn.value_functions.model import model_payload, save_atomic
from madpinn.value_functions.train import TrainSettings, train


MODEL_3D = {"agents": {"model": "double_integrator_3d"}}
"""the overlay that flies the agents as the 3-D double integrator (issue 63 item 2)"""


def smoke_config_3d() -> dict:
    """The smoke configuration with the 3-D agent model for every study: each keeps the runs whose
    methods fly it (the schema's ``x-flown-by``, ``madpinn.config.model_methods``; the config check refuses the others)."""
    import yaml

    from madpinn.config import model_methods

    flying = model_methods()[MODEL_3D["agents"]["model"]]
    planar = load_config([REPO / "config.yaml", SMOKE])
    runs = {name: {"runs": [r for r in st["runs"] if r.partition("-")[0] in flying] or ["nominal"]}
            for name, st in planar["studies"].items()}
    overlay = Path(tempfile.mkdtemp(prefix="madpinn-3d-")) / "model_3d.yaml"
    overlay.write_text(yaml.safe_dump({**MODEL_3D, "studies": runs}))
    return load_config([REPO / "config.yaml", SMOKE, overlay])


@functools.lru_cache(maxsize=None)
def tiny_model_dir(three_d: bool = False) -> Path:
    """Directory with ``models/vhat.pt`` and ``models/vs.pt`` trained on the smoke budget (``three_d``:
    for the 3-D agent model)."""
    cfg = smoke_config_3d() if three_d else load_config([REPO / "config.yaml", SMOKE])
    out = Path(tempfile.mkdtemp(prefix="madpinn-policy-test-")) / "models"
    torch.set_num_threads(1)
    for kind in ("vhat", "vs"):
        problem = problem_from_config(cfg, kind)
        settings = TrainSettings.from_config(cfg["value_functions"][kind], cfg["value_functions"]["seed"])
        net, _ = train(problem, settings, out / f"{kind}.ckpt.pt", training_hash(cfg, kind), progress=False)
        meta = {"iterations": settings.iterations, "config_hash": training_hash(cfg, kind)}   # as the train-value job writes
        save_atomic(model_payload(problem, net, settings.output_scale, meta), out / f"{kind}.pt")
    return out


def tiny_models(dtype=torch.float32, three_d: bool = False):
    d = tiny_model_dir(three_d)
    return load_vhat(d / "vhat.pt", dtype=dtype), load_vs(d / "vs.pt", dtype=dtype)
