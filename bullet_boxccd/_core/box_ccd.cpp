// The BMS solver: route division, topology per section, first contact.
// The file comment of box_ccd.hpp maps the seed's symbols to this code.
#include "box_ccd.hpp"

#include <algorithm>
#include <cstdio>

namespace boxccd {

namespace {

constexpr double kNone = std::numeric_limits<double>::infinity();

std::string num(double v) {
    char buf[40];
    std::snprintf(buf, sizeof buf, "%.17g", v);
    return buf;
}

const char *kAxisName[3] = {"x", "y", "z"};

using Vec = std::array<double, 3>;
double dot3(const Vec &u, const Vec &v) { return u[0] * v[0] + u[1] * v[1] + u[2] * v[2]; }
double norm3(const Vec &v) { return std::sqrt(dot3(v, v)); }
Vec cross3(const Vec &a, const Vec &b) {
    return {a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0]};
}

// Coefficient (k, r, c) of a row-major (3, 4, 4) array.
inline double coef(const double *C, int k, int r, int c) { return C[k * 16 + r * 4 + c]; }

// Entry (r, c) of M(t0 + w s) as a polynomial in s.
Poly entry_in_s(const double *C, int r, int c, double t0, double w) {
    const double c0 = coef(C, 0, r, c), c1 = coef(C, 1, r, c), c2 = coef(C, 2, r, c);
    Poly p{};
    p.deg = 2;
    p.c[0] = c0 + t0 * (c1 + t0 * c2);
    p.c[1] = (c1 + 2.0 * c2 * t0) * w;
    p.c[2] = c2 * w * w;
    return p;
}

// Degree class of a polynomial vector: 0 when every entry is constant (a box
// that only translates has constant edge directions), else its nominal degree.
int degree_class(const PVec &v, int nominal) {
    for (const Poly &p : v.x)
        for (int i = 1; i <= p.deg; ++i)
            if (p.c[i] != 0.0) return nominal;
    return 0;
}

// a x b and a . b with the products a constant operand does not need skipped
// (the same values: the skipped terms are exact zeros). Degrees: a, b in {0, 2}
// for cross; a in {0, 2, 4} and b in {0, 2} for dot.
PVec cross_by_degree(const PVec &a, int da, const PVec &b, int db) {
    if (da == 0) return db == 0 ? cross<0, 0>(a, b) : cross<0, 2>(a, b);
    return db == 0 ? cross<2, 0>(a, b) : cross<2, 2>(a, b);
}
Poly dot_by_degree(const PVec &a, int da, const PVec &b, int db) {
    switch (da) {
        case 0: return db == 0 ? dot<0, 0>(a, b) : dot<0, 2>(a, b);
        case 2: return db == 0 ? dot<2, 0>(a, b) : dot<2, 2>(a, b);
        default: return db == 0 ? dot<4, 0>(a, b) : dot<4, 2>(a, b);
    }
}

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

bool finite_poly(const Poly &p) {
    for (int i = 0; i <= p.deg; ++i)
        if (!std::isfinite(p.c[i])) return false;
    return true;
}

}  // namespace

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

Problem::Problem(const BoxInput &a, const BoxInput &b, double t0_, double t1_, const Tolerances &tol)
    : t0(t0_), t1(t1_), tol_(tol) {
    const double w = t1 - t0;
    const BoxInput *box[2] = {&a, &b};
    PVec centre[2];
    dmag_ = 0.0;
    for (int q = 0; q < 2; ++q) {
        const BoxInput &bx = *box[q];
        for (int i = 0; i < 3; ++i) {
            for (int r = 0; r < 3; ++r) g_[3 * q + i].x[r] = entry_in_s(bx.coeffs, r, i, t0, w);
            h_[3 * q + i] = 0.5 * (bx.hi[i] - bx.lo[i]);
        }
        for (int r = 0; r < 3; ++r) {
            Poly c = entry_in_s(bx.coeffs, r, 3, t0, w);
            dmag_ += c.magnitude();
            for (int i = 0; i < 3; ++i) axpy(c, 0.5 * (bx.lo[i] + bx.hi[i]), g_[3 * q + i].x[r]);
            centre[q].x[r] = c;
        }
        for (int i = 0; i < 3; ++i) {
            gmag_[3 * q + i] = g_[3 * q + i].magnitude();
            dmag_ += std::fabs(0.5 * (bx.lo[i] + bx.hi[i])) * gmag_[3 * q + i];
        }
    }
    cA_ = centre[0];
    cB_ = centre[1];
    for (int r = 0; r < 3; ++r) d_.x[r] = cB_.x[r] - cA_.x[r];
    size_ = hmag_ = 0.0;
    for (int g = 0; g < 6; ++g) {
        hmag_ += h_[g] * gmag_[g];
        size_ += h_[g] * norm3(g_[g].at2(0.5));
    }
    for (int g = 0; g < 6; ++g) gdeg_[g] = degree_class(g_[g], 2);
    ddeg_ = degree_class(d_, 2);
    turning_ = gdeg_[0] | gdeg_[1] | gdeg_[2] | gdeg_[3] | gdeg_[4] | gdeg_[5];
    for (int q = 0; q < 2; ++q) {
        proj_[kDet + q] = dot_by_degree(normal(3 * q), normal_degree(3 * q), g_[3 * q], gdeg_[3 * q]);
        trim(proj_[kDet + q]);  // constant when the box does not turn
        proj_built_ |= 1u << (kDet + q);
    }
    // Inputs near the top of the double range overflow in these products;
    // say so instead of returning nonsense.
    const bool ok = finite_poly(proj_[kDet]) && finite_poly(proj_[kDet + 1]) && std::isfinite(dmag_ * hmag_) &&
                    std::isfinite(size_) && std::isfinite(dmag_ + hmag_) &&
                    std::isfinite((dmag_ + hmag_) * gmag_[0] * gmag_[3] * gmag_[1] * gmag_[4]);
    if (!ok)
        throw NonFiniteError(
            "the boxes' extents, positions or motion coefficients are too large: intermediate products "
            "overflow double precision");
}

