"""Benchmark of the BoxCCD pybullet plugin against plain pybullet, substepping and native CCD.

What it measures
----------------
Scenes of N = 10, 100 and 1000 dynamic boxes (all 0.1 m cubes, mass 1): a resting
pile of N - 4 boxes (a grid of up to 5 layers on the ground, settled by 200 plain
steps before anything is timed) plus 4 projectiles, over a static ground (a box
2 cm thick, top face at z = 0) and a static thin wall (1 cm thick, the plane x = 0,
y in [-1, 1], z in [0, 1.5]). The pile stands away from the projectiles' paths.
Per trial (numpy ``Generator`` seeded with ``--seed + trial``):

* 2 projectiles are fired at the wall (speed U(50, 150) m/s, direction within 20
  degrees of +x, aim point y in [-0.7, 0.7], z in [0.3, 1.2], reached at a seeded
  step 8..60 of the window, gravity compensated; a shot that would start below the
  ground comes down at the wall instead),
* 2 projectiles are fired down at the ground (speed U(50, 150) m/s, within 30
  degrees of vertical, aim point in the empty region x in [-4, -1], y in [-3, -1]),

all with a random spin (each component U(-20, 20) rad/s), and a window of
``--window`` steps (default 120, 1/240 s each, i.e. 0.5 s; at most 72 for 1000 boxes
and more, which still holds every impact) is timed step by step.
A projectile has tunneled if at the end of the window its centre is below the
ground's top face (z < 0, over the ground), or if it is beyond the wall's mid-plane
(x > 0) having crossed that plane within the wall's face (|y| <= 1, 0 <= z <= 1.5;
checked on the segment between the centres after consecutive steps, untimed): a
projectile that bounces off the ground and flies over or round the wall has not
tunneled. ``tunneled/shots`` counts projectiles over all trials. Every method sees
the same settled pile (``p.saveState``/``p.restoreState``) and the same projectiles.

Methods (``fixedTimeStep`` 1/240 s per step throughout):

* ``plain``: ``p.stepSimulation()`` (multibody bodies, ``numSubSteps`` 0),
* ``plugin``: ``BoxCCD(cid).step()`` on the same world,
* ``plugin, no partial steps``: ``BoxCCD(cid, max_partial_steps=0)``: the bodies of a
  contact pybullet would resolve wrongly go back to it on their own and the step ends
  there (pybullet resolves it at the next step), instead of the rest of the step being
  simulated from the contact,
* ``substeps k`` (k = 2, 4, 8, 16): ``p.setPhysicsEngineParameter(numSubSteps=k)``,
  so one step is k solver steps of 1/(240 k) s,
* ``plain (maximal)``: the same scene built with ``useMaximalCoordinates=True``
  (btRigidBody instead of btMultiBody), ``p.stepSimulation()``, the baseline of
  native CCD,
* ``native CCD (maximal)``: that scene with Bullet's own CCD on the projectiles,
  ``changeDynamics(ccdSweptSphereRadius=0.025)`` (half the projectile's smallest half
  extent) and ``contactProcessingThreshold=0`` (a world of its own, built the same way,
  since ``restoreState`` does not undo these settings).

Multibody velocities are unclamped (``maxJointVelocity=10000``); no damping.
``us/step`` is, per trial, the mean wall time of a step over the window (it includes
the impact steps), then the median (and the min) over trials; ``x plain`` is the
median's ratio to ``plain`` of the same N. Trials run seeds outer, methods inner, so
a burst of load from elsewhere hits every method alike. For the plugin the per-phase
seconds of ``ccd.stats.seconds`` (reading the state, broad phase, solver, rewind; a
step in which nothing is fast is not timed by phase) are printed per step, and its
counters (swept boxes, candidate pairs, solver rows, contacts, rewinds, partial steps) summed
over the trials.

First, small worlds (what a reinforcement-learning world steps millions of times):
1 and 10 resting cubes on the ground (settled), the 10 stepped in 4 substeps (BoxCCD takes
them itself and reads the velocities at each: its reads are 4 N), and one cube sliding at
10 m/s on it (a fresh world per repeat, 100 steps timed: it is swept at every one of
them). Per repeat, plain ``stepSimulation``, the N ``getBaseVelocity`` reads alone, and
``BoxCCD.step()`` are timed in turn (this process's CPU time, mean over a block of
steps; the min over repeats, as the machine may carry other load); printed: the plugin's overhead over
plain as a multiple of the reads (bound: at most 2) and, for the slider, the
plugin's ratio to plain (bound: at most 3).

Then the scenes above. Then, tunneling only, ``--extra-seeds`` more seeds (default 100) on the 10-box scene
for plain, the plugin (both modes), substeps 8 and 16 and native CCD (the pile is off
the projectiles' paths, so its size does not matter there).

Targets printed beside the results: plugin overhead at most 30 % of a plain step at
N = 100, and the plugin at zero tunneling cheaper than the cheapest substep count
that also reaches zero tunneling.

Run
---
    python benchmarks/plugin.py            # several minutes
    python benchmarks/plugin.py --quick    # about 2 min

Options: ``--seed`` (default 2024), ``--trials`` (per N up to 100 boxes, default 6;
larger scenes get a third of them, at least 2: every size is shot with the same first
two seeds' projectiles, so that "none through" means the same shots at every size),
``--window``, ``--sizes``, ``--csv``. ``--quick`` runs 2 trials of 64 steps, 20 extra
seeds, fewer small-world repeats, and leaves out substeps 16 (and plugin, no partial
steps, at 1000 boxes). The small-world table is also written to
``benchmarks/results/plugin_small.csv``.
The tables are markdown; the scenes' table is also written to ``benchmarks/results/plugin.csv``
(with the plugin's phases and counters), and every tunneled projectile (N, method,
seed, projectile, final centre) to ``benchmarks/results/plugin_tunneled.csv``. The
commit measured is printed (read-only git). The machine may carry other load: read
the medians, compare with the mins.
This is a benchmark, not a test: it asserts nothing about timings.
"""

