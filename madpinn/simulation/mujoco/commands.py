"""CLI: ``python -m madpinn render-clip`` — optional GIF of a MuJoCo episode, logged to MLflow.

Without an offscreen GL context the command succeeds, writes its status JSON with
``rendered: false`` and the reason, and logs nothing.
"""

from __future__ import annotations

import json
from pathlib import Path


def _render_clip(args) -> int:
    from madpinn.config import load_config
    from madpinn.simulation.mujoco.render import gl_context_available, render_clip
    from madpinn.simulation.mujoco.settings import MujocoSettings

    cfg = load_config(args.config)
    traj = Path(args.traj)
    if not traj.is_file():
        raise FileNotFoundError(f"trajectory file not found: {traj}")
    out = Path(args.out)
    clip = out.with_suffix(".gif")
    ok, detail = gl_context_available()
    status = {"traj": str(traj), "rendered": ok, "detail": detail}
    if ok:
        altitude = MujocoSettings.from_config(cfg["sim"].get("mujoco")).altitude
        render_clip(traj, clip, altitude=altitude)
        status["clip"] = str(clip)
    out.parent.mkdir(parents=True, exist_ok=True)
    out.write_text(json.dumps(status, indent=2))
    print(json.dumps(status))
    if ok and not args.no_track:
        from madpinn.tracking import log_job

        log_job(cfg, job_key=f"render_clip/{args.key or traj.stem}", rule="render_clip",
                wildcards={"traj": str(traj)}, params={"traj": str(traj)}, artifacts=[clip, out])
    return 0


def register(sub) -> None:
    from madpinn.cli import add_config_arg

    p = sub.add_parser("render-clip", help="render a MuJoCo episode (*_traj.npz) to a GIF where offscreen GL exists")
    add_config_arg(p)
    p.add_argument("--traj", required=True, help="an evaluation job's *_traj.npz")
    p.add_argument("--out", required=True, help="status JSON; the clip is written next to it as .gif")
    p.add_argument("--key", default=None, help="MLflow job key (default: the trajectory's name)")
    p.add_argument("--no-track", action="store_true", help="do not log to MLflow")
    p.set_defaults(func=_render_clip)