const PVec &Problem::normal(int ax) const {
    if (!(n_built_ & (1u << ax))) {
        const int ga = axis_generator(ax, 0), gb = axis_generator(ax, 1);
        n_[ax] = cross_by_degree(g_[ga], gdeg_[ga], g_[gb], gdeg_[gb]);
        n_built_ |= 1u << ax;
    }
    return n_[ax];
}

const Poly &Problem::projection(int k) const {
    if (!(proj_built_ & (1u << k))) {  // k < 18: S[q][i][l] = n_{3q+i} . g_{3(1-q)+l}
        const int q = k / 9, i = (k % 9) / 3, l = k % 3, g = 3 * (1 - q) + l;
        proj_[k] = dot_by_degree(normal(3 * q + i), normal_degree(3 * q + i), g_[g], gdeg_[g]);
        trim(proj_[k]);  // constant under pure translation
        proj_built_ |= 1u << k;
    }
    return proj_[k];
}

// n.d of an axis as a polynomial: built when a facet of the axis is
// root-searched or its geometry is asked for (facet values take n.d from the
// vectors at s instead).
const Poly &Problem::normal_dot_d(int ax) const {
    if (!(nd_built_ & (1u << ax))) {
        nd_[ax] = dot_by_degree(normal(ax), normal_degree(ax), d_, ddeg_);
        trim(nd_[ax]);
        nd_built_ |= 1u << ax;
    }
    return nd_[ax];
}

// The projection n_axis . g as one of the 20 shared polynomials (or a
// structural zero: a generator that spans the axis' own facet).
namespace {
struct Projection {
    int8_t index;  // into Problem::proj_, -1 for a structural zero
    int8_t sign;
};
struct ProjectionTable {
    Projection p[15][6]{};
    constexpr ProjectionTable() {
        for (int ax = 0; ax < 15; ++ax)
            for (int g = 0; g < 6; ++g) p[ax][g] = compute(ax, g);
    }
    static constexpr Projection compute(int axis, int g) {
        if (axis < 3) {
            if (g >= 3) return {static_cast<int8_t>(3 * axis + (g - 3)), 1};
            return {static_cast<int8_t>(g == axis ? kDet : -1), 1};
        }
        if (axis < 6) {
            const int j = axis - 3;
            if (g < 3) return {static_cast<int8_t>(9 + 3 * j + g), 1};
            return {static_cast<int8_t>(g - 3 == j ? kDet + 1 : -1), 1};
        }
        const int i = (axis - 6) / 3, j = (axis - 6) % 3;
        if (g < 3) {
            // (a_i x b_j) . a_k = b_j . (a_k x a_i) = +-S[0][m][j], m the third index.
            const int k = g;
            if (k == i) return {-1, 1};
            return {static_cast<int8_t>(3 * (3 - k - i) + j), static_cast<int8_t>(i == (k + 1) % 3 ? 1 : -1)};
        }
        // (a_i x b_j) . b_l = a_i . (b_j x b_l) = +-S[1][m][i].
        const int l = g - 3;
        if (l == j) return {-1, 1};
        return {static_cast<int8_t>(9 + 3 * (3 - j - l) + i), static_cast<int8_t>(l == (j + 1) % 3 ? 1 : -1)};
    }
};
constexpr ProjectionTable kProjection;  // constant: the unrolled loops fold it away

// The 20 triple products at one time (indexed like Problem::proj_) from the six
// face normals (axes 0..5) and the generators there.
void triple_products(const Vec *face, const Vec *gs, double *pv) {
    for (int q = 0; q < 2; ++q) {
        for (int i = 0; i < 3; ++i)
            for (int l = 0; l < 3; ++l) pv[9 * q + 3 * i + l] = dot3(face[3 * q + i], gs[3 * (1 - q) + l]);
        pv[kDet + q] = dot3(face[3 * q], gs[3 * q]);
    }
}
}  // namespace

