"""BoxCCD against pybullet itself: tunneling, rotation, momentum, contact poses by
pybullet's own getClosestPoints, energy, do-no-harm, frames, URDFs, filters."""

from __future__ import annotations

import os

import numpy as np
import pybullet as p
import pybullet_data
import pytest

from bullet_boxccd import BoxCCD, Outcome, _core
from bullet_boxccd.motion import quat_to_matrix
from bullet_boxccd.pybullet_ccd.contacts import IMPACT_SHARE

DT = 1 / 240


def reset(cid, gravity=0.0):
    p.resetSimulation(physicsClientId=cid)
    p.setTimeStep(DT, physicsClientId=cid)
    p.setGravity(0, 0, gravity, physicsClientId=cid)


def box(cid, half, pos, mass=1.0, orn=(0, 0, 0, 1), frame_pos=(0, 0, 0), frame_orn=(0, 0, 0, 1),
        inertial_pos=(0, 0, 0), maximal=False, **dyn):
    col = p.createCollisionShape(p.GEOM_BOX, halfExtents=half, collisionFramePosition=frame_pos,
                                 collisionFrameOrientation=frame_orn, physicsClientId=cid)
    b = p.createMultiBody(mass, col, basePosition=pos, baseOrientation=orn, baseInertialFramePosition=inertial_pos,
                          useMaximalCoordinates=maximal, physicsClientId=cid)
    p.changeDynamics(b, -1, linearDamping=0, angularDamping=0, maxJointVelocity=10000, physicsClientId=cid, **dyn)
    return b


def com_x(cid, b):
    return p.getBasePositionAndOrientation(b, physicsClientId=cid)[0][0]


def closest(cid, ev):
    """The pair's signed distance by pybullet's measure, the shallower of its two orders: its
    box detector prefers a face's axis to an edge's, and which face depends on the order (a
    cube spinning at 1,000 rad/s stopped 0.125 mm deep at a wall by the separating axes is
    0.27 mm deep one way and 0.11 mm the other)."""
    a, b = (ev.body_a, ev.link_a), (ev.body_b, ev.link_b)
    both = [p.getClosestPoints(x[0], y[0], 0.01, x[1], y[1], physicsClientId=cid) for x, y in ((a, b), (b, a))]
    return max(min(c[8] for c in pts) if pts else np.inf for pts in both)


# With no partial step left, the bodies of a contact pybullet would resolve wrongly end
# the step at the contact: that is where the checks of the contact poses look.
STOP_AT_CONTACT = dict(max_partial_steps=0)
PENETRATION, IMPACT_DEPTH = 1e-5, 1e-3  # BoxCCD's defaults


def impact_depth(cid, ev):
    """The overlap BoxCCD resolves the event's impact at: IMPACT_DEPTH, at most IMPACT_SHARE of
    the thinnest half extent of the two links' boxes (IMPACT_DEPTH where pybullet does not give
    them: maximal-coordinate bodies)."""
    try:
        thin = min(min(d[3]) / 2 for body, link in ((ev.body_a, ev.link_a), (ev.body_b, ev.link_b))
                   for d in p.getCollisionShapeData(body, link, physicsClientId=cid) if d[2] == p.GEOM_BOX)
    except p.error:
        return IMPACT_DEPTH
    return max(PENETRATION, min(IMPACT_DEPTH, IMPACT_SHARE * thin))


def check_rewound_poses(cid, events, margin=0.001):
    """Test 4: a body put back at an impact is touching by pybullet's own measure: 0 to the
    impact depth deep at a face, up to the margin's rounding apart at a vertex or edge."""
    n = 0
    for ev in events:
        if ev.rewound and not ev.initial:
            d = closest(cid, ev)
            assert -impact_depth(cid, ev) - 1e-6 <= d <= margin + 1e-6, (ev, d)
            n += 1
    return n


# ------------------------------------------------------------------ the path
def test_step_path_reproduces_bullets_integration(cid):
    """The path rebuilt from the pose after a step lands on the pose before it, for
    spins below and far above Bullet's pi/4-per-step clamp."""
    reset(cid)
    b = box(cid, [0.05, 0.1, 0.2], [0, 0, 1])
    for w in ([0, 0, 5], [30, 40, 100], [300, 0, 0], [-500, 800, 200]):
        p.resetBasePositionAndOrientation(b, [0.1, 0.2, 1], p.getQuaternionFromEuler([0.3, 0.2, 0.1]),
                                          physicsClientId=cid)
        p.resetBaseVelocity(b, [3, -2, 1], w, physicsClientId=cid)
        pos0, q0 = p.getBasePositionAndOrientation(b, physicsClientId=cid)
        p.stepSimulation(physicsClientId=cid)
        pos1, q1 = p.getBasePositionAndOrientation(b, physicsClientId=cid)
        v1, w1 = p.getBaseVelocity(b, physicsClientId=cid)
        state = np.array([[*pos1, *q1, *v1, *w1]])
        X0 = _core.frame_poses(state, DT, np.zeros(1, dtype=np.int64), np.zeros(1))[0]
        np.testing.assert_allclose(X0[:3], pos0, atol=1e-12)
        np.testing.assert_allclose(quat_to_matrix(X0[3:]), quat_to_matrix(q0), atol=1e-9)


