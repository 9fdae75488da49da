"""Crowds of fast boxes in a closed room with thin static walls: escapes, frozen boxes, overlaps, cost.

A scene (seeded, ``params(seed)``): a closed room (6 static box walls of one random half
thickness from 1 mm to 3 cm, plus a thin floor shelf and a thin vertical partition of that
thickness) holding up to 50-300 random boxes (cubes, plates and rods, from a centimetre to
metres, randomly turned, placed apart; a box that finds no free place is left out) thrown
at up to 20, 60, 150 or 300 m/s in random directions and spinning (each axis a normal
draw of up to 20 rad/s standard deviation), restitution 0, 0.3 or 0.8 (walls 0.5), no
damping, every box 1 kg (so no heavy-on-light sandwich), in maximal coordinates
(``useMaximalCoordinates=True``, so pybullet's gyroscopic divergence is not involved;
``--multibody`` for multibodies, which it spins up to their velocity clamp),
with gravity in most seeds, at a step dt of 1/240, 1/60 or 1/30 s, ``numSubSteps`` 1, 2
or 4, and the room at 0, 1e3 or 1e4 m from the origin. The default scenes: seed 4 at its
own dt (214 boxes thrown at up to 300 m/s in a room 34.6 m wide with 5.8 cm walls,
1/30 s, 70 steps) and seed 60 at dt = 1/15 s (87 boxes at up to 300 m/s in a room 9.4 m
wide with 2.4 mm walls, numSubSteps 4, 1e4 m from the origin, 83 steps).

Methods, each on the same scene:

* ``plain``: pybullet's own ``stepSimulation`` at dt (not the journaling wrapper that importing
  bullet_boxccd installs),
* ``boxccd``: ``BoxCCD(cid).step()`` (defaults); ``--knob k=v`` adds a method ``boxccd k=v``
  with those keyword arguments (``--knob a=1,b=2`` for several at once; repeatable),
* ``ref``: plain pybullet at dt/64 (without ``numSubSteps``), 64 fine steps per step of dt.
  It is the reference for freezing and for overlaps, **not for escapes**: at 300 m/s a fine
  step of 1/960 s (seed 60 at 15 Hz) moves a box 0.31 m, far more than a 2.4 mm wall, so
  the reference itself lets boxes through thin walls, and its escapes are reported as such.

Figures, read after every step of dt (the reference: every 64 fine steps), per method and scene:

* ``escapes``: boxes whose centre was found outside the room (more than 1 cm past a wall's
  inner face) at some step end: through a wall. (Passing through the internal plates is not
  counted.)
* ``frozen body-steps``: a box faster than 0.2 m a step at the start of a step that moves
  less than 10 % of speed * dt in it while its velocity changes by less than 5 %: time
  stands still for it (it keeps its velocity and does not move). ``longest run``: the most
  consecutive steps one box stayed frozen; ``boxes frozen 3+``: boxes frozen for 3 or more
  consecutive steps.
* ``ends > 1 cm`` / ``> 5 cm``: step ends where some pair is deeper than 1 cm / 5 cm;
  ``deepest``: the deepest such overlap (m). The pairs are those pybullet has contacts
  for (``getContactPoints``), their overlap where the step ends ``getClosestPoints``' in
  the shallower of its two orders (a contact's own depth is the one pybullet found before
  it moved the bodies in its step: a wall teleported 4 cm a step shows 4 cm there).
* ``us/step``: the mean wall time of a step of dt (the ``step()`` / ``stepSimulation`` calls
  only: building the scene and the per-step reads of every body are not timed);
  ``x plain``: its ratio to ``plain`` on the same scene in the same run.
* ``BoxCCDWarnings``: BoxCCDWarnings given during the run, BoxCCD's construction included
  (all are recorded, none is filtered out; every kind of warning of any category is
  printed under the scene's table with its count and an example; the CSV also counts
  other warnings).

A run that raises or whose positions turn non-finite is reported (``error``), its figures
up to then kept.

Outputs: a markdown table per scene on stdout, ``benchmarks/results/crowd.csv`` (``--csv``;
one row per scene x method) and ``docs/crowd.png`` (``--png``; per scene, the boxes out of
the room so far, the boxes frozen in the step and the deepest overlap at every step end,
per method). ``--quick`` writes
``crowd_quick.csv`` and ``crowd_quick.png`` instead.

Run
---
    python benchmarks/crowd.py                  # seeds 4 and 60@15, ~10 s on 2 cores (one process)
    python benchmarks/crowd.py --quick          # ~5 s: the same scenes, 25 steps each
    python benchmarks/crowd.py --knob max_partial_steps=32              # ~25 s
    python benchmarks/crowd.py --seeds 1,2,3 --steps 40 --png ''
    python benchmarks/crowd.py --multibody --no-ref --csv '' --png ''     # ~1 min

``--seeds`` takes seeds, each at its own dt or, written ``seed@H``, at dt = 1/H s.
Runs are serial (one process), so timings are not shared with another run.

This is a benchmark, not a test: it asserts nothing.
"""

