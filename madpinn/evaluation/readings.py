"""Collision readings (SPEC §1, issue 38): every paper cell under each collision convention.

The paper counts a failure at ``min d_ij ≤ r`` (r = 0.1 m, "a safety distance") but does not say
whether r is a centre distance or each drone's radius, nor what happens at a contact. One table
puts the readings side by side for every cell of the paper's Tables I, III and IV that our result
files hold, beside the paper's value:

- ``r · pass``: collision at centre distance d ≤ r, agents pass through each other (the first protocol);
- ``2r · pass``: discs of radius r touching (d ≤ 2r), from the same episodes' minimum separations;
- ``0.12 m · pass``: the airframes touching (d ≤ 0.12 m, twice the CF2X collision cylinder's radius,
  :func:`madpinn.evaluation.contact.contact_distance`; issue 47), from the same separations;
- ``r · contact`` / ``2r · contact`` / ``0.12 m · contact``: the same counts on episodes flown with contact physics
  (``sim.contacts``: CF2X collision cylinders in MuJoCo, frozen agents in the double integrator),
  read from the study ``<base>_contacts`` of each base study.

Every method's own collision terms use the same r (``agents.collision_radius``): 0.1 m with the
shipped models, so the ``2r`` columns measure the metric alone; 0.2 m under
``workflow/configs/reading_2r.yaml`` (reading (b): every method built for discs touching). The
cost columns are the time-averaged cost over all agents (collided ones included), the quantity
whose trend the paper's failure rows show.
Rows follow the paper's tables and the config's run order; a run the paper row lists under
``also`` (our labelled extensions, e.g. ``madpinn-lookahead``) is shown but marked ``extension``,
and the closing mean |ours − paper| safety is taken over the paper's own rows only.
"""

from __future__ import annotations

from pathlib import Path
from typing import Iterable, Mapping

import numpy as np
import pandas as pd

from madpinn.config import ConfigError, study_sim
from madpinn.evaluation.contact import contact_distance
from madpinn.evaluation.contact_studies import CONTACTS_SUFFIX
from madpinn.evaluation.reproduction import paper_row_of, paper_values
from madpinn.evaluation.tables import label_of, load_results, per_seed, run_order, to_markdown

CONTACT_COL = f"{contact_distance():g} m"
"""column stem of the airframe-contact distance (issue 47: the CF2X cylinders touch at d ≤ 0.12 m)"""
READINGS = {   # column -> (contacts study?, seed figure)
    "r · pass": (False, "safety_rate"),
    "2r · pass": (False, "safety_rate_2r"),
    f"{CONTACT_COL} · pass": (False, "safety_rate_contact"),
    "r · contact": (True, "safety_rate"),
    "2r · contact": (True, "safety_rate_2r"),
    f"{CONTACT_COL} · contact": (True, "safety_rate_contact"),
}
COSTS = {"cost ÷T all · pass": False, "cost ÷T all · contact": True}


def base_study(cfg: Mapping, study: str) -> tuple[str, bool]:
    """``(base study, contacts?)`` of a result's study: ``<base>_contacts`` must fly with contacts."""
    contacts = bool(study_sim(cfg, study)["contacts"])
    if study.endswith(CONTACTS_SUFFIX):
        if not contacts:
            raise ConfigError(f"study '{study}' is named as a contact reading but has sim.contacts false "
                              f"(set studies.{study}.sim.contacts: true)")
        return study[: -len(CONTACTS_SUFFIX)], True
    return study, contacts


