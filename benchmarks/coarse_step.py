"""Two scenes whose outcome pybullet's coarse step sets, with BoxCCD as without it.

What it measures
----------------
BoxCCD resolves an impact as pybullet's solver resolves it at the user's step. Where
pybullet's answer at that step is not its converged one, neither is BoxCCD's. Each scene
is run with plain pybullet, BoxCCD, ``numSubSteps=16`` and plain pybullet at finer steps
(the converged engine), each method in a client of its own:

* **A plate rattling in a closed box.** An 8 x 8 x 4 cm plate (0.5 kg, restitution 0.9,
  no damping, clamp 1e4) thrown at 30 to 80 m/s in a random direction, spinning
  ~N(0, 20) rad/s, inside a closed box of 1 cm walls (0.6 m inside), gravity in half of
  the seeds, for 0.25 s at 240 Hz. Its corner strikes spin it at about 1,000 rad/s, and
  pybullet's explicit gyroscopic term at a coarse step then spins it up in flight (README,
  known limits; ``benchmarks/gyroscopic.py``). Per seed: its kinetic energy at the end
  over its launch's, and whether it left the box (through a wall).
* **A cube held by a gripper, struck.** A fixed two-finger gripper (box fingers on
  prismatic joints, position motors squeezing at 26.9 N, friction 1) holds a 0.195 kg,
  6 cm cube; a 0.25 kg, 3 cm cube strikes it head-on at 62.8 m/s, 0.39 of a step into
  the step after its launch. Per method: the held cube's and the striker's speed along
  the strike 0.025 s after it (m/s). The converged engine's friction holds the cube
  (pybullet at 256 times finer); at the user's step it does not.

Run
---
    python benchmarks/coarse_step.py        # about 5 s
"""

from __future__ import annotations

import os
import tempfile

import numpy as np
import pybullet as p

from bullet_boxccd import BoxCCD

DT = 1 / 240
METHODS = ("plain", "BoxCCD", "numSubSteps=16", "plain, dt/64", "plain, dt/128", "plain, dt/256")
GRIPPER = """<?xml version="1.0"?>
<robot name="gripper">
  <link name="palm">
    <inertial><mass value="1"/><inertia ixx="0.01" iyy="0.01" izz="0.01" ixy="0" ixz="0" iyz="0"/></inertial>
    <collision><geometry><box size="0.06 0.2 0.02"/></geometry></collision>
  </link>
  <link name="left">
    <inertial><mass value="0.1"/><inertia ixx="0.0001" iyy="0.0001" izz="0.0001" ixy="0" ixz="0" iyz="0"/></inertial>
    <collision><geometry><box size="0.04 0.01 0.1"/></geometry></collision>
  </link>
  <link name="right">
    <inertial><mass value="0.1"/><inertia ixx="0.0001" iyy="0.0001" izz="0.0001" ixy="0" ixz="0" iyz="0"/></inertial>
    <collision><geometry><box size="0.04 0.01 0.1"/></geometry></collision>
  </link>
  <joint name="left" type="prismatic">
    <parent link="palm"/><child link="left"/>
    <origin xyz="0 0.08 -0.06"/><axis xyz="0 -1 0"/>
    <limit lower="0" upper="0.07" effort="200" velocity="10"/>
  </joint>
  <joint name="right" type="prismatic">
    <parent link="palm"/><child link="right"/>
    <origin xyz="0 -0.08 -0.06"/><axis xyz="0 1 0"/>
    <limit lower="0" upper="0.07" effort="200" velocity="10"/>
  </joint>
</robot>
"""


def _box(cid, half, pos, mass, orn=(0, 0, 0, 1), **dynamics):
    shape = p.createCollisionShape(p.GEOM_BOX, halfExtents=list(half), physicsClientId=cid)
    body = p.createMultiBody(mass, shape, basePosition=list(pos), baseOrientation=list(orn), physicsClientId=cid)
    p.changeDynamics(body, -1, physicsClientId=cid, **dynamics)
    return body


def _stepper(cid, method):
    """A function taking one step of DT by ``method``."""
    if method == "BoxCCD":
        return BoxCCD(cid).step
    if method == "numSubSteps=16":
        p.setPhysicsEngineParameter(fixedTimeStep=DT, numSubSteps=16, physicsClientId=cid)
        return lambda: p.stepSimulation(physicsClientId=cid)
    fine = int(method.split("/")[1]) if "/" in method else 1
    p.setPhysicsEngineParameter(fixedTimeStep=DT / fine, physicsClientId=cid)

    def step():
        for _ in range(fine):
            p.stepSimulation(physicsClientId=cid)
    return step


def _energy(cid, body):
    mass, _, inertia = p.getDynamicsInfo(body, -1, physicsClientId=cid)[:3]
    v, w = (np.array(x) for x in p.getBaseVelocity(body, physicsClientId=cid))
    q = p.getBasePositionAndOrientation(body, physicsClientId=cid)[1]
    w_body = np.reshape(p.getMatrixFromQuaternion(q), (3, 3)).T @ w
    return 0.5 * mass * float(v @ v) + 0.5 * float(w_body @ (np.array(inertia) * w_body))


