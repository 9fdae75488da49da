// nanobind bindings of the core. Shapes and dtypes are enforced by the Python
// layer (bullet_boxccd/solver.py) before these are called; values are checked
// here, so the messages come from one place for single and batch queries.
#include <nanobind/nanobind.h>
#include <nanobind/ndarray.h>
#include <nanobind/stl/string.h>
#include <nanobind/stl/array.h>
#include <nanobind/stl/tuple.h>

// numpy's own C API makes the two small arrays of a contact: an array made
// through nanobind's ndarray export (numpy.asarray on a buffer) costs several
// times more than the solve of a simple pair.
#define NPY_NO_DEPRECATED_API NPY_1_7_API_VERSION
#include <numpy/arrayobject.h>

#include <string>
#include <vector>

#include "box_ccd.hpp"
#include "step_path.hpp"

namespace nb = nanobind;
using namespace boxccd;

namespace {

template <long... Shape>
using In = nb::ndarray<const double, nb::shape<Shape...>, nb::c_contig, nb::device::cpu>;
using Vec3In = In<3>;
using Coeffs = In<3, 4, 4>;
using Vec3InN = In<-1, 3>;
using CoeffsN = In<-1, 3, 4, 4>;
template <class T, long... Shape>
using Out = nb::ndarray<nb::numpy, T, nb::shape<Shape...>>;

// A new buffer of n elements, owned by the returned capsule (the output array's owner).
template <class T>
std::pair<T *, nb::capsule> new_buffer(size_t n) {
    T *d = new T[n ? n : 1];
    return {d, nb::capsule(d, [](void *q) noexcept { delete[] static_cast<T *>(q); })};
}

struct InputErrorTag : std::runtime_error {  // the base class only; never thrown
    using std::runtime_error::runtime_error;
};

// A validated box and motion, held by the Python Box and QuadraticMotion so
// that a single query crosses the language boundary without array conversion.
struct BoxData {
    double lo[3], hi[3];
};
struct MotionData {
    double c[48];
};

BoxData make_box(const Vec3In &lo, const Vec3In &hi, const std::string &name) {
    check_box(lo.data(), hi.data(), name);
    BoxData b;
    std::copy(lo.data(), lo.data() + 3, b.lo);
    std::copy(hi.data(), hi.data() + 3, b.hi);
    return b;
}

MotionData make_motion(const Coeffs &c, const std::string &name) {
    check_motion(c.data(), name);
    MotionData m;
    std::copy(c.data(), c.data() + 48, m.c);
    return m;
}

// A box and its motion as the core's input, once the time range is checked
// (the first thing a query checks, so that its message comes first).
BoxInput input_in_range(const BoxData &box, const MotionData &m, double t0, double t1) {
    check_time_range(t0, t1);
    return {box.lo, box.hi, m.c};
}

// A checked query on validated boxes and motions (built in place: a Query is not copyable).
struct CheckedQuery {
    Query q;
    CheckedQuery(const BoxData &a, const MotionData &m_a, const BoxData &b, const MotionData &m_b, double t0,
                 double t1, const Tolerances &tol)
        : q(input_in_range(a, m_a, t0, t1), {b.lo, b.hi, m_b.c}, t0, t1, tol) {
        q.check_regular("m_a", "m_b");
    }
};

// Seed name of a feature from its sign triple: (1, 0, -1) -> "X'Z".
std::string feature_name(const std::array<int8_t, 3> &signs) {
    std::string s;
    for (int i = 0; i < 3; ++i) {
        if (signs[i] == 0) continue;
        s += "XYZ"[i];
        if (signs[i] > 0) s += '\'';
    }
    return s;
}

const char *kKind[3] = {"OV", "VO", "EE"};
int kind_index(int facet) { return static_cast<int>(facet_kind(facet)); }

// The Python strings of the 27 feature names and 3 kinds, made once (a hit then
// allocates none). Never freed: they live as long as the module.
struct Names {
    nb::object feature[27], kind[3];
    Names() {
        for (int k = 0; k < 27; ++k)
            feature[k] = nb::str(feature_name({int8_t(k / 9 - 1), int8_t(k / 3 % 3 - 1), int8_t(k % 3 - 1)}).c_str());
        for (int k = 0; k < 3; ++k) kind[k] = nb::str(kKind[k]);
    }
    const nb::object &of(const std::array<int8_t, 3> &s) const {
        return feature[9 * (s[0] + 1) + 3 * (s[1] + 1) + s[2] + 1];
    }
};
const Names &names() {
    static const Names *n = new Names;
    return *n;
}

// The Python result types, Contact(t, point, normal, feature, initial, outcome) and
// Feature(kind, a, b): NamedTuples, and the members of the Outcome enum (by
// value), registered by bullet_boxccd.solver at import.
struct ResultTypes {
    nb::object contact, feature, outcome[kOutcomes];
    nb::object features[3 * 27 * 27];  // Feature instances made so far (feature_of)
};
ResultTypes &result_types() {
    static ResultTypes *r = new ResultTypes;  // never freed: lives as long as the module
    return *r;
}

void set_result_types(nb::handle contact, nb::handle feature, nb::handle outcome) {
    for (nb::handle t : {contact, feature})
        if (!PyType_Check(t.ptr()) || !PyType_IsSubtype((PyTypeObject *)t.ptr(), &PyTuple_Type))
            throw nb::type_error("set_result_types: expected NamedTuple classes");
    ResultTypes &r = result_types();
    for (int k = 0; k < kOutcomes; ++k) r.outcome[k] = outcome(k);  // Outcome(k): the enum member
    r.contact = nb::borrow(contact);
    r.feature = nb::borrow(feature);
    for (nb::object &f : r.features) f = nb::object();  // instances of an earlier Feature type
}

// A new reference from the C API, or the pending Python error as an exception.
nb::object checked(PyObject *o) {
    if (!o) throw nb::python_error();
    return nb::steal(o);
}

// An instance of tuple subclass `type` holding `items`: what NamedTuple._make and
// tuple.__new__(type, items) make, allocated directly (one allocation, no Python
// code). A NamedTuple has the tuple's layout (__slots__ = ()), so tp_alloc gives
// a tuple of that type with its items to fill.
nb::object new_named(const nb::object &type, std::initializer_list<nb::handle> items) {
    PyTypeObject *tp = (PyTypeObject *)type.ptr();
    nb::object t = checked(tp->tp_alloc(tp, (Py_ssize_t)items.size()));
    Py_ssize_t i = 0;
    for (nb::handle x : items) PyTuple_SET_ITEM(t.ptr(), i++, x.inc_ref().ptr());
    return t;
}

nb::object new_vec3(const std::array<double, 3> &v) {
    npy_intp n = 3;
    nb::object a = checked(PyArray_SimpleNew(1, &n, NPY_DOUBLE));
    std::copy(v.begin(), v.end(), static_cast<double *>(PyArray_DATA((PyArrayObject *)a.ptr())));
    return a;
}

// The Feature(kind, a, b) of a facet and its features, made once per combination
// (3 x 27 x 27 at most; Features are immutable) and shared by every contact.
nb::object feature_of(int facet, const std::array<int8_t, 3> &feat_a, const std::array<int8_t, 3> &feat_b) {
    const auto index = [](const std::array<int8_t, 3> &sg) { return 9 * (sg[0] + 1) + 3 * (sg[1] + 1) + sg[2] + 1; };
    const int kind = kind_index(facet);
    ResultTypes &types = result_types();
    nb::object &slot = types.features[(kind * 27 + index(feat_a)) * 27 + index(feat_b)];
    if (!slot.is_valid()) {
        const Names &n = names();
        slot = new_named(types.feature, {n.kind[kind], n.of(feat_a), n.of(feat_b)});
    }
    return slot;
}

// A result as a Contact, or None when the boxes stay apart. Without a facet
// (NonFinite) the feature is None and the point and normal are NaN.
nb::object hit_result(const Hit &h) {
    if (h.outcome == Outcome::Separated) return nb::none();
    const ResultTypes &types = result_types();
    if (!types.contact.is_valid()) throw std::logic_error("bullet_boxccd.solver did not register its result types");
    const bool facet = h.facet >= 0;
    const nb::object feature = facet ? feature_of(h.facet, h.feat_a, h.feat_b) : nb::none();
    constexpr double nan = std::numeric_limits<double>::quiet_NaN();
    const boxccd::Vec3 none{nan, nan, nan};
    const nb::object t = checked(PyFloat_FromDouble(h.t)), point = new_vec3(facet ? h.point : none),
                     normal = new_vec3(facet ? h.normal : none);
    return new_named(types.contact, {t, point, normal, feature, h.initial() ? Py_True : Py_False,
                                     types.outcome[static_cast<int>(h.outcome)]});
}

// t_range in the common form, a tuple of two floats (or float subclasses such as
// numpy.float64); anything else is a TypeError, on which the Python wrapper runs
// its own checks (they name what is wrong, and convert what is valid).
std::pair<double, double> float_pair(nb::handle h) {
    PyObject *o = h.ptr();
    if (PyTuple_CheckExact(o) && PyTuple_GET_SIZE(o) == 2) {
        PyObject *a = PyTuple_GET_ITEM(o, 0), *b = PyTuple_GET_ITEM(o, 1);
        if (PyFloat_Check(a) && PyFloat_Check(b)) return {PyFloat_AS_DOUBLE(a), PyFloat_AS_DOUBLE(b)};
    }
    throw nb::type_error("t_range: expected a tuple of two floats");
}

// A Contact or None. t_range comes whole (see float_pair).
nb::object solve(const BoxData &a, const MotionData &m_a, const BoxData &b, const MotionData &m_b,
                 nb::handle t_range, const Tolerances &tol) {
    const auto [t0, t1] = float_pair(t_range);
    CheckedQuery p(a, m_a, b, m_b, t0, t1, tol);
    return hit_result(p.q.solve(true));
}

// Validates every row (raising for the first bad one, naming all bad rows),
// then solves with the GIL released. Output: contact t, NaN where none; with
// `states`, also each row's Outcome as int8.
nb::object solve_batch(const Vec3InN &lo_a, const Vec3InN &hi_a, const CoeffsN &c_a, const Vec3InN &lo_b, const Vec3InN &hi_b,
                       const CoeffsN &c_b, double t0, double t1, const Tolerances &tol, bool states) {
    check_time_range(t0, t1);
    validate(tol);
    const size_t n = lo_a.shape(0);
    std::vector<size_t> bad;
    std::string first_msg;
    int first_kind = -1;
    double first_t = 0.0;
    auto row_error = [&](size_t i, int kind, const std::string &msg, double t = 0.0) {
        if (bad.empty()) { first_msg = msg; first_kind = kind; first_t = t; }
        bad.push_back(i);
    };
    auto [out, owner] = new_buffer<double>(n);
    auto [state, state_owner] = new_buffer<int8_t>(states ? n : 0);
    {
        nb::gil_scoped_release release;
        for (size_t i = 0; i < n; ++i) {
            const BoxInput a{lo_a.data() + 3 * i, hi_a.data() + 3 * i, c_a.data() + 48 * i};
            const BoxInput b{lo_b.data() + 3 * i, hi_b.data() + 3 * i, c_b.data() + 48 * i};
            out[i] = std::numeric_limits<double>::quiet_NaN();
            if (states) state[i] = static_cast<int8_t>(Outcome::Separated);
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
                if (states) state[i] = static_cast<int8_t>(h.outcome);
            } catch (const NonFiniteError &e) { row_error(i, 0, row(e)); }
            catch (const BoxError &e) { row_error(i, 1, row(e)); }
            catch (const MotionError &e) { row_error(i, 2, row(e)); }
            catch (const SingularMotionError &e) { row_error(i, 3, row(e), e.t); }
        }
    }
    if (!bad.empty()) {
        std::string rows;
        for (size_t k = 0; k < bad.size() && k < 20; ++k) rows += (k ? ", " : "") + std::to_string(bad[k]);
        if (bad.size() > 20) rows += ", ...";
        const std::string msg = first_msg + " [" + std::to_string(bad.size()) + " bad row(s): " + rows + "]";
        switch (first_kind) {
            case 0: throw NonFiniteError(msg);
            case 1: throw BoxError(msg);
            case 2: throw MotionError(msg);
            default: throw SingularMotionError(msg, first_t);
        }
    }
    nb::object times = nb::cast(Out<double, -1>(out, {n}, owner));
    if (!states) return times;
    return nb::make_tuple(times, Out<int8_t, -1>(state, {n}, state_owner));
}

