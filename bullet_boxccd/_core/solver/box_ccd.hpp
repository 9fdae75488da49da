// Exact time of impact of two boxes under quadratic affine motion: the
// BMS algorithm. The public contract of the
// core: inputs, their checks, outcomes, and the three queries (first contact,
// route division, BMS planes at a time).
//
// t runs over [t0, t1] (the caller's t_range); results say t. The units, in the
// order a query runs them (each file maps its part of the BMS algorithm):
//   bms.hpp       the pair's Minkowski difference in its own frame: generators,
//                 15 axes, 30 facets (OV, VO, EE), cofactor polynomials
//   culling.hpp   conservative advancement on fixed separating axes
//   route.hpp     octant switches: the route division into sections
//   topology.hpp  the topology of a section: its 30 facet polynomials
//   advance.hpp   advancement over facet roots to the first contact
//   poly.hpp      polynomials and root isolation;  constants.hpp  every tolerance
#pragma once

#include <array>
#include <cstdint>
#include <limits>
#include <string>
#include <vector>

#include "solver/bms.hpp"

namespace boxccd {

// Argument checks shared by every entry point; `name` starts the message
// ("a", "coeffs_b", ...). The batch entry point prefixes "row i: " itself.
void check_box(const double *lo, const double *hi, const std::string &name);
void check_motion(const double *coeffs, const std::string &name);
void check_time_range(double t0, double t1);

// What a query found. Which fields of Hit hold in each:
//   Separated       none: the boxes stay apart over the whole range
//   Hit             t, s, facet (and the geometry when asked for)
//   Initial         the same; t = t0: touching or overlapping at the start
//   StepCap         the same, but the search hit a cap (Tolerances::max_steps,
//                   or kMaxWindows); t is early (the boxes are apart before it)
//                   and not proven to be a contact
//   ClusteredRoots  the same, but the last facet root was one of a cluster that
//                   doubles cannot separate; t is the cluster's start (early)
//   NonFinite       none: an input row was not finite (step-path queries only;
//                   the solver's own entry points raise NonFiniteError instead)
// A degraded outcome (StepCap, ClusteredRoots) is never reported as Hit.
enum class Outcome : int8_t { Separated = 0, Hit = 1, Initial = 2, StepCap = 3, ClusteredRoots = 4, NonFinite = 5 };
constexpr int kOutcomes = 6;
constexpr bool is_contact(Outcome o) {
    return o == Outcome::Hit || o == Outcome::Initial || o == Outcome::StepCap || o == Outcome::ClusteredRoots;
}

struct Hit {
    Outcome outcome = Outcome::Separated;
    double t = std::numeric_limits<double>::quiet_NaN();  // in the caller's time
    double s = std::numeric_limits<double>::quiet_NaN();  // normalised
    int facet = -1;  // 0..29: axis = facet / 2, outward normal +n (even) or -n (odd)
    // Filled when geometry is asked for: world contact point, unit normal from A
    // towards B, and the touching features as sign triples over each box's local
    // axes (-1 = lo side, +1 = hi side, 0 = the feature spans that axis).
    Vec3 point{}, normal{};
    std::array<int8_t, 3> feat_a{}, feat_b{};
    bool contact() const { return is_contact(outcome); }
    bool initial() const { return contact() && s == 0.0; }
};

// One query on one pair. Not copyable: the cofactor cache refers to the pair.
class Query {
public:
    Query(const BoxInput &a, const BoxInput &b, double t0, double t1, const Tolerances &tol);
    Query(const Query &) = delete;
    Query &operator=(const Query &) = delete;

    // Raises SingularMotionError if A's or B's 3x3 part degenerates in range
    // (`floor`: see boxccd::check_regular).
    void check_regular(const char *name_a, const char *name_b, const double *floor = nullptr) {
        boxccd::check_regular(pair_, name_a, name_b, floor);
    }

    Hit solve(bool want_geometry);

    // Section boundaries in s: 0, the octant switches (sorted, unique), 1.
    std::vector<double> sections();

    // The 30 facets at s, with the topology of the section that contains s:
    // unit outward normals (30, 3), offsets (30,) (facet: n.x = offset, x in D),
    // and each facet's features as sign triples (see Hit), (30, 3) each.
    void planes(double s, double *normals, double *offsets, int8_t *feat_a, int8_t *feat_b);

    const Pair &pair() const { return pair_; }

private:
    void contact_geometry(const int8_t *sig, Hit &hit);

    Pair pair_;
    Cofactors cof_;
};

}  // namespace boxccd
