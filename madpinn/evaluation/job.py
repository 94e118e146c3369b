"""One evaluation job: a (study, run, N, seed) cell -> per-scenario Parquet + JSON summary.

Scenarios are simulated in batches of ``sim.scenario_batch``; all agents of a batch are
computed together. The job's MLflow run is live while it runs; files are written first and
a tracking failure cannot lose them.
"""

from __future__ import annotations

import json
import time
from pathlib import Path

import numpy as np
import pandas as pd

from madpinn.config import config_hash, job_config, method_config
from madpinn.device import resolve_device, resolve_dtype, seed_everything
from madpinn.dynamics import DoubleIntegrator
from madpinn.evaluation.metrics import scenario_metrics, seed_summary
from madpinn.observation import ObservationSpec
from madpinn.policies import PolicyContext, make_policy
from madpinn.scenarios import Arena, generate_scenarios
from madpinn.simulation import make_backend, run_episode


def episode_steps(cfg: dict, arena: Arena) -> int:
    return int(round(arena.episode_s / cfg["sim"]["dt"]))


def policy_period(cfg: dict, mcfg: dict) -> int:
    """Simulation steps between policy queries: the method's own setting, else ``sim``'s."""
    return int(mcfg.get("policy_period_steps", cfg["sim"]["policy_period_steps"]))


def policy_context(cfg: dict, mcfg: dict, seed: int, batch_index: int, device, dtype) -> PolicyContext:
    """Context of the policy that runs scenario batch ``batch_index`` of a job with ``seed``
    (the policy's own seed is a pure function of both)."""
    return PolicyContext(
        cfg=cfg, method_cfg=mcfg, dynamics=DoubleIntegrator(u_max=cfg["agents"]["u_max"], v_max=cfg["agents"]["v_max"]),
        obs_spec=ObservationSpec.from_config(cfg), device=device, dtype=dtype, seed=int(seed) * 1_000_003 + batch_index,
        sim_dt=cfg["sim"]["dt"], policy_period=policy_period(cfg, mcfg), models_dir=Path(cfg["paths"]["results"]) / "models",
    )


def evaluate(
    cfg: dict,
    study: str,
    run: str,
    n_agents: int,
    seed: int,
    out: str | Path,
    backend: str | None = None,
    threads: int = 1,
    progress: bool = True,
    track: bool = True,
) -> dict:
    """Run one evaluation cell and write ``out`` (.parquet), ``out``.json and ``out``_traj.npz,
    inside one live MLflow run (opened before the simulation, closed with the job's status)."""
    from madpinn.tracking import job_run

    out = Path(out)
    if study not in cfg["studies"]:
        raise ValueError(f"unknown study '{study}' (configured: {sorted(cfg['studies'])})")
    method, mcfg = method_config(cfg, run)
    backend = backend or cfg["sim"]["backend"]
    arena_name = cfg["studies"][study]["arena"]
    with job_run(
        cfg, job_key=f"evaluate/{backend}/{study}/{run}/n{n_agents}/seed{seed}", rule="evaluate",
        wildcards={"backend": backend, "study": study, "run": run, "n": n_agents, "seed": seed},
        params={"method": method, "method_config": mcfg, "arena": cfg["arenas"][arena_name],
                "scenarios": cfg["studies"][study]["scenarios"], "sim": cfg["sim"], "observation": cfg["observation"]},
        track=track,
    ) as tracker:
        summary, files = _evaluate_cell(cfg, study, run, method, mcfg, backend, n_agents, seed, out, threads, progress)
        tracker.finish(
            metrics={**{k: summary[k] for k in ("safety_rate", "safe_scenarios", "cost", "cost_time_avg", "cost_all",
                                                 "cost_all_time_avg", "elapsed_s", "policy_us_per_agent_step")},
                     **{f"policy_{k}": v for k, v in summary.get("policy_stats", {}).items()}},
            artifacts=files,
        )
    return summary


def _evaluate_cell(cfg, study, run, method, mcfg, backend, n_agents, seed, out: Path, threads, progress):
    """The cell's simulation and files; returns ``(summary, [parquet, json, npz])``."""
    st = cfg["studies"][study]
    arena = Arena.from_config(cfg, st["arena"])
    device, dtype = resolve_device(cfg["device"]), resolve_dtype(cfg["dtype"])
    seed_everything(seed, threads)
    r = float(cfg["agents"]["collision_radius"])
    n_steps = episode_steps(cfg, arena)
    period = policy_period(cfg, mcfg)

    frames, traj, timing, policy_stats = [], None, {"wall_s": 0.0, "policy_s": 0.0}, {}
    total, batch = int(st["scenarios"]), int(cfg["sim"]["scenario_batch"])
    t0 = time.perf_counter()
    for b, first in enumerate(range(0, total, batch)):
        count = min(batch, total - first)
        starts, goals = generate_scenarios(arena, n_agents, seed, count, r, device, dtype, first_index=first)
        policy = make_policy(method, policy_context(cfg, mcfg, seed, b, device, dtype))
        sim = make_backend(backend, cfg, device, dtype)
        result, stats = run_episode(
            sim, policy, starts, goals, n_steps, r, policy_period=period,
            record_every=int(cfg["sim"]["record_every"]) if first == 0 else 0,
            progress=progress, desc=f"{run} N={n_agents} seed={seed} [{first}:{first + count}]",
        )
        timing["wall_s"] += stats["wall_s"]
        timing["policy_s"] += stats["policy_s"]
        if hasattr(policy, "summarise_stats"):   # policies with summable counters (dict) report them
            for k, v in policy.stats.items():
                policy_stats[k] = policy_stats.get(k, 0) + v
        frames.append(scenario_metrics(result, first_index=first))
        if first == 0:
            traj = result
    df = pd.concat(frames, ignore_index=True)
    meta = {"study": study, "run": run, "method": method, "backend": backend, "arena": arena.name, "seed": int(seed)}
    for k, v in meta.items():
        df.insert(0, k, v)

    summary = {
        **meta,
        "n_agents": int(n_agents),
        **seed_summary(df),
        "n_steps": n_steps,
        "dt": cfg["sim"]["dt"],
        "elapsed_s": time.perf_counter() - t0,
        "sim_wall_s": timing["wall_s"],
        "policy_s": timing["policy_s"],
        "policy_us_per_agent_step": 1e6 * timing["policy_s"] / max(1, total * n_agents * (n_steps // period)),
        "job_config_hash": config_hash(job_config(cfg, study, run)),
        "device": str(device),
    }
    if policy_stats:   # only collected from policies with summarise_stats
        summary["policy_stats"] = policy.summarise_stats(policy_stats)
    out.parent.mkdir(parents=True, exist_ok=True)
    df.to_parquet(out, index=False)
    json_path = out.with_suffix(".json")
    json_path.write_text(json.dumps(summary, indent=2))
    traj_path = out.with_name(out.stem + "_traj.npz")
    np.savez_compressed(
        traj_path, times=traj.times, positions=traj.positions[:, 0], goals=traj.goals[0],
        collided=traj.collided[0], first_collision_step=traj.first_collision_step[0], dt=traj.dt,
        collision_radius=r, half_width=arena.half_width,
    )
    return summary, [out, json_path, traj_path]
