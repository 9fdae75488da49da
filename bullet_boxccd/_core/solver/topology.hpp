// Section topology: where no octant switch of an axis' projections falls (a
// section of the route, as far as that axis is concerned) every n.g keeps its
// sign, so each of the axis' two facets is a fixed signed sum, a polynomial of
// degree <= 6:
//   Q_k(s) = +-n.d - sum_g sig_g h_g (n.g) - tau_axis     (<= 0: touching)
//          = n . (+-d - sum_g sig_g h_g g) - tau_axis
// with sig_g the sign of n.g at the section's middle (the algorithm's t_0: "sample the
// topology at a middle point") and tau the axis' touching tolerance plus its
// rounding allowance there. The second form is the facet's plane through its
// support point (a vertex combination of the two boxes): one dot product of the
// axis' normal (degree 4) with a quadratic curve.
#pragma once

#include <array>
#include <cstdint>

#include "solver/bms.hpp"

namespace boxccd {

// Signs of n_axis . g (+1, -1; 0 for the axis' own two generators, a structural
// zero) from the generators gs at one time.
void axis_signs(int axis, const Vec3 *gs, int8_t *sig);

// The touching features of facet k with the axis' signs sig, as sign triples
// over each box's local axes (-1 = lo side, +1 = hi side, 0 = the feature spans
// that axis).
void facet_features(int facet, const int8_t *sig, int8_t *feat_a, int8_t *feat_b);

// One facet's polynomial over [lo, hi], an interval without a switch of its axis.
struct FacetPiece {
    double lo, hi;
    int8_t sig[6];
    Poly Q;
    bool covers(double s) const { return lo <= s && s < hi; }
};

// Q_k on [lo, hi] (signs sampled at the middle).
void build_piece(const Pair &pair, Cofactors &cof, int facet, double lo, double hi, FacetPiece &piece);

}  // namespace boxccd
