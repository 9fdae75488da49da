"""The seeded scenes of benchmarks/fidelity.py (and tests/test_fidelity.py), one family each.

Every family has three small functions:

* ``build(w, rng, variant) -> s``: make the scene in the world ``w`` (a ``World``: its
  pybullet client is ``w.cid``; ``w.box``/``w.urdf`` make bodies, in maximal coordinates
  for the native-CCD method) and return its handles ``s`` (a namespace: the bodies, the
  number of coarse steps ``s.steps`` to run, an optional ``s.control(w, s, t, h)`` called
  before every solver step of h seconds starting at time t, and what ``observe`` records),
* ``observe(w, s, k)``: after coarse step k (at time ``w.t``), record what the figures need,
* ``measure(w, s) -> dict``: the run's numbers (floats, bools, small arrays).

and a ``Family`` entry in ``FAMILIES`` with its step, the reference's refinement K, the
seeds, the figures (statistics over seeds, each with the tolerance the reference must
converge to) and the error scalar (a method's distance from the reference) of the plot.

Every dynamic body gets linearDamping = angularDamping = 0 and maxJointVelocity = 1e4
(pybullet clamps velocities to 100 by default); restitution and friction are set where
the family says so (pybullet multiplies the two bodies' restitutions).
"""

from __future__ import annotations

import math
import os
from dataclasses import dataclass
from types import SimpleNamespace
from typing import Callable

import numpy as np
import pybullet as p
import pybullet_data

DATA = pybullet_data.getDataPath()
G = 9.81
TABLE_TOP = 0.625  # table/table.urdf at the origin: its top is a 1.5 x 1 x 0.05 m box centred at z = 0.6
TABLE_MID = 0.6
TRAY_FLOOR = (-0.005, 0.015)  # tray/traybox.urdf at the origin: a 0.6 x 0.6 x 0.02 m floor box


# ------------------------------------------------------------------- world
class World:
    """One pybullet client set up for one run: the coarse step ``dt``, the solver step ``h``,
    whether bodies are made in maximal coordinates (native CCD), and the dynamic frames
    (body, link, smallest half extent) that native CCD gives a swept sphere."""

    def __init__(self, cid, dt, h, maximal=False):
        self.cid, self.dt, self.h, self.maximal = cid, dt, h, maximal
        self.dynamic = []
        self.t = 0.0

    def box(self, half, pos, mass=0.0, orn=(0, 0, 0, 1), e=None, mu=None):
        col = p.createCollisionShape(p.GEOM_BOX, halfExtents=list(half), physicsClientId=self.cid)
        b = p.createMultiBody(mass, col, -1, basePosition=list(pos), baseOrientation=list(orn),
                              useMaximalCoordinates=self.maximal, physicsClientId=self.cid)
        self.dynamics(b, -1, mass, min(half), e, mu)
        return b

    def urdf(self, name, pos, orn=(0, 0, 0, 1), half=None, e=None, mu=None):
        """A pybullet_data URDF (one link); ``half``: its smallest half extent if it is dynamic."""
        b = p.loadURDF(os.path.join(DATA, name), list(pos), list(orn), useMaximalCoordinates=self.maximal,
                       physicsClientId=self.cid)
        mass = p.getDynamicsInfo(b, -1, physicsClientId=self.cid)[0]
        self.dynamics(b, -1, mass, half, e, mu)
        return b

    def dynamics(self, b, link, mass, half, e=None, mu=None):
        kw = {}
        if e is not None:
            kw["restitution"] = e
        if mu is not None:
            kw["lateralFriction"] = mu
        if mass > 0:
            kw.update(linearDamping=0.0, angularDamping=0.0, maxJointVelocity=1e4)
            self.dynamic.append((b, link, half))
        if kw:
            p.changeDynamics(b, link, physicsClientId=self.cid, **kw)

    def gravity(self, gz):
        p.setGravity(0, 0, gz, physicsClientId=self.cid)

    def pos(self, b):
        return np.array(p.getBasePositionAndOrientation(b, physicsClientId=self.cid)[0])

    def vel(self, b):
        v, w = p.getBaseVelocity(b, physicsClientId=self.cid)
        return np.array(v), np.array(w)

    def set_vel(self, b, v, w=(0, 0, 0)):
        p.resetBaseVelocity(b, list(map(float, v)), list(map(float, w)), physicsClientId=self.cid)

    def energy(self, b):
        """Kinetic energy of a one-link body (the inertia diagonal in the principal frame)."""
        info = p.getDynamicsInfo(b, -1, physicsClientId=self.cid)
        m, inertia, q_local = info[0], np.array(info[2]), info[4]
        v, w = self.vel(b)
        q = p.multiplyTransforms((0, 0, 0), p.getBasePositionAndOrientation(b, physicsClientId=self.cid)[1],
                                 (0, 0, 0), q_local)[1]
        R = np.array(p.getMatrixFromQuaternion(q)).reshape(3, 3)
        wl = R.T @ w
        return 0.5 * m * v @ v + 0.5 * wl @ (inertia * wl)

    def depth(self, a, b):
        """Penetration depth of a and b now (-min getClosestPoints distance; 0 if apart)."""
        pts = p.getClosestPoints(a, b, 0.0, physicsClientId=self.cid)
        return max((-c[8] for c in pts), default=0.0)

    def near(self, b, candidates):
        """The bodies of ``candidates`` whose bounds overlap b's."""
        lo, hi = p.getAABB(b, -1, physicsClientId=self.cid)
        over = p.getOverlappingObjects(lo, hi, physicsClientId=self.cid) or ()
        return {o for o, _ in over if o in candidates}


