// Exact time of impact of two boxes under quadratic affine motion: the seed's
// BMS algorithm (shared/seed/box-ccd-algorithm.txt).
//
// Time: callers give t in [t_min, t_max]; inside the core everything runs on the
// normalised s = (t - t_min) / (t_max - t_min) in [0, 1].
//
// Seed vocabulary -> code. The seed's static box S is box A, its moving box M
// is box B. Both may move: instead of the seed's relative motion M1 M2^-1 (a
// rational function of t) we keep both in world coordinates, where the
// Minkowski difference D(s) = A(s) + (-B(s)) has the same facets, and every
// quantity stays a polynomial in s. A box has three edge directions (the
// generators): a_i(s) = column i of A's 3x3 part, b_j(s) likewise; g[0..2] =
// a_0..a_2 and g[3..5] = b_0..b_2. D is a zonotope with these six generators,
// so it has exactly 15 facet axes, each spanned by two generators, and 30
// facets (each axis with both signs):
//   axes 0..2  n = a_{i+1} x a_{i+2}  (face i of A; seed: "OV", octant of M
//              = vertex of B against vertex of S's SOR = face of A)
//   axes 3..5  n = b_{j+1} x b_{j+2}  (face j of B against a vertex of A: "VO")
//   axes 6..14 n = a_i x b_j          (edge of A against edge of B: "EE")
// The seed's octant switches are the sign changes of the 18 triple products
// S[0][i][l] = (a_{i+1} x a_{i+2}) . b_l   (a face normal of A crossing the
//                                          great circle of B's SOR normal to b_l)
// S[1][j][l] = (b_{j+1} x b_{j+2}) . a_l   (the same with A and B exchanged);
// every projection of a generator on an axis is one of these, det A, det B or
// a structural zero, so between consecutive sign changes (a section) every
// facet's support is a fixed signed sum: the facet is a degree-6 polynomial.
// Facet k = 2*axis + (0 for +n, 1 for -n):
//   P_k(s) = +-n.d - sum_g |n.g| h_g,   d = centre(B) - centre(A),
// and the origin is inside D (the boxes intersect) iff P_k <= 0 for all k.
#pragma once

#include <array>
#include <cstdint>
#include <stdexcept>
#include <string>
#include <vector>

#include "poly.hpp"

namespace boxccd {

// Every tolerance of the solver, with its reason (mirrored by the Python
// Tolerances dataclass, which documents the defaults).
struct Tolerances {
    // Boxes closer than gap_rel * (world size of A + world size of B) count as
    // touching. Small enough that a 1e-9 relative gap is a clear miss.
    double gap_rel = 1e-12;
    // Rounding allowance: each facet's evaluation error is bounded by
    // rounding * DBL_EPSILON * (a magnitude bound of its terms), and that much
    // is added to the touching tolerance, so rounding can make the answer early,
    // never late (see README, "Guarantee").
    double rounding = 64.0;
    // Cap on advancement steps per section; each step passes one root of one
    // facet polynomial (at most 30 * 6 of them), so the cap is never reached
    // in exact arithmetic. If it is, the solver reports contact (conservative).
    int max_steps = 400;
};

// Typed input errors (translated to ValueError subclasses in Python).
struct NonFiniteError : std::runtime_error { using std::runtime_error::runtime_error; };
struct BoxError : std::runtime_error { using std::runtime_error::runtime_error; };
struct MotionError : std::runtime_error { using std::runtime_error::runtime_error; };
struct SingularMotionError : std::runtime_error {
    double t;
    SingularMotionError(const std::string &m, double t_) : std::runtime_error(m), t(t_) {}
};
struct TimeRangeError : std::runtime_error { using std::runtime_error::runtime_error; };

struct BoxInput {
    const double *lo;      // (3,) corner (X, Y, Z), the box's own frame
    const double *hi;      // (3,) corner (X', Y', Z')
    const double *coeffs;  // (3, 4, 4) row-major: M(t) = C0 + C1 t + C2 t^2
};

// Argument checks shared by every entry point; `name` starts the message
// ("a", "coeffs_b", ...). The batch entry point prefixes "row i: " itself.
void check_box(const double *lo, const double *hi, const std::string &name);
void check_motion(const double *coeffs, const std::string &name);
void check_time_range(double t0, double t1);

enum class Kind : int8_t { OV = 0, VO = 1, EE = 2 };

struct Hit {
    bool hit = false;
    bool initial = false;  // already touching at t_min
    double t = 0.0;        // in the caller's time
    double s = 0.0;        // normalised
    int facet = -1;        // 0..29: axis = facet / 2, outward normal +n (even) or -n (odd)
    // Filled when geometry is asked for: world contact point, unit normal from A
    // towards B, and the touching features as sign triples over each box's local
    // axes (-1 = lo side, +1 = hi side, 0 = the feature spans that axis).
    std::array<double, 3> point{}, normal{};
    std::array<int8_t, 3> feat_a{}, feat_b{};
};

// The two generators spanning each axis (see the file comment): a table, since
// the hot loops ask for them per axis.
inline constexpr int8_t kAxisGenerators[15][2] = {{1, 2}, {2, 0}, {0, 1}, {4, 5}, {5, 3}, {3, 4}, {0, 3}, {0, 4},
                                                  {0, 5}, {1, 3}, {1, 4}, {1, 5}, {2, 3}, {2, 4}, {2, 5}};
constexpr int axis_generator(int axis, int which) { return kAxisGenerators[axis][which]; }

// The precomputed polynomials of one query (see the file comment).
class Problem {
public:
    Problem(const BoxInput &a, const BoxInput &b, double t0, double t1, const Tolerances &tol);

