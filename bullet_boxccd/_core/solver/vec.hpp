// Small fixed-size vectors (Vec3: the core's one vector type; norm3 also takes
// three doubles in place, as the paths store them in rows and matrices), the
// quadratic vector curves of the solver (a box's edge direction or centre as a
// function of s: c0 + c1 s + c2 s^2), and the cofactor products of such curves
// as polynomial vectors (poly.hpp).
#pragma once

#include <array>
#include <cmath>

#include "solver/poly.hpp"

namespace boxccd {

using Vec3 = std::array<double, 3>;

inline double dot3(const Vec3 &u, const Vec3 &v) { return u[0] * v[0] + u[1] * v[1] + u[2] * v[2]; }
inline double norm3(const Vec3 &v) { return std::sqrt(dot3(v, v)); }
inline Vec3 cross3(const Vec3 &a, const Vec3 &b) {
    return {a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0]};
}
inline double sum_abs3(const Vec3 &v) { return std::fabs(v[0]) + std::fabs(v[1]) + std::fabs(v[2]); }
inline Vec3 operator+(const Vec3 &a, const Vec3 &b) { return {a[0] + b[0], a[1] + b[1], a[2] + b[2]}; }
inline Vec3 operator*(double k, const Vec3 &a) { return {k * a[0], k * a[1], k * a[2]}; }
// The same on three doubles in place (a column of a row-major matrix, a part of a row).
inline double norm3(const double *v) { return std::sqrt(v[0] * v[0] + v[1] * v[1] + v[2] * v[2]); }

// A quadratic vector curve c[0] + c[1] s + c[2] s^2.
struct Curve {
    Vec3 c[3];
    Vec3 at(double s) const {
        return {c[0][0] + s * (c[1][0] + s * c[2][0]), c[0][1] + s * (c[1][1] + s * c[2][1]),
                c[0][2] + s * (c[1][2] + s * c[2][2])};
    }
    Vec3 derivative(double s) const {
        const double s2 = 2.0 * s;
        return {c[1][0] + s2 * c[2][0], c[1][1] + s2 * c[2][1], c[1][2] + s2 * c[2][2]};
    }
};

// A polynomial vector (a face normal or an edge-edge axis: degree <= 4).
struct PVec {
    Poly x[3];
};

// r += k * a * b with degrees known at compile time (the loops unroll).
template <int DA, int DB>
inline void mul_acc(Poly &r, double k, const double *a, const double *b) {
    static_assert(DA + DB <= kMaxDeg, "degree overflow");
    for (int i = 0; i <= DA; ++i) {
        const double ka = k * a[i];
        for (int j = 0; j <= DB; ++j) r.c[i + j] += ka * b[j];
    }
}

// The cross product of two curves of degree DA, DB in {0, 2} (0: constant).
template <int DA, int DB>
inline PVec cross_curves(const Curve &a, const Curve &b) {
    PVec r;
    for (int i = 0; i < 3; ++i) {
        const int j = (i + 1) % 3, k = (i + 2) % 3;
        Poly &p = r.x[i];
        p.deg = DA + DB;
        for (int m = 0; m <= DA + DB; ++m) p.c[m] = 0.0;
        const double aj[3] = {a.c[0][j], a.c[1][j], a.c[2][j]}, ak[3] = {a.c[0][k], a.c[1][k], a.c[2][k]};
        const double bj[3] = {b.c[0][j], b.c[1][j], b.c[2][j]}, bk[3] = {b.c[0][k], b.c[1][k], b.c[2][k]};
        mul_acc<DA, DB>(p, 1.0, aj, bk);
        mul_acc<DA, DB>(p, -1.0, ak, bj);
    }
    return r;
}

// n . c for a polynomial vector n of degree DN and a curve c of degree DC.
template <int DN, int DC>
inline Poly dot_curve(const PVec &n, const Curve &c) {
    Poly r;
    r.deg = DN + DC;
    for (int m = 0; m <= DN + DC; ++m) r.c[m] = 0.0;
    for (int i = 0; i < 3; ++i) {
        const double ci[3] = {c.c[0][i], c.c[1][i], c.c[2][i]};
        mul_acc<DN, DC>(r, 1.0, n.x[i].c.data(), ci);
    }
    return r;
}

// The same with the degrees known only at run time (each 0 or 2 for curves,
// 0, 2 or 4 for normals): one dispatch, then the unrolled loops.
inline PVec cross_curves(const Curve &a, int da, const Curve &b, int db) {
    if (da == 0) return db == 0 ? cross_curves<0, 0>(a, b) : cross_curves<0, 2>(a, b);
    return db == 0 ? cross_curves<2, 0>(a, b) : cross_curves<2, 2>(a, b);
}
inline Poly dot_curve(const PVec &n, int dn, const Curve &c, int dc) {
    switch (dn) {
        case 0: return dc == 0 ? dot_curve<0, 0>(n, c) : dot_curve<0, 2>(n, c);
        case 2: return dc == 0 ? dot_curve<2, 0>(n, c) : dot_curve<2, 2>(n, c);
        default: return dc == 0 ? dot_curve<4, 0>(n, c) : dot_curve<4, 2>(n, c);
    }
}

}  // namespace boxccd
