"""The core's judgement of one contact (``_core.judge_contact``: whether pybullet would
resolve a pair wrongly from where a window of the step leaves it, and when the pair's
depth reaches the depth acted at) on straight translations, whose touch and depths are
known in closed form. Impacts are judged at an impact depth equal to the penetration."""

from __future__ import annotations

import math

import numpy as np
import pytest

from bullet_boxccd import _core

PENETRATION, DEPTH_TOLERANCE, CREEP = 1e-5, 1e-3, 0.02
TOL = _core.Tolerances()
WALL = (0.01, 1.0, 1.0)  # half extents of a wall across x = 0
CUBE = (0.1, 0.1, 0.1)


def rows(half_a, x_a, half_b, x_b, y_b=0.0):
    """Path rows of box A going from x_a[0] to x_a[1] and box B from x_b[0] to x_b[1]
    along x over the step (B at y_b), unturned."""
    poses = np.zeros((2, 2, 7))
    poses[..., 6] = 1.0
    poses[:, 1, 1] = y_b
    poses[0, :, 0], poses[1, :, 0] = (x_a[0], x_b[0]), (x_a[1], x_b[1])
    return _core.path_rows_between(poses[0], poses[1], np.arange(2, dtype=np.int64), np.arange(2, dtype=np.int64),
                                   np.stack([np.eye(4)] * 2), np.array([half_a, half_b], dtype=float))


def judge(r, s_touch=None, lo=0.0, with_time=False, swap=False):
    a, b = (r[1], r[0]) if swap else (r[0], r[1])
    if s_touch is None:
        tau = _core.first_touches(_core.window_rows(np.stack([a, b]), lo, 1.0), np.array([[0, 1]], dtype=np.int64),
                                  0.05, TOL, PENETRATION, CREEP)[0][0]
        s_touch = float(tau)
    return _core.judge_contact(a, b, lo, s_touch, True, with_time, False, PENETRATION, PENETRATION, DEPTH_TOLERANCE,
                               CREEP, TOL)


@pytest.mark.parametrize("swap", [False, True])
def test_a_pass_through_goes_wrong_from_its_first_depth(swap):
    """A cube crossing a 2 cm wall in the step ends apart on the far side: wrong, acted on
    from the time it is ``penetration`` deep, x = -0.11 + penetration."""
    c, wrong, s, *_ = judge(rows(WALL, (0, 0), CUBE, (-0.5, 0.5)), swap=swap)
    assert c is not None and wrong
    assert s == pytest.approx(0.39 + PENETRATION, abs=1e-9)
    assert c.t == pytest.approx(0.39, abs=1e-6)


@pytest.mark.parametrize("end, wrong", [(-0.1095, False), (-0.1085, True), (-0.105, True)])
@pytest.mark.parametrize("swap", [False, True])
def test_an_overlap_at_the_end_is_wrong_past_the_depth_tolerance(end, wrong, swap):
    """Met inside the step and ending 0.5, 1.5 or 5 mm into the wall: pybullet's own below
    ``depth_tolerance`` (1 mm); wrong beyond it, from x = -0.11 + penetration."""
    c, got, s, *_ = judge(rows(WALL, (0, 0), CUBE, (-0.5, end)), swap=swap)
    assert c is not None and got == wrong
    if wrong:
        assert s == pytest.approx((0.39 + PENETRATION) / (end + 0.5), abs=1e-9)
    else:
        assert np.isnan(s)
        _, _, s, *_ = judge(rows(WALL, (0, 0), CUBE, (-0.5, end)), with_time=True, swap=swap)
        assert s == pytest.approx((0.39 + PENETRATION) / (end + 0.5), abs=1e-9)


def test_a_pair_that_stays_apart_has_no_contact():
    c, wrong, s, *_ = _core.judge_contact(*rows(WALL, (0, 0), CUBE, (-0.5, -0.2)), 0.0, 0.0, True, True, False,
                                          PENETRATION, PENETRATION, DEPTH_TOLERANCE, CREEP, TOL)
    assert c is None and not wrong and np.isnan(s)


