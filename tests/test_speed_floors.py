"""The speed-floor tools of issue 37 (benchmarks/zsearch_floor.py, scripts/paired_cells.py): the
floor counts exactly the rows the deployed cold search evaluates, the cells' summaries are read in
both layouts (benchmarks/protocol_time.py), and the paired comparison refuses cells that did not
run the same scenarios; episodes in lockstep (benchmarks/lockstep.py, issue 65) take turns of the
given number of steps and return their own results."""

import json
import subprocess
import sys

import numpy as np
import pandas as pd
import pytest
import torch

from conftest import REPO
from madpinn.value_functions.z_search import ZGrid, bisection_steps, cold_search
from policy_models import tiny_models

sys.path.insert(0, str(REPO / "benchmarks"))
from lockstep import run_in_lockstep  # noqa: E402
from protocol_time import cell_summaries  # noqa: E402
from zsearch_floor import certifiable_rows, filter_rows, floor_us_per_agent_step, ran_cold_bisection  # noqa: E402


def test_floor_counts_the_rows_of_the_deployed_cold_search():
    """With unit costs the floor is the cold search's own row count per agent-step where every
    agent is feasible (value: V̂(z_max) + the halvings; gradient: one), and it drops exactly the
    halvings of infeasible agents, whose answer is z_max whatever the halvings return."""
    vhat, _ = tiny_models()
    grid = ZGrid(vhat.z_max, bisection_steps(1e-3))
    g = torch.Generator().manual_seed(0)
    obs = vhat.problem.sample_states(64, g, torch.float32)[:, :-1]
    r = cold_search(vhat, obs, grid)
    B = obs.shape[0]
    assert floor_us_per_agent_step(1.0, 0.0, grid.steps, 0.0) == r.value_rows / B
    assert floor_us_per_agent_step(0.0, 1.0, grid.steps, 0.0) == r.grad_rows / B
    assert floor_us_per_agent_step(1.0, 0.0, grid.steps, 1.0) == 1.0   # only V̂(z_max)
    assert torch.all(r.z[~r.feasible] == vhat.z_max) and torch.all(r.index[~r.feasible] == grid.cells)


def test_certifiable_rows_counts_the_rows_an_output_bound_decides():
    """With the output layer's weights zeroed, V̂ is its exact terminal term plus a constant, so the
    bound decides every row on the path: V̂(z_max) and each feasible agent's halvings. With the
    trained weights it decides at most that many (and every certified sign is checked inside)."""
    import copy

    vhat, _ = tiny_models()
    grid = ZGrid(vhat.z_max, bisection_steps(1e-3))
    obs = vhat.problem.sample_states(200, torch.Generator().manual_seed(1), torch.float32)[:, :-1]
    feasible = cold_search(vhat, obs, grid, with_grad=False).feasible.double().mean().item()
    assert 0.0 <= certifiable_rows(vhat, obs, grid) <= 1 + grid.steps * feasible + 1e-9
    flat = copy.deepcopy(vhat)
    with torch.no_grad():
        flat.net.out.weight.zero_()
    feasible = cold_search(flat, obs, grid, with_grad=False).feasible.double().mean().item()
    assert certifiable_rows(flat, obs, grid) == pytest.approx(1 + grid.steps * feasible, abs=1e-9)


def test_cold_bisection_cells_are_told_from_warm_ones_by_their_rows():
    """Before issue 48 the cold search evaluated 12 rows per agent-step; now it skips infeasible
    agents' halvings (2 + 10·(1 − share) rows, plus padding); a warm search has hits and fewer rows."""
    stats = lambda rows, share=0.2, hit=0.0: {"vhat_evals_per_agent_step": rows, "infeasible_fraction": share,  # noqa: E731
                                              "warm_hit_rate": hit}
    assert ran_cold_bisection(stats(12.0), 10) and ran_cold_bisection(stats(10.0), 10) and ran_cold_bisection(stats(10.3), 10)
    assert not ran_cold_bisection(stats(3.9, hit=0.6), 10) and not ran_cold_bisection(stats(9.9), 10)
    assert not ran_cold_bisection(stats(12.5), 10)


def _cell(study="main", run="madpinn", rows=12.0, elapsed=10.0):
    return {"study": study, "run": run, "n_agents": 4, "n_scenarios": 3, "n_steps": 5, "elapsed_s": elapsed,
            "policy_stats": {"vhat_evals_per_agent_step": rows, "infeasible_fraction": 0.1}}


