"""Cost / accuracy trade-off of the BoxCCD plugin's knobs, beside substepping and native CCD.

What it measures
----------------
The scene and the shots are those of ``benchmarks/plugin.py`` (imported, not
copied): ``--boxes`` dynamic 0.1 m cubes (default 100: a settled pile of 96 plus 4
projectiles) over a static ground (top face z = 0) and a static 1 cm wall (plane
x = 0); per seeded trial 2 projectiles are fired at the wall and 2 down at the
ground at 50..150 m/s with a random spin (``plugin.shots(seed)``), and a window of
``--window`` steps of 1/240 s (default 120) is run. Every configuration sees the
same settled pile (``p.saveState``/``p.restoreState``) and the same shots; trials
run seeds outer, configurations inner (a burst of load from elsewhere hits all).

Configurations (one knob at a time around the default):

* ``BoxCCD default`` (sweep_threshold 0.25, fit_tolerance 0.05, penetration 2e-7),
* ``sweep_threshold`` 0.05, 0.5, 1, 2, 4, 8 (a box is swept when its fastest point
  moves more than this fraction of its smallest extent per step; the projectiles
  move 2..6.3 extents per step, so 4 sweeps only the faster shots and 8 none),
* ``fit_tolerance`` 0.005, 0.5 (rotation fit split into 2, 4, .. pieces until its
  error is below this fraction of the smallest half extent),
* ``penetration`` (the rewind skin) 2e-8, 2e-6 m,
* ``exact_time`` True (the whole world stops at the step's earliest contact and the
  rest of the step is simulated),
* ``reference`` = BoxCCD with fit_tolerance 1e-4 (the fine reference of the
  contact times; itself in the table),
* pybullet ``plain``, ``substeps`` 2, 4, 8, 16, 32 (``numSubSteps``), and, on the same
  scene built with maximal coordinates, ``plain (maximal)`` and ``native CCD
  (maximal)`` (``ccdSweptSphereRadius`` 0.025, ``contactProcessingThreshold`` 0, as
  in plugin.py).

Metrics per configuration:

* ``us/step``: per trial the mean wall time of a step over the window (only the
  step: the checks below are untimed), then the median over trials,
* ``tunneled/shots``: plugin.py's test (centre below the ground, or through the
  wall's face and beyond it, at the end of the window),
* contact-time error (BoxCCD only): for each projectile its first CCD event against
  the ground or the wall that begins inside the step (``not ev.initial``), at time
  step index * dt + ``ev.time``, against the same projectile's first such event in
  the reference run of the same seed; median and max |dt| in seconds over the
  projectiles both runs report within one step (1/240 s) of each other, and
  ``matched/ref`` (a configuration that does not sweep a shot reports no event for
  it, or only a later contact, which is not matched),
* rewind pose error (BoxCCD only): right after each ``ccd.step()`` returning a
  rewound first-touch event of a projectile against the ground or wall,
  ``p.getClosestPoints(body_a, body_b, 0.01, link_a, link_b)`` minimum distance; the
  worst (largest |d|) is reported, and how many fall outside the expected band
  [-1e-6, 0.001 + 1e-6] m (collision margin 0.001). In exact_time mode the rest of
  the step is simulated after the rewind, so this is the pose after that,
* end-of-step penetration (all configurations): after every step, the minimum
  ``p.getClosestPoints(projectile, ground or wall, 0)`` distance over the
  projectiles; the deepest (most negative) value over all steps and trials. For
  substeps / native CCD this is their "pose error"; a tunneling configuration can
  show little here, since a box that is already through is no longer inside.
* ``pieces/pair``: the plugin's ``solver_rows / candidate_pairs`` (how many fit pieces
  the rotation tolerance asked for).

Reading it: the reported contact time comes from a refit of Bullet's exact path
over the window the conservative fit found, so ``fit_tolerance`` changes the cost
and how many pieces are solved, not the answer. A pair that already touches when
a step begins and presses deeper is let in up to half the thinner box's smallest
half extent before the plugin rewinds it (see ``BoxCCD._rewind_time``), which
bounds what the end-of-step penetration of BoxCCD can show (2.5 mm at the wall,
5 mm at the ground here).

Outputs: a markdown table (stdout), ``benchmarks/results/tradeoff.csv`` and
``docs/tradeoff.png`` (Pareto plots, x = us/step, log: left the tunneling rate,
middle the deepest end-of-step penetration, right the max contact-time error of
the BoxCCD configurations; the grey staircase is the Pareto front; the default is
the star; points carry the configuration's number, listed beside the plots).
Every BoxCCD tunneled projectile is printed with its seed and configuration, and
its launch reach (|v| dt / extent, what ``sweep_threshold`` is compared with).

Run
---
    cd /work/main && PYTHONPATH=/work/main python3 benchmarks/tradeoff.py            # < 5 min
    cd /work/main && PYTHONPATH=/work/main python3 benchmarks/tradeoff.py --quick    # < 1 min

Options: ``--seed`` (default 2024), ``--trials`` (default 10; 2 with --quick),
``--window`` (default 120; 72 with --quick: the impacts come by step 61),
``--boxes`` (default 100), ``--csv``, ``--png``. The machine may carry other load:
read the medians. This is a benchmark, not a test: it asserts nothing about timings.
"""