@pytest.mark.parametrize("h", [DT, DT / 7, 0.05])
def test_a_fixed_base_moved_by_its_velocity_turns_it_as_bullet_does(cid, h):
    """A mass-0 base given a velocity and a spin: Bullet moves it by the velocity it ends
    the step with, which it turned with the spin on the way; ``twists_at`` (mode 0) gives
    back the velocity it started from (what a kinematic body is given at a go-back)."""
    reset(cid)
    b = box(cid, [0.1, 0.2, 0.3], [0, 0, 1], mass=0.0)
    p.setTimeStep(h, physicsClientId=cid)
    rng = np.random.default_rng(0)
    for _ in range(5):
        v, w = rng.uniform(-20, 20, 3), rng.uniform(-30, 30, 3)
        p.resetBaseVelocity(b, v.tolist(), w.tolist(), physicsClientId=cid)
        pos0 = np.array(p.getBasePositionAndOrientation(b, physicsClientId=cid)[0])
        p.stepSimulation(physicsClientId=cid)
        pos1 = np.array(p.getBasePositionAndOrientation(b, physicsClientId=cid)[0])
        v1, w1 = map(np.array, p.getBaseVelocity(b, physicsClientId=cid))
        np.testing.assert_allclose(pos1 - pos0, h * v1, atol=1e-12)
        np.testing.assert_allclose(w1, w, atol=1e-12)
        np.testing.assert_allclose(_core.twists_at(np.array([[*v1, *w1]]), [0], h, 0.0, np.zeros(3))[0, :3], v,
                                   atol=1e-9)


# ------------------------------------------------------------- 1. thin walls
def thin_wall_run(cid, use, speed, thickness, phase, spin, orn, cube_kw=None, register=None, ccd_kw=None):
    """A cube at ``speed`` against a static wall of ``thickness`` in the plane x = 0 (2 m
    square). Returns (passed through: its centre crossed the wall's plane within the
    wall, events, rewound poses checked: with ``ccd_kw`` STOP_AT_CONTACT)."""
    reset(cid)
    wall = box(cid, [thickness / 2, 1, 1], [0, 0, 0], mass=0.0)
    cube = box(cid, [0.05] * 3, [-0.3 - phase * speed * DT, 0.1, 0.05], orn=orn, **(cube_kw or {}))
    p.resetBaseVelocity(cube, [speed, 0, 0], spin, physicsClientId=cid)
    ccd = BoxCCD(cid, **(ccd_kw or {})) if use else None
    check = ccd_kw == STOP_AT_CONTACT
    if ccd is not None and register:
        register(ccd, cube)
    if ccd is not None:
        assert ccd.stats.tracked_boxes == 2
    events, checked, through = [], 0, False
    kw = cube_kw or {}  # the box centre in the centre-of-mass frame:
    offset = np.subtract(kw.get("frame_pos", (0, 0, 0)), kw.get("inertial_pos", (0, 0, 0)))

    def centre():  # of the box, not of the centre-of-mass frame (they differ with frame offsets); pybullet's
        # own quaternion matrix on purpose: the test judges the plugin against pybullet
        pos, q = p.getBasePositionAndOrientation(cube, physicsClientId=cid)
        return np.array(pos) + np.array(p.getMatrixFromQuaternion(q)).reshape(3, 3) @ offset

    before = centre()
    for _ in range(int(0.6 / (speed * DT)) + 30):
        if ccd is None:
            p.stepSimulation(physicsClientId=cid)
        else:
            evs = ccd.step()
            checked += check_rewound_poses(cid, evs) if check else 0
            events += evs
        after = centre()
        if before[0] < 0.0 <= after[0]:  # where the centre crossed x = 0: inside the wall's face?
            cross = before + (after - before) * (-before[0] / (after[0] - before[0]))
            through |= bool(abs(cross[1]) <= 1.0 and abs(cross[2]) <= 1.0)
        before = after
    if use:  # not held in the wall still pressing into it (a body pybullet left unresolved)
        vx = p.getBaseVelocity(cube, physicsClientId=cid)[0][0]
        deep = p.getClosestPoints(wall, cube, 0.0, physicsClientId=cid)
        assert not (deep and min(c[8] for c in deep) < -0.01 and vx > 1.0), ("stuck", speed, thickness, phase, vx)
    return through, events, checked


