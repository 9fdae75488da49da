// Univariate polynomials of degree <= 6 in the normalised time s in [0, 1], and
// the two root queries the solver needs: the first s in (lo, hi] at which a
// polynomial that is positive at lo becomes <= 0 (a facet reached), and the
// first sign change (an octant switch).
//
// Why degree 6: a box's edge directions are columns of a quadratic 3x3 matrix
// (degree 2), a face normal or an edge-edge axis is a cross product of two of
// them (degree 4), and every plane of the Minkowski sum is such an axis dotted
// with a degree-2 vector (degree 6). Cofactor forms keep it polynomial: no
// division by a determinant anywhere.
//
// Root isolation uses the Bernstein form on the query interval: the curve lies
// in the convex hull of its control points, so "all control points > 0" proves
// "no root", and Descartes' rule of signs on the control points (one sign
// variation => exactly one root) proves a single crossing that a bracketed
// secant method (Illinois, then bisection) pins down to kRootWidth. Intervals
// with more variations are halved (de Casteljau), left half first, so the first
// root is found first. Degenerate cases, where they are handled:
// * double roots (grazing): "touching" is p <= 0, and the solver shifts each
//   facet by its tolerance, which turns a touch into two simple crossings;
// * clustered roots (closer than doubles can separate): the halving stops at
//   kMaxSubdivisionDepth and the query returns the cluster's start (early) and
//   says so (`clustered`);
// * a secant that stalls on one end: a nudge past that end, then bisection.
#pragma once

#include <array>
#include <cmath>
#include <limits>

#include "solver/constants.hpp"

namespace boxccd {

constexpr int kMaxDeg = 6;

// An aggregate on purpose: `Poly p{}` is the zero polynomial, while a plain
// `Poly p;` (or an array member) is storage that is assigned whole before it is
// read. The solver's tables of polynomials then cost no zeroing per query.
struct Poly {
    std::array<double, kMaxDeg + 1> c;  // c[i] multiplies s^i
    int deg;                            // c[i] == 0 for i > deg

