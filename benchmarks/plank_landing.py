"""A long plank landing on a thick floor at 60 Hz: its first impact, and the pivot after it.

What it measures
----------------
One 5 x 5 cm plank, 0.4 to 1.5 m long (as in the planks family of ``fidelity.py``),
turned at random and dropped from rest at 2 to 10 m onto a static box floor 1 m thick
(nothing can pass through it, so plain pybullet lands it too), run for 2.5 s at 60 Hz.
Per method, over the seeds:

* ``first spin``: the plank's spin (rad/s) at the end of the step its first impact falls
  in (where the reference's plank first turns), median of |method - reference| / reference;
* ``lying``: planks that end lying on the floor (centre within 5 cm of it, slower than
  0.5 m/s), as the reference's do;
* ``spin`` median and max: the fastest spin over the run;

and the same for plain pybullet, BoxCCD and 16 substeps run from the reference's state at
the end of the step of its first impact on, and for the reference, plain pybullet and
BoxCCD from BoxCCD's (what the steps after the impact do alone).

A landing plank first strikes with one end; at a fine step it then pivots on that end
while it turns down, its contact solved at every fine step, and its far end's slap ends
the motion. BoxCCD resolves the first impact at the touch (its spin within a few percent
of the reference's); the pivot that follows is a contact that began before the step,
which pybullet takes in whole steps (at 60 Hz the plank turns 0.5 to 1 rad a step, and
solved once a step, its pivot end leaves the floor), and the far end's slap then at times
throws the plank up spinning. Plain pybullet over this
thick floor lands the plank deep inside it in one step (its first spin far off) and
pushes it out flat, and its slaps likewise. Finer steps (``numSubSteps``) hold the pivot.

Then the same planks dropped pitched and not rolled, so that the far end's bottom edge
slaps the floor flat, both corners at once: the fastest roll about the long axis after
it, for plain pybullet, BoxCCD (and with ``impact_depth=1e-5``), 16 substeps and the
reference. BoxCCD resolves the slap from a 1 mm overlap (``impact_depth``), where
Bullet's box-box detector sees both corners of the edge, as at a fine step; from a 1e-5 m
overlap it sees one (a roll of a few 1e-4 rad lifts the other), whose impulse alone rolls
the plank.

Run
---
    python benchmarks/plank_landing.py              # 32 seeds, about 25 s
"""

from __future__ import annotations

import argparse
import warnings

import numpy as np
import pybullet as p
from _fidelity_scenes import quat

from bullet_boxccd import BoxCCD

DT = 1 / 60
SECONDS = 2.5
K = 128  # the reference's step: DT / K (and DT / 2K, its convergence)


def _floor(method):
    """A client stepping at the method's step, with gravity and the 1 m thick box floor:
    (client, pybullet steps per step of DT)."""
    cid = p.connect(p.DIRECT)
    fine = {"ref": K, "ref2": 2 * K}.get(method, 1)
    p.setGravity(0, 0, -9.81, physicsClientId=cid)
    p.setPhysicsEngineParameter(fixedTimeStep=DT / fine, numSubSteps=16 if method == "sub16" else 0,
                                physicsClientId=cid)
    floor = p.createCollisionShape(p.GEOM_BOX, halfExtents=[5, 5, 0.5], physicsClientId=cid)
    p.createMultiBody(0, floor, basePosition=[0, 0, -0.5], physicsClientId=cid)
    return cid, fine


def _plank(cid, length, height, orn):
    shape = p.createCollisionShape(p.GEOM_BOX, halfExtents=[length / 2, 0.025, 0.025], physicsClientId=cid)
    return p.createMultiBody(length, shape, basePosition=[0, 0, height], baseOrientation=orn, physicsClientId=cid)


def _stepper(cid, method, fine, knobs):
    """One step of DT: BoxCCD's (made now) or pybullet's in ``fine`` steps."""
    if method == "boxccd":
        return BoxCCD(cid, **(knobs or {})).step
    return lambda: [p.stepSimulation(physicsClientId=cid) for _ in range(fine)]


def land(seed, method, knobs=None, start=None):
    """(spin after each step (rad/s), final height (m), final speed (m/s), the plank's state
    (pose, velocities) and step at the end of the step it first turns in) of the plank;
    from ``start`` (such a state and step) if given."""
    rng = np.random.default_rng(seed)
    cid, fine = _floor(method)
    try:
        length = rng.uniform(0.4, 1.5)
        plank = _plank(cid, length, rng.uniform(2, 10), quat(rng))
        first = start
        if start is not None:
            (pos, orn, v, w), k0 = start
            p.resetBasePositionAndOrientation(plank, pos, orn, physicsClientId=cid)
            p.resetBaseVelocity(plank, v, w, physicsClientId=cid)
        step = _stepper(cid, method, fine, knobs)
        spins = []
        for k in range(k0 + 1 if start else 0, int(round(SECONDS / DT))):
            step()
            v, w = p.getBaseVelocity(plank, physicsClientId=cid)
            spins.append(float(np.linalg.norm(w)))
            if first is None and spins[-1] > 1e-3:
                first = (p.getBasePositionAndOrientation(plank, physicsClientId=cid) + (v, w), k)
        z = p.getBasePositionAndOrientation(plank, physicsClientId=cid)[0][2]
        v = float(np.linalg.norm(p.getBaseVelocity(plank, physicsClientId=cid)[0]))
        return np.array(spins), z, v, first
    finally:
        p.disconnect(cid)


