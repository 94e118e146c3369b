"""The claims page (``claims.md``) rendered from :func:`madpinn.evaluation.claims.build_claims`:
verdict counts, the claims with their headline checks, each claim's checks, the per-cell value
tables, and the paper's consistency."""

from __future__ import annotations

from madpinn.evaluation.claim_checks import SCALE, STATED


def _mark(passed) -> str:
    return "–" if passed is None else ("yes" if passed else "**no**")


def _headline(c: dict) -> str:
    h = c["headline"]
    if not h:
        return "–"
    mark = {True: "passed", False: "failed", None: "not judged"}[h["passed"]]
    part = f" [{h['part']}]" if h["part"] else ""
    return f"{mark}{part}: expected {h['expected']} / observed {h['observed']}"


def _readings(c: dict) -> str:
    return "; ".join(f"{r}: {v}" for r, v in c["readings"].items())


def _chosen_on(c: dict) -> list[str]:
    """Where the judged readings were chosen (validation seeds), beside the claim; it judges nothing."""
    from madpinn.evaluation.table_ii_page import chosen_on_line

    line = chosen_on_line(c)
    return ["", line + " Shown, not judged."] if line else []


def claims_section(claims: dict) -> list[str]:
    counts = claims["counts"]
    lines = ["Verdicts: " + ", ".join(f"{w}: {counts[w]}" for w in SCALE if counts.get(w)) + ".", "",
             "| # | Paper claim | Where | Verdict | Per reading | Headline check |", "|---|---|---|---|---|---|"]
    for i, c in enumerate(claims["claims"], 1):
        lines.append(f"| {i} | {c['claim']} | {c['source']} | **{c['verdict']}** | {_readings(c)} | {_headline(c)} |")
    for i, c in enumerate(claims["claims"], 1):
        lines += ["", f"### {i}. {c['id']}: {c['verdict']}", "", f"*{c['claim']}* ({c['source']}).", "",
                  f"Rule: {c['rule']}.", *_chosen_on(c), "", "| reading | expected | observed | paper | passed |",
                  "|---|---|---|---|---|"]
        for ch in c["checks"]:
            reading = ch["reading"] if ch["reading"] != STATED else "paper's"
            lines.append(f"| {reading} | {ch['expected']}{' (essential)' if ch['essential'] else ''} | {ch['observed']} "
                         f"| {ch['paper']} | {_mark(ch['passed'])} |")
    return lines


def values_section(claims: dict) -> list[str]:
    rows = claims["values"]
    k = sum(r["reproduces"] for r in rows)
    lines = [f"The paper's value reproduces when its interval (its t-interval over its seeds where it gives a std, "
             f"else its point) overlaps our 95 % interval: {k} of {len(rows)} values.", "",
             "| table | row | N | figure | ours [95 %] | paper | reproduces |", "|---|---|---|---|---|---|---|"]
    for r in rows:
        lines.append(f"| {r['paper_table']} | {r['label']} | {r['n']} | {r['figure']} | {r['ours']} | {r['paper']} "
                     f"| {_mark(r['reproduces'])} |")
    return lines


def not_in_paper_section(claims: dict) -> list[str]:
    rows = claims.get("not_in_paper") or []
    lines = ["Our rows of the paper's tables that the paper does not have (the calibrated safety level, the speed "
             "governors, sensitivity runs, reference rows; each labelled \"not in paper\" where it is a deployment "
             "of ours): shown beside the claims, judged by none. Safety and safe scenarios % [95 %], cost ÷T [95 %], "
             "and the paired difference from the table's Ours (safety / cost ÷T).", "",
             "| table | row | N | safety | safe scenarios | cost ÷T | − Ours |", "|---|---|---|---|---|---|---|"]
    lines += [f"| {r['paper_table']} | {r['label']} | {r['n']} | {r['safety']} | {r['safe_scenarios']} | {r['cost']} "
              f"| {r['vs_ours']} |" for r in rows]
    return lines


def consistency_section(claims: dict) -> list[str]:
    rows = claims["consistency"]
    bad = [r for r in rows if not r["holds"]]
    lines = ["Computed from madpinn/evaluation/paper_values.yaml alone (madpinn/evaluation/paper_consistency.py): "
             "each printed value stands for ± half a unit of its last digit; a check fails only when no values "
             f"inside those bounds satisfy it. {len(bad)} of {len(rows)} checks cannot hold:", "",
             "| table | row | N | check | reading | expected | observed |", "|---|---|---|---|---|---|---|"]
    lines += [f"| {r['paper_table']} | {r['label']} | {r['n']} | {r['check']} | {r['reading'] or '–'} | {r['expected']} "
              f"| {r['observed']} |" for r in bad]
    lines += ["", "Safety against safe scenarios, every row (the share of a failing scenario's agents that collide "
              "is what the two figures imply):", "", "| table | row | N | observed | holds |", "|---|---|---|---|---|"]
    lines += [f"| {r['paper_table']} | {r['label']} | {r['n']} | {r['observed']} | {_mark(r['holds'])} |"
              for r in rows if r["check"] == "safety vs safe scenarios"]
    lines += ["", "Rows that must agree:", "", "| tables | check | observed | holds |", "|---|---|---|---|"]
    lines += [f"| {r['paper_table']} | {r['check']} | {r['observed']} | {_mark(r['holds'])} |"
              for r in rows if r["label"] == "same cell"]
    return lines


def to_markdown(claims: dict) -> str:
    prov = claims["provenance"]
    lines = ["# The paper's claims, tested", "",
             "Generated by the workflow (`snakemake -j2 claims_table`; madpinn/evaluation/claims.py) from "
             "`reproduction.json`: each claim of the paper with the rule that tests it, the checks phrased "
             "\"expected / observed\" over our figures and their 95 % intervals, and verdicts computed by the rule, "
             f"never typed. Verdict rule: {prov['rule']}.", "",
             f"- config hash `{prov.get('config_hash')}`", f"- collisions: {prov.get('collisions')}",
             f"- intervals: {prov.get('intervals')}", f"- seed provenance: {prov.get('vhat_recipe')}", "",
             "## Claims", "", *claims_section(claims), "",
             "## Values per cell (not claims)", "", *values_section(claims), "",
             "## Rows not in the paper (not claims)", "", *not_in_paper_section(claims), "",
             "## The paper's numbers against each other", "", *consistency_section(claims)]
    return "\n".join(lines) + "\n"