    // Estrin's scheme: the same sum as Horner's rule, grouped in pairs (c[i] +
    // c[i+1] s) and powers s^2, s^4, so that a degree-6 value takes a chain of 4
    // dependent multiply-adds instead of 6 (root refinement evaluates in a loop,
    // each step waiting on the last). Rounding: at most 7 eps sum |c_i| s^i on
    // [0, 1] (Horner: 12 eps), well inside the allowance of Tolerances::rounding.
    double operator()(double s) const {
        const double s2 = s * s;
        switch (deg) {
            case 0: return c[0];
            case 1: return c[0] + c[1] * s;
            case 2: return c[0] + c[1] * s + c[2] * s2;
            case 3: return (c[0] + c[1] * s) + (c[2] + c[3] * s) * s2;
            case 4: return (c[0] + c[1] * s) + (c[2] + c[3] * s) * s2 + c[4] * (s2 * s2);
            case 5: return (c[0] + c[1] * s) + (c[2] + c[3] * s) * s2 + (c[4] + c[5] * s) * (s2 * s2);
            default:
                return (c[0] + c[1] * s) + (c[2] + c[3] * s) * s2 + ((c[4] + c[5] * s) + c[6] * s2) * (s2 * s2);
        }
    }
    // Sum of |coefficients|: bounds |p(s)| on [0, 1] and the rounding of its
    // evaluation (times a small multiple of eps).
    double magnitude() const {
        double m = 0.0;
        for (int i = 0; i <= deg; ++i) m += std::fabs(c[i]);
        return m;
    }
};

inline Poly operator*(double k, const Poly &a) {
    Poly r{};
    r.deg = a.deg;
    for (int i = 0; i <= r.deg; ++i) r.c[i] = k * a.c[i];
    return r;
}
// Lower deg past exactly-zero top coefficients (a constant 3x3 part makes the
// cofactor terms constant): every later evaluation and root search is cheaper.
inline void trim(Poly &p) {
    while (p.deg > 0 && p.c[p.deg] == 0.0) --p.deg;
}

// r += k * a (k is +-1 or a half extent); avoids temporaries in the hot loops.
inline void axpy(Poly &r, double k, const Poly &a) {
    for (int i = r.deg + 1; i <= a.deg; ++i) r.c[i] = 0.0;
    if (a.deg > r.deg) r.deg = a.deg;
    for (int i = 0; i <= a.deg; ++i) r.c[i] += k * a.c[i];
}

// Bernstein control points of p restricted to [lo, hi] (mapped onto u in [0, 1]).
struct Bernstein {
    std::array<double, kMaxDeg + 1> b{};
    int deg = 0;
};

// kPowerToBernstein[n][k][i] = C(k, i) / C(n, i): b_k = sum_{i<=k} ratio * q_i.
struct PowerToBernstein {
    double r[kMaxDeg + 1][kMaxDeg + 1][kMaxDeg + 1] = {};
    constexpr PowerToBernstein() {
        double C[kMaxDeg + 1][kMaxDeg + 1] = {};
        for (int n = 0; n <= kMaxDeg; ++n) {
            C[n][0] = 1.0;
            for (int k = 1; k <= n; ++k) C[n][k] = C[n - 1][k - 1] + (k < n ? C[n - 1][k] : 0.0);
        }
        for (int n = 0; n <= kMaxDeg; ++n)
            for (int k = 0; k <= n; ++k)
                for (int i = 0; i <= k; ++i) r[n][k][i] = C[k][i] / C[n][i];
    }
};
inline constexpr PowerToBernstein kPowerToBernstein;

inline Bernstein to_bernstein(const Poly &p, double lo, double hi) {
    // Taylor shift to lo, then scale by w = hi - lo: q(u) = p(lo + w u).
    std::array<double, kMaxDeg + 1> q = p.c;
    const int n = p.deg;
    if (lo != 0.0)
        for (int i = 0; i < n; ++i)
            for (int j = n - 1; j >= i; --j) q[j] += lo * q[j + 1];
    const double w = hi - lo;
    if (w != 1.0) {
        double wk = w;
        for (int i = 1; i <= n; ++i) {
            q[i] *= wk;
            wk *= w;
        }
    }
    Bernstein r;
    r.deg = n;
    const auto &ratio = kPowerToBernstein.r[n];
    for (int k = 0; k <= n; ++k) {
        double v = 0.0;
        for (int i = 0; i <= k; ++i) v += ratio[k][i] * q[i];
        r.b[k] = v;
    }
    return r;
}

// Split control points at u = 1/2 (de Casteljau).
inline void split_half(const Bernstein &in, Bernstein &left, Bernstein &right) {
    std::array<double, kMaxDeg + 1> w = in.b;
    const int n = in.deg;
    left.deg = right.deg = n;
    left.b[0] = w[0];
    right.b[n] = w[n];
    for (int r = 1; r <= n; ++r) {
        for (int i = 0; i <= n - r; ++i) w[i] = 0.5 * (w[i] + w[i + 1]);
        left.b[r] = w[0];
        right.b[n - r] = w[n - r];
    }
}

inline int sign_variations(const Bernstein &bz) {
    int v = 0, last = 0;
    for (int i = 0; i <= bz.deg; ++i) {
        const int sg = (bz.b[i] > 0.0) - (bz.b[i] < 0.0);
        if (sg != 0) {
            if (last != 0 && sg != last) ++v;
            last = sg;
        }
    }
    return v;
}

// Given p(lo) > 0 >= p(hi) and a single crossing in between: a point x with
// p(x) <= 0 as evaluated, at most kRootWidth after the last point found with
// p > 0 (or adjacent to it, where doubles are coarser). Illinois (regula falsi
// that halves the value kept at a stale end) converges superlinearly and cannot
// leave the bracket; after `max_secant` steps bisection finishes, so the answer
// is converged whatever the polynomial does.
inline double refine_crossing(const Poly &p, double lo, double hi, int max_secant = kMaxSecantSteps) {
    double flo = p(lo), fhi = p(hi);
    if (!(flo > 0.0)) return lo;
    int side = 0;
    double nudge = 0.25 * kRootWidth;
    for (int it = 0; hi - lo > kRootWidth; ++it) {
        double x;
        if (it < max_secant) {
            x = (lo * fhi - hi * flo) / (fhi - flo);
            // Once an end is within rounding of the root, the secant stalls on it:
            // step just past that end instead (doubling the step while it stalls),
            // so that the bracket closes at once rather than by ~50 bisections.
            if (!(x > lo + nudge)) {
                x = lo + nudge;
                nudge *= 2.0;
            } else if (!(x < hi - nudge)) {
                x = hi - nudge;
                nudge *= 2.0;
            }
            if (!(x > lo && x < hi)) x = 0.5 * (lo + hi);
        } else {
            x = 0.5 * (lo + hi);
        }
        if (x <= lo || x >= hi) break;  // adjacent doubles
        const double fx = p(x);
        if (fx > 0.0) {
            lo = x;
            flo = fx;
            if (side == 1) fhi *= 0.5;
            side = 1;
        } else {
            hi = x;
            fhi = fx;
            if (side == -1) flo *= 0.5;
            side = -1;
        }
    }
    return hi;
}

// True if |p| > 0 on all of [0, 1] by the cheapest bound: |c0| > sum |c_i|, i >= 1.
inline bool clearly_nonzero(const Poly &p) {
    double rest = 0.0;
    for (int i = 1; i <= p.deg; ++i) rest += std::fabs(p.c[i]);
    return std::fabs(p.c[0]) > rest;
}

constexpr double kNoRoot = std::numeric_limits<double>::quiet_NaN();

// The first s in (lo, hi] at which p changes sign (an octant switch); NaN if
// none. Roots that only touch zero do not change the topology and are skipped;
// so is an even cluster of roots that doubles cannot separate (the sign is the
// same on both sides, and the section between them is narrower than a double).
// An odd cluster is a switch at its middle; `clustered` is set either way.
// The sign of the first (from_end: last) nonzero control point; 0 if all are zero.
inline int end_sign(const Bernstein &bz, bool from_end) {
    for (int i = 0; i <= bz.deg; ++i) {
        const double b = bz.b[from_end ? bz.deg - i : i];
        if (b != 0.0) return b > 0.0 ? 1 : -1;
    }
    return 0;
}

inline double first_sign_change(const Poly &p, double lo, double hi, const Bernstein &bz, int depth,
                                bool &clustered) {
    const int v = sign_variations(bz);
    if (v == 0) return kNoRoot;
    const double b0 = bz.b[0], bn = bz.b[bz.deg];
    // One variation between nonzero ends: exactly one crossing, ends of opposite sign.
    if (v == 1 && b0 != 0.0 && bn != 0.0) return refine_crossing(b0 > 0.0 ? p : -1.0 * p, lo, hi);
    const double mid = 0.5 * (lo + hi);
    if (depth >= kMaxSubdivisionDepth || mid <= lo || mid >= hi) {
        clustered = true;
        return v % 2 ? mid : kNoRoot;
    }
    Bernstein l, r;
    split_half(bz, l, r);
    const double x = first_sign_change(p, lo, mid, l, depth + 1, clustered);
    if (!std::isnan(x)) return x;
    // p(mid) == 0 exactly (a root at the split point, e.g. a dyadic one): neither
    // half sees it as a variation; it is a sign change if the sides differ.
    if (l.b[l.deg] == 0.0) {
        const int before = end_sign(l, true), after = end_sign(r, false);
        if (before != 0 && after != 0 && before != after) return mid;
    }
    return first_sign_change(p, mid, hi, r, depth + 1, clustered);
}

inline double first_sign_change(const Poly &p, double lo, double hi, bool &clustered) {
    if (clearly_nonzero(p)) return kNoRoot;
    return first_sign_change(p, lo, hi, to_bernstein(p, lo, hi), 0, clustered);
}

// The first s in (lo, hi] with p(s) <= 0, given p(lo) > 0; NaN if p > 0 on all
// of [lo, hi]. Never after the true crossing: where roots cluster closer than
// doubles can separate, it returns the cluster's start and sets `clustered`.
inline double first_nonpositive(const Poly &p, double lo, double hi, const Bernstein &bz, int depth,
                                bool &clustered) {
    if (bz.b[0] <= 0.0) return lo;
    // No negative control point (and b0 > 0): p > 0 on [lo, hi), so the first
    // nonpositive point is hi if p(hi) = 0 (a root at a split point) and none else.
    bool nonnegative = true;
    for (int i = 1; i <= bz.deg; ++i) nonnegative = nonnegative && bz.b[i] >= 0.0;
    if (nonnegative) return bz.b[bz.deg] == 0.0 ? hi : kNoRoot;
    const int v = sign_variations(bz);
    if (v == 1 && bz.b[bz.deg] <= 0.0) return refine_crossing(p, lo, hi);
    const double mid = 0.5 * (lo + hi);
    if (depth >= kMaxSubdivisionDepth || mid <= lo || mid >= hi) {
        clustered = true;
        return lo;
    }
    Bernstein l, r;
    split_half(bz, l, r);
    const double x = first_nonpositive(p, lo, mid, l, depth + 1, clustered);
    if (!std::isnan(x)) return x;
    return first_nonpositive(p, mid, hi, r, depth + 1, clustered);
}

inline double first_nonpositive(const Poly &p, double lo, double hi, bool &clustered) {
    if (p.c[0] > 0.0 && clearly_nonzero(p)) return kNoRoot;
    return first_nonpositive(p, lo, hi, to_bernstein(p, lo, hi), 0, clustered);
}

}  // namespace boxccd
