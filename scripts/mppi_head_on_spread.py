"""Spread of the MPPI head-on test (tests/test_mppi.py::test_head_on_penalty_bends_paths) over
policy seeds: per seed and λ, the number of the 16 encounters that collide (separation < r) and
the mean separation (m). Each encounter is a chaotic draw, so the test asserts margins on these
batch statistics; this prints the distribution the margins are chosen from (docs/reference/reliability.md).

    PYTHONPATH=$PWD python scripts/mppi_head_on_spread.py --seeds 0 1 2 3 4 5 6 [--angle-offset 1e-6]
"""

from __future__ import annotations

import argparse

import torch

from madpinn.config import load_config, method_config
from madpinn.dynamics import DoubleIntegrator
from madpinn.observation import ObservationSettings
from madpinn.policies import PolicyContext, make_policy
from madpinn.simulation import DoubleIntegratorBackend, run_episode

SIM_DT, PERIOD, STEPS, S = 0.0025, 2, 600, 16
FAST = {"samples": 48, "horizon": 8, "plan_dt": 0.1}  # tests/test_mppi.py


def head_on(offset: float = 0.0):
    """16 head-on encounters of two agents 1.2 m apart, their axis turned by k·π/16 (+ offset) rad."""
    angle = torch.arange(S, dtype=torch.float64) * (torch.pi / S) + offset
    d = (0.6 * torch.stack([angle.cos(), angle.sin()], dim=-1)).float()
    return torch.stack([-d, d], dim=1), torch.stack([d, -d], dim=1)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--config", nargs="+", default=["config.yaml"])
    ap.add_argument("--seeds", type=int, nargs="+", default=[0, 1, 2])
    ap.add_argument("--lambdas", type=float, nargs="+", default=[0.0, 1000.0])
    ap.add_argument("--angle-offset", type=float, default=0.0, help="rad; a tiny one mimics another CPU's rounding")
    args = ap.parse_args()
    torch.set_num_threads(1)
    cfg = load_config(args.config)
    r = cfg["agents"]["collision_radius"]
    starts, goals = head_on(args.angle_offset)
    print("seed  lambda  collisions/16  mean_sep_m  min_sep_m")
    for seed in args.seeds:
        for lam in args.lambdas:
            _, mcfg = method_config(cfg, "mppi")
            mcfg = {**mcfg, **FAST, "penalty_weight": lam, "dual_ascent": {"lr": 0.0, "max": 1.0e4}}
            ctx = PolicyContext(cfg=cfg, method_cfg=mcfg, dynamics=DoubleIntegrator(u_max=4.0, v_max=4.0), obs_spec=ObservationSettings.from_config(cfg),
                                device=torch.device("cpu"), dtype=torch.float32, seed=seed, sim_dt=SIM_DT, policy_period=PERIOD)
            backend = DoubleIntegratorBackend(DoubleIntegrator(u_max=4.0, v_max=4.0), SIM_DT)
            result, _ = run_episode(backend, make_policy("mppi", ctx), starts, goals, STEPS, r, policy_period=PERIOD, progress=False)
            sep = result.min_separation.min(axis=1)
            print(f"{seed:4d}  {lam:6g}  {int((sep < r).sum()):13d}  {sep.mean():10.4f}  {sep.min():9.4f}", flush=True)


if __name__ == "__main__":
    main()
