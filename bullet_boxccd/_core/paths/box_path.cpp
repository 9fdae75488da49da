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
    const double *X_CS = row_ + PathRow::kBoxInFrame;
    const double t[3] = {X_CS[3], X_CS[7], X_CS[11]};
    reach_ = norm3(t) + norm3(row_ + PathRow::kHalfExtents);
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

double path_separation(const BoxPath &a, const BoxPath &b, double tau, double *axis) {
    double X_WA[16], X_WB[16];
    a.pose(tau, X_WA);
    b.pose(tau, X_WB);
    return pose_separation(X_WA, a.half_extents(), X_WB, b.half_extents(), axis);
}

double first_depth(const BoxPath &a, const BoxPath &b, double from, double target, int budget) {
    if (!a.finite() || !b.finite() || !(from >= 0.0 && from <= 1.0) || std::isnan(target)) return kNaN;
    if (path_depth(a, b, from) >= target) return from;
    // Depth-first over halved pieces, earliest first: a piece is ruled out when the
    // depth at its middle plus both boxes' travel over it stays below target. Once a
    // piece no wider than kDepthNarrow reaches the target at its middle, the crossing
    // between its start and its middle is found by bisection (constants.hpp).
    struct Piece {
        double lo, hi;
    };
    std::vector<Piece> stack{{from, 1.0}};
    while (!stack.empty()) {
        const Piece p = stack.back();
        stack.pop_back();
        if (--budget < 0) return p.lo;
        const double mid = 0.5 * (p.lo + p.hi);
        const double depth = path_depth(a, b, mid);
        if (depth >= target && p.hi - p.lo <= kDepthNarrow) {
            double lo = p.lo, hi = mid;
            while (hi - lo > kDepthPieceWidth) {
                const double m = 0.5 * (lo + hi);
                if (m <= lo || m >= hi) break;
                (path_depth(a, b, m) >= target ? hi : lo) = m;
            }
            return hi;
        }
        if (p.hi - p.lo <= kDepthPieceWidth) continue;
        if (depth + a.travel(p.lo, p.hi) + b.travel(p.lo, p.hi) < target) continue;
        stack.push_back({mid, p.hi});
        stack.push_back({p.lo, mid});
    }
    return kNaN;
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
        double coeffs_a[48], coeffs_b[48];
        const double grow_a = a.fit(lo, hi, coeffs_a), grow_b = b.fit(lo, hi, coeffs_b);
        // No proven fit (too fast even for 64 pieces, or a fit overflowed): early, never late.
        bool fitted = grow_a < kInf && grow_b < kInf;
        for (int i = 0; i < 48; ++i) fitted = fitted && std::isfinite(coeffs_a[i]) && std::isfinite(coeffs_b[i]);
        if (!fitted) {  // a cap reached (kMaxFitPieces): early, not proven a contact
            outcome = at_start ? Outcome::Initial : Outcome::StepCap;
            if (contact) contact->outcome = outcome, contact->t = lo, contact->s = at_start ? 0.0 : kNaN;
            return lo;
        }
        double lo_a[3], hi_a[3], lo_b[3], hi_b[3];
        for (int i = 0; i < 3; ++i) {
            hi_a[i] = a.half_extents()[i] + grow_a;
            lo_a[i] = -hi_a[i];
            hi_b[i] = b.half_extents()[i] + grow_b;
            lo_b[i] = -hi_b[i];
        }
        Query query({lo_a, hi_a, coeffs_a}, {lo_b, hi_b, coeffs_b}, 0.0, 1.0, tol);
        Hit h = query.solve(contact != nullptr);
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
