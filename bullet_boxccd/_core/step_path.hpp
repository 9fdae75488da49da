// Overlap depth of two sharp boxes along Bullet's exact within-step paths, for
// placing rewound bodies: each box's frame moves linearly and turns about a
// fixed world axis (see bullet_boxccd/motion.py, StepPath).
#pragma once

namespace boxccd {

// One box on its path, as 42 doubles: X_W1 (4x4 row-major, the frame after the
// step), dv (3, displacement over the step), axis (3, unit), angle (turned over
// the step), X_CS (4x4, the box in its frame), half extents (3).
constexpr int kPathBoxSize = 42;

// Separating-axis overlap depth at step fraction tau: > 0 overlapping by that
// much, <= 0 apart (the gap, negated, along the best of the 15 axes).
double path_depth(const double *box_a, const double *box_b, double tau);

// The first tau in (tau_from, 1] at which the depth reaches `target`, NaN if it
// does not. A geometric look-ahead (offsets 2^-k of the rest of the step) finds
// the first sample past the target even for a fast pass through a thin wall;
// bisection then brackets the crossing to 1e-15 and returns its upper end.
double first_depth(const double *box_a, const double *box_b, double tau_from, double target);

// Axis-aligned bounds of a box over the whole step: exact at tau = 0, 1/4, ...,
// 1 (centre +- |R| half) and widened by the largest distance of a point's arc
// from its chords between them, r (angle / 4)^2 / 8 (r: the farthest box point
// from the frame's origin). lo and hi are (3,) each.
void swept_bounds(const double *box, double *lo, double *hi);

}  // namespace boxccd