Out<double, -1> sections(const BoxData &a, const MotionData &m_a, const BoxData &b, const MotionData &m_b, double t0,
                         double t1, const Tolerances &tol) {
    CheckedQuery p(a, m_a, b, m_b, t0, t1, tol);
    const std::vector<double> s = p.q.sections();
    auto [out, owner] = new_buffer<double>(s.size());
    for (size_t i = 0; i < s.size(); ++i) out[i] = s[i] >= 1.0 ? t1 : t0 + s[i] * (t1 - t0);
    return Out<double, -1>(out, {s.size()}, owner);
}

// (normals (30, 3), offsets (30,), [(kind, feature of A, feature of B)] * 30).
nb::tuple planes(const BoxData &a, const MotionData &m_a, const BoxData &b, const MotionData &m_b, double t0,
                 double t1, double t, const Tolerances &tol) {
    CheckedQuery p(a, m_a, b, m_b, t0, t1, tol);
    if (!(t >= t0 && t <= t1))
        throw TimeRangeError("t = " + std::to_string(t) + " lies outside t_range = (" + std::to_string(t0) + ", " +
                             std::to_string(t1) + ")");
    auto [nrm, own_n] = new_buffer<double>(90);
    auto [off, own_o] = new_buffer<double>(30);
    int8_t fa[90], fb[90];
    p.q.planes((t - t0) / (t1 - t0), nrm, off, fa, fb);
    const Names &n = names();
    nb::list features;
    for (int k = 0; k < 30; ++k)
        features.append(nb::make_tuple(n.kind[kind_index(k)], n.of({fa[3 * k], fa[3 * k + 1], fa[3 * k + 2]}),
                                       n.of({fb[3 * k], fb[3 * k + 1], fb[3 * k + 2]})));
    return nb::make_tuple(Out<double, 30, 3>(nrm, {30, 3}, own_n), Out<double, 30>(off, {30}, own_o), features);
}

