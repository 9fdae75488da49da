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

#include <cstdint>
#include <limits>
#include <utility>
#include <vector>

#include "box_ccd.hpp"

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

// Separating-axis overlap depth at step fraction tau: > 0 overlapping by that
// much, <= 0 apart (the gap, negated, along the best of the 15 axes).
double path_depth(const double *box_a, const double *box_b, double tau);

// path_depth, with the axis that gives it (unit, from A towards B): for an overlap,
// the direction in which B is pushed out along the least overlap.
// With a floor: stops at the first axis whose overlap is below it (the depth is then
// below the floor, and the axis is that one).
double path_separation(const double *box_a, const double *box_b, double tau, double *axis,
                       double floor = -std::numeric_limits<double>::infinity());

// The first tau in (tau_from, 1] at which the depth reaches `target`, NaN if it
// does not. A geometric look-ahead (offsets 2^-k of the rest of the step) finds
// the first sample past the target even for a fast pass through a thin wall;
// bisection then brackets the crossing to 1e-15 and returns its upper end.
// Samples nearer tau_from than the boxes' travel lets the depth grow to the target
// are skipped (penetration depth moves no faster than the boxes' points).
// depth_from: the depth at tau_from, if known (NaN: computed).
double first_depth(const double *box_a, const double *box_b, double tau_from, double target,
                   double depth_from = std::numeric_limits<double>::quiet_NaN());

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

// The first touch of two boxes on their fitted motions, each piece's box
// inflated by the fit's error bound so that the answer is never late: the step
// fraction, NaN if they stay apart or a row is not finite; `outcome` says which
// (Separated, NonFinite, Initial for a pair touching at the start, or the solver's
// outcome on the touching piece: a degraded one is early and not proven). `solves`
// counts the solver calls (one per piece tried).
// depth0: path_depth at 0, if known (NaN: computed); a pair touching then touches at 0.
double first_touch(const double *box_a, const double *box_b, double fit_tolerance, const Tolerances &tol,
                   long &solves, Outcome &outcome, double depth0 = std::numeric_limits<double>::quiet_NaN());

// Whether two boxes that touch at the start of the step (path rows) press in during
// it: their overlap grows past what it was at the start by penetration, and by
// creep times the smaller half extent of the two (less is the creep of a contact
// pybullet holds).
bool presses_in(const double *box_a, const double *box_b, double penetration, double creep,
                double depth0 = std::numeric_limits<double>::quiet_NaN());

// The first touch of two boxes known to touch within [lo, hi], with its
// geometry (one fit over the window, inflated likewise); t is a step fraction.
// Its outcome says what happened (NonFinite for a row that is not finite).
Hit path_contact(const double *box_a, const double *box_b, double lo, double hi, const Tolerances &tol);

// A rigid body at a collision: centre of mass (world), inverse mass, inverse and
// direct inertia (world, 3x3 row-major; 0 for an immovable body), velocities.
struct CollisionBody {
    double com[3], inv_m, inv_I[9], I[9], v[3], w[3];
};

// The collision of bodies a and b touching at n_points points (3 each) with unit
// normal n (from a towards b); velocities are updated in place. First perfectly
// inelastic, as a contact solver makes it: sweeps of sequential impulses at the
// points, a normal one that never pulls (the sum at a point stays >= 0) and stops the
// point's approach, and a friction one along the sliding direction bounded by mu
// times the point's normal impulse (Coulomb). Then restitution as Newton's law on the
// centres of mass: the pair parts along n at e times the speed it approached. Last,
// the change is scaled down if it would raise the kinetic energy. Returns whether any
// point approached.
bool resolve_collision(CollisionBody &a, CollisionBody &b, const double *points, int n_points, const double *n,
                       double e, double mu, int sweeps);

// pybullet's collision filter test of two frames' groups and masks (pair rules
// are applied by the caller): mode 0 "A's group & B's mask, and B's group & A's
// mask", mode 1 (pybullet's default) "... or ...".
struct FrameFilter {
    const int64_t *group, *mask;
    int mode;
    bool allowed(int64_t a, int64_t b) const {
        const bool ab = (group[a] & mask[b]) != 0, ba = (group[b] & mask[a]) != 0;
        return mode == 1 ? (ab || ba) : (ab && ba);
    }
};

// Pairs of the n boxes whose swept bounds meet, for the broad phase: bounds is
// (n, 6), lo then hi of each box (swept_bounds). Boxes 0 .. n_fast - 1 are the
// fast ones: every pair has a fast first member, and a pair of fast boxes
// appears once. frame[i] is box i's frame; boxes of one frame never pair, nor
// boxes of one body unless it self-collides (self_collides[frame]), nor frames
// the filter keeps apart.
std::vector<std::pair<int64_t, int64_t>> candidate_pairs(const double *bounds, int64_t n, int64_t n_fast,
                                                         const int64_t *frame, const int64_t *frame_body,
                                                         const uint8_t *self_collides, const FrameFilter &filter);

}  // namespace boxccd
