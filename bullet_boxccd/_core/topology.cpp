// Section topology and facet polynomials. See topology.hpp.
#include "topology.hpp"

namespace boxccd {

void axis_signs(int ax, const double *pv, int8_t *sig) {
    for (int g = 0; g < 6; ++g) {
        const Projection pr = kProjection.p[ax][g];
        const double v = pr.index >= 0 ? pr.sign * pv[pr.index] : 0.0;
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
    double pv[20];
    triple_products(gs, pv);
    axis_signs(ax, pv, piece.sig);
    const double len = norm3(cross3(gs[axis_generator(ax, 0)], gs[axis_generator(ax, 1)]));
    Poly P = (k % 2 == 0 ? 1.0 : -1.0) * cof.normal_dot_d(ax);
    // sig_g (n.g) = |n.g| (product() is n.g itself, sign included).
    for (int g = 0; g < 6; ++g)
        if (piece.sig[g]) axpy(P, -piece.sig[g] * pair.h[g], cof.product(ax, g));
    P.c[0] -= pair.tau(ax, len);
    piece.Q = P;
    piece.lo = lo;
    piece.hi = hi;
}

}  // namespace boxccd