def unit(rng, n=None):
    v = rng.normal(size=3 if n is None else (n, 3))
    return v / np.linalg.norm(v, axis=-1, keepdims=True)


def quat(rng):
    q = rng.normal(size=4)
    return (q / np.linalg.norm(q)).tolist()


def yaw_quat(deg):
    return p.getQuaternionFromEuler([0.0, 0.0, math.radians(deg)])


def med(x):
    x = np.asarray(x, dtype=float)
    return float(np.median(x)) if x.size else math.nan


def q25(x):
    x = np.asarray(x, dtype=float)
    return float(np.percentile(x, 25)) if x.size else math.nan


def q75(x):
    x = np.asarray(x, dtype=float)
    return float(np.percentile(x, 75)) if x.size else math.nan


def all_of(rs, key):
    """The values of ``key`` over the seeds (a list per seed is concatenated)."""
    out = []
    for r in rs:
        v = r[key]
        out.extend(np.ravel(v).tolist())
    return np.array(out, dtype=float)


def paired(rs, refs, key):
    """Per entry |a - b| of ``key`` between a method's seeds and the reference's (vectors: norm
    along the last axis), flattened."""
    d = []
    for a, b in zip(rs, refs):
        x, y = np.asarray(a[key], dtype=float), np.asarray(b[key], dtype=float)
        d.extend(np.ravel(np.linalg.norm(np.atleast_1d(x - y).reshape(-1, x.shape[-1] if x.ndim else 1),
                                         axis=-1)).tolist())
    return np.array(d)


# ------------------------------------------------------- 1. head-on, thick wall
HEAD_ON_VARIANTS = [f"e={e:g} {m}" for e in (1.0, 0.5, 0.0) for m in ("straight", "tilt10", "spin20")]


def head_on_build(w, rng, variant, speed=None, frac=None, spin_axis=None):
    """A 0.4 m cube (mass 1) at a static wall 0.2 m thick (the slab 0 <= x <= 0.2), no gravity,
    friction 0.5, restitution e on both bodies. The cube's front reaches the wall at
    (2 + frac) steps (frac seeded in [0.05, 0.95]: mid-step), speed 50-300 m/s along +x;
    ``tilt10``: turned 10 deg about z; ``spin20``: spinning at 20 rad/s about a seeded axis."""
    e = float(variant.split()[0][2:])
    motion = variant.split()[1]
    speed = rng.uniform(50.0, 300.0) if speed is None else speed
    frac = rng.uniform(0.05, 0.95) if frac is None else frac
    axis = unit(rng) if spin_axis is None else np.asarray(spin_axis, float)
    w.gravity(0.0)
    wall = w.box((0.1, 2.0, 2.0), (0.1, 0.0, 0.0), 0.0, e=e, mu=0.5)
    yaw = 10.0 if motion == "tilt10" else 0.0
    reach = 0.2 * (math.cos(math.radians(yaw)) + math.sin(math.radians(yaw)))  # x half-extent of the turned cube
    spin = 20.0 * axis if motion == "spin20" else np.zeros(3)
    cube = w.box((0.2,) * 3, (-reach - speed * w.dt * (2.0 + frac), 0.0, 0.0), 1.0, yaw_quat(yaw), e=e, mu=0.5)
    w.set_vel(cube, (speed, 0, 0), spin)
    return SimpleNamespace(wall=wall, cube=cube, speed=speed, steps=14)


def head_on_observe(w, s, k):
    pass


def head_on_measure(w, s):
    v, _ = w.vel(s.cube)
    return dict(v=v, speed=s.speed, rebound=-v[0] / s.speed, tunneled=bool(w.pos(s.cube)[0] > 0.1))


# ---------------------------------------------- 2. spinning cubes, thin wall
def spinning_build(w, rng, variant):
    """A 0.1 m cube (mass 1), turned at random, spin ~N(0, 30) rad/s per axis, at 20-300
    m/s along +x into a static wall 1 cm thick (0 <= x <= 0.01, 4 x 4 m), restitution 1,
    friction 0; the front reaches the wall at (2 + U(0.05, 0.95)) steps; gravity on."""
    speed, frac = rng.uniform(20.0, 300.0), rng.uniform(0.05, 0.95)
    orn, spin = quat(rng), rng.normal(0.0, 30.0, 3)
    wall = w.box((0.005, 2.0, 2.0), (0.005, 0.0, 0.0), 0.0, e=1.0, mu=0.0)
    cube = w.box((0.05,) * 3, (-0.05 * math.sqrt(3) - speed * w.dt * (2.0 + frac), 0.0, 0.0), 1.0, orn, e=1.0,
                 mu=0.0)
    w.set_vel(cube, (speed, 0, 0), spin)
    s = SimpleNamespace(wall=wall, cube=cube, speed=speed, steps=3 + int(0.1 / w.dt), ke0=None, touching=False)
    s.ke0 = w.energy(cube)
    return s


def spinning_observe(w, s, k):
    s.touching = bool(p.getClosestPoints(s.cube, s.wall, 0.002, physicsClientId=w.cid))


def spinning_measure(w, s):
    v, _ = w.vel(s.cube)
    x = w.pos(s.cube)[0]
    return dict(rebound=float(np.linalg.norm(v)) / s.speed, ke=w.energy(s.cube) / s.ke0,
                tunneled=bool(x > 0.005), touching=s.touching)


