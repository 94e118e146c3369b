"""Physics + controller time per drone-step of the MuJoCo Crazyflie backend.

    PYTHONPATH=$PWD python benchmarks/bench_mujoco.py [--config config.yaml] [--steps 200] [--repeats 3]
    PYTHONPATH=$PWD python benchmarks/bench_mujoco.py --compare-forces   # qfrc vs xfrc vs site actuators
    PYTHONPATH=$PWD python benchmarks/bench_mujoco.py --contacts         # contact physics vs pass-through
    PYTHONPATH=$PWD python benchmarks/bench_mujoco.py --stages           # where a contact step's time goes

For N ∈ {16, 256, 1024, 5120} drones in one backend (one job's S × N), times ``command`` +
``step`` (one ``sim.dt`` with ``sim.mujoco.substeps`` physics + controller substeps) under
bang-bang policy accelerations; prints best-of-``repeats`` µs per drone-step as process CPU time
(single-threaded, so equal to wall time on an idle machine, and much less disturbed by other
jobs sharing the cores) and as wall time, with MuJoCo's bare free-body step for reference. The
last line is ``us_per_drone_step_at_5120: X`` (CPU time).

``--contacts`` times instead 1 024 drones as 64 scenarios of 16 in the small arena (the density
of Table I's 16-agent cells, random bang-bang commands, so drones do collide) with ``sim.contacts``
off and on, and prints ``contacts_time_ratio_at_1024: X`` (on ÷ off, CPU time; target ≤ 1.5) and
how many drones came within the collision cylinders' reach (2 × 0.06 m).

``--contacts --explicit-pairs`` adds a what-if that the backend does not use: the same worlds with
MuJoCo's broadphase replaced by explicit ``<contact><pair>`` elements, one per pair of drones of a
scenario and one per drone and the floor. The geoms and contact parameters are the same, so the
physics model is the same; only the order in which contacts reach the solver can differ. The
what-if prints its ratio and how far its trajectories drift from the backend's (max position
difference after the episode).
"""

from __future__ import annotations

import argparse
import time

import mujoco
import numpy as np
import torch

import madpinn.simulation.mujoco.backend as backend_module
from madpinn.config import deep_merge, load_config
from madpinn.dynamics import DoubleIntegrator
from madpinn.simulation.mujoco import MujocoBackend, MujocoSettings, compile_world

COUNTS = (16, 256, 1024, 5120)


def _best(fn, repeats: int, per: int, setup=lambda: None) -> tuple[float, float]:
    """Best-of-``repeats`` (CPU, wall) µs per unit of ``fn()``, which does ``per`` units;
    ``setup()`` runs untimed before each repeat."""
    cpu = wall = float("inf")
    for _ in range(repeats):
        setup()
        c0, w0 = time.process_time(), time.perf_counter()
        fn()
        cpu = min(cpu, time.process_time() - c0)
        wall = min(wall, time.perf_counter() - w0)
    return 1e6 * cpu / per, 1e6 * wall / per


def time_backend(cfg: dict, count: int, steps: int, repeats: int, overrides: dict | None = None) -> tuple[float, float]:
    """Best-of-``repeats`` (CPU, wall) µs per drone-step (command + step) for ``count`` drones."""
    settings = MujocoSettings.from_config(deep_merge(cfg["sim"].get("mujoco") or {}, overrides or {}))
    dyn = DoubleIntegrator(cfg["agents"]["u_max"], cfg["agents"]["v_max"])
    backend = MujocoBackend(dyn, cfg["sim"]["dt"], settings)
    gen = torch.Generator().manual_seed(0)
    starts = torch.rand(1, count, 2, generator=gen) * 2 - 1
    accel = (torch.randint(0, 2, (steps, 1, count, 2), generator=gen) * 2 - 1) * cfg["agents"]["u_max"]
    backend.reset(starts, torch.zeros_like(starts))  # warm-up: model compile, caches
    accel = accel.float()

    def episode():
        for k in range(steps):
            backend.command(accel[k], backend.dt)
            backend.step()

    return _best(episode, repeats, steps * count, setup=lambda: backend.reset(starts, torch.zeros_like(starts)))