void Problem::check_regular(const char *name_a, const char *name_b) const {
    const char *names[2] = {name_a, name_b};
    for (int q = 0; q < 2; ++q) {
        const Poly &det = proj_[kDet + q];
        const double noise = tol_.rounding * kEps * gmag_[3 * q] * gmag_[3 * q + 1] * gmag_[3 * q + 2];
        const double v0 = det(0.0);
        double s = std::fabs(v0) <= noise ? 0.0 : std::numeric_limits<double>::quiet_NaN();
        if (std::isnan(s)) {
            Poly shifted = (v0 > 0.0 ? 1.0 : -1.0) * det;
            shifted.c[0] -= noise;
            s = first_nonpositive(shifted, 0.0, 1.0);
        }
        if (!std::isnan(s)) {
            const double t = s >= 1.0 ? t1 : t0 + s * (t1 - t0);
            throw SingularMotionError(std::string(names[q]) + ": the 3x3 part of the motion is singular at t = " +
                                          num(t) + " (det = " + num(det(s)) + "), so box " + (q ? "b" : "a") +
                                          " collapses inside t_range",
                                      t);
        }
    }
}

// A switch polynomial that stays zero (within rounding) over the whole range
// is a normal component that does not change the topology: ignore it.
bool Problem::ignorable_switch(int k) const {
    const int q = k / 9, i = (k % 9) / 3, l = k % 3;
    const double noise = tol_.rounding * kEps * gmag_[3 * q + (i + 1) % 3] * gmag_[3 * q + (i + 2) % 3] *
                         gmag_[3 * (1 - q) + l];
    const Poly &p = projection(k);
    for (int c = 0; c <= p.deg; ++c)
        if (std::fabs(p.c[c]) > noise) return false;
    return true;
}

// The switch polynomials S[q][i][l] = n . c with n = a x b the face normal
// (a, b, c generators): at mid, S = n . c and S' = n' . c + n . c' with
// n' = a' x b + a x b'.
Problem::SwitchProbe Problem::probe_switches(double from, double to) const {
    SwitchProbe pr;
    const double w = 0.5 * (to - from);
    pr.w = w;
    const Axis at_mid = sample_at(0.5 * (from + to));
    const Vec *val = at_mid.val + 1, *der = at_mid.der + 1;  // the generators and their derivatives
    for (int g = 0; g < 6; ++g) {
        const double len = norm3(val[g]), dlen = norm3(der[g]);
        const double len2 = norm3({g_[g].x[0].c[2], g_[g].x[1].c[2], g_[g].x[2].c[2]});  // of the s^2 term
        pr.v[g] = len + (dlen + len2 * w) * w;
        pr.d1[g] = dlen + 2.0 * len2 * w;
        pr.d2[g] = 2.0 * len2;
    }
    for (int f = 0; f < 6; ++f) {
        const int ga = axis_generator(f, 0), gb = axis_generator(f, 1);
        const Vec n = cross3(val[ga], val[gb]), da = cross3(der[ga], val[gb]), db = cross3(val[ga], der[gb]);
        const Vec dn = {da[0] + db[0], da[1] + db[1], da[2] + db[2]};
        const int q = f / 3, i = f % 3;
        for (int l = 0; l < 3; ++l) {
            const int gc = 3 * (1 - q) + l, k = 9 * q + 3 * i + l;
            pr.p[k] = dot3(n, val[gc]);
            pr.dp[k] = dot3(dn, val[gc]) + dot3(n, der[gc]);
        }
    }
    return pr;
}

