#include "paths/chain.hpp"

#include <algorithm>
#include <cmath>
#include <limits>
#include <stdexcept>
#include <string>

namespace boxccd {

namespace {

constexpr double kInf = std::numeric_limits<double>::infinity();

// Quaternions are x y z w, as pybullet gives them.
void qmul(const double *a, const double *b, double *out) {
    const double r[4] = {a[3] * b[0] + b[3] * a[0] + a[1] * b[2] - a[2] * b[1],
                         a[3] * b[1] + b[3] * a[1] + a[2] * b[0] - a[0] * b[2],
                         a[3] * b[2] + b[3] * a[2] + a[0] * b[1] - a[1] * b[0],
                         a[3] * b[3] - a[0] * b[0] - a[1] * b[1] - a[2] * b[2]};
    std::copy(r, r + 4, out);
}

// v rotated by the unit quaternion q: v + w t + u x t, t = 2 u x v.
void qrot(const double *q, const double *v, double *out) {
    const double t[3] = {2.0 * (q[1] * v[2] - q[2] * v[1]), 2.0 * (q[2] * v[0] - q[0] * v[2]),
                         2.0 * (q[0] * v[1] - q[1] * v[0])};
    const double r[3] = {v[0] + q[3] * t[0] + q[1] * t[2] - q[2] * t[1],
                         v[1] + q[3] * t[1] + q[2] * t[0] - q[0] * t[2],
                         v[2] + q[3] * t[2] + q[0] * t[1] - q[1] * t[0]};
    std::copy(r, r + 3, out);
}

// The turn by `angle` about the unit axis.
void qaxis(const double *axis, double angle, double *out) {
    const double s = std::sin(0.5 * angle);
    out[0] = s * axis[0];
    out[1] = s * axis[1];
    out[2] = s * axis[2];
    out[3] = std::cos(0.5 * angle);
}

// A unit quaternion from q (x y z w), or false if q is not a finite nonzero quaternion.
bool unit_quaternion(const double *q, double *out) {
    const double n = std::sqrt(q[0] * q[0] + q[1] * q[1] + q[2] * q[2] + q[3] * q[3]);
    if (!(n > 0.0 && n < kInf)) return false;
    for (int i = 0; i < 4; ++i) out[i] = q[i] / n;
    return true;
}

// 4x4 row-major of a pose (position, unit quaternion).
void pose_matrix(const double *pose, double *X) {
    const double x = pose[3], y = pose[4], z = pose[5], w = pose[6];
    const double R[9] = {1 - 2 * (y * y + z * z), 2 * (x * y - z * w),     2 * (x * z + y * w),
                         2 * (x * y + z * w),     1 - 2 * (x * x + z * z), 2 * (y * z - x * w),
                         2 * (x * z - y * w),     2 * (y * z + x * w),     1 - 2 * (x * x + y * y)};
    for (int i = 0; i < 3; ++i) {
        for (int j = 0; j < 3; ++j) X[4 * i + j] = R[3 * i + j];
        X[4 * i + 3] = pose[i];
        X[12 + i] = 0.0;
    }
    X[15] = 1.0;
}

void mat4_mul(const double *A, const double *B, double *out) {
    for (int i = 0; i < 4; ++i)
        for (int j = 0; j < 4; ++j) {
            double v = 0.0;
            for (int k = 0; k < 4; ++k) v += A[4 * i + k] * B[4 * k + j];
            out[4 * i + j] = v;
        }
}

// The quadratic through X0, X1, X2 (4x4 each) at s = 0, 1/2, 1, as fit_path writes it.
void interpolate(const double *X0, const double *X1, const double *X2, double *coeffs) {
    for (int e = 0; e < 16; ++e) {
        const bool last_row = e >= 12;
        coeffs[e] = X0[e];
        coeffs[16 + e] = last_row ? 0.0 : -3.0 * X0[e] + 4.0 * X1[e] - X2[e];
        coeffs[32 + e] = last_row ? 0.0 : 2.0 * X0[e] - 4.0 * X1[e] + 2.0 * X2[e];
    }
}

struct Affine {  // a + b r
    double a = 0.0, b = 0.0;
};

// The factor-wise bounds V1..V4 after a turn at rate w (>= 0) with lever arm rho (fit_bound).
void turn_bounds(double w, const Affine &rho, Affine &v1, Affine &v2, Affine &v3, Affine &v4) {
    const double w2 = w * w, w3 = w2 * w, w4 = w3 * w;
    const auto step = [&](double Affine::*f) {
        const double r = rho.*f, a1 = v1.*f, a2 = v2.*f, a3 = v3.*f;
        v4.*f += w4 * r + 4 * w3 * a1 + 6 * w2 * a2 + 4 * w * a3;
        v3.*f += w3 * r + 3 * w2 * a1 + 3 * w * a2;
        v2.*f += w2 * r + 2 * w * a1;
        v1.*f += w * r;
    };
    step(&Affine::a);
    step(&Affine::b);
}

// The exact derivatives y[1..3] at the piece's middle after a turn W (fit_bound):
// y^(j) <- sum_i C(j, i) xi^i y^(j - i), where p1 = xi^ y[0] (on the point, or on a
// vector) and xi^ is W x on vectors.
void advance(const Vec3 &W, const Vec3 &p1, Vec3 *y) {
    const Vec3 p2 = cross3(W, p1), p3 = cross3(W, p2);
    const Vec3 y1 = cross3(W, y[1]), y11 = cross3(W, y1), y2 = cross3(W, y[2]);
    y[3] = p3 + 3.0 * y11 + 3.0 * y2 + y[3];
    y[2] = p2 + 2.0 * y1 + y[2];
    y[1] = p1 + y[1];
}

// Spectral norm of the 3x3 matrix whose columns are c[0..2]: the square root of the
// largest eigenvalue of its Gram matrix (closed form for symmetric 3x3), widened by
// 1e-12 of the trace for rounding and never above the Frobenius norm.
double spectral_norm(const Vec3 *c) {
    double G[3][3];
    for (int i = 0; i < 3; ++i)
        for (int j = 0; j < 3; ++j) G[i][j] = c[i][0] * c[j][0] + c[i][1] * c[j][1] + c[i][2] * c[j][2];
    const double trace = G[0][0] + G[1][1] + G[2][2];
    const double off = G[0][1] * G[0][1] + G[0][2] * G[0][2] + G[1][2] * G[1][2];
    double top;
    if (!(off > 0.0)) {
        top = std::max({G[0][0], G[1][1], G[2][2]});
    } else {
        const double q = trace / 3.0;
        const double p = std::sqrt(((G[0][0] - q) * (G[0][0] - q) + (G[1][1] - q) * (G[1][1] - q) +
                                    (G[2][2] - q) * (G[2][2] - q) + 2.0 * off) / 6.0);
        double B[3][3];
        for (int i = 0; i < 3; ++i)
            for (int j = 0; j < 3; ++j) B[i][j] = (G[i][j] - (i == j ? q : 0.0)) / p;
        const double det = B[0][0] * (B[1][1] * B[2][2] - B[1][2] * B[2][1]) -
                           B[0][1] * (B[1][0] * B[2][2] - B[1][2] * B[2][0]) +
                           B[0][2] * (B[1][0] * B[2][1] - B[1][1] * B[2][0]);
        const double phi = std::acos(std::clamp(0.5 * det, -1.0, 1.0)) / 3.0;
        top = q + 2.0 * p * std::cos(phi);
    }
    return std::sqrt(std::max(0.0, std::min(trace, top + 1e-12 * trace)));
}

std::string at_link(int64_t i) { return "link " + std::to_string(i) + ": "; }

bool finite_all(const double *x, int64_t n) {
    return std::all_of(x, x + n, [](double v) { return std::isfinite(v); });
}

}  // namespace

Chain::Chain(int64_t n, const int64_t *parent, const int64_t *joint_type, const double *axis,
             const double *parent_pos, const double *parent_orn, const double *inertial_pos,
             const double *inertial_orn, const int64_t *q_index, const int64_t *qdot_index) {
    links_.resize(size_t(n));
    for (int64_t i = 0; i < n; ++i) {
        ChainLink &l = links_[i];
        if (parent[i] < -1 || parent[i] >= i)
            throw std::out_of_range(at_link(i) + "parent " + std::to_string(parent[i]) +
                                    " is not the base (-1) or an earlier link (pybullet orders parents first)");
        l.parent = int(parent[i]);
        const int64_t t = joint_type[i];
        if (t == int64_t(JointType::Planar))
            throw std::invalid_argument(at_link(i) + "planar joints are not supported (pybullet reports 2 of "
                                                     "their 3 coordinates and no axis)");
        if (t != int64_t(JointType::Revolute) && t != int64_t(JointType::Prismatic) &&
            t != int64_t(JointType::Spherical) && t != int64_t(JointType::Fixed))
            throw std::invalid_argument(at_link(i) + "joint type " + std::to_string(t) +
                                        " is not revolute (0), prismatic (1), spherical (2) or fixed (4)");
        l.type = JointType(t);
        if (!finite_all(axis + 3 * i, 3) || !finite_all(parent_pos + 3 * i, 3) ||
            !finite_all(inertial_pos + 3 * i, 3))
            throw std::invalid_argument(at_link(i) + "axis, parent_pos and inertial_pos must be finite");
        std::copy(axis + 3 * i, axis + 3 * i + 3, l.axis);
        if (l.type == JointType::Revolute) {  // Bullet's turn about the axis normalises it
            const double a = norm3(l.axis);
            if (!(a > 0.0)) throw std::invalid_argument(at_link(i) + "a revolute joint needs a nonzero axis");
            for (double &x : l.axis) x /= a;
        }
        std::copy(parent_pos + 3 * i, parent_pos + 3 * i + 3, l.e);
        double Z[4], I[4];
        if (!unit_quaternion(parent_orn + 4 * i, Z) || !unit_quaternion(inertial_orn + 4 * i, I))
            throw std::invalid_argument(at_link(i) + "parent_orn and inertial_orn must be finite nonzero quaternions");
        l.zero_rot[0] = -Z[0];  // Z^T: the conjugate
        l.zero_rot[1] = -Z[1];
        l.zero_rot[2] = -Z[2];
        l.zero_rot[3] = Z[3];
        const double I_conj[4] = {-I[0], -I[1], -I[2], I[3]};
        qrot(I_conj, inertial_pos + 3 * i, l.d);  // d = R_I^T p_I
        const int nq = l.type == JointType::Spherical ? 4 : l.type == JointType::Fixed ? 0 : 1;
        const int nu = l.type == JointType::Spherical ? 3 : nq;
        l.q_index = l.qdot_index = 0;
        if (nq) {
            if (q_index[i] < 0 || qdot_index[i] < 0 || q_index[i] > (1 << 30) || qdot_index[i] > (1 << 30))
                throw std::out_of_range(at_link(i) + "q_index " + std::to_string(q_index[i]) + " or qdot_index " +
                                        std::to_string(qdot_index[i]) + " is negative or huge");
            l.q_index = int(q_index[i]);
            l.qdot_index = int(qdot_index[i]);
            n_q_ = std::max(n_q_, l.q_index + nq);
            n_qdot_ = std::max(n_qdot_, l.qdot_index + nu);
        }
    }
}

ChainMotion::ChainMotion(const Chain &chain, const double *state, const double *q, const double *qdot, double dt)
    : chain_(&chain), dt_(dt) {
    if (!(dt > 0.0 && dt < kInf)) throw std::invalid_argument("dt must be finite and > 0, got " + std::to_string(dt));
    if (!finite_all(state, FrameState::kSize)) throw std::invalid_argument("the base state must be finite");
    if (!unit_quaternion(state + FrameState::kOrientation, state_ + FrameState::kOrientation))
        throw std::invalid_argument("the base orientation must be a nonzero quaternion");
    std::copy(state, state + FrameState::kOrientation, state_);
    std::copy(state + FrameState::kVelocity, state + FrameState::kSize, state_ + FrameState::kVelocity);
    const double *w = state_ + FrameState::kAngularVelocity, *v = state_ + FrameState::kVelocity;
    const double spin = norm3(w);
    base_angle_ = bullet_step_angle(spin, dt);
    for (int i = 0; i < 3; ++i) base_axis_[i] = spin > 0.0 ? w[i] / spin : 0.0;
    base_shift_ = norm3(v) * dt;

    joints_.resize(size_t(chain.n_links()));
    for (int i = 0; i < chain.n_links(); ++i) {
        const ChainLink &l = chain.link(i);
        JointStep &j = joints_[i];
        j = JointStep{{0, 0, 0, 1}, {0, 0, 0}, 0.0, 0.0};
        const double *qi = q + l.q_index, *ui = qdot + l.qdot_index;
        switch (l.type) {
            case JointType::Revolute:
            case JointType::Prismatic:
                if (!std::isfinite(qi[0]) || !std::isfinite(ui[0]))
                    throw std::invalid_argument(at_link(i) + "q and qdot must be finite");
                j.q1[0] = qi[0];
                std::copy(l.axis, l.axis + 3, j.axis);
                (l.type == JointType::Revolute ? j.angle : j.shift) = ui[0] * dt;
                break;
            case JointType::Spherical: {
                if (!unit_quaternion(qi, j.q1) || !finite_all(ui, 3))
                    throw std::invalid_argument(at_link(i) + "q must be a nonzero quaternion and qdot finite");
                const double speed = norm3(ui);
                for (int k = 0; k < 3; ++k) j.axis[k] = speed > 0.0 ? ui[k] / speed : 0.0;
                j.angle = bullet_step_angle(speed, dt);
                break;
            }
            default:
                break;
        }
    }
}

void ChainMotion::base_pose(double tau, double *pose) const { frame_pose(state_, dt_, tau, pose); }

void ChainMotion::joint_at(int link, double tau, double *J, double &s) const {
    const JointStep &j = joints_[link];
    s = 0.0;
    switch (chain_->link(link).type) {
        case JointType::Revolute:
            qaxis(j.axis, j.q1[0] - (1.0 - tau) * j.angle, J);
            return;
        case JointType::Prismatic:
            s = j.q1[0] - (1.0 - tau) * j.shift;
            break;
        case JointType::Spherical: {
            double back[4];
            qaxis(j.axis, -(1.0 - tau) * j.angle, back);
            qmul(j.q1, back, J);
            return;
        }
        default:
            break;
    }
    J[0] = J[1] = J[2] = 0.0;
    J[3] = 1.0;
}

void ChainMotion::joint_positions(double tau, double *q) const {
    for (int i = 0; i < chain_->n_links(); ++i) {
        const ChainLink &l = chain_->link(i);
        double J[4], s;
        joint_at(i, tau, J, s);
        if (l.type == JointType::Spherical) std::copy(J, J + 4, q + l.q_index);
        if (l.type == JointType::Prismatic) q[l.q_index] = s;
        if (l.type == JointType::Revolute) q[l.q_index] = joints_[i].q1[0] - (1.0 - tau) * joints_[i].angle;
    }
}

void ChainMotion::child_pose(int link, const double *parent, double tau, double *out) const {
    const ChainLink &l = chain_->link(link);
    double J[4], s, q0[4], pivot[3], arm[3];
    joint_at(link, tau, J, s);
    qrot(parent + 3, l.e, pivot);
    qmul(parent + 3, l.zero_rot, q0);
    qmul(q0, J, out + 3);
    const double local[3] = {l.d[0] + s * l.axis[0], l.d[1] + s * l.axis[1], l.d[2] + s * l.axis[2]};
    qrot(out + 3, local, arm);
    for (int i = 0; i < 3; ++i) out[i] = parent[i] + pivot[i] + arm[i];
}

int ChainMotion::ancestors(int link, int *out) const {
    int m = 0;
    for (int k = link; k >= 0; k = chain_->link(k).parent) out[m++] = k;
    return m;
}

namespace {

// Scratch for a link's ancestors: on the stack for chains of up to 64 links.
class Ancestors {
  public:
    explicit Ancestors(int n) {
        if (n > kStack) heap_.resize(size_t(n));
    }
    int *data() { return heap_.empty() ? stack_ : heap_.data(); }