def time_bare_mujoco(cfg: dict, count: int, steps: int, repeats: int) -> tuple[float, float]:
    """Best-of µs per drone per ``sim.dt`` of MuJoCo alone (same worlds and substeps, constant
    hover forces, no controller)."""
    settings = MujocoSettings.from_config(cfg["sim"].get("mujoco"))
    h = cfg["sim"]["dt"] / settings.substeps
    worlds = []
    for start in range(0, count, settings.drones_per_world):
        model = compile_world(min(settings.drones_per_world, count - start), h, settings.spec)
        data = mujoco.MjData(model)
        data.qfrc_applied.reshape(-1, 6)[:, 2] = settings.spec.mass * 9.81
        worlds.append((model, data))
    def run():
        for _ in range(steps * settings.substeps):
            for model, data in worlds:
                mujoco.mj_step(model, data)

    return _best(run, repeats, steps * count)


def explicit_pair_xml(xml: str, count: int, group: int) -> str:
    """World MJCF ``xml`` (contacts on) with MuJoCo's broadphase replaced by explicit ``<pair>``
    elements: each pair of drones of a scenario (``group`` consecutive drones) and each drone with
    the floor. Same geoms, same contact parameters."""
    import re

    hulls = re.findall(r'<geom name="(d\d+hull)"', xml)
    assert len(hulls) == count and count % group == 0, (len(hulls), count, group)
    pairs = [f'<pair geom1="floor" geom2="{h}"/>' for h in hulls]
    for start in range(0, count, group):
        pairs += [f'<pair geom1="{hulls[i]}" geom2="{hulls[j]}"/>'
                  for i in range(start, start + group) for j in range(i + 1, start + group)]
    xml = xml.replace('contype="1" conaffinity="1"', 'contype="0" conaffinity="0"')
    return xml.replace("</worldbody>", "</worldbody><contact>" + "".join(pairs) + "</contact>")


def explicit_pair_worlds(group: int):
    """A stand-in for :func:`compile_world` whose worlds list their contact pairs explicitly
    (:func:`explicit_pair_xml`; the ``--explicit-pairs`` what-if)."""
    from madpinn.simulation.mujoco.model import world_xml

    def compile_explicit(count, timestep, spec, actuated=False, contacts=False, visual=True):
        xml = world_xml(count, timestep, spec, actuated, contacts, visual)
        return mujoco.MjModel.from_xml_string(explicit_pair_xml(xml, count, group) if contacts else xml)

    return compile_explicit