# ------------------------------------------------------ 3. table throws
def table_build(w, rng, variant):
    """pybullet_data cube_small (5 cm, 0.1 kg) thrown straight down at table/table.urdf at
    80-200 m/s, restitution 0 on both, spin ~N(0, 20) rad/s per axis, over a seeded point of
    the top; its lowest point reaches the top at (2 + U(0.05, 0.95)) steps. Figures over the
    0.5 s after the impact."""
    speed, frac = rng.uniform(80.0, 200.0), rng.uniform(0.05, 0.95)
    xy = rng.uniform(-0.3, 0.3, 2)
    orn, spin = quat(rng), rng.normal(0.0, 20.0, 3)
    table = w.urdf("table/table.urdf", (0, 0, 0), e=0.0)
    z0 = TABLE_TOP + 0.025 * math.sqrt(3) + speed * w.dt * (2.0 + frac)
    cube = w.urdf("cube_small.urdf", (xy[0], xy[1], z0), orn, half=0.025, e=0.0)
    w.set_vel(cube, (0, 0, -speed), spin)
    t_hit = (z0 - TABLE_TOP - 0.025) / speed
    return SimpleNamespace(table=table, cube=cube, speed=speed, t_hit=t_hit, steps=int(math.ceil((t_hit + 0.5) / w.dt)),
                           rise=0.0, through=False, prev=w.pos(cube), xy_hit=None, hit=False)


def _over_top(c):
    return abs(c[0]) < 0.75 and abs(c[1]) < 0.5


def table_observe(w, s, k):
    c = w.pos(s.cube)
    if s.prev[2] > TABLE_MID >= c[2]:  # crossed the top's mid-plane within its outline
        m = s.prev + (c - s.prev) * (s.prev[2] - TABLE_MID) / (s.prev[2] - c[2])
        s.through |= _over_top(m)
    s.prev = c
    if not s.hit and w.t >= s.t_hit:
        s.hit, s.xy_hit = True, c[:2].copy()
    if s.hit and w.t <= s.t_hit + 0.1 + 1e-9:
        s.rise = max(s.rise, w.vel(s.cube)[0][2])


def table_measure(w, s):
    c = w.pos(s.cube)
    return dict(rise=s.rise, travel=float(np.linalg.norm(c[:2] - s.xy_hit)),
                through=bool(s.through or (c[2] < TABLE_MID and _over_top(c))))



# ---------------------------------------------- 9. glancing impacts
def glancing_build(w, rng, variant):
    """A 0.1 m cube (mass 1, restitution 0.5, friction 0.5), not spinning, turned at random
    about z and tipped up to 5 deg, at 50-200 m/s along +x and 5-15 deg below the
    horizontal, at a static floor 1 cm thick (top z = 0, 100 x 10 m, restitution 1,
    friction 1); its lowest point reaches the floor at (2 + U(0.05, 0.95)) steps. Figures
    over the 0.1 s after: the rebound (the highest upward speed over the normal speed it
    struck with) and the kinetic energy ratio."""
    speed, frac, slope = rng.uniform(50.0, 200.0), rng.uniform(0.05, 0.95), math.radians(rng.uniform(5.0, 15.0))
    orn = p.getQuaternionFromEuler([math.radians(rng.uniform(-5.0, 5.0)), math.radians(rng.uniform(-5.0, 5.0)),
                                    rng.uniform(-math.pi, math.pi)])
    floor = w.box((50.0, 5.0, 0.005), (30.0, 0.0, -0.005), 0.0, e=1.0, mu=1.0)
    R = np.array(p.getMatrixFromQuaternion(orn)).reshape(3, 3)
    low = float(np.sum(np.abs(R[2]) * 0.05))  # the centre's height over its lowest point
    t_hit = (2.0 + frac) * w.dt
    v = speed * np.array([math.cos(slope), 0.0, -math.sin(slope)])
    pos = np.array([0.0, 0.0, low]) - v * t_hit + np.array([0.0, 0.0, 0.5 * G * t_hit ** 2])
    cube = w.box((0.05,) * 3, pos, 1.0, orn, e=0.5, mu=0.5)
    w.set_vel(cube, v)
    s = SimpleNamespace(floor=floor, cube=cube, vn=speed * math.sin(slope) + G * t_hit, t_hit=t_hit, rise=0.0,
                        through=False, steps=int(math.ceil((t_hit + 0.1) / w.dt)))
    s.ke0 = w.energy(cube)
    return s


def glancing_observe(w, s, k):
    z = w.pos(s.cube)[2]
    s.through |= z < -0.01
    if w.t > s.t_hit:
        s.rise = max(s.rise, w.vel(s.cube)[0][2])


def glancing_measure(w, s):
    return dict(rebound=s.rise / s.vn, ke=w.energy(s.cube) / s.ke0, through=bool(s.through))

# ----------------------------------------------------- 4. planks on tiles
TILE, N_TILES = 0.5, 12  # a 12 x 12 floor of 0.5 m tiles (6 x 6 m), 2 cm thick, top at z = 0


