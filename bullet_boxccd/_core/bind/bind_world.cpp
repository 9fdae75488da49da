// The world's bindings: the pybullet plugin's per-step work on tables of boxes
// and frames (world/sweeper.hpp): path rows from frame states or poses, frame
// poses, the broad phase, the first touches of pairs, and the Sweeper; and the
// plugin's builtin wrappers of pybullet's functions (as_builtin).
#include <nanobind/stl/optional.h>
#include <nanobind/stl/string.h>
#include <nanobind/stl/tuple.h>

#include <initializer_list>
#include <optional>
#include <string>
#include <vector>

#include "bind/common.hpp"
#include "world/sweeper.hpp"

namespace boxccd::bind {

namespace {

using PathRows = In<-1, kPathBoxSize>;
using States = In<-1, kFrameStateSize>;
// Counts by Outcome (int64, one per outcome), added to in place.
using Counts = nb::ndarray<int64_t, nb::shape<kOutcomes>, nb::c_contig, nb::device::cpu>;

BoxTable box_table(const Index<-1> &box_frame, const In<-1, 4, 4> &X_CS, const In<-1, 3> &half) {
    const size_t n = box_frame.shape(0);
    if (X_CS.shape(0) != n || half.shape(0) != n) throw nb::value_error("box tables differ in length");
    return {n, box_frame.data(), X_CS.data(), half.data()};
}

Out<double, -1, kPathBoxSize> py_path_rows(const States &state, double dt, const Index<-1> &boxes,
                                          const Index<-1> &box_frame, const In<-1, 4, 4> &X_CS,
                                          const In<-1, 3> &half) {
    const BoxTable table = box_table(box_frame, X_CS, half);
    const size_t n = boxes.shape(0);
    auto [out, owner] = new_buffer<double>(kPathBoxSize * n);
    path_rows(state.data(), state.shape(0), dt, boxes.data(), n, table, out);
    return Out<double, -1, kPathBoxSize>(out, {n, size_t(kPathBoxSize)}, owner);
}

// Path rows of boxes on kinematic frames: frame f went from poses0[f] to poses1[f] (7 each).
Out<double, -1, kPathBoxSize> py_path_rows_between(const In<-1, 7> &poses0, const In<-1, 7> &poses1,
                                                   const Index<-1> &boxes, const Index<-1> &box_frame,
                                                   const In<-1, 4, 4> &X_CS, const In<-1, 3> &half) {
    const BoxTable table = box_table(box_frame, X_CS, half);
    if (poses0.shape(0) != poses1.shape(0)) throw nb::value_error("poses0 and poses1 differ in length");
    const size_t n = boxes.shape(0);
    auto [out, owner] = new_buffer<double>(kPathBoxSize * n);
    path_rows_between(poses0.data(), poses1.data(), poses0.shape(0), boxes.data(), n, table, out);
    return Out<double, -1, kPathBoxSize>(out, {n, size_t(kPathBoxSize)}, owner);
}

Out<double, -1, 7> py_frame_poses(const States &state, double dt, const Index<-1> &frames, const In<-1> &taus) {
    const size_t n = frames.shape(0);
    if (taus.shape(0) != n) throw nb::value_error("frames and taus differ in length");
    auto [out, owner] = new_buffer<double>(7 * n);
    frame_poses(state.data(), state.shape(0), dt, frames.data(), taus.data(), n, out);
    return Out<double, -1, 7>(out, {n, 7}, owner);
}

Out<int64_t, -1, 2> py_candidate_pairs(const In<-1, 6> &bounds, int64_t n_fast, const Index<-1> &frame,
                                       const Index<-1> &frame_body, const Bytes &self_collides,
                                       const Index<-1> &group, const Index<-1> &mask, int filter_mode) {
    const int64_t n = int64_t(bounds.shape(0));
    if (frame.shape(0) != size_t(n) || n_fast < 0 || n_fast > n)
        throw nb::value_error(("candidate_pairs: " + std::to_string(n) + " bounds, " + std::to_string(frame.shape(0)) +
                               " frames and n_fast = " + std::to_string(n_fast) +
                               "; expected one frame per box and 0 <= n_fast <= boxes")
                                  .c_str());
    const size_t nf = frame_body.shape(0);
    if (self_collides.shape(0) != nf || group.shape(0) != nf || mask.shape(0) != nf)
        throw nb::value_error("frame tables differ in length");
    for (int64_t i = 0; i < n; ++i) check_index(frame.data()[i], nf, "frame");
    const FrameFilter filter{group.data(), mask.data(), filter_mode};
    const auto pairs =
        candidate_pairs(bounds.data(), n, n_fast, frame.data(), frame_body.data(), self_collides.data(), filter);
    auto [out, owner] = new_buffer<int64_t>(2 * pairs.size());
    for (size_t k = 0; k < pairs.size(); ++k) {
        out[2 * k] = pairs[k].first;
        out[2 * k + 1] = pairs[k].second;
    }
    return Out<int64_t, -1, 2>(out, {pairs.size(), 2}, owner);
}

// (first touch of each pair, NaN where none; solver calls made), or with `states`
// (first touch, each pair's Outcome as int8, solver calls): see first_touches.
nb::tuple py_first_touches(const PathRows &rows, const Index<-1, 2> &pairs, double fit_tolerance,
                           const Tolerances &tol, double penetration, double creep, bool states) {
    validate(tol);
    const size_t n = pairs.shape(0);
    for (size_t k = 0; k < 2 * n; ++k) check_index(pairs.data()[k], rows.shape(0), "row");
    auto [out, owner] = new_buffer<double>(n);
    auto [state, state_owner] = new_buffer<int8_t>(n);
    long solves;
    {
        nb::gil_scoped_release release;
        solves = first_touches(rows.data(), pairs.data(), n, fit_tolerance, tol, penetration, creep, out, state,
                               nullptr);
    }
    if (!states) return nb::make_tuple(Out<double, -1>(out, {n}, owner), solves);
    return nb::make_tuple(Out<double, -1>(out, {n}, owner), Out<int8_t, -1>(state, {n}, state_owner), solves);
}

// ------------------------------------------------------------------ Sweeper
// A list (or any sequence) of Python ints.
std::vector<int64_t> int_list(nb::handle seq) {
    PyObject *fast = PySequence_Fast(seq.ptr(), "expected a sequence of indices");
    if (!fast) throw nb::python_error();
    const Py_ssize_t m = PySequence_Fast_GET_SIZE(fast);
    std::vector<int64_t> out(size_t(m > 0 ? m : 0));
    for (Py_ssize_t i = 0; i < m; ++i) {
        const long long x = PyLong_AsLongLong(PySequence_Fast_GET_ITEM(fast, i));
        if (x == -1 && PyErr_Occurred()) {
            Py_DECREF(fast);
            throw nb::python_error();
        }
        out[size_t(i)] = x;
    }
    Py_DECREF(fast);
    return out;
}

nb::list to_list(const std::vector<int64_t> &v) {
    nb::list out;
    for (const int64_t x : v) out.append(x);
    return out;
}

// pybullet's reads as they come (tuples of tuples of floats), written into frame-state
// rows without numpy on the way: for a small world, the conversion costs more than the
// reads. `frames` is a list of frame indices, `values` one read per frame, each a tuple
// of `parts` tuples of the given sizes, written from column `column` on.
void put_reads(Sweeper &sweeper, nb::handle frames, nb::handle values, int column, std::initializer_list<int> parts) {
    PyObject *fl = frames.ptr(), *vl = values.ptr();
    if (!PyList_Check(fl) || !PyList_Check(vl) || PyList_GET_SIZE(fl) != PyList_GET_SIZE(vl))
        throw nb::value_error("expected two lists of equal length: frame indices and their reads");
    for (Py_ssize_t i = 0; i < PyList_GET_SIZE(fl); ++i) {
        const long long f = PyLong_AsLongLong(PyList_GET_ITEM(fl, i));
        if (f == -1 && PyErr_Occurred()) throw nb::python_error();
        check_index(f, sweeper.n_frames(), "frame");
        double *row = sweeper.state() + kFrameStateSize * f + column;
        PyObject *read = PyList_GET_ITEM(vl, i);
        if (!PyTuple_Check(read) || PyTuple_GET_SIZE(read) < Py_ssize_t(parts.size()))
            throw nb::value_error("a read is not a tuple of its parts");
        int k = 0, c = 0;
        for (const int size : parts) {
            PyObject *part = PyTuple_GET_ITEM(read, k++);
            if (!PyTuple_Check(part) || PyTuple_GET_SIZE(part) != size) throw nb::value_error("a read's part has the wrong size");
            for (int j = 0; j < size; ++j) {
                const double x = PyFloat_AsDouble(PyTuple_GET_ITEM(part, j));
                if (x == -1.0 && PyErr_Occurred()) throw nb::python_error();
                row[c++] = x;
            }
        }
    }
}

void put_twists(Sweeper &s, nb::handle frames, nb::handle twists) {
    put_reads(s, frames, twists, FrameState::kVelocity, {3, 3});
}
void put_poses(Sweeper &s, nb::handle frames, nb::handle poses) {
    put_reads(s, frames, poses, FrameState::kPosition, {3, 4});
}

void init_sweeper(Sweeper *self, const Index<-1> &box_frame, const In<-1> &radius, const In<-1, 4, 4> &X_CS,
                  const In<-1, 3> &half, const In<-1> &sweep_reach, const Index<-1> &frame_body,
                  const Bytes &self_collides, const Index<-1> &group, const Index<-1> &mask, int filter_mode) {
    const size_t n = box_frame.shape(0), nf = frame_body.shape(0);
    if (radius.shape(0) != n || X_CS.shape(0) != n || half.shape(0) != n || sweep_reach.shape(0) != n)
        throw nb::value_error("box tables differ in length");
    if (self_collides.shape(0) != nf || group.shape(0) != nf || mask.shape(0) != nf)
        throw nb::value_error("frame tables differ in length");
    new (self) Sweeper({n, nf, box_frame.data(), radius.data(), X_CS.data(), half.data(), sweep_reach.data(),
                        frame_body.data(), self_collides.data(), group.data(), mask.data(), filter_mode});
}

// The fast boxes of the state, with `frames` and `twists` (velocity reads) put first:
// None if none is fast, else ([box], the largest reach of the others, [their frames]).
nb::object sweeper_fast(Sweeper &s, double dt, nb::handle frames, nb::handle twists, double clamp) {
    if (!frames.is_none()) put_twists(s, frames, twists);
    const Sweeper::Fast f = s.fast(dt, clamp);
    if (f.boxes.empty() && f.broken.empty() && f.clamped.empty()) return nb::none();
    return nb::make_tuple(to_list(f.boxes), f.slack, to_list(f.frames), to_list(f.broken), to_list(f.clamped));
}

// (n, 6): velocity_at of each row of `after` (n, 6: v, w after the step; the velocities
// before it not known) with its mode (0 or 2) and damping (n, 2), if given.
Out<double, -1, 6> py_twists_at(const In<-1, 6> &after, nb::handle modes, double dt, double tau,
                                const In<3> &gravity, std::optional<In<-1, 2>> damping) {
    const size_t n = after.shape(0);
    const std::vector<int64_t> mode = int_list(modes);
    if (mode.size() != n) throw nb::value_error("twists_at: one mode per row");
    if (damping && damping->shape(0) != n) throw nb::value_error("twists_at: one damping row per row");
    auto [out, owner] = new_buffer<double>(6 * n);
    for (size_t i = 0; i < n; ++i)
        velocity_at(after.data() + 6 * i, nullptr, int(mode[i]), dt, tau, gravity.data(),
                    damping ? damping->data() + 2 * i : nullptr, out + 6 * i);
    return Out<double, -1, 6>(out, {n, 6}, owner);
}

// (v (n, 3), w (n, 3), [still]) of Sweeper::velocities_at; frames and modes are lists,
// twist0 an (n_frames, 6) array or None, gravity (3,), damping an (n_frames, 2) array or None.
nb::tuple sweeper_velocities_at(const Sweeper &s, double dt, double tau, nb::handle frames, nb::handle modes,
                                std::optional<In<-1, 6>> twist0, const In<3> &gravity,
                                std::optional<In<-1, 2>> damping) {
    const std::vector<int64_t> ids = int_list(frames), kinds = int_list(modes);
    const size_t n = ids.size();
    if (kinds.size() != n) throw nb::value_error("velocities_at: one mode per frame");
    if (twist0 && twist0->shape(0) != s.n_frames()) throw nb::value_error("velocities_at: twist0 is not one row per frame");
    if (damping && damping->shape(0) != s.n_frames())
        throw nb::value_error("velocities_at: damping is not one row per frame");
    const std::vector<int8_t> mode(kinds.begin(), kinds.end());
    auto [v, v_owner] = new_buffer<double>(3 * n);
    auto [w, w_owner] = new_buffer<double>(3 * n);
    std::vector<uint8_t> still(n);
    s.velocities_at(dt, tau, ids.data(), mode.data(), n, twist0 ? twist0->data() : nullptr, gravity.data(),
                    damping ? damping->data() : nullptr, v, w, still.data());
    nb::list rest;
    for (uint8_t x : still) rest.append(bool(x));
    return nb::make_tuple(Out<double, -1, 3>(v, {n, 3}, v_owner), Out<double, -1, 3>(w, {n, 3}, w_owner), rest);
}

// (path rows, swept bounds) of the boxes (a list of box indices).
nb::tuple sweeper_rows(const Sweeper &s, double dt, nb::handle boxes) {
    const std::vector<int64_t> ids = int_list(boxes);
    const size_t n = ids.size();
    auto [rows, owner] = new_buffer<double>(kPathBoxSize * n);
    auto [bounds, bounds_owner] = new_buffer<double>(6 * n);
    s.rows(dt, ids.data(), n, rows, bounds);
    return nb::make_tuple(Out<double, -1, kPathBoxSize>(rows, {n, size_t(kPathBoxSize)}, owner),
                          Out<double, -1, 6>(bounds, {n, 6}, bounds_owner));
}

// The first n_moving of `boxes` (a list of box indices) against each other and the
// rest of them (with all_others: against every other box of the world, appended to
// `boxes`): (number of candidate pairs, solver calls, None if no pair touches, else
// (boxes, path rows, candidate pairs of rows, [(row a, row b, first touch)] of the
// pairs that touch)). Every candidate pair's Outcome is counted into `outcomes`, if given.
nb::tuple sweeper_touches(const Sweeper &s, double dt, nb::handle boxes, int64_t n_moving, bool all_others,
                          double fit_tolerance, const Tolerances &tol, double penetration, double creep,
                          std::optional<Counts> outcomes) {
    std::vector<int64_t> ids = int_list(boxes);
    Sweeper::Touches t;
    {
        nb::gil_scoped_release release;
        t = s.touches(dt, std::move(ids), n_moving, all_others, fit_tolerance, tol, penetration, creep,
                      outcomes ? outcomes->data() : nullptr);
    }
    const size_t m = t.pairs, n = t.boxes.size();
    nb::list hits;
    for (size_t k = 0; k < m; ++k)
        if (!std::isnan(t.tau[k])) hits.append(nb::make_tuple(t.pair_rows[2 * k], t.pair_rows[2 * k + 1], t.tau[k]));
    if (hits.size() == 0) return nb::make_tuple(m, t.solves, nb::none());
    auto [box_out, boxes_owner] = hand_over(std::move(t.boxes));
    auto [rows, rows_owner] = hand_over(std::move(t.rows));
    auto [pair_out, pairs_owner] = hand_over(std::move(t.pair_rows));
    return nb::make_tuple(m, t.solves,
                          nb::make_tuple(Out<int64_t, -1>(box_out, {n}, boxes_owner),
                                         Out<double, -1, kPathBoxSize>(rows, {n, size_t(kPathBoxSize)}, rows_owner),
                                         Out<int64_t, -1, 2>(pair_out, {m, 2}, pairs_owner), hits));
}

// ------------------------------------------------------------------ hooks
// A Python callable as a builtin function (builtin_function_or_method), for the
// plugin's wrappers of pybullet's functions: pybullet_utils.bullet_client passes
// its client id only to callables that inspect.isbuiltin() accepts. The method
// definitions live as long as the module (one per wrapped name).
PyObject *forward_call(PyObject *self, PyObject *args, PyObject *kwargs) { return PyObject_Call(self, args, kwargs); }

nb::object as_builtin(nb::object fn, const std::string &name, const std::string &doc) {
    if (!PyCallable_Check(fn.ptr())) throw nb::type_error("as_builtin: expected a callable");
    static std::vector<PyMethodDef *> *defs = new std::vector<PyMethodDef *>;
    char *n = new char[name.size() + 1], *d = new char[doc.size() + 1];
    std::copy(name.c_str(), name.c_str() + name.size() + 1, n);
    std::copy(doc.c_str(), doc.c_str() + doc.size() + 1, d);
    defs->push_back(new PyMethodDef{n, reinterpret_cast<PyCFunction>(reinterpret_cast<void (*)()>(forward_call)),
                                    METH_VARARGS | METH_KEYWORDS, d});
    PyObject *out = PyCFunction_New(defs->back(), fn.ptr());
    if (!out) throw nb::python_error();
    return nb::steal(out);
}

}  // namespace

void bind_world(nb::module_ &m) {
    m.def("path_rows", &py_path_rows, nb::arg("state"), nb::arg("dt"), nb::arg("boxes"), nb::arg("box_frame"),
          nb::arg("X_CS"), nb::arg("half"));
    m.def("path_rows_between", &py_path_rows_between, nb::arg("poses0"), nb::arg("poses1"), nb::arg("boxes"),
          nb::arg("box_frame"), nb::arg("X_CS"), nb::arg("half"));
    m.def("frame_poses", &py_frame_poses, nb::arg("state"), nb::arg("dt"), nb::arg("frames"), nb::arg("taus"));
    m.def("twists_at", &py_twists_at, nb::arg("after"), nb::arg("modes"), nb::arg("dt"), nb::arg("tau"),
          nb::arg("gravity"), nb::arg("damping").none() = nb::none(),
          "(n, 6) the velocities frames leave step fraction tau with when the world is taken back there, from "
          "those after the step (mode 0: a fixed base moved by its velocity; 2: less the rest's gravity and, "
          "given damping (n, 2: linear, angular), the rest's damping).");
    m.def("candidate_pairs", &py_candidate_pairs, nb::arg("bounds"), nb::arg("n_fast"), nb::arg("frame"),
          nb::arg("frame_body"), nb::arg("self_collides"), nb::arg("group"), nb::arg("mask"), nb::arg("filter_mode"));
    m.def("first_touches", &py_first_touches, nb::arg("rows"), nb::arg("pairs"), nb::arg("fit_tolerance"),
          nb::arg("tolerances"), nb::arg("penetration") = 0.0, nb::arg("creep") = -1.0, nb::arg("states") = false);
    nb::class_<Sweeper>(m, "Sweeper")
        .def("__init__", &init_sweeper, nb::arg("box_frame"), nb::arg("radius"), nb::arg("X_CS"), nb::arg("half"),
             nb::arg("sweep_reach"), nb::arg("frame_body"), nb::arg("self_collides"), nb::arg("group"),
             nb::arg("mask"), nb::arg("filter_mode"))
        .def_prop_ro(
            "state",
            [](nb::handle self) {
                Sweeper &s = nb::cast<Sweeper &>(self);
                return Out<double, -1, kFrameStateSize>(s.state(), {s.n_frames(), size_t(kFrameStateSize)}, self);
            },
            "The frames' state (F, 13): a numpy view of the sweeper's own rows.")
        .def("put_twists", &put_twists, nb::arg("frames"), nb::arg("twists"))
        .def("put_poses", &put_poses, nb::arg("frames"), nb::arg("poses"))
        .def("fast", &sweeper_fast, nb::arg("dt"), nb::arg("frames") = nb::none(), nb::arg("twists") = nb::none(),
             nb::arg("clamp") = INFINITY,
             "(fast boxes, slack, their frames, frames not finite, frames of boxes with a finite sweep reach "
             "at_speed(clamp)), or None if all are empty.")
        .def(
            "at_speed",
            [](const Sweeper &s, nb::handle frames, double speed, double rel_tol) {
                return to_list(s.at_speed(int_list(frames), speed, rel_tol));
            },
            nb::arg("frames"), nb::arg("speed"), nb::arg("rel_tol"),
            "Those of the frames with a component of velocity or spin of magnitude `speed` or more (less rel_tol of it).")
        .def("slack", &Sweeper::slack, nb::arg("dt"),
             "The farthest a box with a finite sweep reach moves in a step of dt (m).")
        .def("velocities_at", &sweeper_velocities_at, nb::arg("dt"), nb::arg("tau"), nb::arg("frames"),
             nb::arg("modes"), nb::arg("twist0").none(), nb::arg("gravity"), nb::arg("damping").none() = nb::none())
        .def("rows", &sweeper_rows, nb::arg("dt"), nb::arg("boxes"))
        .def("touches", &sweeper_touches, nb::arg("dt"), nb::arg("boxes"), nb::arg("n_moving"),
             nb::arg("all_others"), nb::arg("fit_tolerance"), nb::arg("tolerances"), nb::arg("penetration"),
             nb::arg("creep"), nb::arg("outcomes") = nb::none());
    m.def("as_builtin", &as_builtin, nb::arg("fn"), nb::arg("name"), nb::arg("doc"));
}

}  // namespace boxccd::bind
