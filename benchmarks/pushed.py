"""Boxes driven by what does not stop for them, against pybullet's converged physics.

1. ``arm``: a fixed-base two-link box arm (links 0.3 x 0.06 x 0.06 m, 1 kg, in a
   horizontal plane), its shoulder's velocity motor at 15-60 rad/s (100-1000 N m), its
   elbow held, swings into a free 5 cm cube of 0.05-2 kg placed at random in its reach
   (restitution 0 or 0.5, friction 0.2-0.8, on a table or floating), at 240 or 60 Hz: the
   link strikes the cube and often drives it along its face for a few steps.
2. ``bar``: a mass-0 bar (0.4 x 0.02 x 0.1 m) turned about its end at 20-60 rad/s by a
   teleport to its pose at every step (and given its spin too, in half the scenes) sweeps
   a free 5 cm cube out along it and off its end.
3. ``struck``: a fixed-base three-link box arm (upright links 0.08 x 0.08 x 0.3 m, 2 kg)
   holding its pose under velocity motors (target 0, 0-1000 N m) is struck at a link by
   a free cube (6-10 cm, 0.5-3 kg) thrown at 20-80 m/s, at 240 or 60 Hz: the link is
   knocked away, as much as its motors let it be.

Per scene: the cube's velocity after the run against the converged engine's (plain
pybullet at a 128 times finer step at 240 Hz, 256 at 60 Hz, the mean over 4 offsets of
its step grid, every per-step command given at every fine step), as a share of the
driving speed (the arm's tip, the bar's tip, the thrown cube); and the deepest overlap of the cube and
what drives it (or the table) where a step ends. Printed: each method's median error,
mean and largest error, the scenes more than 0.15 off, and the scenes ending a step
deeper than 1 cm or twice the converged engine's deepest.

Run
---
    python benchmarks/pushed.py                 # ~20 s on 2 cores
    python benchmarks/pushed.py --family bar --scenes 8

Saves ``docs/pushed.png`` (``--png``): each family's scenes, BoxCCD beside plain pybullet.
"""

from __future__ import annotations

import argparse
import math
import multiprocessing
import time

import numpy as np
import pybullet as p

import bullet_boxccd  # noqa: F401  (the hooks, before any body is made)
from bullet_boxccd import BoxCCD

RAW_STEP = p._bullet_boxccd_originals["stepSimulation"]


def _scenes(n, seed, draw, slow_every, steps):
    """n scenes of ``draw(rng, k)`` (a dict), every ``slow_every``-th at 60 Hz for ``steps[0]``
    steps (the last of each run of that many), the others at 240 Hz for ``steps[1]``."""
    rng = np.random.default_rng(seed)
    out = []
    for k in range(n):
        slow = k % slow_every == slow_every - 1
        out.append(dict(draw(rng, k), dt=1 / 60 if slow else 1 / 240, steps=steps[0] if slow else steps[1]))
    return out


def _arm(rng, k):
    r, a = rng.uniform(0.36, 0.58), rng.uniform(-0.1, 0.6)
    return dict(at=(r * math.cos(a), r * math.sin(a)), mass=float(rng.choice([0.05, 0.2, 0.5, 1.0, 2.0])),
                omega=float(rng.choice([15.0, 25.0, 40.0, 60.0])),
                force=float(rng.choice([100.0, 300.0, 500.0, 1000.0])),
                rest=float(rng.choice([0.0, 0.5])), fric=float(rng.choice([0.2, 0.5, 0.8])),
                table=bool(rng.random() < 0.5))


def _bar(rng, k):
    return dict(omega=float(rng.uniform(20.0, 60.0)), spin=bool(k % 2), mass=float(rng.choice([0.05, 0.2, 1.0])),
                rest=float(rng.choice([0.0, 0.5])), table=bool(rng.random() < 0.5))


def _struck(rng, k):
    return dict(link=int(rng.integers(0, 3)), height=float(rng.uniform(0.05, 0.25)),
                half=float(rng.uniform(0.03, 0.05)),
                mass=float(rng.choice([0.5, 1.0, 2.0, 3.0])), speed=float(rng.uniform(20.0, 80.0)),
                force=float(rng.choice([0.0, 100.0, 300.0, 1000.0])),
                aim=(float(rng.uniform(-0.2, 0.2)), float(rng.uniform(-0.2, 0.2))), table=False)