def planks_build(w, rng, variant):
    """Six 5 x 5 cm planks 0.4-1.5 m long (mass = length in m, kg), turned at random, dropped
    from rest at 2-10 m (centres within 1.2 m of the middle) over a floor of 144 static box tiles
    (0.5 x 0.5 m, 2 cm thick, top at z = 0) covering 6 x 6 m; the step is 1/60 s. Run until 1 s
    after the last lands. Tunneled: a centre below the tiles over the floor (one that slid off
    the edge is not counted). Thrown: a centre that ends farther than 0.5 m from lying on the
    tiles (off the floor, or still in the air a second after the last landing)."""
    tiles = set()
    for i in range(N_TILES):
        for j in range(N_TILES):
            tiles.add(w.box((TILE / 2, TILE / 2, 0.01), ((i + 0.5 - N_TILES / 2) * TILE,
                                                        (j + 0.5 - N_TILES / 2) * TILE, -0.01)))
    planks = []
    for _ in range(6):
        length = rng.uniform(0.4, 1.5)
        pos = (rng.uniform(-1.2, 1.2), rng.uniform(-1.2, 1.2), rng.uniform(2.0, 10.0))
        planks.append(w.box((length / 2, 0.025, 0.025), pos, length, quat(rng)))
    fall = math.sqrt(2 * 10.0 / G)
    return SimpleNamespace(tiles=tiles, planks=planks, steps=int(math.ceil((fall + 1.0) / w.dt)), deepest=0.0)


def planks_observe(w, s, k):
    for b in s.planks:
        for t in w.near(b, s.tiles):
            s.deepest = max(s.deepest, w.depth(b, t))


def planks_measure(w, s):
    c = np.array([w.pos(b) for b in s.planks])
    over = np.all(np.abs(c[:, :2]) < TILE * N_TILES / 2, axis=1)
    return dict(deepest=s.deepest, height=c[:, 2], tunneled=int(np.sum((c[:, 2] < -0.02) & over)),
                thrown=int(np.sum(np.abs(c[:, 2] - 0.025) > 0.5)))


# ------------------------------------------------------------------ 5. rain
def rain_build(w, rng, variant):
    """``variant`` boxes (jenga pieces 15 x 5 x 3 cm and cube_small 5 cm, alternately) on a
    grid 17 cm apart (16 a layer, layers 0.4 m apart from 1 m up), turned at random, spin
    ~N(0, 10), thrown down at 20-60 m/s (+-2 m/s across) into tray/traybox.urdf, over a
    static ground box (40 x 40 m, 2 cm thick, top at z = -0.005, under the tray). Run 0.4 s. Rise: a
    box's fastest upward velocity over the run (its rebounds off the tray and the others);
    spun: boxes that turned faster than 2000 rad/s (pybullet's gyroscopic term at a coarse
    step spins a fast-turning jenga piece up to its velocity clamp)."""
    n = int(variant)
    tray = w.urdf("tray/traybox.urdf", (0, 0, 0))
    ground = w.box((20.0, 20.0, 0.01), (0, 0, -0.015))
    side = 4 if n <= 48 else int(math.ceil(math.sqrt(n / 3)))
    per = side * side
    boxes = []
    for i in range(n):
        layer, r = divmod(i, per)
        gx, gy = divmod(r, side)
        pos = ((gx - (side - 1) / 2) * 0.17, (gy - (side - 1) / 2) * 0.17, 1.0 + 0.4 * layer)
        if i % 2:
            b = w.urdf("jenga/jenga.urdf", pos, quat(rng), half=0.015)
        else:
            b = w.urdf("cube_small.urdf", pos, quat(rng), half=0.025)
        w.set_vel(b, (rng.uniform(-2, 2), rng.uniform(-2, 2), -rng.uniform(20.0, 60.0)), rng.normal(0, 10, 3))
        boxes.append(b)
    steps = int(round(0.4 / w.dt)) if n <= 48 else 40
    return SimpleNamespace(tray=tray, ground=ground, boxes=boxes, steps=steps, deepest=0.0, track=n <= 48,
                           rise=np.zeros(n), spin=np.zeros(n))


def rain_observe(w, s, k):
    if s.track:
        for i, b in enumerate(s.boxes):
            s.deepest = max(s.deepest, w.depth(b, s.tray))
            v, omega = w.vel(b)
            s.rise[i] = max(s.rise[i], v[2])
            s.spin[i] = max(s.spin[i], float(np.linalg.norm(omega)))


def _under_tray(c):
    """Centre ``c`` below the tray's floor within it, or below the ground within its 40 x 40 m
    (a box thrown off the ground's edge fell past it, not through it)."""
    return ((c[2] < TRAY_FLOOR[0] and abs(c[0]) < 0.3 and abs(c[1]) < 0.3)
            or (c[2] < -0.025 and abs(c[0]) < 20.0 and abs(c[1]) < 20.0))


def rain_measure(w, s):
    cs = [w.pos(b) for b in s.boxes]
    return dict(tunneled=int(sum(_under_tray(c) for c in cs)), deepest=s.deepest, rise=s.rise,
                spun=int(np.sum(s.spin > 2000.0)),
                in_tray=int(sum(c[2] > TRAY_FLOOR[0] and abs(c[0]) < 0.3 and abs(c[1]) < 0.3 for c in cs)))


