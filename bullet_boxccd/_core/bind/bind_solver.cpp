// The solver's bindings: its errors, Tolerances, validated boxes and motions,
// the single query (time_of_impact, a builtin made here), the batch, the route
// division and the BMS planes, and the polynomial routines (for tests).
// Shapes and dtypes are enforced by the Python layer (bullet_boxccd/solver.py)
// before these are called; values are checked by the core (solver/entry.hpp),
// so the messages come from one place for single and batch queries.
#include <nanobind/stl/string.h>

#include <exception>
#include <string>
#include <utility>

#include "bind/common.hpp"
#include "solver/entry.hpp"

namespace boxccd::bind {

namespace {

using Vec3In = In<3>;

struct InputErrorTag : std::runtime_error {  // the base class only; never thrown
    using std::runtime_error::runtime_error;
};

BoxData py_make_box(const Vec3In &lo, const Vec3In &hi, const std::string &name) {
    return make_box(lo.data(), hi.data(), name);
}

MotionData py_make_motion(const In<3, 4, 4> &c, const std::string &name) { return make_motion(c.data(), name); }

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
// error is raised by that one function, with its one message. The boxes' and
// motions' core data are their attribute `_data`, the Tolerances' its attribute
// `_core`, fetched by name (PyObject_GetAttr).
struct Entry {
    PyObject *names[6];             // interned parameter names
    PyObject *data, *core, *slow;   // "_data", "_core", the Python function's name (interned)
    PyTypeObject *box_class, *motion_class;   // Box and QuadraticMotion (their subclasses too)
    PyTypeObject *box, *motion, *tolerances;  // the core's types
    bool fast = true;  // false: every call runs the Python function (tests swap its core calls for stubs)
};
Entry &entry() {
    static Entry *e = new Entry{};  // never freed: lives as long as the module
    return *e;
}

// The core data of type `type` that an instance of `cls` holds as attribute `_data`
// (held in `hold` for the call); nullptr if obj is not one or has none of that type.
template <class T>
const T *core_data(PyObject *obj, PyTypeObject *cls, PyTypeObject *type, nb::object &hold) {
    if (!PyObject_TypeCheck(obj, cls)) return nullptr;
    PyObject *d = PyObject_GetAttr(obj, entry().data);
    if (!d) {
        PyErr_Clear();
        return nullptr;
    }
    hold = nb::steal(d);
    return Py_TYPE(d) == type ? nb::inst_ptr<T>(d) : nullptr;
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
            nb::object held[5];  // the core objects, held for the call
            const BoxData *a = core_data<BoxData>(arg[0], e.box_class, e.box, held[0]),
                          *b = core_data<BoxData>(arg[2], e.box_class, e.box, held[1]);
            const MotionData *m_a = core_data<MotionData>(arg[1], e.motion_class, e.motion, held[2]),
                             *m_b = core_data<MotionData>(arg[3], e.motion_class, e.motion, held[3]);
            static const Tolerances defaults{};
            const Tolerances *tol = &defaults;
            if (arg[5] && arg[5] != Py_None) {
                PyObject *c = PyObject_GetAttr(arg[5], e.core);
                if (!c) PyErr_Clear();
                held[4] = nb::steal(c);
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

// Makes time_of_impact (see Entry) for `module`, whose function `slow` it hands
// the other calls to, with the parameter names, the doc (which starts with the
// text signature, for help and inspect.signature), and the classes whose
// attribute `_data` holds the core's data. The method definitions live as long
// as the core (one per call: one per import of bullet_boxccd.solver).
nb::object make_time_of_impact(nb::module_ module, nb::str slow, nb::tuple names, const std::string &doc,
                               nb::type_object box_class, nb::type_object motion_class) {
    if (names.size() != 6) throw nb::value_error("make_time_of_impact: expected 6 parameter names");
    Entry &e = entry();
    e.box_class = (PyTypeObject *)box_class.inc_ref().ptr();
    e.motion_class = (PyTypeObject *)motion_class.inc_ref().ptr();
    const auto interned = [](nb::handle s) {
        PyObject *o = s.inc_ref().ptr();
        PyUnicode_InternInPlace(&o);
        return o;
    };
    for (int k = 0; k < 6; ++k) e.names[k] = interned(names[k]);
    e.data = interned(nb::str("_data"));
    e.core = interned(nb::str("_core"));
    e.slow = interned(slow);
    e.box = (PyTypeObject *)nb::type<BoxData>().ptr();
    e.motion = (PyTypeObject *)nb::type<MotionData>().ptr();
    e.tolerances = (PyTypeObject *)nb::type<Tolerances>().ptr();
    PyMethodDef *def = new PyMethodDef{
        "time_of_impact", reinterpret_cast<PyCFunction>(reinterpret_cast<void (*)()>(time_of_impact_entry)),
        METH_FASTCALL | METH_KEYWORDS, (new std::string(doc))->c_str()};
    PyObject *fn = PyCFunction_NewEx(def, module.ptr(), nb::getattr(module, "__name__").ptr());
    if (!fn) throw nb::python_error();
    return nb::steal(fn);
}

// Contact times (NaN where none), with `states` also each row's Outcome as int8:
// see solve_batch (solver/entry.hpp). The GIL is released while solving.
nb::object py_solve_batch(const In<-1, 3> &lo_a, const In<-1, 3> &hi_a, const In<-1, 3, 4, 4> &c_a,
                          const In<-1, 3> &lo_b, const In<-1, 3> &hi_b, const In<-1, 3, 4, 4> &c_b, double t0,
                          double t1, const Tolerances &tol, bool states) {
    const size_t n = lo_a.shape(0);
    auto [out, owner] = new_buffer<double>(n);
    auto [state, state_owner] = new_buffer<int8_t>(states ? n : 0);
    {
        nb::gil_scoped_release release;
        solve_batch(lo_a.data(), hi_a.data(), c_a.data(), lo_b.data(), hi_b.data(), c_b.data(), n, t0, t1, tol, out,
                    states ? state : nullptr);
    }
    nb::object times = nb::cast(Out<double, -1>(out, {n}, owner));
    if (!states) return times;
    return nb::make_tuple(times, Out<int8_t, -1>(state, {n}, state_owner));
}

Out<double, -1> sections(const BoxData &a, const MotionData &m_a, const BoxData &b, const MotionData &m_b, double t0,
                         double t1, const Tolerances &tol) {
    CheckedQuery p(a, m_a, b, m_b, t0, t1, tol);
    const std::vector<double> s = p.section_times();
    auto [out, owner] = new_buffer<double>(s.size());
    std::copy(s.begin(), s.end(), out);
    return Out<double, -1>(out, {s.size()}, owner);
}

// (normals (30, 3), offsets (30,), [(kind, feature of A, feature of B)] * 30).
nb::tuple planes(const BoxData &a, const MotionData &m_a, const BoxData &b, const MotionData &m_b, double t0,
                 double t1, double t, const Tolerances &tol) {
    CheckedQuery p(a, m_a, b, m_b, t0, t1, tol);
    auto [nrm, own_n] = new_buffer<double>(90);
    auto [off, own_o] = new_buffer<double>(30);
    int8_t fa[90], fb[90];
    p.planes_at(t, nrm, off, fa, fb);
    return nb::make_tuple(Out<double, 30, 3>(nrm, {30, 3}, own_n), Out<double, 30>(off, {30}, own_o),
                          plane_features(fa, fb));
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

void bind_solver(nb::module_ &m) {
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
    m.def("make_box", &py_make_box, nb::arg("lo"), nb::arg("hi"), nb::arg("name"));
    m.def("make_motion", &py_make_motion, nb::arg("coeffs"), nb::arg("name"));
    m.def("solve", &solve);
    m.def(
        "set_fast_time_of_impact", [](bool on) { entry().fast = on; }, nb::arg("on"),
        "Whether time_of_impact takes the common call straight to the core (True, the default) or runs every "
        "call through its Python function (False: for tests that swap the core's queries for stubs).");
    m.def("make_time_of_impact", &make_time_of_impact, nb::arg("module"), nb::arg("slow"), nb::arg("names"),
          nb::arg("doc"), nb::arg("box_class"), nb::arg("motion_class"));
    m.def("solve_batch", &py_solve_batch, nb::arg("lo_a"), nb::arg("hi_a"), nb::arg("coeffs_a"), nb::arg("lo_b"),
          nb::arg("hi_b"), nb::arg("coeffs_b"), nb::arg("t0"), nb::arg("t1"), nb::arg("tolerances"),
          nb::arg("states") = false);
    m.def("sections", &sections);
    m.def("planes", &planes);
    m.def("first_nonpositive", &py_first_nonpositive, nb::arg("coeffs"), nb::arg("lo"), nb::arg("hi"),
          "(s, clustered): poly.hpp's first s in (lo, hi] with p(s) <= 0 (NaN: none), for tests.");
    m.def("first_sign_change", &py_first_sign_change, nb::arg("coeffs"), nb::arg("lo"), nb::arg("hi"),
          "(s, clustered): poly.hpp's first sign change in (lo, hi] (NaN: none), for tests.");
    m.def("refine_crossing", &py_refine_crossing, nb::arg("coeffs"), nb::arg("lo"), nb::arg("hi"),
          nb::arg("max_secant"), "poly.hpp's bracketed crossing with at most max_secant Illinois steps, for tests.");
    m.attr("kRootWidth") = kRootWidth;
}

}  // namespace boxccd::bind