from __future__ import annotations

import argparse
import math
import os
import platform
import re
import sys
import textwrap
import time
import warnings
from collections import Counter

os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")

import numpy as np  # noqa: E402
import pybullet as p  # noqa: E402

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from _report import code_version, knobs, write_csv  # noqa: E402

# Imported before any world is built: it wraps pybullet's world-changing calls (its journal
# of user moves), which BoxCCD needs to have seen.
from bullet_boxccd import BoxCCD, BoxCCDWarning  # noqa: E402
from bullet_boxccd.validate.tables import markdown  # noqa: E402

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
RAW_STEP = getattr(p, "_bullet_boxccd_originals", {}).get("stepSimulation", p.stepSimulation)
FINE = 64  # the reference's fine steps per step of dt
DEFAULT_SEEDS = "4,60@15"
QUICK_STEPS = 25


# ------------------------------------------------------------------- scenes
def params(seed):
    """Scene parameters drawn from a random generator seeded with ``seed``."""
    r = np.random.default_rng(seed)
    P = dict(seed=seed)
    P["n"] = int(r.integers(50, 301))
    P["L"] = float(r.uniform(4, 30))  # room half size
    P["wall_t"] = float(10 ** r.uniform(-3, -1.5))  # wall half thickness 1 mm .. 3 cm
    P["dt"] = float(r.choice([1 / 240, 1 / 60, 1 / 30]))
    P["vmax"] = float(r.choice([20, 60, 150, 300]))
    P["offset"] = float(r.choice([0, 1e3, 1e4]))
    P["nsub"] = int(r.choice([1, 1, 1, 2, 4]))
    P["steps"] = int(r.integers(40, 90))
    P["gravity"] = bool(r.random() < 0.7)
    P["rseed"] = int(r.integers(1 << 30))
    P["equal_mass"] = True
    return P


def build(P, cid):
    """(room centre, plates [(id, centre, half extents, normal axis)], box ids) in client cid."""
    r = np.random.default_rng(P["rseed"])
    L, t = P["L"], P["wall_t"]
    origin = np.array([P["offset"], -P["offset"], 0.5 * P["offset"]])

    def static(half, at):
        shape = p.createCollisionShape(p.GEOM_BOX, halfExtents=list(half), physicsClientId=cid)
        return p.createMultiBody(0, shape, basePosition=list(at), physicsClientId=cid)

    statics = []
    for ax in range(3):
        for sgn in (-1, 1):
            he = [L + t] * 3
            he[ax] = t
            pos = origin.copy()
            pos[ax] += sgn * (L + t)
            statics.append(static(he, pos))
    # internal thin plates: a floor shelf and a vertical partition
    plates = []
    for ph, pp, ax in (([0.6 * L, 0.6 * L, t], origin + np.array([0.2 * L, 0, -0.3 * L]), 2),
                       ([t, 0.5 * L, 0.5 * L], origin + np.array([-0.4 * L, 0.1 * L, 0.2 * L]), 0)):
        plates.append((static(ph, pp), pp, np.array(ph), ax))
        statics.append(plates[-1][0])
    boxes, placed = [], []
    for _ in range(P["n"]):
        kind = r.random()
        s = 10 ** r.uniform(-2, math.log10(max(0.02, min(1.0, 0.05 * L))))
        if kind < 0.6:
            he = s * r.uniform(0.5, 1.5, 3)  # cubes
        elif kind < 0.8:
            he = s * np.array([1, 10 ** r.uniform(0, 1.5), 10 ** r.uniform(0, 1.5)])  # plates
        else:
            he = s * np.array([1, 1, 10 ** r.uniform(1, 2)])  # rods
        he = np.minimum(he, 0.3 * L)
        r.shuffle(he)
        rad = float(np.linalg.norm(he))
        ok = False
        for _try in range(60):
            pos = origin + r.uniform(-(L - rad - 2 * t), (L - rad - 2 * t), 3)
            if any(abs(pos[a] - pl[1][a]) < rad + pl[2][a]
                   and all(abs(pos[j] - pl[1][j]) < pl[2][j] + rad for j in range(3) if j != a)
                   for pl in plates for a in [pl[3]]):
                continue
            if any(np.linalg.norm(pos - q0) < rad + r0 for q0, r0 in placed):
                continue
            ok = True
            break
        if not ok:
            continue
        placed.append((pos, rad))
        q = r.normal(size=4)
        q /= np.linalg.norm(q)
        mass = max(float(np.prod(he) * 8 * 1000 * 10 ** r.uniform(-1, 1)), 1e-3)  # drawn, to keep the stream
        if P.get("equal_mass", True):
            mass = 1.0
        shape = p.createCollisionShape(p.GEOM_BOX, halfExtents=list(he), physicsClientId=cid)
        b = p.createMultiBody(mass, shape, basePosition=list(pos), baseOrientation=list(q),
                              useMaximalCoordinates=bool(P.get("maximal", True)), physicsClientId=cid)
        v = r.normal(size=3)
        v = v / np.linalg.norm(v) * r.uniform(0, P["vmax"])
        w = r.normal(size=3) * r.uniform(0, 20)
        p.changeDynamics(b, -1, restitution=float(r.choice([0, 0.3, 0.8])), maxJointVelocity=1e4, linearDamping=0,
                         angularDamping=0, physicsClientId=cid)
        p.resetBaseVelocity(b, list(v), list(w), physicsClientId=cid)
        boxes.append(b)
    for b in statics:
        p.changeDynamics(b, -1, restitution=0.5, physicsClientId=cid)
    return origin, plates, boxes


