// Boxes on Bullet's exact within-step paths, for the pybullet plugin: each
// box's frame (a link's centre of mass) moves linearly with the post-solve
// velocity v and turns about the fixed world axis of the post-solve angular
// velocity w (Bullet's exponential map), rebuilt backwards from the pose after
// the step. tau in [0, 1] is the fraction of the step (1: after the step).
//
// Bullet clamps the angle above pi/4 per step, but it scales the quaternion's
// vector part by |w| / (clamped |w|) before normalising, so the realised angle
// is 2 atan(|w| dt / (pi/4) * tan(pi/8)) (btMultiBody::stepPositionsMultiDof
// and btTransformUtil::integrateTransform both do this; measured on pybullet
// 3.2.7 to 1e-15).
#pragma once

#include <limits>

#include "solver/box_ccd.hpp"

namespace boxccd {

// A frame's state after the step: the columns of one row of doubles (the Python
// side names the same columns: bullet_boxccd/pybullet_ccd/layout.py).
struct FrameState {
    static constexpr int kPosition = 0;          // (3) centre of mass, world
    static constexpr int kOrientation = 3;       // (4) quaternion x y z w, pybullet's order
    static constexpr int kVelocity = 7;          // (3) linear, world
    static constexpr int kAngularVelocity = 10;  // (3) world
    static constexpr int kSize = 13;
};
constexpr int kFrameStateSize = FrameState::kSize;

// One box on its path over the step: the columns of one row of doubles.
struct PathRow {
    static constexpr int kPoseAfter = 0;      // (16) X_W1, the frame after the step, 4x4 row-major
    static constexpr int kDisplacement = 16;  // (3) of the frame's origin over the step
    static constexpr int kAxis = 19;          // (3) unit, world: the fixed axis the frame turns about
    static constexpr int kAngle = 22;         // (1) turned over the step
    static constexpr int kBoxInFrame = 23;    // (16) X_CS, the box in its frame, 4x4 row-major
    static constexpr int kHalfExtents = 39;   // (3)
    static constexpr int kSize = 42;
};
constexpr int kPathBoxSize = PathRow::kSize;

// The angle Bullet turns a body in a step of dt at angular speed `speed`.
double bullet_step_angle(double speed, double dt);

// How far a point at distance `radius` from the frame's origin can move in the
// step: (|v| + |w| radius) dt (Bullet turns by at most |w| dt).
double step_reach(const double *state, double dt, double radius);

// The farthest point of a box (X_CS: 4x4 in its frame, half extents) from its frame's origin.
double reach_radius(const double *X_CS, const double *half);

// The path row of a box at X_CS (4x4) with half extents `half` on a frame with `state`.
void path_row(const double *state, double dt, const double *X_CS, const double *half, double *row);

// The path row of a box on a frame that went from pose0 to pose1 (position (3) and
// quaternion x y z w (4) each) over the step, moving linearly and turning about a
// fixed axis by the smaller angle: a kinematic body the user moved between steps.
void path_row_between(const double *pose0, const double *pose1, const double *X_CS, const double *half, double *row);

// The pose (4x4 row-major) of a path row's box at tau.
void row_pose(const double *row, double tau, double *pose);

// The path row over the window [lo, hi] of the step, on its own tau in [0, 1].
void window_row(const double *row, double lo, double hi, double *out);

// The frame's pose at tau: position (3) and unit quaternion x y z w (4).
void frame_pose(const double *state, double dt, double tau, double *pose);

// A fixed base moved by its velocity (a kinematic body): Bullet turns its linear
// velocity with its spin w as it integrates a step of h, v_end = v + h w x v, and moves
// it by v_end h (measured on pybullet 3.2.7 to 1e-16). The linear velocity v that ends
// a step of h at v_end: (I + h [w x])^-1 v_end.
void fixed_base_velocity_before(const double *v_end, const double *w, double h, double *v);

// Bullet's damping of a multibody's base (btMultiBody: a unit mass's acceleration
// -d (1 + |x|) x, on the velocity x the step starts from; measured on pybullet 3.2.7 to
// 1e-10): the velocity x that a step of h with damping coefficient d ends at b, net of
// every other acceleration, x (1 - h d (1 + |x|)) = b. x may alias b.
void undamped_velocity(const double *b, double d, double h, double *x);

// The velocities (v, w: 6) a frame leaves step fraction tau of a step of dt with when the
// world is taken back there, so that the rest of the step simulated again ends as the
// step did, from its velocities after the step (`after`: v, w) and, if known, before it
// (`before`, or null). mode 0: a fixed base moved by its velocity (the linear one as
// fixed_base_velocity_before gives it over the rest); 1: between before and after, in
// proportion (2 without before); 2: after, less the rest of the step's gravity and of its
// damping (`damping`: linear and angular coefficients, or null for none) (a body struck
// as the step began, or one whose velocities before are not known: in free flight the
// rest of the step then ends exactly where the step ended).
void velocity_at(const double *after, const double *before, int mode, double dt, double tau, const double *gravity,
                 const double *damping, double *out);

// Separating-axis overlap depth of two boxes at poses X_WA, X_WB (4x4 row-major)
// with half extents ha, hb: > 0 overlapping by that much, <= 0 apart (the gap,
// negated, along the best of the 15 axes). The one overlap test of every path kind.
double pose_depth(const double *X_WA, const double *ha, const double *X_WB, const double *hb);

// pose_depth, with the axis that gives it (unit, from A towards B; if not null): for
// an overlap, the direction in which B is pushed out along the least overlap. With a
// floor: stops at the first axis whose overlap is below it (the depth is then below
// the floor, and the axis is that one).
double pose_separation(const double *X_WA, const double *ha, const double *X_WB, const double *hb, double *axis,
                       double floor = -std::numeric_limits<double>::infinity());

// Axis-aligned bounds of a box over the whole step: exact at tau = 0, 1/4, ...,
// 1 (centre +- |R| half) and widened by the largest distance of a point's arc
// from its chords between them, r (angle / 4)^2 / 8 (r: the farthest box point
// from the frame's origin). lo and hi are (3,) each.
void swept_bounds(const double *box, double *lo, double *hi);

// Quadratic motion of the box over the window [lo, hi] of the step (on its own
// t in [0, 1]): interpolation of the exact pose at the window's start, middle
// and end, written to coeffs (3x4x4, row-major). The position is linear, so it
// is exact; the 3x3 part deviates from the true rotation by at most the
// returned bound (spectral norm), so a point at distance r from the frame's
// origin is off by at most bound * r.
double fit_path(const double *box, double lo, double hi, double *coeffs);

// Pieces (1, 2, 4, ... 64) of the step for which the fit of the box errs by at
// most fit_tolerance times its smallest half extent.
int fit_pieces(const double *box, double fit_tolerance);

// Depths, first touches and contacts of two path rows' boxes are box_path.hpp's, on
// RowBoxPaths (one abstraction for every path kind).

}  // namespace boxccd