def land_flat(length, pitch, height, method, knobs=None):
    """The fastest roll (rad/s, about its long axis) of a plank dropped from rest at
    ``height``, pitched by ``pitch`` (rad) and not rolled, onto the floor: it lands on one
    end, pivots, and its far end's bottom edge slaps the floor flat, both corners at once."""
    cid, fine = _floor(method)
    try:
        plank = _plank(cid, length, height, p.getQuaternionFromEuler([0, pitch, 0]))
        step = _stepper(cid, method, fine, knobs)
        roll = 0.0
        for _ in range(int(round(SECONDS / DT))):
            step()
            orn = p.getBasePositionAndOrientation(plank, physicsClientId=cid)[1]
            axis = np.array(p.getMatrixFromQuaternion(orn))[[0, 3, 6]]
            roll = max(roll, abs(float(axis @ p.getBaseVelocity(plank, physicsClientId=cid)[1])))
        return roll
    finally:
        p.disconnect(cid)


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--seeds", type=int, default=32)
    args = ap.parse_args(argv)
    methods = {"plain": ("plain", None), "boxccd": ("boxccd", None),
               "boxccd max_turn=0.1": ("boxccd", {"max_turn": 0.1}), "sub16": ("sub16", None),
               f"ref (dt/{K})": ("ref", None), f"ref2 (dt/{2 * K})": ("ref2", None)}
    ref_name = f"ref (dt/{K})"
    # Each method run again from another's state at the end of the step of its first impact.
    handed = [(m, ref_name, "the reference's") for m in ("plain", "boxccd", "sub16")] + \
             [(m, "boxccd", "BoxCCD's") for m in ("ref", "plain", "boxccd")]
    runs = {name: [] for name in methods}
    runs.update({f"{m}, from {whose} first impact on": [] for m, _, whose in handed})
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")  # (the planks' spins may reach pybullet's velocity clamp: named by BoxCCD)
        for seed in range(args.seeds):
            for name, (method, knobs) in methods.items():
                runs[name].append(land(seed, method, knobs))
            for method, source, whose in handed:
                runs[f"{method}, from {whose} first impact on"].append(land(seed, method, start=runs[source][-1][3]))
    ref = runs[ref_name]
    print(f"A plank (0.4-1.5 m, 5 x 5 cm) dropped from 2-10 m onto a 1 m thick box floor at 60 Hz, "
          f"{args.seeds} seeds, {SECONDS} s\n")
    print("| method | first spin: median error | lying at the end | spin median (rad/s) | spin max |")
    print("|---|---|---|---|---|")
    for name, rs in runs.items():
        if ", from " in name:
            err = "-"
        else:
            k = [r[3][1] for r in ref]  # the step the reference's plank first turns in
            err = f"{np.median([abs(s[i] - r[0][i]) / r[0][i] for (s, *_), r, i in zip(rs, ref, k)]):.1%}"
        lying = sum(z < 0.075 and v < 0.5 for _, z, v, _ in rs)
        top = [s.max() for s, *_ in rs]
        print(f"| {name} | {err} | {lying} of {len(rs)} | {np.median(top):.0f} | {max(top):.0f} |")

    drops = [(length, pitch, 1.5 + 2 * length) for length in (0.8, 1.0, 1.2, 1.5) for pitch in (0.4, 0.8)]
    flat = {"plain": ("plain", None), "boxccd": ("boxccd", None),
            "boxccd impact_depth=1e-5": ("boxccd", {"impact_depth": 1e-5}), "sub16": ("sub16", None),
            ref_name: ("ref", None)}
    print(f"\nThe same planks (0.8-1.5 m) dropped pitched 0.4 or 0.8 rad and not rolled ({len(drops)} drops): their "
          "far end's edge slaps the floor flat; the fastest roll about the long axis after it\n")
    print("| method | rolled faster than 5 rad/s | fastest roll (rad/s) |")
    print("|---|---|---|")
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        for name, (method, knobs) in flat.items():
            rolls = np.array([land_flat(*d, method, knobs) for d in drops])
            print(f"| {name} | {np.sum(rolls > 5)} of {len(drops)} | {rolls.max():.1f} |")


if __name__ == "__main__":
    main()
