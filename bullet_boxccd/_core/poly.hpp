// Univariate polynomials of degree <= 6 in the normalised time s in [0, 1], and
// the one root query the solver needs: the first s in (lo, hi] at which a
// polynomial that is positive at lo becomes <= 0.
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
// variation => exactly one root) proves a single crossing that bisection then
// pins down to the last representable double. Intervals with more variations
// are halved (de Casteljau), left half first, so the first root is found first.
#pragma once

#include <array>
#include <cmath>
#include <limits>

namespace boxccd {

constexpr int kMaxDeg = 6;
constexpr double kEps = std::numeric_limits<double>::epsilon();

struct Poly {
    std::array<double, kMaxDeg + 1> c{};  // c[i] multiplies s^i
    int deg = 0;                          // c[i] == 0 for i > deg

    double operator()(double s) const {
        double v = c[deg];
        for (int i = deg - 1; i >= 0; --i) v = v * s + c[i];
        return v;
    }
    // Sum of |coefficients|: bounds |p(s)| on [0, 1] and the rounding of its
    // evaluation (times a small multiple of eps).
    double magnitude() const {
        double m = 0.0;
        for (int i = 0; i <= deg; ++i) m += std::fabs(c[i]);
        return m;
    }
};

inline Poly operator+(const Poly &a, const Poly &b) {
    Poly r;
    r.deg = a.deg > b.deg ? a.deg : b.deg;
    for (int i = 0; i <= r.deg; ++i) r.c[i] = a.c[i] + b.c[i];
    return r;
}
inline Poly operator-(const Poly &a, const Poly &b) {
    Poly r;
    r.deg = a.deg > b.deg ? a.deg : b.deg;
    for (int i = 0; i <= r.deg; ++i) r.c[i] = a.c[i] - b.c[i];
    return r;
}
inline Poly operator*(double k, const Poly &a) {
    Poly r;
    r.deg = a.deg;
    for (int i = 0; i <= r.deg; ++i) r.c[i] = k * a.c[i];
    return r;
}
inline Poly operator*(const Poly &a, const Poly &b) {  // caller keeps a.deg + b.deg <= 6
    Poly r;
    r.deg = a.deg + b.deg;
    for (int i = 0; i <= a.deg; ++i)
        for (int j = 0; j <= b.deg; ++j) r.c[i + j] += a.c[i] * b.c[j];
    return r;
}
// r += k * a (k is +-1 or a half extent); avoids temporaries in the hot loops.
inline void axpy(Poly &r, double k, const Poly &a) {
    if (a.deg > r.deg) r.deg = a.deg;
    for (int i = 0; i <= a.deg; ++i) r.c[i] += k * a.c[i];
}

// A polynomial vector (a box edge direction, a centre, a normal).
struct PVec {
    Poly x[3];
    std::array<double, 3> operator()(double s) const { return {x[0](s), x[1](s), x[2](s)}; }
    double magnitude() const { return x[0].magnitude() + x[1].magnitude() + x[2].magnitude(); }
};
inline PVec cross(const PVec &a, const PVec &b) {
    PVec r;
    for (int i = 0; i < 3; ++i) {
        const int j = (i + 1) % 3, k = (i + 2) % 3;
        r.x[i] = a.x[j] * b.x[k] - a.x[k] * b.x[j];
    }
    return r;
}
inline Poly dot(const PVec &a, const PVec &b) {
    return a.x[0] * b.x[0] + a.x[1] * b.x[1] + a.x[2] * b.x[2];
}

// Bernstein control points of p restricted to [lo, hi] (mapped onto u in [0, 1]).
struct Bernstein {
    std::array<double, kMaxDeg + 1> b{};
    int deg = 0;
};

inline Bernstein to_bernstein(const Poly &p, double lo, double hi) {
    // Taylor shift to lo, then scale by w = hi - lo: q(u) = p(lo + w u).
    std::array<double, kMaxDeg + 1> q = p.c;
    const int n = p.deg;
    for (int i = 0; i < n; ++i)
        for (int j = n - 1; j >= i; --j) q[j] += lo * q[j + 1];
    const double w = hi - lo;
    double wk = 1.0;
    for (int i = 0; i <= n; ++i) { q[i] *= wk; wk *= w; }
    // Power -> Bernstein: b_k = sum_{i<=k} C(k,i)/C(n,i) q_i.
    static const double binom[kMaxDeg + 1][kMaxDeg + 1] = {
        {1}, {1, 1}, {1, 2, 1}, {1, 3, 3, 1}, {1, 4, 6, 4, 1},
        {1, 5, 10, 10, 5, 1}, {1, 6, 15, 20, 15, 6, 1}};
    Bernstein r;
    r.deg = n;
    for (int k = 0; k <= n; ++k) {
        double v = 0.0;
        for (int i = 0; i <= k; ++i) v += binom[k][i] / binom[n][i] * q[i];
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
        const int s = (bz.b[i] > 0.0) - (bz.b[i] < 0.0);
        if (s != 0) {
            if (last != 0 && s != last) ++v;
            last = s;
        }
    }
    return v;
}

// Given p(lo) > 0 >= p(hi) and a single crossing in between, the smallest
// double x in (lo, hi] with p(x) <= 0 as evaluated (bisection to adjacent doubles;
// bisection rather than Newton because it cannot leave the bracket or stall at
// the double roots that grazing contacts produce).
inline double bisect_crossing(const Poly &p, double lo, double hi) {
    for (int it = 0; it < 80; ++it) {
        const double mid = 0.5 * (lo + hi);
        if (mid <= lo || mid >= hi) break;
        if (p(mid) > 0.0) lo = mid; else hi = mid;
    }
    return hi;
}

// Every s in (lo, hi) at which p changes sign (the octant switches). Roots that
// only touch zero do not change the topology and are not reported.
template <class Out>
void sign_changes(const Poly &p, double lo, double hi, const Bernstein &bz, int depth, Out &out) {
    const int v = sign_variations(bz);
    if (v == 0) return;
    const double b0 = bz.b[0], bn = bz.b[bz.deg];
    if (v == 1 || depth >= 60 || hi - lo <= 4.0 * kEps * (1.0 + std::fabs(hi))) {
        if ((b0 > 0.0 && bn < 0.0) || (b0 < 0.0 && bn > 0.0)) {
            const Poly q = b0 > 0.0 ? p : -1.0 * p;
            out(bisect_crossing(q, lo, hi));
        }
        return;
    }
    Bernstein l, r;
    split_half(bz, l, r);
    const double mid = 0.5 * (lo + hi);
    sign_changes(p, lo, mid, l, depth + 1, out);
    sign_changes(p, mid, hi, r, depth + 1, out);
}

// The first s in (lo, hi] with p(s) <= 0, given p(lo) > 0; NaN if p > 0 on all
// of [lo, hi]. Conservative near clustered roots: it may return a point just
// before the true crossing, never one after it.
inline double first_nonpositive(const Poly &p, double lo, double hi, const Bernstein &bz, int depth) {
    bool all_positive = true;
    for (int i = 0; i <= bz.deg; ++i) all_positive = all_positive && bz.b[i] > 0.0;
    if (all_positive) return std::numeric_limits<double>::quiet_NaN();
    if (bz.b[0] <= 0.0) return lo;
    const int v = sign_variations(bz);
    if (v == 1 && bz.b[bz.deg] <= 0.0) return bisect_crossing(p, lo, hi);
    const double mid = 0.5 * (lo + hi);
    if (depth >= 60 || mid <= lo || mid >= hi) return lo;  // clustered roots: stay early
    Bernstein l, r;
    split_half(bz, l, r);
    const double x = first_nonpositive(p, lo, mid, l, depth + 1);
    if (!std::isnan(x)) return x;
    return first_nonpositive(p, mid, hi, r, depth + 1);
}

inline double first_nonpositive(const Poly &p, double lo, double hi) {
    return first_nonpositive(p, lo, hi, to_bernstein(p, lo, hi), 0);
}

}  // namespace boxccd