// Taylor's theorem at mid: |p(s) - p(mid)| <= |p'(mid)| w + max|p''| w^2 / 2 for
// |s - mid| <= w, so p keeps its sign if |p(mid)| exceeds that plus a bound of
// the rounding of p(mid) and p'(mid). Here p = (a x b) . c with quadratic vector
// curves a, b, c (the generators), so over the interval |a| <= |a(mid)| +
// |a'(mid)| w + |a2| w^2, |a'| <= |a'(mid)| + 2 |a2| w and |a''| = 2 |a2| (a2 the
// s^2 coefficient vector), and
//   |p''| <= |a''||b||c| + |a||b''||c| + |a||b||c''| + 2 (|a'||b'||c| + |a'||b||c'| + |a||b'||c'|).
// The rounding of p and p' from the generators' values (each within a few eps
// of its coefficients' magnitude) stays below 32 eps times the product of the
// three magnitudes, and 8 times that for p' (derivatives up to twice as large).
bool Problem::switch_constant(int k, const SwitchProbe &pr) const {
    const int q = k / 9, i = (k % 9) / 3, l = k % 3;
    const int a = 3 * q + (i + 1) % 3, b = 3 * q + (i + 2) % 3, c = 3 * (1 - q) + l;
    const double curvature = pr.d2[a] * pr.v[b] * pr.v[c] + pr.v[a] * pr.d2[b] * pr.v[c] +
                             pr.v[a] * pr.v[b] * pr.d2[c] +
                             2.0 * (pr.d1[a] * pr.d1[b] * pr.v[c] + pr.d1[a] * pr.v[b] * pr.d1[c] +
                                    pr.v[a] * pr.d1[b] * pr.d1[c]);
    const double w = pr.w, rounding = 32.0 * kEps * gmag_[a] * gmag_[b] * gmag_[c] * (1.0 + 8.0 * w);
    return std::fabs(pr.p[k]) > std::fabs(pr.dp[k]) * w + 0.5 * curvature * w * w + rounding;
}

// The first sign change of switch polynomial k in (from, to], kNone if none.
// The cheapest proof of a constant sign comes first (switch_constant: most
// intervals the search covers are short); the polynomial is built only if it
// fails. `probe`: probe_switches(from, to).
double Problem::next_switch(int k, double from, double to, const SwitchProbe &probe) const {
    if (!(from < to)) return kNone;
    const int q = k / 9, i = (k % 9) / 3, l = k % 3;
    if (!(gdeg_[3 * q + (i + 1) % 3] | gdeg_[3 * q + (i + 2) % 3] | gdeg_[3 * (1 - q) + l]))
        return kNone;  // three constant generators: a constant
    if (switch_constant(k, probe)) return kNone;
    if (ignorable_switch(k)) return kNone;
    const double r = first_sign_change(projection(k), from, to);
    return std::isnan(r) ? kNone : r;
}

Problem::Switches Problem::first_switches(double from, double to) const {
    Switches sw;
    sw.to = to;
    sw.next.fill(kNone);
    if (!turning_) return sw;  // constant edge directions: no octant switches
    const SwitchProbe probe = probe_switches(from, to);
    for (int k = 0; k < 18; ++k) sw.next[k] = next_switch(k, from, to, probe);
    return sw;
}

double Problem::Switches::boundary() const {
    double b = to;
    for (double r : next) b = std::min(b, r);
    return b;
}

void Problem::pass(Switches &sw, double boundary) const {
    // Sign changes within a few doubles of the one just passed are the same switch.
    const double from = boundary + 4.0 * kRootWidth;
    const SwitchProbe probe = probe_switches(from, sw.to);
    for (int k = 0; k < 18; ++k)
        if (sw.next[k] <= boundary) sw.next[k] = next_switch(k, from, sw.to, probe);
}

std::vector<double> Problem::sections() const {
    std::vector<double> cuts{0.0};
    Switches sw = first_switches(0.0);
    for (double b = sw.boundary(); b < 1.0; b = sw.boundary()) {
        cuts.push_back(b);
        pass(sw, b);
    }
    cuts.push_back(1.0);
    return cuts;
}

Problem::Section Problem::make_section(double lo, double hi) const {
    Section sec;
    sec.lo = lo;
    sec.hi = hi;
    return sec;
}

