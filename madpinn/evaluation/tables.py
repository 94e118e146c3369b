"""Paper tables assembled from evaluation result files (never from MLflow).

Kinds:
- ``safety_by_n``: paper Table I layout — one row per run, for each agent count the safety
  rate and the safe-scenario percentage, then both costs (mean ± std over seeds).
- ``summary``: one row per (run, N) — time-averaged cost (the paper's figures), cumulative cost,
  safety rate, safe scenarios (paper Tables II–IV).

Both costs are the mean over collision-free agents (SPEC §3); "÷T" is the cumulative cost
divided by the episode length T. Beside them every table shows the time-averaged cost over all
agents (collided ones included), and ``summary`` tables the safety under the disc reading (d ≤ 2r,
from the same episodes; SPEC §1). Given oracle files (:mod:`madpinn.evaluation.oracle`), each
table ends with an oracle row per agent count: the lone-agent cost lower bound on the same
scenarios. Single-seed studies show the mean with its 95 % bootstrap interval over scenarios (no
"± 0.00"). ``summary`` tables also read safety where the drones' bodies touch (d ≤ 0.12 m,
:mod:`madpinn.evaluation.contact`). The ``.csv`` carries a 95 % interval (``*_ci_lo``,
``*_ci_hi``) of every figure of :data:`madpinn.evaluation.intervals.INTERVAL_METRICS`: t over seeds
for multi-seed cells, the bootstrap over scenarios for single-seed ones
(:mod:`madpinn.evaluation.intervals`).

Each table is written as ``.csv`` (numeric mean/std columns, oracle rows with run ``oracle``),
``.md`` and ``.tex``.
"""

from __future__ import annotations

from pathlib import Path
from typing import Iterable

import numpy as np
import pandas as pd

from madpinn.config import method_config
from madpinn.evaluation.cell_files import cell_summary
from madpinn.evaluation.contact import contact_distance, seed_contact, with_contact
from madpinn.evaluation.intervals import seed_figures
from madpinn.evaluation.metrics import across_seeds, scenario_intervals, seed_summary
from madpinn.scenarios import UNIFORM

KINDS = ("safety_by_n", "summary")
ORACLE_RUN, ORACLE_LABEL = "oracle", "Oracle (lone-agent lower bound)"
# first-column header of the ``summary`` tables (what a row is), by table name
ROW_HEADERS = {"table_update_ablation": "Update period k (steps)", "table_neighbour_ablation": "Neighbour selection"}
COST_HEADER, CUM_HEADER = "Cost ÷T (time-avg.)", "Cumulative cost ∫ (m·s)"
INFEASIBLE_HEADER = "Infeasible (z_max)"
"""MAD-PINN agent-steps with no feasible budget (V̂ > 0 at z_max), where the infeasible branch acts (issue 46)"""
ALL_HEADER = "Cost ÷T, all agents"


def load_results(paths: Iterable[str | Path]) -> pd.DataFrame:
    paths = list(paths)
    if not paths:
        raise ValueError("no result files given")
    missing = [str(p) for p in paths if not Path(p).is_file()]
    if missing:
        raise FileNotFoundError(f"missing result files: {missing[:5]}{' …' if len(missing) > 5 else ''}")
    return pd.concat([pd.read_parquet(p) for p in paths], ignore_index=True)


def per_seed(df: pd.DataFrame) -> pd.DataFrame:
    """One row per (run, N, seed): the seed figures, the contact reading and their bootstrap intervals over scenarios."""
    rows = []
    for (run, n, seed), g in with_contact(df).groupby(["run", "n_agents", "seed"], sort=False):
        rows.append({"run": run, "n_agents": int(n), "seed": int(seed), **seed_summary(g), **scenario_intervals(g),
                     **seed_contact(g)})
    return pd.DataFrame(rows)


def run_order(df: pd.DataFrame, cfg: dict) -> dict[str, int]:
    """Rank of each run of ``df``: the order of its studies' ``runs`` lists in ``cfg``, then any
    other run in the order met (whatever order the result files came in)."""
    order: dict[str, int] = {}
    studies = cfg["studies"]
    for study in dict.fromkeys(df["study"]) if "study" in df else ():
        for run in studies[study]["runs"] if study in studies else ():
            order.setdefault(str(run), len(order))
    for run in dict.fromkeys(df["run"]):
        order.setdefault(run, len(order))
    return order


