#include "step_path.hpp"

#include <cmath>
#include <limits>

namespace boxccd {

namespace {

struct Pose {
    double R[3][3];  // box axes as columns, world
    double c[3];     // box centre, world
};

// Pose of the box at tau: X(tau) = [Rot(axis, (tau - 1) angle) R1, p1 + (tau - 1) dv] X_CS.
Pose box_pose(const double *b, double tau) {
    const double *X1 = b, *dv = b + 16, *k = b + 19, *X_CS = b + 23;
    const double th = (tau - 1.0) * b[22], s = std::sin(th), c = 1.0 - std::cos(th);
    double K[3][3] = {{0, -k[2], k[1]}, {k[2], 0, -k[0]}, {-k[1], k[0], 0}};
    double Q[3][3];  // I + s K + c K^2
    for (int i = 0; i < 3; ++i)
        for (int j = 0; j < 3; ++j) {
            double kk = 0.0;
            for (int m = 0; m < 3; ++m) kk += K[i][m] * K[m][j];
            Q[i][j] = (i == j) + s * K[i][j] + c * kk;
        }
    double F[3][4];  // the frame at tau (rotation | origin)
    for (int i = 0; i < 3; ++i) {
        for (int j = 0; j < 3; ++j) {
            double v = 0.0;
            for (int m = 0; m < 3; ++m) v += Q[i][m] * X1[m * 4 + j];
            F[i][j] = v;
        }
        F[i][3] = X1[i * 4 + 3] + (tau - 1.0) * dv[i];
    }
    Pose p;
    for (int i = 0; i < 3; ++i) {
        for (int j = 0; j < 3; ++j) {
            double v = 0.0;
            for (int m = 0; m < 3; ++m) v += F[i][m] * X_CS[m * 4 + j];
            p.R[i][j] = v;
        }
        double v = F[i][3];
        for (int m = 0; m < 3; ++m) v += F[i][m] * X_CS[m * 4 + 3];
        p.c[i] = v;
    }
    return p;
}

double overlap_on(const double u[3], const Pose &A, const double *ha, const Pose &B, const double *hb,
                  const double d[3]) {
    double r = 0.0;
    for (int i = 0; i < 3; ++i) {
        r += ha[i] * std::fabs(u[0] * A.R[0][i] + u[1] * A.R[1][i] + u[2] * A.R[2][i]);
        r += hb[i] * std::fabs(u[0] * B.R[0][i] + u[1] * B.R[1][i] + u[2] * B.R[2][i]);
    }
    return r - std::fabs(u[0] * d[0] + u[1] * d[1] + u[2] * d[2]);
}

}  // namespace

double path_depth(const double *box_a, const double *box_b, double tau) {
    const Pose A = box_pose(box_a, tau), B = box_pose(box_b, tau);
    const double *ha = box_a + 39, *hb = box_b + 39;
    const double d[3] = {B.c[0] - A.c[0], B.c[1] - A.c[1], B.c[2] - A.c[2]};
    double depth = std::numeric_limits<double>::infinity();
    for (int i = 0; i < 3; ++i) {  // face normals (the boxes are rigid: axes are orthonormal)
        const double ua[3] = {A.R[0][i], A.R[1][i], A.R[2][i]}, ub[3] = {B.R[0][i], B.R[1][i], B.R[2][i]};
        depth = std::fmin(depth, overlap_on(ua, A, ha, B, hb, d));
        depth = std::fmin(depth, overlap_on(ub, A, ha, B, hb, d));
    }
    for (int i = 0; i < 3; ++i)
        for (int j = 0; j < 3; ++j) {
            const double a[3] = {A.R[0][i], A.R[1][i], A.R[2][i]}, b[3] = {B.R[0][j], B.R[1][j], B.R[2][j]};
            double u[3] = {a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0]};
            const double n = std::sqrt(u[0] * u[0] + u[1] * u[1] + u[2] * u[2]);
            if (!(n > 1e-9)) continue;  // parallel edges give no axis
            for (double &x : u) x /= n;
            depth = std::fmin(depth, overlap_on(u, A, ha, B, hb, d));
        }
    return depth;
}

void swept_bounds(const double *box, double *lo, double *hi) {
    const double *X_CS = box + 23, *h = box + 39;
    const double r = std::sqrt(X_CS[3] * X_CS[3] + X_CS[7] * X_CS[7] + X_CS[11] * X_CS[11]) +
                     std::sqrt(h[0] * h[0] + h[1] * h[1] + h[2] * h[2]);
    const double q = 0.25 * box[22];
    const double sag = r * q * q / 8.0 + 1e-9;
    for (int i = 0; i < 3; ++i) {
        lo[i] = std::numeric_limits<double>::infinity();
        hi[i] = -lo[i];
    }
    for (int k = 0; k <= 4; ++k) {
        const Pose P = box_pose(box, 0.25 * k);
        for (int i = 0; i < 3; ++i) {
            const double e = std::fabs(P.R[i][0]) * h[0] + std::fabs(P.R[i][1]) * h[1] + std::fabs(P.R[i][2]) * h[2];
            lo[i] = std::fmin(lo[i], P.c[i] - e - sag);
            hi[i] = std::fmax(hi[i], P.c[i] + e + sag);
        }
    }
}

double first_depth(const double *box_a, const double *box_b, double tau_from, double target) {
    const double span = 1.0 - tau_from;
    double lo = tau_from, hi = std::numeric_limits<double>::quiet_NaN();
    for (int k = 48; k >= 0; --k) {
        const double t = tau_from + std::ldexp(span, -k);
        if (path_depth(box_a, box_b, t) >= target) { hi = t; break; }
        lo = t;
    }
    if (std::isnan(hi)) return hi;
    for (int it = 0; it < 200 && hi - lo > 1e-15; ++it) {
        const double mid = 0.5 * (lo + hi);
        if (mid <= lo || mid >= hi) break;
        if (path_depth(box_a, box_b, mid) >= target) hi = mid; else lo = mid;
    }
    return hi;
}

}  // namespace boxccd
