// The BMS solver: route division, topology per section, first contact.
// The file comment of box_ccd.hpp maps the seed's symbols to this code.
#include "box_ccd.hpp"

#include <algorithm>
#include <cstdio>

namespace boxccd {

namespace {

std::string num(double v) {
    char buf[40];
    std::snprintf(buf, sizeof buf, "%.17g", v);
    return buf;
}

const char *kAxisName[3] = {"x", "y", "z"};

double norm3(const std::array<double, 3> &v) { return std::sqrt(v[0] * v[0] + v[1] * v[1] + v[2] * v[2]); }

// Coefficient (k, r, c) of a row-major (3, 4, 4) array.
inline double coef(const double *C, int k, int r, int c) { return C[k * 16 + r * 4 + c]; }

// Entry (r, c) of M(t0 + w s) as a polynomial in s.
Poly entry_in_s(const double *C, int r, int c, double t0, double w) {
    const double c0 = coef(C, 0, r, c), c1 = coef(C, 1, r, c), c2 = coef(C, 2, r, c);
    Poly p;
    p.deg = 2;
    p.c[0] = c0 + t0 * (c1 + t0 * c2);
    p.c[1] = (c1 + 2.0 * c2 * t0) * w;
    p.c[2] = c2 * w * w;
    return p;
}

bool finite_poly(const Poly &p) {
    for (int i = 0; i <= p.deg; ++i)
        if (!std::isfinite(p.c[i])) return false;
    return true;
}

}  // namespace

void check_box(const double *lo, const double *hi, const std::string &name, const std::string &where) {
    for (int i = 0; i < 3; ++i) {
        if (!std::isfinite(lo[i]))
            throw NonFiniteError(where + name + ".lo[" + std::to_string(i) + "] is " + num(lo[i]) +
                                 "; expected a finite number");
        if (!std::isfinite(hi[i]))
            throw NonFiniteError(where + name + ".hi[" + std::to_string(i) + "] is " + num(hi[i]) +
                                 "; expected a finite number");
    }
    for (int i = 0; i < 3; ++i)
        if (!(lo[i] < hi[i]))
            throw BoxError(where + name + ": lo[" + std::to_string(i) + "] = " + num(lo[i]) + " >= hi[" +
                           std::to_string(i) + "] = " + num(hi[i]) + "; expected lo < hi on the " +
                           kAxisName[i] + " axis (a box has positive extent)");
}

void check_motion(const double *C, const std::string &name, const std::string &where) {
    for (int k = 0; k < 3; ++k)
        for (int r = 0; r < 4; ++r)
            for (int c = 0; c < 4; ++c) {
                const double v = coef(C, k, r, c);
                if (!std::isfinite(v))
                    throw NonFiniteError(where + name + ".coeffs[" + std::to_string(k) + ", " + std::to_string(r) +
                                         ", " + std::to_string(c) + "] is " + num(v) + "; expected a finite number");
            }
    for (int k = 0; k < 3; ++k)
        for (int c = 0; c < 4; ++c) {
            const double want = (k == 0 && c == 3) ? 1.0 : 0.0;
            const double v = coef(C, k, 3, c);
            if (v != want)
                throw MotionError(where + name + ".coeffs[" + std::to_string(k) + ", 3, " + std::to_string(c) +
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

int axis_generator(int axis, int which) {
    if (axis < 3) return (axis + 1 + which) % 3;
    if (axis < 6) return 3 + (axis - 3 + 1 + which) % 3;
    const int e = axis - 6;
    return which == 0 ? e / 3 : 3 + e % 3;
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
        for (int i = 0; i < 3; ++i)
            dmag_ += std::fabs(0.5 * (bx.lo[i] + bx.hi[i])) * g_[3 * q + i].magnitude();
    }
    cA_ = centre[0];
    cB_ = centre[1];
    for (int r = 0; r < 3; ++r) d_.x[r] = cB_.x[r] - cA_.x[r];
    size_ = 0.0;
    for (int g = 0; g < 6; ++g) {
        gmag_[g] = g_[g].magnitude();
        size_ += h_[g] * norm3(g_[g](0.5));
    }
    for (int ax = 0; ax < 15; ++ax) {
        n_[ax] = cross(g_[axis_generator(ax, 0)], g_[axis_generator(ax, 1)]);
        nd_[ax] = dot(n_[ax], d_);
    }
    det_[0] = dot(g_[0], n_[0]);
    det_[1] = dot(g_[3], n_[3]);
    for (int i = 0; i < 3; ++i)
        for (int l = 0; l < 3; ++l) {
            S_[0][i][l] = dot(n_[i], g_[3 + l]);
            S_[1][i][l] = dot(n_[3 + i], g_[l]);
        }
    // Inputs near the top of the double range overflow in these products;
    // say so instead of returning nonsense.
    bool ok = finite_poly(det_[0]) && finite_poly(det_[1]) && std::isfinite(dmag_) && std::isfinite(size_);
    for (int ax = 0; ax < 15; ++ax) ok = ok && finite_poly(nd_[ax]);
    for (int q = 0; q < 2; ++q)
        for (int i = 0; i < 3; ++i)
            for (int l = 0; l < 3; ++l) ok = ok && finite_poly(S_[q][i][l]);
    if (!ok)
        throw NonFiniteError(
            "the boxes' extents, positions or motion coefficients are too large: intermediate products "
            "overflow double precision");
}

// The projection n_axis . g as one of the precomputed polynomials, or nullptr
// for a structural zero (a generator that spans the axis' own facet).
void Problem::projection(int axis, int g, const Poly *&p, double &sign) const {
    p = nullptr;
    sign = 1.0;
    if (axis < 3) {
        if (g < 3) { if (g == axis) p = &det_[0]; }
        else p = &S_[0][axis][g - 3];
        return;
    }
    if (axis < 6) {
        const int j = axis - 3;
        if (g >= 3) { if (g - 3 == j) p = &det_[1]; }
        else p = &S_[1][j][g];
        return;
    }
    const int i = (axis - 6) / 3, j = (axis - 6) % 3;
    if (g < 3) {
        // (a_i x b_j) . a_k = b_j . (a_k x a_i) = +-S[0][m][j], m the third index.
        const int k = g;
        if (k == i) return;
        p = &S_[0][3 - k - i][j];
        sign = (i == (k + 1) % 3) ? 1.0 : -1.0;
    } else {
        // (a_i x b_j) . b_l = a_i . (b_j x b_l) = +-S[1][m][i].
        const int l = g - 3;
        if (l == j) return;
        p = &S_[1][3 - j - l][i];
        sign = (l == (j + 1) % 3) ? 1.0 : -1.0;
    }
}

void Problem::check_regular(const char *name_a, const char *name_b) const {
    const char *names[2] = {name_a, name_b};
    for (int q = 0; q < 2; ++q) {
        const Poly &det = det_[q];
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

std::vector<double> Problem::sections() const {
    std::vector<double> cuts;
    auto collect = [&cuts](double s) { cuts.push_back(s); };
    for (int q = 0; q < 2; ++q) {
        const int other = 3 * (1 - q);
        for (int i = 0; i < 3; ++i)
            for (int l = 0; l < 3; ++l) {
                const Poly &p = S_[q][i][l];
                // A normal component that stays zero (within rounding) over the
                // whole range is not a switch: skip it.
                const double noise = tol_.rounding * kEps * gmag_[3 * q + (i + 1) % 3] *
                                     gmag_[3 * q + (i + 2) % 3] * gmag_[other + l];
                bool zero = true;
                for (int c = 0; c <= p.deg; ++c) zero = zero && std::fabs(p.c[c]) <= noise;
                if (!zero) sign_changes(p, 0.0, 1.0, to_bernstein(p, 0.0, 1.0), 0, collect);
            }
    }
    cuts.push_back(0.0);
    cuts.push_back(1.0);
    std::sort(cuts.begin(), cuts.end());
    std::vector<double> out;
    for (double s : cuts) {
        if (s < 0.0 || s > 1.0) continue;
        if (!out.empty() && s <= out.back()) continue;  // duplicates
        out.push_back(s);
    }
    return out;
}

Problem::Section Problem::make_section(double lo, double hi) const {
    Section sec;
    sec.lo = lo;
    sec.hi = hi;
    const double mid = 0.5 * (lo + hi);
    double hmag = 0.0;
    for (int g = 0; g < 6; ++g) hmag += h_[g] * gmag_[g];
    for (int ax = 0; ax < 15; ++ax) {
        Poly H;
        for (int g = 0; g < 6; ++g) {
            const Poly *p;
            double sign;
            projection(ax, g, p, sign);
            sec.sig[ax][g] = 0;
            if (!p) continue;
            const double v = sign * (*p)(mid);
            // The topology sampled at an interior point holds over the section.
            const int8_t sg = static_cast<int8_t>((v > 0.0) - (v < 0.0));
            sec.sig[ax][g] = sg;
            if (sg != 0) axpy(H, sg * sign * h_[g], *p);
        }
        const int g1 = axis_generator(ax, 0), g2 = axis_generator(ax, 1);
        const double noise = tol_.rounding * kEps * (dmag_ + hmag) * gmag_[g1] * gmag_[g2];
        const double nn = norm3(n_[ax](mid));
        // Parallel edges (or a flat box) give an axis with no direction: it can
        // rank no contact (its facet has zero area).
        const bool has_direction = nn > 1e-9 * norm3(g_[g1](mid)) * norm3(g_[g2](mid));
        const double tau = tol_.gap_rel * size_ * nn + noise;
        for (int sgn = 0; sgn < 2; ++sgn) {
            const int k = 2 * ax + sgn;
            Poly P = (sgn == 0 ? 1.0 : -1.0) * nd_[ax] - H;
            P.c[0] -= tau;  // Q_k = P_k - tau_k: <= 0 means touching within tolerance
            sec.Q[k] = P;
            sec.tau[k] = tau;
            sec.scale[k] = has_direction ? nn : 0.0;
        }
    }
    return sec;
}

// Advancement inside one section: from s, take the facet that separates most,
// jump to its first root (the first time the origin reaches that facet's
// plane), and repeat until no facet separates (contact) or the separating
// facet stays positive to the section's end. Each jump passes a root of a
// facet polynomial, so s only increases and no contact is skipped: before
// that root the facet proves the boxes apart.
bool Problem::advance(const Section &sec, double &s, int &last) const {
    uint32_t touching = 0;  // facets within rounding of zero at this s
    for (int step = 0; step < tol_.max_steps; ++step) {
        int best = -1;
        double best_v = 0.0;
        for (int k = 0; k < 30; ++k) {
            if (touching & (1u << k)) continue;
            const double q = sec.Q[k](s);
            if (q <= 0.0) continue;
            const double rank = sec.scale[k] > 0.0 ? q / sec.scale[k] : 0.0;  // separation distance
            if (best < 0 || rank > best_v) {
                best_v = rank;
                best = k;
            }
        }
        if (best < 0) return true;
        const double r = first_nonpositive(sec.Q[best], s, sec.hi);
        if (std::isnan(r)) return false;
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

int Problem::best_facet(const Section &sec, double s) const {
    int best = 0;
    double best_v = -std::numeric_limits<double>::infinity();
    for (int k = 0; k < 30; ++k) {
        if (sec.scale[k] == 0.0) continue;
        const double v = (sec.Q[k](s) + sec.tau[k]) / sec.scale[k];
        if (v > best_v) { best_v = v; best = k; }
    }
    return best;
}

Hit Problem::solve(bool want_geometry) const {
    Hit hit;
    const std::vector<double> cuts = sections();
    int last = -1;
    for (size_t i = 0; i + 1 < cuts.size(); ++i) {
        const Section sec = make_section(cuts[i], cuts[i + 1]);
        double s = sec.lo;
        if (!advance(sec, s, last)) continue;
        hit.hit = true;
        hit.s = s;
        hit.t = s >= 1.0 ? t1 : t0 + s * (t1 - t0);
        hit.initial = (s == 0.0);
        // The facet the origin just crossed; when no facet was crossed (contact
        // at the start or exactly at a section boundary) the facet of least
        // penetration.
        hit.facet = (last >= 0 && !hit.initial) ? last : best_facet(sec, s);
        if (want_geometry) contact_geometry(sec, hit);
        return hit;
    }
    return hit;
}

// Outward normal sign of facet k on generator g (+1 / -1, 0 for structural).
static inline int facet_sign(const int8_t sig[6], int facet, int g) {
    return (facet % 2 == 0 ? 1 : -1) * sig[g];
}

void Problem::contact_geometry(const Section &sec, Hit &hit) const {
    const int ax = hit.facet / 2;
    const double s = hit.s;
    std::array<double, 3> n = n_[ax](s), cA = cA_(s), cB = cB_(s);
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
    const std::vector<double> cuts = sections();
    size_t i = 0;
    while (i + 2 < cuts.size() && s >= cuts[i + 1]) ++i;
    const Section sec = make_section(cuts[i], cuts[i + 1]);
    for (int k = 0; k < 30; ++k) {
        const int ax = k / 2;
        const double sgn = k % 2 == 0 ? 1.0 : -1.0;
        const std::array<double, 3> n = n_[ax](s);
        const double nn = norm3(n);
        for (int r = 0; r < 3; ++r) normals[3 * k + r] = sgn * n[r] / nn;
        offsets[k] = -(sec.Q[k](s) + sec.tau[k]) / nn;
        for (int g = 0; g < 3; ++g) {
            feat_a[3 * k + g] = static_cast<int8_t>(facet_sign(sec.sig[ax], k, g));
            feat_b[3 * k + g] = static_cast<int8_t>(-facet_sign(sec.sig[ax], k, 3 + g));
        }
    }
}

}  // namespace boxccd