def arm_scenes(n, seed=5):
    return _scenes(n, seed, _arm, 2, (6, 24))


def bar_scenes(n, seed=6):
    return _scenes(n, seed, _bar, 4, (8, 24))


def struck_scenes(n, seed=7):
    return _scenes(n, seed, _struck, 2, (3, 12))


def _shape(cid, half, at=(0, 0, 0)):
    return p.createCollisionShape(p.GEOM_BOX, halfExtents=half, collisionFramePosition=at, physicsClientId=cid)


def build_arm(cid, s):
    """(the cube, the bodies whose overlap with it is measured, a per-step command or None)."""
    link = _shape(cid, [0.15, 0.03, 0.03], [0.15, 0, 0])
    arm = p.createMultiBody(0, _shape(cid, [0.03] * 3), -1, [0, 0, 0], linkMasses=[1, 1],
                            linkCollisionShapeIndices=[link, link], linkVisualShapeIndices=[-1, -1],
                            linkPositions=[[0, 0, 0], [0.3, 0, 0]], linkOrientations=[[0, 0, 0, 1]] * 2,
                            linkInertialFramePositions=[[0.15, 0, 0]] * 2,
                            linkInertialFrameOrientations=[[0, 0, 0, 1]] * 2, linkParentIndices=[0, 1],
                            linkJointTypes=[p.JOINT_REVOLUTE] * 2, linkJointAxis=[[0, 0, 1]] * 2, physicsClientId=cid)
    for j in (-1, 0, 1):
        p.changeDynamics(arm, j, linearDamping=0, angularDamping=0, maxJointVelocity=1000, jointDamping=0,
                         restitution=s["rest"], physicsClientId=cid)
    p.resetJointState(arm, 0, -1.0, s["omega"], physicsClientId=cid)
    for joint, target in ((0, s["omega"]), (1, 0.0)):
        p.setJointMotorControl2(arm, joint, p.VELOCITY_CONTROL, targetVelocity=target, force=s["force"],
                                physicsClientId=cid)
    others, z = [arm], 0.0
    if s["table"]:
        table = p.createMultiBody(0, _shape(cid, [2, 2, 0.05]), -1, [0, 0, -0.081], physicsClientId=cid)
        p.changeDynamics(table, -1, lateralFriction=s["fric"], physicsClientId=cid)
        others, z = [arm, table], -0.006
    cube = p.createMultiBody(s["mass"], _shape(cid, [0.025] * 3), -1, [*s["at"], z], physicsClientId=cid)
    p.changeDynamics(cube, -1, restitution=s["rest"], lateralFriction=s["fric"], linearDamping=0, angularDamping=0,
                     maxJointVelocity=1000, physicsClientId=cid)
    return cube, others, None


def build_bar(cid, s):
    omega, z = s["omega"], 0.025 if s["table"] else 0.0

    def angle(t):
        return -0.6 + omega * t

    def pose(t):
        a = angle(t)
        return [0.2 * math.cos(a), 0.2 * math.sin(a), z], p.getQuaternionFromEuler([0, 0, a])

    bar = p.createMultiBody(0, _shape(cid, [0.2, 0.01, 0.05]), -1, *pose(0.0), physicsClientId=cid)
    others = [bar]
    if s["table"]:
        table = p.createMultiBody(0, _shape(cid, [2, 2, 0.05]), -1, [0, 0, -0.05], physicsClientId=cid)
        p.setCollisionFilterPair(bar, table, -1, -1, 0, physicsClientId=cid)
        others.append(table)
    cube = p.createMultiBody(s["mass"], _shape(cid, [0.025] * 3), -1, [0.3, 0.15, z], physicsClientId=cid)
    for b in (bar, cube):
        p.changeDynamics(b, -1, restitution=s["rest"], lateralFriction=0.5, physicsClientId=cid)
    p.changeDynamics(cube, -1, linearDamping=0, angularDamping=0, maxJointVelocity=1000, physicsClientId=cid)

    def command(t):
        p.resetBasePositionAndOrientation(bar, *pose(t), physicsClientId=cid)
        if s["spin"]:
            a = angle(t)
            p.resetBaseVelocity(bar, [-0.2 * omega * math.sin(a), 0.2 * omega * math.cos(a), 0], [0, 0, omega],
                                physicsClientId=cid)

    return cube, others, command


