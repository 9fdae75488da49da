#include "step_path.hpp"

#include <algorithm>
#include <cmath>
#include <limits>

namespace boxccd {

namespace {

using fs = FrameState;
using pr = PathRow;

constexpr double kNaN = std::numeric_limits<double>::quiet_NaN();
constexpr double kPi = 3.14159265358979323846;
constexpr double kAngularMotionThreshold = 0.25 * kPi;  // Bullet's clamp
// Quadratic interpolation through tau = 0, 1/2, 1 of sin(phi tau) or
// 1 - cos(phi tau) errs by at most phi^3 / 6 * max |tau (tau - 1/2)(tau - 1)|
// = phi^3 sqrt(3) / 216 each; a rotation is I + sin K + (1 - cos) K^2 with
// |K| = |K^2| = 1, so the 3x3 part errs by at most twice that.
constexpr double kFitErrorPerCubedAngle = 2.0 * 1.7320508075688772 / 216.0;

// Farthest point of the box from its frame's origin.
double reach_radius(const double *box) {
    const double *X_CS = box + pr::kBoxInFrame, *h = box + pr::kHalfExtents;
    return std::sqrt(X_CS[3] * X_CS[3] + X_CS[7] * X_CS[7] + X_CS[11] * X_CS[11]) +
           std::sqrt(h[0] * h[0] + h[1] * h[1] + h[2] * h[2]);
}

struct Pose {
    double R[3][3];  // box axes as columns, world
    double c[3];     // box centre, world
};

// Pose of the box at tau: X(tau) = [Rot(axis, (tau - 1) angle) R1, p1 + (tau - 1) dv] X_CS.
Pose box_pose(const double *b, double tau) {
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

double path_separation(const double *box_a, const double *box_b, double tau, double *axis, double floor) {
    const Pose A = box_pose(box_a, tau), B = box_pose(box_b, tau);
    const double *ha = box_a + pr::kHalfExtents, *hb = box_b + pr::kHalfExtents;
    const double d[3] = {B.c[0] - A.c[0], B.c[1] - A.c[1], B.c[2] - A.c[2]};
    double depth = std::numeric_limits<double>::infinity();
    const auto consider = [&](const double u[3]) {  // whether the depth is still >= floor
        const double o = overlap_on(u, A, ha, B, hb, d);
        if (o < depth) {
            depth = o;
            if (axis) {  // oriented from A towards B
                const double sgn = u[0] * d[0] + u[1] * d[1] + u[2] * d[2] < 0.0 ? -1.0 : 1.0;
                for (int k = 0; k < 3; ++k) axis[k] = sgn * u[k];
            }
        }
        return !(depth < floor);
    };
    for (int i = 0; i < 3; ++i) {  // face normals (the boxes are rigid: axes are orthonormal)
        const double ua[3] = {A.R[0][i], A.R[1][i], A.R[2][i]}, ub[3] = {B.R[0][i], B.R[1][i], B.R[2][i]};
        if (!consider(ua) || !consider(ub)) return depth;
    }
    for (int i = 0; i < 3; ++i)
        for (int j = 0; j < 3; ++j) {
            const double a[3] = {A.R[0][i], A.R[1][i], A.R[2][i]}, b[3] = {B.R[0][j], B.R[1][j], B.R[2][j]};
            double u[3] = {a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0]};
            const double n = std::sqrt(u[0] * u[0] + u[1] * u[1] + u[2] * u[2]);
            if (!(n > kParallel)) continue;  // parallel edges give no axis (unit a, b: |a x b| = sin)
            for (double &x : u) x /= n;
            if (!consider(u)) return depth;
        }
    return depth;
}

double path_depth(const double *box_a, const double *box_b, double tau) {
    return path_separation(box_a, box_b, tau, nullptr);
}

namespace {

// Whether the depth at tau reaches target (path_depth >= target), stopping at the
// first axis that says no.
bool depth_reaches(const double *box_a, const double *box_b, double tau, double target) {
    return path_separation(box_a, box_b, tau, nullptr, target) >= target;
}

}  // namespace

void swept_bounds(const double *box, double *lo, double *hi) {
    const double *h = box + pr::kHalfExtents;
    const double r = reach_radius(box);
    const double q = 0.25 * box[pr::kAngle];
    const double sag = r * q * q / 8.0;
    for (int i = 0; i < 3; ++i) {
        lo[i] = std::numeric_limits<double>::infinity();
        hi[i] = -lo[i];
    }
    // A box that does not turn moves linearly: its end poses bound the step.
    const int stride = box[pr::kAngle] == 0.0 ? 4 : 1;
    for (int k = 0; k <= 4; k += stride) {
        const Pose P = box_pose(box, 0.25 * k);
        for (int i = 0; i < 3; ++i) {
            const double e = std::fabs(P.R[i][0]) * h[0] + std::fabs(P.R[i][1]) * h[1] + std::fabs(P.R[i][2]) * h[2];
            // The pose's rounding: a few eps of the coordinate's magnitude.
            const double pad = sag + kBoundsRounding * kEps * (std::fabs(P.c[i]) + r);
            lo[i] = std::fmin(lo[i], P.c[i] - e - pad);
            hi[i] = std::fmax(hi[i], P.c[i] + e + pad);
        }
    }
}

double first_depth(const double *box_a, const double *box_b, double tau_from, double target, double depth_from) {
    const double span = 1.0 - tau_from;
    // The boxes' penetration depth (what path_depth gives while they overlap: the
    // smallest of the 15 axes' overlaps) moves by at most the sum of their points'
    // travel, which over a fraction s of the step is at most s (|displacement| +
    // angle r) each: look-ahead samples nearer than that to tau_from cannot reach the
    // target, and are skipped.
    const auto travel = [](const double *box) {
        const double *d = box + pr::kDisplacement;
        return std::sqrt(d[0] * d[0] + d[1] * d[1] + d[2] * d[2]) + std::fabs(box[pr::kAngle]) * reach_radius(box);
    };
    if (std::isnan(depth_from)) depth_from = path_depth(box_a, box_b, tau_from);
    const double need = target - std::fmax(depth_from, 0.0);
    const double speed = (travel(box_a) + travel(box_b)) * span;
    // The first sample taken: the largest k <= kDepthLookAhead with speed 2^-k >= need (k = 0 is
    // always taken; with speed not a number, every k is).
    int k0 = kDepthLookAhead;
    if (need > 0.0 && speed >= 0.0) {
        const double x = speed / need;
        int e = kDepthLookAhead + 1;
        if (std::isfinite(x)) std::frexp(x, &e);  // x = m 2^e, m in [0.5, 1): floor(log2 x) = e - 1
        k0 = std::clamp(e - 1, 0, kDepthLookAhead);
        while (k0 < kDepthLookAhead && !(std::ldexp(speed, -(k0 + 1)) < need)) ++k0;  // the division's rounding
        while (k0 > 0 && std::ldexp(speed, -k0) < need) --k0;
    }
    double lo = k0 < kDepthLookAhead ? tau_from + std::ldexp(span, -(k0 + 1)) : tau_from, hi = kNaN;
    for (double step = std::ldexp(span, -k0); ; step *= 2.0) {  // 2^-k of the rest of the step, k = k0 .. 0
        const double t = tau_from + step;
        if (depth_reaches(box_a, box_b, t, target)) {
            hi = t;
            break;
        }
        lo = t;
        if (!(step < span)) break;
    }
    if (std::isnan(hi)) return hi;
    for (int it = 0; it < kMaxDepthHalvings && hi - lo > kDepthWidth; ++it) {
        const double mid = 0.5 * (lo + hi);
        if (mid <= lo || mid >= hi) break;
        if (depth_reaches(box_a, box_b, mid, target)) hi = mid; else lo = mid;
    }
    return hi;
}

double step_reach(const double *state, double dt, double radius) {
    const double *v = state + fs::kVelocity, *w = state + fs::kAngularVelocity;
    return (std::sqrt(v[0] * v[0] + v[1] * v[1] + v[2] * v[2]) +
            std::sqrt(w[0] * w[0] + w[1] * w[1] + w[2] * w[2]) * radius) * dt;
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
    const double speed = std::sqrt(w[0] * w[0] + w[1] * w[1] + w[2] * w[2]);
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
    const double sin_half = std::sqrt(t[0] * t[0] + t[1] * t[1] + t[2] * t[2]);
    for (int i = 0; i < 3; ++i) row[pr::kAxis + i] = sin_half > 0.0 ? t[i] / sin_half : 0.0;
    row[pr::kAngle] = 2.0 * std::atan2(sin_half, t[3]);
}

void row_pose(const double *row, double tau, double *pose) {
    const Pose P = box_pose(row, tau);
    for (int i = 0; i < 3; ++i) {
        for (int j = 0; j < 3; ++j) pose[4 * i + j] = P.R[i][j];
        pose[4 * i + 3] = P.c[i];
        pose[12 + i] = 0.0;
    }
    pose[15] = 1.0;
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

void frame_pose(const double *state, double dt, double tau, double *pose) {
    const double *q1 = state + fs::kOrientation, *v = state + fs::kVelocity, *w = state + fs::kAngularVelocity;
    const double speed = std::sqrt(w[0] * w[0] + w[1] * w[1] + w[2] * w[2]);
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
    const Pose P[3] = {box_pose(box, lo), box_pose(box, 0.5 * (lo + hi)), box_pose(box, hi)};
    for (int i = 0; i < 4; ++i)
        for (int j = 0; j < 4; ++j) {
            double x[3];
            for (int k = 0; k < 3; ++k) x[k] = i == 3 ? (j == 3) : j == 3 ? P[k].c[i] : P[k].R[i][j];
            const int e = 4 * i + j;
            coeffs[e] = x[0];
            coeffs[16 + e] = i == 3 ? 0.0 : -3.0 * x[0] + 4.0 * x[1] - x[2];
            coeffs[32 + e] = i == 3 ? 0.0 : 2.0 * x[0] - 4.0 * x[1] + 2.0 * x[2];
        }
    const double phi = box[pr::kAngle] * (hi - lo);
    return kFitErrorPerCubedAngle * phi * phi * phi;
}

int fit_pieces(const double *box, double fit_tolerance) {
    const double *h = box + pr::kHalfExtents, phi = box[pr::kAngle];
    const double err1 = kFitErrorPerCubedAngle * phi * phi * phi * reach_radius(box);
    const double allowed = fit_tolerance * std::min({h[0], h[1], h[2]});
    int pieces = 1;
    while (pieces < kMaxFitPieces && err1 > allowed * pieces * pieces * pieces) pieces *= 2;
    return pieces;
}

namespace {

// The fitted motion of a box over [lo, hi], its box inflated by the fit's
// reach: a point at distance r is off by at most err r, and a ball fits in the
// sheared box once scaled by 1 / (1 - err) (err < 0.5: Bullet turns a body by
// less than pi in a step). `extra`: a further inflation, relative to r.
struct FittedBox {
    double lo[3], hi[3], coeffs[48];
    FittedBox(const double *box, double t_lo, double t_hi, double extra) {
        const double err = fit_path(box, t_lo, t_hi, coeffs), r = reach_radius(box);
        const double grow = err * r / (1.0 - err) + extra * r;
        for (int i = 0; i < 3; ++i) {
            hi[i] = box[pr::kHalfExtents + i] + grow;
            lo[i] = -hi[i];
        }
    }
    BoxInput input() const { return {lo, hi, coeffs}; }
};

bool finite_row(const double *box) {
    for (int i = 0; i < kPathBoxSize; ++i)
        if (!std::isfinite(box[i])) return false;
    return true;
}

}  // namespace

double first_touch(const double *box_a, const double *box_b, double fit_tolerance, const Tolerances &tol,
                   long &solves, Outcome &outcome, double depth0) {
    outcome = Outcome::Separated;
    if (!finite_row(box_a) || !finite_row(box_b)) {
        outcome = Outcome::NonFinite;
        return kNaN;
    }
    // Touching at the start (most often a resting contact): the fitted motions, exact
    // at the start and inflated, touch there too.
    if (std::isnan(depth0)) depth0 = path_depth(box_a, box_b, 0.0);
    if (depth0 >= 0.0) {
        outcome = Outcome::Initial;
        return 0.0;
    }
    const int n = std::max(fit_pieces(box_a, fit_tolerance), fit_pieces(box_b, fit_tolerance));
    for (int k = 0; k < n; ++k) {  // pieces in order: the first that touches has the first touch
        const double lo = double(k) / n, hi = double(k + 1) / n;
        const FittedBox a(box_a, lo, hi, 0.0), b(box_b, lo, hi, 0.0);
        Query query(a.input(), b.input(), 0.0, 1.0, tol);
        const Hit h = query.solve(false);
        ++solves;
        if (h.contact()) {
            outcome = h.outcome;
            return lo + h.t * (hi - lo);
        }
    }
    return kNaN;
}

bool presses_in(const double *box_a, const double *box_b, double penetration, double creep, double depth0) {
    const double *ha = box_a + pr::kHalfExtents, *hb = box_b + pr::kHalfExtents;
    const double thin = std::min({ha[0], ha[1], ha[2], hb[0], hb[1], hb[2]});
    if (std::isnan(depth0)) depth0 = path_depth(box_a, box_b, 0.0);
    const double target = std::max(depth0, 0.0) + std::max(penetration, creep * thin);
    return !std::isnan(first_depth(box_a, box_b, 0.0, target, depth0));
}

Hit path_contact(const double *box_a, const double *box_b, double lo, double hi, const Tolerances &tol) {
    if (!finite_row(box_a) || !finite_row(box_b)) {
        Hit h;
        h.outcome = Outcome::NonFinite;
        return h;
    }
    if (hi - lo < kMinWindow) lo = std::max(0.0, hi - kMinWindow);
    const FittedBox a(box_a, lo, hi, kMinWindow), b(box_b, lo, hi, kMinWindow);
    Query query(a.input(), b.input(), 0.0, 1.0, tol);
    Hit h = query.solve(true);
    if (h.contact()) h.t = lo + h.t * (hi - lo);
    return h;
}

namespace {

void cross(const double *a, const double *b, double *out) {
    out[0] = a[1] * b[2] - a[2] * b[1];
    out[1] = a[2] * b[0] - a[0] * b[2];
    out[2] = a[0] * b[1] - a[1] * b[0];
}
double dot(const double *a, const double *b) { return a[0] * b[0] + a[1] * b[1] + a[2] * b[2]; }
void mat_vec(const double *M, const double *x, double *out) {
    for (int i = 0; i < 3; ++i) out[i] = M[3 * i] * x[0] + M[3 * i + 1] * x[1] + M[3 * i + 2] * x[2];
}

// Velocity of point x on body c.
void point_velocity(const CollisionBody &c, const double *x, double *out) {
    const double r[3] = {x[0] - c.com[0], x[1] - c.com[1], x[2] - c.com[2]};
    cross(c.w, r, out);
    for (int i = 0; i < 3; ++i) out[i] += c.v[i];
}

// Of b against a, at x.
void relative_velocity(const CollisionBody &a, const CollisionBody &b, const double *x, double *out) {
    double va[3], vb[3];
    point_velocity(a, x, va);
    point_velocity(b, x, vb);
    for (int i = 0; i < 3; ++i) out[i] = vb[i] - va[i];
}

// The effective inverse mass of one body along direction d at offset r.
double inverse_mass(const CollisionBody &c, const double *r, const double *d) {
    double rd[3], Ird[3], t[3];
    cross(r, d, rd);
    mat_vec(c.inv_I, rd, Ird);
    cross(Ird, r, t);
    return c.inv_m + dot(d, t);
}

// Impulse J on b at x, -J on a.
void apply_impulse(CollisionBody &a, CollisionBody &b, const double *x, const double *J) {
    for (CollisionBody *c : {&a, &b}) {
        const double sign = c == &a ? -1.0 : 1.0;
        const double r[3] = {x[0] - c->com[0], x[1] - c->com[1], x[2] - c->com[2]};
        double rJ[3], dw[3];
        cross(r, J, rJ);
        mat_vec(c->inv_I, rJ, dw);
        for (int i = 0; i < 3; ++i) {
            c->v[i] += sign * c->inv_m * J[i];
            c->w[i] += sign * dw[i];
        }
    }
}

}  // namespace

bool resolve_collision(CollisionBody &a, CollisionBody &b, const double *points, int n_points, const double *n,
                       double e, double mu, int sweeps) {
    bool approaching = false;
    for (int k = 0; k < n_points && !approaching; ++k) {
        double u[3];
        relative_velocity(a, b, points + 3 * k, u);
        approaching = dot(u, n) < 0.0;
    }
    if (!approaching) return false;
    const CollisionBody a0 = a, b0 = b;
    const double approach = -(dot(b.v, n) - dot(a.v, n));
    std::vector<double> normal(n_points, 0.0);
    for (int sweep = 0; sweep < sweeps; ++sweep)
        for (int k = 0; k < n_points; ++k) {
            const double *x = points + 3 * k;
            const double ra[3] = {x[0] - a.com[0], x[1] - a.com[1], x[2] - a.com[2]};
            const double rb[3] = {x[0] - b.com[0], x[1] - b.com[1], x[2] - b.com[2]};
            const double k_n = inverse_mass(a, ra, n) + inverse_mass(b, rb, n);
            if (!(k_n > 0.0)) continue;
            double u[3];
            relative_velocity(a, b, x, u);
            const double dj = std::max(normal[k] - dot(u, n) / k_n, 0.0) - normal[k];
            normal[k] += dj;
            const double Jn[3] = {dj * n[0], dj * n[1], dj * n[2]};
            apply_impulse(a, b, x, Jn);
            relative_velocity(a, b, x, u);
            const double un = dot(u, n);
            double slip[3] = {u[0] - un * n[0], u[1] - un * n[1], u[2] - un * n[2]};
            const double speed = std::sqrt(dot(slip, slip));
            if (!(speed > 0.0 && normal[k] > 0.0)) continue;
            for (double &s : slip) s /= speed;
            const double k_t = inverse_mass(a, ra, slip) + inverse_mass(b, rb, slip);
            if (!(k_t > 0.0)) continue;
            const double jt = std::min(speed / k_t, mu * normal[k]);
            const double Jt[3] = {-jt * slip[0], -jt * slip[1], -jt * slip[2]};
            apply_impulse(a, b, x, Jt);
        }
    const double parting = dot(b.v, n) - dot(a.v, n), k_com = a.inv_m + b.inv_m;
    if (e > 0.0 && approach > 0.0 && parting < e * approach && k_com > 0.0) {
        const double dj = (e * approach - parting) / k_com;
        for (int i = 0; i < 3; ++i) {
            a.v[i] -= a.inv_m * dj * n[i];
            b.v[i] += b.inv_m * dj * n[i];
        }
    }
    // The kinetic energy along the change is E(l) = E0 + l B + l^2 Q: keep l <= -B / Q.
    double B = 0.0, Q = 0.0;
    for (const auto &[now, was] : {std::pair<CollisionBody *, const CollisionBody *>{&a, &a0}, {&b, &b0}}) {
        if (now->inv_m == 0.0) continue;
        double dv[3], dw[3], Idw[3];
        for (int i = 0; i < 3; ++i) {
            dv[i] = now->v[i] - was->v[i];
            dw[i] = now->w[i] - was->w[i];
        }
        mat_vec(now->I, dw, Idw);
        B += dot(was->v, dv) / now->inv_m + dot(was->w, Idw);
        Q += 0.5 * (dot(dv, dv) / now->inv_m + dot(dw, Idw));
    }
    if (Q > 0.0 && B + Q > 0.0) {
        const double scale = std::clamp(-B / Q, 0.0, 1.0);
        for (const auto &[now, was] : {std::pair<CollisionBody *, const CollisionBody *>{&a, &a0}, {&b, &b0}})
            for (int i = 0; i < 3; ++i) {
                now->v[i] = was->v[i] + scale * (now->v[i] - was->v[i]);
                now->w[i] = was->w[i] + scale * (now->w[i] - was->w[i]);
            }
    }
    return true;
}

std::vector<std::pair<int64_t, int64_t>> candidate_pairs(const double *bounds, int64_t n, int64_t n_fast,
                                                         const int64_t *frame, const int64_t *frame_body,
                                                         const uint8_t *self_collides, const FrameFilter &filter) {
    std::vector<std::pair<int64_t, int64_t>> out;
    for (int64_t i = 0; i < n_fast; ++i)
        for (int64_t j = 0; j < n; ++j) {
            if (j == i || (j < n_fast && j < i)) continue;
            const double *bi = bounds + 6 * i, *bj = bounds + 6 * j;
            if (!(bi[0] <= bj[3] && bj[0] <= bi[3] && bi[1] <= bj[4] && bj[1] <= bi[4] && bi[2] <= bj[5] &&
                  bj[2] <= bi[5]))
                continue;
            const int64_t fi = frame[i], fj = frame[j];
            if (fi == fj) continue;  // boxes of one link never collide with each other
            if (frame_body[fi] == frame_body[fj] && !self_collides[fi]) continue;
            if (!filter.allowed(fi, fj)) continue;
            out.emplace_back(i, j);
        }
    return out;
}

}  // namespace boxccd