def phases(n=50, seed=0):
    rng = np.random.default_rng(seed)
    for k in range(n):
        yield k / n, rng.uniform(-30, 30, 3), p.getQuaternionFromEuler(rng.uniform(-0.3, 0.3, 3))


@pytest.mark.parametrize("thickness", [0.01, 0.001])
@pytest.mark.parametrize("speed", [10.0, 100.0, 1000.0])
def test_thin_wall_never_tunnels(cid, speed, thickness):
    plain = ccd_through = checked = 0
    for phase, spin, orn in phases():
        plain += thin_wall_run(cid, False, speed, thickness, phase, spin, orn)[0]
        ccd_through += thin_wall_run(cid, True, speed, thickness, phase, spin, orn)[0]
        through, _, n = thin_wall_run(cid, True, speed, thickness, phase, spin, orn, ccd_kw=STOP_AT_CONTACT)
        ccd_through += through
        checked += n
    assert ccd_through == 0
    if speed >= 100:  # at 10 m/s the cube moves 4 cm a step: plain pybullet catches it too
        assert checked >= 25  # test 4 ran on the rewound first impacts (those pybullet would resolve wrongly)
        assert plain >= 25, f"plain pybullet tunneled only {plain}/50: the test shows nothing"


# --------------------------------------------------------------- 2. rotation
@pytest.mark.parametrize("radius", [0.3, 0.45])
def test_spinning_plank_never_passes_through(cid, radius):
    plain = through = 0
    for k in range(40):
        for use in (False, True):
            reset(cid)
            box(cid, [0.05] * 3, [radius, 0, 0], mass=0.0)
            yaw = np.pi / 2 + k / 40 * 0.83
            plank = box(cid, [0.5, 0.01, 0.1], [0, 0, 0], orn=p.getQuaternionFromEuler([0, 0, yaw]))
            p.resetBaseVelocity(plank, [0, 0, 0], [0, 0, -200.0], physicsClientId=cid)
            ccd = BoxCCD(cid) if use else None
            for _ in range(8):
                ccd.step() if ccd else p.stepSimulation(physicsClientId=cid)
            untouched = abs(p.getBaseVelocity(plank, physicsClientId=cid)[1][2] + 200.0) < 1e-6
            if use:
                through += untouched
            else:
                plain += untouched
    assert through == 0
    assert plain > 5


@pytest.mark.parametrize("speed", [120.0, 125.0, 130.0])
def test_a_spinning_rod_already_touching_a_wall_does_not_pass_through_it(cid, speed):
    """A 1.34 m rod spinning at 1,143 rad/s that begins a 1/120 s step 0.4 mm into a 7.6 mm
    wall (as a step may leave it) and moves into it at 120-130 m/s leaves the contact as
    the step begins and crosses the wall between two of the depth search's look-ahead
    samples: BoxCCD finds that crossing and keeps the rod on its side (plain pybullet and
    pybullet at a 64 times finer step: through, and on its side)."""
    def run(fine, use):
        reset(cid)
        p.setTimeStep(1 / 120 / fine, physicsClientId=cid)
        wall = box(cid, [0.0038007, 50, 50], [-4.284878727558222, 0, 0], mass=0.0)
        rod = box(cid, [0.0076, 0.0228, 0.6713], [-3.9618619828849764, 2.1698349102806906, 3.6885533146294764],
                  mass=1.2126, orn=[-0.506136674039897, -0.23351341059765682, 0.07530257597318037, 0.8268171964314026])
        p.changeDynamics(wall, -1, restitution=1.0, physicsClientId=cid)
        p.changeDynamics(rod, -1, restitution=0.3, lateralFriction=0.5, maxJointVelocity=2000, linearDamping=0,
                         angularDamping=0, physicsClientId=cid)
        p.resetBaseVelocity(rod, [-speed, 0, 0], [1000.0, -302.5573974024994, 456.0051219791426], physicsClientId=cid)
        if use:
            BoxCCD(cid).step()
        else:
            for _ in range(fine):
                p.stepSimulation(physicsClientId=cid)
        return com_x(cid, rod) - p.getBasePositionAndOrientation(wall, physicsClientId=cid)[0][0]

    assert run(1, False) < 0.0 < run(64, False)  # (the rod's centre starts on the wall's + side)
    assert run(1, True) > 0.0