def build_struck(cid, s):
    link = _shape(cid, [0.04, 0.04, 0.15], [0, 0, 0.15])
    arm = p.createMultiBody(0, _shape(cid, [0.1, 0.1, 0.05]), -1, [0, 0, 0.05], linkMasses=[2.0] * 3,
                            linkCollisionShapeIndices=[link] * 3, linkVisualShapeIndices=[-1] * 3,
                            linkPositions=[[0, 0, 0.05], [0, 0, 0.3], [0, 0, 0.3]],
                            linkOrientations=[[0, 0, 0, 1]] * 3, linkInertialFramePositions=[[0, 0, 0.15]] * 3,
                            linkInertialFrameOrientations=[[0, 0, 0, 1]] * 3, linkParentIndices=[0, 1, 2],
                            linkJointTypes=[p.JOINT_REVOLUTE] * 3, linkJointAxis=[[0, 1, 0]] * 3,
                            physicsClientId=cid)
    for j in range(-1, 3):
        p.changeDynamics(arm, j, maxJointVelocity=1000, linearDamping=0, angularDamping=0, jointDamping=0,
                         restitution=0.5, physicsClientId=cid)
    for j in range(3):
        p.setJointMotorControl2(arm, j, p.VELOCITY_CONTROL, targetVelocity=0, force=s["force"], physicsClientId=cid)
    # Thrown along +x (tilted by the aim) at a point of the link's face, to touch it in the second step.
    d = np.array([1.0, *s["aim"]])
    d /= np.linalg.norm(d)
    target = np.array([-0.04, 0.0, 0.1 + 0.3 * s["link"] + s["height"]])
    start = target - d * (s["speed"] * 1.5 * s["dt"] + s["half"] * math.sqrt(3))
    cube = p.createMultiBody(s["mass"], _shape(cid, [s["half"]] * 3), -1, start.tolist(), physicsClientId=cid)
    p.changeDynamics(cube, -1, maxJointVelocity=1000, linearDamping=0, angularDamping=0, restitution=0.5,
                     lateralFriction=0.5, physicsClientId=cid)
    p.resetBaseVelocity(cube, (d * s["speed"]).tolist(), [0, 0, 0], physicsClientId=cid)
    return cube, [arm], None


BUILD = {"arm": build_arm, "bar": build_bar, "struck": build_struck}
SCENES = {"arm": (arm_scenes, 40), "bar": (bar_scenes, 16), "struck": (struck_scenes, 16)}


def run(family, s, method, fine=1, phase=0.0):
    """(the cube's velocity after the run, the deepest overlap where a step of dt ends)."""
    cid = p.connect(p.DIRECT)
    try:
        h = s["dt"] / fine
        p.setTimeStep(h, physicsClientId=cid)
        p.setGravity(0, 0, -9.81 if s["table"] else 0.0, physicsClientId=cid)
        cube, others, command = BUILD[family](cid, s)
        t = 0.0
        if phase:
            t = phase * h
            p.setTimeStep(t, physicsClientId=cid)
            if command:
                command(t)
            RAW_STEP(physicsClientId=cid)
            p.setTimeStep(h, physicsClientId=cid)
        ccd = BoxCCD(cid) if method == "boxccd" else None
        deepest = 0.0
        for _ in range(s["steps"]):
            for _ in range(fine):
                t += h
                if command:
                    command(t)
                ccd.step() if ccd else RAW_STEP(physicsClientId=cid)
            for b in others:
                deepest = max([deepest] + [-c[8] for c in p.getClosestPoints(b, cube, 0.0, physicsClientId=cid)])
        return np.array(p.getBaseVelocity(cube, physicsClientId=cid)[0]), deepest
    finally:
        p.disconnect(cid)


def scene(job):
    family, k, s = job
    fine = 128 if s["dt"] < 1 / 100 else 256
    refs = [run(family, s, "plain", fine, j / 4) for j in range(4)]
    v_ref, ref_deepest = np.mean([r[0] for r in refs], axis=0), max(r[1] for r in refs)
    drive = s["speed"] if family == "struck" else (0.6 if family == "arm" else 0.4) * s["omega"]  # a tip's speed
    out = {"family": family, "scene": k, "ref_deepest": ref_deepest}
    for method in ("boxccd", "plain"):
        v, deepest = run(family, s, method)
        out[method] = (float(np.linalg.norm(v - v_ref) / drive), deepest)
    return out


TITLES = {"arm": "an arm's link strikes a cube and drives it", "bar": "a teleported bar sweeps a cube",
          "struck": "a cube thrown at an arm holding its pose"}