    // Raises SingularMotionError if A's or B's 3x3 part degenerates in range.
    void check_regular(const char *name_a, const char *name_b) const;

    Hit solve(bool want_geometry) const;

    // Section boundaries in s: 0, the octant switches (sorted, unique), 1.
    std::vector<double> sections() const;

    // The 30 facets at s, with the topology of the section that contains s:
    // unit outward normals (30, 3), offsets (30,) (facet: n.x = offset, x in D),
    // and each facet's features as sign triples (see Hit), (30, 3) each.
    void planes(double s, double *normals, double *offsets, int8_t *feat_a, int8_t *feat_b) const;

    double t0, t1;

private:
    // One section: the topology sampled at its midpoint, and the facet
    // polynomials, built only for the facets the advancement asks about.
    struct Section {
        double lo, hi;
        // Per axis, filled on first use (ensure_axis):
        mutable int8_t sig[15][6];             // sign of n_axis . g at mid-section (0: structural)
        mutable std::array<double, 15> tau;    // touching tolerance + rounding allowance
        mutable uint32_t ready = 0;            // which axes are filled
        mutable bool mid_ready = false;        // the shared values at mid-section below
        mutable double pv_mid[20];             // the 20 triple products at mid-section
        mutable std::array<double, 3> g_mid[6];
        mutable std::array<Poly, 30> Q;        // facet polynomial minus tau: <= 0 is touching
        mutable uint32_t built = 0;            // which Q are built
    };
    // The route division, found lazily: for each of the 18 switch polynomials,
    // its next sign change after the last boundary passed (+inf: none).
    struct Switches {
        std::array<double, 18> next;
        double to = 1.0;                 // where the search ends
        double boundary() const;         // the next section end (`to` at the latest)
    };
    bool ignorable_switch(int k) const;
    // The 18 switch polynomials on an interval [mid - w, mid + w], from the
    // generators at mid: their values and derivatives at mid, and bounds over
    // the interval of each generator's length (v), and of its first and second
    // derivatives' (d1, d2).
    struct SwitchProbe {
        double w, p[18], dp[18], v[6], d1[6], d2[6];
    };
    SwitchProbe probe_switches(double from, double to) const;
    // Whether switch k keeps its sign on the probe's interval (false: not proven).
    bool switch_constant(int k, const SwitchProbe &probe) const;
    double next_switch(int k, double from, double to, const SwitchProbe &probe) const;
    Switches first_switches(double from, double to = 1.0) const;
    void pass(Switches &sw, double boundary) const;
    Section make_section(double lo, double hi) const;
    const Poly &facet_poly(const Section &sec, int facet) const;
    // The 15 axes at one time, from the generators gs and d there: each axis'
    // normal n (the cross product of its two generators, unnormalised), |n|^2,
    // n.d, and the support sum_g h_g |n.g| of the boxes' extents along n. An
    // axis has no direction (parallel edges, a flat box) when |n| <= 1e-9 times
    // the product of its generators' lengths.
    struct AxisValues {
        std::array<double, 3> n[15];
        double nn2[15], nd[15], support[15];
        bool direction[15];
    };
    void axis_values(const std::array<double, 3> *gs, const std::array<double, 3> &ds, AxisValues &v) const;
    // The 30 facets at s: q[k] = +-n.d - support - tau[axis] (<= 0: touching),
    // tau the touching tolerance at s plus the rounding allowance, and each
    // axis' |n| at s (0: no direction) to rank facets by distance. Within a
    // section the support is the section's signed sum (its signs hold there):
    // these are the facet polynomials' values, up to rounding and tau's |n|.
    struct FacetValues {
        double q[30], tau[15], len[15];
    };
    void facet_values(double s, FacetValues &f) const;
    // A sample time of the culling: the most separating axis there (unit u and
    // its gap; gap 0: none separates), and d and the generators (v = 0 and
    // 1..6) with their derivatives there, from which the Bernstein control
    // points of a piece between two samples follow without evaluating anything.
    struct Axis {
        std::array<double, 3> u{};
        double gap = 0.0;
        int facet = -1;         // the BMS facet of u (if gap > 0)
        bool searched = false;  // u and gap are set (find_axis)
        std::array<double, 3> val[7], der[7];
    };
    Axis sample_at(double s) const;  // values and derivatives only (gap 0: no axis yet)
    void find_axis(Axis &a) const;   // the most separating of the 15 axes at a's time
    // Whether the axis at lo or at hi (those asked for) keeps [lo, hi] apart.
    bool apart_on_fixed_axis(double lo, double hi, const Axis &at_lo, const Axis &at_hi, bool use_lo,
                             bool use_hi) const;
    double first_unproven(double lo, double hi, Axis &at_lo, Axis &at_hi, int depth, int &budget,
                          double &overlap, int &facet) const;
    // Pieces (2^depth at most) and new sample times per query, measured best on
    // the benchmark pairs (benchmarks/solver.py).
    static constexpr int kCullDepth = 2, kCullDepthTurning = 6, kCullBudget = 8;
    void ensure_axis(const Section &sec, int ax) const;
    // From s in the section: true with s at the first contact, or false when a
    // facet (`separating`, also a warm start on entry) keeps the section apart.
    bool advance(const Section &sec, double &s, int &last, int &separating) const;
    int best_facet(double s) const;
    void contact_geometry(const Section &sec, Hit &hit) const;