# -------------------------------------------------- 3. two fast boxes, momentum
@pytest.mark.parametrize("angle_deg", [0.0, 35.0])
def test_two_fast_boxes_collide_and_conserve_momentum(cid, angle_deg):
    d = np.array([np.cos(np.radians(angle_deg)), np.sin(np.radians(angle_deg)), 0.0])
    for k in range(20):
        reset(cid)
        gap = 1.0 + k / 20 * 400 * DT
        a = box(cid, [0.05] * 3, [-gap / 2, 0.0, 0.0], restitution=1.0)
        b = box(cid, [0.06, 0.04, 0.05], (gap / 2 * d).tolist(), mass=2.5, restitution=1.0,
                orn=p.getQuaternionFromEuler([0.1 * k, 0.2, 0.0]))
        p.resetBaseVelocity(a, [200, 0, 0], [0, 5, 0], physicsClientId=cid)
        p.resetBaseVelocity(b, (-200 * d).tolist(), [3, 0, 0], physicsClientId=cid)
        m0 = np.array([200.0, 0, 0]) + 2.5 * (-200 * d)
        ccd = BoxCCD(cid)
        events = []
        for _ in range(int(gap / 400 / DT) + 8):
            events += ccd.step()
        va = np.array(p.getBaseVelocity(a, physicsClientId=cid)[0])
        vb = np.array(p.getBaseVelocity(b, physicsClientId=cid)[0])
        assert events, "no CCD contact"
        # Every contact came from an exact search whose outcome the stats count; none is degraded here.
        found = ccd.stats.outcomes[Outcome.HIT] + ccd.stats.outcomes[Outcome.INITIAL]
        assert found >= len(events) and ccd.stats.degraded == 0, (ccd.stats.outcomes, len(events))
        assert not np.allclose(va, [200, 0, 0]), "the boxes passed through each other"
        assert np.linalg.norm(va + 2.5 * vb - m0) <= 0.01 * np.linalg.norm(m0), (k, va, vb)


# ---------------------------------------------------------------- 5. energy
def _restitution_one_scene(cid, phase, h=DT, wall_half=0.005):
    """A 0.1 m cube (restitution 1) at 50 m/s at a static wall 2 x ``wall_half`` thick
    (restitution 1), no gravity; it reaches the wall ``phase`` of the way into its step of DT.
    Returns the cube."""
    reset(cid)
    p.setTimeStep(h, physicsClientId=cid)
    box(cid, [wall_half, 1, 1], [0, 0, 0], mass=0.0, restitution=1.0)
    cube = box(cid, [0.05] * 3, [-0.3 - phase * 50 * DT, 0.0, 0.0], restitution=1.0)
    p.resetBaseVelocity(cube, [50, 0, 0], [0, 0, 0], physicsClientId=cid)
    return cube


def _run(cid, steps, h=DT, shift=None):
    """``steps`` steps of DT of the world built for a step of h: by BoxCCD where h is DT, else
    by plain pybullet, its step grid offset by a first step of ``shift`` of one."""
    step = BoxCCD(cid).step if h == DT else (lambda: p.stepSimulation(physicsClientId=cid))
    if shift is not None:
        p.setTimeStep(h * shift, physicsClientId=cid)
        p.stepSimulation(physicsClientId=cid)
        p.setTimeStep(h, physicsClientId=cid)
    for _ in range(round(steps * DT / h)):
        step()


def converged_rebound(cid, wall_half=0.005, fine=64, phases=8):
    """The cube's velocity along x after 40 steps of DT in that scene, by plain pybullet at
    DT / fine, over ``phases`` offsets of its step grid (its rebound depends on where in its
    fine step the touch falls: its position correction adds 0 to 8 % of the impact speed):
    (their mean, lowest, highest)."""
    ref = []
    for j in range(phases):
        cube = _restitution_one_scene(cid, 0.5, DT / fine, wall_half)
        _run(cid, 40, DT / fine, j / phases)
        ref.append(p.getBaseVelocity(cube, physicsClientId=cid)[0][0])
    return float(np.mean(ref)), min(ref), max(ref)


def test_restitution_one_comes_back_at_the_converged_engines_speed(cid):
    """BoxCCD at DT, the touch at 10 phases of its step: within 1 % of the impact speed of
    the converged engine's mean (``converged_rebound``), and inside the range its offsets span."""
    mean, lo, hi = converged_rebound(cid)
    assert hi - lo > 0.02 * 50.0  # the converged engine's own spread over its grid's offsets
    rewinds = 0
    for phase in np.linspace(0, 1, 10, endpoint=False):
        cube = _restitution_one_scene(cid, phase)
        ccd = BoxCCD(cid)
        for _ in range(40):
            ccd.step()
        v = p.getBaseVelocity(cube, physicsClientId=cid)[0]
        rewinds += ccd.stats.rewinds
        assert abs(v[0] - mean) <= 0.5 and lo <= v[0] <= hi, (phase, v, mean, lo, hi)
    assert rewinds >= 5  # a strike late in a step is pybullet's own: it resolves it from the end


def _between_maximal_walls(cid):
    """Restitution 0.8 on a maximal-coordinate cube and on two 1 cm walls 0.6 m apart."""
    reset(cid)
    for x in (-0.3, 0.3):
        box(cid, [0.005, 1, 1], [x, 0, 0], mass=0.0, maximal=True, restitution=0.8)
    return box(cid, [0.05] * 3, [-0.1, 0.0, 0.0], maximal=True, restitution=0.8)


