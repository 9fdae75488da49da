#include "paths/step_path.hpp"

#include <algorithm>
#include <cmath>
#include <limits>

#include "solver/vec.hpp"

namespace boxccd {

double reach_radius(const double *X_CS, const double *half) {
    return norm3(Vec3{X_CS[3], X_CS[7], X_CS[11]}) + norm3(half);
}

namespace {

using fs = FrameState;
using pr = PathRow;

constexpr double kNaN = std::numeric_limits<double>::quiet_NaN();

// reach_radius of a path row's box.
double row_reach(const double *box) { return reach_radius(box + pr::kBoxInFrame, box + pr::kHalfExtents); }

// Column i of a row-major 4x4 pose's rotation.
Vec3 column(const double *X, int i) { return {X[i], X[4 + i], X[8 + i]}; }

}  // namespace


// X(tau) = [Rot(axis, (tau - 1) angle) R1, p1 + (tau - 1) dv] X_CS.
void row_pose(const double *b, double tau, double *X) {
    const double *X1 = b + pr::kPoseAfter, *dv = b + pr::kDisplacement, *k = b + pr::kAxis,
                 *X_CS = b + pr::kBoxInFrame;
    const double th = (tau - 1.0) * b[pr::kAngle], s = std::sin(th), c = 1.0 - std::cos(th);
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
    for (int i = 0; i < 3; ++i) {
        for (int j = 0; j < 3; ++j) {
            double v = 0.0;
            for (int m = 0; m < 3; ++m) v += F[i][m] * X_CS[m * 4 + j];
            X[4 * i + j] = v;
        }
        double v = F[i][3];
        for (int m = 0; m < 3; ++m) v += F[i][m] * X_CS[m * 4 + 3];
        X[4 * i + 3] = v;
        X[12 + i] = 0.0;
    }
    X[15] = 1.0;
}

namespace {

// Overlap of the two boxes' projections on unit axis u (negative: a gap); d is
// the centre of B less the centre of A.
double overlap_on(const Vec3 &u, const double *X_WA, const double *ha, const double *X_WB, const double *hb,
                  const Vec3 &d) {
    double r = 0.0;
    for (int i = 0; i < 3; ++i) {
        r += ha[i] * std::fabs(dot3(u, column(X_WA, i)));
        r += hb[i] * std::fabs(dot3(u, column(X_WB, i)));
    }
    return r - std::fabs(dot3(u, d));
}

}  // namespace

double pose_separation(const double *X_WA, const double *ha, const double *X_WB, const double *hb, double *axis,
                       double floor) {
    const Vec3 d{X_WB[3] - X_WA[3], X_WB[7] - X_WA[7], X_WB[11] - X_WA[11]};
    double depth = std::numeric_limits<double>::infinity();
    const auto consider = [&](const Vec3 &u) {  // whether the depth is still >= floor
        const double o = overlap_on(u, X_WA, ha, X_WB, hb, d);
        if (o < depth) {
            depth = o;
            if (axis) {  // oriented from A towards B
                const double sgn = dot3(u, d) < 0.0 ? -1.0 : 1.0;
                for (int k = 0; k < 3; ++k) axis[k] = sgn * u[k];
            }
        }
        return !(depth < floor);
    };
    for (int i = 0; i < 3; ++i)  // face normals (rigid boxes: the axes are orthonormal)
        if (!consider(column(X_WA, i)) || !consider(column(X_WB, i))) return depth;
    for (int i = 0; i < 3; ++i)
        for (int j = 0; j < 3; ++j) {
            const Vec3 u = cross3(column(X_WA, i), column(X_WB, j));
            const double n = norm3(u);
            if (!(n > kParallel)) continue;  // parallel edges give no axis (unit a, b: |a x b| is the sine)
            if (!consider(Vec3{u[0] / n, u[1] / n, u[2] / n})) return depth;
        }
    return depth;
}

double pose_depth(const double *X_WA, const double *ha, const double *X_WB, const double *hb) {
    return pose_separation(X_WA, ha, X_WB, hb, nullptr);
}

void swept_bounds(const double *box, double *lo, double *hi) {
    const double *h = box + pr::kHalfExtents;
    const double r = row_reach(box);
    const double q = 0.25 * box[pr::kAngle];
    const double sag = r * q * q / 8.0;
    for (int i = 0; i < 3; ++i) {
        lo[i] = std::numeric_limits<double>::infinity();
        hi[i] = -lo[i];
    }
    // A box that does not turn moves linearly: its end poses bound the step.
    const int stride = box[pr::kAngle] == 0.0 ? 4 : 1;
    for (int k = 0; k <= 4; k += stride) {
        double X[16];
        row_pose(box, 0.25 * k, X);
        for (int i = 0; i < 3; ++i) {
            const double *R = X + 4 * i, c = X[4 * i + 3];
            const double e = std::fabs(R[0]) * h[0] + std::fabs(R[1]) * h[1] + std::fabs(R[2]) * h[2];
            // The pose's rounding: a few eps of the coordinate's magnitude.
            const double pad = sag + kBoundsRounding * kEps * (std::fabs(c) + r);
            lo[i] = std::fmin(lo[i], c - e - pad);
            hi[i] = std::fmax(hi[i], c + e + pad);
        }
    }
}

double step_reach(const double *state, double dt, double radius) {
    const double *v = state + fs::kVelocity, *w = state + fs::kAngularVelocity;
    return (norm3(v) + norm3(w) * radius) * dt;
}

double bullet_step_angle(double speed, double dt) {
    const double a = speed * dt;
    if (!(a > kAngularMotionThreshold)) return a;
    return 2.0 * std::atan(a / kAngularMotionThreshold * std::tan(0.5 * kAngularMotionThreshold));
}

namespace {

// Rotation matrix of a quaternion x y z w (normalised here).
void quat_matrix(const double *q, double R[3][3]) {
    const double qq = q[0] * q[0] + q[1] * q[1] + q[2] * q[2] + q[3] * q[3];
    const double s2 = qq > 0.0 ? 2.0 / qq : 0.0;  // the products below carry the 2 and the normalisation
    const double x = q[0], y = q[1], z = q[2], r = q[3];
    const double M[3][3] = {{1 - s2 * (y * y + z * z), s2 * (x * y - z * r), s2 * (x * z + y * r)},
                            {s2 * (x * y + z * r), 1 - s2 * (x * x + z * z), s2 * (y * z - x * r)},
                            {s2 * (x * z - y * r), s2 * (y * z + x * r), 1 - s2 * (x * x + y * y)}};
    std::copy(&M[0][0], &M[0][0] + 9, &R[0][0]);
}

// The row's frame after the step (pose1: position, quaternion), box and extents.
void row_frame_and_box(const double *pose1, const double *X_CS, const double *half, double *row) {
    double R[3][3];
    quat_matrix(pose1 + 3, R);
    double *X1 = row + pr::kPoseAfter;
    for (int i = 0; i < 3; ++i) {
        for (int j = 0; j < 3; ++j) X1[4 * i + j] = R[i][j];
        X1[4 * i + 3] = pose1[i];
        X1[12 + i] = 0.0;
    }
    X1[15] = 1.0;
    std::copy(X_CS, X_CS + 16, row + pr::kBoxInFrame);
    std::copy(half, half + 3, row + pr::kHalfExtents);
}

}  // namespace

void path_row(const double *state, double dt, const double *X_CS, const double *half, double *row) {
    const double *v = state + fs::kVelocity, *w = state + fs::kAngularVelocity;
    row_frame_and_box(state + fs::kPosition, X_CS, half, row);
    for (int i = 0; i < 3; ++i) row[pr::kDisplacement + i] = v[i] * dt;
    const double speed = norm3(w);
    for (int i = 0; i < 3; ++i) row[pr::kAxis + i] = speed > 0.0 ? w[i] / speed : 0.0;
    row[pr::kAngle] = bullet_step_angle(speed, dt);
}

void path_row_between(const double *pose0, const double *pose1, const double *X_CS, const double *half, double *row) {
    row_frame_and_box(pose1, X_CS, half, row);
    for (int i = 0; i < 3; ++i) row[pr::kDisplacement + i] = pose1[i] - pose0[i];
    // The turn q1 q0^-1 (x y z w), taken the short way round (w >= 0).
    const double *a = pose1 + 3, *b = pose0 + 3;
    double t[4] = {b[3] * a[0] - a[3] * b[0] - (a[1] * b[2] - a[2] * b[1]),
                   b[3] * a[1] - a[3] * b[1] - (a[2] * b[0] - a[0] * b[2]),
                   b[3] * a[2] - a[3] * b[2] - (a[0] * b[1] - a[1] * b[0]),
                   a[3] * b[3] + a[0] * b[0] + a[1] * b[1] + a[2] * b[2]};
    if (t[3] < 0.0)
        for (double &x : t) x = -x;
    const double sin_half = norm3(t);
    for (int i = 0; i < 3; ++i) row[pr::kAxis + i] = sin_half > 0.0 ? t[i] / sin_half : 0.0;
    row[pr::kAngle] = 2.0 * std::atan2(sin_half, t[3]);
}

void window_row(const double *row, double lo, double hi, double *out) {
    std::copy(row, row + pr::kSize, out);
    // The frame at hi: the row's frame after the step, turned and moved back by (1 - hi).
    double frame[pr::kSize];
    std::copy(row, row + pr::kSize, frame);
    const double identity[16] = {1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1};
    std::copy(identity, identity + 16, frame + pr::kBoxInFrame);
    row_pose(frame, hi, out + pr::kPoseAfter);
    for (int i = 0; i < 3; ++i) out[pr::kDisplacement + i] = (hi - lo) * row[pr::kDisplacement + i];
    out[pr::kAngle] = (hi - lo) * row[pr::kAngle];
}

void fixed_base_velocity_before(const double *v_end, const double *w, double h, double *v) {
    // (I + S)^-1 with S = h [w x]: (v_end - S v_end + h^2 (w . v_end) w) / (1 + h^2 |w|^2).
    const double wv[3] = {w[1] * v_end[2] - w[2] * v_end[1], w[2] * v_end[0] - w[0] * v_end[2],
                          w[0] * v_end[1] - w[1] * v_end[0]};
    const double along = w[0] * v_end[0] + w[1] * v_end[1] + w[2] * v_end[2];
    const double scale = 1.0 / (1.0 + h * h * (w[0] * w[0] + w[1] * w[1] + w[2] * w[2]));
    for (int i = 0; i < 3; ++i) v[i] = (v_end[i] - h * wv[i] + h * h * along * w[i]) * scale;
}

void undamped_velocity(const double *b, double d, double h, double *x) {
    // x = alpha b: alpha (1 - k (1 + alpha |b|)) = 1 with k = h d, the root near 1.
    const double k = h * d, n = std::sqrt(b[0] * b[0] + b[1] * b[1] + b[2] * b[2]);
    const double a = 1.0 - k, alpha = 2.0 / (a + std::sqrt(std::fmax(a * a - 4.0 * k * n, 0.0)));
    for (int i = 0; i < 3; ++i) x[i] = alpha * b[i];
}

void velocity_at(const double *after, const double *before, int mode, double dt, double tau, const double *gravity,
                 const double *damping, double *out) {
    std::copy(after, after + 6, out);
    const double rest = (1.0 - tau) * dt;
    if (mode == 0) {
        fixed_base_velocity_before(after, after + 3, rest, out);
    } else if (mode == 1 && before) {
        for (int i = 0; i < 6; ++i) out[i] = before[i] + tau * (after[i] - before[i]);
    } else {
        for (int i = 0; i < 3; ++i) out[i] -= gravity[i] * rest;
        if (damping) {
            undamped_velocity(out, damping[0], rest, out);
            undamped_velocity(out + 3, damping[1], rest, out + 3);
        }
    }
}

void frame_pose(const double *state, double dt, double tau, double *pose) {
    const double *q1 = state + fs::kOrientation, *v = state + fs::kVelocity, *w = state + fs::kAngularVelocity;
    const double speed = norm3(w);
    const double half_angle = 0.5 * (tau - 1.0) * bullet_step_angle(speed, dt);
    const double s = speed > 0.0 ? std::sin(half_angle) / speed : 0.0, c = std::cos(half_angle);
    const double u[3] = {s * w[0], s * w[1], s * w[2]};  // the turn (tau - 1) angle about w: (u, c)
    const double out[4] = {c * q1[0] + q1[3] * u[0] + u[1] * q1[2] - u[2] * q1[1],
                           c * q1[1] + q1[3] * u[1] + u[2] * q1[0] - u[0] * q1[2],
                           c * q1[2] + q1[3] * u[2] + u[0] * q1[1] - u[1] * q1[0],
                           c * q1[3] - u[0] * q1[0] - u[1] * q1[1] - u[2] * q1[2]};
    const double n = std::sqrt(out[0] * out[0] + out[1] * out[1] + out[2] * out[2] + out[3] * out[3]);
    for (int i = 0; i < 3; ++i) pose[i] = state[i] + (tau - 1.0) * v[i] * dt;
    for (int i = 0; i < 4; ++i) pose[3 + i] = out[i] / n;
}

double fit_path(const double *box, double lo, double hi, double *coeffs) {
    double X[3][16];
    row_pose(box, lo, X[0]);
    row_pose(box, 0.5 * (lo + hi), X[1]);
    row_pose(box, hi, X[2]);
    for (int i = 0; i < 4; ++i)
        for (int j = 0; j < 4; ++j) {
            const int e = 4 * i + j;
            const double x[3] = {X[0][e], X[1][e], X[2][e]};
            coeffs[e] = x[0];
            coeffs[16 + e] = i == 3 ? 0.0 : -3.0 * x[0] + 4.0 * x[1] - x[2];
            coeffs[32 + e] = i == 3 ? 0.0 : 2.0 * x[0] - 4.0 * x[1] + 2.0 * x[2];
        }
    const double phi = box[pr::kAngle] * (hi - lo);
    return kFitErrorPerCubedAngle * phi * phi * phi;
}

int fit_pieces(const double *box, double fit_tolerance) {
    const double *h = box + pr::kHalfExtents, phi = box[pr::kAngle];
    const double err1 = kFitErrorPerCubedAngle * phi * phi * phi * row_reach(box);
    const double allowed = fit_tolerance * std::min({h[0], h[1], h[2]});
    int pieces = 1;
    while (pieces < kMaxFitPieces && err1 > allowed * pieces * pieces * pieces) pieces *= 2;
    return pieces;
}

}  // namespace boxccd
