#include "paths/box_path.hpp"

#include <algorithm>
#include <cmath>
#include <vector>

namespace boxccd {

namespace {

constexpr double kNaN = std::numeric_limits<double>::quiet_NaN();
constexpr double kInf = std::numeric_limits<double>::infinity();

}  // namespace

RowBoxPath::RowBoxPath(const double *row) {
    std::copy(row, row + PathRow::kSize, row_);
    reach_ = reach_radius(row_ + PathRow::kBoxInFrame, row_ + PathRow::kHalfExtents);
    finite_ = std::all_of(row_, row_ + PathRow::kSize, [](double x) { return std::isfinite(x); });
}

void RowBoxPath::pose(double tau, double *X_WS) const { row_pose(row_, tau, X_WS); }

double RowBoxPath::fit(double lo, double hi, double *coeffs) const {
    // fit_path bounds the 3x3 part's error by err, so a point at distance r from
    // the frame's origin is off by at most err r; mapped back through the fitted
    // 3x3 part (|inverse| <= 1 / (1 - err)) that is the growth in the box's frame.
    const double err = fit_path(row_, lo, hi, coeffs);
    return err < 1.0 ? err * reach_ / (1.0 - err) : kInf;
}

int RowBoxPath::pieces(double fit_tolerance) const { return fit_pieces(row_, fit_tolerance); }

double RowBoxPath::travel(double lo, double hi) const {
    // Linear translation and a turn about the frame's origin at a constant rate:
    // a point's track over the piece is at most (hi - lo) (|d| + angle r) long.
    return 0.5 * (hi - lo) * (norm3(row_ + PathRow::kDisplacement) + std::fabs(row_[PathRow::kAngle]) * reach_);
}

double path_depth(const BoxPath &a, const BoxPath &b, double tau) {
    double X_WA[16], X_WB[16];
    a.pose(tau, X_WA);
    b.pose(tau, X_WB);
    return pose_depth(X_WA, a.half_extents(), X_WB, b.half_extents());
}

double path_separation(const BoxPath &a, const BoxPath &b, double tau, double *axis, double floor) {
    double X_WA[16], X_WB[16];
    a.pose(tau, X_WA);
    b.pose(tau, X_WB);
    return pose_separation(X_WA, a.half_extents(), X_WB, b.half_extents(), axis, floor);
}

double relative_move(const BoxPath &a, const BoxPath &b) {
    const double *ha = a.half_extents(), *hb = b.half_extents();
    const bool a_small = std::max({ha[0], ha[1], ha[2]}) < std::max({hb[0], hb[1], hb[2]});
    const BoxPath &small = a_small ? a : b, &large = a_small ? b : a;
    const double *h = small.half_extents();
    // The small box's frame in the large one's at tau: inverse(X_L) X_S (rigid).
    const auto relative = [&](double tau, double *R) {
        double L[16], S[16];
        large.pose(tau, L);
        small.pose(tau, S);
        for (int i = 0; i < 3; ++i)
            for (int j = 0; j < 4; ++j) {
                double x = 0.0;
                for (int k = 0; k < 3; ++k) x += L[4 * k + i] * (S[4 * k + j] - (j == 3 ? L[4 * k + 3] : 0.0));
                R[4 * i + j] = x;
            }
    };
    double R0[12], R1[12];
    relative(0.0, R0);
    relative(1.0, R1);
    double out = 0.0;
    for (int corner = 0; corner < 8; ++corner) {
        const double c[3] = {corner & 1 ? h[0] : -h[0], corner & 2 ? h[1] : -h[1], corner & 4 ? h[2] : -h[2]};
        double d2 = 0.0;
        for (int i = 0; i < 3; ++i) {
            double d = R1[4 * i + 3] - R0[4 * i + 3];
            for (int k = 0; k < 3; ++k) d += (R1[4 * i + k] - R0[4 * i + k]) * c[k];
            d2 += d * d;
        }
        out = std::fmax(out, std::sqrt(d2));
    }
    return out;
}

namespace {

// The first tau in (from, 1] at which depth(tau) >= target, for a depth that was
// depth_from at `from`: first_depth's look-ahead and bisection. depth(tau) may stop early
// below the target with any value at least the true depth. Between two samples below the
// target the depth can rise no faster than the boxes' points move (`rate` a unit of tau
// from either end); a gap where that bound reaches the target is split until it cannot
// (a fast box passing through a thin wall between two samples, out again at the second),
// with at most kGapSamples depth evaluations a gap.
template <class Depth>
double first_reach(const BoxPath &a, const BoxPath &b, double from, double target, double depth_from,
                   const Depth &depth) {
    const double span = 1.0 - from;
    const double need = target - std::fmax(depth_from, 0.0);
    // A point gets at most twice its travel about the middle from where it was at `from`.
    const double speed = 2.0 * (a.travel(from, 1.0) + b.travel(from, 1.0));
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
    const double rate = speed / span;
    // The first sample in the gap (l, r) (depths dl, dr below the target) at which the
    // depth reaches the target, left-first; the sample before it to `before`.
    const auto in_gap = [&](double l, double dl, double r, double dr, double &before) {
        int budget = kGapSamples;
        struct Gap {
            double l, dl, r, dr;
        };
        Gap stack[2 * kMaxDepthHalvings];
        int n = 0;
        stack[n++] = {l, dl, r, dr};
        while (n > 0) {
            const Gap g = stack[--n];
            if (0.5 * (g.dl + g.dr + rate * (g.r - g.l)) < target || g.r - g.l <= kDepthWidth || budget <= 0) continue;
            const double m = 0.5 * (g.l + g.r);
            if (!(m > g.l && m < g.r)) continue;
            --budget;
            const double dm = depth(m);
            if (dm >= target) {
                before = g.l;
                return m;
            }
            if (n + 2 > int(std::size(stack))) continue;
            stack[n++] = {m, dm, g.r, g.dr};
            stack[n++] = {g.l, g.dl, m, dm};
        }
        return kNaN;
    };
    double lo = k0 < kDepthLookAhead ? from + std::ldexp(span, -(k0 + 1)) : from, hi = kNaN;
    double last = from, d_last = std::isnan(depth_from) ? target : depth_from;  // (unknown: assume the worst)
    for (double step = std::ldexp(span, -k0);; step *= 2.0) {  // 2^-k of the rest of the step, k = k0 .. 0
        const double t = from + step;
        const double d = depth(t);
        if (d >= target) {
            hi = t;
            break;
        }
        hi = in_gap(std::fmax(last, lo), last < lo ? d_last + rate * (lo - last) : d_last, t, d, lo);
        if (!std::isnan(hi)) break;
        lo = last = t;
        d_last = d;
        if (!(step < span)) break;
    }
    if (std::isnan(hi)) return hi;
    for (int it = 0; it < kMaxDepthHalvings && hi - lo > kDepthWidth; ++it) {
        const double mid = 0.5 * (lo + hi);
        if (mid <= lo || mid >= hi) break;
        (depth(mid) >= target ? hi : lo) = mid;
    }
    return hi;
}

// The corner of box p (pose Xp, half extents hp) numbered k (bit j: + side along its axis
// j), in the world.
Vec3 corner_of(const double *Xp, const double *hp, unsigned k) {
    Vec3 c;
    for (int i = 0; i < 3; ++i) {
        c[i] = Xp[4 * i + 3];
        for (int j = 0; j < 3; ++j) c[i] += Xp[4 * i + j] * ((k >> j & 1u) ? hp[j] : -hp[j]);
    }
    return c;
}

// How deep point c is inside box q (pose Xq, half extents hq): its least distance to a
// face, negative outside; the face's axis to `axis` if asked.
double depth_in(const Vec3 &c, const double *Xq, const double *hq, int *axis = nullptr) {
    const Vec3 d{c[0] - Xq[3], c[1] - Xq[7], c[2] - Xq[11]};
    double depth = std::numeric_limits<double>::infinity();
    for (int j = 0; j < 3; ++j) {
        const double dj = hq[j] - std::fabs(Xq[j] * d[0] + Xq[4 + j] * d[1] + Xq[8 + j] * d[2]);
        if (dj < depth) {
            depth = dj;
            if (axis) *axis = j;
        }
    }
    return depth;
}

// The deepest of the corners of box p picked by `mask` inside box q (its number to
// `deepest`), -inf without one. With `apart`, the mask of the corners outside q by more
// than `gap` is written there.
double corners_in(const double *Xp, const double *hp, const double *Xq, const double *hq, unsigned mask,
                  unsigned *deepest = nullptr, double gap = 0.0, unsigned *apart = nullptr) {
    double most = -std::numeric_limits<double>::infinity();
    for (unsigned k = 0; k < 8; ++k) {
        if (!(mask >> k & 1u)) continue;
        const double depth = depth_in(corner_of(Xp, hp, k), Xq, hq);
        if (apart && depth < -gap) *apart |= 1u << k;
        if (depth > most) {
            most = depth;
            if (deepest) *deepest = k;
        }
    }
    return most;
}

}  // namespace

double first_depth(const BoxPath &a, const BoxPath &b, double from, double target, double depth_from) {
    if (!a.finite() || !b.finite() || !(from >= 0.0 && from <= 1.0) || std::isnan(target)) return kNaN;
    // The depth at tau, stopping below the target at the first axis that says so.
    const auto depth = [&](double tau) { return path_separation(a, b, tau, nullptr, target); };
    if (std::isnan(depth_from)) depth_from = path_depth(a, b, from);
    return first_reach(a, b, from, target, depth_from, depth);
}

CornerStrike first_corner_strike(const BoxPath &a, const BoxPath &b, double from, double gap, double target) {
    CornerStrike out;
    if (!a.finite() || !b.finite() || !(from >= 0.0 && from <= 1.0) || std::isnan(target)) return out;
    const double *ha = a.half_extents(), *hb = b.half_extents();
    double Xa[16], Xb[16];
    a.pose(from, Xa);
    b.pose(from, Xb);
    unsigned of_a = 0, of_b = 0;  // the corners of a apart from b, and of b from a
    corners_in(Xa, ha, Xb, hb, 0xffu, nullptr, gap, &of_a);
    corners_in(Xb, hb, Xa, ha, 0xffu, nullptr, gap, &of_b);
    if (!of_a && !of_b) return out;
    unsigned ka = 0, kb = 0;
    double da = 0.0, db = 0.0;
    const auto depth = [&](double tau) {
        a.pose(tau, Xa);
        b.pose(tau, Xb);
        da = corners_in(Xa, ha, Xb, hb, of_a, &ka);
        db = corners_in(Xb, hb, Xa, ha, of_b, &kb);
        return std::fmax(da, db);
    };
    out.tau = first_reach(a, b, from, target, 0.0, depth);
    if (std::isnan(out.tau)) return out;
    depth(out.tau);
    out.of_a = da >= db;
    out.corner = static_cast<int>(out.of_a ? ka : kb);
    return out;
}

Hit corner_contact(const BoxPath &a, const BoxPath &b, const CornerStrike &strike) {
    Hit hit;
    if (std::isnan(strike.tau)) return hit;
    double Xa[16], Xb[16];
    a.pose(strike.tau, Xa);
    b.pose(strike.tau, Xb);
    const double *Xp = strike.of_a ? Xa : Xb, *Xq = strike.of_a ? Xb : Xa;
    const double *hp = strike.of_a ? a.half_extents() : b.half_extents();
    const double *hq = strike.of_a ? b.half_extents() : a.half_extents();
    const auto k = static_cast<unsigned>(strike.corner);
    const Vec3 c = corner_of(Xp, hp, k);
    int j = 0;
    depth_in(c, Xq, hq, &j);
    const Vec3 axis{Xq[j], Xq[4 + j], Xq[8 + j]};
    const double side = dot3(axis, Vec3{c[0] - Xq[3], c[1] - Xq[7], c[2] - Xq[11]}) >= 0.0 ? 1.0 : -1.0;
    // The face's outward normal points at the corner: from A towards B it is that normal
    // for a corner of B on a face of A, its opposite for a corner of A on a face of B.
    const double sign = strike.of_a ? -side : side;
    for (int i = 0; i < 3; ++i) hit.normal[i] = sign * axis[i];
    hit.point = c;
    hit.outcome = Outcome::Hit;
    hit.t = hit.s = strike.tau;
    // The VO facets (a face of B, a vertex of A) are 6 .. 11, the OV ones 0 .. 5; even: the
    // normal along the face's axis.
    hit.facet = (strike.of_a ? 6 : 0) + 2 * j + (sign < 0.0 ? 1 : 0);
    auto &corner = strike.of_a ? hit.feat_a : hit.feat_b;
    auto &face = strike.of_a ? hit.feat_b : hit.feat_a;
    for (int i = 0; i < 3; ++i) {
        corner[i] = static_cast<int8_t>((k >> i & 1u) ? 1 : -1);
        face[i] = static_cast<int8_t>(i == j ? static_cast<int>(side) : 0);
    }
    return hit;
}

bool presses_in(const BoxPath &a, const BoxPath &b, double penetration, double creep, double depth0) {
    const double *ha = a.half_extents(), *hb = b.half_extents();
    const double thin = std::min({ha[0], ha[1], ha[2], hb[0], hb[1], hb[2]});
    if (std::isnan(depth0)) depth0 = path_depth(a, b, 0.0);
    const double target = std::max(depth0, 0.0) + std::max(penetration, creep * thin);
    return !std::isnan(first_depth(a, b, 0.0, target, depth0));
}

void path_bounds(const BoxPath &path, int n, double *lo, double *hi) {
    const double *h = path.half_extents();
    for (int i = 0; i < 3; ++i) {
        lo[i] = kInf;
        hi[i] = -kInf;
    }
    for (int k = 0; k < n; ++k) {
        const double a = double(k) / n, b = double(k + 1) / n;
        double X[16];
        path.pose(0.5 * (a + b), X);
        const double grow = path.travel(a, b);
        for (int i = 0; i < 3; ++i) {
            const double e = std::fabs(X[4 * i]) * h[0] + std::fabs(X[4 * i + 1]) * h[1] + std::fabs(X[4 * i + 2]) * h[2];
            lo[i] = std::fmin(lo[i], X[4 * i + 3] - e - grow);
            hi[i] = std::fmax(hi[i], X[4 * i + 3] + e + grow);
        }
    }
}

namespace {

// One solve of the two boxes on their quadratic fits over [lo, hi] (the Hit's t is
// on the piece's own [0, 1]), each box grown by its fit's growth and by `extra`
// times its reach; `fitted` false (and no solve) when a fit is not proven.
Hit solve_piece(const BoxPath &a, const BoxPath &b, double lo, double hi, double extra, const Tolerances &tol,
                bool geometry, bool &fitted) {
    double coeffs_a[48], coeffs_b[48];
    const double grow_a = a.fit(lo, hi, coeffs_a) + extra * a.reach(), grow_b = b.fit(lo, hi, coeffs_b) + extra * b.reach();
    fitted = grow_a < kInf && grow_b < kInf;
    for (int i = 0; i < 48; ++i) fitted = fitted && std::isfinite(coeffs_a[i]) && std::isfinite(coeffs_b[i]);
    if (!fitted) return Hit{};
    double lo_a[3], hi_a[3], lo_b[3], hi_b[3];
    for (int i = 0; i < 3; ++i) {
        hi_a[i] = a.half_extents()[i] + grow_a;
        lo_a[i] = -hi_a[i];
        hi_b[i] = b.half_extents()[i] + grow_b;
        lo_b[i] = -hi_b[i];
    }
    Query query({lo_a, hi_a, coeffs_a}, {lo_b, hi_b, coeffs_b}, 0.0, 1.0, tol);
    return query.solve(geometry);
}

}  // namespace

Hit window_contact(const BoxPath &a, const BoxPath &b, double lo, double hi, const Tolerances &tol) {
    Hit h;
    if (!a.finite() || !b.finite()) {
        h.outcome = Outcome::NonFinite;
        return h;
    }
    if (hi - lo < kMinWindow) lo = std::max(0.0, hi - kMinWindow);
    bool fitted;
    h = solve_piece(a, b, lo, hi, kMinWindow, tol, true, fitted);
    if (!fitted) {
        h.outcome = Outcome::StepCap, h.t = lo, h.s = kNaN;
        return h;
    }
    if (h.contact()) h.t = lo + h.t * (hi - lo);
    return h;
}

double first_touch(const BoxPath &a, const BoxPath &b, double fit_tolerance, const Tolerances &tol, long &solves,
                   Outcome &outcome, double depth0, Hit *contact) {
    outcome = Outcome::Separated;
    if (contact) *contact = Hit{};
    if (!a.finite() || !b.finite()) {
        outcome = Outcome::NonFinite;
        if (contact) contact->outcome = outcome;
        return kNaN;
    }
    if (std::isnan(depth0)) depth0 = path_depth(a, b, 0.0);
    // Touching at the start: the fitted motions, exact there, touch too (the first
    // piece's solve, asked for the contact, describes it).
    const bool at_start = depth0 >= 0.0;
    if (at_start && !contact) {
        outcome = Outcome::Initial;
        return 0.0;
    }
    const int n = std::max(a.pieces(fit_tolerance), b.pieces(fit_tolerance));
    for (int k = 0; k < n; ++k) {  // pieces in order: the first that touches has the first touch
        const double lo = double(k) / n, hi = double(k + 1) / n;
        bool fitted;
        Hit h = solve_piece(a, b, lo, hi, 0.0, tol, contact != nullptr, fitted);
        // No proven fit (too fast even for kMaxFitPieces pieces, or a fit overflowed): early,
        // never late, and not proven a contact.
        if (!fitted) {
            outcome = at_start ? Outcome::Initial : Outcome::StepCap;
            if (contact) contact->outcome = outcome, contact->t = lo, contact->s = at_start ? 0.0 : kNaN;
            return lo;
        }
        ++solves;
        if (h.contact() || at_start) {
            // A degraded outcome (early, not proven) stays what it is; a touch at the
            // start is one whatever the solve says.
            if (at_start) h.outcome = Outcome::Initial, h.s = 0.0;
            h.t = at_start ? 0.0 : lo + h.t * (hi - lo);
            outcome = h.outcome;
            if (contact) *contact = h;
            return h.t;
        }
    }
    return kNaN;
}

}  // namespace boxccd