// ---------------------------------------------------------------- step paths
// The pybullet plugin's per-step work (see step_path.hpp). Indices come from
// the plugin's own tables; they are still checked, so a bad one raises
// IndexError instead of reading out of bounds.
using PathBoxes = In<2, kPathBoxSize>;
using PathRows = In<-1, kPathBoxSize>;
using States = In<-1, kFrameStateSize>;
template <long... Shape>
using Index = nb::ndarray<const int64_t, nb::shape<Shape...>, nb::c_contig, nb::device::cpu>;

void check_index(int64_t i, size_t n, const char *what) {
    if (i < 0 || size_t(i) >= n)
        throw nb::index_error((std::string(what) + " index " + std::to_string(i) + " out of range").c_str());
}

Out<double, -1> py_path_depth(const PathBoxes &boxes, const In<-1> &taus) {
    const size_t n = taus.shape(0);
    auto [out, owner] = new_buffer<double>(n);
    for (size_t i = 0; i < n; ++i) out[i] = path_depth(boxes.data(), boxes.data() + kPathBoxSize, taus.data()[i]);
    return Out<double, -1>(out, {n}, owner);
}

Out<double, -1, 6> py_swept_bounds(const PathRows &boxes) {
    const size_t n = boxes.shape(0);
    auto [out, owner] = new_buffer<double>(6 * n);
    for (size_t i = 0; i < n; ++i) swept_bounds(boxes.data() + kPathBoxSize * i, out + 6 * i, out + 6 * i + 3);
    return Out<double, -1, 6>(out, {n, 6}, owner);
}