def readings_table(result_paths: Iterable[str | Path], cfg: dict, table_of: Mapping[str, str],
                   paper: dict | None = None) -> pd.DataFrame:
    """One row per (paper table, run, N) of the results: the paper's safety and cost, our safety
    under each reading (mean over seeds) and the all-agent cost with and without contacts.
    ``table_of``: base study -> paper table name (e.g. ``main`` -> ``table_safety_scaling``);
    results of other studies are left out."""
    paper = paper_values() if paper is None else paper
    df = load_results(result_paths)
    seeds = []
    for study, g in df.groupby("study", sort=False):
        base, contacts = base_study(cfg, str(study))
        if base not in table_of:
            continue
        s = per_seed(g)
        s["table"], s["contacts"] = table_of[base], contacts
        seeds.append(s)
    if not seeds:
        raise ValueError(f"no results of the studies {sorted(table_of)} (or their {CONTACTS_SUFFIX} readings)")
    seeds = pd.concat(seeds, ignore_index=True)
    order = run_order(df, cfg)
    tables = list(dict.fromkeys(table_of[b] for b in table_of))   # paper order, as given
    seeds["_t"], seeds["_r"] = seeds["table"].map(tables.index), seeds["run"].map(order)
    seeds = seeds.sort_values(["_t", "_r", "n_agents"], kind="stable")
    rows = []
    for (table, run, n), g in seeds.groupby(["table", "run", "n_agents"], sort=False):
        ref = paper.get(table, {}).get("runs", {})
        p = paper_row_of(ref).get(run, {}).get("n", {}).get(int(n), {})
        row = {"table": table, "run": run, "label": label_of(cfg, run), "n_agents": int(n),
               "extension": run not in ref and bool(p),
               "paper_safety": p.get("safety", np.nan), "paper_cost": p.get("cost", np.nan)}
        for col, (contacts, metric) in READINGS.items():
            sel = g[g["contacts"] == contacts]
            row[col] = float(sel[metric].mean()) if len(sel) else np.nan
        for col, contacts in COSTS.items():
            sel = g[g["contacts"] == contacts]
            row[col] = float(sel["cost_all_time_avg"].mean()) if len(sel) else np.nan
        row["n_seeds"] = int(g["seed"].nunique())
        row["seeds"] = " ".join(str(int(x)) for x in sorted(g["seed"].unique()))
        rows.append(row)
    return pd.DataFrame(rows)


def mean_gap(table: pd.DataFrame) -> dict[str, float]:
    """Mean |ours − paper| safety (fraction) per reading over the paper's own rows (not the
    extensions compared with them) that have a paper value and ours."""
    out = {}
    own = table[~table["extension"]]
    for col in READINGS:
        both = own[["paper_safety", col]].dropna()
        out[col] = float((both[col] - both["paper_safety"]).abs().mean()) if len(both) else float("nan")
    return out


def format_readings(table: pd.DataFrame) -> pd.DataFrame:
    """Display table: percentages, costs with two decimals, a closing mean |ours − paper| row."""
    pct = lambda x: "–" if pd.isna(x) else f"{100 * x:.1f}%"   # noqa: E731
    cost = lambda x: "–" if pd.isna(x) else f"{x:.2f}"   # noqa: E731
    rows = []
    for _, r in table.iterrows():
        row = {"Table": r["table"].removeprefix("table_").replace("_", " "),
               "Method": r["label"] + (" (extension, vs the paper's row)" if r["extension"] else ""),
               "N": int(r["n_agents"]), "Paper safety": pct(r["paper_safety"])}
        row.update({col: pct(r[col]) for col in READINGS})
        row["Paper cost"] = cost(r["paper_cost"])
        row.update({col: cost(r[col]) for col in COSTS})
        rows.append(row)
    gap = mean_gap(table)
    cells = int((table["paper_safety"].notna() & ~table["extension"]).sum())
    summary = {"Table": "mean |ours − paper|", "Method": f"over {cells} paper cells", "N": "", "Paper safety": ""}
    summary.update({col: "–" if np.isnan(v) else f"{100 * v:.1f} pp" for col, v in gap.items()})
    summary.update({"Paper cost": "", **{col: "" for col in COSTS}})
    return pd.DataFrame(rows + [summary])


def write_readings(result_paths: Iterable[str | Path], cfg: dict, table_of: Mapping[str, str],
                   out_dir: str | Path, name: str = "table_collision_readings") -> list[Path]:
    """Write ``<name>.csv`` (numbers), ``<name>.md`` and ``<name>.html`` (display, with the reading
    definitions; the HTML page is what the Snakemake report shows)."""
    from madpinn.evaluation.html import write_table_files

    table = readings_table(result_paths, cfg, table_of)
    seeds = sorted({int(x) for row in table["seeds"] for x in row.split()})
    r = float(cfg["agents"]["collision_radius"])
    text = (
        "Safety rate per paper cell under each collision reading (SPEC §1; madpinn/evaluation/readings.py).\n"
        f"Here r = {r:g} m (agents.collision_radius). r · pass: d ≤ r, agents pass through; 2r · pass: discs\n"
        f"of radius r touching (d ≤ 2r), same episodes; {CONTACT_COL}: the airframes' collision cylinders touching\n"
        "(d ≤ that distance); · contact: the same counts on episodes flown with contact physics\n"
        "(sim.contacts). Every method's collision terms (V̂, V_s, MPPI's penalty, DEF-MARL's constraint) use r.\n"
        f"Cost ÷T over all agents. Experiment {cfg['experiment']}, seeds {seeds}.\n\n"
        + to_markdown(format_readings(table)))
    return write_table_files(table, text, out_dir, name)