# ---------------------------------------------------------- 6a. box-link arm
def _multibody(w, base_mass, base_half, base_pos, links):
    """createMultiBody of box links and revolute joints. links: [(mass, half extents, parent
    (0 = base, i = link i - 1), joint position in the parent's link frame, box centre in the
    link's frame (also its centre of mass), joint axis)]; a link's frame sits at its joint."""
    cid = w.cid

    def shape(h, c=(0, 0, 0)):
        return p.createCollisionShape(p.GEOM_BOX, halfExtents=list(h), collisionFramePosition=list(c),
                                      physicsClientId=cid)

    b = p.createMultiBody(
        base_mass, shape(base_half), -1, basePosition=list(base_pos),
        linkMasses=[lk[0] for lk in links], linkCollisionShapeIndices=[shape(lk[1], lk[4]) for lk in links],
        linkVisualShapeIndices=[-1] * len(links), linkPositions=[list(lk[3]) for lk in links],
        linkOrientations=[[0, 0, 0, 1]] * len(links), linkInertialFramePositions=[list(lk[4]) for lk in links],
        linkInertialFrameOrientations=[[0, 0, 0, 1]] * len(links), linkParentIndices=[lk[2] for lk in links],
        linkJointTypes=[p.JOINT_REVOLUTE] * len(links), linkJointAxis=[list(lk[5]) for lk in links],
        physicsClientId=cid)
    w.dynamics(b, -1, base_mass, min(base_half))
    for j, lk in enumerate(links):
        w.dynamics(b, j, lk[0], min(lk[1]))
    return b


def _motors(w, body, targets, force, max_velocity):
    """POSITION_CONTROL with positionGain = velocityGain = 1: pybullet's motor then asks for
    the velocity (target - angle) / h, clamped to max_velocity, so the motion is the same
    physical one (at max_velocity, then stop at the target) at every solver step h."""
    for j, q in enumerate(targets):
        p.setJointMotorControl2(body, j, p.POSITION_CONTROL, targetPosition=float(q), force=force,
                                positionGain=1.0, velocityGain=1.0, maxVelocity=max_velocity, physicsClientId=w.cid)


def arm_build(w, rng, variant):
    """A two-link arm of boxes (createMultiBody): a static pedestal, a shoulder (revolute
    about y) at x = -0.4, 4 cm above the cube's top, upper arm and forearm 0.5 m each (8 x 8
    cm, 2 kg and 1 kg), the elbow held straight. The shoulder starts at -90 deg (arm up) and
    is driven by POSITION_CONTROL (1000 N m) at 30-60 rad/s (tip 30-60 m/s) to 20-40 deg below
    horizontal, onto pybullet_data's cube_small resting on table/table.urdf at x in [0, 0.5],
    y in [-0.06, 0.06] (the arm's half width plus the cube's is 0.065: some strikes are glancing),
    turned up to 20 deg about z. Run 0.3 s."""
    if w.maximal:
        raise NotImplementedError("maximal coordinates have no joints")
    table = w.urdf("table/table.urdf", (0, 0, 0))
    xc, yc, yaw = rng.uniform(0.0, 0.5), rng.uniform(-0.06, 0.06), rng.uniform(-20, 20)
    cube = w.urdf("cube_small.urdf", (xc, yc, TABLE_TOP + 0.025), yaw_quat(yaw), half=0.025)
    omega, below = rng.uniform(30.0, 60.0), math.radians(rng.uniform(20.0, 40.0))
    links = [(2.0, (0.25, 0.04, 0.04), 0, (0, 0, 0), (0.25, 0, 0), (0, 1, 0)),
             (1.0, (0.25, 0.04, 0.04), 1, (0.5, 0, 0), (0.25, 0, 0), (0, 1, 0))]
    arm = _multibody(w, 0.0, (0.05, 0.05, 0.05), (-0.4, 0.0, TABLE_TOP + 0.05 + 0.04), links)
    p.resetJointState(arm, 0, -math.pi / 2, physicsClientId=w.cid)
    _motors(w, arm, [below, 0.0], 1000.0, omega)
    return SimpleNamespace(table=table, cube=cube, arm=arm, tip=omega * 1.0, steps=int(round(0.3 / w.dt)),
                           prev=w.pos(cube), through=False, vmax=0.0)


def arm_observe(w, s, k):
    c = w.pos(s.cube)
    if s.prev[2] > TABLE_MID >= c[2] and _over_top(c):
        s.through = True
    s.prev = c
    s.vmax = max(s.vmax, float(np.linalg.norm(w.vel(s.cube)[0])))


def arm_measure(w, s):
    v, _ = w.vel(s.cube)
    c = w.pos(s.cube)
    return dict(v=v, speed=float(np.linalg.norm(v)), tip=s.tip, vmax=s.vmax,
                through=bool(s.through or (c[2] < TABLE_MID and _over_top(c))))


