"""One evaluation cell: a (study, run, N, seed) -> per-scenario metrics, summary, trajectory.

Scenarios are simulated in batches of ``sim.scenario_batch``; all agents of a batch are
computed together. :func:`run_cell` computes, :func:`write_cell` writes the result files
(the ``evaluate`` command then logs them to MLflow).
"""

from __future__ import annotations

import importlib
import json
import time
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Callable, Mapping

import numpy as np
import pandas as pd

from madpinn.config import ConfigError, RunSettings, config_hash
from madpinn.device import resolve_device, resolve_dtype, seed_everything
from madpinn.evaluation.cell_files import cell_paths
from madpinn.evaluation.metrics import scenario_metrics, seed_summary
from madpinn.observation import ObservationSettings
from madpinn.policies import PolicyContext, make_policy, policy_settings
from madpinn.encounters import straight_line_encounters
from madpinn.machine import cpu_model
from madpinn.scenarios import Arena, generate_scenarios, horizon_steps
from madpinn.settings import AgentSettings
from madpinn.simulation.settings import SimSettings
from madpinn.simulation import EpisodeResult, make_backend, run_episode


_MODULES = {"agents": "madpinn.evaluation.run_overrides"}
"""run override key -> the module that applies it, imported only for a run that has the key (a
plugin registry: :mod:`madpinn.provenance` hashes it into those runs' cells alone)"""


def run_limits(cfg: Mapping, method_cfg: Mapping) -> AgentSettings:
    """The agents a run's cells simulate: ``agents``, or for a run with its own ``agents`` override
    (``methods.<method>[.variants.<v>].agents``, a speed governor) that override merged over it
    (:func:`madpinn.evaluation.run_overrides.governed_limits`)."""
    override = method_cfg.get("agents")
    if not override:
        return AgentSettings.from_config(cfg)
    return importlib.import_module(_MODULES["agents"]).governed_limits(cfg["agents"], override)


@dataclass(frozen=True)
class CellSettings:
    """Everything an evaluation cell of (study, run) depends on, parsed once from the config."""

    study: str
    """study name (``studies.<study>``)"""
    run: str
    """run name ``method[-variant]``"""
    method: str
    """policy registry name"""
    method_settings: Any
    """the method's settings object (variant merged)"""
    arena: Arena
    """the study's arena"""
    pattern: str
    """the study's scenarios: ``uniform`` (SPEC §2) or a structured conflict (:mod:`madpinn.conflicts`)"""
    scenarios: int
    """scenarios per (N, seed) cell"""
    limits: AgentSettings
    """agents' size and control limits (with the run's own ``agents`` override: :func:`run_limits`)"""
    sim: SimSettings
    """simulation settings"""
    observation: ObservationSettings
    """decentralized observation layout"""
    policy_period: int
    """simulation steps between policy queries (the method's own setting, else ``sim``'s)"""
    device: str
    """``device`` setting (auto | cpu | cuda)"""
    dtype: str
    """``dtype`` setting"""
    job_config_hash: str
    """hash of the config part the cell depends on (:func:`madpinn.config.job_config`)"""
    horizon_steps: tuple[int, ...]
    """simulation steps of the study's ``cost_horizons_s``: cost and safety also read there (:func:`madpinn.evaluation.metrics.scenario_metrics`)"""
    collision_events: bool
    """the study's ``collision_events``: classify every collision onset
    (:class:`madpinn.evaluation.collisions.CollisionProbe`, MAD-PINN runs) into the cell's summary"""

    @classmethod
    def from_config(cls, cfg: Mapping, study: str, run: str) -> "CellSettings":
        return cls.from_run(cfg, RunSettings.resolve(cfg, study, run))

    @classmethod
    def from_run(cls, cfg: Mapping, r: RunSettings) -> "CellSettings":
        """From the run resolved once (:class:`madpinn.config.RunSettings`: its study's agent model
        among them) and the config's shared sections (``device``, ``dtype``)."""
        st, mcfg = r.study_config, r.method_config
        if st["collision_events"] and r.method != "madpinn":
            raise ConfigError(f"studies.{r.study}.collision_events classifies MAD-PINN collisions; run '{r.run}' is not a MAD-PINN run")
        sim = SimSettings.from_section(r.sim)
        flown = {**cfg, "agents": r.study_agents}   # the study's agent model (studies.<s>.agents over agents)
        return cls(
            study=r.study, run=r.run, method=r.method, method_settings=policy_settings(r.method, mcfg),
            arena=Arena.from_config(cfg, st["arena"]), pattern=str(st["pattern"]), scenarios=int(st["scenarios"]), limits=run_limits(flown, mcfg),
            sim=sim, observation=ObservationSettings.from_config({**flown, "observation": r.observation}),
            policy_period=sim.policy_period_steps if mcfg["policy_period_steps"] is None else int(mcfg["policy_period_steps"]),
            device=str(cfg["device"]), dtype=str(cfg["dtype"]), job_config_hash=config_hash(r.job_config),
            horizon_steps=horizon_steps(st["cost_horizons_s"], float(cfg["arenas"][st["arena"]]["episode_s"]), sim.dt),
            collision_events=bool(st["collision_events"]),
        )

    @property
    def episode_steps(self) -> int:
        """Simulation steps of one episode."""
        return int(round(self.arena.episode_s / self.sim.dt))