// The topology of one axis in a section, sampled at the section's midpoint (it
// holds over the whole section), with the axis' tolerance. Computed on first
// use: only the axes whose facets are root-searched need it.
void Problem::ensure_axis(const Section &sec, int ax) const {
    if (sec.ready & (1u << ax)) return;
    if (!sec.mid_ready) {  // shared by all 15 axes
        const double mid = 0.5 * (sec.lo + sec.hi);
        for (int g = 0; g < 6; ++g) sec.g_mid[g] = g_[g].at2(mid);
        Vec face[6];
        for (int ax = 0; ax < 6; ++ax)
            face[ax] = cross3(sec.g_mid[axis_generator(ax, 0)], sec.g_mid[axis_generator(ax, 1)]);
        triple_products(face, sec.g_mid, sec.pv_mid);
        sec.mid_ready = true;
    }
    for (int g = 0; g < 6; ++g) {
        const Projection pr = kProjection.p[ax][g];
        const double v = pr.index >= 0 ? pr.sign * sec.pv_mid[pr.index] : 0.0;
        sec.sig[ax][g] = static_cast<int8_t>((v > 0.0) - (v < 0.0));
    }
    const double nn = norm3(cross3(sec.g_mid[axis_generator(ax, 0)], sec.g_mid[axis_generator(ax, 1)]));
    sec.tau[ax] = tol_.gap_rel * size_ * nn + noise(ax);
    sec.ready |= 1u << ax;
}

// Q_k = +-n.d - sum_g sig * |n.g| h_g - tau, built on first use.
const Poly &Problem::facet_poly(const Section &sec, int facet) const {
    if (!(sec.built & (1u << facet))) {
        const int ax = facet / 2;
        ensure_axis(sec, ax);
        Poly H{};
        for (int g = 0; g < 6; ++g) {
            if (!sec.sig[ax][g]) continue;
            const Projection pr = kProjection.p[ax][g];
            axpy(H, sec.sig[ax][g] * pr.sign * h_[g], projection(pr.index));
        }
        Poly P = (facet % 2 == 0 ? 1.0 : -1.0) * normal_dot_d(ax) - H;
        P.c[0] -= sec.tau[ax];
        sec.Q[facet] = P;
        sec.built |= 1u << facet;
    }
    return sec.Q[facet];
}

void Problem::facet_values(double s, FacetValues &f) const {
    std::array<double, 3> gs[6];
    for (int g = 0; g < 6; ++g) gs[g] = g_[g].at2(s);
    AxisValues v;
    axis_values(gs, d_.at2(s), v);
    for (int ax = 0; ax < 15; ++ax) {
        const double len = std::sqrt(v.nn2[ax]);
        f.len[ax] = v.direction[ax] ? len : 0.0;
        f.tau[ax] = tol_.gap_rel * size_ * len + noise(ax);
        f.q[2 * ax] = v.nd[ax] - v.support[ax] - f.tau[ax];
        f.q[2 * ax + 1] = -v.nd[ax] - v.support[ax] - f.tau[ax];
    }
}

// Advancement inside one section: from s, take the facet that separates most,
// jump to its first root (the first time the origin reaches that facet's
// plane), and repeat until no facet separates (contact) or the separating
// facet stays positive to the section's end. Each jump passes a root of a
// facet polynomial, so s only increases and no contact is skipped: before
// that root the facet proves the boxes apart.
bool Problem::advance(const Section &sec, double &s, int &last, int &separating) const {
    // Warm start: the facet that kept the previous section apart often keeps
    // this one apart too, which the other 29 facets need not be asked about.
    if (separating >= 0 && facet_poly(sec, separating)(s) > 0.0) {
        const double r = first_nonpositive(facet_poly(sec, separating), s, sec.hi);
        if (std::isnan(r)) return false;
        if (r > s) {
            s = r;
            last = separating;
        }
    }
    uint32_t touching = 0;  // facets within rounding of zero at this s
    FacetValues f;
    double evaluated_at = std::numeric_limits<double>::quiet_NaN();
    for (int step = 0; step < tol_.max_steps; ++step) {
        if (!(s == evaluated_at)) {
            facet_values(s, f);
            evaluated_at = s;
        }
        int best = -1;
        double best_v = 0.0;
        for (int k = 0; k < 30; ++k) {
            if (f.q[k] <= 0.0 || (touching & (1u << k))) continue;
            const double len = f.len[k / 2];
            const double rank = len > 0.0 ? f.q[k] / len : 0.0;  // separation distance
            if (best < 0 || rank > best_v) {
                best_v = rank;
                best = k;
            }
        }
        if (best < 0) return true;
        const double r = first_nonpositive(facet_poly(sec, best), s, sec.hi);
        if (std::isnan(r)) {
            separating = best;
            return false;
        }
        if (r <= s) {  // Horner and Bernstein disagree in the last bits: treat as touching here
            touching |= 1u << best;
            continue;
        }
        s = r;
        last = best;
        touching = 0;
    }
    return true;  // step cap: report contact at s (early, never late)
}

int Problem::best_facet(double s) const {
    FacetValues f;
    facet_values(s, f);
    int best = 0;
    double best_v = -std::numeric_limits<double>::infinity();
    for (int k = 0; k < 30; ++k) {
        const double len = f.len[k / 2];
        if (len == 0.0) continue;
        const double v = (f.q[k] + f.tau[k / 2]) / len;
        if (v > best_v) { best_v = v; best = k; }
    }
    return best;
}