# ---------------------------------------------------------- 6b. box-link biped
def biped_build(w, rng, variant):
    """A 12-joint biped of boxes (createMultiBody): a 5 kg pelvis (0.2 x 0.3 x 0.1 m), per
    leg hip yaw (z), hip roll (x) and hip pitch (y) joints, a 0.4 m thigh, knee (y), a 0.4 m
    shin, ankle pitch (y) and roll (x), a 0.2 x 0.1 x 0.03 m foot; every joint held at 0 by
    POSITION_CONTROL (200 N m, at most 10 rad/s). Dropped with the pelvis 1.5-4 m up, tilted
    up to 0.5 rad, moving down at 0-8 m/s (+-2 across, spin ~N(0, 2)), onto a static box floor
    1 cm thick (top at z = 0). The step is 0.1 s; run 2 s."""
    if w.maximal:
        raise NotImplementedError("maximal coordinates have no joints")
    floor = w.box((20.0, 20.0, 0.005), (0, 0, -0.005))
    small = (0.02, 0.02, 0.02)
    links = []
    for s in (-1, 1):
        k = len(links)  # this leg's first link is link k (parent index k + 1)
        links += [(0.5, small, 0, (0, 0.1 * s, -0.05), (0, 0, -0.02), (0, 0, 1)),
                  (0.5, small, k + 1, (0, 0, -0.04), (0, 0, -0.02), (1, 0, 0)),
                  (3.0, (0.04, 0.04, 0.2), k + 2, (0, 0, -0.04), (0, 0, -0.2), (0, 1, 0)),
                  (2.0, (0.035, 0.035, 0.2), k + 3, (0, 0, -0.4), (0, 0, -0.2), (0, 1, 0)),
                  (0.3, small, k + 4, (0, 0, -0.4), (0, 0, -0.02), (0, 1, 0)),
                  (0.5, (0.1, 0.05, 0.015), k + 5, (0, 0, -0.04), (0.03, 0, -0.015), (1, 0, 0))]
    robot = _multibody(w, 5.0, (0.1, 0.15, 0.05), (0, 0, 1.0 + rng.uniform(0.5, 3.0)), links)
    orn = p.getQuaternionFromEuler([rng.uniform(-0.5, 0.5), rng.uniform(-0.5, 0.5), rng.uniform(-math.pi, math.pi)])
    p.resetBasePositionAndOrientation(robot, w.pos(robot).tolist(), orn, physicsClientId=w.cid)
    w.set_vel(robot, (rng.uniform(-2, 2), rng.uniform(-2, 2), -rng.uniform(0, 8)), rng.normal(0, 2, 3))
    _motors(w, robot, [0.0] * len(links), 200.0, 10.0)
    return SimpleNamespace(floor=floor, robot=robot, steps=int(round(2.0 / w.dt)), vmax=0.0)


def biped_observe(w, s, k):
    s.vmax = max(s.vmax, float(np.linalg.norm(w.vel(s.robot)[0])))


def biped_measure(w, s):
    v, _ = w.vel(s.robot)
    return dict(speed=float(np.linalg.norm(v)), vmax=s.vmax, below=bool(w.pos(s.robot)[2] < 0.0))


# ---------------------------------------------------------- 7. kinematic pusher
def pusher_build(w, rng, variant):
    """A static (mass 0) box 0.2 x 0.6 x 0.2 m, 1 cm above a static ground box, moved along +x
    at 20-50 m/s (resetBaseVelocity before every solver step: pybullet moves a mass-0
    multibody base by its velocity; in maximal coordinates, for native CCD, it is teleported
    to its scheduled pose too) for 2 m (a whole number of steps), then held still, through a
    row of five free 0.1 m cubes (mass 1) resting 0.3 m apart on the ground, friction 0.5.
    Run until 0.05 s after the pusher stops."""
    ground = w.box((20.0, 3.0, 0.01), (5.0, 0, -0.01), mu=0.5)
    x0 = -0.5
    pusher = w.box((0.1, 0.3, 0.1), (x0, 0, 0.11), mu=0.5)
    cubes = [w.box((0.05,) * 3, (0.3 * i + rng.uniform(0, 0.1), rng.uniform(-0.1, 0.1), 0.05), 1.0,
                   yaw_quat(rng.uniform(-30, 30)), mu=0.5) for i in range(5)]
    n_move = max(1, int(round(2.0 / rng.uniform(20.0, 50.0) / w.dt)))
    T = n_move * w.dt
    return SimpleNamespace(ground=ground, pusher=pusher, cubes=cubes, x0=x0, v=2.0 / T, T=T,
                           steps=n_move + int(round(0.05 / w.dt)), control=pusher_control)


def pusher_control(w, s, t, h):
    v = s.v if t < s.T - 1e-9 else 0.0
    if w.maximal:  # a static rigid body is not moved by its velocity: teleport it (velocity zeroed)
        x = s.x0 + s.v * min(t, s.T)
        p.resetBasePositionAndOrientation(s.pusher, [x, 0, 0.11], [0, 0, 0, 1], physicsClientId=w.cid)
    w.set_vel(s.pusher, (v, 0, 0))


def pusher_observe(w, s, k):
    pass


def pusher_measure(w, s):
    front = w.pos(s.pusher)[0] + 0.1
    v = np.array([w.vel(c)[0] for c in s.cubes])
    return dict(v=v / s.v, speed=np.linalg.norm(v, axis=1) / s.v,
                behind=int(sum(w.pos(c)[0] < front for c in s.cubes)))


# ---------------------------------------------------------- 8. stack, side hit
def stack_build(w, rng, variant):
    """A column of six 0.1 m cubes (mass 1, friction 0.5) standing on a static ground box,
    hit from the side by a 0.1 m cube (mass 1) at 50-150 m/s along +x (up to 5 deg off, spin
    ~N(0, 10)), aimed at a seeded height of the column, reaching it at (2 + U(0.05, 0.95))
    steps (gravity compensated). Run 0.25 s after the impact."""
    ground = w.box((30.0, 30.0, 0.01), (0, 0, -0.01), mu=0.5)
    stack = [w.box((0.05,) * 3, (0, 0, 0.05 + 0.1 * i), 1.0, mu=0.5) for i in range(6)]
    speed, frac = rng.uniform(50.0, 150.0), rng.uniform(0.05, 0.95)
    a, b = math.radians(rng.uniform(-5, 5)), math.radians(rng.uniform(-5, 5))
    d = np.array([math.cos(a) * math.cos(b), math.sin(a) * math.cos(b), math.sin(b)])
    t_hit = (2.0 + frac) * w.dt
    aim = np.array([-0.1, rng.uniform(-0.03, 0.03), rng.uniform(0.05, 0.55)])
    pos = aim - speed * d * t_hit + np.array([0, 0, 0.5 * G * t_hit ** 2])
    proj = w.box((0.05,) * 3, pos, 1.0, yaw_quat(rng.uniform(-10, 10)), mu=0.5)
    w.set_vel(proj, speed * d, rng.normal(0, 10, 3))
    bodies = stack + [proj]
    s = SimpleNamespace(ground=ground, stack=stack, proj=proj, bodies=bodies, t_hit=t_hit,
                        steps=int(math.ceil((t_hit + 0.25) / w.dt)), ke_after=None)
    s.ke0 = sum(w.energy(b) for b in bodies)
    return s