def test_cell_summaries_take_both_layouts_and_stop_on_an_unreadable_one(tmp_path):
    (tmp_path / "eval" / "main").mkdir(parents=True)
    (tmp_path / "eval" / "main" / "n4_seed0.json").write_text(json.dumps(_cell()))
    (tmp_path / "abc123_summary.json").write_text(json.dumps(_cell(run="nominal")))
    (tmp_path / "store.json").write_text(json.dumps({"study": "x"}))   # not a cell summary
    (tmp_path / "n4_seed1.json").write_text(json.dumps({"study": "x"}))  # no elapsed_s: not a finished cell
    runs = sorted(c["run"] for c in cell_summaries(tmp_path))
    assert runs == ["madpinn", "nominal"]
    (tmp_path / "n4_seed2.json").write_text("{truncated")
    with pytest.raises(SystemExit, match="n4_seed2.json"):
        cell_summaries(tmp_path)


def test_the_network_floor_counts_the_cbvf_filters_rows_of_the_filtered_runs_only():
    from madpinn.config import load_config

    cfg = load_config([REPO / "config.yaml"])
    sf = cfg["methods"]["madpinn"]["variants"]["filtered"]["safety_filter"]
    assert filter_rows(cfg, "madpinn-filtered") == (sf["candidates"], sf["critical_neighbours"]) == (4, 2)
    assert {filter_rows(cfg, r) for r in ("madpinn", "madpinn-lookahead", "madpinn-cs", "mppi", "safemarl", "nominal")} == {(0, 0)}


def test_the_floor_leaves_out_cells_computed_on_another_cpu(tmp_path):
    """A cell's CPU time compares with a floor measured on its own CPU only (issue 65)."""
    (tmp_path / "a_summary.json").write_text(json.dumps({**_cell(), "cpu_model": "Another CPU (not this one)"}))
    out = subprocess.run([sys.executable, str(REPO / "benchmarks" / "zsearch_floor.py"), "--cells", str(tmp_path), "--repeats", "1"],
                         cwd=REPO, capture_output=True, text=True, timeout=300,
                         env={"PYTHONPATH": f"{REPO}:{REPO / 'benchmarks'}", "PATH": "/usr/bin:/bin"})
    assert out.returncode != 0 and "cells on another CPU: 1 (left out)" in out.stdout
    assert "no evaluation cell summaries" in out.stderr and "(on this CPU)" in out.stderr


def _frame(scenarios, safety, cost, seed=100, final=0.1):
    n = len(scenarios)
    return pd.DataFrame({"scenario": scenarios, "n_agents": [8] * n, "seed": [seed] * n, "safety_rate": safety,
                         "safe": [s == 1.0 for s in safety], "cost_safe_time_avg": cost, "cost_all_time_avg": cost,
                         "final_distance_mean": [final] * n})


def test_paired_cells_differences_and_refusal(tmp_path):
    a, b, c = tmp_path / "a.parquet", tmp_path / "b.parquet", tmp_path / "c.parquet"
    _frame([0, 1, 2], [1.0, 0.75, 0.5], [1.0, 2.0, 3.0], final=0.25).to_parquet(a)
    _frame([0, 1, 2], [1.0, 0.5, 0.5], [0.5, 1.5, 2.5], final=0.05).to_parquet(b)
    _frame([0, 1, 3], [1.0, 0.5, 0.5], [0.5, 1.5, 2.5]).to_parquet(c)
    script = str(REPO / "scripts" / "paired_cells.py")
    out = subprocess.run([sys.executable, script, str(a), str(b)], capture_output=True, text=True, check=True).stdout
    row = out.strip().splitlines()[-1]
    d = np.array([0.0, 25.0, 0.0])
    assert f"{d.mean():+.3f} ± {d.std(ddof=1) / np.sqrt(3):.3f}" in row   # safety difference, points
    assert "+0.500 ± 0.000" in row                                          # cost difference
    assert "| 100 % | 0.250 / 0.050 |" in row                                # A costlier everywhere; final distances
    bad = subprocess.run([sys.executable, script, str(a), str(c)], capture_output=True, text=True)
    assert bad.returncode != 0 and "not the same scenarios" in bad.stderr


@pytest.mark.parametrize("argv", [[], ["only_one.parquet"]])
def test_paired_cells_needs_pairs(argv):
    bad = subprocess.run([sys.executable, str(REPO / "scripts" / "paired_cells.py"), *argv], capture_output=True, text=True)
    assert bad.returncode != 0