def _next_rebound(cid, cube):
    """The cube's velocity along x over what it had, at its next impact in plain pybullet at DT/64."""
    p.setTimeStep(DT / 64, physicsClientId=cid)
    v = after = p.getBaseVelocity(cube, physicsClientId=cid)[0][0]
    for _ in range(64 * 20):
        p.stepSimulation(physicsClientId=cid)
        after = p.getBaseVelocity(cube, physicsClientId=cid)[0][0]
        if np.sign(after) != np.sign(v):
            break
    return after / v


def test_a_maximal_coordinate_cube_rebounds_between_two_walls_with_its_own_restitution(cid):
    """The cube of ``_between_maximal_walls`` at 50 m/s: after two impacts it moves at 0.8^4
    of its speed, each resolved from its touch (pybullet reports no restitution of a
    maximal-coordinate body, so BoxCCD does not raise it), and after them the bodies still
    have the restitution the user gave them: the third impact, in plain pybullet at a fine
    step, rebounds as in a world just made with that restitution and the cube's state."""
    cube = _between_maximal_walls(cid)
    p.resetBaseVelocity(cube, [50, 0, 0], [0, 0, 0], physicsClientId=cid)
    ccd = BoxCCD(cid)
    hits = 0
    while hits < 2:
        hits += sum(e.rewound for e in ccd.step())
    state = p.getBasePositionAndOrientation(cube, physicsClientId=cid), p.getBaseVelocity(cube, physicsClientId=cid)
    assert abs(abs(state[1][0][0]) - 50 * 0.64**2) < 0.01 * 50, state
    rebound = _next_rebound(cid, cube)
    fresh = _between_maximal_walls(cid)
    p.resetBasePositionAndOrientation(fresh, *state[0], physicsClientId=cid)
    p.resetBaseVelocity(fresh, *state[1], physicsClientId=cid)
    want = _next_rebound(cid, fresh)
    assert -0.72 < want < -0.6 and abs(rebound - want) < 0.005, (rebound, want)


def _two_cubes_at_one_wall(cid, restitutions, h=DT, shift=None):
    """A static 1 cm wall of restitution 0.5, struck in the same step by 0.1 m cubes of the
    given restitutions, 1 m apart, each at 50 m/s; 30 steps of DT (``_run``). Returns each
    cube's velocity along x."""
    reset(cid)
    p.setTimeStep(h, physicsClientId=cid)
    box(cid, [0.005, 2, 2], [0, 0, 0], mass=0.0, restitution=0.5)
    x = -0.3 - 0.37 * 50 * DT
    cubes = [box(cid, [0.05] * 3, [x, y, 0], restitution=e) for e, y in zip(restitutions, (-0.5, 0.5))]
    for c in cubes:
        p.resetBaseVelocity(c, [50, 0, 0], [0, 0, 0], physicsClientId=cid)
    _run(cid, 30, h, shift)
    return [p.getBaseVelocity(c, physicsClientId=cid)[0][0] for c in cubes]


def test_boxes_of_different_restitutions_striking_one_wall_at_once_stay_in_the_converged_range(cid):
    """Restitution 0 and 1 at a wall of 0.5 at once: one restitution of the wall cannot raise
    both pairs by the converged engine's mean, so both are resolved from their touch, the
    low end of the converged engine's range (plain pybullet at DT/64 over 8 grid offsets),
    not above it; and the wall and the cubes keep the restitution the user gave them."""
    ref = np.array([_two_cubes_at_one_wall(cid, (0.0, 1.0), DT / 64, k / 8) for k in range(8)])
    v = _two_cubes_at_one_wall(cid, (0.0, 1.0))
    for vk, lo, hi in zip(v, ref.min(axis=0), ref.max(axis=0)):
        assert abs(vk - hi) <= 0.01 * 50 and vk >= lo, (v, ref.min(axis=0), ref.max(axis=0))  # hi: the slowest
    assert [p.getDynamicsInfo(b, -1, physicsClientId=cid)[5] for b in range(3)] == [0.5, 0.0, 1.0]


# ---------------------------------------------------------- 6. do no harm
def run_quiet_scene(cid, use):
    reset(cid, gravity=-9.81)
    box(cid, [2, 2, 0.05], [0, 0, -0.05], mass=0.0)
    stack = [box(cid, [0.1, 0.1, 0.05], [0, 0, 0.05 + 0.1 * i]) for i in range(10)]
    slider = box(cid, [0.1, 0.1, 0.1], [1.0, 0, 0.1])
    p.resetBaseVelocity(slider, [0.5, 0, 0], [0, 0, 0], physicsClientId=cid)
    ccd = BoxCCD(cid) if use else None
    traj = []
    for _ in range(1000):
        ccd.step() if ccd else p.stepSimulation(physicsClientId=cid)
        traj.append([p.getBasePositionAndOrientation(b, physicsClientId=cid)[0] for b in stack + [slider]])
    return np.array(traj), ccd