from __future__ import annotations

import argparse
import csv
import math
import os
import statistics
import sys
import time

import numpy as np
import pybullet as p
from tqdm import tqdm

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import plugin as P  # noqa: E402  (scene, shots and tunneling checks of benchmarks/plugin.py)

from bullet_boxccd import BoxCCD  # noqa: E402

HERE = os.path.dirname(os.path.abspath(__file__))
ROOT = os.path.dirname(HERE)
GROUND, WALL = 0, 1  # body ids of plugin.build's static ground and wall (created first)
MARGIN = 0.001  # pybullet's collision margin for boxes
BAND = (-1e-6, MARGIN + 1e-6)
REF_FIT = 1e-4

DEFAULT = dict(sweep_threshold=0.25, fit_tolerance=0.05, penetration=2e-7, exact_time=False)


def configs(quick):
    """(name, kind, BoxCCD kwargs or substep count)."""
    out = [("BoxCCD default", "ccd", {})]
    for s in ((0.05, 1.0, 4.0, 8.0) if quick else (0.05, 0.5, 1.0, 2.0, 4.0, 8.0)):
        out.append((f"sweep_threshold={s:g}", "ccd", dict(sweep_threshold=s)))
    for f in (0.005, 0.5):
        out.append((f"fit_tolerance={f:g}", "ccd", dict(fit_tolerance=f)))
    for d in (2e-8, 2e-6):
        out.append((f"penetration={d:g}", "ccd", dict(penetration=d)))
    out.append(("exact_time", "ccd", dict(exact_time=True)))
    out.append((f"reference (fit_tolerance={REF_FIT:g})", "ref", dict(fit_tolerance=REF_FIT)))
    out.append(("plain", "plain", 0))
    for k in ((2, 8, 32) if quick else (2, 4, 8, 16, 32)):
        out.append((f"substeps {k}", "plain", k))
    out.append(("plain (maximal)", "maximal", 0))
    out.append(("native CCD (maximal)", "native", 0))
    return out


def _min_dist(cid, a, b, dist, la=-1, lb=-1):
    pts = p.getClosestPoints(a, b, dist, linkIndexA=la, linkIndexB=lb, physicsClientId=cid)
    return min((c[8] for c in pts), default=None)