from __future__ import annotations

import argparse
import csv
import os
import platform
import statistics
import time

import numpy as np
import pybullet as p
from _report import code_version
from tqdm import tqdm

from bullet_boxccd import BoxCCD
from bullet_boxccd.pybullet_ccd.tradeoff.grid import write_csv
from bullet_boxccd.pybullet_ccd.tradeoff.scenes import DT, HALF, N_PROJ, G, build, run_trial  # shared with tradeoff.py
from bullet_boxccd.validate.tables import markdown

SUBSTEPS = (2, 4, 8, 16)
PHASES = ("state", "broad_phase", "solve", "rewind")
EXACT = ["plugin, no partial steps"]
PLUGINS = ["plugin"] + EXACT
METHODS = ["plain", "plugin"] + EXACT + [f"substeps {k}" for k in SUBSTEPS] + ["plain (maximal)",
                                                                                "native CCD (maximal)"]
EXTRA_METHODS = ["plain", "plugin"] + EXACT + ["substeps 8", "substeps 16", "native CCD (maximal)"]
COUNTERS = ("swept_boxes", "candidate_pairs", "solver_rows", "contacts", "rewinds", "partial_steps")


def print_table(title, header, rows):
    print(f"\n{title}\n{markdown(header, rows)}")


# ------------------------------------------------------------------ runs
def _world_of(method):
    return "native" if method.startswith("native") else ("maximal" if "maximal" in method else "multibody")


def _config(method):
    """The method as a configuration of ``tradeoff.scenes.run_trial``: (name, kind, substeps)."""
    if method.startswith("plugin"):
        return method, "ccd", 0
    if method.startswith("substeps"):
        return method, "plain", int(method.split()[1])
    return method, {"multibody": "plain"}.get(_world_of(method), _world_of(method)), 0


def trial(world, method, seed, window, ccds):
    """One trial (the scene module's, untimed checks off): returns (mean us per step,
    [(projectile, aimed at, final centre)] of the tunneled).

    ``ccds`` keeps one BoxCCD per (world, method) across trials, so its stats add up."""
    cid = world[0]
    ccd = None
    if method.startswith("plugin"):
        if (cid, method) not in ccds:
            ccds[(cid, method)] = BoxCCD(cid, max_partial_steps=0) if "partial" in method else BoxCCD(cid)
        ccd = ccds[(cid, method)]
    r = run_trial(world, _config(method), seed, window, ccd, checks=False)
    return r["us"], r["tunnel"]