double py_first_depth(const PathBoxes &boxes, double tau_from, double target) {
    return first_depth(boxes.data(), boxes.data() + kPathBoxSize, tau_from, target);
}

// (indices of the boxes whose reach exceeds sweep_reach, the largest reach of the others).
nb::tuple py_fast_boxes(const States &state, double dt, const Index<-1> &box_frame, const In<-1> &radius,
                        const In<-1> &sweep_reach) {
    const size_t n = box_frame.shape(0);
    if (radius.shape(0) != n || sweep_reach.shape(0) != n) throw nb::value_error("box tables differ in length");
    auto [out, owner] = new_buffer<int64_t>(n);
    size_t k = 0;
    double slack = 0.0;
    for (size_t i = 0; i < n; ++i) {
        const int64_t f = box_frame.data()[i];
        check_index(f, state.shape(0), "frame");
        const double r = step_reach(state.data() + kFrameStateSize * f, dt, radius.data()[i]);
        if (!std::isfinite(r)) continue;  // a broken body (pybullet's NaN) is left to pybullet
        if (r > sweep_reach.data()[i]) out[k++] = int64_t(i);
        else slack = std::fmax(slack, r);
    }
    return nb::make_tuple(Out<int64_t, -1>(out, {k}, owner), slack);
}

Out<double, -1, kPathBoxSize> py_path_rows(const States &state, double dt, const Index<-1> &boxes,
                                          const Index<-1> &box_frame, const In<-1, 4, 4> &X_CS,
                                          const In<-1, 3> &half) {
    const size_t n = boxes.shape(0), nb_ = box_frame.shape(0);
    if (X_CS.shape(0) != nb_ || half.shape(0) != nb_) throw nb::value_error("box tables differ in length");
    auto [out, owner] = new_buffer<double>(kPathBoxSize * n);
    for (size_t i = 0; i < n; ++i) {
        const int64_t b = boxes.data()[i];
        check_index(b, nb_, "box");
        const int64_t f = box_frame.data()[b];
        check_index(f, state.shape(0), "frame");
        path_row(state.data() + kFrameStateSize * f, dt, X_CS.data() + 16 * b, half.data() + 3 * b,
                 out + kPathBoxSize * i);
    }
    return Out<double, -1, kPathBoxSize>(out, {n, size_t(kPathBoxSize)}, owner);
}