def scene_list(spec, steps_cap=None):
    """'4,60@15' -> [params(4), params(60) with dt = 1/15], steps capped at steps_cap."""
    out = []
    for item in spec.split(","):
        item = item.strip()
        if not item:
            continue
        seed, _, hz = item.partition("@")
        P = params(int(seed))
        if hz:
            P["dt"] = 1.0 / float(hz)
        if steps_cap:
            P["steps"] = min(P["steps"], steps_cap)
        P["name"] = f"seed {int(seed)}" + (f" at {float(hz):g} Hz" if hz else "")
        out.append(P)
    return out


# --------------------------------------------------------------------- one run


def run(P, method, kw=None):
    """One method on scene P: the figures (dict) and per-step traces."""
    cid = p.connect(p.DIRECT)
    ref = method == "ref"
    dt = P["dt"]
    res = dict(boxes=0, steps=0, escapes=0, frozen=0, longest=0, frozen3=0, ov1=0, ov5=0, deepest=0.0,
               us=float("nan"), warnings=0, error="", messages=Counter(), examples={}, trace_out=[], trace_frozen=[],
               trace_deep=[])
    try:
        p.setGravity(0, 0, -9.81 if P["gravity"] else 0.0, physicsClientId=cid)
        p.setTimeStep(dt / FINE if ref else dt, physicsClientId=cid)
        if P["nsub"] > 1 and not ref:
            p.setPhysicsEngineParameter(numSubSteps=P["nsub"], physicsClientId=cid)
        origin, plates, ids = build(P, cid)
        n = res["boxes"] = len(ids)
        L = P["L"]

        def read():
            pos = np.array([p.getBasePositionAndOrientation(b, physicsClientId=cid)[0] for b in ids])
            vel = np.array([p.getBaseVelocity(b, physicsClientId=cid)[0] for b in ids])
            return pos, vel

        prev, vprev = read()
        run_len, max_run = np.zeros(n, int), np.zeros(n, int)
        escaped = np.zeros(n, bool)
        times = []
        with warnings.catch_warnings(record=True) as caught:
            warnings.simplefilter("always")
            try:
                ccd = BoxCCD(cid, **(kw or {})) if method.startswith("boxccd") else None
                for _ in range(P["steps"]):
                    t0 = time.perf_counter()
                    if ccd is not None:
                        ccd.step()
                    elif ref:
                        for _ in range(FINE):
                            RAW_STEP(physicsClientId=cid)
                    else:
                        RAW_STEP(physicsClientId=cid)
                    times.append(time.perf_counter() - t0)
                    # measurement (not timed)
                    cur, vcur = read()
                    res["steps"] += 1
                    if not np.all(np.isfinite(cur)):
                        res["error"] = f"non-finite position of {int((~np.isfinite(cur).all(1)).sum())} boxes"
                        break
                    escaped |= (np.abs(cur - origin) > L + 0.01).any(1)
                    sp = np.linalg.norm(vprev, axis=1)
                    disp = np.linalg.norm(cur - prev, axis=1)
                    fr = (sp * dt > 0.2) & (disp < 0.1 * sp * dt) & (np.linalg.norm(vcur - vprev, axis=1) < 0.05 * sp)
                    res["frozen"] += int(fr.sum())
                    run_len = np.where(fr, run_len + 1, 0)
                    max_run = np.maximum(max_run, run_len)
                    prev, vprev = cur, vcur
                    deep = deepest_overlap(cid)
                    res["trace_out"].append(int(escaped.sum()))
                    res["trace_frozen"].append(int(fr.sum()))
                    res["trace_deep"].append(deep)
            except Exception as e:  # reported, the figures up to then kept
                res["error"] = repr(e)[:200]
        res["warnings"] = sum(1 for w in caught if issubclass(w.category, BoxCCDWarning))
        for w in caught:  # grouped by kind: the message with its numbers taken out; one example kept
            kind = f"{w.category.__name__}: " + re.sub(r"\d+(\.\d+)?(e[-+]?\d+)?", "#", str(w.message))
            res["messages"][kind] += 1
            res["examples"].setdefault(kind, f"{w.category.__name__}: {w.message}")
        res["escapes"] = int(escaped.sum())
        res["longest"] = int(max_run.max()) if n else 0
        res["frozen3"] = int((max_run >= 3).sum())
        d = np.array(res["trace_deep"])
        res["ov1"], res["ov5"] = int((d > 0.01).sum()), int((d > 0.05).sum())
        res["deepest"] = float(d.max()) if len(d) else 0.0
        res["us"] = 1e6 * float(np.mean(times)) if times else float("nan")
    finally:
        p.disconnect(cid)
    return res