  private:
    static constexpr int kStack = 64;
    int stack_[kStack];
    std::vector<int> heap_;
};

}  // namespace

void ChainMotion::link_pose(int link, double tau, double *pose) const {
    Ancestors scratch(chain_->n_links());
    int *path = scratch.data();
    const int m = ancestors(link, path);
    double parent[7];
    base_pose(tau, parent);
    for (int i = m - 1; i >= 0; --i) {
        child_pose(path[i], parent, tau, pose);
        std::copy(pose, pose + 7, parent);
    }
}

void ChainMotion::link_poses(double tau, double *poses) const {
    double base[7];
    base_pose(tau, base);
    for (int i = 0; i < chain_->n_links(); ++i) {
        const int p = chain_->link(i).parent;  // an earlier link: already done
        child_pose(i, p < 0 ? base : poses + 7 * p, tau, poses + 7 * i);
    }
}

void ChainMotion::chord_state(int link, double *row) const {
    double p0[7], *p1 = row;
    if (link == -1) {
        base_pose(0.0, p0);
        base_pose(1.0, p1);
    } else {
        link_pose(link, 0.0, p0);
        link_pose(link, 1.0, p1);
    }
    // The chord as a move between two poses (step_path.hpp: the turn the short way round).
    double path[kPathBoxSize];
    const double identity[16] = {1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1}, unit[3] = {1, 1, 1};
    path_row_between(p0, p1, identity, unit, path);
    for (int i = 0; i < 3; ++i) {
        p1[7 + i] = path[PathRow::kDisplacement + i] / dt_;
        p1[10 + i] = path[PathRow::kAxis + i] * path[PathRow::kAngle] / dt_;
    }
}

// The bound on [lo, hi], derived.
//
// Over the piece, with s = tau - tm about the middle tm, the link's frame is a
// product of motions about fixed world axes (the product of exponentials taken at
// tm): X(tau) = T_b(s) R_b(s) G_1(s) ... G_m(s) X(tm), where T_b moves the base's
// centre of mass by s v dt, R_b turns about the line through the base's centre
// at tm along w by s phi_b, and G_k is joint k (outermost first) as a screw in
// the world at tm: a turn about the line through its pivot along its axis (a
// revolute joint; a spherical one about qdot's direction) at rate w_k (the angle
// per unit tau, qdot dt or Bullet's clamped angle), or a slide at velocity S_k
// (qdot dt a, prismatic). A point x of the link is y_1(s), where
// y_k = G_k y_{k+1} and y_{m+1} = x: innermost first, each factor moves the
// point by a constant-rate motion applied after the inner ones.
//
// For y_k = U(s) y with U = exp(s xi), U' = xi^ U, Leibniz gives
//   y_k^(1) = xi^ U y + U y^(1)
//   y_k^(2) = xi^2 U y + 2 xi^ U y^(1) + U y^(2)
//   y_k^(3) = xi^3 U y + 3 xi^2 U y^(1) + 3 xi^ U y^(2) + U y^(3)
//   y_k^(4) = xi^4 U y + 4 xi^3 U y^(1) + 6 xi^2 U y^(2) + 4 xi^ U y^(3) + U y^(4).
// A turn at rate w about a line L (unit u, through o): xi^ applied to a point p
// is W x (p - o) with W = w u, of norm <= |w| dist(p, L), and applied to a vector
// v it is W x v, so |xi^j U y| <= |w|^j dist(y, L) (U turns about L, keeping the
// distance) and |xi^j U v| <= |w|^j |v|. A slide: xi^ p = S for a point, and xi^
// is zero on vectors (xi^2 = 0).
//
// Factor-wise bound. With V1..V4 bounds of |y^(1)| .. |y^(4)| over the piece, a
// turn makes
//   rho = dist(y_{k+1}(tm), L) + h V1    (h = (hi - lo) / 2: y moves at most that)
//   V4 <- w^4 rho + 4 w^3 V1 + 6 w^2 V2 + 4 w V3 + V4,
//   V3 <- w^3 rho + 3 w^2 V1 + 3 w V2 + V3,  V2 <- w^2 rho + 2 w V1 + V2,
//   V1 <- w rho + V1      (w = |w_k|)
// and a slide makes V1 <- |S| + V1. Starting from V = 0 (x is fixed in the link),
// and dist(y_{k+1}(tm), L) <= dist(link origin at tm, L) + r for a point within r
// of the link's origin (y_{k+1}(tm) is the point's place at tm), every V is
// affine in r. The fit's error is at most sup|x^(3)| (hi - lo)^3 sqrt(3) / 216
// (kInterpolationError; tau runs over hi - lo), so at most V3 times that. The exact
// case: one turn at radius rho gives V3 = w^3 rho, the |x^(3)| of a circle.
//
// Local bound. The triangle inequality above adds turns that partly cancel (two
// joints turning opposite ways). At s = 0 every U is I, so the same recursion on
// vectors gives x^(3) at tm exactly, cancellations included: for the link's
// origin c, D_j (j = 1..3) from D_j <- sum_i C(j, i) xi^i D_{j-i} with D_0 = c
// (xi^i on the point, then on vectors); a point c + delta adds A delta, A built
// alike from delta as a vector (only turns act on it). So sup|x^(3)| <= |D_3| +
// |A| r + h V4, with |A| the spectral norm (from the largest eigenvalue of A^T A,
// in closed form). The point bound is the smaller of the two.
//
// The rotation part alone is a product of turns, whose third derivative is at
// most (sum |w_k|)^3 in norm (Leibniz again, each |R^(j)| <= |w|^j), and at most
// |A| + h (sum |w_k|)^4 (A is R^(3)(tm) R(tm)^T); `rotation` is the smaller.
// Rounding: the poses and these sums are computed in doubles; kFitRounding
// covers that relative to the lengths and to the factor-wise bound's terms.
FitBound ChainMotion::fit_bound(int link, double lo, double hi) const {
    Ancestors scratch(chain_->n_links());
    int *path = scratch.data();
    const int m = ancestors(link, path);
    const double tm = 0.5 * (lo + hi), h = 0.5 * (hi - lo), len = hi - lo;
    // Poses at tm of the base (slot m) and of the link's ancestors (slot i: path[i]).
    double stack[7 * 65];
    std::vector<double> heap;
    if (m >= 65) heap.resize(7 * size_t(m + 1));
    double *pose = heap.empty() ? stack : heap.data();
    base_pose(tm, &pose[7 * m]);
    for (int i = m - 1; i >= 0; --i) child_pose(path[i], &pose[7 * (i + 1)], tm, &pose[7 * i]);
    const double *c = &pose[0];  // the link's origin at tm
    Affine v1, v2, v3, v4;
    Vec3 D[4] = {Vec3{c[0], c[1], c[2]}, {}, {}, {}};                       // of the origin: D[0] the point
    Vec3 E[4][3] = {{Vec3{1, 0, 0}, Vec3{0, 1, 0}, Vec3{0, 0, 1}}, {}, {}, {}};  // of the world axes, as vectors
    double spin = 0.0, lengths = norm3(c);
    const auto turn = [&](double w, const double *o, const double *u) {  // rate w about the line (o, u)
        const double aw = std::fabs(w);
        if (!(aw > 0.0)) return;
        const Vec3 co{c[0] - o[0], c[1] - o[1], c[2] - o[2]}, W{w * u[0], w * u[1], w * u[2]};
        const double along = co[0] * u[0] + co[1] * u[1] + co[2] * u[2];
        const double off[3] = {co[0] - along * u[0], co[1] - along * u[1], co[2] - along * u[2]};
        const Affine rho{norm3(off) + h * v1.a, 1.0 + h * v1.b};
        turn_bounds(aw, rho, v1, v2, v3, v4);
        advance(W, cross3(W, co), D);
        for (int k = 0; k < 3; ++k) {
            Vec3 y[4] = {E[0][k], E[1][k], E[2][k], E[3][k]};
            advance(W, cross3(W, y[0]), y);
            for (int j = 1; j < 4; ++j) E[j][k] = y[j];
        }
        spin += aw;
    };
    for (int i = 0; i < m; ++i) {
        const ChainLink &l = chain_->link(path[i]);
        const JointStep &j = joints_[path[i]];
        const double *parent = &pose[7 * (i + 1)], *child = &pose[7 * i];
        lengths += norm3(l.e) + norm3(l.d) + std::fabs(j.q1[0]) * norm3(l.axis);
        if (l.type == JointType::Revolute || l.type == JointType::Spherical) {
            double pivot[3], u[3];
            qrot(parent + 3, l.e, pivot);
            for (int k = 0; k < 3; ++k) pivot[k] += parent[k];
            qrot(child + 3, j.axis, u);  // the axis is fixed in the child: its world direction at tm
            turn(j.angle, pivot, u);
        } else if (l.type == JointType::Prismatic) {
            double S[3];
            qrot(child + 3, l.axis, S);  // the child's axis (a slide does not turn the child)
            for (int k = 0; k < 3; ++k) D[1][k] += j.shift * S[k];
            v1.a += std::fabs(j.shift) * norm3(l.axis);
        }
    }
    turn(base_angle_, &pose[7 * m], base_axis_);
    for (int k = 0; k < 3; ++k) D[1][k] += state_[FrameState::kVelocity + k] * dt_;
    v1.a += base_shift_;
    const double scale = kInterpolationError * len * len * len, slack = kFitRounding * (m + 2);
    const double a_norm = spectral_norm(E[3]) * (1.0 + slack);
    const double spin3 = spin * spin * spin, spin4 = spin3 * spin;
    FitBound b;
    b.factor0 = scale * v3.a + slack * lengths;
    b.factor1 = scale * v3.b + slack;
    b.local0 = scale * (norm3(D[3]) + h * v4.a + slack * v3.a) + slack * lengths;
    b.local1 = scale * (a_norm + h * v4.b + slack * v3.b) + slack;
    b.rotation = scale * std::min(spin3, a_norm + h * spin4) + slack;
    b.sweep0 = h * v1.a + slack * lengths;
    b.sweep1 = h * v1.b + slack;
    return b;
}

FitBound ChainMotion::fit(int link, double lo, double hi, double *coeffs) const {
    double pose[7], X[3][16];
    const double taus[3] = {lo, 0.5 * (lo + hi), hi};
    for (int k = 0; k < 3; ++k) {
        link_pose(link, taus[k], pose);
        pose_matrix(pose, X[k]);
    }
    interpolate(X[0], X[1], X[2], coeffs);
    return fit_bound(link, lo, hi);
}

LinkBoxPath::LinkBoxPath(const ChainMotion &motion, int link, const double *X_CS, const double *half)
    : motion_(&motion), link_(link) {
    if (link < 0 || link >= motion.chain().n_links())
        throw std::out_of_range("link " + std::to_string(link) + " is not one of the chain's " +
                                std::to_string(motion.chain().n_links()) + " links");
    if (!finite_all(X_CS, 16) || !finite_all(half, 3)) throw std::invalid_argument("X_CS and half must be finite");
    if (!(half[0] > 0.0 && half[1] > 0.0 && half[2] > 0.0))
        throw std::invalid_argument("half extents must be > 0");
    std::copy(X_CS, X_CS + 16, X_CS_);
    std::copy(half, half + 3, half_);
    reach_ = reach_radius(X_CS, half);
}

void LinkBoxPath::pose(double tau, double *X_WS) const {
    double p[7], X_WC[16];
    motion_->link_pose(link_, tau, p);
    pose_matrix(p, X_WC);
    mat4_mul(X_WC, X_CS_, X_WS);
}

LinkBoxPath::Growth LinkBoxPath::growth(double lo, double hi) const {
    // A box point x is off its fitted place by at most e = b.point(reach); the fitted
    // 3x3 part M is within `rotation` of a rotation, so the box point y whose fitted
    // place is x's true one has |y - x| = |M^-1 e| <= e / (1 - rotation).
    const FitBound b = motion_->fit_bound(link_, lo, hi);
    const double quadratic = b.rotation < 1.0 ? b.point(reach_) / (1.0 - b.rotation) : kInf;
    // Too fast for a quadratic (a joint turning radians per piece): the box held still
    // at its middle pose, grown by how far its points get from there, is closer.
    const double still = b.sweep(reach_);
    return still < quadratic ? Growth{still, true} : Growth{quadratic, false};
}

double LinkBoxPath::fit(double lo, double hi, double *coeffs) const {
    double X[3][16];
    const double taus[3] = {lo, 0.5 * (lo + hi), hi};
    const Growth g = growth(lo, hi);
    for (int k = 0; k < 3; ++k)
        if (k == 1 || !g.still) pose(taus[k], X[k]);
    if (g.still)
        interpolate(X[1], X[1], X[1], coeffs);
    else
        interpolate(X[0], X[1], X[2], coeffs);
    return g.length;
}

double LinkBoxPath::travel(double lo, double hi) const { return motion_->fit_bound(link_, lo, hi).sweep(reach_); }

int LinkBoxPath::pieces(double fit_tolerance) const {
    // The whole step's bound on the third derivative holds on every piece, and the
    // error shrinks as the cube of the piece's length: an upper estimate. Each piece's
    // own bound is smaller (its lever arms and third derivative are taken at its
    // middle), so fewer pieces may do: halve while every piece's growth still fits.
    const FitBound b = motion_->fit_bound(link_, 0.0, 1.0);
    const double allowed = fit_tolerance * std::min({half_[0], half_[1], half_[2]});
    const double error = b.point(reach_);
    int n = 1;
    while (n < kMaxFitPieces && !(b.rotation < double(n) * n * n && error / (double(n) * n * n - b.rotation) <= allowed)) n *= 2;
    while (n > 1) {
        const int half_n = n / 2;
        bool fits = true;
        for (int k = 0; k < half_n && fits; ++k)
            fits = growth(double(k) / half_n, double(k + 1) / half_n).length <= allowed;
        if (!fits) break;
        n = half_n;
    }
    return n;
}

std::vector<FastBox> fast_boxes(const ChainMotion &motion, size_t n, const int64_t *links, const double *X_CS,
                                const double *half, const double *reach) {
    std::vector<FastBox> out;
    const double dt = motion.dt();
    double chord[13];
    int64_t chord_link = -2;
    for (size_t k = 0; k < n; ++k) {
        const double *X = X_CS + 16 * k, *h = half + 3 * k;
        // How far the box's points go from where the step began to where it ended:
        // its frame's chord (the path's own bulge is of second order in the turn).
        if (links[k] != chord_link) {
            chord_link = links[k];
            motion.chord_state(int(chord_link), chord);
        }
        const double move = step_reach(chord, dt, reach_radius(X, h));
        if (!(move > reach[k])) continue;
        FastBox b{int64_t(k), move, {}, {}};
        const int pieces = move < std::min({h[0], h[1], h[2]}) ? 1 : 4;
        if (links[k] == -1) {
            double row[kPathBoxSize];
            path_row(motion.state(), dt, X, h, row);
            path_bounds(RowBoxPath(row), pieces, b.lo, b.hi);
        } else {
            path_bounds(LinkBoxPath(motion, int(links[k]), X, h), pieces, b.lo, b.hi);
        }
        out.push_back(b);
    }
    return out;
}

}  // namespace boxccd
