"""scripts/claims_diff.py (issue 61's closing note): two claims pages side by side, each claim's
verdict and rule before and after."""

from __future__ import annotations

import json
import subprocess
import sys

from conftest import REPO


def claim(cid: str, verdict: str, passed: int, total: int, rule: str = "r") -> dict:
    return {"id": cid, "verdict": verdict, "passed": passed, "checks_total": total, "rule": rule,
            "headline": {"observed": f"{cid} seen"}}


def test_changed_verdicts_rules_and_claims_in_one_page_only_are_listed(tmp_path):
    old = {"claims": [claim("same", "holds", 2, 2), claim("flip", "holds", 3, 3), claim("rule", "partly", 1, 2),
                      claim("gone", "does not hold", 0, 1)]}
    new = {"claims": [claim("same", "holds", 2, 2), claim("flip", "does not hold", 0, 3),
                      claim("rule", "partly", 1, 2, rule="r2"), claim("added", "holds", 1, 1)]}
    (tmp_path / "old.json").write_text(json.dumps(old))
    (tmp_path / "new.json").write_text(json.dumps(new))
    out = subprocess.run([sys.executable, str(REPO / "scripts" / "claims_diff.py"), str(tmp_path / "old.json"),
                          str(tmp_path / "new.json"), "--changed"], capture_output=True, text=True, check=True).stdout
    lines = {line.split(" | ")[0].strip("| "): line for line in out.splitlines() if line.startswith("| ")}
    assert "same" not in lines
    assert "| holds (3 of 3) | does not hold (0 of 3) | no |" in lines["flip"]
    assert "| partly (1 of 2) | partly (1 of 2) | yes |" in lines["rule"]
    assert "| – | holds (1 of 1) |" in lines["added"] and "| does not hold (0 of 1) | – |" in lines["gone"]
    assert out.strip().endswith("3 of 5 claims changed verdict")   # flip, added, gone