@pytest.mark.parametrize("end, wrong", [(-0.1097, False), (-0.105, True)])
def test_a_pair_touching_as_the_window_begins_is_judged_on_how_much_deeper_it_ends(end, wrong):
    """0.1 mm in at the start: pybullet's solver saw it. Wrong if it ends more than
    ``depth_tolerance`` deeper; acted on from the depth at the start plus the creep (2% of
    the wall's 1 cm half thickness, 0.2 mm): x = -0.11 + 0.3 mm."""
    c, got, s, *_ = judge(rows(WALL, (0, 0), CUBE, (-0.1099, end)), s_touch=0.0)
    assert c is not None and c.initial and got == wrong
    if wrong:
        assert s == pytest.approx((-0.11 + 3e-4 + 0.1099) / (end + 0.1099), abs=1e-9)


def test_a_window_later_in_the_step():
    """The same pass through, judged over the window [0.25, 1] of the step: its fractions
    are the window's."""
    c, wrong, s, *_ = judge(rows(WALL, (0, 0), CUBE, (-0.5, 0.5)), lo=0.25)
    assert c is not None and wrong
    assert s == pytest.approx((0.39 + PENETRATION - 0.25) / 0.75, abs=1e-9)


def test_a_box_ending_past_the_middle_of_a_thin_sheet_goes_wrong():
    """A cube driven along x into the edge of a sheet 0.8 mm thick in y (their faces 0.3 mm
    into each other in y all along) ends 1 cm from the sheet's centre along the contact
    normal: its least overlap is the sheet's 0.3 mm in y, which pybullet would push it out
    along, sideways. Shallow, yet wrong: past the middle."""
    c, wrong, s, *_ = judge(rows((0.1, 4e-4, 0.1), (0, 0), CUBE, (-0.5, -0.01), y_b=0.1004 - 3e-4))
    assert c is not None and wrong and s == pytest.approx((0.3 + PENETRATION) / 0.49, abs=1e-9)



def turning_rows(x0, dx, turn):
    """Rows of the wall and of the cube turned 45 degrees about z (a vertical edge towards
    the wall), its centre going from x0 to x0 + dx along x while it turns ``turn`` more."""
    poses = np.zeros((2, 2, 7))
    poses[..., 6] = 1.0
    for k, angle in enumerate((math.pi / 4, math.pi / 4 + turn)):
        poses[k, 1, 0] = x0 + k * dx
        poses[k, 1, 5:] = math.sin(angle / 2), math.cos(angle / 2)
    return _core.path_rows_between(poses[0], poses[1], np.arange(2, dtype=np.int64), np.arange(2, dtype=np.int64),
                                   np.stack([np.eye(4)] * 2), np.array([WALL, CUBE], dtype=float))


EDGE = -0.01 - 0.1 * math.sqrt(2)  # the cube's centre with its edge on the wall's face


def test_a_touching_pair_that_parts_and_meets_again_says_when():
    """An edge 0.1 mm into the wall at the start, the cube turning a quarter turn as its
    centre comes 3 mm closer: the edge leaves (the face turns towards the wall, 4 cm away
    midway), and the next edge strikes and ends 3.1 mm in: wrong, parted, and touching
    again where its depth crosses 0 (apart just before)."""
    r = turning_rows(EDGE + 1e-4, 0.003, math.pi / 2)
    c, wrong, _, _, parted, again, *_ = judge(r, s_touch=0.0)
    assert c is not None and wrong and parted
    a, b = _core.RowBoxPath(r[0]), _core.RowBoxPath(r[1])
    assert 0.5 < again < 1.0
    assert 0.0 <= _core.paths_depth(a, b, again) < 1e-12 and _core.paths_depth(a, b, again - 1e-9) < 0.0
    assert _core.paths_depth(a, b, 1.0) == pytest.approx(0.003 + 1e-4, abs=1e-9)


def test_a_touching_pair_that_parts_for_good_is_not_looked_at():
    """The same turn with the centre going 3 mm away instead: the next edge ends 2.9 mm
    short of the wall. Not wrong, so nothing is looked for."""
    r = turning_rows(EDGE + 1e-4, -0.003, math.pi / 2)
    c, wrong, _, _, parted, again, *_ = judge(r, s_touch=0.0)
    assert c is not None and not wrong and not parted and np.isnan(again)