def stack_observe(w, s, k):
    if s.ke_after is None and w.t >= s.t_hit + 0.05 - 1e-9:
        s.ke_after = sum(w.energy(b) for b in s.bodies)
        s.stack_ke = sum(w.energy(b) for b in s.stack)


def stack_measure(w, s):
    xy = np.array([w.pos(b)[:2] for b in s.stack])
    return dict(ke=s.ke_after / s.ke0, spread=float(np.mean(np.linalg.norm(xy, axis=1))),
                tunneled=bool(w.pos(s.proj)[0] > 0.05 and s.stack_ke < 0.01 * s.ke0))


# ------------------------------------------------------------------ registry
@dataclass
class Figure:
    """A statistic over a family's seeds: ``fn(rs)`` of one method's per-seed results, or, if
    ``paired``, ``fn(rs, refs)`` its distance from the reference's (0 for the reference
    itself); ``tol``: how close the reference at the step h/2 must come to it at h."""

    name: str
    fn: Callable
    tol: float
    paired: bool = False


@dataclass
class Family:
    key: str
    label: str
    dt: float
    K: int  # the reference's steps per coarse step (ref2: 2 K)
    seeds: int
    quick_seeds: int
    variants: list
    build: Callable
    observe: Callable
    measure: Callable
    figures: list  # Figure; the paired ones are errors against the reference
    error: Figure  # the plot's scalar (paired)
    unit: str  # of the error, for the plot
    phases: int = 1  # the reference: mean over this many offsets of its step grid
    native: bool = True  # False: no maximal-coordinate version (joints)
    cost_only: tuple = ()  # variants timed only (no reference)
    failure: str = "tunneled"  # the count figure of boxes through (drawn hollow in the plot if above the ref's)


def _rel_v(rs, refs):
    return paired(rs, refs, "v") / all_of(refs, "speed")


def _count(key):
    return lambda rs: float(sum(np.sum(r[key]) for r in rs))


def _pct(key, fn):
    return lambda rs: fn(all_of(rs, key))


def _quartiles(key, label, tol_median, tol_quartile):
    """The figures "<label> median", "<label> q25" and "<label> q75" of the measure ``key``."""
    return [Figure(f"{label} median", _pct(key, med), tol_median),
            Figure(f"{label} q25", _pct(key, q25), tol_quartile),
            Figure(f"{label} q75", _pct(key, q75), tol_quartile)]


def _diff_median(key):
    return lambda rs, refs: abs(med(all_of(rs, key)) - med(all_of(refs, key)))