def contact_stages(cfg: dict, scenarios: int = 64, agents: int = 16, steps: int = 400) -> None:
    """Bare ``mj_step`` of one contact world (``scenarios`` × ``agents`` drones at their scenario
    offsets, uniform starts in [-1, 1]² at 1 m, planar velocities uniform in ±2 m/s, hover force):
    MuJoCo's stage timers (ms per step) with contacts off and on, then the process CPU µs per
    drone-step of settings that keep the contact model (and two solver settings) — the ``--stages``
    table of docs/reference/performance.md."""
    import re

    from madpinn.simulation.mujoco.model import scenario_offsets, world_xml

    settings = MujocoSettings.from_config(cfg["sim"].get("mujoco"))
    count = scenarios * agents
    h = cfg["sim"]["dt"] / settings.substeps
    xml = world_xml(count, h, settings.spec, contacts=True, visual=False)
    offsets = scenario_offsets(count, agents)[::agents]
    boxes = "".join(f'<geom name="floor{i}" type="box" size="6 6 0.05" pos="{float(o[0])!r} {float(o[1])!r} -0.05" '
                    'contype="1" conaffinity="1"/>' for i, o in enumerate(offsets))

    def world(text: str, disable: int = 0, solver=None):
        m = mujoco.MjModel.from_xml_string(text)
        m.opt.disableflags |= disable
        if solver is not None:
            m.opt.solver = solver
        d = mujoco.MjData(m)
        rng = np.random.default_rng(0)
        q = d.qpos.reshape(-1, 7)
        q[:, 0:2] = rng.uniform(-1, 1, (count, 2)) + scenario_offsets(count, agents)
        q[:, 2], q[:, 3] = 1.0, 1.0
        d.qvel.reshape(-1, 6)[:, 0:2] = rng.uniform(-2, 2, (count, 2))
        d.qfrc_applied.reshape(-1, 6)[:, 2] = m.body_mass[1] * 9.81
        return m, d

    def cpu_us(m, d) -> float:
        t0 = time.process_time()
        for _ in range(steps):
            mujoco.mj_step(m, d)
        return 1e6 * (time.process_time() - t0) / steps / count

    names = ("STEP", "COL_BROAD", "COL_NARROW", "CONSTRAINT", "POS_MAKE")
    for label, disable in (("off", int(mujoco.mjtDisableBit.mjDSBL_CONTACT)), ("on", 0)):
        m, d = world(xml, disable)
        for _ in range(steps):
            mujoco.mj_step(m, d)
        ms = {n: d.timer[int(getattr(mujoco.mjtTimer, "mjTIMER_" + n))].duration / steps * 1e3 for n in names}
        print(f"contacts {label}: " + ", ".join(f"{n} {v:.3f} ms" for n, v in ms.items()) + " per step", flush=True)
    dsbl = mujoco.mjtDisableBit
    variants = [("contacts off", xml, int(dsbl.mjDSBL_CONTACT), None), ("contacts on (the backend)", xml, 0, None),
                ("explicit pairs", explicit_pair_xml(xml, count, agents), 0, None),
                ("floor of per-scenario boxes", re.sub(r'<geom name="floor"[^>]*/>', boxes, xml), 0, None),
                ("islands off", xml, int(dsbl.mjDSBL_ISLAND), None), ("midphase off", xml, int(dsbl.mjDSBL_MIDPHASE), None),
                ("libccd (native CCD off)", xml, int(dsbl.mjDSBL_NATIVECCD), None),
                ("multi-point CCD off", xml, int(dsbl.mjDSBL_MULTICCD), None),
                ("solver: warm start off", xml, int(dsbl.mjDSBL_WARMSTART), None),
                ("solver: CG", xml, 0, mujoco.mjtSolver.mjSOL_CG)]
    cpu = {label: min(cpu_us(*world(text, disable, solver)) for _ in range(3)) for label, text, disable, solver in variants}
    base = cpu["contacts on (the backend)"]
    for label, us in cpu.items():
        vs = "" if label.startswith("contacts") else f" ({us / base - 1:+.0%} vs the backend's)"
        print(f"{label:30s} {us:.3f} us/drone per mj_step{vs}", flush=True)


