// The link paths' bindings: one articulated body's chain, its motion over a
// step and boxes on its links (paths/chain.hpp). Arrays come as float64 / int64
// C-contiguous (bullet_boxccd/pybullet_ccd/chain.py converts); shapes and values
// are checked here and raise ValueError (wrong shape or value) or IndexError (an
// index out of range) saying which argument.
#include <nanobind/stl/tuple.h>

#include <cmath>
#include <limits>
#include <string>

#include "bind/common.hpp"
#include "paths/chain.hpp"

namespace boxccd::bind {

namespace {

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

Out<double, -1, 7> link_poses(const ChainMotion &motion, double tau) {
    check_tau(tau);
    const size_t n = size_t(motion.chain().n_links());
    double *out;
    auto a = new_array<-1, 7>({n, 7}, out);
    motion.link_poses(tau, out);
    return a;
}

Out<double, 7> link_pose(const ChainMotion &motion, int link, double tau) {
    check_tau(tau);
    check_link(motion.chain(), link);
    double *out;
    auto a = new_array<7>({7}, out);
    motion.link_pose(link, tau, out);
    return a;
}

Out<double, 7> base_pose(const ChainMotion &motion, double tau) {
    check_tau(tau);
    double *out;
    auto a = new_array<7>({7}, out);
    motion.base_pose(tau, out);
    return a;
}

// (n, 13) frame-state rows of the given links (-1: the base): ChainMotion::chord_state.
Out<double, -1, 13> frame_rows(const ChainMotion &motion, const Ints &links) {
    expect(links, "links", {-1});
    const size_t n = links.shape(0);
    for (size_t k = 0; k < n; ++k)
        if (links.data()[k] != -1) check_link(motion.chain(), int(links.data()[k]));
    double *out;
    auto a = new_array<-1, 13>({n, 13}, out);
    for (size_t k = 0; k < n; ++k) motion.chord_state(int(links.data()[k]), out + 13 * k);
    return a;
}

Out<double, -1> joint_positions(const ChainMotion &motion, double tau) {
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

// [(k, move, [lo (3), hi (3)])] of the boxes (links, X_CS (n, 4, 4), half (n, 3),
// reach (n)) that move farther than their reach: fast_boxes.
nb::list py_fast_boxes(const ChainMotion &motion, const Ints &links, const Doubles &X_CS, const Doubles &half,
                       const Doubles &reach) {
    expect(links, "links", {-1});
    const long n = long(links.shape(0));
    expect(X_CS, "X_CS", {n, 4, 4});
    expect(half, "half", {n, 3});
    expect(reach, "reach", {n});
    for (long k = 0; k < n; ++k)
        if (links.data()[k] != -1) check_link(motion.chain(), int(links.data()[k]));
    nb::list out;
    for (const FastBox &b : fast_boxes(motion, size_t(n), links.data(), X_CS.data(), half.data(), reach.data())) {
        nb::list bounds;
        for (double x : b.lo) bounds.append(x);
        for (double x : b.hi) bounds.append(x);
        out.append(nb::make_tuple(b.index, b.move, bounds));
    }
    return out;
}

LinkBoxPath make_link_box(const ChainMotion &motion, int link, const Doubles &X_CS, const Doubles &half) {
    check_link(motion.chain(), link);
    expect(X_CS, "X_CS", {4, 4});
    expect(half, "half", {3});
    return LinkBoxPath(motion, link, X_CS.data(), half.data());
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
        .def("frame_rows", &frame_rows, nb::arg("links"),
             "(n, 13) the links' (-1: base) poses after the step and the chords of their steps as velocities.")
        .def("fast_boxes", &py_fast_boxes, nb::arg("links"), nb::arg("X_CS"), nb::arg("half"), nb::arg("reach"),
             "[(k, move, [lo (3), hi (3)])] of the boxes on links (-1: base) that move farther than their reach.")
        .def("fit", &link_fit, nb::arg("link"), nb::arg("lo"), nb::arg("hi"), nb::arg("r") = 0.0);
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
}

}  // namespace boxccd::bind