def rattle(seed, method):
    """(kinetic energy at the end / at launch, whether the plate left the box)."""
    cid = p.connect(p.DIRECT)
    try:
        rng = np.random.default_rng(seed)
        p.setGravity(0, 0, -9.81 if rng.random() < 0.5 else 0.0, physicsClientId=cid)
        inside, wall = 0.3, 0.005
        for axis in range(3):
            for side in (-1, 1):
                half, pos = [inside + wall] * 3, [0.0] * 3
                half[axis], pos[axis] = wall, side * (inside + wall)
                _box(cid, half, pos, 0.0, restitution=1.0, lateralFriction=0.3)
        speed, way = rng.uniform(30, 80), rng.normal(size=3)
        orn = rng.normal(size=4)
        plate = _box(cid, [0.04, 0.04, 0.02], rng.uniform(-0.15, 0.15, 3), 0.5, orn / np.linalg.norm(orn),
                     restitution=0.9, lateralFriction=0.3, linearDamping=0, angularDamping=0, maxJointVelocity=1e4)
        p.resetBaseVelocity(plate, (speed * way / np.linalg.norm(way)).tolist(), rng.normal(0, 20, 3).tolist(),
                            physicsClientId=cid)
        launch, left = _energy(cid, plate), False
        step = _stepper(cid, method)
        for _ in range(60):
            step()
            left |= max(map(abs, p.getBasePositionAndOrientation(plate, physicsClientId=cid)[0])) > inside + 0.01
        return _energy(cid, plate) / launch, left
    finally:
        p.disconnect(cid)


def grip(method, urdf):
    """(the held cube's, the striker's velocity along the strike) 0.025 s after it."""
    cid = p.connect(p.DIRECT)
    try:
        p.setGravity(0, 0, -9.81, physicsClientId=cid)
        gripper = p.loadURDF(urdf, [0, 0, 0.5], useFixedBase=True, physicsClientId=cid)
        for joint in (0, 1):
            p.changeDynamics(gripper, joint, lateralFriction=1.0, physicsClientId=cid)
            p.resetJointState(gripper, joint, 0.045, physicsClientId=cid)
        cube = _box(cid, [0.03] * 3, [0, 0, 0.44], 0.1947, restitution=0.5, lateralFriction=1.0)
        striker = _box(cid, [0.015] * 3, [-5, 0, 0.44], 0.2503, restitution=0.0, lateralFriction=0.5,
                       activationState=p.ACTIVATION_STATE_DISABLE_SLEEPING)
        p.setJointMotorControlArray(gripper, [0, 1], p.POSITION_CONTROL, targetPositions=[0.07, 0.07],
                                    forces=[26.85, 26.85], physicsClientId=cid)
        step = _stepper(cid, method)
        for k in range(30):
            if k == 24:  # the striker thrown to touch the held cube 1.39 steps later
                x, y, z = p.getBasePositionAndOrientation(cube, physicsClientId=cid)[0]
                d = 1.39122819 * DT
                p.resetBasePositionAndOrientation(striker, [x - 0.045 - 62.84 * d, y, z + 0.5 * 9.81 * d * d],
                                                  [0, 0, 0, 1], physicsClientId=cid)
                p.resetBaseVelocity(striker, [62.84, 0, 0], [0, 0, 0], physicsClientId=cid)
            step()
        return tuple(p.getBaseVelocity(b, physicsClientId=cid)[0][0] for b in (cube, striker))
    finally:
        p.disconnect(cid)


def main():
    seeds = range(6)
    print("A plate rattling in a closed box of 1 cm walls, 0.25 s at 240 Hz: kinetic energy at the end over its "
          "launch's per seed (* : it left the box)\n")
    print("| method | " + " | ".join(f"seed {s}" for s in seeds) + " |\n|---|" + "---|" * len(seeds))
    for method in METHODS[:3] + ("plain, dt/128",):
        cells = []
        for seed in seeds:
            gain, left = rattle(seed, method)
            cells.append(f"{gain:.3g}" + (" *" if left else ""))
        print(f"| {method} | " + " | ".join(cells) + " |")
    print("\nA cube held by a gripper (26.9 N, friction 1), struck head-on at 62.8 m/s: speeds along the strike "
          "0.025 s after it (m/s)\n")
    print("| method | held cube | striker |\n|---|---|---|")
    with tempfile.TemporaryDirectory() as folder:
        urdf = os.path.join(folder, "gripper.urdf")
        with open(urdf, "w") as f:
            f.write(GRIPPER)
        for method in METHODS:
            held, striker = grip(method, urdf)
            print(f"| {method} | {held:.1f} | {striker:.1f} |")


if __name__ == "__main__":
    main()