def summarize(df: pd.DataFrame, cfg: dict) -> pd.DataFrame:
    """Mean/std across seeds per (run, N), with the 95 % intervals of
    :func:`madpinn.evaluation.intervals.seed_figures` and display labels, in config order (:func:`run_order`)."""
    keys = ["run", "n_agents"]
    seeds = per_seed(df)
    agg = across_seeds(seeds, keys)
    fig = seed_figures(seeds, keys)
    agg = agg.drop(columns=[c for c in fig.columns if c in agg and c not in keys]).merge(fig, on=keys, how="left")
    agg.insert(1, "label", [label_of(cfg, r) for r in agg["run"]])
    order = run_order(df, cfg)
    agg["_o"] = agg["run"].map(order)
    return agg.sort_values(["_o", "n_agents"]).drop(columns="_o").reset_index(drop=True)


def load_oracle(paths: Iterable[str | Path]) -> pd.DataFrame:
    """Concatenated oracle cache files (rows per arena, scenario pattern, N, seed, scenario; files
    written before patterns existed hold uniform scenarios)."""
    paths = list(paths)
    missing = [str(p) for p in paths if not Path(p).is_file()]
    if missing:
        raise FileNotFoundError(f"missing oracle files: {missing[:5]}{' …' if len(missing) > 5 else ''}")
    df = pd.concat([pd.read_parquet(p) for p in paths], ignore_index=True)
    df["pattern"] = df["pattern"].fillna(UNIFORM) if "pattern" in df else UNIFORM
    return df


def oracle_summary(oracle: pd.DataFrame, results: pd.DataFrame) -> pd.DataFrame:
    """Oracle figures on exactly the (N, seed, scenario) cells of ``results``, aggregated like a
    run: mean over scenarios per seed, then mean ± std over seeds; one row per N (run ``oracle``).
    Its safety columns are NaN (a lone agent has no one to collide with)."""
    keys = ["n_agents", "seed", "scenario"]
    cells = results[keys + (["arena"] if "arena" in results else [])].drop_duplicates()
    on = keys + (["arena"] if "arena" in results and "arena" in oracle else [])
    merged = cells.merge(oracle, on=on, how="left")
    if merged["oracle_cost"].isna().any():
        lack = merged[merged["oracle_cost"].isna()][keys].drop_duplicates().head(3).to_dict("records")
        raise ValueError(f"oracle files lack scenarios of the results, e.g. {lack}")
    seeds = merged.groupby(["n_agents", "seed"], as_index=False)[["oracle_cost", "oracle_cost_time_avg"]].mean()
    seeds = seeds.rename(columns={"oracle_cost": "cost", "oracle_cost_time_avg": "cost_time_avg"})
    seeds["run"] = ORACLE_RUN
    for m in ("safety_rate", "safe_scenarios", "cost_all", "cost_all_time_avg", "safety_rate_2r", "safe_scenarios_2r"):
        seeds[m] = float("nan")
    agg = across_seeds(seeds, ["run", "n_agents"])
    agg.insert(1, "label", ORACLE_LABEL)
    return agg


def label_of(cfg: dict, run: str) -> str:
    try:
        return method_config(cfg, run)[1]["label"]
    except Exception:  # noqa: BLE001 - a result of a run no longer configured keeps its name
        return run


def _pct(mean: float, std: float, n_seeds: int = 2, ci: tuple[float, float] | None = None) -> str:
    """Percent: ``mean ± std`` over seeds; one seed: ``mean [lo, hi]`` (95 % bootstrap over scenarios) when given."""
    if pd.isna(mean):
        return "–"
    if n_seeds >= 2:
        return f"{100 * mean:.1f}% ± {100 * std:.1f}%"
    return f"{100 * mean:.1f}%" if ci is None or pd.isna(ci[0]) else f"{100 * mean:.1f}% [{100 * ci[0]:.1f}, {100 * ci[1]:.1f}]"