// Culling before the route division: if one fixed unit direction u separates
// the boxes over an interval [lo, hi], they do not touch in it. For fixed u every
// term is a quadratic in s, bounded by its three Bernstein control points on
// the interval:
//   gap_u(s) = |u.d| - sum_g h_g |u.g| >= min |ctrl(u.d)| - sum_g h_g max |ctrl(u.g)|
// when the control points of u.d share a sign. Candidates: the most separating
// of the 15 axes at lo and at hi (computed once per sample time). The bound only
// ever proves pairs apart that are apart by more than the touching tolerance, so
// it changes speed, and contact times only within that tolerance.
Problem::Axis Problem::sample_at(double s) const {
    Axis a;
    for (int v = 0; v < 7; ++v) {
        const PVec &P = v == 0 ? d_ : g_[v - 1];
        for (int r = 0; r < 3; ++r) {
            const Poly &p = P.x[r];
            a.val[v][r] = eval2(p, s);
            a.der[v][r] = p.c[1] + 2.0 * p.c[2] * s;
        }
    }
    return a;
}

void Problem::axis_values(const std::array<double, 3> *gs, const std::array<double, 3> &ds, AxisValues &v) const {
    double len2[6], pv[20];
    for (int g = 0; g < 6; ++g) len2[g] = dot3(gs[g], gs[g]);
#pragma GCC unroll 15
    for (int ax = 0; ax < 15; ++ax) {
        const int g1 = axis_generator(ax, 0), g2 = axis_generator(ax, 1);
        v.n[ax] = cross3(gs[g1], gs[g2]);
        v.nn2[ax] = dot3(v.n[ax], v.n[ax]);
        v.nd[ax] = dot3(v.n[ax], ds);
        v.direction[ax] = v.nn2[ax] > 1e-18 * len2[g1] * len2[g2];
    }
    triple_products(v.n, gs, pv);
#pragma GCC unroll 15
    for (int ax = 0; ax < 15; ++ax) {
        double h = 0.0;
#pragma GCC unroll 6
        for (int g = 0; g < 6; ++g) {
            const Projection pr = kProjection.p[ax][g];
            if (pr.index >= 0) h += h_[g] * std::fabs(pv[pr.index]);
        }
        v.support[ax] = h;
    }
}

// The most separating of the 15 axes at the sample's time (unit u) and its
// separation; gap 0 if none separates (the boxes overlap there).
void Problem::find_axis(Axis &best) const {
    best.searched = true;
    AxisValues v;
    axis_values(best.val + 1, best.val[0], v);
    int best_ax = -1;
    double best_gap = 0.0, best_gap2 = 0.0;  // gap (unnormalised) and (gap / |n|)^2 of the best
    for (int ax = 0; ax < 15; ++ax) {
        const double gap = std::fabs(v.nd[ax]) - v.support[ax];
        // gap^2 / |n|^2 ranks the axes without a sqrt.
        if (gap > 0.0 && v.direction[ax] && gap * gap > best_gap2 * v.nn2[ax]) {
            best_gap = gap;
            best_gap2 = gap * gap / v.nn2[ax];
            best_ax = ax;
        }
    }
    if (best_ax >= 0) {
        const double nn = std::sqrt(v.nn2[best_ax]);
        const Vec &n = v.n[best_ax];
        best.gap = best_gap / nn;
        best.u = {n[0] / nn, n[1] / nn, n[2] / nn};
        best.facet = 2 * best_ax + (v.nd[best_ax] < 0.0);
    }
}

