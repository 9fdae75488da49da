// The pybullet plugin's per-step world logic on tables of boxes and frames: the
// broad phase (swept bounds and pybullet's collision filters), the first touches
// of pairs on their step paths, and the Sweeper, which holds a world's box tables
// across its steps so that a step's sweep passes the frames' state only.
//
// Indices come from the plugin's own tables; they are still checked, and a bad
// one throws std::out_of_range ("box index 7 out of range": IndexError in
// Python) instead of reading out of bounds; bad sizes throw std::invalid_argument.
// Nothing here runs Python: callers may release the GIL around any of it.
#pragma once

#include <cmath>
#include <cstddef>
#include <cstdint>
#include <utility>
#include <vector>

#include "paths/step_path.hpp"

namespace boxccd {

// Throws std::out_of_range "<what> index i out of range" unless 0 <= i < n.
void check_index(int64_t i, size_t n, const char *what);

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

// A world's boxes: box b sits at X_CS (4x4) with half extents `half` (3) on frame box_frame[b].
struct BoxTable {
    size_t n;  // boxes
    const int64_t *box_frame;
    const double *X_CS, *half;
};

// Path rows (PathRow, kPathBoxSize each) into out of the n boxes `boxes` (indices
// into the table), their frames' states (FrameState rows, n_frames of them) after a step of dt.
void path_rows(const double *state, size_t n_frames, double dt, const int64_t *boxes, size_t n,
               const BoxTable &table, double *out);

// The same for boxes on frames that went from poses0[f] to poses1[f] (7 each: position, quaternion).
void path_rows_between(const double *poses0, const double *poses1, size_t n_frames, const int64_t *boxes, size_t n,
                       const BoxTable &table, double *out);

// The poses (7 each) of n frames (indices into the n_frames states) at taus (one each).
void frame_poses(const double *state, size_t n_frames, double dt, const int64_t *frames, const double *taus,
                 size_t n, double *out);

// The first touch of each of n pairs (of rows) into out, NaN where none; returns the
// solver calls made. With creep >= 0, a pair touching at the start that does not
// press in (presses_in) counts as none. Each pair's Outcome goes to state (if not
// null), and is counted in counts[outcome] (if not null).
long first_touches(const double *rows, const int64_t *pairs, size_t n, double fit_tolerance, const Tolerances &tol,
                   double penetration, double creep, double *out, int8_t *state, int64_t *counts);

// The box and frame tables of a world (copied), and its frames' state (F rows of
// FrameState, owned: the plugin writes pybullet's reads into it).
class Sweeper {
  public:
    struct Tables {
        size_t n_boxes, n_frames;
        const int64_t *box_frame;      // (n_boxes) the frame of each box
        const double *radius;          // (n_boxes) farthest point of the box from its frame's origin
        const double *X_CS, *half;     // (n_boxes, 4, 4), (n_boxes, 3)
        const double *sweep_reach;     // (n_boxes) a box moving farther in a step is swept
        const int64_t *frame_body;     // (n_frames) the body of each frame
        const uint8_t *self_collides;  // (n_frames) whether the frame's body collides with itself
        const int64_t *group, *mask;   // (n_frames) pybullet's collision filter
        int filter_mode;               // FrameFilter::mode
    };
    explicit Sweeper(const Tables &t);  // throws std::out_of_range for a box's frame out of range

    size_t n_boxes() const { return n_; }
    size_t n_frames() const { return frame_body_.size(); }
    // The frames' state, (n_frames, kFrameStateSize) row-major; starts at rest at
    // the origin with the identity orientation.
    double *state() { return state_.data(); }
    const double *state() const { return state_.data(); }

    // The boxes that move farther than their sweep reach in a step of dt (a broken
    // body, whose reach is not finite, is left to pybullet), their frames (sorted,
    // unique), and the largest reach of the others (the slack of pybullet's own
    // detection); with `clamp`, the frames of the boxes swept as free or kinematic ones
    // (a finite sweep reach) at that speed (at_speed).
    struct Fast {
        std::vector<int64_t> boxes, frames;
        double slack = 0.0;
        std::vector<int64_t> broken;  // frames whose state is not finite (pybullet's alone)
        std::vector<int64_t> clamped;  // frames of boxes with a finite reach at_speed(clamp)
    };
    Fast fast(double dt, double clamp = INFINITY) const;

    // Those of the frames (checked) with a component of velocity or spin (world axes)
    // of magnitude `speed` or more, less rel_tol of it (pybullet's velocity clamp, which
    // cuts each component on its own; a velocity the world was put at can be above it).
    std::vector<int64_t> at_speed(const std::vector<int64_t> &frames, double speed, double rel_tol) const;
    bool at_clamp(int64_t frame, double speed, double rel_tol = 1e-9) const;

    // The farthest a box with a finite sweep reach moves in a step of dt (the boxes
    // given an infinite reach are swept elsewhere, on paths of their own).
    double slack(double dt) const;

    // The velocities the n frames (checked) leave step fraction tau of a step of dt
    // with when the world is taken back there: velocity_at (step_path.hpp) with mode[k],
    // twist0 (n_frames x 6: the velocities the step began with, or null), gravity and
    // damping (n_frames x 2: each frame's linear and angular damping, or null).
    // still[k]: the frame was at rest before and after the step (only known with
    // twist0). v, w: (n, 3) each.
    void velocities_at(double dt, double tau, const int64_t *frames, const int8_t *mode, size_t n,
                       const double *twist0, const double *gravity, const double *damping, double *v, double *w,
                       uint8_t *still) const;

    // Throws std::out_of_range for a box index out of range.
    void check_boxes(const std::vector<int64_t> &boxes) const;

    // Path rows (kPathBoxSize each) and swept bounds (6 each) of the n boxes (checked).
    void rows(double dt, const int64_t *boxes, size_t n, double *rows, double *bounds) const;

    // The first n_moving of `boxes` against each other and the rest of them (with
    // all_others: against every other box of the world, appended to `boxes`).
    // Every candidate pair's Outcome is counted into counts, if not null.
    struct Touches {
        size_t pairs = 0;   // candidate pairs
        long solves = 0;    // solver calls
        std::vector<int64_t> boxes;      // the boxes swept (with all_others, the others appended)
        std::vector<double> rows;        // their path rows
        std::vector<int64_t> pair_rows;  // (pairs, 2) candidate pairs of rows
        std::vector<double> tau;         // (pairs) first touch of each, NaN where none
    };
    Touches touches(double dt, std::vector<int64_t> boxes, int64_t n_moving, bool all_others, double fit_tolerance,
                    const Tolerances &tol, double penetration, double creep, int64_t *counts) const;

  private:
    void path_rows_and_bounds(double dt, const int64_t *boxes, size_t n, double *rows, double *bounds) const;

    size_t n_;
    std::vector<int64_t> box_frame_;
    std::vector<double> radius_, X_CS_, half_, sweep_reach_;
    std::vector<int64_t> frame_body_;
    std::vector<uint8_t> self_collides_;
    std::vector<int64_t> group_, mask_;
    int mode_;
    std::vector<double> state_;
};

}  // namespace boxccd