def run_trial(world, cfg, seed, window, ccd):
    """One trial of one configuration (mirrors plugin.run_trial, with the extra measurements).

    Returns dict(us, tunnel=[(projectile, kind, centre)], first={projectile: time}, pose=[d],
    deepest=float)."""
    name, kind, arg = cfg
    cid, state, proj, _ = world
    p.restoreState(state, physicsClientId=cid)
    k = arg if kind == "plain" else 0
    p.setPhysicsEngineParameter(fixedTimeStep=P.DT, numSubSteps=k, physicsClientId=cid)
    sh = P.shots(seed)
    for b, (pos, q, v, w, _) in zip(proj, sh):
        p.resetBasePositionAndOrientation(b, pos.tolist(), q.tolist(), physicsClientId=cid)
        p.resetBaseVelocity(b, v.tolist(), w.tolist(), physicsClientId=cid)
        if kind == "native":
            p.changeDynamics(b, -1, ccdSweptSphereRadius=P.NATIVE_RADIUS, contactProcessingThreshold=0.0,
                             physicsClientId=cid)
    if ccd is not None:
        step = ccd.step
    else:
        def step():
            p.stepSimulation(physicsClientId=cid)
            return ()
    index = {b: i for i, b in enumerate(proj)}
    total, first, pose, deepest = 0.0, {}, [], math.inf
    prev = [P._centre(cid, b) for b in proj]
    through_wall = [False] * len(proj)
    for s in range(window):
        t0 = time.perf_counter()
        events = step()
        total += time.perf_counter() - t0
        # untimed from here
        for ev in events:
            if ev.initial:
                continue
            pair = {ev.body_a, ev.body_b}
            static = pair & {GROUND, WALL}
            moving = [index[b] for b in pair if b in index]
            if not static or len(moving) != 1:
                continue
            i = moving[0]
            if i not in first:
                first[i] = s * P.DT + ev.time
            if ev.rewound:
                d = _min_dist(cid, ev.body_a, ev.body_b, 0.01, ev.link_a, ev.link_b)
                pose.append(0.01 if d is None else d)  # nothing within 1 cm: at least 1 cm off
        for i, b in enumerate(proj):
            c = P._centre(cid, b)
            through_wall[i] |= P._crosses_wall(prev[i], c)
            prev[i] = c
            for st in (GROUND, WALL):
                d = _min_dist(cid, b, st, 0.0)
                if d is not None:
                    deepest = min(deepest, d)
    tunnel = [(i, sh[i][4], tuple(c)) for i, c in enumerate(prev)
              if (through_wall[i] and c[0] > 0.0) or P._below_ground(c)]
    return dict(us=1e6 * total / window, tunnel=tunnel, first=first, pose=pose, deepest=deepest)


def pareto(xs, ys):
    """Indices of the non-dominated points (lower x and lower y are better), by x."""
    pts = sorted(range(len(xs)), key=lambda i: (xs[i], ys[i]))
    front, best = [], math.inf
    for i in pts:
        if ys[i] < best:
            front.append(i)
            best = ys[i]
    return front