def test_resting_stack_and_slow_slider_are_untouched(cid):
    plain, _ = run_quiet_scene(cid, False)
    with_ccd, ccd = run_quiet_scene(cid, True)
    assert np.abs(plain - with_ccd).max() <= 1e-9
    assert ccd.stats.rewinds == 0 and ccd.stats.tracked_boxes == 12


# ------------------------------------------------------------------ 7. frames
FRAME_CASES = {
    "collision frame offset": dict(frame_pos=(0.02, -0.01, 0.03), frame_orn=p.getQuaternionFromEuler([0.2, 0.1, 0.3])),
    "inertial frame offset": dict(inertial_pos=(0.03, 0.01, -0.02)),
    "both offsets": dict(frame_pos=(0.01, 0.02, 0.0), inertial_pos=(-0.02, 0.0, 0.01)),
}


@pytest.mark.parametrize("name", sorted(FRAME_CASES))
def test_frames_thin_wall(cid, name):
    checked = 0
    for phase, spin, orn in phases(12, seed=3):
        assert not thin_wall_run(cid, True, 100.0, 0.001, phase, spin, orn, FRAME_CASES[name])[0]
        through, events, n = thin_wall_run(cid, True, 100.0, 0.001, phase, spin, orn, FRAME_CASES[name],
                                           ccd_kw=STOP_AT_CONTACT)
        assert not through
        checked += n
    assert checked >= 6  # the rewound poses, checked by pybullet's own distance


def test_maximal_coordinates_are_read_without_registering(cid):
    plain = checked = 0
    for phase, spin, orn in phases(12, seed=4):
        kw = dict(maximal=True)
        plain += thin_wall_run(cid, False, 100.0, 0.001, phase, spin, orn, kw)[0]
        assert not thin_wall_run(cid, True, 100.0, 0.001, phase, spin, orn, kw)[0]
        through, events, n = thin_wall_run(cid, True, 100.0, 0.001, phase, spin, orn, kw, ccd_kw=STOP_AT_CONTACT)
        assert not through
        checked += n
    assert checked >= 6 and plain > 0


def test_compound_link_of_several_boxes(cid):
    """A dumbbell: two cubes and a bar on one link, with frame offsets, at 100 m/s."""
    for (phase, spin, orn), kw in zip(phases(24, seed=5), [{}, STOP_AT_CONTACT] * 12):
        reset(cid)
        box(cid, [0.0005, 1, 1], [0, 0, 0], mass=0.0)
        col = p.createCollisionShapeArray([p.GEOM_BOX] * 3, halfExtents=[[0.04] * 3, [0.04] * 3, [0.1, 0.01, 0.01]],
                                          collisionFramePositions=[[-0.12, 0, 0], [0.12, 0, 0], [0, 0, 0]],
                                          physicsClientId=cid)
        b = p.createMultiBody(1.0, col, basePosition=[-0.5 - phase * 100 * DT, 0.1, 0.0], baseOrientation=orn,
                              physicsClientId=cid)
        p.changeDynamics(b, -1, maxJointVelocity=10000, linearDamping=0, angularDamping=0, physicsClientId=cid)
        p.resetBaseVelocity(b, [100, 0, 0], spin, physicsClientId=cid)
        ccd = BoxCCD(cid, **kw)
        assert ccd.stats.tracked_boxes == 4
        for _ in range(40):
            events = ccd.step()
            if kw:
                check_rewound_poses(cid, events)
        assert com_x(cid, b) < 0.0


