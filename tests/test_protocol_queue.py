"""scripts/protocol_queue.sh (the protocol rerun over several sittings): its list is every cached job
a dry run of `all` under the shipped profile still plans (evaluation cells, oracle bounds, V̂'s calibration), each
once, in the stated study order, so that scripts/protocol_finish.sh's `all` computes no cached job."""

from __future__ import annotations

import os
import re
import subprocess
import sys

import yaml

from conftest import REPO

CACHED = yaml.safe_load((REPO / "profiles" / "shipped" / "config.yaml").read_text())["cache"]
CELL = re.compile(r"^results/(eval/[^/]+/(?P<study>[^/]+)/[^/]+/n\d+_seed\d+\.parquet|(?P<oracle>oracle)/.+/n\d+_seed\d+_s\d+\.parquet"
                  r"|validation/(?P<calibration>[^/]+)_calibration\.json)$")


def test_the_queue_lists_every_cached_job_of_all_once_in_study_order():
    env = os.environ | {"LIST": "1", "PYTHON": sys.executable}
    listed = subprocess.run(["bash", "scripts/protocol_queue.sh"], cwd=REPO, env=env, capture_output=True,
                            text=True, timeout=600, check=True).stdout.split()
    plan = subprocess.run([sys.executable, "-m", "snakemake", "-n", "--nolock", "--configfile", "config.yaml",
                           "workflow/configs/shipped.yaml", "--profile", "profiles/shipped", "all"],
                          cwd=REPO, capture_output=True, text=True, timeout=600, check=True)
    counts = dict(re.findall(rf"^({'|'.join(CACHED)})\s+(\d+)$", plan.stdout + plan.stderr, re.M))
    assert len(listed) == len(set(listed)) == sum(int(n) for n in counts.values()), (len(listed), counts)
    studies = []
    for target in listed:
        match = CELL.match(target)
        assert match, target
        studies.append(match["study"] or ("oracle" if match["oracle"] else "calibration"))
    order = re.search(r"^order=\((.*?)\)", (REPO / "scripts" / "protocol_queue.sh").read_text(), re.S | re.M)[1]
    rank = {s: i for i, s in enumerate(re.sub(r"#.*", "", order).split())}
    ranks = [rank.get(s, len(rank)) for s in studies]
    assert ranks == sorted(ranks), studies