bool Problem::apart_on_fixed_axis(double lo, double hi, const Axis &at_lo, const Axis &at_hi, bool use_lo,
                                  bool use_hi) const {
    const double margin = tol_.gap_rel * size_ + tol_.rounding * kEps * (dmag_ + hmag_);
    use_lo = use_lo && at_lo.gap > margin;
    use_hi = use_hi && at_hi.gap > margin && !(use_lo && at_hi.u == at_lo.u);
    if (!use_lo && !use_hi) return false;
    // Bernstein control points on [lo, hi] of d (v = 0) and the generators
    // (v = 1..6), shared by both candidate axes: the values at the ends and the
    // tangent at lo, ctrl[v][k] a point in R^3 (the curves are quadratic).
    const double half_w = 0.5 * (hi - lo);
    std::array<double, 3> ctrl[7][3];
    for (int v = 0; v < 7; ++v) {
        ctrl[v][0] = at_lo.val[v];
        ctrl[v][2] = at_hi.val[v];
        for (int r = 0; r < 3; ++r) ctrl[v][1][r] = at_lo.val[v][r] + half_w * at_lo.der[v][r];
    }
    for (const Axis *axis : {&at_lo, &at_hi}) {
        if (!(axis == &at_lo ? use_lo : use_hi)) continue;
        const std::array<double, 3> &u = axis->u;
        const double bd[3] = {dot3(u, ctrl[0][0]), dot3(u, ctrl[0][1]), dot3(u, ctrl[0][2])};
        if (!((bd[0] > 0 && bd[1] > 0 && bd[2] > 0) || (bd[0] < 0 && bd[1] < 0 && bd[2] < 0))) continue;
        double lower = std::min({std::fabs(bd[0]), std::fabs(bd[1]), std::fabs(bd[2])});
        for (int g = 0; g < 6; ++g)
            lower -= h_[g] * std::max({std::fabs(dot3(u, ctrl[g + 1][0])), std::fabs(dot3(u, ctrl[g + 1][1])),
                                       std::fabs(dot3(u, ctrl[g + 1][2]))});
        if (lower > margin) return true;
    }
    return false;
}

// The start of the first piece of [lo, hi] (halved `depth` times) that no fixed
// axis proves apart; NaN if every piece is proven apart. A sample's own axis is
// searched only when the axes already found cannot prove its piece apart.
// `budget` caps the new sample times: once spent, an unproven piece is not split.
// If no axis separates at the end of that piece (the boxes overlap there, up to
// rounding), `overlap` is set to it: the first contact lies within the piece.
// `facet` is set to the BMS facet of the axis that separates at the piece's start
// (-1: none), a warm start for the search.
double Problem::first_unproven(double lo, double hi, Axis &at_lo, Axis &at_hi, int depth, int &budget,
                               double &overlap, int &facet) const {
    const bool new_lo = !at_lo.searched, new_hi = !at_hi.searched;
    if (apart_on_fixed_axis(lo, hi, at_lo, at_hi, true, true)) return std::numeric_limits<double>::quiet_NaN();
    if (new_lo) find_axis(at_lo);
    if (new_hi) find_axis(at_hi);
    if ((new_lo || new_hi) && apart_on_fixed_axis(lo, hi, at_lo, at_hi, new_lo, new_hi))
        return std::numeric_limits<double>::quiet_NaN();
    if (at_lo.gap == 0.0) return lo;  // overlapping at lo: no fixed axis proves any piece from lo apart
    if (depth == 0 || budget == 0) {
        if (at_hi.gap == 0.0) overlap = hi;
        facet = at_lo.facet;
        return lo;
    }
    --budget;
    const double mid = 0.5 * (lo + hi);
    Axis at_mid = sample_at(mid);
    const double s = first_unproven(lo, mid, at_lo, at_mid, depth - 1, budget, overlap, facet);
    return std::isnan(s) ? first_unproven(mid, hi, at_mid, at_hi, depth - 1, budget, overlap, facet) : s;
}

Hit Problem::solve(bool want_geometry) const {
    Hit hit;
    // Pieces of the range that one fixed axis keeps apart need no BMS search.
    // Turning boxes make the BMS search costly (octant switches, degree-6
    // facets), so their culling goes deeper than that of translating ones.
    int budget = kCullBudget;
    double overlap = 1.0;
    int separating = -1;  // a facet that separates at the search's start
    // The axis at the range's end is searched only if the one at its start
    // cannot keep the whole range apart on its own.
    Axis at0 = sample_at(0.0), at1 = sample_at(1.0);
    find_axis(at0);
    const double start =
        first_unproven(0.0, 1.0, at0, at1, turning_ ? kCullDepthTurning : kCullDepth, budget, overlap, separating);
    if (std::isnan(start)) return hit;
    // The search ends where the culling saw the boxes overlap: only the octant
    // switches before it matter. If rounding fooled that sample and nothing
    // touches before it, the search goes on from there to the end.
    Switches sw = first_switches(start, overlap);
    int last = -1;
    for (double lo = start;;) {
        const double hi = sw.boundary();
        const Section sec = make_section(lo, hi);
        double s = lo;
        if (advance(sec, s, last, separating)) {
            hit.hit = true;
            hit.s = s;
            hit.t = s >= 1.0 ? t1 : t0 + s * (t1 - t0);
            hit.initial = (s == 0.0);
            // The facet the origin just crossed; when no facet was crossed
            // (contact at the start or exactly at a section boundary) the facet
            // of least penetration.
            hit.facet = (last >= 0 && !hit.initial) ? last : best_facet(s);
            if (want_geometry) contact_geometry(sec, hit);
            return hit;
        }
        if (hi >= 1.0) return hit;
        if (hi >= sw.to) sw = first_switches(hi);
        else pass(sw, hi);
        lo = hi;
    }
}

