// nanobind bindings of the core. Shapes and dtypes are enforced by the Python
// layer (bullet_boxccd/solver.py) before these are called; values are checked
// here, so the messages come from one place for single and batch queries.
#include <nanobind/nanobind.h>
#include <nanobind/ndarray.h>
#include <nanobind/stl/string.h>
#include <nanobind/stl/array.h>
#include <nanobind/stl/optional.h>
#include <nanobind/stl/tuple.h>

// numpy's own C API makes the two small arrays of a contact: an array made
// through nanobind's ndarray export (numpy.asarray on a buffer) costs several
// times more than the solve of a simple pair.
#define NPY_NO_DEPRECATED_API NPY_1_7_API_VERSION
#include <numpy/arrayobject.h>
#include <structmember.h>  // PyMemberDef: time_of_impact reads a slot at its offset

#include <algorithm>
#include <initializer_list>
#include <optional>
#include <string>
#include <vector>

#include "box_ccd.hpp"
#include "box_path.hpp"
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
    double det_floor;  // det_floor01(c): |det| of the 3x3 part on [0, 1] is at least this
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
    m.det_floor = det_floor01(m.c);
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
        const double floor[2] = {m_a.det_floor, m_b.det_floor};
        q.check_regular("m_a", "m_b", floor);
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

// A free list of Contacts, like CPython's own for floats and tuples: making a
// Contact (a tuple and two small numpy arrays) and freeing it cost more than
// solving a simple pair. The pool keeps the last contacts it made; one that
// nobody else holds any more is refilled in place (a tuple held by one owner
// only may be, as zip and enumerate do with theirs), and so are its arrays
// unless someone still holds or changed them. Nothing a caller holds changes.
// Off where reference counts are not exact (free-threaded Python).
struct ContactPool {
    static constexpr int kSize = 8;
    PyObject *slot[kSize] = {};
    int next = 0;  // the slot a new contact takes when none is free

