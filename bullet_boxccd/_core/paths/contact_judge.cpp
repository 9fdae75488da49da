#include "paths/contact_judge.hpp"

#include <algorithm>
#include <cmath>
#include <limits>

#include "solver/bms.hpp"
#include "solver/vec.hpp"

namespace boxccd {

namespace {

using pr = PathRow;

// v turned with a row's frame from s to the end of its path: R(1) R(s)^T v.
Vec3 turned_to_end(const double *row, double s, const Vec3 &v) {
    double Xs[16], X1[16];
    row_pose(row, s, Xs);
    row_pose(row, 1.0, X1);
    Vec3 local{}, out{};
    for (int i = 0; i < 3; ++i) local[i] = Xs[i] * v[0] + Xs[4 + i] * v[1] + Xs[8 + i] * v[2];
    for (int i = 0; i < 3; ++i) out[i] = X1[4 * i] * local[0] + X1[4 * i + 1] * local[1] + X1[4 * i + 2] * local[2];
    return out;
}

// The contact normal at s turned to the end of the window with the body whose face it
// is (for an edge-edge contact, the one that turns less); NaN without a facet.
Vec3 normal_at_end(const double *row_a, const double *row_b, double s, const Hit &hit) {
    constexpr double nan = std::numeric_limits<double>::quiet_NaN();
    if (hit.facet < 0) return {nan, nan, nan};
    const Kind kind = facet_kind(hit.facet);
    const bool first = kind == Kind::OV || (kind == Kind::EE && row_a[pr::kAngle] <= row_b[pr::kAngle]);
    return turned_to_end(first ? row_a : row_b, s, hit.normal);
}

// Half the extent of a box (pose X, row-major 4x4; half extents h) along unit n.
double half_width(const double *X, const double *h, const Vec3 &n) {
    double r = 0.0;
    for (int k = 0; k < 3; ++k) r += std::fabs(X[k] * n[0] + X[4 + k] * n[1] + X[8 + k] * n[2]) * h[k];
    return r;
}

// The first sample time of (0, 1] at which the boxes are apart by more than `gap`, NaN if
// they reach `target` depth first or are never seen apart: 2^-k for k = 8 .. 5 (a corner
// leaving right after pybullet's solver parted it), then the sixteenths.
double first_apart(const BoxPath &a, const BoxPath &b, double gap, double target) {
    constexpr double kSamples[] = {1.0 / 256, 1.0 / 128, 1.0 / 64, 1.0 / 32};
    constexpr int kEven = 16;
    for (int k = 0; k < 4 + kEven; ++k) {
        const double s = k < 4 ? kSamples[k] : (k - 3.0) / kEven;
        const double depth = path_separation(a, b, s, nullptr, -gap);
        if (depth >= target) return std::numeric_limits<double>::quiet_NaN();
        if (depth < -gap) return s;
    }
    return std::numeric_limits<double>::quiet_NaN();
}

}  // namespace

Judgement judge_contact(const double *row_a, const double *row_b, double lo, double s_touch, bool judge,
                        bool with_time, bool after_impact, double penetration, double impact_depth,
                        double depth_tolerance, double creep, const Tolerances &tol) {
    double wa[pr::kSize], wb[pr::kSize];
    window_row(row_a, lo, 1.0, wa);
    window_row(row_b, lo, 1.0, wb);
    const RowBoxPath a(wa), b(wb);
    Judgement out;
    out.contact = window_contact(a, b, s_touch, 1.0, tol);
    if (out.contact.outcome == Outcome::Separated) return out;
    out.normal_at_end = normal_at_end(wa, wb, s_touch, out.contact);
    if (!judge) return out;
    const double *ha = a.half_extents(), *hb = b.half_extents();
    const bool initial = s_touch == 0.0;
    const double thin = std::min(*std::min_element(ha, ha + 3), *std::min_element(hb, hb + 3));
    double target = impact_depth, start = 0.0;
    if (initial) {
        start = std::max(path_depth(a, b, 0.0), 0.0);
        target = start + std::max(penetration, std::min(creep * thin, depth_tolerance));
    }
    bool timed = false;
    const auto depth_time = [&] {
        if (!timed) out.depth_time = first_depth(a, b, s_touch, target);
        timed = true;
        return out.depth_time;
    };
    const Vec3 &n = out.normal_at_end;
    Vec3 axis;
    const double end = out.depth_end = path_separation(a, b, 1.0, axis.data());
    if (end - start > depth_tolerance || !(std::isfinite(n[0]) && std::isfinite(n[1]) && std::isfinite(n[2]))) {
        out.wrong = true;
    } else {
        if (end <= 0.0) {
            out.wrong = !std::isnan(depth_time());  // apart: overlapped that deep on the way
        } else {
            double Xa[16], Xb[16];
            row_pose(wa, 1.0, Xa);
            row_pose(wb, 1.0, Xb);
            const Vec3 ab{Xb[3] - Xa[3], Xb[7] - Xa[7], Xb[11] - Xa[11]};
            out.wrong = dot3(axis, n) < 0.0 || dot3(ab, n) < 0.5 * (half_width(Xa, ha, n) + half_width(Xb, hb, n));
            // Ending in a shallow overlap on the right side, but past the thinner box's middle
            // on the way: pybullet resolves the pair from the end, never having seen that.
            if (!out.wrong) out.wrong = !std::isnan(first_depth(a, b, s_touch, start + thin));
            // Met inside the window and ending in a shallow overlap, but deeper on the way (a
            // turning box's corner that dipped in and is leaving): pybullet resolves the pair
            // from the end, where the corner no longer approaches, and its impact is lost.
            if (!out.wrong && !initial) out.wrong = !std::isnan(first_depth(a, b, s_touch, end + penetration));
        }
    }
    if (out.wrong || with_time) depth_time();
    if (out.wrong && initial) {
        // Apart at a sample after going past the thinner box's middle (through a thin wall
        // between two samples) is not parted: it went through.
        const double apart = first_apart(a, b, penetration, target);
        out.parted = !std::isnan(apart) && !(first_depth(a, b, 0.0, start + thin) <= apart);
        if (out.parted) {
            out.again = first_depth(a, b, apart, 0.0);
        } else if (after_impact) {
            // A corner that was apart as the window began at the pair's impact striking before
            // the pair presses in by the target: the next corner of a turning box, an impact of
            // its own.
            const CornerStrike struck = first_corner_strike(a, b, 0.0, penetration, impact_depth);
            out.fresh = !std::isnan(struck.tau) && !(depth_time() < struck.tau);
            if (out.fresh) {
                out.depth_time = struck.tau;
                const CornerStrike touch = first_corner_strike(a, b, 0.0, penetration, 0.0);
                out.contact = corner_contact(a, b, std::isnan(touch.tau) ? struck : touch);
            }
        }
    }
    return out;
}

namespace {

// Whether pybullet resolves a link pair wrongly from the step's end (the boxes at Xa, Xb
// there, their depth1 along axis1), once it overlapped by the target at s_act. With n the
// least-overlap axis then (from A towards B): overlapping at the end, the least overlap
// pointing back out of the far side, or the boxes overlapping along n by more than half
// the thinner of them along n (one has gone past the other's middle: its nearest way out
// is through); apart at the end, B's centre on A's far side along n (it went through). A
// pair that parted on the side it came from, or sideways (a strike, a link sweeping along
// a face), is pybullet's to resolve.
bool link_goes_wrong(const BoxPath &a, const BoxPath &b, double s_act, const double *Xa, const double *Xb,
                     double depth1, const Vec3 &axis1) {
    Vec3 n;
    path_separation(a, b, s_act, n.data());
    const Vec3 ab{Xb[3] - Xa[3], Xb[7] - Xa[7], Xb[11] - Xa[11]};
    const double along = dot3(ab, n);
    if (depth1 <= 0.0) return along < 0.0;
    const double wa = half_width(Xa, a.half_extents(), n), wb = half_width(Xb, b.half_extents(), n);
    return dot3(axis1, n) < 0.0 || wa + wb - along > std::min(wa, wb);
}

}  // namespace

LinkJudgement judge_link_contact(const BoxPath &a, const BoxPath &b, double fit_tolerance, double penetration,
                                 double creep, const Tolerances &tol) {
    LinkJudgement out;
    Outcome outcome;
    out.touch = first_touch(a, b, fit_tolerance, tol, out.solves, outcome,
                            std::numeric_limits<double>::quiet_NaN(), &out.contact);
    if (std::isnan(out.touch)) return out;
    const double *ha = a.half_extents(), *hb = b.half_extents();
    const double thin = std::min(*std::min_element(ha, ha + 3), *std::min_element(hb, hb + 3));
    const double d0 = path_depth(a, b, 0.0), creep_depth = creep * thin;
    out.initial = d0 >= 0.0;
    out.pressing = d0 > -creep_depth;
    const double target = out.pressing ? std::max(d0, 0.0) + std::max(penetration, creep_depth) : penetration;
    // A pressing pair ending in contact but shallower than the target is pybullet's (its
    // solver holds it); one ending apart either lifted off or went through.
    double Xa[16], Xb[16];
    a.pose(1.0, Xa);
    b.pose(1.0, Xb);
    Vec3 axis1;
    const double d1 = pose_separation(Xa, ha, Xb, hb, axis1.data());
    if (!(out.pressing && d1 < target && d1 >= 0.0)) {
        const double act = first_depth(a, b, out.touch, target);
        // Apart at the end on the side it came from, but past the middle of the thinner box on
        // the way (a link swinging through a plate and out again within the step): pybullet
        // never sees that contact.
        if (!std::isnan(act) && (link_goes_wrong(a, b, act, Xa, Xb, d1, axis1) ||
                                 (d1 <= 0.0 && !std::isnan(first_depth(a, b, act, thin)))))
            out.act = act;
    }
    if (out.contact.facet < 0) {
        path_separation(a, b, out.touch, out.normal.data());
        double Xa[16], Xb[16];
        a.pose(out.touch, Xa);
        b.pose(out.touch, Xb);
        out.point = {0.5 * (Xa[3] + Xb[3]), 0.5 * (Xa[7] + Xb[7]), 0.5 * (Xa[11] + Xb[11])};
    }
    return out;
}

}  // namespace boxccd