def _cost(mean: float, std: float, n_seeds: int = 2, ci: tuple[float, float] | None = None) -> str:
    """Cost: as :func:`_pct`, two decimals."""
    if pd.isna(mean):
        return "n/a"
    if n_seeds >= 2:
        return f"{mean:.2f} ± {std:.2f}"
    return f"{mean:.2f}" if ci is None or pd.isna(ci[0]) else f"{mean:.2f} [{ci[0]:.2f}, {ci[1]:.2f}]"


def _fmt(r, metric: str) -> str:
    if f"{metric}_mean" not in r:   # a reading these rows do not hold (e.g. no per-agent separations)
        return "–"
    f = _pct if metric.startswith(("safety_rate", "safe_scenarios")) else _cost
    lo, hi = r.get(f"{metric}_ci_lo"), r.get(f"{metric}_ci_hi")
    return f(r[f"{metric}_mean"], r[f"{metric}_std"], int(r["n_seeds"]), None if lo is None else (lo, hi))


def format_table(agg: pd.DataFrame, kind: str, row_header: str = "Method") -> pd.DataFrame:
    """Display table of ``agg`` (:func:`summarize`, oracle rows appended); ``row_header`` names
    the first column of ``summary`` tables (e.g. "Update period k (steps)")."""
    cols = (("safety_rate", "Safety"), ("safe_scenarios", "Safe Sc."), ("cost_time_avg", "Cost ÷T"), ("cost", "Cum. cost"),
            ("cost_all_time_avg", "Cost ÷T all"))
    share = lambda r: "–" if pd.isna(r.get("infeasible_mean", np.nan)) else f"{100 * r['infeasible_mean']:.1f}%"   # noqa: E731
    if kind == "safety_by_n":
        counts = sorted(agg["n_agents"].unique())
        rows = []
        for label, g in agg.groupby("label", sort=False):
            row = {"Method": label}
            by_n = g.set_index("n_agents")
            for n in counts:
                for metric, head in cols:
                    row[f"{n} agents · {head}"] = _fmt(by_n.loc[n], metric) if n in by_n.index else "–"
                row[f"{n} agents · {INFEASIBLE_HEADER}"] = share(by_n.loc[n]) if n in by_n.index else "–"
            rows.append(row)
        return pd.DataFrame(rows)
    if kind == "summary":
        table = {row_header: agg["label"]}
        if agg["n_agents"].nunique() > 1 or row_header == "Method":
            table["Number of Agents"] = agg["n_agents"]
        table.update({
            COST_HEADER: [_fmt(r, "cost_time_avg") for _, r in agg.iterrows()],
            CUM_HEADER: [_fmt(r, "cost") for _, r in agg.iterrows()],
            "Safety Rate": [_fmt(r, "safety_rate") for _, r in agg.iterrows()],
            "Safe Scenarios": [_fmt(r, "safe_scenarios") for _, r in agg.iterrows()],
            ALL_HEADER: [_fmt(r, "cost_all_time_avg") for _, r in agg.iterrows()],
            "Safety (d ≤ 2r)": [_fmt(r, "safety_rate_2r") for _, r in agg.iterrows()],
            "Safe Sc. (d ≤ 2r)": [_fmt(r, "safe_scenarios_2r") for _, r in agg.iterrows()],
            f"Safety (d ≤ {contact_distance():g} m)": [_fmt(r, "safety_rate_contact") for _, r in agg.iterrows()],
            INFEASIBLE_HEADER: [share(r) for _, r in agg.iterrows()],
        })
        return pd.DataFrame(table)
    raise ValueError(f"unknown table kind '{kind}' (have {KINDS})")


def to_markdown(table: pd.DataFrame) -> str:
    cols = list(table.columns)
    lines = ["| " + " | ".join(cols) + " |", "|" + "|".join(["---"] * len(cols)) + "|"]
    lines += ["| " + " | ".join(str(v) for v in row) + " |" for row in table.itertuples(index=False)]
    return "\n".join(lines) + "\n"