    // A pooled Contact that nobody else holds (a new reference), or null. Every
    // pooled contact is of the registered type: set_result_types empties the pool.
    PyObject *take() {
#ifndef Py_GIL_DISABLED  // there reference counts are not exact: no refills
        for (PyObject *c : slot)
            if (c && Py_REFCNT(c) == 1) return Py_NewRef(c);
#endif
        return nullptr;
    }
    void keep(nb::handle c) {
        Py_XSETREF(slot[next], c.inc_ref().ptr());
        next = (next + 1) % kSize;
    }
    void clear() {
        for (PyObject *&c : slot) Py_CLEAR(c);
    }
};
ContactPool &contact_pool() {
    static ContactPool *p = new ContactPool;  // never freed: lives as long as the module
    return *p;
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
    contact_pool().clear();
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

nb::object new_vec3(const Vec3 &v) {
    npy_intp n = 3;
    nb::object a = checked(PyArray_SimpleNew(1, &n, NPY_DOUBLE));
    std::copy(v.begin(), v.end(), static_cast<double *>(PyArray_DATA((PyArrayObject *)a.ptr())));
    return a;
}

// Whether `a` is a (3,) float64 array as new_vec3 makes it, held by nobody but
// its container: its data can be overwritten unseen. A user may have changed an
// array in place (shape, dtype, flags) or hold a weak reference to it: then not.
bool unseen_vec3(PyObject *a) {
    static const int fresh_flags = PyArray_FLAGS((PyArrayObject *)new_vec3({}).ptr());
    if (Py_REFCNT(a) != 1 || Py_TYPE(a) != &PyArray_Type) return false;
    PyArrayObject *arr = (PyArrayObject *)a;
    return PyArray_NDIM(arr) == 1 && PyArray_DIM(arr, 0) == 3 && PyArray_STRIDE(arr, 0) == sizeof(double) &&
           PyArray_DESCR(arr)->type_num == NPY_DOUBLE && PyArray_ISNBO(PyArray_DESCR(arr)->byteorder) &&
           PyArray_FLAGS(arr) == fresh_flags && !PyArray_BASE(arr) &&
           !reinterpret_cast<PyArrayObject_fields *>(arr)->weakreflist;
}

// Item i of `tuple` (held by nobody else) replaced by `x`.
void set_item(PyObject *tuple, Py_ssize_t i, nb::handle x) {
    PyObject *old = PyTuple_GET_ITEM(tuple, i);
    PyTuple_SET_ITEM(tuple, i, x.inc_ref().ptr());
    Py_XDECREF(old);
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
    const Vec3 &point = facet ? h.point : none, &normal = facet ? h.normal : none;
    const nb::object t = checked(PyFloat_FromDouble(h.t));
    PyObject *initial = h.initial() ? Py_True : Py_False;
    const nb::object &outcome = types.outcome[static_cast<int>(h.outcome)];
    ContactPool &pool = contact_pool();
    nb::object c = nb::steal(pool.take());
    if (!c.is_valid()) {
        c = new_named(types.contact, {t, new_vec3(point), new_vec3(normal), feature, initial, outcome});
        pool.keep(c);
        return c;
    }
    const auto refill = [&c](Py_ssize_t i, const Vec3 &v) {  // the array in item i, or a new one
        PyObject *a = PyTuple_GET_ITEM(c.ptr(), i);
        if (unseen_vec3(a)) std::copy(v.begin(), v.end(), static_cast<double *>(PyArray_DATA((PyArrayObject *)a)));
        else set_item(c.ptr(), i, new_vec3(v));
    };
    refill(1, point);
    refill(2, normal);
    set_item(c.ptr(), 0, t);
    set_item(c.ptr(), 3, feature);
    set_item(c.ptr(), 4, initial);
    set_item(c.ptr(), 5, outcome);
    return c;
}

// t_range in the common form, a tuple of two floats (or float subclasses such as
// numpy.float64); anything else is a TypeError, on which time_of_impact hands the
// call to its Python function (whose checks name what is wrong, and convert what
// is valid).
std::pair<double, double> float_pair(nb::handle h) {
    PyObject *o = h.ptr();
    if (PyTuple_CheckExact(o) && PyTuple_GET_SIZE(o) == 2) {
        PyObject *a = PyTuple_GET_ITEM(o, 0), *b = PyTuple_GET_ITEM(o, 1);
        if (PyFloat_Check(a) && PyFloat_Check(b)) return {PyFloat_AS_DOUBLE(a), PyFloat_AS_DOUBLE(b)};
    }
    throw nb::type_error("t_range: expected a tuple of two floats");
}

// A Contact or None, for time_of_impact's Python function (t_range converted).
nb::object solve(const BoxData &a, const MotionData &m_a, const BoxData &b, const MotionData &m_b,
                 nb::handle t_range, const Tolerances &tol) {
    const auto [t0, t1] = float_pair(t_range);
    CheckedQuery p(a, m_a, b, m_b, t0, t1, tol);
    return hit_result(p.q.solve(true));
}

// time_of_impact itself: a builtin function of bullet_boxccd.solver (its `self`)
// that takes the common call straight to the core (Box, QuadraticMotion, Box,
// QuadraticMotion, then optionally a tuple of two floats and a Tolerances or
// None, by position or keyword: no Python code runs) and hands every other call,
// and every call the core raises on, to the module's Python function of the same
// signature, which checks the arguments, names what is wrong and solves: every
// error is raised by that one function, with its one message.
struct Entry {
    PyObject *names[6];      // interned parameter names
    PyObject *core, *slow;   // "_core" (Tolerances' core object), the Python function's name
    PyTypeObject *box, *motion, *tolerances;  // the core's types
    // Box and QuadraticMotion (and their subclasses) keep their core data in the
    // slot `_data`, read at its offset.
    PyTypeObject *box_class, *motion_class;
    Py_ssize_t box_offset, motion_offset;
    bool fast = true;  // false: every call runs the Python function (tests swap its core calls for stubs)
};
Entry &entry() {
    static Entry *e = new Entry{};  // never freed: lives as long as the module
    return *e;
}

// The core data of type `type` in the slot at `offset` of an instance of `cls`
// (borrowed: obj keeps it alive); nullptr if obj is not one or the slot is empty.
template <class T> const T *slot_data(PyObject *obj, PyTypeObject *cls, Py_ssize_t offset, PyTypeObject *type) {
    if (!PyObject_TypeCheck(obj, cls)) return nullptr;
    PyObject *d = *reinterpret_cast<PyObject **>(reinterpret_cast<char *>(obj) + offset);
    return d && Py_TYPE(d) == type ? nb::inst_ptr<T>(d) : nullptr;
}

PyObject *time_of_impact_entry(PyObject *module, PyObject *const *args, Py_ssize_t nargs, PyObject *kwnames) {
    const Entry &e = entry();
    PyObject *arg[6] = {};
    bool fast = e.fast && nargs <= 6;
    for (Py_ssize_t i = 0; fast && i < nargs; ++i) arg[i] = args[i];
    const Py_ssize_t nkw = kwnames ? PyTuple_GET_SIZE(kwnames) : 0;
    for (Py_ssize_t j = 0; fast && j < nkw; ++j) {
        PyObject *name = PyTuple_GET_ITEM(kwnames, j);
        int k = 0;
        while (k < 6 && name != e.names[k]) ++k;  // the keywords of a call are usually interned
        for (int i = 0; k == 6 && i < 6; ++i)
            if (PyUnicode_Compare(name, e.names[i]) == 0) k = i;
        fast = k < 6 && !arg[k];
        if (fast) arg[k] = args[nargs + j];
    }
    if (fast && arg[0] && arg[1] && arg[2] && arg[3]) {
        try {
            const BoxData *a = slot_data<BoxData>(arg[0], e.box_class, e.box_offset, e.box),
                          *b = slot_data<BoxData>(arg[2], e.box_class, e.box_offset, e.box);
            const MotionData *m_a = slot_data<MotionData>(arg[1], e.motion_class, e.motion_offset, e.motion),
                             *m_b = slot_data<MotionData>(arg[3], e.motion_class, e.motion_offset, e.motion);
            static const Tolerances defaults{};
            const Tolerances *tol = &defaults;
            nb::object given;  // a Tolerances' core object, held for the call
            if (arg[5] && arg[5] != Py_None) {
                PyObject *c = PyObject_GetAttr(arg[5], e.core);
                if (!c) PyErr_Clear();
                given = nb::steal(c);
                tol = c && Py_TYPE(c) == e.tolerances ? nb::inst_ptr<Tolerances>(c) : nullptr;
            }
            if (a && m_a && b && m_b && tol) {
                const auto [t0, t1] = arg[4] ? float_pair(arg[4]) : std::pair<double, double>(0.0, 1.0);
                CheckedQuery q(*a, *m_a, *b, *m_b, t0, t1, *tol);
                return hit_result(q.q.solve(true)).release().ptr();
            }
        } catch (...) {  // the Python function raises it again, as the named error
        }
    }
    PyObject *slow = PyObject_GetAttr(module, e.slow);
    if (!slow) return nullptr;
    PyObject *out = PyObject_Vectorcall(slow, args, nargs, kwnames);
    Py_DECREF(slow);
    return out;
}

// The offset of class `cls`'s slot `_data` (its member descriptor's).
Py_ssize_t slot_offset(nb::handle cls) {
    PyObject *d = PyDict_GetItemString(((PyTypeObject *)cls.ptr())->tp_dict, "_data");
    if (!d || Py_TYPE(d) != &PyMemberDescr_Type) throw nb::type_error("make_time_of_impact: no slot _data");
    const PyMemberDef *m = reinterpret_cast<PyMemberDescrObject *>(d)->d_member;
    if (m->type != T_OBJECT_EX) throw nb::type_error("make_time_of_impact: _data is not an object slot");
    return m->offset;
}

// Makes time_of_impact (see Entry) for `module`, whose function `slow` it hands
// the other calls to, with the parameter names, the doc (which starts with the
// text signature, for help and inspect.signature), and the classes whose slot
// `_data` holds the core's data. The method definitions live as long as the core
// (one per call: one per import of bullet_boxccd.solver).
nb::object make_time_of_impact(nb::module_ module, nb::str slow, nb::tuple names, const std::string &doc,
                               nb::type_object box_class, nb::type_object motion_class) {
    if (names.size() != 6) throw nb::value_error("make_time_of_impact: expected 6 parameter names");
    Entry &e = entry();
    e.box_offset = slot_offset(box_class);
    e.motion_offset = slot_offset(motion_class);
    e.box_class = (PyTypeObject *)box_class.inc_ref().ptr();
    e.motion_class = (PyTypeObject *)motion_class.inc_ref().ptr();
    const auto interned = [](nb::handle s) {
        PyObject *o = s.inc_ref().ptr();
        PyUnicode_InternInPlace(&o);
        return o;
    };
    for (int k = 0; k < 6; ++k) e.names[k] = interned(names[k]);
    e.core = interned(nb::str("_core"));
    e.slow = interned(slow);
    e.box = (PyTypeObject *)nb::type<BoxData>().ptr();
    e.motion = (PyTypeObject *)nb::type<MotionData>().ptr();
    e.tolerances = (PyTypeObject *)nb::type<Tolerances>().ptr();
    PyMethodDef *def = new PyMethodDef{
        "time_of_impact", reinterpret_cast<PyCFunction>(reinterpret_cast<void (*)()>(time_of_impact_entry)),
        METH_FASTCALL | METH_KEYWORDS, (new std::string(doc))->c_str()};
    return checked(PyCFunction_NewEx(def, module.ptr(), nb::getattr(module, "__name__").ptr()));
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
using Bytes = nb::ndarray<const uint8_t, nb::shape<-1>, nb::c_contig, nb::device::cpu>;
// Counts by Outcome (int64, one per outcome), added to in place.
using Counts = nb::ndarray<int64_t, nb::shape<kOutcomes>, nb::c_contig, nb::device::cpu>;
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

// (depth, axis (3,)) of path_separation at tau.
nb::tuple py_path_separation(const PathBoxes &boxes, double tau) {
    auto [out, owner] = new_buffer<double>(3);
    const double depth = path_separation(boxes.data(), boxes.data() + kPathBoxSize, tau, out);
    return nb::make_tuple(depth, Out<double, 3>(out, {3}, owner));
}

double py_first_depth(const PathBoxes &boxes, double tau_from, double target) {
    return first_depth(boxes.data(), boxes.data() + kPathBoxSize, tau_from, target);
}

// Path rows of `n` boxes (indices into tables of n_all boxes) into out.
void fill_path_rows(const States &state, double dt, const int64_t *boxes, size_t n, size_t n_all,
                    const int64_t *box_frame, const double *X_CS, const double *half, double *out) {
    for (size_t i = 0; i < n; ++i) {
        const int64_t b = boxes[i];
        check_index(b, n_all, "box");
        const int64_t f = box_frame[b];
        check_index(f, state.shape(0), "frame");
        path_row(state.data() + kFrameStateSize * f, dt, X_CS + 16 * b, half + 3 * b, out + kPathBoxSize * i);
    }
}

Out<double, -1, kPathBoxSize> py_path_rows(const States &state, double dt, const Index<-1> &boxes,
                                          const Index<-1> &box_frame, const In<-1, 4, 4> &X_CS,
                                          const In<-1, 3> &half) {
    const size_t n = boxes.shape(0), n_all = box_frame.shape(0);
    if (X_CS.shape(0) != n_all || half.shape(0) != n_all) throw nb::value_error("box tables differ in length");
    auto [out, owner] = new_buffer<double>(kPathBoxSize * n);
    fill_path_rows(state, dt, boxes.data(), n, n_all, box_frame.data(), X_CS.data(), half.data(), out);
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
                                       const Index<-1> &frame_body,
                                       const Bytes &self_collides,
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

// Path rows of boxes on kinematic frames: frame f went from poses0[f] to poses1[f] (7 each).
Out<double, -1, kPathBoxSize> py_path_rows_between(const In<-1, 7> &poses0, const In<-1, 7> &poses1,
                                                   const Index<-1> &boxes, const Index<-1> &box_frame,
                                                   const In<-1, 4, 4> &X_CS, const In<-1, 3> &half) {
    const size_t n = boxes.shape(0), nb_ = box_frame.shape(0);
    if (X_CS.shape(0) != nb_ || half.shape(0) != nb_) throw nb::value_error("box tables differ in length");
    if (poses0.shape(0) != poses1.shape(0)) throw nb::value_error("poses0 and poses1 differ in length");
    auto [out, owner] = new_buffer<double>(kPathBoxSize * n);
    for (size_t i = 0; i < n; ++i) {
        const int64_t b = boxes.data()[i];
        check_index(b, nb_, "box");
        const int64_t f = box_frame.data()[b];
        check_index(f, poses0.shape(0), "frame");
        path_row_between(poses0.data() + 7 * f, poses1.data() + 7 * f, X_CS.data() + 16 * b, half.data() + 3 * b,
                         out + kPathBoxSize * i);
    }
    return Out<double, -1, kPathBoxSize>(out, {n, size_t(kPathBoxSize)}, owner);
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

// A body for resolve_collision from a (34,) row: com (3), inv_m, inv_I (9), I (9), v (3), w (3).
CollisionBody collision_body(const double *x) {
    CollisionBody c;
    std::copy(x, x + 3, c.com);
    c.inv_m = x[3];
    std::copy(x + 4, x + 13, c.inv_I);
    std::copy(x + 13, x + 22, c.I);
    std::copy(x + 22, x + 25, c.v);
    std::copy(x + 25, x + 28, c.w);
    return c;
}

// (approached, (2, 6) new v and w of a and b); bodies (2, 28) as in collision_body.
nb::tuple py_resolve_collision(const In<2, 28> &bodies, const In<-1, 3> &points, const In<3> &normal, double e,
                               double mu, int sweeps) {
    CollisionBody a = collision_body(bodies.data()), b = collision_body(bodies.data() + 28);
    const bool approached =
        resolve_collision(a, b, points.data(), int(points.shape(0)), normal.data(), e, mu, sweeps);
    auto [out, owner] = new_buffer<double>(12);
    for (int i = 0; i < 3; ++i) {
        out[i] = a.v[i];
        out[3 + i] = a.w[i];
        out[6 + i] = b.v[i];
        out[9 + i] = b.w[i];
    }
    return nb::make_tuple(approached, Out<double, 2, 6>(out, {2, 6}, owner));
}

// pybullet's reads as they come (tuples of tuples of floats), written into frame-state
// rows without numpy on the way: for a small world, the conversion costs more than the
// reads. `frames` is a list of frame indices, `values` one read per frame, each a tuple
// of `parts` tuples of the given sizes, written from column `column` on.
using MutStates = nb::ndarray<double, nb::shape<-1, kFrameStateSize>, nb::c_contig, nb::device::cpu>;

void put_reads(MutStates &state, nb::handle frames, nb::handle values, int column, std::initializer_list<int> parts) {
    PyObject *fl = frames.ptr(), *vl = values.ptr();
    if (!PyList_Check(fl) || !PyList_Check(vl) || PyList_GET_SIZE(fl) != PyList_GET_SIZE(vl))
        throw nb::value_error("expected two lists of equal length: frame indices and their reads");
    for (Py_ssize_t i = 0; i < PyList_GET_SIZE(fl); ++i) {
        const long long f = PyLong_AsLongLong(PyList_GET_ITEM(fl, i));
        if (f == -1 && PyErr_Occurred()) throw nb::python_error();
        check_index(f, state.shape(0), "frame");
        double *row = state.data() + kFrameStateSize * f + column;
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

// The first touch of each of n pairs (of rows) into out, NaN where none; returns the
// solver calls made. With creep >= 0, a pair touching at the start that does not
// press in (presses_in) counts as none. Each pair's Outcome goes to state (if not
// null), and is counted in counts[outcome] (if not null).
long first_touches(const double *rows, const int64_t *pairs, size_t n, double fit_tolerance, const Tolerances &tol,
                   double penetration, double creep, double *out, int8_t *state, int64_t *counts) {
    long solves = 0;
    nb::gil_scoped_release release;
    for (size_t k = 0; k < n; ++k) {
        const double *a = rows + kPathBoxSize * pairs[2 * k], *b = rows + kPathBoxSize * pairs[2 * k + 1];
        const double depth0 = path_depth(a, b, 0.0);
        Outcome o;
        out[k] = first_touch(a, b, fit_tolerance, tol, solves, o, depth0);
        if (out[k] == 0.0 && creep >= 0.0 && !presses_in(a, b, penetration, creep, depth0)) {
            out[k] = std::numeric_limits<double>::quiet_NaN();
            o = Outcome::Separated;
        }
        if (state) state[k] = static_cast<int8_t>(o);
        if (counts) ++counts[static_cast<int>(o)];
    }
    return solves;
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
    const long solves =
        first_touches(rows.data(), pairs.data(), n, fit_tolerance, tol, penetration, creep, out, state, nullptr);
    if (!states) return nb::make_tuple(Out<double, -1>(out, {n}, owner), solves);
    return nb::make_tuple(Out<double, -1>(out, {n}, owner), Out<int8_t, -1>(state, {n}, state_owner), solves);
}

// An array's elements, copied.
template <class A>
auto copy(const A &a) {
    using T = std::remove_const_t<std::remove_pointer_t<decltype(a.data())>>;
    return std::vector<T>(a.data(), a.data() + a.size());
}

// The box tables of a world, held across its steps, so that a step's sweep passes the
// frame state only: the fast boxes, then the first touches of the fast boxes with
// their partners (path rows, swept bounds, pybullet's filters, solves) in one call.
class Sweeper {
  public:
    Sweeper(const Index<-1> &box_frame, const In<-1> &radius, const In<-1, 4, 4> &X_CS, const In<-1, 3> &half,
            const In<-1> &sweep_reach, const Index<-1> &frame_body, const Bytes &self_collides,
            const Index<-1> &group, const Index<-1> &mask, int filter_mode)
        : n_(box_frame.shape(0)), box_frame_(copy(box_frame)), radius_(copy(radius)), X_CS_(copy(X_CS)),
          half_(copy(half)), sweep_reach_(copy(sweep_reach)), frame_body_(copy(frame_body)),
          self_collides_(copy(self_collides)), group_(copy(group)), mask_(copy(mask)), mode_(filter_mode),
          state_(kFrameStateSize * frame_body.shape(0), 0.0) {
        const size_t nf = frame_body.shape(0);
        if (radius.shape(0) != n_ || X_CS.shape(0) != n_ || half.shape(0) != n_ || sweep_reach.shape(0) != n_)
            throw nb::value_error("box tables differ in length");
        if (self_collides.shape(0) != nf || group.shape(0) != nf || mask.shape(0) != nf)
            throw nb::value_error("frame tables differ in length");
        for (const int64_t f : box_frame_) check_index(f, nf, "frame");
        for (size_t f = 0; f < nf; ++f) state_[kFrameStateSize * f + FrameState::kOrientation + 3] = 1.0;
    }

    // The frames' state, a numpy view of the sweeper's own rows (F, 13): the calls below
    // read it without converting an array.
    Out<double, -1, kFrameStateSize> state(nb::handle self) {
        return Out<double, -1, kFrameStateSize>(state_.data(), {state_.size() / kFrameStateSize,
                                                                size_t(kFrameStateSize)}, self);
    }

    // pybullet's reads of `frames` (a list of frame indices) as they come, into the state.
    void put_twists(nb::handle frames, nb::handle twists) {
        put_reads(frames, twists, FrameState::kVelocity, {3, 3});
    }
    void put_poses(nb::handle frames, nb::handle poses) { put_reads(frames, poses, FrameState::kPosition, {3, 4}); }

    // The fast boxes of the state, with `frames` and `twists` (velocity reads) put first:
    // None if none is fast, else ([box], the largest reach of the others, [their frames]).
    nb::object fast(double dt, nb::handle frames, nb::handle twists) {
        if (!frames.is_none()) put_twists(frames, twists);
        std::vector<int64_t> boxes, fast_frames;
        double slack = 0.0;
        for (size_t i = 0; i < n_; ++i) {
            const int64_t f = box_frame_[i];
            const double r = step_reach(state_.data() + kFrameStateSize * f, dt, radius_[i]);
            if (!std::isfinite(r)) continue;  // a broken body (pybullet's NaN) is left to pybullet
            if (r > sweep_reach_[i]) {
                boxes.push_back(int64_t(i));
                fast_frames.push_back(f);
            } else {
                slack = std::fmax(slack, r);
            }
        }
        if (boxes.empty()) return nb::none();
        std::sort(fast_frames.begin(), fast_frames.end());
        fast_frames.erase(std::unique(fast_frames.begin(), fast_frames.end()), fast_frames.end());
        return nb::make_tuple(to_list(boxes), slack, to_list(fast_frames));
    }

    // (path rows, swept bounds) of the boxes (a list of box indices).
    nb::tuple rows(double dt, nb::handle boxes) const {
        const std::vector<int64_t> ids = from_list(boxes, n_, "box");
        const size_t n = ids.size();
        auto [rows, owner] = new_buffer<double>(kPathBoxSize * n);
        auto [bounds, bounds_owner] = new_buffer<double>(6 * n);
        path_rows_and_bounds(dt, ids.data(), n, rows, bounds);
        return nb::make_tuple(Out<double, -1, kPathBoxSize>(rows, {n, size_t(kPathBoxSize)}, owner),
                              Out<double, -1, 6>(bounds, {n, 6}, bounds_owner));
    }

    // The first n_moving of `boxes` (a list of box indices) against each other and the
    // rest of them (with all_others: against every other box of the world, appended to
    // `boxes`): (number of candidate pairs, solver calls, None if no pair touches, else
    // (boxes, path rows, candidate pairs of rows, [(row a, row b, first touch)] of the
    // pairs that touch)). Every candidate pair's Outcome is counted into `outcomes`, if given.
    nb::tuple touches(double dt, nb::handle boxes, int64_t n_moving, bool all_others, double fit_tolerance,
                      const Tolerances &tol, double penetration, double creep, std::optional<Counts> outcomes) const {
        std::vector<int64_t> ids = from_list(boxes, n_, "box");
        if (n_moving < 0 || size_t(n_moving) > ids.size()) throw nb::value_error("touches: n_moving out of range");
        if (all_others) {
            std::vector<uint8_t> in(n_, 0);
            for (const int64_t b : ids) in[b] = 1;
            for (size_t b = 0; b < n_; ++b)
                if (!in[b]) ids.push_back(int64_t(b));
        }
        const size_t n = ids.size();
        auto [rows, rows_owner] = new_buffer<double>(kPathBoxSize * n);
        std::vector<double> bounds(6 * n);
        path_rows_and_bounds(dt, ids.data(), n, rows, bounds.data());
        std::vector<int64_t> frame(n);
        for (size_t i = 0; i < n; ++i) frame[i] = box_frame_[ids[i]];
        const FrameFilter filter{group_.data(), mask_.data(), mode_};
        const auto pairs = candidate_pairs(bounds.data(), int64_t(n), n_moving, frame.data(), frame_body_.data(),
                                           self_collides_.data(), filter);
        const size_t m = pairs.size();
        auto [pair_out, pairs_owner] = new_buffer<int64_t>(2 * m);
        for (size_t k = 0; k < m; ++k) {
            pair_out[2 * k] = pairs[k].first;
            pair_out[2 * k + 1] = pairs[k].second;
        }
        std::vector<double> tau(m);
        const long solves = first_touches(rows, pair_out, m, fit_tolerance, tol, penetration, creep, tau.data(),
                                          nullptr, outcomes ? outcomes->data() : nullptr);
        nb::list hits;
        for (size_t k = 0; k < m; ++k)
            if (!std::isnan(tau[k])) hits.append(nb::make_tuple(pairs[k].first, pairs[k].second, tau[k]));
        if (hits.size() == 0) return nb::make_tuple(m, solves, nb::none());  // the owners free the buffers
        auto [box_out, boxes_owner] = new_buffer<int64_t>(n);
        std::copy(ids.begin(), ids.end(), box_out);
        return nb::make_tuple(m, solves,
                              nb::make_tuple(Out<int64_t, -1>(box_out, {n}, boxes_owner),
                                             Out<double, -1, kPathBoxSize>(rows, {n, size_t(kPathBoxSize)}, rows_owner),
                                             Out<int64_t, -1, 2>(pair_out, {m, 2}, pairs_owner), hits));
    }

  private:
    void path_rows_and_bounds(double dt, const int64_t *boxes, size_t n, double *rows, double *bounds) const {
        for (size_t i = 0; i < n; ++i) {
            const int64_t b = boxes[i];
            path_row(state_.data() + kFrameStateSize * box_frame_[b], dt, X_CS_.data() + 16 * b, half_.data() + 3 * b,
                     rows + kPathBoxSize * i);
            swept_bounds(rows + kPathBoxSize * i, bounds + 6 * i, bounds + 6 * i + 3);
        }
    }

    void put_reads(nb::handle frames, nb::handle values, int column, std::initializer_list<int> parts) {
        MutStates view(state_.data(), {state_.size() / kFrameStateSize, size_t(kFrameStateSize)});
        ::put_reads(view, frames, values, column, parts);
    }

    static nb::list to_list(const std::vector<int64_t> &v) {
        nb::list out;
        for (const int64_t x : v) out.append(x);
        return out;
    }

    // A list (or any sequence) of indices below n.
    static std::vector<int64_t> from_list(nb::handle seq, size_t n, const char *what) {
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
        for (const int64_t x : out) check_index(x, n, what);
        return out;
    }

    size_t n_;
    std::vector<int64_t> box_frame_;
    std::vector<double> radius_, X_CS_, half_, sweep_reach_;
    std::vector<int64_t> frame_body_;
    std::vector<uint8_t> self_collides_;
    std::vector<int64_t> group_, mask_;
    int mode_;
    std::vector<double> state_;
};

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

// (t, solves, Contact or None) of paths_first_touch: the contact on the fitted
// motions (None: apart). Its outcome says what happened (a degraded one is early
// and not proven); a touch where no facet was found (at the start, or on a piece
// too fast to fit) has feature None and a NaN point and normal.
nb::tuple py_paths_contact(const BoxPath &a, const BoxPath &b, double fit_tolerance, const Tolerances &tol) {
    if (!(fit_tolerance > 0.0))
        throw nb::value_error(("fit_tolerance must be > 0, got " + std::to_string(fit_tolerance)).c_str());
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

// ---------------------------------------------------------------- hooks
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
    return checked(PyCFunction_New(defs->back(), fn.ptr()));
}

}  // namespace

// Link paths and the first touch of boxes on any paths: chain_bindings.cpp.
void bind_chain(nb::module_ &m);

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
    m.def(
        "set_fast_time_of_impact", [](bool on) { entry().fast = on; }, nb::arg("on"),
        "Whether time_of_impact takes the common call straight to the core (True, the default) or runs every "
        "call through its Python function (False: for tests that swap the core's queries for stubs).");
    m.def("make_time_of_impact", &make_time_of_impact, nb::arg("module"), nb::arg("slow"), nb::arg("names"),
          nb::arg("doc"), nb::arg("box_class"), nb::arg("motion_class"));
    m.def("solve_batch", &solve_batch, nb::arg("lo_a"), nb::arg("hi_a"), nb::arg("coeffs_a"), nb::arg("lo_b"),
          nb::arg("hi_b"), nb::arg("coeffs_b"), nb::arg("t0"), nb::arg("t1"), nb::arg("tolerances"),
          nb::arg("states") = false);
    m.def("sections", &sections);
    m.def("planes", &planes);
    m.def("path_depth", &py_path_depth, nb::arg("boxes"), nb::arg("taus"));
    m.def("path_separation", &py_path_separation, nb::arg("boxes"), nb::arg("tau"));
    m.def("first_depth", &py_first_depth, nb::arg("boxes"), nb::arg("tau_from"), nb::arg("target"));
    m.def("swept_bounds", &py_swept_bounds, nb::arg("boxes"));
    m.def("path_rows", &py_path_rows, nb::arg("state"), nb::arg("dt"), nb::arg("boxes"), nb::arg("box_frame"),
          nb::arg("X_CS"), nb::arg("half"));
    nb::class_<Sweeper>(m, "Sweeper")
        .def(nb::init<const Index<-1> &, const In<-1> &, const In<-1, 4, 4> &, const In<-1, 3> &, const In<-1> &,
                      const Index<-1> &, const Bytes &, const Index<-1> &, const Index<-1> &, int>(),
             nb::arg("box_frame"), nb::arg("radius"), nb::arg("X_CS"), nb::arg("half"), nb::arg("sweep_reach"),
             nb::arg("frame_body"), nb::arg("self_collides"), nb::arg("group"), nb::arg("mask"),
             nb::arg("filter_mode"))
        .def_prop_ro("state", [](nb::handle self) { return nb::cast<Sweeper &>(self).state(self); },
                     "The frames' state (F, 13): a numpy view of the sweeper's own rows.")
        .def("put_twists", &Sweeper::put_twists, nb::arg("frames"), nb::arg("twists"))
        .def("put_poses", &Sweeper::put_poses, nb::arg("frames"), nb::arg("poses"))
        .def("fast", &Sweeper::fast, nb::arg("dt"), nb::arg("frames") = nb::none(), nb::arg("twists") = nb::none())
        .def("rows", &Sweeper::rows, nb::arg("dt"), nb::arg("boxes"))
        .def("touches", &Sweeper::touches, nb::arg("dt"), nb::arg("boxes"), nb::arg("n_moving"), nb::arg("all_others"),
             nb::arg("fit_tolerance"), nb::arg("tolerances"), nb::arg("penetration"), nb::arg("creep"),
             nb::arg("outcomes") = nb::none());
    m.def("frame_poses", &py_frame_poses, nb::arg("state"), nb::arg("dt"), nb::arg("frames"), nb::arg("taus"));
    m.def("candidate_pairs", &py_candidate_pairs, nb::arg("bounds"), nb::arg("n_fast"), nb::arg("frame"),
          nb::arg("frame_body"), nb::arg("self_collides"), nb::arg("group"), nb::arg("mask"), nb::arg("filter_mode"));
    m.def("path_rows_between", &py_path_rows_between, nb::arg("poses0"), nb::arg("poses1"), nb::arg("boxes"),
          nb::arg("box_frame"), nb::arg("X_CS"), nb::arg("half"));
    m.def("layouts", &layouts);
    m.def("row_poses", &py_row_poses, nb::arg("rows"), nb::arg("taus"));
    m.def("bullet_step_angle", &bullet_step_angle, nb::arg("speed"), nb::arg("dt"));
    m.def("resolve_collision", &py_resolve_collision, nb::arg("bodies"), nb::arg("points"), nb::arg("normal"),
          nb::arg("e"), nb::arg("mu"), nb::arg("sweeps"));
    m.def("window_rows", &py_window_rows, nb::arg("rows"), nb::arg("lo"), nb::arg("hi"));
    m.def("fit_path", &py_fit_path, nb::arg("box"), nb::arg("lo"), nb::arg("hi"));
    m.def("first_touches", &py_first_touches, nb::arg("rows"), nb::arg("pairs"), nb::arg("fit_tolerance"),
          nb::arg("tolerances"), nb::arg("penetration") = 0.0, nb::arg("creep") = -1.0, nb::arg("states") = false);
    m.def("path_contact", &py_path_contact, nb::arg("boxes"), nb::arg("lo"), nb::arg("hi"), nb::arg("tolerances"));
    m.def("first_nonpositive", &py_first_nonpositive, nb::arg("coeffs"), nb::arg("lo"), nb::arg("hi"),
          "(s, clustered): poly.hpp's first s in (lo, hi] with p(s) <= 0 (NaN: none), for tests.");
    m.def("first_sign_change", &py_first_sign_change, nb::arg("coeffs"), nb::arg("lo"), nb::arg("hi"),
          "(s, clustered): poly.hpp's first sign change in (lo, hi] (NaN: none), for tests.");
    m.def("refine_crossing", &py_refine_crossing, nb::arg("coeffs"), nb::arg("lo"), nb::arg("hi"),
          nb::arg("max_secant"), "poly.hpp's bracketed crossing with at most max_secant Illinois steps, for tests.");
    m.attr("kRootWidth") = kRootWidth;
    m.def("paths_contact", &py_paths_contact, nb::arg("a"), nb::arg("b"), nb::arg("fit_tolerance"),
          nb::arg("tolerances"));
    m.def("as_builtin", &as_builtin, nb::arg("fn"), nb::arg("name"), nb::arg("doc"));
    bind_chain(m);
}
