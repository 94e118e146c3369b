"""Paper tables assembled from evaluation result files (never from MLflow).

Kinds:
- ``safety_by_n``: paper Table I layout — one row per run, for each agent count the safety
  rate and the safe-scenario percentage (mean ± std over seeds).
- ``summary``: one row per (run, N) — cumulative cost, safety rate, safe scenarios.

Each table is written as ``.csv`` (numeric mean/std columns), ``.md`` and ``.tex``.
"""

from __future__ import annotations

from pathlib import Path
from typing import Iterable

import pandas as pd

from madpinn.config import method_config
from madpinn.evaluation.metrics import across_seeds, seed_summary

KINDS = ("safety_by_n", "summary")


def load_results(paths: Iterable[str | Path]) -> pd.DataFrame:
    paths = list(paths)
    if not paths:
        raise ValueError("no result files given")
    missing = [str(p) for p in paths if not Path(p).is_file()]
    if missing:
        raise FileNotFoundError(f"missing result files: {missing[:5]}{' …' if len(missing) > 5 else ''}")
    return pd.concat([pd.read_parquet(p) for p in paths], ignore_index=True)


def per_seed(df: pd.DataFrame) -> pd.DataFrame:
    rows = []
    for (run, n, seed), g in df.groupby(["run", "n_agents", "seed"], sort=False):
        rows.append({"run": run, "n_agents": int(n), "seed": int(seed), **seed_summary(g)})
    return pd.DataFrame(rows)


def summarize(df: pd.DataFrame, cfg: dict) -> pd.DataFrame:
    """Mean/std across seeds per (run, N), with display labels, in config order."""
    agg = across_seeds(per_seed(df), ["run", "n_agents"])
    agg.insert(1, "label", [label_of(cfg, r) for r in agg["run"]])
    order = {r: i for i, r in enumerate(dict.fromkeys(df["run"]))}
    agg["_o"] = agg["run"].map(order)
    return agg.sort_values(["_o", "n_agents"]).drop(columns="_o").reset_index(drop=True)


def label_of(cfg: dict, run: str) -> str:
    try:
        return method_config(cfg, run)[1].get("label", run)
    except Exception:  # noqa: BLE001 - a result of a run no longer configured keeps its name
        return run


def _pct(mean: float, std: float) -> str:
    return f"{100 * mean:.1f}% ± {100 * std:.1f}%"


def _cost(mean: float, std: float) -> str:
    return "n/a" if pd.isna(mean) else f"{mean:.2f} ± {std:.2f}"


def format_table(agg: pd.DataFrame, kind: str) -> pd.DataFrame:
    if kind == "safety_by_n":
        counts = sorted(agg["n_agents"].unique())
        rows = []
        for label, g in agg.groupby("label", sort=False):
            row = {"Method": label}
            by_n = g.set_index("n_agents")
            for n in counts:
                if n in by_n.index:
                    r = by_n.loc[n]
                    row[f"{n} agents · Safety"] = _pct(r["safety_rate_mean"], r["safety_rate_std"])
                    row[f"{n} agents · Safe Sc."] = _pct(r["safe_scenarios_mean"], r["safe_scenarios_std"])
                else:
                    row[f"{n} agents · Safety"] = row[f"{n} agents · Safe Sc."] = "–"
            rows.append(row)
        return pd.DataFrame(rows)
    if kind == "summary":
        return pd.DataFrame(
            {
                "Method": agg["label"],
                "Number of Agents": agg["n_agents"],
                "Cumulative Cost": [_cost(m, s) for m, s in zip(agg["cost_mean"], agg["cost_std"])],
                "Safety Rate": [_pct(m, s) for m, s in zip(agg["safety_rate_mean"], agg["safety_rate_std"])],
                "Safe Scenarios": [_pct(m, s) for m, s in zip(agg["safe_scenarios_mean"], agg["safe_scenarios_std"])],
            }
        )
    raise ValueError(f"unknown table kind '{kind}' (have {KINDS})")


def to_markdown(table: pd.DataFrame) -> str:
    cols = list(table.columns)
    lines = ["| " + " | ".join(cols) + " |", "|" + "|".join(["---"] * len(cols)) + "|"]
    lines += ["| " + " | ".join(str(v) for v in row) + " |" for row in table.itertuples(index=False)]
    return "\n".join(lines) + "\n"


def to_latex(table: pd.DataFrame, caption: str) -> str:
    def esc(s) -> str:
        return str(s).replace("%", r"\%").replace("±", r"$\pm$").replace("·", "--").replace("_", r"\_")

    cols = list(table.columns)
    spec = "l" + "c" * (len(cols) - 1)
    body = [" & ".join(esc(c) for c in cols) + r" \\", r"\midrule"]
    body += [" & ".join(esc(v) for v in row) + r" \\" for row in table.itertuples(index=False)]
    return "\n".join(
        [r"\begin{table}[t]", r"\centering", r"\resizebox{\columnwidth}{!}{%", rf"\begin{{tabular}}{{{spec}}}",
         r"\toprule", *body, r"\bottomrule", r"\end{tabular}}", rf"\caption{{{esc(caption)}}}", r"\end{table}", ""]
    )


def write_table(name: str, kind: str, result_paths: Iterable[str | Path], cfg: dict, out_dir: str | Path) -> list[Path]:
    agg = summarize(load_results(result_paths), cfg)
    table = format_table(agg, kind)
    out_dir = Path(out_dir)
    out_dir.mkdir(parents=True, exist_ok=True)
    csv, md, tex = (out_dir / f"{name}.{ext}" for ext in ("csv", "md", "tex"))
    agg.to_csv(csv, index=False)
    md.write_text(to_markdown(table))
    caption = f"{name.replace('_', ' ')} (mean ± std over seeds; {cfg['experiment']})"
    tex.write_text(to_latex(table, caption))
    return [csv, md, tex]
