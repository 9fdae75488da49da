// The solver's entry points: input checks, the first-contact driver (culling,
// then the BMS search window by window), contact geometry, the BMS planes.
#include "solver/box_ccd.hpp"

#include <algorithm>
#include <cstdio>

#include "solver/advance.hpp"
#include "solver/culling.hpp"
#include "solver/route.hpp"

namespace boxccd {

namespace {

std::string num(double v) {
    char buf[40];
    std::snprintf(buf, sizeof buf, "%.17g", v);
    return buf;
}

const char *kAxisName[3] = {"x", "y", "z"};

// Coefficient (k, r, c) of a row-major (3, 4, 4) array.
inline double coef(const double *C, int k, int r, int c) { return C[k * 16 + r * 4 + c]; }

// Whether all n values are finite: x * 0 is 0 for a finite x and NaN for inf or
// NaN, so one branch-free pass (four independent sums) answers for the common
// case; the callers then look for the culprit only to name it.
bool all_finite(const double *x, int n) {
    double acc[4] = {0.0, 0.0, 0.0, 0.0};
    int i = 0;
    for (; i + 4 <= n; i += 4)
        for (int k = 0; k < 4; ++k) acc[k] += x[i + k] * 0.0;
    for (; i < n; ++i) acc[0] += x[i] * 0.0;
    return (acc[0] + acc[1]) + (acc[2] + acc[3]) == 0.0;
}

}  // namespace

void validate(const Tolerances &tol) {
    if (!(tol.gap_rel >= 0.0 && tol.gap_rel <= 0.1))
        throw ToleranceError("Tolerances.gap_rel is " + num(tol.gap_rel) + "; expected a number in [0, 0.1]");
    if (!(tol.rounding >= 0.0 && tol.rounding <= 1e10))
        throw ToleranceError("Tolerances.rounding is " + num(tol.rounding) + "; expected a number in [0, 1e+10]");
    if (tol.max_steps < 1)
        throw ToleranceError("Tolerances.max_steps is " + std::to_string(tol.max_steps) +
                             "; expected an integer >= 1");
}

void check_box(const double *lo, const double *hi, const std::string &name) {
    if (!(all_finite(lo, 3) && all_finite(hi, 3)))
        for (int i = 0; i < 3; ++i) {
            if (!std::isfinite(lo[i]))
                throw NonFiniteError(name + ".lo[" + std::to_string(i) + "] is " + num(lo[i]) +
                                     "; expected a finite number");
            if (!std::isfinite(hi[i]))
                throw NonFiniteError(name + ".hi[" + std::to_string(i) + "] is " + num(hi[i]) +
                                     "; expected a finite number");
        }
    for (int i = 0; i < 3; ++i)
        if (!(lo[i] < hi[i]))
            throw BoxError(name + ": lo[" + std::to_string(i) + "] = " + num(lo[i]) + " >= hi[" +
                           std::to_string(i) + "] = " + num(hi[i]) + "; expected lo < hi on the " +
                           kAxisName[i] + " axis (a box has positive extent)");
}

void check_motion(const double *C, const std::string &name) {
    if (!all_finite(C, 48))
        for (int k = 0; k < 3; ++k)
            for (int r = 0; r < 4; ++r)
                for (int c = 0; c < 4; ++c) {
                    const double v = coef(C, k, r, c);
                    if (!std::isfinite(v))
                        throw NonFiniteError(name + ".coeffs[" + std::to_string(k) + ", " + std::to_string(r) +
                                             ", " + std::to_string(c) + "] is " + num(v) +
                                             "; expected a finite number");
                }
    for (int k = 0; k < 3; ++k)
        for (int c = 0; c < 4; ++c) {
            const double want = (k == 0 && c == 3) ? 1.0 : 0.0;
            const double v = coef(C, k, 3, c);
            if (v != want)
                throw MotionError(name + ".coeffs[" + std::to_string(k) + ", 3, " + std::to_string(c) +
                                  "] is " + num(v) + "; expected " + num(want) +
                                  " (the bottom row of an affine motion is (0, 0, 0, 1) in coeffs[0] and zero in "
                                  "coeffs[1] and coeffs[2])");
        }
}

void check_time_range(double t0, double t1) {
    if (!std::isfinite(t0) || !std::isfinite(t1))
        throw TimeRangeError("t_range = (" + num(t0) + ", " + num(t1) + ") is not finite");
    if (!(t0 < t1))
        throw TimeRangeError("t_range = (" + num(t0) + ", " + num(t1) +
                             ") is empty or inverted; expected t_range[0] < t_range[1]");
    if (!std::isfinite(t1 - t0))
        throw TimeRangeError("t_range = (" + num(t0) + ", " + num(t1) + ") is too long to represent");
}

namespace {
const Tolerances &validated(const Tolerances &tol) {
    validate(tol);
    return tol;
}
}  // namespace

Query::Query(const BoxInput &a, const BoxInput &b, double t0, double t1, const Tolerances &tol)
    : pair_(a, b, t0, t1, validated(tol)), cof_(pair_) {}

std::vector<double> Query::sections() { return route_division(pair_, cof_); }

// Boxes that do not turn have constant axes and no octant switch: the BMS
// search runs on the whole range at once. Turning boxes alternate: conservative
// advancement on fixed axes up to a short window, the BMS search on it, and back
// to the advancement if the window stays apart.
Hit Query::solve(bool want_geometry) {
    Hit hit;
    SearchState state;
    FixedAxes fixed;
    double s = 0.0;
    bool contact = false;
    if (!pair_.turning) {
        fixed_axes(pair_, fixed);
        state.fixed = &fixed;
        contact = search(pair_, cof_, 0.0, 1.0, state, s);
    } else {
        double from = 0.0, min_window = 0.0;
        for (int k = 0; k < kMaxWindows; ++k) {
            const Culling c = advance_on_axes(pair_, from, min_window);
            if (c.apart) break;
            state.separating = c.facet;
            contact = search(pair_, cof_, c.start, c.end, state, s);
            if (contact || c.end >= 1.0) break;
            from = c.end;
            min_window = 2.0 * (c.end - c.start);
            if (k + 1 == kMaxWindows) {  // report contact where the search stopped: early, never late
                state.capped = contact = true;
                s = from;
            }
        }
    }
    if (!contact) return hit;
    hit.s = s;
    hit.t = pair_.time(s);
    int8_t sig[6];
    hit.facet = contact_facet(pair_, state, s, sig);
    const bool jumped = state.last >= 0 && state.last_at == s;
    if (state.capped) hit.outcome = Outcome::StepCap;
    else if (jumped && state.clustered) hit.outcome = Outcome::ClusteredRoots;
    else hit.outcome = s == 0.0 ? Outcome::Initial : Outcome::Hit;
    if (want_geometry) contact_geometry(sig, hit);
    return hit;
}

void Query::contact_geometry(const int8_t *sig, Hit &hit) {
    const int ax = hit.facet / 2;
    const double s = hit.s;
    const Pair &p = pair_;
    Vec3 gv[6];
    for (int g = 0; g < 6; ++g) gv[g] = p.g[g].at(s);
    const Vec3 n = cross3(gv[axis_generator(ax, 0)], gv[axis_generator(ax, 1)]);
    const double sgn = hit.facet % 2 == 0 ? 1.0 : -1.0, nn = norm3(n);
    for (int r = 0; r < 3; ++r) hit.normal[r] = nn > 0.0 ? sgn * n[r] / nn : 0.0;
    facet_features(hit.facet, sig, hit.feat_a.data(), hit.feat_b.data());
    // Support points of each box's feature (local frame): centre + the signed half edges.
    Vec3 pa = p.cA.at(s), pb = p.cB.at(s);
    for (int i = 0; i < 3; ++i)
        for (int r = 0; r < 3; ++r) {
            pa[r] += hit.feat_a[i] * p.h[i] * gv[i][r];
            pb[r] += hit.feat_b[i] * p.h[3 + i] * gv[3 + i][r];
        }
    Vec3 local;
    if (axis_kind(ax) == Kind::OV) {
        local = pb;  // face of A, vertex of B
    } else if (axis_kind(ax) == Kind::VO) {
        local = pa;  // face of B, vertex of A
    } else {
        // Edge-edge: closest points of the two edge lines, clamped to the edges.
        const int i = (ax - 6) / 3, j = (ax - 6) % 3;
        const Vec3 &u = gv[i], &v = gv[3 + j];
        const Vec3 w = {pa[0] - pb[0], pa[1] - pb[1], pa[2] - pb[2]};
        const double uu = dot3(u, u), vv = dot3(v, v), uv = dot3(u, v), uw = dot3(u, w), vw = dot3(v, w);
        const double den = uu * vv - uv * uv;
        double la = 0.0, mu = 0.0;
        if (den > kParallel2 * uu * vv) {  // parallel edges: any point of the overlap; take the centres
            la = (uv * vw - vv * uw) / den;
            mu = (uu * vw - uv * uw) / den;
        }
        la = std::clamp(la, -p.h[i], p.h[i]);
        mu = std::clamp(mu, -p.h[3 + j], p.h[3 + j]);
        for (int r = 0; r < 3; ++r) local[r] = 0.5 * (pa[r] + la * u[r] + pb[r] + mu * v[r]);
    }
    for (int r = 0; r < 3; ++r) hit.point[r] = p.origin[r] + local[r];
}

void Query::planes(double s, double *normals, double *offsets, int8_t *feat_a, int8_t *feat_b) {
    // The section of the full route division that contains s; its topology at its middle.
    Route route(pair_, cof_);
    double lo = 0.0;
    while (route.boundary() <= s && route.boundary() < 1.0) {
        lo = route.boundary();
        route.pass(lo);
    }
    const double mid = 0.5 * (lo + route.boundary());
    Vec3 gs[6];
    for (int g = 0; g < 6; ++g) gs[g] = pair_.g[g].at(mid);
    Vec3 gs_s[6];
    for (int g = 0; g < 6; ++g) gs_s[g] = pair_.g[g].at(s);
    AxesAt v;
    axes_at(pair_, gs_s, pair_.d.at(s), v);
    for (int k = 0; k < 30; ++k) {
        const int ax = k / 2;
        const double sgn = k % 2 == 0 ? 1.0 : -1.0;
        const Vec3 n = axis_normal(gs_s, ax);
        const double nn = norm3(n);
        for (int r = 0; r < 3; ++r) normals[3 * k + r] = sgn * n[r] / nn;
        // D = A - B does not move with the shared translation: offsets need no origin.
        offsets[k] = (v.support[ax] - sgn * v.nd[ax]) / nn;
        int8_t sig[6];
        axis_signs(ax, gs, sig);
        facet_features(k, sig, feat_a + 3 * k, feat_b + 3 * k);
    }
}

}  // namespace boxccd
