"""pybullet's explicit gyroscopic term on an elongated box spinning fast, in free flight.

What it measures
----------------
One free box, no gravity, no damping, its velocity clamp (``maxJointVelocity``) lifted
to 1e4 rad/s, given a spin about a fixed body-skew axis, stepped in plain pybullet (no
BoxCCD: this is pybullet's own integration). Per step size: the largest spin component
reached (rad/s; 1e4 is the clamp) and the kinetic energy at the end over that at the
start (1 for exact free rotation), for the body as pybullet makes it by default (a
multibody, whose gyroscopic term it integrates explicitly) and in maximal coordinates
(``useMaximalCoordinates=True``: a rigid body, whose gyroscopic term it integrates
implicitly). Two bodies:

* a 0.6 x 0.04 x 0.2 m box at 270 rad/s for 0.1 s at 240, 960 and 3,840 Hz,
* a 1.2 x 0.05 x 0.1 m plank at 40 rad/s for 1 s at 60, 240 and 960 Hz.

It is what bounds BoxCCD's fidelity after corner strikes that leave such spins
(README, known limits): a finer step is the only cure, in plain pybullet too.

Run
---
    python benchmarks/gyroscopic.py        # about 1 s
"""

from __future__ import annotations

import numpy as np
import pybullet as p

CLAMP = 1e4  # rad/s, each axis
AXIS = np.array([0.2, 1.0, 0.1]) / np.linalg.norm([0.2, 1.0, 0.1])  # the spin's direction (body frame at start)


def spin(half, rate, hz, seconds, maximal):
    """(largest spin component reached, kinetic energy at the end / at the start)."""
    cid = p.connect(p.DIRECT)
    try:
        p.setGravity(0, 0, 0, physicsClientId=cid)
        p.setTimeStep(1.0 / hz, physicsClientId=cid)
        body = p.createMultiBody(1.0, p.createCollisionShape(p.GEOM_BOX, halfExtents=half, physicsClientId=cid),
                                 useMaximalCoordinates=maximal, physicsClientId=cid)
        p.changeDynamics(body, -1, linearDamping=0, angularDamping=0, maxJointVelocity=CLAMP, physicsClientId=cid)
        p.resetBaseVelocity(body, [0, 0, 0], (rate * AXIS).tolist(), physicsClientId=cid)
        inertia = np.array(p.getDynamicsInfo(body, -1, physicsClientId=cid)[2])

        def state():
            w = np.array(p.getBaseVelocity(body, physicsClientId=cid)[1])
            q = p.getBasePositionAndOrientation(body, physicsClientId=cid)[1]
            w_body = np.reshape(p.getMatrixFromQuaternion(q), (3, 3)).T @ w
            return float(np.abs(w).max()), 0.5 * float(w_body @ (inertia * w_body))

        largest, energy0 = state()
        for _ in range(int(round(seconds * hz))):
            p.stepSimulation(physicsClientId=cid)
            largest = max(largest, state()[0])
        return largest, state()[1] / energy0
    finally:
        p.disconnect(cid)


def main():
    rows = []
    bodies = (("0.6 x 0.04 x 0.2 m box", (0.3, 0.02, 0.1), 270.0, 0.1, (240, 960, 3840)),
              ("1.2 x 0.05 x 0.1 m plank", (0.6, 0.025, 0.05), 40.0, 1.0, (60, 240, 960)))
    for name, half, rate, seconds, rates in bodies:
        for hz in rates:
            row = [name, f"{rate:g}", f"{seconds:g}", str(hz)]
            for maximal in (False, True):
                largest, gain = spin(half, rate, hz, seconds, maximal)
                row += [f"{largest:,.0f}", f"{gain:.3g}"]
            rows.append(row)
    head = ("body", "spin (rad/s)", "run (s)", "step (Hz)", "multibody: largest spin component (rad/s; clamp 1e4)",
            "multibody: kinetic energy end / start", "maximal: largest spin component", "maximal: kinetic energy")
    print("| " + " | ".join(head) + " |\n|" + "|".join("---" for _ in head) + "|")
    for r in rows:
        print("| " + " | ".join(r) + " |")


if __name__ == "__main__":
    main()
