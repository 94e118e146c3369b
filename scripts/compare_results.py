"""Compare two smoke result trees: every Parquet frame, JSON number, CSV/MD/TeX table, NPZ array
and model weight equal; timing fields, wall-clock columns and config hashes are ignored
(they differ run to run or by the removed path keys)."""
import json, sys
from pathlib import Path

import numpy as np
import pandas as pd
import torch

IGNORE = {"elapsed_s", "cpu_s", "cpu_model", "sim_wall_s", "policy_s", "policy_us_per_agent_step", "wall_s", "job_config_hash",
          "config_hash", "git_commit", "clip", "traj", "detail"}
TIMING_COLS = {"wall_s", "elapsed_s", "policy_s", "sim_wall_s", "policy_us_per_agent_step", "time_s"}


def strip(o):
    if isinstance(o, dict):
        return {k: strip(v) for k, v in o.items() if k not in IGNORE}
    if isinstance(o, list):
        return [strip(v) for v in o]
    return o


def main(a, b):
    a, b = Path(a), Path(b)
    fa = sorted(p.relative_to(a) for p in a.rglob("*") if p.is_file() and "logs" not in p.parts and "tracking" not in p.parts
                and p.name != "config.resolved.yaml" and "checkpoints" not in p.parts)
    fb = sorted(p.relative_to(b) for p in b.rglob("*") if p.is_file() and "logs" not in p.parts and "tracking" not in p.parts
                and p.name != "config.resolved.yaml" and "checkpoints" not in p.parts)
    bad, n = [], 0
    if fa != fb:
        bad.append(f"file sets differ: only in A {sorted(set(fa) - set(fb))[:10]}, only in B {sorted(set(fb) - set(fa))[:10]}")
    for rel in sorted(set(fa) & set(fb)):
        pa, pb = a / rel, b / rel
        n += 1
        s = rel.suffix
        try:
            if s == ".parquet":
                da, db = pd.read_parquet(pa), pd.read_parquet(pb)
                pd.testing.assert_frame_equal(da, db, check_exact=True)
            elif s == ".json":
                ja, jb = strip(json.loads(pa.read_text())), strip(json.loads(pb.read_text()))
                assert ja == jb, f"{ja} != {jb}"
            elif s == ".npz":
                za, zb = np.load(pa), np.load(pb)
                assert sorted(za.files) == sorted(zb.files)
                for k in za.files:
                    assert np.array_equal(za[k], zb[k]), k
            elif s == ".csv":
                da, db = pd.read_csv(pa), pd.read_csv(pb)
                cols = [c for c in da.columns if c not in TIMING_COLS]
                pd.testing.assert_frame_equal(da[cols], db[cols], check_exact=True)
            elif s in (".md", ".tex"):
                assert pa.read_text() == pb.read_text()
            elif s == ".pt":
                ta = torch.load(pa, weights_only=True); tb = torch.load(pb, weights_only=True)
                def tensors(d, pre=""):
                    out = {}
                    for k, v in d.items():
                        if isinstance(v, dict):
                            out.update(tensors(v, f"{pre}{k}."))
                        elif isinstance(v, torch.Tensor):
                            out[pre + k] = v
                    return out
                xa, xb = tensors(ta), tensors(tb)
                assert xa.keys() == xb.keys() and all(torch.equal(xa[k], xb[k]) for k in xa), "weights differ"
            elif s in (".pdf", ".png", ".gif"):
                n -= 1  # images: rendering metadata (dates) differ; their data are the compared tables
            else:
                assert pa.read_bytes() == pb.read_bytes()
        except AssertionError as exc:
            bad.append(f"{rel}: {str(exc)[:300]}")
    print(f"compared {n} files under {a} vs {b}: {len(bad)} differ")
    for line in bad:
        print("  DIFF", line)
    return 1 if bad else 0


if __name__ == "__main__":
    sys.exit(main(*sys.argv[1:3]))