def build_worlds(n):
    """The scene of n boxes built three ways: multibody, maximal, and maximal for native CCD (a
    world of its own: restoreState leaves the native CCD settings alone)."""
    return {w: build(n, w != "multibody") for w in ("multibody", "maximal", "native")}


def close_worlds(worlds):
    for w in worlds.values():
        p.disconnect(w[0])


# ------------------------------------------------------------ small worlds
def _small_world(n, slide, substeps=0):
    """n settled 0.1 m cubes on a box ground (the first sliding at 10 m/s if slide), stepped
    in ``substeps`` substeps."""
    cid = p.connect(p.DIRECT)
    p.setGravity(0, 0, -G, physicsClientId=cid)
    p.setPhysicsEngineParameter(fixedTimeStep=DT, numSubSteps=substeps, physicsClientId=cid)
    def box(half, pos, mass):
        col = p.createCollisionShape(p.GEOM_BOX, halfExtents=half, physicsClientId=cid)
        return p.createMultiBody(mass, col, basePosition=pos, physicsClientId=cid)

    box((50.0, 50.0, 0.05), (0.0, 0.0, -0.05), 0.0)
    cubes = [box((HALF,) * 3, (0.3 * (k % 10), 0.3 * (k // 10), HALF), 1.0) for k in range(n)]
    for _ in range(200):
        p.stepSimulation(physicsClientId=cid)
    if slide:
        p.resetBaseVelocity(cubes[0], [10.0, 0.0, 0.0], [0.0, 0.0, 0.0], physicsClientId=cid)
    return cid, cubes


def _per_call(fn, calls):
    """us of this process's CPU time per call (other load on the machine does not count)."""
    t0 = time.process_time()
    for _ in range(calls):
        fn()
    return 1e6 * (time.process_time() - t0) / calls


def _resting_row(n, repeats, substeps=0):
    """n resting cubes; with substeps, BoxCCD reads them at each substep it takes: its reads are
    the substeps' N reads each."""
    cid, cubes = _small_world(n, False, substeps)
    ccd = BoxCCD(cid)
    times = {"plain": [], "reads": [], "plugin": []}
    reads = cubes * max(substeps, 1)
    for _ in range(repeats):  # in turn: a burst of load hits all three alike
        times["plain"].append(_per_call(lambda: p.stepSimulation(physicsClientId=cid), 1000))
        times["reads"].append(_per_call(lambda: [p.getBaseVelocity(b, physicsClientId=cid) for b in reads], 1000))
        times["plugin"].append(_per_call(ccd.step, 1000))
    best = {k: min(v) for k, v in times.items()}
    world = f"{n} resting" + (f", {substeps} substeps" if substeps else "")
    row = dict(world=world, plain_us=best["plain"], reads_us=best["reads"], plugin_us=best["plugin"],
               swept=ccd.stats.swept_boxes, steps=ccd.stats.steps)
    p.disconnect(cid)
    return row


def _slider_row(repeats):
    times, swept, steps = {"plain": [], "reads": [], "plugin": []}, 0, 0
    for _ in range(repeats):
        for method in times:
            cid, cubes = _small_world(1, True)
            ccd = BoxCCD(cid) if method == "plugin" else None
            fn = {"plain": lambda: p.stepSimulation(physicsClientId=cid),
                  "reads": lambda: (p.stepSimulation(physicsClientId=cid), p.getBaseVelocity(cubes[0],
                                                                                           physicsClientId=cid)),
                  "plugin": ccd.step if ccd else None}[method]
            times[method].append(_per_call(fn, 100))
            if ccd:
                swept, steps = swept + ccd.stats.swept_boxes, steps + ccd.stats.steps
            p.disconnect(cid)
    best = {k: min(v) for k, v in times.items()}
    # For the slider "reads" is timed with its step: the read alone is that less plain.
    return dict(world="1 sliding at 10 m/s", plain_us=best["plain"], reads_us=best["reads"] - best["plain"],
                plugin_us=best["plugin"], swept=swept, steps=steps)


def small_worlds(repeats, csv_path):
    """The small-world rows: resting 1 and 10 (and 10 in 4 substeps), one slider."""
    rows = [_resting_row(1, repeats), _resting_row(10, repeats), _resting_row(10, repeats, 4), _slider_row(repeats)]
    table = []
    for r in rows:
        r["overhead_in_reads"] = (r["plugin_us"] - r["plain_us"]) / r["reads_us"]
        r["ratio_to_plain"] = r["plugin_us"] / r["plain_us"]
        slider = r["world"].startswith("1 sliding")
        bound = ("x plain <= 3: " + ("within" if r["ratio_to_plain"] <= 3.0 else "ABOVE")) if slider else \
            ("overhead <= 2 reads: " + ("within" if r["overhead_in_reads"] <= 2.0 else "ABOVE"))
        table.append((r["world"], f"{r['plain_us']:.1f}", f"{r['reads_us']:.1f}", f"{r['plugin_us']:.1f}",
                      f"{r['overhead_in_reads']:.2f}", f"{r['ratio_to_plain']:.2f}", f"{r['swept']}/{r['steps']}",
                      bound))
    print_table(f"small worlds (us of CPU time per step, min over {repeats} repeats; reads: the N getBaseVelocity "
                "calls)",
                ("world", "plain", "reads", "plugin", "overhead / reads", "x plain", "swept/steps", "bound"),
                table)
    write_csv([{k: round(v, 3) if isinstance(v, float) else v for k, v in r.items()} for r in rows], csv_path)


# ------------------------------------------------------------------ scenes
def _quick_skip(n):
    return {"substeps 16"} | ({"plugin, no partial steps"} if n >= 1000 else set())


def scene_rows(n, seeds, window, res):
    """The table rows of one scene from {method: (us per trial, tunneled, stats)}, and its plugin phase rows."""
    rows, phase_rows = [], []
    plain = statistics.median(res["plain"][0])
    for m in METHODS:
        if m not in res:
            continue
        us, nt, stats = res[m]
        med = statistics.median(us)
        row = dict(n_boxes=n, method=m, us_per_step_median=round(med, 1), us_per_step_min=round(min(us), 1),
                   ratio_to_plain=round(med / plain, 3), tunneled=nt, shots=N_PROJ * len(seeds),
                   trials=len(seeds), window_steps=window)
        if stats is not None:
            steps = max(stats.steps, 1)
            for ph in PHASES:
                row[f"plugin_{ph}_us_per_step"] = round(1e6 * stats.seconds[ph] / steps, 1)
            for c in COUNTERS:
                row[f"plugin_{c}"] = getattr(stats, c)
            phase_rows.append((n, m, steps, stats))
        rows.append(row)
    return rows, phase_rows


def run_scenes(args, trials, window):
    """Every scene size: trials of every method. Returns (rows, plugin phase rows, tunnel log)."""
    n_trials = {n: (trials if n <= 100 else max(2, trials // 3)) for n in args.sizes}
    methods = {n: [m for m in METHODS if not (args.quick and m in _quick_skip(n))] for n in args.sizes}
    bar = tqdm(total=sum(n_trials[n] * len(methods[n]) for n in args.sizes), desc="runs", unit="trial")
    results, phase_rows, tunnel_log = [], [], []
    for n in args.sizes:
        seeds = [args.seed + t for t in range(n_trials[n])]
        win = window if n < 1000 else min(window, 72)  # the impacts come by step 61
        worlds = build_worlds(n)
        res = {m: ([], 0, None) for m in methods[n]}
        ccds = {}
        # Seeds outer, methods inner: a burst of load from elsewhere hits every method alike.
        for seed in seeds:
            for m in methods[n]:
                w = worlds[_world_of(m)]
                us, tun = trial(w, m, seed, win, ccds)
                st = ccds.get((w[0], m))
                res[m] = (res[m][0] + [us], res[m][1] + len(tun), st.stats if st else None)
                tunnel_log += [(n, m, seed) + tuple(t) for t in tun]
                bar.update(1)
        close_worlds(worlds)
        rows, phases = scene_rows(n, seeds, win, res)
        results += rows
        phase_rows += phases
    bar.close()
    return results, phase_rows, tunnel_log


def run_extra_seeds(seeds, window):
    """Tunneling only, more seeds: the 10-box scene (the pile is off the projectiles' paths).
    Returns [(method, tunneled, shots, median us, stats)] and the tunnel log."""
    extra, tunnel_log = [], []
    worlds = build_worlds(10)
    bar = tqdm(total=len(seeds) * len(EXTRA_METHODS), desc="extra seeds", unit="trial")
    ccds = {}
    for m in EXTRA_METHODS:
        w = worlds[_world_of(m)]
        us, nt = [], 0
        for seed in seeds:
            u, tun = trial(w, m, seed, window, ccds)
            us.append(u)
            nt += len(tun)
            tunnel_log += [("10 (extra)", m, seed) + tuple(t) for t in tun]
            bar.update(1)
        st = ccds.get((w[0], m))
        extra.append((m, nt, N_PROJ * len(seeds), statistics.median(us), st.stats if st else None))
    bar.close()
    close_worlds(worlds)
    return extra, tunnel_log


# ------------------------------------------------------------------ reports
def print_scenes(results, phase_rows):
    rows = [(r["n_boxes"], r["method"], f"{r['us_per_step_median']:.0f}", f"{r['us_per_step_min']:.0f}",
             f"{r['ratio_to_plain']:.2f}", f"{r['tunneled']}/{r['shots']}") for r in results]
    print_table("time per step and tunneling (us/step: median (and min) over trials of the mean over the window)",
                ("boxes", "method", "us/step", "min", "x plain", "tunneled/shots"), rows)
    prow = []
    for n, m, steps, st in phase_rows:
        per = {ph: 1e6 * st.seconds[ph] / steps for ph in PHASES}
        sweep = sum(per.values())
        prow.append((n, m, steps, *(f"{per[ph]:.0f}" for ph in PHASES), f"{sweep:.0f}", st.swept_boxes,
                     st.candidate_pairs, st.solver_rows, st.contacts, st.rewinds, st.partial_steps))
    print_table("plugin phases (us per step, mean over all trials) and counters (totals over all trials)",
                ("boxes", "method", "steps", "state", "broad", "solve", "rewind", "sweep total",
                 "swept", "pairs", "rows", "contacts", "rewinds", "partial steps"), prow)


def print_extra(extra, seeds, window):
    """The extra seeds' table; returns their CSV rows."""
    print_table(f"tunneling over {len(seeds)} more seeds ({seeds[0]}..{seeds[-1]}), 10 boxes",
                ("method", "tunneled/shots", "us/step", "CCD rewinds", "partial steps"),
                [(m, f"{nt}/{shots_}", f"{us:.0f}", st.rewinds if st else "", st.partial_steps if st else "")
                 for m, nt, shots_, us, st in extra])
    return [dict(n_boxes=10, method=f"{m} [extra seeds]", us_per_step_median=round(us, 1), tunneled=nt, shots=shots_,
                 trials=len(seeds), window_steps=window) for m, nt, shots_, us, _st in extra]


def _zero_tunneling_verdict(plug, zero):
    if plug["tunneled"]:
        return f"tunneled {plug['tunneled']}/{plug['shots']}: no"
    if not zero:
        return (f"{plug['us_per_step_median']:.0f} us at zero tunneling; no substep count up to "
                f"{SUBSTEPS[-1]} reaches zero: yes")
    best = min(zero, key=lambda r: r["us_per_step_median"])
    ok = plug["us_per_step_median"] < best["us_per_step_median"]
    return (f"{plug['us_per_step_median']:.0f} us vs cheapest zero-tunneling {best['method']} "
            f"{best['us_per_step_median']:.0f} us: {'yes' if ok else 'no'}")


def print_bounds(results, sizes):
    print("\nbounds")
    by = {(r["n_boxes"], r["method"]): r for r in results}
    for pm in PLUGINS:
        if (100, "plain") in by and (100, pm) in by:
            ov = by[(100, pm)]["us_per_step_median"] / by[(100, "plain")]["us_per_step_median"] - 1.0
            print(f"  {pm} overhead at 100 boxes: {100 * ov:.0f} % of a plain step (bound 30 %): "
                  f"{'within' if ov <= 0.30 else 'ABOVE'}")
    for n in sizes:
        zero = [by[(n, f"substeps {k}")] for k in SUBSTEPS
                if (n, f"substeps {k}") in by and by[(n, f"substeps {k}")]["tunneled"] == 0]
        for pm in PLUGINS:
            if (n, pm) in by:  # --quick skips some
                print(f"  {n} boxes, {pm} at zero tunneling cheaper than substepping at zero: "
                      f"{_zero_tunneling_verdict(by[(n, pm)], zero)}")


def print_tunneled(tunnel_log, tunneled_csv):
    shown = [t for t in tunnel_log if t[1].startswith("plugin") or t[1] in ("native CCD (maximal)", "substeps 8",
                                                                               "substeps 16")]
    print("\ntunneled with plugin, native CCD, substeps 8 or 16 (boxes, method, seed, projectile, aimed at, "
          f"final centre){'' if shown else ': none'}")
    for n, m, seed, i, kind, pos in shown:
        print(f"  {n}, {m}, seed {seed}, #{i}, {kind}, ({pos[0]:.3f}, {pos[1]:.3f}, {pos[2]:.3f})")
    print(f"(every tunneled projectile: {tunneled_csv})")


def write_csvs(results, tunnel_log, csv_path, tunneled_csv):
    write_csv(results, csv_path)
    with open(tunneled_csv, "w", newline="") as f:
        wr = csv.writer(f)
        wr.writerow(("n_boxes", "method", "seed", "projectile", "aimed_at", "x", "y", "z"))
        for n, m, seed, i, kind, pos in tunnel_log:
            wr.writerow((n, m, seed, i, kind) + tuple(round(float(x), 4) for x in pos))
    print(f"\nwritten: {csv_path}")


# ------------------------------------------------------------------ main
def parse_args(argv):
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--quick", action="store_true",
                    help="2 trials, 64-step window, no substeps 16 (nor plugin, no partial steps, at 1000 boxes)")
    ap.add_argument("--seed", type=int, default=2024)
    ap.add_argument("--trials", type=int, default=None, help="trials per N (default 6; 2 with --quick)")
    ap.add_argument("--window", type=int, default=None, help="timed steps per trial (default 120; 64 with --quick)")
    ap.add_argument("--extra-seeds", type=int, default=None,
                    help="more seeds for a tunneling-only table at 10 boxes (default 100; 20 with --quick)")
    ap.add_argument("--sizes", type=int, nargs="+", default=[10, 100, 1000])
    ap.add_argument("--csv", default=os.path.join(os.path.dirname(os.path.abspath(__file__)), "results", "plugin.csv"))
    args = ap.parse_args(argv)
    args.trials = args.trials or (2 if args.quick else 6)
    args.window = args.window or (64 if args.quick else 120)
    if args.extra_seeds is None:
        args.extra_seeds = 20 if args.quick else 100
    return args


def main(argv=None):
    args = parse_args(argv)
    results_dir = os.path.dirname(args.csv)
    print(f"machine: {platform.platform()}, {platform.processor() or platform.machine()}, "
          f"python {platform.python_version()}, pybullet API {p.getAPIVersion()}, numpy {np.__version__}")
    print(f"code: {code_version()}")
    print(f"seed {args.seed}, window {args.window} steps of 1/240 s (at most 72 from 1000 boxes on), "
          f"{N_PROJ} projectiles per trial")

    small_worlds(3 if args.quick else 9, os.path.join(results_dir, "plugin_small.csv"))
    results, phase_rows, tunnel_log = run_scenes(args, args.trials, args.window)
    extra_seeds = [args.seed + 1000 + t for t in range(args.extra_seeds)]
    extra, extra_log = run_extra_seeds(extra_seeds, args.window) if extra_seeds else ([], [])

    print_scenes(results, phase_rows)
    if extra:
        results += print_extra(extra, extra_seeds, args.window)
    print_bounds(results, args.sizes)
    tunneled_csv = os.path.join(results_dir, "plugin_tunneled.csv")
    print_tunneled(tunnel_log + extra_log, tunneled_csv)
    write_csvs(results, tunnel_log + extra_log, args.csv, tunneled_csv)


if __name__ == "__main__":
    main()