def to_latex(table: pd.DataFrame, caption: str) -> str:
    def esc(s) -> str:
        s = str(s).replace("%", r"\%").replace("±", r"$\pm$").replace("_", r"\_")
        for a, b in (("÷", r"$\div$"), ("∫", r"$\int$"), ("‖", r"$\|$"), ("−", "-"), ("∞", r"$\infty$"),
                     ("m·s", r"m$\cdot$s"), ("·", "--")):
            s = s.replace(a, b)
        return s

    cols = list(table.columns)
    spec = "l" + "c" * (len(cols) - 1)
    body = [" & ".join(esc(c) for c in cols) + r" \\", r"\midrule"]
    body += [" & ".join(esc(v) for v in row) + r" \\" for row in table.itertuples(index=False)]
    return "\n".join(
        [r"\begin{table}[t]", r"\centering", r"\resizebox{\columnwidth}{!}{%", rf"\begin{{tabular}}{{{spec}}}",
         r"\toprule", *body, r"\bottomrule", r"\end{tabular}}", rf"\caption{{{esc(caption)}}}", r"\end{table}", ""]
    )


def cell_infeasible_shares(result_paths: Iterable[str | Path]) -> pd.DataFrame:
    """``(study, run, n_agents, infeasible)`` per result file: the share of MAD-PINN agent-steps with
    no feasible budget (``policy_stats.infeasible_fraction`` of the cell's JSON summary beside its
    Parquet); cells without that branch (or without a summary) are left out."""
    rows = []
    for p in result_paths:
        d = cell_summary(p)
        share = (d.get("policy_stats") or {}).get("infeasible_fraction")
        if share is not None and "run" in d:
            rows.append({"study": d.get("study"), "run": d["run"], "n_agents": int(d["n_agents"]), "infeasible": float(share)})
    return pd.DataFrame(rows, columns=["study", "run", "n_agents", "infeasible"])


def infeasible_shares(result_paths: Iterable[str | Path]) -> pd.DataFrame:
    """``(run, n_agents, infeasible_mean)``: :func:`cell_infeasible_shares` averaged over seeds."""
    return cell_infeasible_shares(result_paths).groupby(["run", "n_agents"], as_index=False)["infeasible"].mean().rename(
        columns={"infeasible": "infeasible_mean"})


def table_data(result_paths: Iterable[str | Path], cfg: dict, oracle_paths: Iterable[str | Path] = ()) -> pd.DataFrame:
    """:func:`summarize` of the result files (with MAD-PINN's :func:`infeasible_shares`), the oracle
    rows appended when given."""
    result_paths = list(result_paths)
    df = load_results(result_paths)
    agg = summarize(df, cfg).merge(infeasible_shares(result_paths), on=["run", "n_agents"], how="left")
    oracle_paths = list(oracle_paths)
    if oracle_paths:
        agg = pd.concat([agg, oracle_summary(load_oracle(oracle_paths), df)], ignore_index=True)
    return agg


def write_table(name: str, kind: str, result_paths: Iterable[str | Path], cfg: dict, out_dir: str | Path,
                oracle_paths: Iterable[str | Path] = ()) -> list[Path]:
    """Write ``<name>.csv`` (numbers), ``.md``, ``.tex`` and ``.html`` (display; the HTML page is
    what the Snakemake report shows) into ``out_dir``; returns the four paths in that order."""
    from madpinn.evaluation.html import markdown_page

    agg = table_data(result_paths, cfg, oracle_paths)
    table = format_table(agg, kind, ROW_HEADERS.get(name, "Method"))
    out_dir = Path(out_dir)
    out_dir.mkdir(parents=True, exist_ok=True)
    csv, md, tex, page = (out_dir / f"{name}.{ext}" for ext in ("csv", "md", "tex", "html"))
    agg.to_csv(csv, index=False)
    md.write_text(to_markdown(table))
    page.write_text(markdown_page(to_markdown(table), name))
    seeds = int(agg["n_seeds"].max())
    spread = "mean ± std over seeds" if seeds > 1 else "one seed"
    caption = (f"{name.replace('_', ' ')} ({spread}; {cfg['experiment']}). Costs over collision-free agents: "
               f"Cost ÷T = cumulative cost ∫‖p−g‖dt + ‖p(T)−g‖ divided by the episode length T")
    tex.write_text(to_latex(table, caption))
    return [csv, md, tex, page]
