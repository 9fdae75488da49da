// Section topology and facet polynomials. See topology.hpp.
#include "solver/topology.hpp"

#include <algorithm>

namespace boxccd {

void axis_signs(int ax, const Vec3 *gs, int8_t *sig) {
    const int g1 = axis_generator(ax, 0), g2 = axis_generator(ax, 1);
    const Vec3 n = cross3(gs[g1], gs[g2]);
    for (int g = 0; g < 6; ++g) {
        const double v = g == g1 || g == g2 ? 0.0 : dot3(n, gs[g]);
        sig[g] = static_cast<int8_t>((v > 0.0) - (v < 0.0));
    }
}

void facet_features(int k, const int8_t *sig, int8_t *feat_a, int8_t *feat_b) {
    const int sgn = k % 2 == 0 ? 1 : -1;  // the outward normal's sign on each generator
    for (int i = 0; i < 3; ++i) {
        feat_a[i] = static_cast<int8_t>(sgn * sig[i]);
        feat_b[i] = static_cast<int8_t>(-sgn * sig[3 + i]);
    }
}

void build_piece(const Pair &pair, Cofactors &cof, int k, double lo, double hi, FacetPiece &piece) {
    const int ax = k / 2;
    const double mid = 0.5 * (lo + hi);
    Vec3 gs[6];
    for (int g = 0; g < 6; ++g) gs[g] = pair.g[g].at(mid);
    axis_signs(ax, gs, piece.sig);
    // The support point's curve w = +-d - sum_g sig_g h_g g.
    const double sgn = k % 2 == 0 ? 1.0 : -1.0;
    Curve w;
    int wdeg = pair.ddeg;
    for (int c = 0; c < 3; ++c)
        for (int r = 0; r < 3; ++r) w.c[c][r] = sgn * pair.d.c[c][r];
    for (int g = 0; g < 6; ++g) {
        if (!piece.sig[g]) continue;
        const double f = -piece.sig[g] * pair.h[g];
        for (int c = 0; c < 3; ++c)
            for (int r = 0; r < 3; ++r) w.c[c][r] += f * pair.g[g].c[c][r];
        wdeg = std::max(wdeg, pair.gdeg[g]);
    }
    piece.Q = dot_curve(cof.normal(ax), pair.normal_degree(ax), w, wdeg);
    trim(piece.Q);
    const double len = norm3(cross3(gs[axis_generator(ax, 0)], gs[axis_generator(ax, 1)]));
    piece.Q.c[0] -= pair.tau(ax, len);
    piece.lo = lo;
    piece.hi = hi;
}

}  // namespace boxccd
