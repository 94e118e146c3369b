"""``render-clip``: optional GIF of a MuJoCo episode, logged to MLflow.

Without an offscreen GL context the command succeeds, writes its status JSON with
``rendered: false`` and the reason, and logs nothing.
"""

from __future__ import annotations

from pathlib import Path

from madpinn.commands.args import add_config_arg, config_of
from madpinn.commands.finish import JobRecord, finish, job, write_json
from madpinn.commands.reads import keys


def _render_clip(args) -> int:
    from madpinn.simulation.mujoco.render import gl_context_available, render_clip
    from madpinn.simulation.mujoco.settings import MujocoSettings

    cfg = config_of(args)
    traj = Path(args.traj)
    if not traj.is_file():
        raise FileNotFoundError(f"trajectory file not found: {traj}")
    out = Path(args.out)
    clip = out.with_suffix(".gif")
    settings = MujocoSettings.from_config(cfg["sim"]["mujoco"])
    ok, detail = gl_context_available(settings.spec)
    record = JobRecord(job_key=f"render_clip/{args.key or traj.stem}", rule="render_clip",
                       wildcards={"traj": str(traj)}, params={"traj": str(traj)})
    with job(cfg, record, ok and not args.no_track) as run:
        status = {"traj": str(traj), "rendered": ok, "detail": detail}
        if ok:
            render_clip(traj, clip, settings)
            status["clip"] = str(clip)
        write_json(out, status)
        record.artifacts = [clip, out] if ok else [out]
        return finish(run, record, echo=status)


def register(sub) -> None:
    p = sub.add_parser("render-clip", help="render a MuJoCo episode (*_traj.npz) to a GIF where offscreen GL exists")
    add_config_arg(p)
    p.add_argument("--traj", required=True, help="an evaluation job's *_traj.npz")
    p.add_argument("--out", required=True, help="status JSON; the clip is written next to it as .gif")
    p.add_argument("--key", default=None, help="MLflow job key (default: the trajectory's name)")
    p.add_argument("--no-track", action="store_true", help="do not log to MLflow")
    p.set_defaults(func=_render_clip, reads=keys("sim.mujoco", "arenas"))