class _Logged:
    """A policy that logs its steps into a shared list."""

    def __init__(self, name, log):
        self.name, self.log = name, log

    def reset(self, state, goals):
        pass

    def act(self, state, goals, t):
        self.log.append(self.name)
        return t


@pytest.mark.parametrize("steps", [1, 3])
def test_lockstep_episodes_take_turns_of_steps_and_keep_their_results(steps):
    log = []

    def episode(name, n):
        def run(wrap):
            policy = wrap(_Logged(name, log))
            policy.reset(None, None)
            return [policy.act(None, None, k) for k in range(n)]
        return run

    (a, cpu_a), (b, cpu_b) = run_in_lockstep([episode("a", 7), episode("b", 4)], steps)
    assert a == list(range(7)) and b == list(range(4)) and cpu_a >= 0 and cpu_b >= 0
    assert "".join(log) == {1: "ababababaaa", 3: "aaabbbaaaba"}[steps]


def test_lockstep_reports_a_failed_episode_without_hanging():
    def failing(wrap):
        wrap(_Logged("x", [])).reset(None, None)
        raise ValueError("boom")

    def fine(wrap):
        policy = wrap(_Logged("y", []))
        policy.reset(None, None)
        return [policy.act(None, None, k) for k in range(3)]

    with pytest.raises(RuntimeError, match="failed"):
        run_in_lockstep([failing, fine])


def test_floor_rounds_give_a_strict_and_a_typical_host_floor(tmp_path):
    """``--rounds K`` measures every row cost K times: the strict floor takes each cost's minimum
    over the rounds, the typical-host floor its median, so the typical-host ratio is never above the
    strict one (median ≥ min); the filtered run adds its V_s rows to the network floors only."""
    (tmp_path / "a_summary.json").write_text(json.dumps(_cell()))
    (tmp_path / "b_summary.json").write_text(json.dumps(_cell(run="madpinn-filtered")))
    (tmp_path / "c_summary.json").write_text(json.dumps(_cell(run="nominal", rows=None)))
    out = subprocess.run([sys.executable, str(REPO / "benchmarks" / "zsearch_floor.py"), "--cells", str(tmp_path),
                          "--repeats", "1", "--rounds", "3"],
                         cwd=REPO, capture_output=True, text=True, timeout=300, check=True,
                         env={"PYTHONPATH": f"{REPO}:{REPO / 'benchmarks'}", "PATH": "/usr/bin:/bin"}).stdout
    read = {k: float(v.split()[0]) for k, v in (line.split(": ", 1) for line in out.splitlines()
                                               if line.startswith(("protocol_", "cold_bisection_floor", "network_floor")))}
    assert read["protocol_time_over_floor_typical_host"] <= read["protocol_time_over_floor"]
    assert read["protocol_time_over_network_floor_typical_host"] <= read["protocol_time_over_network_floor"]
    assert read["protocol_time_over_network_floor"] < read["protocol_time_over_floor"]   # the filter's V_s rows
    assert "(3 rounds)" in out and out.count("round 1: batch") == 3             # V̂ at 12 rows, V_s at 48 and 24


def test_paired_floor_runs_the_cell_between_two_floor_measurements(tmp_path):
    """benchmarks/zsearch_floor_paired.py: a real (tiny) MAD-PINN cell through the job function, its
    floor from its own row counts at row costs timed around it; the cell's CPU time holds far more
    than its V̂ rows (MuJoCo, the neighbour scoring), so its ratio is above 1; a protocol seed is refused."""
    script = str(REPO / "benchmarks" / "zsearch_floor_paired.py")
    env = {"PYTHONPATH": f"{REPO}:{REPO / 'benchmarks'}", "PATH": "/usr/bin:/bin"}
    out = subprocess.run([sys.executable, script, "--cell", "main/madpinn/3/100", "--scenarios", "1", "--repeats", "1",
                          "--out", str(tmp_path / "paired.jsonl")],
                         cwd=REPO, capture_output=True, text=True, timeout=600, env=env, check=True).stdout
    (line,) = [json.loads(x) for x in (tmp_path / "paired.jsonl").read_text().splitlines()]
    assert line["cell"] == "main/madpinn/3/100" and line["batch"] == 3 and line["ratio"] > 1.0
    assert line["cpu_s"] > line["floor_s"] > 0 and len(line["value_row_us"]) == 2
    assert "paired_cells_time_over_floor: " in out
    bad = subprocess.run([sys.executable, script, "--cell", "main/madpinn/3/0"], cwd=REPO, capture_output=True,
                         text=True, timeout=300, env=env)
    assert bad.returncode != 0 and "validation seeds only" in bad.stderr