def time_contacts(cfg: dict, scenarios: int, agents: int, steps: int, repeats: int,
                  explicit_pairs: bool = False) -> dict:
    """Best-of (CPU, wall) µs per drone-step for ``scenarios`` × ``agents`` drones (uniform starts
    in [-1, 1]², bang-bang commands) with contacts off and on; and the share of drones that came
    within 0.12 m of another of their scenario with contacts on."""
    from madpinn.simulation.mujoco.model import COLLISION_CYLINDER

    settings = MujocoSettings.from_config(cfg["sim"].get("mujoco"))
    dyn = DoubleIntegrator(cfg["agents"]["u_max"], cfg["agents"]["v_max"])
    gen = torch.Generator().manual_seed(0)
    starts = torch.rand(scenarios, agents, 2, generator=gen, dtype=torch.float64) * 2 - 1
    accel = (torch.randint(0, 2, (steps, scenarios, agents, 2), generator=gen) * 2 - 1).double() * cfg["agents"]["u_max"]
    out = {}
    variants = [(False, False), (True, False)] + ([(True, True)] if explicit_pairs else [])
    for contacts, explicit in variants:
        original = backend_module.compile_world
        if explicit:
            backend_module.compile_world = explicit_pair_worlds(agents)
        try:
            backend = MujocoBackend(dyn, cfg["sim"]["dt"], settings, dtype=torch.float64, contacts=contacts)
            backend.reset(starts, torch.zeros_like(starts))   # warm-up: compile
        finally:
            backend_module.compile_world = original
        backend.reset(starts, torch.zeros_like(starts))   # warm-up: compile
        touched = torch.zeros(scenarios, agents, dtype=torch.bool)

        def episode():
            nonlocal touched
            for k in range(steps):
                backend.command(accel[k], backend.dt)
                p = backend.step()[..., 0:2]
                d = torch.cdist(p, p) + torch.eye(agents, dtype=p.dtype) * 1e9
                touched |= d.amin(-1) < 2 * COLLISION_CYLINDER[0]

        key = "explicit" if explicit else contacts
        out[key] = _best(episode, repeats, steps * scenarios * agents,
                         setup=lambda: backend.reset(starts, torch.zeros_like(starts)))
        out[f"touched_{key}"] = float(touched.double().mean())
        out[f"final_{key}"] = backend.step()[..., 0:2].clone()
    return out


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--config", nargs="+", default=["config.yaml"])
    ap.add_argument("--steps", type=int, default=200, help="sim steps timed per repeat")
    ap.add_argument("--repeats", type=int, default=3)
    ap.add_argument("--compare-forces", action="store_true", help="also time xfrc and site actuators")
    ap.add_argument("--contacts", action="store_true", help="time contact physics against pass-through (1 024 drones)")
    ap.add_argument("--explicit-pairs", action="store_true", help="with --contacts: also time the explicit-pair what-if")
    ap.add_argument("--stages", action="store_true", help="MuJoCo's stage timers and contact settings (bare mj_step)")
    args = ap.parse_args()
    torch.set_num_threads(1)
    cfg = load_config(args.config)
    m = cfg["sim"].get("mujoco") or {}
    print(f"MuJoCo {mujoco.__version__}, dt = {cfg['sim']['dt']} s, substeps = {m.get('substeps')}, "
          f"force_application = {m.get('force_application')}, drones_per_world = {m.get('drones_per_world')}")
    if args.stages:
        contact_stages(cfg)
        return
    if args.contacts:
        r = time_contacts(cfg, 64, 16, args.steps, args.repeats, args.explicit_pairs)
        print(f"1024 drones (64 scenarios x 16): pass-through {r[False][0]:.3f} us/drone-step CPU ({r[False][1]:.3f} wall), "
              f"contacts {r[True][0]:.3f} CPU ({r[True][1]:.3f} wall); drones within 0.12 m of another: "
              f"{100 * r['touched_True']:.0f} % with contacts ({100 * r['touched_False']:.0f} % passing through)")
        if args.explicit_pairs:
            drift = float((r["final_explicit"] - r["final_True"]).norm(dim=-1).max())
            print(f"explicit-pair what-if: {r['explicit'][0]:.3f} us/drone-step CPU ({r['explicit'][1]:.3f} wall), "
                  f"ratio {r['explicit'][0] / r[False][0]:.3f}; max position difference from the backend's contacts "
                  f"after the episode {drift:.3e} m; drones within 0.12 m: {100 * r['touched_explicit']:.0f} %")
        print(f"contacts_time_ratio_at_1024: {r[True][0] / r[False][0]:.3f}")
        return
    if args.compare_forces:
        for count in (16, 64, 256, 1024):
            row = []
            for mode in ("qfrc", "xfrc", "site"):
                if mode == "site" and count > 1024:
                    continue
                cpu, _ = time_backend(cfg, count, max(20, args.steps // 4), args.repeats,
                                      {"force_application": mode, "drones_per_world": count})
                row.append(f"{mode} {cpu:.3f}")
            print(f"forces N={count:5d} (one world): " + ", ".join(row) + "  us/drone-step (CPU)", flush=True)
    result = {}
    for count in COUNTS:
        cpu, wall = time_backend(cfg, count, args.steps, args.repeats)
        bare_cpu, bare_wall = time_bare_mujoco(cfg, count, args.steps, args.repeats)
        result[count] = cpu
        print(f"N={count:5d}: backend {cpu:.3f} us/drone-step CPU ({wall:.3f} wall); "
              f"MuJoCo alone {bare_cpu:.3f} CPU ({bare_wall:.3f} wall)", flush=True)
    print(f"us_per_drone_step_at_5120: {result[5120]:.3f}")


if __name__ == "__main__":
    main()