def plot(rows, path):
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    from matplotlib.ticker import LogLocator, NullFormatter

    panels = [
        ("tunneled / shots", lambda r: r["tunnel_rate"], "linear", None, None),
        ("deepest end-of-step penetration (m)", lambda r: max(-r["deepest_penetration_m"], 0.0), "log", 1e-9,
         "0 drawn at 1e-9 m"),
        ("max contact-time error vs reference (s)", lambda r: r.get("time_err_max_s"), "log", 1e-12,
         "BoxCCD configurations only; 0 drawn at 1e-12 s"),
    ]
    colors = {"ccd": "tab:blue", "ref": "tab:cyan", "plain": "tab:red", "maximal": "tab:orange",
              "native": "tab:green"}
    number = {r["config"]: k + 1 for k, r in enumerate(rows)}
    fig, axes = plt.subplots(1, 3, figsize=(17, 6), gridspec_kw=dict(right=0.82))
    for ax, (label, get, scale, floor, note) in zip(axes, panels):
        pts = [(r, get(r)) for r in rows if get(r) not in (None, "")]
        if floor is not None:
            pts = [(r, max(float(y), floor)) for r, y in pts]
        xs = [r["us_per_step_median"] for r, _ in pts]
        ys = [float(y) for _, y in pts]
        front = pareto(xs, ys)
        if len(front) > 1:
            ax.step([xs[i] for i in front], [ys[i] for i in front], where="post", color="grey", alpha=0.6,
                    zorder=1, label="Pareto front")
        # Labels: the configuration's number; points that share a spot stack their numbers.
        def norm(v, lo, hi, log):
            return (math.log10(v) - math.log10(lo)) / max(math.log10(hi / lo), 1e-12) if log else \
                (v - lo) / max(hi - lo, 1e-12)
        groups = []  # [(u, v), [(x, y, number)]]: points this close (axes fractions) share a label
        for (r, y), x in zip(pts, xs):
            star = r["config"] == "BoxCCD default"
            ax.scatter(x, y, s=220 if star else 45, marker="*" if star else "o", color=colors[r["kind"]],
                       edgecolor="k", linewidth=0.5, zorder=3 + star)
            uv = (norm(x, min(xs), max(xs), True), norm(y, min(ys), max(ys), scale == "log"))
            for g in groups:
                if abs(g[0][0] - uv[0]) < 0.12 and abs(g[0][1] - uv[1]) < 0.04:
                    g[1].append((x, y, number[r["config"]]))
                    break
            else:
                groups.append((uv, [(x, y, number[r["config"]])]))
        for _, group in groups:
            x, y, _ = group[0]
            ax.annotate(",".join(str(n) for _, _, n in sorted(group, key=lambda g: g[2])), (x, y), fontsize=7,
                        xytext=(4, 4), textcoords="offset points")
        ax.set_xscale("log")
        ax.set_yscale(scale)
        ax.xaxis.set_minor_formatter(NullFormatter())
        ax.xaxis.set_major_locator(LogLocator(base=10, subs=(1.0, 2.0, 5.0)))
        ax.xaxis.set_major_formatter(matplotlib.ticker.FuncFormatter(lambda v, _: f"{v:g}"))
        ax.set_xlabel("time per step (us, median over trials)")
        ax.set_ylabel(label)
        ax.grid(True, which="both", alpha=0.3)
        if note:
            ax.set_title(note, fontsize=8)
    handles = [plt.Line2D([], [], marker="o", ls="", color=c, label=k) for k, c in
               (("BoxCCD", colors["ccd"]), ("BoxCCD reference", colors["ref"]),
                ("pybullet plain / substeps", colors["plain"]), ("plain (maximal)", colors["maximal"]),
                ("native CCD (maximal)", colors["native"]))]
    handles.append(plt.Line2D([], [], marker="*", ls="", color=colors["ccd"], markersize=12, label="BoxCCD default"))
    handles.append(plt.Line2D([], [], color="grey", alpha=0.6, label="Pareto front"))
    fig.legend(handles=handles, loc="upper center", ncol=7, fontsize=9)
    key = "\n".join(f"{number[r['config']]:>2}  {r['config']}" for r in rows)
    fig.text(0.835, 0.5, key, fontsize=8, family="monospace", va="center")
    fig.subplots_adjust(left=0.04, right=0.82, wspace=0.25, top=0.88, bottom=0.1)
    os.makedirs(os.path.dirname(os.path.abspath(path)), exist_ok=True)
    fig.savefig(path, dpi=110)
    plt.close(fig)


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--quick", action="store_true",
                    help="2 trials of 72 steps; sweep_threshold 0.05, 1, 4, 8 only; substeps 2, 8, 32 only")
    ap.add_argument("--seed", type=int, default=2024)
    ap.add_argument("--trials", type=int, default=None)
    ap.add_argument("--window", type=int, default=None)
    ap.add_argument("--boxes", type=int, default=100)
    ap.add_argument("--csv", default=os.path.join(HERE, "results", "tradeoff.csv"))
    ap.add_argument("--png", default=os.path.join(ROOT, "docs", "tradeoff.png"))
    args = ap.parse_args(argv)
    trials = args.trials or (2 if args.quick else 10)
    window = args.window or (72 if args.quick else 120)
    cfgs = configs(args.quick)
    seeds = [args.seed + t for t in range(trials)]
    print(f"code: {P._code_version()}")
    print(f"{args.boxes} boxes, {trials} trials (seeds {seeds[0]}..{seeds[-1]}), window {window} steps of 1/240 s, "
          f"{P.N_PROJ} projectiles per trial")

    worlds = {w: P.build(args.boxes, w != "multibody") for w in ("multibody", "maximal", "native")}
    world_of = {"ccd": "multibody", "ref": "multibody", "plain": "multibody", "maximal": "maximal",
                "native": "native"}
    ccds = {c[0]: BoxCCD(worlds["multibody"][0], **{**DEFAULT, **c[2]}) for c in cfgs if c[1] in ("ccd", "ref")}
    res = {c[0]: [] for c in cfgs}
    t_start = time.perf_counter()
    with tqdm(total=len(seeds) * len(cfgs), desc="runs", unit="trial") as bar:
        for seed in seeds:
            for c in cfgs:
                r = run_trial(worlds[world_of[c[1]]], c, seed, window, ccds.get(c[0]))
                res[c[0]].append((seed, r))
                bar.update(1)
    for w in worlds.values():
        p.disconnect(w[0])
    wall = time.perf_counter() - t_start

    ref_name = next(c[0] for c in cfgs if c[1] == "ref")
    ref_first = {(seed, i): t for seed, r in res[ref_name] for i, t in r["first"].items()}
    rows, tunnel_log = [], []
    for name, kind, _ in cfgs:
        trs = res[name]
        us = [r["us"] for _, r in trs]
        nt = sum(len(r["tunnel"]) for _, r in trs)
        tunnel_log += [(name, seed) + t for seed, r in trs for t in r["tunnel"]]
        row = dict(config=name, kind=kind, us_per_step_median=round(statistics.median(us), 1),
                   us_per_step_min=round(min(us), 1), tunneled=nt, shots=P.N_PROJ * len(trs),
                   tunnel_rate=nt / (P.N_PROJ * len(trs)))
        deepest, d_seed = min((r["deepest"], seed) for seed, r in trs)
        row["deepest_penetration_m"] = deepest if math.isfinite(deepest) else 0.0
        row["deepest_seed"] = d_seed if math.isfinite(deepest) else ""
        if kind in ("ccd", "ref"):
            errs = [abs(r["first"][i] - ref_first[(seed, i)]) for seed, r in trs for i in r["first"]
                    if (seed, i) in ref_first]
            errs = [e for e in errs if e <= P.DT]  # farther: another contact (this one missed the first)
            row["time_matched"] = len(errs)
            row["time_ref_events"] = len(ref_first)
            row["time_err_median_s"] = statistics.median(errs) if errs else ""
            row["time_err_max_s"] = max(errs) if errs else ""
            pose = [d for _, r in trs for d in r["pose"]]
            row["pose_checks"] = len(pose)
            row["pose_err_worst_m"] = max(pose, key=abs) if pose else ""
            row["pose_out_of_band"] = sum(not (BAND[0] <= d <= BAND[1]) for d in pose)
            st = ccds[name].stats
            row["pieces_per_pair"] = round(st.solver_rows / st.candidate_pairs, 3) if st.candidate_pairs else ""
            row["swept_per_step"] = round(st.swept_boxes / max(st.steps, 1), 3)
            row["rewinds"] = st.rewinds
        rows.append(row)

    def f(x, fmt):
        return "" if x in ("", None) else format(x, fmt)

    table = [(r["config"], f"{r['us_per_step_median']:.0f}", f"{r['tunneled']}/{r['shots']}",
              f(r.get("time_err_median_s"), ".1e"), f(r.get("time_err_max_s"), ".1e"),
              f"{r['time_matched']}/{r['time_ref_events']}" if "time_matched" in r else "",
              f(r.get("pose_err_worst_m"), ".2e"),
              f"{r['pose_out_of_band']}/{r['pose_checks']}" if "pose_checks" in r else "",
              f"{r['deepest_penetration_m']:.2e}", f(r.get("pieces_per_pair"), ".2f"))
             for r in rows]
    P.print_table(f"trade-off, {args.boxes} boxes, {trials} trials x {window} steps "
                  f"(us/step: median over trials of the mean step; errors against '{ref_name}')",
                  ("config", "us/step", "tunneled/shots", "|dt| median (s)", "|dt| max (s)", "matched/ref",
                   "rewind pose worst (m)", "pose outside band", "deepest end-of-step (m)", "pieces/pair"),
                  table)
    print(f"\nexpected rewind pose band: [{BAND[0]:g}, {BAND[1]:g}] m; 'deepest end-of-step' is the minimum "
          "getClosestPoints distance of a projectile to the ground or wall after any step (< 0: inside)")
    shown = [t for t in tunnel_log if t[0] in ccds]
    print("\nBoxCCD configurations that tunneled: seed#projectile (aimed at, launch reach = |v| dt / extent, "
          f"the quantity sweep_threshold is compared with){'' if shown else ': none'}")
    for name in ccds:
        mine = [t for t in shown if t[0] == name]
        if mine:
            items = [f"{seed}#{i} ({kind[0]}, {np.linalg.norm(P.shots(seed)[i][2]) * P.DT / (2 * P.HALF):.2f})"
                     for _, seed, i, kind, _ in mine]
            print(f"  {name}: {len(mine)}: " + ", ".join(items))

    os.makedirs(os.path.dirname(os.path.abspath(args.csv)), exist_ok=True)
    keys = list(dict.fromkeys(k for r in rows for k in r))
    with open(args.csv, "w", newline="") as fh:
        wr = csv.DictWriter(fh, fieldnames=keys + ["boxes", "trials", "window_steps"])
        wr.writeheader()
        for r in rows:
            wr.writerow({**r, "boxes": args.boxes, "trials": trials, "window_steps": window})
    plot(rows, args.png)
    print(f"\nwritten: {args.csv}, {args.png} (runs took {wall:.0f} s)")


if __name__ == "__main__":
    main()
