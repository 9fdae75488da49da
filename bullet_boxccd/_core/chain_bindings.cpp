// nanobind bindings of the link paths (chain.hpp) and of the first touch of two
// boxes on any paths (box_path.hpp). bindings.cpp calls bind_chain once. Arrays
// come as float64 / int64 C-contiguous (bullet_boxccd/pybullet_ccd/chain.py
// converts); shapes and values are checked here and raise ValueError (wrong
// shape or value) or IndexError (an index out of range) saying which argument.
#include <nanobind/nanobind.h>
#include <nanobind/ndarray.h>
#include <nanobind/stl/tuple.h>

#include <cmath>
#include <initializer_list>
#include <limits>
#include <string>

#include "box_path.hpp"
#include "chain.hpp"

namespace nb = nanobind;
using namespace boxccd;

namespace {

using Doubles = nb::ndarray<const double, nb::c_contig, nb::device::cpu>;
using Ints = nb::ndarray<const int64_t, nb::c_contig, nb::device::cpu>;
template <long... Shape>
using Out = nb::ndarray<nb::numpy, double, nb::shape<Shape...>>;

template <class A>
std::string shape_of(const A &a) {
    std::string s = "(";
    for (size_t i = 0; i < a.ndim(); ++i) s += (i ? ", " : "") + std::to_string(a.shape(i));
    return s + (a.ndim() == 1 ? ",)" : ")");
}

// Raises ValueError unless a has the shape (-1: any length).
template <class A>
void expect(const A &a, const char *name, std::initializer_list<long> shape) {
    bool ok = a.ndim() == shape.size();
    size_t i = 0;
    for (const long n : shape) ok = ok && (n < 0 || (i < a.ndim() && long(a.shape(i)) == n)), ++i;
    if (ok) return;
    std::string want = "(";
    i = 0;
    for (const long n : shape) want += (i++ ? ", " : "") + (n < 0 ? std::string("n") : std::to_string(n));
    throw nb::value_error((std::string(name) + ": expected shape " + want + (shape.size() == 1 ? ",)" : ")") +
                           ", got " + shape_of(a))
                              .c_str());
}

template <long... Shape>
Out<Shape...> new_array(std::initializer_list<size_t> shape, double *&data) {
    size_t n = 1;
    for (const size_t s : shape) n *= s;
    data = new double[n ? n : 1];
    nb::capsule owner(data, [](void *p) noexcept { delete[] static_cast<double *>(p); });
    return Out<Shape...>(data, shape.size(), shape.begin(), owner);
}

void check_tau(double tau) {
    if (!std::isfinite(tau)) throw nb::value_error(("tau must be finite, got " + std::to_string(tau)).c_str());
}

void check_piece(double lo, double hi) {
    if (!(0.0 <= lo && lo < hi && hi <= 1.0))
        throw nb::value_error(
            ("expected 0 <= lo < hi <= 1, got lo = " + std::to_string(lo) + ", hi = " + std::to_string(hi)).c_str());
}

void check_link(const Chain &chain, int link) {
    if (link < 0 || link >= chain.n_links())
        throw nb::index_error(("link " + std::to_string(link) + " is not one of the chain's " +
                               std::to_string(chain.n_links()) + " links")
                                  .c_str());
}

Chain make_chain(const Ints &parent, const Ints &joint_type, const Doubles &axis, const Doubles &parent_pos,
                 const Doubles &parent_orn, const Doubles &inertial_pos, const Doubles &inertial_orn,
                 const Ints &q_index, const Ints &qdot_index) {
    expect(parent, "parent", {-1});
    const long n = long(parent.shape(0));
    expect(joint_type, "joint_type", {n});
    expect(axis, "axis", {n, 3});
    expect(parent_pos, "parent_pos", {n, 3});
    expect(parent_orn, "parent_orn", {n, 4});
    expect(inertial_pos, "inertial_pos", {n, 3});
    expect(inertial_orn, "inertial_orn", {n, 4});
    expect(q_index, "q_index", {n});
    expect(qdot_index, "qdot_index", {n});
    return Chain(n, parent.data(), joint_type.data(), axis.data(), parent_pos.data(), parent_orn.data(),
                 inertial_pos.data(), inertial_orn.data(), q_index.data(), qdot_index.data());
}

ChainMotion make_motion(const Chain &chain, const Doubles &state, const Doubles &q, const Doubles &qdot, double dt) {
    expect(state, "state", {kFrameStateSize});
    expect(q, "q", {chain.n_q()});
    expect(qdot, "qdot", {chain.n_qdot()});
    return ChainMotion(chain, state.data(), q.data(), qdot.data(), dt);
}

Out<-1, 7> link_poses(const ChainMotion &motion, double tau) {
    check_tau(tau);
    const size_t n = size_t(motion.chain().n_links());
    double *out;
    auto a = new_array<-1, 7>({n, 7}, out);
    motion.link_poses(tau, out);
    return a;
}

Out<7> link_pose(const ChainMotion &motion, int link, double tau) {
    check_tau(tau);
    check_link(motion.chain(), link);
    double *out;
    auto a = new_array<7>({7}, out);
    motion.link_pose(link, tau, out);
    return a;
}

Out<7> base_pose(const ChainMotion &motion, double tau) {
    check_tau(tau);
    double *out;
    auto a = new_array<7>({7}, out);
    motion.base_pose(tau, out);
    return a;
}

// (n, 13) frame-state rows of the given links (-1: the base): the pose after the
// step, then the velocities (v, w) that carry the pose before the step to it in dt
// linearly and about a fixed axis at a constant rate: the chord of the link's step.
Out<-1, 13> frame_rows(const ChainMotion &motion, const Ints &links, double dt) {
    expect(links, "links", {-1});
    if (!(dt > 0.0) || !std::isfinite(dt)) throw nb::value_error("dt must be finite and > 0");
    const size_t n = links.shape(0);
    for (size_t k = 0; k < n; ++k)
        if (links.data()[k] != -1) check_link(motion.chain(), int(links.data()[k]));
    double *out;
    auto a = new_array<-1, 13>({n, 13}, out);
    for (size_t k = 0; k < n; ++k) {
        const int link = int(links.data()[k]);
        double p0[7], *p1 = out + 13 * k;
        if (link == -1) {
            motion.base_pose(0.0, p0);
            motion.base_pose(1.0, p1);
        } else {
            motion.link_pose(link, 0.0, p0);
            motion.link_pose(link, 1.0, p1);
        }
        // The chord as a move between two poses (step_path.hpp: the turn the short way round).
        double row[kPathBoxSize];
        const double identity[16] = {1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1}, unit[3] = {1, 1, 1};
        path_row_between(p0, p1, identity, unit, row);
        for (int i = 0; i < 3; ++i) {
            p1[7 + i] = row[PathRow::kDisplacement + i] / dt;
            p1[10 + i] = row[PathRow::kAxis + i] * row[PathRow::kAngle] / dt;
        }
    }
    return a;
}

Out<-1> joint_positions(const ChainMotion &motion, double tau) {
    check_tau(tau);
    double *out;
    auto a = new_array<-1>({size_t(motion.chain().n_q())}, out);
    motion.joint_positions(tau, out);
    return a;
}

void check_radius(double r) {
    if (!(r >= 0.0 && r < std::numeric_limits<double>::infinity()))
        throw nb::value_error(("r must be finite and >= 0, got " + std::to_string(r)).c_str());
}

// (coeffs (3, 4, 4), point bound at r, rotation bound, sweep at r).
nb::tuple link_fit(const ChainMotion &motion, int link, double lo, double hi, double r) {
    check_link(motion.chain(), link);
    check_piece(lo, hi);
    check_radius(r);
    double *out;
    auto coeffs = new_array<3, 4, 4>({3, 4, 4}, out);
    const FitBound b = motion.fit(link, lo, hi, out);
    return nb::make_tuple(coeffs, b.point(r), b.rotation, b.sweep(r));
}

// (point bound at r, rotation bound, sweep at r).
nb::tuple link_fit_bound(const ChainMotion &motion, int link, double lo, double hi, double r) {
    check_link(motion.chain(), link);
    check_piece(lo, hi);
    check_radius(r);
    const FitBound b = motion.fit_bound(link, lo, hi);
    return nb::make_tuple(b.point(r), b.rotation, b.sweep(r));
}

LinkBoxPath make_link_box(const ChainMotion &motion, int link, const Doubles &X_CS, const Doubles &half) {
    check_link(motion.chain(), link);
    expect(X_CS, "X_CS", {4, 4});
    expect(half, "half", {3});
    return LinkBoxPath(motion, link, X_CS.data(), half.data());
}

RowBoxPath make_row_box(const Doubles &row) {
    expect(row, "row", {kPathBoxSize});
    for (size_t i = 0; i < size_t(kPathBoxSize); ++i)
        if (!std::isfinite(row.data()[i]))
            throw nb::value_error(("row: column " + std::to_string(i) + " is not finite").c_str());
    return RowBoxPath(row.data());
}

Out<4, 4> path_pose(const BoxPath &path, double tau) {
    check_tau(tau);
    double *out;
    auto a = new_array<4, 4>({4, 4}, out);
    path.pose(tau, out);
    return a;
}

Out<-1, 4, 4> path_poses(const BoxPath &path, const Doubles &taus) {
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
    if (!(fit_tolerance > 0.0))
        throw nb::value_error(("fit_tolerance must be > 0, got " + std::to_string(fit_tolerance)).c_str());
    return path.pieces(fit_tolerance);
}

Out<3> path_half_extents(const BoxPath &path) {
    double *out;
    auto a = new_array<3>({3}, out);
    std::copy(path.half_extents(), path.half_extents() + 3, out);
    return a;
}

// (first touch, solver calls), or with `state` (first touch, its Outcome as int, solver calls).
nb::tuple paths_first_touch(const BoxPath &a, const BoxPath &b, double fit_tolerance, const Tolerances &tol,
                            bool state) {
    if (!(fit_tolerance > 0.0))
        throw nb::value_error(("fit_tolerance must be > 0, got " + std::to_string(fit_tolerance)).c_str());
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

double paths_depth(const BoxPath &a, const BoxPath &b, double tau) {
    check_tau(tau);
    return path_depth(a, b, tau);
}

// (depth, axis (3,)): pose_separation of the two boxes at tau.
nb::tuple paths_separation(const BoxPath &a, const BoxPath &b, double tau) {
    check_tau(tau);
    double X_WA[16], X_WB[16], *axis;
    auto out = new_array<3>({3}, axis);
    a.pose(tau, X_WA);
    b.pose(tau, X_WB);
    const double depth = pose_separation(X_WA, a.half_extents(), X_WB, b.half_extents(), axis);
    return nb::make_tuple(depth, out);
}

double paths_first_depth(const BoxPath &a, const BoxPath &b, double from, double target) {
    check_tau(from);
    if (!std::isfinite(target)) throw nb::value_error("target must be finite");
    nb::gil_scoped_release release;
    return first_depth(a, b, from, target);
}

Out<6> bounds_of(const BoxPath &path, int pieces) {
    if (pieces < 1 || pieces > 4096)
        throw nb::value_error(("pieces must be in [1, 4096], got " + std::to_string(pieces)).c_str());
    double *out;
    auto a = new_array<6>({6}, out);
    path_bounds(path, pieces, out, out + 3);
    return a;
}

}  // namespace

void bind_chain(nb::module_ &m) {
    nb::class_<Chain>(m, "Chain", "One articulated body's links (chain.hpp): parents, joints, frames.")
        .def("__init__",
             [](Chain *self, const Ints &parent, const Ints &joint_type, const Doubles &axis,
                const Doubles &parent_pos, const Doubles &parent_orn, const Doubles &inertial_pos,
                const Doubles &inertial_orn, const Ints &q_index, const Ints &qdot_index) {
                 new (self) Chain(make_chain(parent, joint_type, axis, parent_pos, parent_orn, inertial_pos,
                                             inertial_orn, q_index, qdot_index));
             },
             nb::arg("parent"), nb::arg("joint_type"), nb::arg("axis"), nb::arg("parent_pos"), nb::arg("parent_orn"),
             nb::arg("inertial_pos"), nb::arg("inertial_orn"), nb::arg("q_index"), nb::arg("qdot_index"))
        .def_prop_ro("n_links", &Chain::n_links)
        .def_prop_ro("n_q", &Chain::n_q)
        .def_prop_ro("n_qdot", &Chain::n_qdot);
    nb::class_<ChainMotion>(m, "ChainMotion", "A chain over one step, from the state after it (chain.hpp).")
        .def("__init__",
             [](ChainMotion *self, const Chain &chain, const Doubles &state, const Doubles &q, const Doubles &qdot,
                double dt) { new (self) ChainMotion(make_motion(chain, state, q, qdot, dt)); },
             nb::arg("chain"), nb::arg("state"), nb::arg("q"), nb::arg("qdot"), nb::arg("dt"), nb::keep_alive<1, 2>())
        .def("base_pose", &base_pose, nb::arg("tau"))
        .def("link_pose", &link_pose, nb::arg("link"), nb::arg("tau"))
        .def("link_poses", &link_poses, nb::arg("tau"))
        .def("joint_positions", &joint_positions, nb::arg("tau"))
        .def("frame_rows", &frame_rows, nb::arg("links"), nb::arg("dt"),
             "(n, 13) the links' (-1: base) poses after the step and the chords of their steps as velocities.")
        .def("fit", &link_fit, nb::arg("link"), nb::arg("lo"), nb::arg("hi"), nb::arg("r") = 0.0)
        .def("fit_bound", &link_fit_bound, nb::arg("link"), nb::arg("lo"), nb::arg("hi"), nb::arg("r") = 0.0);
    nb::class_<BoxPath>(m, "BoxPath", "A box on a within-step path (box_path.hpp); see RowBoxPath, LinkBoxPath.")
        .def("pose", &path_pose, nb::arg("tau"))
        .def("poses", &path_poses, nb::arg("taus"))
        .def("fit", &path_fit, nb::arg("lo"), nb::arg("hi"))
        .def("pieces", &path_pieces, nb::arg("fit_tolerance"))
        .def("travel", [](const BoxPath &p, double lo, double hi) { check_piece(lo, hi); return p.travel(lo, hi); },
             nb::arg("lo"), nb::arg("hi"), "How far any point of the box can be, over [lo, hi], from its place at the middle.")
        .def("bounds", &bounds_of, nb::arg("pieces") = 4, "(6,) world bounds (lo, hi) of the box over the step.")
        .def_prop_ro("half_extents", &path_half_extents, nb::rv_policy::move);
    nb::class_<RowBoxPath, BoxPath>(m, "RowBoxPath", "A box on a free frame's path row.")
        .def("__init__", [](RowBoxPath *self, const Doubles &row) { new (self) RowBoxPath(make_row_box(row)); },
             nb::arg("row"));
    nb::class_<LinkBoxPath, BoxPath>(m, "LinkBoxPath", "A box fixed to a link, on the link's path.")
        .def("__init__",
             [](LinkBoxPath *self, const ChainMotion &motion, int link, const Doubles &X_CS, const Doubles &half) {
                 new (self) LinkBoxPath(make_link_box(motion, link, X_CS, half));
             },
             nb::arg("motion"), nb::arg("link"), nb::arg("X_CS"), nb::arg("half"), nb::keep_alive<1, 2>());
    m.def(
        "link_poses",
        [](const Chain &chain, const Doubles &state, const Doubles &q, const Doubles &qdot, double dt, double tau) {
            return link_poses(make_motion(chain, state, q, qdot, dt), tau);
        },
        nb::arg("chain"), nb::arg("state"), nb::arg("q"), nb::arg("qdot"), nb::arg("dt"), nb::arg("tau"));
    m.def("paths_first_touch", &paths_first_touch, nb::arg("a"), nb::arg("b"), nb::arg("fit_tolerance"),
          nb::arg("tolerances"), nb::arg("state") = false);
    m.def("paths_depth", &paths_depth, nb::arg("a"), nb::arg("b"), nb::arg("tau"));
    m.def("paths_separation", &paths_separation, nb::arg("a"), nb::arg("b"), nb::arg("tau"));
    m.def("paths_first_depth", &paths_first_depth, nb::arg("a"), nb::arg("b"), nb::arg("from_tau"), nb::arg("target"));
}