Out<double, -1, 7> py_frame_poses(const States &state, double dt, const Index<-1> &frames, const In<-1> &taus) {
    const size_t n = frames.shape(0);
    if (taus.shape(0) != n) throw nb::value_error("frames and taus differ in length");
    auto [out, owner] = new_buffer<double>(7 * n);
    for (size_t i = 0; i < n; ++i) {
        check_index(frames.data()[i], state.shape(0), "frame");
        frame_pose(state.data() + kFrameStateSize * frames.data()[i], dt, taus.data()[i], out + 7 * i);
    }
    return Out<double, -1, 7>(out, {n, 7}, owner);
}

Out<int64_t, -1, 2> py_candidate_pairs(const In<-1, 6> &bounds, int64_t n_fast, const Index<-1> &frame,
                                       const Index<-1> &frame_body, const nb::ndarray<const uint8_t, nb::shape<-1>,
                                       nb::c_contig, nb::device::cpu> &frame_flags) {
    const int64_t n = int64_t(bounds.shape(0));
    if (frame.shape(0) != size_t(n) || n_fast < 0 || n_fast > n)
        throw nb::value_error(("candidate_pairs: " + std::to_string(n) + " bounds, " + std::to_string(frame.shape(0)) +
                               " frames and n_fast = " + std::to_string(n_fast) +
                               "; expected one frame per box and 0 <= n_fast <= boxes")
                                  .c_str());
    if (frame_flags.shape(0) != frame_body.shape(0)) throw nb::value_error("frame tables differ in length");
    for (int64_t i = 0; i < n; ++i) check_index(frame.data()[i], frame_body.shape(0), "frame");
    const auto pairs = candidate_pairs(bounds.data(), n, n_fast, frame.data(), frame_body.data(), frame_flags.data());
    auto [out, owner] = new_buffer<int64_t>(2 * pairs.size());
    for (size_t k = 0; k < pairs.size(); ++k) {
        out[2 * k] = pairs[k].first;
        out[2 * k + 1] = pairs[k].second;
    }
    return Out<int64_t, -1, 2>(out, {pairs.size(), 2}, owner);
}

// (first touch of each pair, NaN where none; solver calls made), or with
// `states` (first touch, each pair's Outcome as int8, solver calls).
nb::tuple py_first_touches(const PathRows &rows, const Index<-1, 2> &pairs, double fit_tolerance,
                           const Tolerances &tol, bool states) {
    validate(tol);
    const size_t n = pairs.shape(0);
    for (size_t k = 0; k < 2 * n; ++k) check_index(pairs.data()[k], rows.shape(0), "row");
    auto [out, owner] = new_buffer<double>(n);
    auto [state, state_owner] = new_buffer<int8_t>(n);
    long solves = 0;
    {
        nb::gil_scoped_release release;
        for (size_t k = 0; k < n; ++k) {
            Outcome o;
            out[k] = first_touch(rows.data() + kPathBoxSize * pairs.data()[2 * k],
                                 rows.data() + kPathBoxSize * pairs.data()[2 * k + 1], fit_tolerance, tol, solves, o);
            state[k] = static_cast<int8_t>(o);
        }
    }
    if (!states) return nb::make_tuple(Out<double, -1>(out, {n}, owner), solves);
    return nb::make_tuple(Out<double, -1>(out, {n}, owner), Out<int8_t, -1>(state, {n}, state_owner), solves);
}

