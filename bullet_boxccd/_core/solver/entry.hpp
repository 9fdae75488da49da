// The solver's entry points as the Python API calls them: boxes and motions
// validated once (the Python Box and QuadraticMotion hold them), a checked query
// on them, and the batch query with its row checks and one error for all bad rows.
#pragma once

#include <cstddef>
#include <cstdint>
#include <string>
#include <vector>

#include "solver/box_ccd.hpp"

namespace boxccd {

// A validated box and motion (copies of the caller's arrays).
struct BoxData {
    double lo[3], hi[3];
};
struct MotionData {
    double c[48];
    double det_floor;  // det_floor01(c): |det| of the 3x3 part on [0, 1] is at least this
};

// Throw BoxError / MotionError / NonFiniteError (message starting with `name`) for bad input.
BoxData make_box(const double *lo, const double *hi, const std::string &name);
MotionData make_motion(const double *coeffs, const std::string &name);

// A checked query on validated boxes and motions: the time range is checked first
// (so that its message comes first), then the motions' regularity on it (built in
// place: a Query is not copyable).
struct CheckedQuery {
    Query q;
    double t0, t1;
    CheckedQuery(const BoxData &a, const MotionData &m_a, const BoxData &b, const MotionData &m_b, double t0,
                 double t1, const Tolerances &tol);
    // The route division in the caller's time: t0, the octant switches, t1.
    std::vector<double> section_times();
    // The 30 planes at time t of the range (TimeRangeError outside it): see Query::planes.
    void planes_at(double t, double *normals, double *offsets, int8_t *feat_a, int8_t *feat_b);
};

// n pairs as rows of arrays (lo, hi: (n, 3); coeffs: (n, 3, 4, 4)). Every row is
// checked; if any is bad, the error of the first bad row's kind is thrown, its
// message followed by the count and indices (up to 20) of all bad rows. Else each
// row's contact time goes to out (NaN: apart) and, if states is not null, its
// Outcome. Runs no Python: callers may release the GIL around it.
void solve_batch(const double *lo_a, const double *hi_a, const double *c_a, const double *lo_b, const double *hi_b,
                 const double *c_b, size_t n, double t0, double t1, const Tolerances &tol, double *out,
                 int8_t *states);

}  // namespace boxccd