def deepest_overlap(cid):
    """The deepest overlap (m, 0 if none) of the pairs pybullet has contacts for, where the
    step ends: ``getClosestPoints`` of each pair, the shallower of its two orders (pybullet's
    box detector prefers a face's axis, which one depends on the order)."""
    pairs = {(c[1], c[3], c[2], c[4]) for c in p.getContactPoints(physicsClientId=cid)}
    deepest = 0.0
    for a, la, b, lb in pairs:
        both = [p.getClosestPoints(x, y, 0.0, i, j, physicsClientId=cid)
                for x, i, y, j in ((a, la, b, lb), (b, lb, a, la))]
        deepest = max(deepest, min(max(-c[8] for c in pts) if pts else 0.0 for pts in both))
    return deepest


# ------------------------------------------------------------------- report
COLUMNS = ["boxes", "steps", "escapes", "frozen body-steps", "longest run", "boxes frozen 3+", "ends > 1 cm",
           "ends > 5 cm", "deepest (m)", "us/step", "x plain", "BoxCCDWarnings"]


def row_of(r, plain_us):
    return [r["boxes"], r["steps"], r["escapes"], r["frozen"], r["longest"], r["frozen3"], r["ov1"], r["ov5"],
            f"{r['deepest']:.3f}", f"{r['us']:.0f}", f"{r['us'] / plain_us:.1f}", r["warnings"]]


def describe(P):
    return (f"dt 1/{1 / P['dt']:.0f} s, numSubSteps {P['nsub']}, room {2 * P['L']:.1f} m wide, walls "
            f"{2000 * P['wall_t']:.1f} mm, up to {P['vmax']:g} m/s, {P['offset']:g} m from the origin, "
            f"gravity {'on' if P['gravity'] else 'off'}")


LABELS = {"plain": "plain pybullet", "boxccd": "BoxCCD (defaults)", "ref": f"reference: pybullet at dt/{FINE}"}
STYLE = {"plain": ("#b0202a", "-"), "boxccd": ("#1a7a3a", "-"), "ref": ("#222222", "--")}
KNOB_COLORS = ["#1f4fb4", "#c07a00", "#7a2aa0"]


def label_of(m):
    return LABELS.get(m, "BoxCCD " + m[len("boxccd"):].strip())


def style_of(m, methods):
    if m in STYLE:
        return STYLE[m]
    knobs = [x for x in methods if x not in STYLE]
    return KNOB_COLORS[knobs.index(m) % len(KNOB_COLORS)], "-"


