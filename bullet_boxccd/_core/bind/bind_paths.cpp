// The step paths' bindings: boxes on Bullet's within-step paths as path rows
// (paths/step_path.hpp), and as BoxPath objects of either kind with the first
// touch, depth and separation of two of them (paths/box_path.hpp). Arrays come as
// float64 C-contiguous; shapes are checked by nanobind (rows) or `expect`.
#include <nanobind/stl/tuple.h>

#include <algorithm>
#include <cmath>
#include <limits>
#include <string>

#include "bind/common.hpp"
#include "paths/box_path.hpp"
#include "paths/contact_judge.hpp"
#include "paths/step_path.hpp"

namespace boxccd::bind {

namespace {

using PathRows = In<-1, kPathBoxSize>;

// ------------------------------------------------------------------ path rows
Out<double, -1, 6> py_swept_bounds(const PathRows &boxes) {
    const size_t n = boxes.shape(0);
    auto [out, owner] = new_buffer<double>(6 * n);
    for (size_t i = 0; i < n; ++i) swept_bounds(boxes.data() + kPathBoxSize * i, out + 6 * i, out + 6 * i + 3);
    return Out<double, -1, 6>(out, {n, 6}, owner);
}

// (n, 4, 4) poses of path rows' boxes at taus (one each).
Out<double, -1, 4, 4> py_row_poses(const PathRows &rows, const In<-1> &taus) {
    const size_t n = rows.shape(0);
    if (taus.shape(0) != n) throw nb::value_error("rows and taus differ in length");
    auto [out, owner] = new_buffer<double>(16 * n);
    for (size_t i = 0; i < n; ++i) row_pose(rows.data() + kPathBoxSize * i, taus.data()[i], out + 16 * i);
    return Out<double, -1, 4, 4>(out, {n, 4, 4}, owner);
}

// Path rows restricted to the window [lo, hi] of the step.
Out<double, -1, kPathBoxSize> py_window_rows(const PathRows &rows, double lo, double hi) {
    const size_t n = rows.shape(0);
    auto [out, owner] = new_buffer<double>(kPathBoxSize * n);
    for (size_t i = 0; i < n; ++i) window_row(rows.data() + kPathBoxSize * i, lo, hi, out + kPathBoxSize * i);
    return Out<double, -1, kPathBoxSize>(out, {n, size_t(kPathBoxSize)}, owner);
}

// (coeffs (3, 4, 4), error bound) of one box's path over [lo, hi].
nb::tuple py_fit_path(const In<kPathBoxSize> &box, double lo, double hi) {
    auto [out, owner] = new_buffer<double>(48);
    const double err = fit_path(box.data(), lo, hi, out);
    return nb::make_tuple(Out<double, 3, 4, 4>(out, {3, 4, 4}, owner), err);
}

// Column layouts (name -> (start, stop)) of the frame state and the path row.
nb::dict layouts() {
    using fs = FrameState;
    using pr = PathRow;
    nb::dict state, row, out;
    state["position"] = nb::make_tuple(fs::kPosition, fs::kOrientation);
    state["orientation"] = nb::make_tuple(fs::kOrientation, fs::kVelocity);
    state["velocity"] = nb::make_tuple(fs::kVelocity, fs::kAngularVelocity);
    state["angular_velocity"] = nb::make_tuple(fs::kAngularVelocity, fs::kSize);
    row["pose_after"] = nb::make_tuple(pr::kPoseAfter, pr::kDisplacement);
    row["displacement"] = nb::make_tuple(pr::kDisplacement, pr::kAxis);
    row["axis"] = nb::make_tuple(pr::kAxis, pr::kAngle);
    row["angle"] = nb::make_tuple(pr::kAngle, pr::kBoxInFrame);
    row["box_in_frame"] = nb::make_tuple(pr::kBoxInFrame, pr::kHalfExtents);
    row["half_extents"] = nb::make_tuple(pr::kHalfExtents, pr::kSize);
    out["frame_state"] = state;
    out["path_row"] = row;
    return out;
}

// ------------------------------------------------------------------ BoxPaths
RowBoxPath make_row_box(const Doubles &row) {
    expect(row, "row", {kPathBoxSize});
    for (size_t i = 0; i < size_t(kPathBoxSize); ++i)
        if (!std::isfinite(row.data()[i]))
            throw nb::value_error(("row: column " + std::to_string(i) + " is not finite").c_str());
    return RowBoxPath(row.data());
}

Out<double, 4, 4> path_pose(const BoxPath &path, double tau) {
    check_tau(tau);
    double *out;
    auto a = new_array<4, 4>({4, 4}, out);
    path.pose(tau, out);
    return a;
}

Out<double, -1, 4, 4> path_poses(const BoxPath &path, const Doubles &taus) {
    expect(taus, "taus", {-1});
    const size_t n = taus.shape(0);
    for (size_t k = 0; k < n; ++k) check_tau(taus.data()[k]);
    double *out;
    auto a = new_array<-1, 4, 4>({n, 4, 4}, out);
    for (size_t k = 0; k < n; ++k) path.pose(taus.data()[k], out + 16 * k);
    return a;
}

nb::tuple path_fit(const BoxPath &path, double lo, double hi) {
    check_piece(lo, hi);
    double *out;
    auto coeffs = new_array<3, 4, 4>({3, 4, 4}, out);
    const double grow = path.fit(lo, hi, out);
    return nb::make_tuple(coeffs, grow);
}

int path_pieces(const BoxPath &path, double fit_tolerance) {
    check_fit_tolerance(fit_tolerance);
    return path.pieces(fit_tolerance);
}

Out<double, 3> path_half_extents(const BoxPath &path) {
    double *out;
    auto a = new_array<3>({3}, out);
    std::copy(path.half_extents(), path.half_extents() + 3, out);
    return a;
}

Out<double, 6> bounds_of(const BoxPath &path, int pieces) {
    if (pieces < 1 || pieces > 4096)
        throw nb::value_error(("pieces must be in [1, 4096], got " + std::to_string(pieces)).c_str());
    double *out;
    auto a = new_array<6>({6}, out);
    path_bounds(path, pieces, out, out + 3);
    return a;
}

// (first touch, solver calls), or with `state` (first touch, its Outcome as int, solver calls).
nb::tuple paths_first_touch(const BoxPath &a, const BoxPath &b, double fit_tolerance, const Tolerances &tol,
                            bool state) {
    check_fit_tolerance(fit_tolerance);
    long solves = 0;
    double t;
    Outcome outcome;
    {
        nb::gil_scoped_release release;
        t = first_touch(a, b, fit_tolerance, tol, solves, outcome);
    }
    if (!state) return nb::make_tuple(t, solves);
    return nb::make_tuple(t, static_cast<int>(outcome), solves);
}

// (t, solves, Contact or None) of paths_first_touch: the contact on the fitted
// motions (None: apart). Its outcome says what happened (a degraded one is early
// and not proven); a touch where no facet was found (at the start, or on a piece
// too fast to fit) has feature None and a NaN point and normal.
nb::tuple py_paths_contact(const BoxPath &a, const BoxPath &b, double fit_tolerance, const Tolerances &tol) {
    check_fit_tolerance(fit_tolerance);
    long solves = 0;
    Hit h;
    Outcome outcome;
    double t;
    {
        nb::gil_scoped_release release;
        t = first_touch(a, b, fit_tolerance, tol, solves, outcome, std::numeric_limits<double>::quiet_NaN(), &h);
    }
    return nb::make_tuple(t, solves, hit_result(h));
}

// Like solve: a Contact (whose outcome says what happened) or None: window_contact
// over [lo, hi].
nb::object paths_window_contact(const BoxPath &a, const BoxPath &b, double lo, double hi, const Tolerances &tol) {
    if (!(0.0 <= lo && lo <= hi && hi <= 1.0))
        throw nb::value_error(
            ("expected 0 <= lo <= hi <= 1, got lo = " + std::to_string(lo) + ", hi = " + std::to_string(hi)).c_str());
    validate(tol);
    return hit_result(window_contact(a, b, lo, hi, tol));
}

// (contact or None, wrong, depth time, normal at the window's end (3,), parted, again, fresh, depth at the end):
// judge_contact of rows a, b over the window [lo, 1].
nb::tuple py_judge_contact(const In<kPathBoxSize> &row_a, const In<kPathBoxSize> &row_b, double lo, double s_touch,
                           bool judge, bool with_time, bool after_impact, double penetration, double impact_depth,
                           double depth_tolerance, double creep, const Tolerances &tol) {
    if (!(0.0 <= lo && lo < 1.0 && 0.0 <= s_touch && s_touch <= 1.0))
        throw nb::value_error(("expected 0 <= lo < 1 and 0 <= s_touch <= 1, got lo = " + std::to_string(lo) +
                               ", s_touch = " + std::to_string(s_touch))
                                  .c_str());
    validate(tol);
    const Judgement j = judge_contact(row_a.data(), row_b.data(), lo, s_touch, judge, with_time, after_impact,
                                      penetration, impact_depth, depth_tolerance, creep, tol);
    double *normal;
    auto n = new_array<3>({3}, normal);
    std::copy(j.normal_at_end.begin(), j.normal_at_end.end(), normal);
    return nb::make_tuple(hit_result(j.contact), j.wrong, j.depth_time, n, j.parted, j.again, j.fresh, j.depth_end);
}

// (touch, act, contact or None, point (3,), normal (3,), initial, pressing, solves):
// judge_link_contact of two box paths (touch and act NaN where there is none; point and
// normal are the contact's where it has no facet).
nb::tuple py_judge_link_contact(const BoxPath &a, const BoxPath &b, double fit_tolerance, double penetration,
                                double creep, const Tolerances &tol) {
    check_fit_tolerance(fit_tolerance);
    validate(tol);
    LinkJudgement j;
    {
        nb::gil_scoped_release release;
        j = judge_link_contact(a, b, fit_tolerance, penetration, creep, tol);
    }
    double *point, *normal;
    auto p = new_array<3>({3}, point);
    auto n = new_array<3>({3}, normal);
    std::copy(j.point.begin(), j.point.end(), point);
    std::copy(j.normal.begin(), j.normal.end(), normal);
    return nb::make_tuple(j.touch, j.act, hit_result(j.contact), p, n, j.initial, j.pressing, j.solves);
}

double paths_depth(const BoxPath &a, const BoxPath &b, double tau) {
    check_tau(tau);
    return path_depth(a, b, tau);
}

// (depth, axis (3,)): pose_separation of the two boxes at tau.
nb::tuple paths_separation(const BoxPath &a, const BoxPath &b, double tau) {
    check_tau(tau);
    double *axis;
    auto out = new_array<3>({3}, axis);
    const double depth = path_separation(a, b, tau, axis);
    return nb::make_tuple(depth, out);
}

double paths_first_depth(const BoxPath &a, const BoxPath &b, double from, double target) {
    check_tau(from);
    if (!std::isfinite(target)) throw nb::value_error("target must be finite");
    nb::gil_scoped_release release;
    return first_depth(a, b, from, target);
}

}  // namespace

void bind_paths(nb::module_ &m) {
    m.def("layouts", &layouts);
    m.def("swept_bounds", &py_swept_bounds, nb::arg("boxes"));
    m.def("row_poses", &py_row_poses, nb::arg("rows"), nb::arg("taus"));
    m.def("window_rows", &py_window_rows, nb::arg("rows"), nb::arg("lo"), nb::arg("hi"));
    m.def("fit_path", &py_fit_path, nb::arg("box"), nb::arg("lo"), nb::arg("hi"));

    nb::class_<BoxPath>(m, "BoxPath", "A box on a within-step path (box_path.hpp); see RowBoxPath, LinkBoxPath.")
        .def("pose", &path_pose, nb::arg("tau"))
        .def("poses", &path_poses, nb::arg("taus"))
        .def("fit", &path_fit, nb::arg("lo"), nb::arg("hi"))
        .def("pieces", &path_pieces, nb::arg("fit_tolerance"))
        .def("bounds", &bounds_of, nb::arg("pieces") = 4, "(6,) world bounds (lo, hi) of the box over the step.")
        .def_prop_ro("half_extents", &path_half_extents, nb::rv_policy::move);
    nb::class_<RowBoxPath, BoxPath>(m, "RowBoxPath", "A box on a free frame's path row.")
        .def("__init__", [](RowBoxPath *self, const Doubles &row) { new (self) RowBoxPath(make_row_box(row)); },
             nb::arg("row"));
    m.def("paths_first_touch", &paths_first_touch, nb::arg("a"), nb::arg("b"), nb::arg("fit_tolerance"),
          nb::arg("tolerances"), nb::arg("state") = false);
    m.def("paths_contact", &py_paths_contact, nb::arg("a"), nb::arg("b"), nb::arg("fit_tolerance"),
          nb::arg("tolerances"));
    m.def("paths_window_contact", &paths_window_contact, nb::arg("a"), nb::arg("b"), nb::arg("lo"), nb::arg("hi"),
          nb::arg("tolerances"));
    m.def("judge_contact", &py_judge_contact, nb::arg("row_a"), nb::arg("row_b"), nb::arg("lo"), nb::arg("s_touch"),
          nb::arg("judge"), nb::arg("with_time"), nb::arg("after_impact"), nb::arg("penetration"),
          nb::arg("impact_depth"), nb::arg("depth_tolerance"), nb::arg("creep"), nb::arg("tolerances"));
    m.def("judge_link_contact", &py_judge_link_contact, nb::arg("a"), nb::arg("b"), nb::arg("fit_tolerance"),
          nb::arg("penetration"), nb::arg("creep"), nb::arg("tolerances"));
    m.def("paths_depth", &paths_depth, nb::arg("a"), nb::arg("b"), nb::arg("tau"));
    m.def("paths_relative_move", &relative_move, nb::arg("a"), nb::arg("b"),
          "How far the smaller box's corners move in the other's frame from the step's start to its end.");
    m.def("paths_separation", &paths_separation, nb::arg("a"), nb::arg("b"), nb::arg("tau"));
    m.def("paths_first_depth", &paths_first_depth, nb::arg("a"), nb::arg("b"), nb::arg("from_tau"), nb::arg("target"));
}

}  // namespace boxccd::bind
