"""Keep copies of a resumable training checkpoint at chosen iterations, while the training runs.

The trainer overwrites its checkpoint every ``checkpoint_every`` iterations; this watcher copies the
file each time its iteration is one of ``--at`` (a multiple of ``checkpoint_every``), so one long run
also yields the same network at smaller budgets (issue 46: the 3x V̂ at 1.5x and 2x samples).
Usage (from the repository root, beside the running pieces):
    python training/snapshot_checkpoint.py --checkpoint training/vhat_budget3x/vhat.ckpt.pt \
        --at 90000 120000 --out-dir training/vhat_budget3x/snapshots
Exits when every snapshot exists. Copies are named ``<stem>_it<iteration>.ckpt.pt``.
"""

from __future__ import annotations

import argparse
import shutil
import time
from pathlib import Path

import torch


def checkpoint_iteration(path: Path) -> int | None:
    """The iteration a resume checkpoint holds (None: unreadable right now, e.g. being replaced)."""
    try:
        data = torch.load(path, map_location="cpu", weights_only=True)
        return int(data["meta"]["train_state"]["iteration"])
    except Exception:   # noqa: BLE001 - a file mid-replacement: try again at the next poll
        return None


def main() -> int:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--checkpoint", type=Path, required=True)
    p.add_argument("--at", type=int, nargs="+", required=True, help="iterations to keep")
    p.add_argument("--out-dir", type=Path, required=True)
    p.add_argument("--poll-s", type=float, default=15.0)
    args = p.parse_args()
    args.out_dir.mkdir(parents=True, exist_ok=True)
    stem = args.checkpoint.name.removesuffix(".ckpt.pt")
    wanted = {k: args.out_dir / f"{stem}_it{k:06d}.ckpt.pt" for k in sorted(args.at)}
    last = None
    while any(not f.exists() for f in wanted.values()):
        it = checkpoint_iteration(args.checkpoint)
        if it is not None and it != last:
            last = it
            if it in wanted and not wanted[it].exists():
                tmp = wanted[it].with_suffix(".tmp")
                shutil.copyfile(args.checkpoint, tmp)
                if checkpoint_iteration(tmp) == it:   # the copy is the state at `it`, not a later overwrite
                    tmp.replace(wanted[it])
                    print(f"kept iteration {it}: {wanted[it]}", flush=True)
                else:
                    tmp.unlink()
            elif it > max(wanted) and any(not f.exists() for f in wanted.values()):
                print(f"checkpoint passed {max(wanted)} with snapshots missing: {[k for k, f in wanted.items() if not f.exists()]}")
                return 1
        time.sleep(args.poll_s)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