def plot(scenes, methods, results, path):
    """Per scene (a column): boxes out of the room, boxes frozen in the step and the deepest overlap, at each
    step end, per method."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, axes = plt.subplots(3, len(scenes), figsize=(6.2 * len(scenes), 9.6), squeeze=False, sharex="col")
    for j, P in enumerate(scenes):
        out, frozen, deep = axes[0][j], axes[1][j], axes[2][j]
        rs = {m: results[(P["name"], m)] for m in methods}
        for m, r in rs.items():
            color, ls = style_of(m, methods)
            k = np.arange(1, len(r["trace_frozen"]) + 1)
            out.plot(k, r["trace_out"], color=color, ls=ls, lw=1.4, label=label_of(m) if j == 0 else None)
            frozen.step(k, r["trace_frozen"], where="mid", color=color, ls=ls, lw=1.4)
            deep.plot(k, np.maximum(r["trace_deep"], 1e-5), color=color, ls=ls, lw=1.2)
        short = {m: {"plain": "plain", "boxccd": "BoxCCD", "ref": "ref"}.get(m, label_of(m)) for m in methods}

        def title(ax, head, parts):
            ax.set_title(textwrap.fill(head + ": " + ", ".join(parts), 95), fontsize=8)

        out.set_title(f"{P['name']}: {rs[methods[0]]['boxes']} boxes, dt 1/{1 / P['dt']:.0f} s, numSubSteps "
                      f"{P['nsub']}, up to {P['vmax']:g} m/s\nroom {2 * P['L']:.1f} m wide, walls "
                      f"{2000 * P['wall_t']:.1f} mm thick, {P['offset']:g} m from the origin\nout at the end: "
                      + ", ".join(f"{short[m]} {r['escapes']}" for m, r in rs.items()), fontsize=8)
        out.set_ylabel("boxes out of the room\n(through a wall, so far)", fontsize=8)
        title(frozen, "frozen body-steps (longest run)", [f"{short[m]} {r['frozen']} ({r['longest']})"
                                                           for m, r in rs.items()])
        frozen.set_ylabel("boxes frozen in the step\n(fast, yet barely moved)", fontsize=8)
        title(deep, "step ends deeper than 1 cm / 5 cm", [f"{short[m]} {r['ov1']}/{r['ov5']}" for m, r in rs.items()])
        deep.set_yscale("log")
        deep.set_ylim(1e-5, 5)
        for y, txt in ((0.01, "1 cm"), (0.05, "5 cm")):
            deep.axhline(y, color="grey", ls=":", lw=1)
            deep.text(1.005, y, txt, color="grey", fontsize=7, va="center", transform=deep.get_yaxis_transform())
        deep.set_ylabel("deepest contact at the step end\n(m, log; 1e-5: none)", fontsize=8)
        deep.set_xlabel("step of dt", fontsize=8)
        for ax in (out, frozen, deep):
            ax.grid(True, alpha=0.3)
            ax.tick_params(labelsize=7)
        warned = [f"{short[m]}: {r['warnings']} BoxCCDWarnings" for m, r in rs.items() if r["warnings"]]
        errors = [f"{short[m]}: error after {r['steps']} steps" for m, r in rs.items() if r["error"]]
        if warned or errors:
            deep.text(0.01, 0.02, "; ".join(warned + errors), transform=deep.transAxes, fontsize=7, color="#a00000")
    fig.legend(loc="lower center", ncol=len(methods), fontsize=8, frameon=False)
    fig.suptitle("Crowds of fast boxes thrown in a closed room with thin static walls\nplain pybullet, BoxCCD and "
                 f"pybullet at a {FINE}x finer step (which itself lets boxes through thin walls at 300 m/s:\n"
                 "a reference for freezing and overlaps, not for escapes)", fontsize=10)
    fig.tight_layout(rect=(0, 0.03, 1, 0.95))
    fig.savefig(path, dpi=110)
    plt.close(fig)


# ---------------------------------------------------------------------- main
def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--seeds", default=DEFAULT_SEEDS, help="comma-separated seeds, each at its own dt or as "
                    f"seed@H at dt = 1/H (default {DEFAULT_SEEDS})")
    ap.add_argument("--steps", type=int, default=None, help="at most this many steps per scene")
    ap.add_argument("--quick", action="store_true", help=f"at most {QUICK_STEPS} steps per scene; crowd_quick.csv/.png")
    ap.add_argument("--knob", action="append", default=[], metavar="K=V[,K=V]",
                    help="another BoxCCD method with these keyword arguments (repeatable)")
    ap.add_argument("--no-ref", action="store_true", help="without the fine reference (the slowest method)")
    ap.add_argument("--multibody", action="store_true",
                    help="the boxes as multibodies (useMaximalCoordinates=False), where pybullet's explicit "
                         "gyroscopic term spins fast elongated boxes up to their velocity clamp")
    ap.add_argument("--csv", default=None, help="results CSV ('' for none; default benchmarks/results/crowd.csv)")
    ap.add_argument("--png", default=None, help="the picture ('' for none; default docs/crowd.png)")
    args = ap.parse_args(argv)
    name = "crowd_quick" if args.quick else "crowd"
    csv_path = os.path.join(ROOT, "benchmarks", "results", name + ".csv") if args.csv is None else args.csv
    png_path = os.path.join(ROOT, "docs", name + ".png") if args.png is None else args.png
    cap = args.steps or (QUICK_STEPS if args.quick else None)
    scenes = scene_list(args.seeds, cap)
    for P in scenes:
        P["maximal"] = not args.multibody
    methods = ["plain", "boxccd"] + [f"boxccd {k.strip()}" for k in args.knob] + ([] if args.no_ref else ["ref"])
    kws = {m: knobs(m[len("boxccd"):]) for m in methods if m.startswith("boxccd")}

    import bullet_boxccd

    print(f"machine: {platform.platform()}, {os.cpu_count()} cpus, python {platform.python_version()}, "
          f"pybullet API {p.getAPIVersion()}, numpy {np.__version__}")
    print(f"code: {code_version()}; bullet_boxccd imported from {os.path.dirname(bullet_boxccd.__file__)}")
    print(f"methods: {', '.join(methods)}; the reference: plain pybullet at dt/{FINE}")
    t_all = time.perf_counter()
    results, rows = {}, []
    for P in scenes:
        for m in methods:
            t0 = time.perf_counter()
            results[(P["name"], m)] = run(P, m, kws.get(m))
            results[(P["name"], m)]["wall"] = time.perf_counter() - t0
        plain_us = results[(P["name"], "plain")]["us"]
        print(f"\n{P['name']}: {results[(P['name'], 'plain')]['boxes']} boxes, {P['steps']} steps; {describe(P)}\n")
        body = [[label_of(m)] + row_of(results[(P["name"], m)], plain_us) for m in methods]
        print(markdown(["method"] + COLUMNS, body))
        for m in methods:
            r = results[(P["name"], m)]
            if r["error"]:
                print(f"  {label_of(m)}: ERROR after {r['steps']} steps: {r['error']}")
            for kind, c in sorted(r["messages"].items()):
                print(f"  {label_of(m)}: warned {c}x, e.g. {textwrap.shorten(r['examples'][kind], 300)}")
            rows.append(dict(scene=P["name"], seed=P["seed"], dt=P["dt"], numSubSteps=P["nsub"], room_half=P["L"],
                             wall_half_thickness=P["wall_t"], vmax=P["vmax"], offset=P["offset"],
                             gravity=int(P["gravity"]), method=m, boxes=r["boxes"], steps=r["steps"],
                             escapes=r["escapes"], frozen_body_steps=r["frozen"], longest_frozen_run=r["longest"],
                             boxes_frozen_3plus=r["frozen3"], step_ends_over_1cm=r["ov1"],
                             step_ends_over_5cm=r["ov5"], deepest_m=r["deepest"], us_per_step=r["us"],
                             x_plain=r["us"] / plain_us, boxccd_warnings=r["warnings"],
                             other_warnings=sum(r["messages"].values()) - r["warnings"], error=r["error"],
                             run_seconds=r["wall"]))
    print(f"\nescapes of the reference are its own tunneling (a fine step of dt/{FINE} still moves a box at 300 m/s "
          "further than a thin wall is thick); it is the reference for freezing and overlaps")
    if csv_path:
        write_csv(csv_path, rows)
    if png_path:
        os.makedirs(os.path.dirname(os.path.abspath(png_path)), exist_ok=True)
        plot(scenes, methods, results, png_path)
    written = ", ".join(x for x in (csv_path, png_path) if x) or "nothing"
    print(f"\n{len(scenes) * len(methods)} runs in {time.perf_counter() - t_all:.0f} s; written: {written}")


if __name__ == "__main__":
    main()
