// The Minkowski difference of one pair of boxes: its generators, its 15 axes
// and 30 facets (the BMS planes), as functions of the normalised time s.
//
// Time: callers give t in [t0, t1]; here everything runs on s = (t - t0) /
// (t1 - t0) in [0, 1].
//
// The BMS algorithm's vocabulary -> code. Its static box S is box A, its moving box M
// is box B. Both may move: instead of the algorithm's relative motion M1 M2^-1 (a
// rational function of t) both stay in one frame, where the Minkowski
// difference D(s) = A(s) + (-B(s)) has the same facets, and every quantity
// stays a polynomial in s. A box has three edge directions (the generators):
// a_i(s) = column i of A's 3x3 part, b_j(s) likewise; g[0..2] = a_0..a_2 and
// g[3..5] = b_0..b_2. D is a zonotope with these six generators, so it has 15
// facet axes, each spanned by two generators, and 30 facets (each axis with
// both signs):
//   axes 0..2  n = a_{i+1} x a_{i+2}  (face i of A against a vertex of B; the
//              the algorithm's OV: octant of M's SOR, vertex of S's SOR)
//   axes 3..5  n = b_{j+1} x b_{j+2}  (face j of B against a vertex of A: VO)
//   axes 6..14 n = a_i x b_j          (edge of A against edge of B: EE)
// Facet k = 2 axis + (0 for +n, 1 for -n):
//   P_k(s) = +-n.d - sum_g |n.g| h_g,   d = centre(B) - centre(A),
// and the boxes intersect iff P_k <= 0 for all k.
//
// The frame: a shared translation (A's centre at s = 0, computed exactly in
// double-double and rounded) is taken off both boxes, so that d and every
// rounding allowance scale with the pair's own extent and motion, not with its
// distance from the world origin (a scene 1e6 box sizes away loses nothing).
#pragma once

#include <cstdint>
#include <stdexcept>
#include <string>

#include "solver/constants.hpp"
#include "solver/poly.hpp"
#include "solver/vec.hpp"