// Outward normal sign of facet k on generator g (+1 / -1, 0 for structural).
static inline int facet_sign(const int8_t sig[6], int facet, int g) {
    return (facet % 2 == 0 ? 1 : -1) * sig[g];
}

void Problem::contact_geometry(const Section &sec, Hit &hit) const {
    const int ax = hit.facet / 2;
    ensure_axis(sec, ax);
    const double s = hit.s;
    std::array<double, 3> n = normal(ax)(s), cA = cA_(s), cB = cB_(s);
    std::array<double, 3> gv[6];
    for (int g = 0; g < 6; ++g) gv[g] = g_[g](s);
    const double sgn = hit.facet % 2 == 0 ? 1.0 : -1.0, nn = norm3(n);
    for (int r = 0; r < 3; ++r) hit.normal[r] = nn > 0.0 ? sgn * n[r] / nn : 0.0;
    for (int i = 0; i < 3; ++i) {
        hit.feat_a[i] = static_cast<int8_t>(facet_sign(sec.sig[ax], hit.facet, i));
        hit.feat_b[i] = static_cast<int8_t>(-facet_sign(sec.sig[ax], hit.facet, 3 + i));
    }
    // Support points of each box's feature: centre + the signed half edges.
    std::array<double, 3> pa = cA, pb = cB;
    for (int i = 0; i < 3; ++i)
        for (int r = 0; r < 3; ++r) {
            pa[r] += hit.feat_a[i] * h_[i] * gv[i][r];
            pb[r] += hit.feat_b[i] * h_[3 + i] * gv[3 + i][r];
        }
    if (ax < 3) { hit.point = pb; return; }  // face of A, vertex of B
    if (ax < 6) { hit.point = pa; return; }  // face of B, vertex of A
    // Edge-edge: closest points of the two edge lines, clamped to the edges.
    const int i = (ax - 6) / 3, j = (ax - 6) % 3;
    const std::array<double, 3> &u = gv[i], &v = gv[3 + j];
    std::array<double, 3> w;
    for (int r = 0; r < 3; ++r) w[r] = pa[r] - pb[r];
    const double uu = u[0] * u[0] + u[1] * u[1] + u[2] * u[2], vv = v[0] * v[0] + v[1] * v[1] + v[2] * v[2];
    const double uv = u[0] * v[0] + u[1] * v[1] + u[2] * v[2];
    const double uw = u[0] * w[0] + u[1] * w[1] + u[2] * w[2], vw = v[0] * w[0] + v[1] * w[1] + v[2] * w[2];
    const double den = uu * vv - uv * uv;
    double la = 0.0, mu = 0.0;
    if (den > 1e-300) {  // parallel edges (den == 0): any point of the overlap; take the centres
        la = (uv * vw - vv * uw) / den;
        mu = (uu * vw - uv * uw) / den;
    }
    la = std::clamp(la, -h_[i], h_[i]);
    mu = std::clamp(mu, -h_[3 + j], h_[3 + j]);
    for (int r = 0; r < 3; ++r) hit.point[r] = 0.5 * (pa[r] + la * u[r] + pb[r] + mu * v[r]);
}

void Problem::planes(double s, double *normals, double *offsets, int8_t *feat_a, int8_t *feat_b) const {
    Switches sw = first_switches(0.0);
    double lo = 0.0;
    while (sw.boundary() <= s && sw.boundary() < 1.0) {
        lo = sw.boundary();
        pass(sw, lo);
    }
    const Section sec = make_section(lo, sw.boundary());
    FacetValues f;
    facet_values(s, f);
    for (int k = 0; k < 30; ++k) {
        const int ax = k / 2;
        ensure_axis(sec, ax);
        const double sgn = k % 2 == 0 ? 1.0 : -1.0;
        const std::array<double, 3> n = normal(ax)(s);
        const double nn = norm3(n);
        for (int r = 0; r < 3; ++r) normals[3 * k + r] = sgn * n[r] / nn;
        offsets[k] = -(f.q[k] + f.tau[ax]) / nn;
        for (int g = 0; g < 3; ++g) {
            feat_a[3 * k + g] = static_cast<int8_t>(facet_sign(sec.sig[ax], k, g));
            feat_b[3 * k + g] = static_cast<int8_t>(-facet_sign(sec.sig[ax], k, 3 + g));
        }
    }
}

}  // namespace boxccd
