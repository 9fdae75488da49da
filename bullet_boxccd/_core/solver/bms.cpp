// The pair's Minkowski difference: setup in the pair's frame, the 15 axes at a
// time, the cofactor polynomials, the regularity check. See bms.hpp.
#include "solver/bms.hpp"

#include <algorithm>
#include <cstdio>

namespace boxccd {

namespace {

// Coefficient (k, r, c) of a row-major (3, 4, 4) array.
inline double coef(const double *C, int k, int r, int c) { return C[k * 16 + r * 4 + c]; }

// Double-double arithmetic (error-free transforms, no FMA needed): the centres'
// constant terms are summed exactly, so that the shared translation taken off
// both boxes loses nothing the input had.
struct DD {
    double hi = 0.0, lo = 0.0;
};
inline void two_sum(double a, double b, double &s, double &e) {
    s = a + b;
    const double bb = s - a;
    e = (a - (s - bb)) + (b - bb);
}
inline void split(double a, double &hi, double &lo) {  // Dekker: a = hi + lo, 26 bits each
    const double c = 134217729.0 * a;
    hi = c - (c - a);
    lo = a - hi;
}
inline void two_prod(double a, double b, double &p, double &e) {
    p = a * b;
    double ah, al, bh, bl;
    split(a, ah, al);
    split(b, bh, bl);
    e = ((ah * bh - p) + ah * bl + al * bh) + al * bl;
}
inline void add(DD &x, double v) {
    double s, e;
    two_sum(x.hi, v, s, e);
    x.hi = s;
    x.lo += e;
}
inline void add_prod(DD &x, double a, double b) {
    double p, e;
    two_prod(a, b, p, e);
    add(x, p);
    x.lo += e;
}
inline double round_dd(const DD &x) { return x.hi + x.lo; }

// Entry (r, c) of M(t0 + w s) as a quadratic in s: its three coefficients.
void entry_in_s(const double *C, int r, int c, double t0, double w, double out[3]) {
    const double c0 = coef(C, 0, r, c), c1 = coef(C, 1, r, c), c2 = coef(C, 2, r, c);
    out[0] = c0 + t0 * (c1 + t0 * c2);
    out[1] = (c1 + 2.0 * c2 * t0) * w;
    out[2] = c2 * w * w;
}

// The exact constant term (s = 0, t = t0) of entry (r, c) times k, added to x.
void add_entry_at_t0(DD &x, const double *C, int r, int c, double t0, double k) {
    const double c0 = coef(C, 0, r, c), c1 = coef(C, 1, r, c), c2 = coef(C, 2, r, c);
    if (k == 1.0) add(x, c0); else add_prod(x, k, c0);
    if (t0 == 0.0) return;
    double t0c1, e1;
    two_prod(t0, c1, t0c1, e1);  // t0 c1 exactly
    add_prod(x, k, t0c1);
    add_prod(x, k, e1);
    double tt, ett;
    two_prod(t0, t0, tt, ett);  // t0^2 exactly
    double p, e;
    two_prod(tt, c2, p, e);
    add_prod(x, k, p);
    add_prod(x, k, e + ett * c2);
}

}  // namespace

namespace {

// One box's generators, half extents and centre as curves in s, with the
// centre's constant term exactly (double-double) and the magnitude of the
// summands of its higher coefficients added to `summands`.
void box_in_s(const BoxInput &bx, double t0, double w, Curve *g, double *h, Curve &centre, DD *c0, double &summands) {
    const double *C = bx.coeffs;
    double m[3];  // the box's centre in its own frame
    bool offset = false;
    for (int i = 0; i < 3; ++i) {
        m[i] = 0.5 * (bx.lo[i] + bx.hi[i]);
        h[i] = 0.5 * (bx.hi[i] - bx.lo[i]);
        offset = offset || m[i] != 0.0;
    }
    const bool plain = t0 == 0.0 && w == 1.0;  // t_range (0, 1): the coefficients as given
    double e[3];
    for (int r = 0; r < 3; ++r) {
        for (int i = 0; i < 3; ++i) {
            if (plain) {
                for (int k = 0; k < 3; ++k) g[i].c[k][r] = coef(C, k, r, i);
            } else {
                entry_in_s(C, r, i, t0, w, e);
                for (int k = 0; k < 3; ++k) g[i].c[k][r] = e[k];
            }
        }
        if (plain) {
            for (int k = 0; k < 3; ++k) e[k] = coef(C, k, r, 3);
        } else {
            entry_in_s(C, r, 3, t0, w, e);
        }
        double c1 = e[1], c2 = e[2];
        summands += std::fabs(c1) + std::fabs(c2);
        if (plain && !offset) {  // the constant term as given is exact
            c0[r] = {e[0], 0.0};
        } else {
            c0[r] = DD{};
            add_entry_at_t0(c0[r], C, r, 3, t0, 1.0);
            for (int i = 0; i < 3; ++i) {
                if (m[i] == 0.0) continue;
                add_entry_at_t0(c0[r], C, r, i, t0, m[i]);
                c1 += m[i] * g[i].c[1][r];
                c2 += m[i] * g[i].c[2][r];
                summands += std::fabs(m[i]) * (std::fabs(g[i].c[1][r]) + std::fabs(g[i].c[2][r]));
            }
        }
        centre.c[1][r] = c1;
        centre.c[2][r] = c2;
    }
}

}  // namespace

Pair::Pair(const BoxInput &a, const BoxInput &b, double t0_, double t1_, const Tolerances &tol_)
    : t0(t0_), t1(t1_), tol(tol_) {
    const double w = t1 - t0;
    DD centre0[2][3];  // the centres at s = 0, exactly
    double summands = 0.0;
    box_in_s(a, t0, w, g, h, cA, centre0[0], summands);
    box_in_s(b, t0, w, g + 3, h + 3, cB, centre0[1], summands);
    // The pair's frame: A's centre at s = 0, rounded. A's constant term there is
    // the rounding residue; B's is rounded once, relative to its local value.
    for (int r = 0; r < 3; ++r) {
        origin[r] = centre0[0][r].hi;
        cA.c[0][r] = centre0[0][r].lo;
        DD local;
        two_sum(centre0[1][r].hi, -origin[r], local.hi, local.lo);
        local.lo += centre0[1][r].lo;
        cB.c[0][r] = round_dd(local);
    }
    for (int k = 0; k < 3; ++k)
        for (int r = 0; r < 3; ++r) d.c[k][r] = cB.c[k][r] - cA.c[k][r];
    dmag = summands + sum_abs3(cA.c[0]) + sum_abs3(cB.c[0]);
    size = hmag = 0.0;
    turning = false;
    // Squared lengths first, square roots in one pass after (18 independent
    // roots that the compiler can pair, rather than a chain of loop bodies each
    // waiting on its own). A generator that does not turn has c1 = c2 = 0, so
    // its bounds come out 0 without a branch.
    double sq[3][6];
    for (int k = 0; k < 6; ++k) {
        const Vec3 &c1 = g[k].c[1], &c2 = g[k].c[2];
        const double m1 = sum_abs3(c1), m2 = sum_abs3(c2);
        gmag[k] = sum_abs3(g[k].c[0]) + m1 + m2;
        gdeg[k] = m1 + m2 == 0.0 ? 0 : 2;
        const Vec3 end = {c1[0] + 2.0 * c2[0], c1[1] + 2.0 * c2[1], c1[2] + 2.0 * c2[2]};  // g'(1)
        sq[0][k] = std::max(dot3(c1, c1), dot3(end, end));  // |g'| is largest at an end: g' is linear
        sq[1][k] = dot3(c2, c2);
        const Vec3 mid = g[k].at(0.5);
        sq[2][k] = dot3(mid, mid);
        hmag += h[k] * gmag[k];
        turning = turning || gdeg[k];
    }
    double root[3][6];
    for (int i = 0; i < 3; ++i)
        for (int k = 0; k < 6; ++k) root[i][k] = std::sqrt(sq[i][k]);
    for (int k = 0; k < 6; ++k) {
        gbounds[k] = {root[0][k], 2.0 * root[1][k]};
        size += h[k] * root[2][k];
    }
    ddeg = sum_abs3(d.c[1]) + sum_abs3(d.c[2]) == 0.0 ? 0 : 2;
    const double rounding = tol.rounding * kEps * (dmag + hmag);
    for (int ax = 0; ax < 15; ++ax) noise[ax] = rounding * gmag[axis_generator(ax, 0)] * gmag[axis_generator(ax, 1)];
    unit_margin = tol.gap_rel * size + rounding;
    // Inputs near the top of the double range overflow in these products; say
    // so instead of returning nonsense.
    const bool ok = std::isfinite(dmag * hmag) && std::isfinite(size) && std::isfinite(dmag + hmag) &&
                    std::isfinite(sum_abs3(origin)) &&
                    std::isfinite((dmag + hmag) * gmag[0] * gmag[3] * gmag[1] * gmag[4]);
    if (!ok)
        throw NonFiniteError(
            "the boxes' extents, positions or motion coefficients are too large: intermediate products "
            "overflow double precision");
}

// The supports come straight from the triple products S (the Projection
// table, written out): a face axis of A sees det A on its own generator and
// S[0][i][.] on B's; an edge-edge axis (i, j) sees S[0][m][j] on A's other two
// generators and S[1][m][i] on B's (m the third index). Written for the
// compiler: every index is a constant after inlining (no loop counters, no
// modulo), the normals stay in registers, nothing is stored but the results.
void axes_at(const Pair &pair, const Vec3 *gs, const Vec3 &d, AxesAt &v) {
    const double *h = pair.h;
    const double len2[6] = {dot3(gs[0], gs[0]), dot3(gs[1], gs[1]), dot3(gs[2], gs[2]),
                            dot3(gs[3], gs[3]), dot3(gs[4], gs[4]), dot3(gs[5], gs[5])};
    double S[2][3][3], det[2];  // |S[q][i][l]| and |det|
    // Face axis 3q + i: n = own[i+1] x own[i+2] (generators u, w of box q).
    const auto face = [&](int q, int i, int u, int w) {
        const Vec3 n = cross3(gs[u], gs[w]);
        const int ax = 3 * q + i, o = 3 * (1 - q);
        v.nn2[ax] = dot3(n, n);
        v.nd[ax] = dot3(n, d);
        v.direction[ax] = v.nn2[ax] > kParallel2 * len2[u] * len2[w];
        S[q][i][0] = std::fabs(dot3(n, gs[o]));
        S[q][i][1] = std::fabs(dot3(n, gs[o + 1]));
        S[q][i][2] = std::fabs(dot3(n, gs[o + 2]));
        if (i == 0) det[q] = std::fabs(dot3(n, gs[3 * q]));
    };
    face(0, 0, 1, 2), face(0, 1, 2, 0), face(0, 2, 0, 1);
    face(1, 0, 4, 5), face(1, 1, 5, 3), face(1, 2, 3, 4);
    for (int q = 0; q < 2; ++q) {
        const double *ho = h + 3 * (1 - q);
        for (int i = 0; i < 3; ++i)
            v.support[3 * q + i] = h[3 * q + i] * det[q] + ho[0] * S[q][i][0] + ho[1] * S[q][i][1] + ho[2] * S[q][i][2];
    }
    // Edge-edge axis (i, j): n = a_i x b_j; (i1, i2) and (j1, j2) the other two indices.
    const auto edge = [&](int i, int j, int i1, int i2, int j1, int j2) {
        const int ax = 6 + 3 * i + j;
        const Vec3 n = cross3(gs[i], gs[3 + j]);
        v.nn2[ax] = dot3(n, n);
        v.nd[ax] = dot3(n, d);
        v.direction[ax] = v.nn2[ax] > kParallel2 * len2[i] * len2[3 + j];
        // h_a[k] |S[0][m][j]| for k != i (m = 3 - k - i), h_b[l] |S[1][m][i]| for l != j.
        v.support[ax] = h[i1] * S[0][i2][j] + h[i2] * S[0][i1][j] + h[3 + j1] * S[1][j2][i] + h[3 + j2] * S[1][j1][i];
    };
    edge(0, 0, 1, 2, 1, 2), edge(0, 1, 1, 2, 2, 0), edge(0, 2, 1, 2, 0, 1);
    edge(1, 0, 2, 0, 1, 2), edge(1, 1, 2, 0, 2, 0), edge(1, 2, 2, 0, 0, 1);
    edge(2, 0, 0, 1, 1, 2), edge(2, 1, 0, 1, 2, 0), edge(2, 2, 0, 1, 0, 1);
}

Cofactors::Cofactors(const Pair &pair) : pair_(pair) {}

const PVec &Cofactors::normal(int ax) {
    if (!(n_built_ & (1u << ax))) {
        const int ga = axis_generator(ax, 0), gb = axis_generator(ax, 1);
        n_[ax] = cross_curves(pair_.g[ga], pair_.gdeg[ga], pair_.g[gb], pair_.gdeg[gb]);
        n_built_ |= 1u << ax;
    }
    return n_[ax];
}

const Poly &Cofactors::projection(int k) {
    if (!(proj_built_ & (1u << k))) {
        // S[q][i][l] = n_{3q+i} . g_{3(1-q)+l}.
        const int q = k / 9, axis = 3 * q + (k % 9) / 3, gen = 3 * (1 - q) + k % 3;
        proj_[k] = dot_curve(normal(axis), pair_.normal_degree(axis), pair_.g[gen], pair_.gdeg[gen]);
        trim(proj_[k]);  // constant when the boxes do not turn
        proj_built_ |= 1u << k;
    }
    return proj_[k];
}

namespace {
std::string num(double v) {
    char buf[40];
    std::snprintf(buf, sizeof buf, "%.17g", v);
    return buf;
}
bool finite_poly(const Poly &p) {
    for (int i = 0; i <= p.deg; ++i)
        if (!std::isfinite(p.c[i])) return false;
    return true;
}
}  // namespace

// det [g0 g1 g2] of three curves as a polynomial: (g1 x g2) . g0, coefficient by
// coefficient (the cross product's five coefficient vectors, then the dot).
// A box that does not turn has a constant determinant: one triple product.
Poly det_poly(const Curve *g, bool turning) {
    Poly p{};
    p.deg = 0;
    if (!turning) {
        p.c[0] = dot3(cross3(g[1].c[0], g[2].c[0]), g[0].c[0]);
        return p;
    }
    Vec3 n[5] = {};
    for (int i = 0; i < 3; ++i)
        for (int j = 0; j < 3; ++j) {
            const Vec3 c = cross3(g[1].c[i], g[2].c[j]);
            for (int r = 0; r < 3; ++r) n[i + j][r] += c[r];
        }
    p.deg = 6;
    for (int k = 0; k < 5; ++k)
        for (int l = 0; l < 3; ++l) p.c[k + l] += dot3(n[k], g[0].c[l]);
    trim(p);
    return p;
}

double det_floor01(const double *C) {
    Curve g[3];
    bool turning = false;
    for (int i = 0; i < 3; ++i)
        for (int k = 0; k < 3; ++k)
            for (int r = 0; r < 3; ++r) {
                g[i].c[k][r] = coef(C, k, r, i);  // as box_in_s takes them on t_range (0, 1)
                turning = turning || (k > 0 && g[i].c[k][r] != 0.0);
            }
    const Poly det = det_poly(g, turning);
    if (!finite_poly(det) || det.c[0] == 0.0) return 0.0;
    const Bernstein bz = to_bernstein((det.c[0] > 0.0 ? 1.0 : -1.0) * det, 0.0, 1.0);
    double floor = bz.b[0];
    for (int i = 1; i <= bz.deg; ++i) floor = std::min(floor, bz.b[i]);
    return std::max(floor, 0.0);
}

void check_regular(const Pair &pair, const char *name_a, const char *name_b, const double *floor) {
    const char *names[2] = {name_a, name_b};
    const bool unit_range = pair.t0 == 0.0 && pair.t1 == 1.0;  // then the curves are the coefficients as given
    for (int q = 0; q < 2; ++q) {
        const double noise = pair.tol.rounding * kEps * pair.gmag[3 * q] * pair.gmag[3 * q + 1] * pair.gmag[3 * q + 2];
        if (floor && unit_range && floor[q] > 2.0 * noise) continue;
        const Poly det = det_poly(pair.g + 3 * q, pair.gdeg[3 * q] | pair.gdeg[3 * q + 1] | pair.gdeg[3 * q + 2]);
        if (!finite_poly(det))
            throw NonFiniteError(
                "the boxes' extents, positions or motion coefficients are too large: intermediate products "
                "overflow double precision");
        const double v0 = det(0.0);
        double s = std::fabs(v0) <= noise ? 0.0 : kNoRoot;
        if (std::isnan(s)) {
            Poly shifted = (v0 > 0.0 ? 1.0 : -1.0) * det;
            shifted.c[0] -= noise;
            bool clustered = false;  // a cluster of roots is a collapse all the same
            s = first_nonpositive(shifted, 0.0, 1.0, clustered);
        }
        if (!std::isnan(s)) {
            const double t = pair.time(s);
            throw SingularMotionError(std::string(names[q]) + ": the 3x3 part of the motion is singular at t = " +
                                          num(t) + " (det = " + num(det(s)) + "), so box " + (q ? "b" : "a") +
                                          " collapses inside t_range",
                                      t);
        }
    }
}

}  // namespace boxccd
