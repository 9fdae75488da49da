// Conservative advancement on fixed separating axes. See culling.hpp.
#include "solver/culling.hpp"

#include <algorithm>
#include <limits>

namespace boxccd {

Sample sample_at(const Pair &pair, double s) {
    Sample a;
    a.s = s;
    for (int g = 0; g < 6; ++g) {
        a.g[g] = pair.g[g].at(s);
        a.dg[g] = pair.g[g].derivative(s);
    }
    a.d = pair.d.at(s);
    a.dd = pair.d.derivative(s);
    return a;
}

constexpr double kTiny = std::numeric_limits<double>::min();

SeparatingAxis most_separating(const Pair &pair, const Sample &at) {
    AxesAt v;
    axes_at(pair, at.g, at.d, v);
    SeparatingAxis best;
    // (gap / |n|)^2 ranks the axes without a sqrt; written without branches (which
    // axis wins is data, and mispredicted branches cost more than 15 divisions).
    const double margin = pair.unit_margin;
    double best_gap2 = margin * margin;
    int best_ax = -1;
    for (int ax = 0; ax < 15; ++ax) {
        const double gap = std::fabs(v.nd[ax]) - v.support[ax];
        const double separates = static_cast<double>((gap > 0.0) & v.direction[ax]);
        // nn2 > 0 where there is a direction; the floor only keeps 0 / 0 out of the rest.
        const double nn2 = v.nn2[ax] > kTiny ? v.nn2[ax] : kTiny;
        const double gap2 = gap * gap / nn2 * separates;
        const bool better = gap2 > best_gap2;
        best_gap2 = better ? gap2 : best_gap2;
        best_ax = better ? ax : best_ax;
    }
    if (best_ax >= 0) {
        best.axis = best_ax;
        best.facet = 2 * best_ax + (v.nd[best_ax] < 0.0);
        best.n = axis_normal(at.g, best.axis);
        best.len = std::sqrt(v.nn2[best.axis]);
        best.gap = std::sqrt(best_gap2);
    }
    return best;
}

SeparatingAxis axis_at(const Pair &pair, const Sample &at, int ax) {
    SeparatingAxis out;
    const int g1 = axis_generator(ax, 0), g2 = axis_generator(ax, 1);
    const Vec3 n = cross3(at.g[g1], at.g[g2]);
    const double nn2 = dot3(n, n), nd = dot3(n, at.d);
    if (!(nn2 > kParallel2 * dot3(at.g[g1], at.g[g1]) * dot3(at.g[g2], at.g[g2]))) return out;
    // The axis' own generators add only their rounding (n.g is zero for them):
    // summed without a branch, that makes the gap a few eps smaller, never larger.
    double support = 0.0;
    for (int g = 0; g < 6; ++g) support += pair.h[g] * std::fabs(dot3(n, at.g[g]));
    const double len = std::sqrt(nn2), gap = (std::fabs(nd) - support) / len;
    if (!(gap > pair.unit_margin)) return out;
    out.axis = ax;
    out.facet = 2 * ax + (nd < 0.0);
    out.n = n;
    out.len = len;
    out.gap = gap;
    return out;
}

// The centre line d at the sample as a fixed direction: no BMS axis (axis -1),
// but as good a separating direction as any for boxes far apart, at the cost of
// six projections instead of 15 axes.
SeparatingAxis centre_line(const Pair &pair, const Sample &at) {
    SeparatingAxis out;
    const double len = norm3(at.d);
    double support = 0.0;
    for (int g = 0; g < 6; ++g) support += pair.h[g] * std::fabs(dot3(at.d, at.g[g]));
    const double gap = len > 0.0 ? (len * len - support) / len : 0.0;
    if (!(gap > pair.unit_margin)) return out;
    out.n = at.d;
    out.len = len;
    out.gap = gap;
    return out;
}

namespace {

// The first root in (lo, hi] of q(x) = A + B x + C x^2, given q(lo) > 0 (lo where
// it is not: on an axis found to separate by a hair more than the margin, rounding
// can leave the bound at or below zero, and the contact may then be at lo); NaN if
// q > 0 on all of it. Closed form (the stable one); the caller shrinks it by a few
// eps, which the margin covers.
double first_root(double A, double B, double C, double lo, double hi) {
    const auto q = [&](double x) { return A + x * (B + x * C); };
    if (!(q(lo) > 0.0)) return lo;
    if (q(hi) > 0.0) {
        // Still positive at hi: a root inside needs a convex dip below zero.
        if (!(C > 0.0)) return kNoRoot;
        const double v = -B / (2.0 * C);
        if (!(v > lo && v < hi) || q(v) > 0.0) return kNoRoot;
        hi = v;
    }
    // Exactly one crossing in (lo, hi].
    if (C == 0.0) return B < 0.0 ? std::clamp(-A / B, lo, hi) : hi;
    const double disc = B * B - 4.0 * A * C;
    if (!(disc >= 0.0)) return lo;  // rounding: the crossing is a double root; stay early
    const double sq = std::sqrt(disc);
    const double qq = -0.5 * (B + (B >= 0.0 ? sq : -sq));
    double r1 = qq / C, r2 = qq != 0.0 ? A / qq : r1;
    if (r1 > r2) std::swap(r1, r2);
    const double r = r1 > lo ? r1 : r2;
    return std::clamp(r, lo, hi);
}

}  // namespace

// The bound: along fixed n, with sigma the sign of n.d at s and tau = s' - s,
//   n.d(s + tau) = a_d + b_d tau + c_d tau^2       (exact: d is quadratic)
//   |n.g(s + tau)| <= |a + b tau| + |c| tau^2      (each generator)
// so gap >= sigma (a_d + b_d tau + c_d tau^2) - sum_g h_g (|a + b tau| + |c| tau^2),
// a piecewise quadratic whose kinks are where a + b tau changes sign. It matches
// the gap's value and slope at tau = 0, which makes the advancement converge
// geometrically; it is exact for boxes that do not turn.
double apart_until(const Pair &pair, const Sample &at, const SeparatingAxis &axis, double hi) {
    const Vec3 &n = axis.n;
    const double nd = dot3(n, at.d);
    const double sigma = std::copysign(1.0, nd);
    double A = sigma * nd - axis.len * pair.unit_margin;
    double B = sigma * dot3(n, at.dd), C = sigma * dot3(n, pair.d.c[2]);
    // Kinks: where |a + b tau| turns back up (tau = -a / b, a + b tau shrinking), with
    // the change of A and B there; +inf where it does not. Branch-free: the signs
    // are data, and mispredicted branches cost more than the arithmetic.
    // In passes over arrays (the six divisions pair up in vector registers).
    double a[6], b[6], c[6], kink[6], dA[6], dB[6];
    for (int g = 0; g < 6; ++g) {
        a[g] = dot3(n, at.g[g]);
        b[g] = dot3(n, at.dg[g]);
        c[g] = dot3(n, pair.g[g].c[2]);
    }
    for (int g = 0; g < 6; ++g) kink[g] = -a[g] / b[g];  // all six (b = 0 gives inf or NaN, not used)
    for (int g = 0; g < 6; ++g) {
        const double sg = std::copysign(1.0, a[g] != 0.0 ? a[g] : b[g]);  // the sign of a + b tau just after 0
        dA[g] = pair.h[g] * sg * a[g];
        dB[g] = pair.h[g] * sg * b[g];
        if (!(dB[g] < 0.0)) kink[g] = std::numeric_limits<double>::infinity();
    }
    for (int g = 0; g < 6; ++g) {
        A -= dA[g];
        B -= dB[g];
        C -= pair.h[g] * std::fabs(c[g]);
        dA[g] *= 2.0;
        dB[g] *= 2.0;
    }
    // Segment by segment, from tau = 0 up to the next kink, until a root.
    const double span = hi - at.s;
    for (double lo = 0.0;;) {
        int next = 0;
        for (int g = 1; g < 6; ++g) next = kink[g] < kink[next] ? g : next;
        const double end = std::min(kink[next], span);
        if (end > lo) {
            const double r = first_root(A, B, C, lo, end);
            if (!std::isnan(r)) return at.s + r * (1.0 - 8.0 * kEps);
        }
        if (!(kink[next] < span)) return hi;
        A += dA[next];
        B += dB[next];
        kink[next] = std::numeric_limits<double>::infinity();
        lo = std::max(lo, end);
    }
}

// The most separating axis is searched at the start; later steps keep the axis
// they had (its normal at the new time: one axis instead of 15) while it still
// separates by more than the handover distance, and search again when it does not,
// so the handover happens only where no axis separates by more.
Culling advance_on_axes(const Pair &pair, double from, double min_window) {
    Culling out;
    const auto window = [&](double start, double step) {
        out.start = start;
        out.end = std::min(1.0, start + std::max(kWindow * step, min_window));
        return out;
    };
    const double handover = kHandover * pair.size;
    double s = from, step = 1.0 - from;  // the last step (the whole rest before the first)
    int kept = -1;                       // the axis of the last step
    bool use_centre = true;
    for (int k = 0;; ++k) {
        const Sample at = sample_at(pair, s);
        SeparatingAxis axis;
        if (kept >= 0) axis = axis_at(pair, at, kept);
        if (kept < 0 && use_centre) axis = centre_line(pair, at);
        use_centre = use_centre && axis.len > 0.0 && axis.gap > kCentreLine * pair.size;
        if (axis.len == 0.0 || axis.gap <= handover) axis = most_separating(pair, at);
        if (axis.len == 0.0) return window(s, step);  // touching or overlapping at s: the contact is at s
        const double r = apart_until(pair, at, axis, 1.0);
        if (r >= 1.0) {
            out.apart = true;
            return out;
        }
        out.facet = axis.facet;
        // Near the contact (or no longer advancing): the BMS search takes over
        // from r, where the same facet is still the one most likely to separate.
        if (!(r > s)) return window(r, 1.0);
        if (axis.gap <= handover || k + 1 == kMaxCullSteps) return window(r, r - s);
        kept = axis.axis;
        step = r - s;
        s = r;
    }
}

}  // namespace boxccd
