"""One sensing radius for every method (issue 47, docs/reference/protocol.md §8): no policy reads an agent
beyond ``observation.sensing_radius``.

Behavioural check on the shipped models: the ego's control must not change when agents beyond the
radius (of the ego and of every agent it senses, so no relayed information either) move elsewhere
beyond it or change velocity. They stay inside V_s's 2 m box, where the protocol before issue 47
ranked them, so MAD-PINN's value ranking fails this test without the radius.
"""

from __future__ import annotations

import pytest
import torch

from conftest import REPO
from madpinn.config import load_config
from madpinn.evaluation.cell import CellSettings, policy_context
from madpinn.policies import make_policy
from madpinn.dynamics import DoubleIntegrator
from madpinn.policies.neighbours import in_domain, make_selector
from madpinn.value_functions import load_vs

MODELS = REPO / "models"
RUN_MODELS = {   # the trained files each method's factory loads (ctx.model names)
    "madpinn": {"vhat": MODELS / "vhat.pt", "vs": MODELS / "vs.pt"},
    "safemarl": {"nominal": MODELS / "safemarl_nominal.pt", "vs": MODELS / "vs.pt"},
    "defmarl-n3": {"policy": MODELS / "defmarl_n3.pt"},
    "defmarl-n8": {"policy": MODELS / "defmarl_n8.pt"},
}
RUNS = ["madpinn", "madpinn-nearest", "madpinn-random", "madpinn-lookahead", "madpinn-filtered", "mppi", "safemarl",
        "safemarl-layered", "safemarl-unfiltered", "defmarl-n3", "defmarl-n8", "nominal"]


@pytest.fixture(scope="module")
def cfg():
    return load_config([REPO / "config.yaml"])


def _scene(far: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor]:
    """Ego 0 at the origin moving +x, agent 1 sensed 0.5 m behind it, agents 2-3 at ``far``
    ``[2, 4]``; one scenario ``[1, 4, 4]`` and its goals ``[1, 4, 2]``."""
    near = torch.tensor([[0.0, 0.0, 1.0, 0.0], [-0.5, 0.0, 1.0, 0.3]])
    state = torch.cat([near, far]).unsqueeze(0)
    goals = torch.tensor([[[0.8, 0.2], [0.6, -0.5], [-0.6, 0.4], [-0.5, -0.7]]])
    return state, goals


# agents 2-3: > 1 m from the ego and from agent 1, < 2 m per axis from the ego (inside V_s's box)
FAR = [torch.tensor([[1.4, 0.0, -2.0, 0.0], [1.2, 1.0, -1.0, -1.5]]),
       torch.tensor([[1.5, -0.3, -3.0, 0.5], [1.1, 1.2, 0.0, -2.5]]),
       torch.tensor([[1.6, 0.4, 0.5, 0.0], [1.3, -1.1, -2.0, 2.0]])]


def test_scene_puts_the_far_agents_beyond_the_radius_and_inside_the_vs_box(cfg):
    radius = float(cfg["observation"]["sensing_radius"])
    for far in FAR:
        state, _ = _scene(far)
        d = torch.cdist(state[0, :, 0:2], state[0, :, 0:2])
        assert (d[:2, 2:] > radius + 0.05).all() and d[0, 1] < radius
        assert in_domain(state, 2.0, 8.0, DoubleIntegrator)[0, 0, 2:].all()     # the old ranking's candidates


@pytest.mark.parametrize("run", RUNS)
def test_no_method_reads_an_agent_beyond_the_sensing_radius(cfg, run, one_thread):
    cs = CellSettings.from_config(cfg, "main", run)
    assert cs.observation.sensing_radius == cfg["observation"]["sensing_radius"]
    models = RUN_MODELS.get(run, RUN_MODELS.get(run.split("-")[0], {}))
    controls = []
    for far in FAR:
        policy = make_policy(cs.method, policy_context(cs, 0, 0, torch.device("cpu"), torch.float32, models))
        state, goals = _scene(far)
        with torch.no_grad():
            policy.reset(state, goals)
            controls.append(policy.act(state, goals, 0.0)[0, 0])
    for u in controls[1:]:
        assert torch.equal(u, controls[0]), f"{run}: the ego's control depends on agents beyond the sensing radius"


def test_value_ranking_reads_farther_agents_only_with_a_wider_radius(cfg):
    """The sensitivity row (``madpinn-wide``, 2.83 m) ranks the far agents again: the radius, not
    the scene, is what hides them."""
    vs = load_vs(MODELS / "vs.pt")
    state, _ = _scene(FAR[0])
    narrow = make_selector("value", 2, vs=vs, radius=float(cfg["observation"]["sensing_radius"]))(state)
    wide_radius = CellSettings.from_config(cfg, "main", "madpinn-wide").observation.sensing_radius
    wide = make_selector("value", 2, vs=vs, radius=wide_radius)(state)
    assert narrow[0, 0].tolist() == [1, -1]                   # agent 1, then a phantom
    assert set(wide[0, 0].tolist()) <= {1, 2, 3} and -1 not in wide[0, 0].tolist()
