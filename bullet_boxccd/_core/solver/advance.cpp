// Advancement to the first contact. See advance.hpp.
#include "solver/advance.hpp"

#include <algorithm>
#include <cmath>

#include "solver/route.hpp"

namespace boxccd {

void fixed_axes(const Pair &pair, FixedAxes &f) {
    Vec3 gs[6];
    for (int g = 0; g < 6; ++g) gs[g] = pair.g[g].c[0];
    axes_at(pair, gs, pair.d.c[0], f.at);
    for (int ax = 0; ax < 15; ++ax) {
        f.n[ax] = axis_normal(gs, ax);
        const double len = std::sqrt(f.at.nn2[ax]);
        f.len[ax] = f.at.direction[ax] ? len : 0.0;
        f.tau[ax] = pair.tau(ax, len);
    }
}

void facet_values(const Pair &pair, double s, FacetValues &f, const FixedAxes *fixed) {
    const Vec3 d = pair.d.at(s);
    if (fixed) {
        for (int ax = 0; ax < 15; ++ax) {
            const double nd = dot3(fixed->n[ax], d), base = fixed->at.support[ax] + fixed->tau[ax];
            f.len[ax] = fixed->len[ax];
            f.q[2 * ax] = nd - base;
            f.q[2 * ax + 1] = -nd - base;
        }
        return;
    }
    Vec3 gs[6];
    for (int g = 0; g < 6; ++g) gs[g] = pair.g[g].at(s);
    AxesAt v;
    axes_at(pair, gs, d, v);
    for (int ax = 0; ax < 15; ++ax) {
        // tau >= noise: an axis whose gap does not exceed its noise has no positive
        // facet, and needs no |n| (a square root) for its tolerance.
        double tau = pair.noise[ax];
        f.len[ax] = -1.0;
        if (std::fabs(v.nd[ax]) - v.support[ax] > tau) {
            const double len = std::sqrt(v.nn2[ax]);
            f.len[ax] = v.direction[ax] ? len : 0.0;
            tau = pair.tau(ax, len);
        }
        f.q[2 * ax] = v.nd[ax] - v.support[ax] - tau;
        f.q[2 * ax + 1] = -v.nd[ax] - v.support[ax] - tau;
    }
}

namespace {

// The facet of least penetration at s: the largest +-n.d - support over |n| among
// the axes with a direction.
int least_penetration(const Pair &pair, double s, const Vec3 *gs) {
    AxesAt v;
    axes_at(pair, gs, pair.d.at(s), v);
    int best = 0;
    double best_v = -std::numeric_limits<double>::infinity();
    for (int ax = 0; ax < 15; ++ax) {
        if (!v.direction[ax]) continue;
        const double len = std::sqrt(v.nn2[ax]), gap = (std::fabs(v.nd[ax]) - v.support[ax]) / len;
        if (gap > best_v) {
            best_v = gap;
            best = 2 * ax + (v.nd[ax] < 0.0);
        }
    }
    return best;
}

}  // namespace

namespace {

// Boxes that do not turn: one piece over the whole range, +-n.d(s) - support -
// tau with the constant axis (a quadratic).
void fixed_piece(const Pair &pair, const FixedAxes &fixed, int k, FacetPiece &piece) {
    const int ax = k / 2;
    const Vec3 &n = fixed.n[ax];
    const double sgn = k % 2 == 0 ? 1.0 : -1.0;
    Poly &Q = piece.Q;
    Q.deg = 2;
    for (int c = 0; c < 3; ++c) Q.c[c] = sgn * dot3(n, pair.d.c[c]);
    Q.c[0] -= fixed.at.support[ax] + fixed.tau[ax];
    trim(Q);
    Vec3 gs[6];
    for (int g = 0; g < 6; ++g) gs[g] = pair.g[g].c[0];
    axis_signs(ax, gs, piece.sig);
    piece.lo = 0.0;
    piece.hi = 1.0;
}

// Facet k's piece at s: the cached one if it covers s, else built up to the next
// switch of its axis (searched from a few root widths on: a switch at s itself
// was passed already) or `end`.
FacetPiece &piece_at(const Pair &pair, Cofactors &cof, SearchState &st, int k, double s, double end) {
    FacetPiece &piece = st.pieces[k];
    if ((st.built & (1u << k)) && piece.covers(s)) return piece;
    if (st.fixed) {
        fixed_piece(pair, *st.fixed, k, piece);
    } else {
        const double hi = std::min(end, axis_switch(pair, cof, k / 2, s + kSwitchRepeat * kRootWidth, end));
        build_piece(pair, cof, k, s, std::max(s, hi), piece);
    }
    st.built |= 1u << k;
    return piece;
}

// The facet most separating at s among those positive and not marked touching
// (-1: none): rank by distance, q / |n|.
int most_separating_facet(const FacetValues &f, uint32_t touching) {
    int best = -1;
    double best_v = 0.0;
    for (int k = 0; k < 30; ++k) {
        if (f.q[k] <= 0.0 || (touching & (1u << k))) continue;
        const double len = f.len[k / 2];
        const double rank = len > 0.0 ? f.q[k] / len : 0.0;
        if (best < 0 || rank > best_v) {
            best_v = rank;
            best = k;
        }
    }
    return best;
}

}  // namespace

bool search(const Pair &pair, Cofactors &cof, double start, double end, SearchState &st, double &s) {
    s = start;
    // Warm start: the facet that kept the last window apart (or that the culling
    // saw separating) often keeps this one apart too, which the other 29 facets
    // need not be asked about.
    if (st.separating >= 0) {
        const int k = st.separating;
        const FacetPiece &piece = piece_at(pair, cof, st, k, s, end);
        if (piece.Q(s) > 0.0) {
            bool clustered = false;
            const double r = first_nonpositive(piece.Q, s, piece.hi, clustered);
            if (std::isnan(r)) {
                if (piece.hi >= end) return false;
                s = piece.hi;
            } else if (r > s) {
                s = r;
                st.last = k;
                st.last_at = r;
                st.clustered = clustered;
            }
        }
    }
    uint32_t touching = 0;  // facets within rounding of zero at this s
    FacetValues f;
    double evaluated_at = kNoRoot;
    for (int step = 0; step < pair.tol.max_steps; ++step) {
        if (!(s == evaluated_at)) {
            facet_values(pair, s, f, st.fixed);
            evaluated_at = s;
            touching = 0;
        }
        const int best = most_separating_facet(f, touching);
        if (best < 0) return true;
        const FacetPiece &piece = piece_at(pair, cof, st, best, s, end);
        bool clustered = false;
        const double r = first_nonpositive(piece.Q, s, piece.hi, clustered);
        if (std::isnan(r)) {  // apart until the piece's end: the window's, or a switch of this facet's axis
            st.separating = best;
            if (piece.hi >= end) return false;
            s = piece.hi;
            continue;
        }
        if (r <= s) {  // the value and the Bernstein bound disagree in the last bits: touching here
            touching |= 1u << best;
            continue;
        }
        s = r;
        st.last = best;
        st.last_at = r;
        st.clustered = clustered;
    }
    st.capped = true;
    return true;
}

int contact_facet(const Pair &pair, const SearchState &st, double s, int8_t *sig) {
    if (st.last >= 0 && st.last_at == s && s > 0.0) {
        std::copy(st.pieces[st.last].sig, st.pieces[st.last].sig + 6, sig);
        return st.last;
    }
    Vec3 gs[6];
    for (int g = 0; g < 6; ++g) gs[g] = pair.g[g].at(s);
    const int best = least_penetration(pair, s, gs);
    axis_signs(best / 2, gs, sig);
    return best;
}

}  // namespace boxccd
