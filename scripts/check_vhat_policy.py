"""Sanity check of a trained V̂: the induced ego policy (bang-bang from ∇V̂ at z*, SPEC §6, here
with the 2 nearest neighbours) drives a single agent to its goal and makes two agents on a
head-on course avoid each other. A development check, not the MAD-PINN policy itself.

    PYTHONPATH=$PWD python scripts/check_vhat_policy.py results/models/vhat.pt [--config config.yaml] [--symmetry point]
"""

from __future__ import annotations

import argparse
import json

import torch

from madpinn.config import load_config
from madpinn.dynamics import DoubleIntegrator
from madpinn.observation import ObservationSettings, build_observation, nearest_neighbours
from madpinn.simulation import run_episode
from madpinn.simulation.backend import DoubleIntegratorBackend
from madpinn.value_functions import min_feasible_z
from madpinn.value_functions.model import load_value_function
from madpinn.value_functions.symmetry import GROUPS, symmetrize


class GreedyVHatPolicy:
    """u_ego = −u_max·sign(∂V̂/∂v_ego) at (t = 0, o, z*) every call (z*: the deployed search at
    ``z_tolerance``); nearest neighbours."""

    def __init__(self, vhat, u_max: float, z_tolerance: float):
        self.vhat, self.u_max, self.z_tolerance = vhat, u_max, z_tolerance

    def reset(self, state, goals):
        pass

    def act(self, state, goals, t):
        S, N, _ = state.shape
        spec = self.vhat.obs_spec
        obs = build_observation(state, goals, nearest_neighbours(spec.agent.position(state), spec.n_neighbours), spec).reshape(S * N, -1)
        z, _ = min_feasible_z(self.vhat, obs, self.z_tolerance)
        _, grad, _ = self.vhat.value_and_grad(obs, z, 0.0)
        return (-self.u_max * torch.sign(grad[:, 0:2])).reshape(S, N, 2)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("model")
    ap.add_argument("--config", default="config.yaml")
    ap.add_argument("--seconds", type=float, default=2.0)
    ap.add_argument("--symmetry", default="none", choices=GROUPS, help="average V̂ over this symmetry group")
    args = ap.parse_args()
    torch.set_num_threads(1)
    cfg = load_config([args.config])
    vhat = symmetrize(load_value_function(args.model, "vhat"), args.symmetry)  # a final model or a training checkpoint
    dyn = DoubleIntegrator(cfg["agents"]["u_max"], cfg["agents"]["v_max"])
    dt, r = cfg["sim"]["dt"], cfg["agents"]["collision_radius"]
    steps = int(round(args.seconds / dt))
    # Bystanders parked at their goals far away fill the observation instead of phantoms: with
    # fewer than n real neighbours build_observation puts every phantom at the same corner, so
    # phantom pairs "collide" (g_d = r > 0) and V̂ > 0 for every z (see docs/reference/value_functions.md).
    far = [[-3.0, 3.0], [3.0, -3.0]]
    cases = {
        "single_agent": (torch.tensor([[[-0.6, -0.4], *far]]), torch.tensor([[[0.7, 0.5], *far]])),
        # each of the pair has its own nearest bystander, placed point-symmetrically
        "head_on_pair": (torch.tensor([[[-0.6, 0.0], [0.6, 0.02], *far]]), torch.tensor([[[0.6, 0.0], [-0.6, 0.02], *far]])),
        "head_on_pair_one_bystander": (torch.tensor([[[-0.6, 0.0], [0.6, 0.02], far[0]]]),
                                       torch.tensor([[[0.6, 0.0], [-0.6, 0.02], far[0]]])),
        "three_agents": (torch.tensor([[[-0.6, 0.0], [0.6, 0.02], [0.0, -0.6]]]),
                         torch.tensor([[[0.6, 0.0], [-0.6, 0.02], [0.0, 0.6]]])),
    }
    out = {}
    for name, (starts, goals) in cases.items():
        backend = DoubleIntegratorBackend(dyn, dt)
        res, _ = run_episode(backend, GreedyVHatPolicy(vhat, dyn.u_max, cfg["methods"]["madpinn"]["z_tolerance"]), starts, goals, steps, r, record_every=0,
                             progress=False)
        out[name] = {k: getattr(res, k)[0].astype(float).round(3).tolist() for k in ("collided", "min_separation", "final_distance", "cost")}
    print(json.dumps(out, indent=1))


if __name__ == "__main__":
    main()
