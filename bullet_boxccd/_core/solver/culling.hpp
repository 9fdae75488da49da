// Culling: proofs that the boxes stay apart, from fixed separating axes, before
// (and between) the BMS searches. A fixed direction n that separates the boxes
// at s keeps them apart while
//   |n.d(s')| - sum_g h_g |n.g(s')| > margin,
// and for fixed n every term is a quadratic in s'. From s, the first time a
// lower bound of that gap reaches the margin is a step of conservative
// advancement: the boxes are apart before it, whatever happens to the BMS
// topology. Repeated from the new time with the then most separating axis, the
// steps shrink geometrically towards a contact (or run past the range's end: a
// miss), and the BMS search takes over near the contact on a short window,
// where most octant switches are proven absent without root isolation.
#pragma once

#include "solver/bms.hpp"

namespace boxccd {

// The pair at one time: d and the generators, with their derivatives.
struct Sample {
    double s;
    Vec3 g[6], dg[6], d, dd;
};
Sample sample_at(const Pair &pair, double s);

// The most separating of the 15 axes at a sample, if one separates by more than
// the margin (axis -1 otherwise: the boxes touch or overlap there).
struct SeparatingAxis {
    int axis = -1;
    int facet = -1;     // its BMS facet (the sign of n.d picks +n or -n)
    Vec3 n{};           // unnormalised normal
    double len = 0.0;   // |n|
    double gap = 0.0;   // separation along n / |n|: a length
};
SeparatingAxis most_separating(const Pair &pair, const Sample &at);

// One axis at a sample (its normal there), if it separates by more than the margin.
SeparatingAxis axis_at(const Pair &pair, const Sample &at, int axis);

// The first s' in (at.s, hi] at which a lower bound of the gap along the fixed
// axis reaches the margin; hi if it stays above it. Before the answer the boxes
// are apart.
double apart_until(const Pair &pair, const Sample &at, const SeparatingAxis &axis, double hi);

// Conservative advancement from `from`: either the boxes are apart on [from, 1]
// (apart), or they are apart on [from, start) and the BMS search should look on
// [start, end] first, starting from `facet` (-1: none separates at start). The
// window is at least `min_window` long (the caller doubles it each time a window
// stays apart, so a slow approach costs a few windows, not one per step).
struct Culling {
    bool apart = false;
    double start = 0.0, end = 1.0;
    int facet = -1;
};
Culling advance_on_axes(const Pair &pair, double from, double min_window);

}  // namespace boxccd
