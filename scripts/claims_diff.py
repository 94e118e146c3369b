"""Before / after a protocol rerun: every claim of two claims pages side by side (issue 61's closing
note: each rule, its old and new verdict).

    python scripts/claims_diff.py git:HEAD~1:paper_figures/claims.json paper_figures/claims.json [--changed]

Each page is a path or ``git:REV:PATH`` (:func:`report_gap.load`). Prints a Markdown table, one row
per claim in either page: its verdict and checks passed before and after, whether its rule text
changed, and its headline observation before and after. ``--changed`` keeps the claims whose
verdict, checks or rule changed. The last line counts the verdicts that changed.
"""
from __future__ import annotations

import argparse

from report_gap import load


def verdict(claim: dict | None) -> str:
    if claim is None:
        return "–"
    checks = f" ({claim['passed']} of {claim['checks_total']})" if claim.get("checks_total") else ""
    text = claim["verdict"]
    return text if text.endswith(")") else text + checks


def observed(claim: dict | None) -> str:
    head = (claim or {}).get("headline") or {}
    return str(head.get("observed", "–")).replace("|", "/").replace("\n", " ")


def rows(old: dict, new: dict, changed_only: bool) -> list[dict]:
    before = {c["id"]: c for c in old["claims"]}
    after = {c["id"]: c for c in new["claims"]}
    out = []
    for cid in [*after, *(c for c in before if c not in after)]:
        a, b = before.get(cid), after.get(cid)
        row = {"id": cid, "old": verdict(a), "new": verdict(b),
               "rule_changed": a is not None and b is not None and a.get("rule") != b.get("rule"),
               "old_observed": observed(a), "new_observed": observed(b)}
        row["changed"] = row["old"] != row["new"] or row["rule_changed"] or a is None or b is None
        if row["changed"] or not changed_only:
            out.append(row)
    return out


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("old", help="claims.json before (a path or git:REV:PATH)")
    ap.add_argument("new", help="claims.json after")
    ap.add_argument("--changed", action="store_true", help="only the claims whose verdict, checks or rule changed")
    args = ap.parse_args()
    old, new = load(args.old), load(args.new)
    every = rows(old, new, changed_only=False)
    print("| claim | verdict before | verdict after | rule changed | observed before | observed after |")
    print("|---|---|---|---|---|---|")
    for r in every:
        if r["changed"] or not args.changed:
            print(f"| {r['id']} | {r['old']} | {r['new']} | {'yes' if r['rule_changed'] else 'no'} | "
                  f"{r['old_observed']} | {r['new_observed']} |")
    moved = sum(r["old"].split(" (")[0] != r["new"].split(" (")[0] for r in every)
    print(f"\n{moved} of {len(every)} claims changed verdict")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