def policy_context(cs: CellSettings, seed: int, batch_index: int, device, dtype,
                   models: Mapping[str, Path] | None = None) -> PolicyContext:
    """Context of the policy that runs scenario batch ``batch_index`` of a job with ``seed``
    (the policy's own seed is a pure function of both); ``models`` names the trained files it loads."""
    return PolicyContext(
        method=cs.method_settings, dynamics=cs.limits.dynamics(), obs_spec=cs.observation, device=device, dtype=dtype,
        seed=int(seed) * 1_000_003 + batch_index, sim_dt=cs.sim.dt, policy_period=cs.policy_period,
        models=dict(models or {}),
    )


@dataclass
class Cell:
    """Result of one evaluation cell."""

    frame: pd.DataFrame
    """one row per scenario (SPEC §3 metrics, with study/run/method/backend/arena/seed columns)"""
    summary: dict
    """seed-level summary (safety rate, cost, timings, config hash)"""
    trajectory: EpisodeResult
    """the first scenario batch's recorded episode"""
    collision_radius: float
    """agent collision radius r (m)"""
    half_width: float
    """arena half width (m)"""


def cell_batches(cs: CellSettings, n_agents: int, seed: int, backend: str, device, dtype,
                 models: Mapping[str, Path] | None = None,
                 wrap: Callable[[Any, int], Any] | None = None, record: bool = False, progress: bool = True):
    """Simulate one cell batch by batch (``cs.sim.scenario_batch`` scenarios each, fresh policy and
    backend per batch); yield ``(first scenario index, policy, EpisodeResult, run stats)``. The
    one loop of :func:`run_cell` (with the collision probe where the study asks for it) and of
    ``scripts/defmarl_consensus.py``: ``wrap(policy, first)`` replaces the policy (e.g. by a probe
    around it), ``record`` keeps the first batch's trajectories."""
    total = cs.scenarios
    batch = cs.sim.scenario_batch
    for b, first in enumerate(range(0, total, batch)):
        count = min(batch, total - first)
        starts, goals = generate_scenarios(cs.arena, n_agents, seed, count, cs.sim.start_separation, device, dtype, first_index=first,
                                           pattern=cs.pattern)
        encounters = np.stack([straight_line_encounters(s_, g_, cs.limits.v_max, 2 * cs.limits.collision_radius,
                                                        cs.episode_steps * cs.sim.dt)
                               for s_, g_ in zip(starts.cpu().double().numpy(), goals.cpu().double().numpy())])
        model = cs.limits.dynamics()
        starts, goals = model.place(starts), model.place(goals)   # the planar layout in the agents' space
        policy = make_policy(cs.method, policy_context(cs, seed, b, device, dtype, models))
        if wrap is not None:
            policy = wrap(policy, first)
        sim = make_backend(backend, cs.sim, cs.limits, device, dtype)
        result, stats = run_episode(
            sim, policy, starts, goals, cs.episode_steps, cs.limits.collision_radius, policy_period=cs.policy_period,
            record_every=cs.sim.record_every if record and first == 0 else 0,
            progress=progress, desc=f"{cs.run} N={n_agents} seed={seed} [{first}:{first + count}]",
            horizon_steps=cs.horizon_steps,
        )
        stats["encounters"] = encounters   # [S, N]: the layout's straight-line encounters per agent
        yield first, policy, result, stats