# --------------------------------------------------------------------- 8. URDFs
def test_urdf_pieces_stay_in_the_tray(cid):
    data = pybullet_data.getDataPath()
    plain = escaped = 0
    for seed in range(2):
        for use in (False, True):
            reset(cid, gravity=-9.81)
            p.loadURDF(os.path.join(data, "tray/traybox.urdf"), physicsClientId=cid)
            box(cid, [0.36, 0.36, 0.01], [0, 0, 0.13], mass=0.0)  # a lid closes the tray
            rng = np.random.default_rng(seed)
            pieces = []
            for k in range(9):
                pos = [-0.15 + 0.15 * (k % 3), -0.15 + 0.15 * (k // 3), 0.07]
                b = p.loadURDF(os.path.join(data, ("lego/lego.urdf", "jenga/jenga.urdf")[k % 2]), pos,
                               physicsClientId=cid)
                p.changeDynamics(b, -1, maxJointVelocity=10000, physicsClientId=cid)
                p.resetBaseVelocity(b, [rng.uniform(-40, 40), rng.uniform(-40, 40), rng.uniform(-80, 80)],
                                    rng.uniform(-30, 30, 3).tolist(), physicsClientId=cid)
                pieces.append(b)
            ccd = BoxCCD(cid) if use else None
            if ccd:
                assert ccd.stats.tracked_boxes == 5 + 1 + 9
            for _ in range(120):
                ccd.step() if ccd else p.stepSimulation(physicsClientId=cid)
            out = 0
            for b in pieces:
                x, y, z = p.getBasePositionAndOrientation(b, physicsClientId=cid)[0]
                out += not (abs(x) < 0.36 and abs(y) < 0.36 and -0.01 < z < 0.14)
            if use:
                escaped += out
            else:
                plain += out
    assert escaped == 0
    assert plain > 0


# ---------------------------------------------------- discovery and filtering
def test_discovery_lists_what_is_left_to_pybullet(cid):
    reset(cid)
    box(cid, [0.1] * 3, [0, 0, 0])
    s = p.createCollisionShape(p.GEOM_SPHERE, radius=0.1, physicsClientId=cid)
    p.createMultiBody(1.0, s, basePosition=[1, 0, 0], physicsClientId=cid)
    box(cid, [0.1] * 3, [2, 0, 0], maximal=True)
    ccd = BoxCCD(cid)
    text = ccd.summary()
    assert ccd.stats.tracked_boxes == 2
    assert "sphere" in text
    box(cid, [0.1] * 3, [3, 0, 0])  # added later: picked up on the next step
    ccd.step()
    assert ccd.stats.tracked_boxes == 3


def test_world_rebuilt_after_reset_simulation_is_rediscovered(cid):
    """p.resetSimulation() and a new scene with the same bodies' count and ids: the
    plugin must not sweep the old scene's boxes. In the old scene body 1 was a static
    block, in the new one it is a cube at 100 m/s that tunnels through a 1 mm wall in
    one step unless it is swept."""
    reset(cid)
    box(cid, [0.0005, 1, 1], [0.0, 0, 0], mass=0.0)
    box(cid, [0.5, 0.5, 0.5], [-3.0, 0, 0], mass=0.0)
    ccd = BoxCCD(cid)
    ccd.step()
    reset(cid)
    box(cid, [0.0005, 1, 1], [0.0, 0, 0], mass=0.0)
    cube = box(cid, [0.05] * 3, [-0.3, 0, 0])
    p.resetBaseVelocity(cube, [100, 0, 0], [0, 0, 0], physicsClientId=cid)
    for _ in range(10):
        ccd.step()
    assert com_x(cid, cube) < 0.0
    assert ccd.stats.tracked_boxes == 2


def test_static_wall_moved_by_the_user_is_seen_where_it_is(cid):
    """A mass-0 wall teleported between steps (a kinematic obstacle): the cube is
    stopped by the wall where it now is, not by where it was when BoxCCD started."""
    reset(cid)
    wall = box(cid, [0.0005, 1, 1], [5.0, 0, 0], mass=0.0)
    cube = box(cid, [0.05] * 3, [-0.3, 0, 0])
    p.resetBaseVelocity(cube, [100, 0, 0], [0, 0, 0], physicsClientId=cid)
    ccd = BoxCCD(cid)
    p.resetBasePositionAndOrientation(wall, [0.0, 0, 0], [0, 0, 0, 1], physicsClientId=cid)
    for _ in range(20):
        ccd.step()
    assert com_x(cid, cube) < 0.0


def test_filtered_pair_is_not_swept(cid):
    reset(cid)
    wall = box(cid, [0.0005, 1, 1], [0, 0, 0], mass=0.0)
    cube = box(cid, [0.05] * 3, [-0.3, 0, 0])
    p.resetBaseVelocity(cube, [100, 0, 0], [0, 0, 0], physicsClientId=cid)
    ccd = BoxCCD(cid)
    ccd.set_collision_filter_pair(wall, cube, -1, -1, False)
    for _ in range(20):
        assert not ccd.step()
    assert com_x(cid, cube) > 1.0  # pybullet does not collide them either


def test_articulated_link_is_swept_and_its_free_partner_rewound(cid):
    """A box on a fast revolute link strikes a free cube: the event names the link, and
    the pair is acted on (the arm stopped at the strike, then the cube pushed ahead of
    the link: tests/test_articulated.py)."""
    reset(cid)
    arm_col = p.createCollisionShape(p.GEOM_BOX, halfExtents=[0.5, 0.01, 0.05], collisionFramePosition=[0.5, 0, 0],
                                     physicsClientId=cid)
    base_col = p.createCollisionShape(p.GEOM_BOX, halfExtents=[0.02] * 3, physicsClientId=cid)
    arm = p.createMultiBody(0.0, base_col, basePosition=[0, 0, 0], linkMasses=[1.0],
                            linkCollisionShapeIndices=[arm_col], linkVisualShapeIndices=[-1],
                            linkPositions=[[0, 0, 0]], linkOrientations=[[0, 0, 0, 1]],
                            linkInertialFramePositions=[[0.5, 0, 0]], linkInertialFrameOrientations=[[0, 0, 0, 1]],
                            linkParentIndices=[0], linkJointTypes=[p.JOINT_REVOLUTE], linkJointAxis=[[0, 0, 1]],
                            physicsClientId=cid)
    p.changeDynamics(arm, 0, maxJointVelocity=10000, physicsClientId=cid)
    p.setJointMotorControl2(arm, 0, p.VELOCITY_CONTROL, force=0, physicsClientId=cid)
    p.resetJointState(arm, 0, 0.0, 150.0, physicsClientId=cid)
    cube = box(cid, [0.03] * 3, [0.3, 0.35, 0.0])
    ccd = BoxCCD(cid)
    events = []
    for _ in range(6):
        events += ccd.step()
    mine = [e for e in events if {e.body_a, e.body_b} == {arm, cube}]
    assert mine and all((e.link_a if e.body_a == arm else e.link_b) == 0 for e in mine)
    assert any(e.rewound for e in mine)


# ---------------------------------------------------------- partial steps
def test_a_contact_of_a_fast_spinning_plank_is_reported_where_it_touches(cid):
    """A 0.6 m plank spinning at 900 rad/s falls on a floor (top z = 0) and strikes it end
    first: every contact met inside a step is reported at the boxes' own touch, on the floor's
    top, not where the boxes grown by one fit's allowance over the rest of the step touch
    (for such a spin, millimetres to centimetres from it)."""
    heights = []
    for k in range(12):
        reset(cid, gravity=-9.81)
        box(cid, [2, 2, 0.01], [0, 0, -0.01], mass=0.0)
        plank = box(cid, [0.3, 0.025, 0.025], [0, 0, 0.31 + 0.02 * k],
                    orn=p.getQuaternionFromEuler([0.2, 0.1 * k, 0.3]))
        p.resetBaseVelocity(plank, [0, 0, -5], [30, 900, 20], physicsClientId=cid)
        ccd = BoxCCD(cid)
        for _ in range(6):
            heights += [ev.point[2] for ev in ccd.step() if not ev.initial]
    assert len(heights) >= 4
    assert np.max(np.abs(heights)) < 1e-6, heights


def test_partial_steps_take_the_world_to_the_contact_and_on(cid):
    """The whole world stops at the contact, the rest of the step is simulated from
    there: no tunneling, the rebound at restitution 1 the converged engine's, and bystanders keep their
    exact paths (stopped and restarted, not delayed, and not given gravity twice)."""
    mean, _, _ = converged_rebound(cid, wall_half=0.0005)
    rewinds = 0
    for phase in np.linspace(0, 1, 8, endpoint=False):
        reset(cid)
        faller = box(cid, [0.05] * 3, [5.0, 5.0, 20.0])
        p.setGravity(0, 0, -9.81, physicsClientId=cid)
        box(cid, [0.0005, 1, 1], [0, 0, 0], mass=0.0, restitution=1.0)
        cube = box(cid, [0.05] * 3, [-0.3 - phase * 50 * DT, 0.0, 0.0], restitution=1.0)
        bystander = box(cid, [0.05] * 3, [-0.3, 3.0, 0.0])
        idler = box(cid, [0.05] * 3, [5.0, -3.0, 0.0])  # slow and far: never swept, still stopped
        p.resetBaseVelocity(idler, [0.1, 0, 0], [0, 0, 0], physicsClientId=cid)
        p.resetBaseVelocity(cube, [50, 0, 0], [0, 0, 0], physicsClientId=cid)
        p.resetBaseVelocity(bystander, [20, 0, 0], [0, 0, 0], physicsClientId=cid)
        ccd = BoxCCD(cid)
        n = 40
        for _ in range(n):
            ccd.step()
        assert p.getPhysicsEngineParameters(physicsClientId=cid)["fixedTimeStep"] == DT
        rewinds += ccd.stats.partial_steps
        assert abs(p.getBaseVelocity(cube, physicsClientId=cid)[0][0] - mean) <= 0.5
        assert com_x(cid, cube) < 0.0
        assert abs(com_x(cid, bystander) - (-0.3 + 20 * n * DT)) < 1e-9
        assert abs(com_x(cid, idler) - (5.0 + 0.1 * n * DT)) < 1e-9
        # Bullet's semi-implicit Euler: v_k = -g k dt, z_k = z_0 - g dt^2 k (k + 1) / 2.
        vz = p.getBaseVelocity(faller, physicsClientId=cid)[0][2]
        z = p.getBasePositionAndOrientation(faller, physicsClientId=cid)[0][2]
        assert abs(vz + 9.81 * n * DT) < 1e-9
        assert abs(z - (20.0 - 9.81 * DT**2 * n * (n + 1) / 2)) < 1e-9
    assert rewinds >= 4  # in at least 4 phases the world went back to the contact