@pytest.mark.parametrize("end", [0.5, 100.0])
def test_a_touching_pair_pressed_through_is_never_apart_first(end):
    """0.1 mm in at the start and driven through the wall: it ends apart on the far side,
    but reached the pressing depth first: not parted (the press is acted on). So too when
    it is through before the first time the pair is looked at for parting (100 m in the
    step: 0.4 m in its first 1/256, the cube and wall together 0.22 m)."""
    c, wrong, s, _, parted, again, *_ = judge(rows(WALL, (0, 0), CUBE, (-0.1099, end)), s_touch=0.0)
    assert c is not None and wrong and not np.isnan(s)
    assert not parted and np.isnan(again)


def test_a_pair_met_inside_the_window_is_not_looked_at_for_parting():
    assert not judge(rows(WALL, (0, 0), CUBE, (-0.5, 0.5)))[4]

# ------------------------------------------------------------- link boxes
def judge_link(r):
    return _core.judge_link_contact(_core.RowBoxPath(r[0]), _core.RowBoxPath(r[1]), 0.05, PENETRATION, CREEP, TOL)


def test_a_link_box_through_a_wall_goes_wrong_from_its_first_depth():
    """A link box's contact (any two box paths: ``judge_link_contact``): the cube through
    the 2 cm wall is acted on from x = -0.11 + penetration, touching at x = -0.11."""
    touch, act, c, _, _, initial, pressing, solves = judge_link(rows(WALL, (0, 0), CUBE, (-0.5, 0.5)))
    assert c is not None and solves >= 1 and not initial and not pressing
    assert touch == pytest.approx(0.39, abs=1e-6)
    assert act == pytest.approx(0.39 + PENETRATION, abs=1e-9)


@pytest.mark.parametrize("end", [-0.105, -0.1015])
def test_a_link_box_ending_deep_on_its_own_side_is_pybullets(end):
    """Ending 5 mm or 8.5 mm into the 2 cm wall from the side it came from, short of the
    wall's middle: a link's contact that ends merely deep is pybullet's (its motors press
    links into what they touch), unlike a free body's (wrong past 1 mm)."""
    touch, act, c, *_ = judge_link(rows(WALL, (0, 0), CUBE, (-0.5, end)))
    assert c is not None and touch == pytest.approx(0.39 / (end + 0.5) * 1.0, rel=1e-5) and np.isnan(act)
    assert judge(rows(WALL, (0, 0), CUBE, (-0.5, end)))[1]


@pytest.mark.parametrize("end", [-0.0985, -0.06, -0.001])
def test_a_link_box_past_the_middle_of_the_wall_goes_wrong(end):
    """Ending 1.5 mm past the 2 cm wall's middle, 3 cm past its far face, or with its centre
    1 mm short of the wall's: the boxes overlap along the normal by more than half the
    thinner one (the wall), so the nearest way out is through, and pybullet would resolve
    the pair from that overlap, not from the strike: acted on from the first depth."""
    touch, act, c, *_ = judge_link(rows(WALL, (0, 0), CUBE, (-0.5, end)))
    assert c is not None and act == pytest.approx((0.39 + PENETRATION) / (end + 0.5), abs=1e-9)


@pytest.mark.parametrize("end, wrong", [(0.2, True), (-0.05, True), (-0.1098, False), (-0.3, False)])
def test_a_link_box_pressing_as_the_step_begins(end, wrong):
    """0.1 mm in at the start (pressing, initial), then through the wall, 5 cm past its
    middle, 0.1 mm deeper, or lifted off: acted on, from the depth at the start plus the
    creep (0.2 mm), only where it ends where pybullet goes wrong; one ending in contact
    shallower than that target, or lifted off, is pybullet's."""
    touch, act, c, _, _, initial, pressing, _ = judge_link(rows(WALL, (0, 0), CUBE, (-0.1099, end)))
    assert initial and pressing and touch == 0.0
    if wrong:
        assert act == pytest.approx((-0.11 + 3e-4 + 0.1099) / (end + 0.1099), abs=1e-9)
    else:
        assert np.isnan(act)


