#include "solver/entry.hpp"

#include <algorithm>
#include <limits>

namespace boxccd {

BoxData make_box(const double *lo, const double *hi, const std::string &name) {
    check_box(lo, hi, name);
    BoxData b;
    std::copy(lo, lo + 3, b.lo);
    std::copy(hi, hi + 3, b.hi);
    return b;
}

MotionData make_motion(const double *coeffs, const std::string &name) {
    check_motion(coeffs, name);
    MotionData m;
    std::copy(coeffs, coeffs + 48, m.c);
    m.det_floor = det_floor01(m.c);
    return m;
}

namespace {

// A box and its motion as the core's input, once the time range is checked.
BoxInput input_in_range(const BoxData &box, const MotionData &m, double t0, double t1) {
    check_time_range(t0, t1);
    return {box.lo, box.hi, m.c};
}

}  // namespace

CheckedQuery::CheckedQuery(const BoxData &a, const MotionData &m_a, const BoxData &b, const MotionData &m_b,
                           double t0_, double t1_, const Tolerances &tol)
    : q(input_in_range(a, m_a, t0_, t1_), {b.lo, b.hi, m_b.c}, t0_, t1_, tol), t0(t0_), t1(t1_) {
    const double floor[2] = {m_a.det_floor, m_b.det_floor};
    q.check_regular("m_a", "m_b", floor);
}

std::vector<double> CheckedQuery::section_times() {
    std::vector<double> s = q.sections();
    for (double &x : s) x = x >= 1.0 ? t1 : t0 + x * (t1 - t0);
    return s;
}

void CheckedQuery::planes_at(double t, double *normals, double *offsets, int8_t *feat_a, int8_t *feat_b) {
    if (!(t >= t0 && t <= t1))
        throw TimeRangeError("t = " + std::to_string(t) + " lies outside t_range = (" + std::to_string(t0) + ", " +
                             std::to_string(t1) + ")");
    q.planes((t - t0) / (t1 - t0), normals, offsets, feat_a, feat_b);
}

void solve_batch(const double *lo_a, const double *hi_a, const double *c_a, const double *lo_b, const double *hi_b,
                 const double *c_b, size_t n, double t0, double t1, const Tolerances &tol, double *out,
                 int8_t *states) {
    check_time_range(t0, t1);
    validate(tol);
    enum class Bad { NonFinite, Box, Motion, Singular };
    std::vector<size_t> bad;
    std::string first_msg;
    Bad first_kind = Bad::NonFinite;
    double first_t = 0.0;
    const auto row_error = [&](size_t i, Bad kind, const std::string &msg, double t = 0.0) {
        if (bad.empty()) first_msg = msg, first_kind = kind, first_t = t;
        bad.push_back(i);
    };
    for (size_t i = 0; i < n; ++i) {
        const BoxInput a{lo_a + 3 * i, hi_a + 3 * i, c_a + 48 * i};
        const BoxInput b{lo_b + 3 * i, hi_b + 3 * i, c_b + 48 * i};
        out[i] = std::numeric_limits<double>::quiet_NaN();
        if (states) states[i] = static_cast<int8_t>(Outcome::Separated);
        // Messages get their "row i: " prefix only when a row is bad (no
        // allocation on the good path).
        const auto row = [i](const std::exception &e) { return "row " + std::to_string(i) + ": " + e.what(); };
        try {
            check_box(a.lo, a.hi, "lo_a/hi_a");
            check_box(b.lo, b.hi, "lo_b/hi_b");
            check_motion(a.coeffs, "coeffs_a");
            check_motion(b.coeffs, "coeffs_b");
            Query p(a, b, t0, t1, tol);
            p.check_regular("coeffs_a", "coeffs_b");
            if (!bad.empty()) continue;  // keep collecting bad rows, skip the work
            const Hit h = p.solve(false);
            if (h.contact()) out[i] = h.t;
            if (states) states[i] = static_cast<int8_t>(h.outcome);
        } catch (const NonFiniteError &e) { row_error(i, Bad::NonFinite, row(e)); }
        catch (const BoxError &e) { row_error(i, Bad::Box, row(e)); }
        catch (const MotionError &e) { row_error(i, Bad::Motion, row(e)); }
        catch (const SingularMotionError &e) { row_error(i, Bad::Singular, row(e), e.t); }
    }
    if (bad.empty()) return;
    std::string rows;
    for (size_t k = 0; k < bad.size() && k < 20; ++k) rows += (k ? ", " : "") + std::to_string(bad[k]);
    if (bad.size() > 20) rows += ", ...";
    const std::string msg = first_msg + " [" + std::to_string(bad.size()) + " bad row(s): " + rows + "]";
    switch (first_kind) {
        case Bad::NonFinite: throw NonFiniteError(msg);
        case Bad::Box: throw BoxError(msg);
        case Bad::Motion: throw MotionError(msg);
        case Bad::Singular: break;
    }
    throw SingularMotionError(msg, first_t);
}

}  // namespace boxccd