def plot(rows, families, path):
    """Each family's scenes, sorted by BoxCCD's error, BoxCCD beside plain pybullet; a scene
    ending a step too deep hollow."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, axes = plt.subplots(1, len(families), figsize=(5.2 * len(families), 4.2), squeeze=False)
    for ax, f in zip(axes[0], families):
        rs = sorted((r for r in rows if r["family"] == f), key=lambda r: r["boxccd"][0])
        x = np.arange(len(rs))
        for m, color, marker, label in (("plain", "#b0202a", "o", "plain pybullet"),
                                        ("boxccd", "#1a7a3a", "s", "BoxCCD")):
            err = np.maximum([r[m][0] for r in rs], 1e-3)
            deep = np.array([r[m][1] > max(0.01, 2 * r["ref_deepest"]) for r in rs])
            ax.scatter(x[~deep], err[~deep], color=color, marker=marker, s=22, label=label)
            ax.scatter(x[deep], err[deep], facecolors="none", edgecolors=color, marker=marker, s=22,
                       label=f"{label}: a step too deep")
        ax.axhline(0.15, color="grey", ls=":", lw=1)
        ax.text(0, 0.16, "0.15", color="grey", fontsize=7)
        ax.set_yscale("log")
        ax.set_ylim(1e-3, 5)
        ax.set_title(f"{f}: {TITLES[f]} ({len(rs)} scenes)", fontsize=9)
        ax.set_xlabel("scene, sorted by BoxCCD's error", fontsize=8)
        ax.set_ylabel("|v - v_ref| / driving speed (log)", fontsize=8)
        ax.grid(True, which="both", alpha=0.3)
    handles, labels = axes[0][0].get_legend_handles_labels()
    fig.legend(handles, labels, loc="lower center", ncol=4, fontsize=8, frameon=False)
    fig.suptitle("Boxes driven by what does not stop for them: the cube's velocity off pybullet's converged "
                 "physics (128-256x finer step)\nhollow: a step ended deeper than 1 cm or twice the converged "
                 "engine's deepest", fontsize=10)
    fig.tight_layout(rect=(0, 0.07, 1, 0.92))
    fig.savefig(path, dpi=110)
    plt.close(fig)


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--family", choices=["arm", "bar", "struck", "all"], default="all")
    ap.add_argument("--scenes", type=int, default=None, help="scenes per family (default: arm 40, bar 16, struck 16)")
    ap.add_argument("--jobs", type=int, default=2)
    ap.add_argument("--verbose", action="store_true", help="each scene's figures too")
    ap.add_argument("--png", default="docs/pushed.png", help="the picture ('' for none)")
    args = ap.parse_args()
    families = list(SCENES) if args.family == "all" else [args.family]
    jobs = []
    for f in families:
        make, n = SCENES[f]
        jobs += [(f, k, s) for k, s in enumerate(make(args.scenes or n))]
    t0 = time.perf_counter()
    with multiprocessing.Pool(args.jobs) as pool:
        rows = pool.map(scene, jobs)
    for f in families:
        rs = [r for r in rows if r["family"] == f]
        print(f"\n{f}: {len(rs)} scenes; error = |v - v_ref| / driving speed")
        if args.verbose:
            scenes = {k: s for g, k, s in jobs if g == f}
            for r in rs:
                print(f"  {r['scene']:2d} {scenes[r['scene']]}: error boxccd {r['boxccd'][0]:.3f} plain "
                      f"{r['plain'][0]:.3f}; deepest boxccd {r['boxccd'][1]:.4f} plain {r['plain'][1]:.4f} "
                      f"reference {r['ref_deepest']:.4f}")
        print("| method | median error | mean | largest | more than 0.15 off | a step deeper than 1 cm or 2x the "
              "reference's |")
        print("|---|---|---|---|---|---|")
        for m in ("boxccd", "plain"):
            e = np.array([r[m][0] for r in rs])
            deep = sum(r[m][1] > max(0.01, 2 * r["ref_deepest"]) for r in rs)
            print(f"| {m} | {np.median(e):.3f} | {e.mean():.3f} | {e.max():.2f} | {int((e > 0.15).sum())} | {deep} |")
    if args.png:
        plot(rows, families, args.png)
        print(f"picture: {args.png}")
    print(f"\n{time.perf_counter() - t0:.0f} s")


if __name__ == "__main__":
    main()