# K per family, from ``fidelity.py --study``: the smallest power of two at which every figure
# at dt/2K is within its tolerance of dt/K. Measured (figure at dt/K for K = 32, 64, ..):
# head_on's median error 0.019, 0.007, 0.006, 0.004 vs dt/1024 (K = 512 for its tilted cases);
# spinning's median rebound 0.63, 0.87, 0.87, 0.84, 0.85 (256); table's median rise 5, 12, 14,
# 18, 18, 21, 22 m/s up to K = 2048 (512: within 3 m/s of 1024); planks' deepest penetration
# 6, 3, 0.6, 0.4 mm from K = 16 (128); rain, arm, biped, pusher, stack: within tolerance from
# K = 16 to 64 (64); glancing's median rebound 0.569, 0.546, 0.551, 0.556 from K = 64 (256).
FAMILIES = {f.key: f for f in [
    Family("head_on", "1 head-on 0.4 m cube, 0.2 m wall", 1 / 240, 512, 4, 1, HEAD_ON_VARIANTS,
           head_on_build, head_on_observe, head_on_measure,
           [Figure("rebound -vx/speed (median)", _pct("rebound", med), 0.01),
            Figure("tunneled", _count("tunneled"), 0.5),
            Figure("max |v-v_ref|/speed", lambda rs, refs: float(np.max(_rel_v(rs, refs))), 0.05, True)],
           Figure("median |v-v_ref|/speed", lambda rs, refs: med(_rel_v(rs, refs)), 0.01, True),
           "|v - v_ref| / impact speed (median)", phases=8),
    Family("spinning", "2 spinning 0.1 m cubes, 1 cm wall", 1 / 240, 256, 16, 6, ["-"],
           spinning_build, spinning_observe, spinning_measure,
           [*_quartiles("rebound", "rebound", 0.05, 0.08),
            *_quartiles("ke", "KE ratio", 0.05, 0.08),
            Figure("KE ratio max", _pct("ke", np.max), 0.1),
            Figure("tunneled", _count("tunneled"), 0.5)],
           Figure("|median rebound - ref|", _diff_median("rebound"), 0.05, True), "|median rebound - ref's|"),
    Family("table", "3 cube_small thrown at table.urdf", 1 / 240, 512, 12, 4, ["-"],
           table_build, table_observe, table_measure,
           [*_quartiles("rise", "rise m/s", 3.0, 4.0),
            Figure("rise m/s max", _pct("rise", np.max), 5.0),
            Figure("travel m median", _pct("travel", med), 2.0),
            Figure("fell through", _count("through"), 0.5)],
           Figure("|median rise - ref| m/s", _diff_median("rise"), 3.0, True), "|median rise - ref's| (m/s)",
           failure="fell through"),
    Family("planks", "4 planks on 2 cm tiles, 60 Hz", 1 / 60, 128, 6, 2, ["-"],
           planks_build, planks_observe, planks_measure,
           [Figure("deepest pen. m (max)", lambda rs: float(np.max(all_of(rs, "deepest"))), 0.002),
            Figure("deepest pen. m (median)", _pct("deepest", med), 0.001),
            Figure("rest height m (median)", _pct("height", med), 0.005),
            Figure("mean |h - median h_ref| m",
                   lambda rs, refs: float(np.mean(np.abs(all_of(rs, "height") - med(all_of(refs, "height"))))), 0.01,
                   True),
            Figure("tunneled", _count("tunneled"), 0.5),
            Figure("thrown", _count("thrown"), 0.5)],
           Figure("thrown fraction - ref's",
                  lambda rs, refs: (_count("thrown")(rs) - _count("thrown")(refs)) / (6.0 * len(rs)), 0.03, True),
           "planks thrown off the tiles or up, fraction - ref's"),
    Family("rain", "5 rain of 48 boxes into traybox", 1 / 240, 64, 4, 1, ["48", "100", "1000"],
           rain_build, rain_observe, rain_measure,
           [Figure("tunneled", _count("tunneled"), 0.5),
            Figure("deepest pen. m (max)", lambda rs: float(np.max(all_of(rs, "deepest"))), 0.003),
            Figure("in tray (median)", _pct("in_tray", med), 3.0),
            Figure("rise m/s (median)", _pct("rise", med), 0.5),
            Figure("rise m/s q75", _pct("rise", q75), 1.0),
            Figure("spun past 2000 rad/s", _count("spun"), 0.5)],
           Figure("tunneled fraction - ref's",
                  lambda rs, refs: (_count("tunneled")(rs) - _count("tunneled")(refs)) / (48.0 * len(rs)), 0.01,
                  True), "tunneled fraction - ref's", cost_only=("100", "1000")),
    Family("arm", "6a box-link arm strikes cube_small", 1 / 240, 64, 8, 2, ["-"],
           arm_build, arm_observe, arm_measure,
           [Figure("cube final speed m/s (median)", _pct("speed", med), 0.5),
            Figure("cube max speed m/s (median)", _pct("vmax", med), 0.5),
            Figure("cube max speed m/s (max)", _pct("vmax", np.max), 1.0),
            Figure("pressed through", _count("through"), 0.5),
            Figure("median |v-v_ref| m/s", lambda rs, refs: med(paired(rs, refs, "v")), 0.5, True)],
           Figure("|median max speed - ref| m/s", _diff_median("vmax"), 0.5, True),
           "|median cube max speed - ref's| (m/s)", native=False,
           failure="pressed through"),
    Family("biped", "6b 12-joint biped, 0.1 s step", 0.1, 64, 8, 2, ["-"],
           biped_build, biped_observe, biped_measure,
           [Figure("final base speed m/s (median)", _pct("speed", med), 0.2),
            Figure("final base speed m/s (max)", _pct("speed", np.max), 0.2),
            Figure("max base speed m/s (median)", _pct("vmax", med), 0.5),
            Figure("max base speed m/s (max)", _pct("vmax", np.max), 0.5),
            Figure("ended below floor", _count("below"), 0.5)],
           Figure("max |final speed - ref's| m/s", lambda rs, refs: float(np.max(paired(rs, refs, "speed"))), 0.2,
                  True), "max over seeds |final base speed - ref's| (m/s)", native=False, failure="ended below floor"),
    Family("pusher", "7 kinematic pusher through 5 cubes", 1 / 240, 64, 8, 2, ["-"],
           pusher_build, pusher_observe, pusher_measure,
           [Figure("cube speed/pusher (median)", _pct("speed", med), 0.05),
            Figure("cube speed/pusher (mean)", _pct("speed", np.mean), 0.05),
            Figure("behind the pusher", _count("behind"), 0.5)],
           Figure("|mean cube speed - ref|/pusher",
                  lambda rs, refs: abs(float(np.mean(all_of(rs, "speed")) - np.mean(all_of(refs, "speed")))), 0.05,
                  True), "|mean cube speed - ref's| / pusher speed", failure="behind the pusher"),
    Family("stack", "8 stack of 6 cubes hit from the side", 1 / 240, 64, 12, 3, ["-"],
           stack_build, stack_observe, stack_measure,
           [Figure("KE ratio median", _pct("ke", med), 0.05),
            Figure("KE ratio max", _pct("ke", np.max), 0.1),
            Figure("spread m (median)", _pct("spread", med), 0.5),
            Figure("tunneled", _count("tunneled"), 0.5)],
           Figure("|median KE ratio - ref|", _diff_median("ke"), 0.05, True), "|median KE ratio - ref's|"),
    Family("glancing", "9 cube glancing off a 1 cm floor", 1 / 240, 256, 16, 6, ["-"],
           glancing_build, glancing_observe, glancing_measure,
           [*_quartiles("rebound", "rebound", 0.05, 0.08),
            Figure("KE ratio median", _pct("ke", med), 0.05),
            Figure("fell through", _count("through"), 0.5)],
           Figure("|median rebound - ref|", _diff_median("rebound"), 0.05, True), "|median rebound - ref's|",
           failure="fell through"),
]}