def run_cell(
    cs: CellSettings,
    n_agents: int,
    seed: int,
    models: Mapping[str, str | Path] | None = None,
    backend: str | None = None,
    threads: int = 1,
    progress: bool = True,
) -> Cell:
    """Simulate every scenario of one cell; ``models`` names the trained files the run's policy loads."""
    models = {k: Path(v) for k, v in (models or {}).items()}
    backend = backend or cs.sim.backend
    arena = cs.arena
    device, dtype = resolve_device(cs.device), resolve_dtype(cs.dtype)
    seed_everything(seed, threads)
    r = cs.limits.collision_radius
    n_steps = cs.episode_steps
    period = cs.policy_period

    frames, traj, timing, policy_stats, events = [], None, {"wall_s": 0.0, "policy_s": 0.0}, {}, []
    total = cs.scenarios
    t0, cpu0 = time.perf_counter(), time.process_time()
    for first, policy, result, stats in cell_batches(cs, n_agents, seed, backend, device, dtype, models,
                                                     wrap=_collision_probe(r) if cs.collision_events else None,
                                                     record=True, progress=progress):
        if cs.collision_events:
            events += policy.events
        timing["wall_s"] += stats["wall_s"]
        timing["policy_s"] += stats["policy_s"]
        if hasattr(policy, "summarise_stats"):   # policies with summable counters (dict) report them
            for k, v in policy.stats.items():
                policy_stats[k] = policy_stats.get(k, 0) + v
        frame = scenario_metrics(result, first_index=first)
        frame["encounters_per_agent"] = stats["encounters"].mean(axis=1)   # at v_max, within 2r, over the episode
        frames.append(frame)
        if first == 0:
            traj = result
    df = pd.concat(frames, ignore_index=True)
    meta = {"study": cs.study, "run": cs.run, "method": cs.method, "backend": backend, "arena": arena.name, "seed": int(seed)}
    for k, v in meta.items():
        df.insert(0, k, v)

    summary = {
        **meta,
        "n_agents": int(n_agents),
        **seed_summary(df),
        "n_steps": n_steps,
        "dt": cs.sim.dt,
        "elapsed_s": time.perf_counter() - t0,
        "cpu_s": time.process_time() - cpu0,   # process CPU time (s, all threads): what a loaded machine inflates least
        "sim_wall_s": timing["wall_s"],
        "policy_s": timing["policy_s"],
        "policy_us_per_agent_step": 1e6 * timing["policy_s"] / max(1, total * n_agents * (n_steps // period)),
        "job_config_hash": cs.job_config_hash,
        "device": str(device),
        "cpu_model": cpu_model(),   # the machine behind elapsed_s / cpu_s (benchmarks compare them on the same CPU only)
    }
    if policy_stats:   # only collected from policies with summarise_stats
        summary["policy_stats"] = policy.summarise_stats(policy_stats)
    if cs.collision_events:
        summary["collision_events"] = [{**e, "seed": int(seed)} for e in events]
    return Cell(df, summary, traj, r, arena.half_width)


def _collision_probe(r: float):
    """``wrap`` of :func:`cell_batches`: a :class:`~madpinn.evaluation.collisions.CollisionProbe`
    (collision radius ``r``, m) around each batch's policy, numbering its scenarios from ``first``."""
    from madpinn.evaluation.collisions import CollisionProbe

    def wrap(policy, first):
        probe = CollisionProbe(policy, r)
        probe.scenario_offset = first
        return probe
    return wrap


def write_cell(cell: Cell, out: str | Path) -> list[Path]:
    """Write ``out`` (.parquet), ``out``.json and ``out``_traj.npz; return the three paths."""
    out, json_path, traj_path = cell_paths(out)
    out.parent.mkdir(parents=True, exist_ok=True)
    cell.frame.to_parquet(out, index=False)
    json_path.write_text(json.dumps(cell.summary, indent=2))
    traj = cell.trajectory
    np.savez_compressed(
        traj_path, times=traj.times, positions=traj.positions[:, 0], goals=traj.goals[0],
        collided=traj.collided[0], first_collision_step=traj.first_collision_step[0], dt=traj.dt,
        collision_radius=cell.collision_radius, half_width=cell.half_width,
    )
    return [out, json_path, traj_path]