namespace boxccd {

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

// The kind of a BMS facet, from the BMS algorithm: the pairs of features that make it.
enum class Kind : int8_t { OV = 0, VO = 1, EE = 2 };
constexpr Kind axis_kind(int axis) { return axis < 3 ? Kind::OV : axis < 6 ? Kind::VO : Kind::EE; }
constexpr Kind facet_kind(int facet) { return axis_kind(facet / 2); }

// The two generators spanning each axis (see the file comment).
inline constexpr int8_t kAxisGenerators[15][2] = {{1, 2}, {2, 0}, {0, 1}, {4, 5}, {5, 3}, {3, 4}, {0, 3}, {0, 4},
                                                  {0, 5}, {1, 3}, {1, 4}, {1, 5}, {2, 3}, {2, 4}, {2, 5}};
constexpr int axis_generator(int axis, int which) { return kAxisGenerators[axis][which]; }

// The 18 octant-switch functions and the two determinants share one index:
// k = 9q + 3i + l is S[q][i][l] = (face normal i of box q) . (generator l of the
// other box), a face normal crossing a great circle of the other box's SOR (an
// octant switch); k = kDet + q is det of box q.
constexpr int kSwitches = 18, kDet = 18;

// The projection n_axis . g as one of those 20 functions (or a structural zero: a
// generator that spans the axis' own facet), with its sign.
struct Projection {
    int8_t index;  // -1 for a structural zero
    int8_t sign;
};
struct ProjectionTable {
    Projection p[15][6]{};
    constexpr ProjectionTable() {
        for (int ax = 0; ax < 15; ++ax)
            for (int g = 0; g < 6; ++g) p[ax][g] = compute(ax, g);
    }
    static constexpr Projection compute(int axis, int g) {
        if (axis_kind(axis) == Kind::OV) {
            if (g >= 3) return {static_cast<int8_t>(3 * axis + (g - 3)), 1};
            return {static_cast<int8_t>(g == axis ? kDet : -1), 1};
        }
        if (axis_kind(axis) == Kind::VO) {
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
inline constexpr ProjectionTable kProjection;

// Bounds over [0, 1] of a generator's derivatives: |g'| (linear in s, so its
// largest norm is at an end) and |g''| = 2 |c2|.
struct GeneratorBounds {
    double d1, d2;
};

// The pair, set up for one query: both boxes' generators and centres as curves
// in s, in the pair's frame, and the magnitudes that bound their rounding.
struct Pair {
    Pair(const BoxInput &a, const BoxInput &b, double t0, double t1, const Tolerances &tol);

    double t0, t1;
    Tolerances tol;
    Curve g[6];         // generators a_0..a_2, b_0..b_2
    double h[6];        // half extents along them
    Curve cA, cB, d;    // centres in the pair's frame, and d = cB - cA
    Vec3 origin;        // the pair's frame: world = origin + local
    double gmag[6];     // magnitude of each generator curve (bounds |g| on [0, 1])
    GeneratorBounds gbounds[6];
    int gdeg[6], ddeg;  // degree classes: 0 (constant) or 2
    bool turning;       // some generator is not constant
    double dmag;        // bounds |d| and the rounding of the centres' construction
    double hmag;        // sum_g h_g gmag_g
    double size;        // world size used by gap_rel: sum_g h_g |g_g(1/2)|

    // Rounding allowance of each axis' facets (unnormalised, like the facets):
    // rounding eps (dmag + hmag) |g_a| |g_b| for the axis' generators a, b.
    double noise[15];
    // The same for a fixed unit direction (culling): gap_rel * size and the
    // rounding of a unit projection of the whole configuration.
    double unit_margin;

    int normal_degree(int axis) const { return gdeg[axis_generator(axis, 0)] + gdeg[axis_generator(axis, 1)]; }
    // Touching tolerance plus rounding allowance of an axis whose normal has length len.
    double tau(int axis, double len) const { return tol.gap_rel * size * len + noise[axis]; }
    double time(double s) const { return s >= 1.0 ? t1 : t0 + s * (t1 - t0); }
};

// The 15 axes at one time, from the generators gs and d there: for each axis
// (normal n = the cross product of its two generators, unnormalised) |n|^2, n.d,
// the support sum_g h_g |n.g|, and whether it has a direction (kParallel).
struct AxesAt {
    double nn2[15], nd[15], support[15];
    bool direction[15];
};
void axes_at(const Pair &pair, const Vec3 *gs, const Vec3 &d, AxesAt &v);
inline Vec3 axis_normal(const Vec3 *gs, int axis) { return cross3(gs[axis_generator(axis, 0)], gs[axis_generator(axis, 1)]); }

// The cofactor polynomials of one query, built on first use: most queries need
// few of them (the culling and the facet values work from vectors; only
// root-searched facets and unproven octant switches need polynomials).
class Cofactors {
public:
    explicit Cofactors(const Pair &pair);
    const PVec &normal(int axis);   // n_axis(s)
    const Poly &projection(int k);  // switch function S[q][i][l], k = 9q + 3i + l < kSwitches

private:
    const Pair &pair_;
    PVec n_[15];
    Poly proj_[kSwitches];
    uint32_t n_built_ = 0, proj_built_ = 0;
};

// A lower bound of |det| of a motion's 3x3 part over t in [0, 1] (the smallest
// Bernstein control point of the determinant times its sign at t = 0; 0 when that
// is not positive), from its (3, 4, 4) coefficients. A motion object computes it
// once, so that queries on t_range (0, 1) can skip their own regularity check.
double det_floor01(const double *coeffs);

// Raises SingularMotionError if A's or B's 3x3 part degenerates in range.
// `floor` (optional): det_floor01 of A's and B's motions; on t_range (0, 1) a box
// whose floor exceeds twice the check's rounding allowance is regular without the
// check (the check would compute the same control points, less that allowance).
void check_regular(const Pair &pair, const char *name_a, const char *name_b, const double *floor = nullptr);

}  // namespace boxccd