def swinging_rows(x0, turn):
    """Rows of the wall and of the cube, its centre standing at x0, turning ``turn`` about z
    from square to the wall: its reach along x is 0.1 (cos a + sin a) at angle a."""
    poses = np.zeros((2, 2, 7))
    poses[..., 6] = 1.0
    poses[:, 1, 0] = x0
    poses[1, 1, 5:] = math.sin(turn / 2), math.cos(turn / 2)
    return _core.path_rows_between(poses[0], poses[1], np.arange(2, dtype=np.int64), np.arange(2, dtype=np.int64),
                                   np.stack([np.eye(4)] * 2), np.array([WALL, CUBE], dtype=float))


@pytest.mark.parametrize("dip, wrong", [(0.0214, True), (0.005, False)])
def test_a_link_box_swinging_into_a_wall_and_out_again(dip, wrong):
    """A link box turning a quarter turn in the step, apart from the 2 cm wall at both ends:
    its edge sweeps 2.14 cm into the wall at the middle of the step (through it: pybullet,
    which sees only the step's end, never meets that contact) and is acted on from its
    first depth; one whose edge dips 5 mm in, short of the wall's middle, is pybullet's, as
    a link's contact that ends merely deep is."""
    x0 = -0.01 - 0.1 * math.sqrt(2) + dip
    touch, act, c, *_ = judge_link(swinging_rows(x0, math.pi / 2))
    assert c is not None
    # The edge reaches the face when 0.1 sqrt(2) sin(a + pi/4) = -0.01 - x0 (a = turn so far);
    # the touch is the sweep's, on a fit of the turn: never late.
    angle = math.asin((-0.01 - x0) / (0.1 * math.sqrt(2))) - math.pi / 4
    assert 0.0 < touch <= angle / (math.pi / 2)
    if wrong:
        angle = math.asin((-0.01 + PENETRATION - x0) / (0.1 * math.sqrt(2))) - math.pi / 4
        assert act == pytest.approx(angle / (math.pi / 2), abs=1e-6)
    else:
        assert np.isnan(act)


def test_a_link_box_that_stays_apart_has_no_contact():
    touch, act, c, *_ = judge_link(rows(WALL, (0, 0), CUBE, (-0.5, -0.2)))
    assert np.isnan(touch) and np.isnan(act) and c is None


def pivoting_rows(half, turn):
    """Rows of the wall and of a box of half extents ``half`` standing with its x face 0.1 mm
    into the wall, turning ``turn`` about z in the step: its reach along x is
    hx cos a + hy sin a at angle a, hx again at the end when tan(turn / 2) = hy / hx."""
    poses = np.zeros((2, 2, 7))
    poses[..., 6] = 1.0
    poses[:, 1, 0] = -0.01 - half[0] + 1e-4
    poses[1, 1, 5:] = math.sin(turn / 2), math.cos(turn / 2)
    return _core.path_rows_between(poses[0], poses[1], np.arange(2, dtype=np.int64), np.arange(2, dtype=np.int64),
                                   np.stack([np.eye(4)] * 2), np.array([WALL, half], dtype=float))


@pytest.mark.parametrize("hy, wrong", [(0.05, True), (0.032, False)])
def test_a_touching_box_pivoting_into_a_wall_and_back_to_its_face(hy, wrong):
    """A box touching the 2 cm wall with its face (0.1 mm in) at both ends of the step, its
    edge sweeping sqrt(hx^2 + hy^2) - hx into the wall on the way: 1.18 cm (past the wall's
    middle: pybullet, which sees the shallow end, never meets that) goes wrong, from the time
    it is a creep deeper than it began; 5 mm (short of the middle) is pybullet's."""
    half = (0.1, hy, 0.1)
    r = pivoting_rows(half, 2.0 * math.atan(hy / half[0]))
    a, b = _core.RowBoxPath(r[0]), _core.RowBoxPath(r[1])
    assert _core.paths_depth(a, b, 1.0) == pytest.approx(1e-4, abs=1e-9)
    c, judged_wrong, s, *_ = judge(r, s_touch=0.0)
    assert c is not None and judged_wrong == wrong
    if wrong:
        target = 1e-4 + max(PENETRATION, min(CREEP * WALL[0], DEPTH_TOLERANCE))
        assert _core.paths_depth(a, b, s) == pytest.approx(target, abs=1e-9)