    Tolerances tol_;
    PVec g_[6];
    double h_[6];
    PVec cA_, cB_, d_;
    double gmag_[6];
    int gdeg_[6], ddeg_;  // degree classes of g_ and d_ (0: constant, else 2)
    bool turning_;        // some generator is not constant
    int normal_degree(int axis) const {  // of n_[axis], the cross product of its two generators
        return gdeg_[axis_generator(axis, 0)] + gdeg_[axis_generator(axis, 1)];
    }
    double dmag_, hmag_;
    double size_;  // world size used by gap_rel
    double noise(int ax) const {  // rounding allowance of an axis' facets
        return tol_.rounding * kEps * (dmag_ + hmag_) * gmag_[axis_generator(ax, 0)] * gmag_[axis_generator(ax, 1)];
    }
    // Cofactor terms, as polynomials: n_[0], n_[3] and the determinants come
    // with the problem (the regularity check needs them); the rest is built on
    // first use, through the accessors below. Most queries need few of them: a
    // fixed axis keeps most pairs apart, the switches on a short interval are
    // mostly proven constant from vectors, and only the root-searched facets
    // need their polynomials.
    // proj_[9q + 3i + l] = S[q][i][l] (see the file comment), proj_[18 + q] = det.
    mutable PVec n_[15];
    mutable Poly proj_[20];
    mutable Poly nd_[15];
    mutable uint32_t n_built_ = 0, proj_built_ = 0, nd_built_ = 0;  // which are built
    const PVec &normal(int ax) const;     // n_[ax]
    const Poly &projection(int k) const;  // proj_[k]
    const Poly &normal_dot_d(int ax) const;  // nd_[ax] = n_[ax] . d
};

constexpr int kDet = 18;                   // proj_[kDet + q] is det A (q = 0) or det B (q = 1)

}  // namespace boxccd