// (coeffs (3, 4, 4), error bound) of one box's path over [lo, hi].
nb::tuple py_fit_path(const In<kPathBoxSize> &box, double lo, double hi) {
    auto [out, owner] = new_buffer<double>(48);
    const double err = fit_path(box.data(), lo, hi, out);
    return nb::make_tuple(Out<double, 3, 4, 4>(out, {3, 4, 4}, owner), err);
}

// Like solve: a Contact (whose outcome says what happened, NON_FINITE for a row
// that is not finite) or None.
nb::object py_path_contact(const PathBoxes &boxes, double lo, double hi, const Tolerances &tol) {
    validate(tol);
    return hit_result(path_contact(boxes.data(), boxes.data() + kPathBoxSize, lo, hi, tol));
}

// ------------------------------------------------------- polynomial routines
// The root queries of poly.hpp on a polynomial given by its coefficients
// (constant first), for direct tests of the degenerate cases and the caps.
Poly poly_of(const In<-1> &coeffs) {
    const size_t n = coeffs.shape(0);
    if (n < 1 || n > size_t(kMaxDeg + 1))
        throw nb::value_error(("expected 1 to " + std::to_string(kMaxDeg + 1) + " coefficients").c_str());
    Poly p{};
    p.deg = int(n) - 1;
    for (size_t i = 0; i < n; ++i) p.c[i] = coeffs.data()[i];
    return p;
}
void check_interval(double lo, double hi) {
    if (!(0.0 <= lo && lo < hi && hi <= 1.0)) throw nb::value_error("expected 0 <= lo < hi <= 1");
}
nb::tuple py_first_nonpositive(const In<-1> &coeffs, double lo, double hi) {
    check_interval(lo, hi);
    bool clustered = false;
    const double s = first_nonpositive(poly_of(coeffs), lo, hi, clustered);
    return nb::make_tuple(s, clustered);
}
nb::tuple py_first_sign_change(const In<-1> &coeffs, double lo, double hi) {
    check_interval(lo, hi);
    bool clustered = false;
    const double s = first_sign_change(poly_of(coeffs), lo, hi, clustered);
    return nb::make_tuple(s, clustered);
}
double py_refine_crossing(const In<-1> &coeffs, double lo, double hi, int max_secant) {
    check_interval(lo, hi);
    return refine_crossing(poly_of(coeffs), lo, hi, max_secant);
}

}  // namespace

