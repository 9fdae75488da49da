// A box on an arbitrary within-step path, and the first touch of two of them.
//
// tau in [0, 1] is the fraction of the step (0: its start, 1: after it). A path
// kind says three things about its box: the exact pose at tau, a quadratic fit
// of that pose over a piece [lo, hi] of the step with how much the box must grow
// for the fitted motion to hold the true box throughout the piece, and how many
// pieces keep that growth small. Two kinds exist: RowBoxPath (a free frame's
// path row, step_path.hpp) and LinkBoxPath (a link of an articulated body,
// chain.hpp). first_touch takes any two, so the plugin sweeps link boxes
// against anything with one function.
#pragma once

#include <limits>

#include "solver/box_ccd.hpp"
#include "paths/step_path.hpp"

namespace boxccd {

class BoxPath {
  public:
    virtual ~BoxPath() = default;
    // X_WS(tau): the box's pose at step fraction tau, 4x4 row-major (the box's
    // axes as columns, its centre as the last column), world frame.
    virtual void pose(double tau, double *X_WS) const = 0;
    // (3,) half extents of the box.
    virtual const double *half_extents() const = 0;
    // The quadratic motion M(s) = C0 + C1 s + C2 s^2, s = (tau - lo) / (hi - lo)
    // in [0, 1], interpolating X_WS at lo, (lo + hi) / 2 and hi, written to
    // coeffs (3x4x4 row-major), and returned: how much each half extent must
    // grow (a length) so that the box, so grown, on M(s) holds the true box
    // at every tau of the piece. +inf when no growth is proven to do it.
    virtual double fit(double lo, double hi, double *coeffs) const = 0;
    // Pieces (1, 2, 4, ... 64) of the step for which the growth stays below
    // fit_tolerance times the box's smallest half extent (64 if none does).
    virtual int pieces(double fit_tolerance) const = 0;
    // Whether every number the path holds is finite (one that is not has no touch).
    virtual bool finite() const = 0;
    // How far any point of the box can be, over [lo, hi], from where it is at
    // (lo + hi) / 2 (a length, world): what first_depth's look-ahead skips with.
    virtual double travel(double lo, double hi) const = 0;
    // The farthest point of the box from its frame's origin.
    virtual double reach() const = 0;
};

// A box on a free frame's path row (PathRow, 42 doubles, copied).
class RowBoxPath : public BoxPath {
  public:
    explicit RowBoxPath(const double *row);
    void pose(double tau, double *X_WS) const override;
    const double *half_extents() const override { return row_ + PathRow::kHalfExtents; }
    double fit(double lo, double hi, double *coeffs) const override;
    int pieces(double fit_tolerance) const override;
    bool finite() const override { return finite_; }
    double travel(double lo, double hi) const override;
    double reach() const override { return reach_; }

  private:
    double row_[PathRow::kSize];
    double reach_;  // the farthest point of the box from its frame's origin
    bool finite_;
};

// pose_depth of two paths' boxes at tau.
double path_depth(const BoxPath &a, const BoxPath &b, double tau);

// pose_separation of two paths' boxes at tau (axis: (3,) or null; floor: stop at
// the first axis whose overlap is below it, as pose_separation).
double path_separation(const BoxPath &a, const BoxPath &b, double tau, double *axis,
                       double floor = -std::numeric_limits<double>::infinity());

// How far the corners of the box with the smaller largest half extent move in the
// other box's frame from the step's start (tau 0) to its end (tau 1): the pair's
// relative move over the step's chord.
double relative_move(const BoxPath &a, const BoxPath &b);

// The first tau in (from, 1] at which the boxes' depth reaches `target`
// (path_depth >= target), NaN if it does not. A geometric look-ahead (offsets
// 2^-k of the rest of the step, k = kDepthLookAhead .. 0) finds the first sample
// past the target even for a fast pass through a thin wall; between two samples
// below it, the gaps where the depth could have risen to the target and fallen back
// (it moves no faster than the boxes' points) are split until it could not, or it
// did; bisection then brackets the crossing to kDepthWidth and returns its upper
// end. Samples nearer `from` than the boxes' travel lets the depth grow to the
// target are skipped. depth_from: the depth at `from`, if known (NaN: computed).
double first_depth(const BoxPath &a, const BoxPath &b, double from, double target,
                   double depth_from = std::numeric_limits<double>::quiet_NaN());

// A corner of one box striking the other: when, and which.
struct CornerStrike {
    double tau = std::numeric_limits<double>::quiet_NaN();  // NaN: none
    bool of_a = true;  // a corner of a (into b), else of b (into a)
    int corner = -1;   // bit j: on the + side of its box's axis j
};

// The first tau in (from, 1] at which a corner of either box that was outside the other
// by more than `gap` at `from` is inside it by `target` (its least distance to a face of
// the other box), found by first_depth's look-ahead and bisection. What it sees is a
// corner striking, not an edge.
CornerStrike first_corner_strike(const BoxPath &a, const BoxPath &b, double from, double gap, double target);

// The contact of a corner strike at its time: the corner, the normal of the face it is at
// (from A towards B), a VO or OV facet and its features. Separated without a strike.
Hit corner_contact(const BoxPath &a, const BoxPath &b, const CornerStrike &strike);

// Whether two boxes that touch at the start of the step press in during it: their
// overlap grows past what it was at the start by penetration, and by creep times
// the smaller half extent of the two (less is the creep of a contact pybullet
// holds). depth0: the depth at the start, if known.
bool presses_in(const BoxPath &a, const BoxPath &b, double penetration, double creep,
                double depth0 = std::numeric_limits<double>::quiet_NaN());

// Bounds (lo, hi: world) of the box over the whole step: its place at the middle
// of each of n equal pieces, grown by the travel over that piece.
void path_bounds(const BoxPath &path, int n, double *lo, double *hi);

// The first touch of two boxes on their fitted motions: the step is cut into
// the larger of the two paths' pieces, and on each piece, in order, both
// fitted motions carry their boxes grown by the fit's growth, so the answer is
// never later than the true first touch and never misses one. The step
// fraction, or NaN if they stay apart (or a path is not finite). A piece whose growth is not finite
// (motion too fast to fit even in 64 pieces) is reported as touching at its
// start (early, never late). depth0: path_depth at 0 if known (NaN: computed);
// touching then is a touch at 0. `solves` counts the solver calls. `outcome` says
// what happened (Separated, NonFinite, Initial for a touch at 0, StepCap for a piece
// no fit up to kMaxFitPieces proves, or the solver's outcome on the touching piece:
// a degraded one is early and not proven). With `contact`, the solver's contact
// (point, normal, features on the grown boxes' fitted motions; t in step fractions)
// is written there (outcome Separated when apart; a touch at the start or on an
// unfitted piece may have no facet).
double first_touch(const BoxPath &a, const BoxPath &b, double fit_tolerance, const Tolerances &tol, long &solves,
                   Outcome &outcome, double depth0 = std::numeric_limits<double>::quiet_NaN(),
                   Hit *contact = nullptr);

// The first touch of two boxes known to touch within [lo, hi] (step fractions),
// with its geometry: one quadratic fit of each path over the window (widened to
// kMinWindow if narrower), each box grown by its fit's growth and by kMinWindow
// of its reach (the refit's rounding), so that the touch cannot be lost. t is a
// step fraction. NonFinite for a path that is not finite; StepCap (t = lo) when
// no fit over the window is proven.
Hit window_contact(const BoxPath &a, const BoxPath &b, double lo, double hi, const Tolerances &tol);

}  // namespace boxccd