NB_MODULE(_core, m) {
    m.doc() = "Compiled core of bullet_boxccd: the BMS box-box time-of-impact solver.";
    if (_import_array() < 0) throw nb::python_error();

    nb::exception<InputErrorTag> base(m, "InvalidInputError", PyExc_ValueError);
    nb::exception<NonFiniteError>(m, "NonFiniteInputError", base);
    nb::exception<BoxError>(m, "InvalidBoxError", base);
    nb::exception<TimeRangeError>(m, "InvalidTimeRangeError", base);
    nb::exception<MotionError> motion(m, "InvalidMotionError", base);
    nb::exception<ToleranceError>(m, "InvalidToleranceError", base);
    // SingularMotionError carries the time of collapse as attribute `t`.
    nb::object singular = nb::borrow(nb::exception<SingularMotionError>(m, "SingularMotionError", motion));
    nb::register_exception_translator(
        [](const std::exception_ptr &p, void *payload) {
            try {
                std::rethrow_exception(p);
            } catch (const SingularMotionError &e) {
                PyObject *cls = static_cast<PyObject *>(payload);
                PyObject *exc = PyObject_CallFunction(cls, "s", e.what());
                if (exc) {
                    PyObject *t = PyFloat_FromDouble(e.t);
                    PyObject_SetAttrString(exc, "t", t);
                    Py_XDECREF(t);
                    PyErr_SetObject(cls, exc);
                    Py_DECREF(exc);
                }
            }
        },
        singular.ptr());

    // Validated at construction and read-only after: a core Tolerances is always valid.
    const Tolerances defaults;
    nb::class_<Tolerances>(m, "Tolerances")
        .def(
            "__init__",
            [](Tolerances *t, double gap_rel, double rounding, int max_steps) {
                const Tolerances v{gap_rel, rounding, max_steps};
                validate(v);
                new (t) Tolerances(v);
            },
            nb::arg("gap_rel") = defaults.gap_rel, nb::arg("rounding") = defaults.rounding,
            nb::arg("max_steps") = defaults.max_steps)
        .def_ro("gap_rel", &Tolerances::gap_rel)
        .def_ro("rounding", &Tolerances::rounding)
        .def_ro("max_steps", &Tolerances::max_steps);
    nb::class_<BoxData>(m, "BoxData");
    nb::class_<MotionData>(m, "MotionData");
    m.def("make_box", &make_box, nb::arg("lo"), nb::arg("hi"), nb::arg("name"));
    m.def("make_motion", &make_motion, nb::arg("coeffs"), nb::arg("name"));
    m.def("feature_name", &feature_name, nb::arg("signs"));
    m.def("set_result_types", &set_result_types, nb::arg("contact"), nb::arg("feature"), nb::arg("outcome"));
    m.def("solve", &solve);
    m.def("solve_batch", &solve_batch, nb::arg("lo_a"), nb::arg("hi_a"), nb::arg("coeffs_a"), nb::arg("lo_b"),
          nb::arg("hi_b"), nb::arg("coeffs_b"), nb::arg("t0"), nb::arg("t1"), nb::arg("tolerances"),
          nb::arg("states") = false);
    m.def("sections", &sections);
    m.def("planes", &planes);
    m.def("path_depth", &py_path_depth, nb::arg("boxes"), nb::arg("taus"));
    m.def("first_depth", &py_first_depth, nb::arg("boxes"), nb::arg("tau_from"), nb::arg("target"));
    m.def("swept_bounds", &py_swept_bounds, nb::arg("boxes"));
    m.def("fast_boxes", &py_fast_boxes, nb::arg("state"), nb::arg("dt"), nb::arg("box_frame"), nb::arg("radius"),
          nb::arg("sweep_reach"));
    m.def("path_rows", &py_path_rows, nb::arg("state"), nb::arg("dt"), nb::arg("boxes"), nb::arg("box_frame"),
          nb::arg("X_CS"), nb::arg("half"));
    m.def("frame_poses", &py_frame_poses, nb::arg("state"), nb::arg("dt"), nb::arg("frames"), nb::arg("taus"));
    m.def("candidate_pairs", &py_candidate_pairs, nb::arg("bounds"), nb::arg("n_fast"), nb::arg("frame"),
          nb::arg("frame_body"), nb::arg("frame_flags"));
    m.def("fit_path", &py_fit_path, nb::arg("box"), nb::arg("lo"), nb::arg("hi"));
    m.def("first_touches", &py_first_touches, nb::arg("rows"), nb::arg("pairs"), nb::arg("fit_tolerance"),
          nb::arg("tolerances"), nb::arg("states") = false);
    m.def("path_contact", &py_path_contact, nb::arg("boxes"), nb::arg("lo"), nb::arg("hi"), nb::arg("tolerances"));
    m.def("first_nonpositive", &py_first_nonpositive, nb::arg("coeffs"), nb::arg("lo"), nb::arg("hi"),
          "(s, clustered): poly.hpp's first s in (lo, hi] with p(s) <= 0 (NaN: none), for tests.");
    m.def("first_sign_change", &py_first_sign_change, nb::arg("coeffs"), nb::arg("lo"), nb::arg("hi"),
          "(s, clustered): poly.hpp's first sign change in (lo, hi] (NaN: none), for tests.");
    m.def("refine_crossing", &py_refine_crossing, nb::arg("coeffs"), nb::arg("lo"), nb::arg("hi"),
          nb::arg("max_secant"), "poly.hpp's bracketed crossing with at most max_secant Illinois steps, for tests.");
    m.attr("kRootWidth") = kRootWidth;
}
