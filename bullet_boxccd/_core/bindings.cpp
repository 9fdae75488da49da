// nanobind bindings of the core. Shapes and dtypes are enforced by the Python
// layer (bullet_boxccd/solver.py) before these are called; values are checked
// here, so the messages come from one place for single and batch queries.
#include <nanobind/nanobind.h>
#include <nanobind/ndarray.h>
#include <nanobind/stl/string.h>
#include <nanobind/stl/tuple.h>

#include <string>
#include <vector>

#include "box_ccd.hpp"

namespace nb = nanobind;
using namespace boxccd;

namespace {

template <long... Shape>
using In = nb::ndarray<const double, nb::shape<Shape...>, nb::c_contig, nb::device::cpu>;
using Vec3 = In<3>;
using Coeffs = In<3, 4, 4>;
using Vec3N = In<-1, 3>;
using CoeffsN = In<-1, 3, 4, 4>;

struct InputErrorTag : std::runtime_error {  // the base class only; never thrown
    using std::runtime_error::runtime_error;
};

Tolerances make_tol(double gap_rel, double rounding, int max_steps) {
    Tolerances t;
    t.gap_rel = gap_rel;
    t.rounding = rounding;
    t.max_steps = max_steps;
    return t;
}

Problem make_problem(const Vec3 &lo_a, const Vec3 &hi_a, const Coeffs &c_a, const Vec3 &lo_b, const Vec3 &hi_b,
                     const Coeffs &c_b, double t0, double t1, const Tolerances &tol) {
    check_time_range(t0, t1);
    Problem p({lo_a.data(), hi_a.data(), c_a.data()}, {lo_b.data(), hi_b.data(), c_b.data()}, t0, t1, tol);
    p.check_regular("m_a", "m_b");
    return p;
}

nb::tuple triple(const std::array<int8_t, 3> &v) { return nb::make_tuple(v[0], v[1], v[2]); }
nb::tuple vec(const std::array<double, 3> &v) { return nb::make_tuple(v[0], v[1], v[2]); }

nb::object solve(const Vec3 &lo_a, const Vec3 &hi_a, const Coeffs &c_a, const Vec3 &lo_b, const Vec3 &hi_b,
                 const Coeffs &c_b, double t0, double t1, double gap_rel, double rounding, int max_steps) {
    const Problem p = make_problem(lo_a, hi_a, c_a, lo_b, hi_b, c_b, t0, t1, make_tol(gap_rel, rounding, max_steps));
    const Hit h = p.solve(true);
    if (!h.hit) return nb::none();
    return nb::make_tuple(h.t, h.initial, h.facet, vec(h.point), vec(h.normal), triple(h.feat_a), triple(h.feat_b));
}

// Validates every row (raising for the first bad one, naming all bad rows),
// then solves with the GIL released. Output: contact t, NaN where none.
nb::ndarray<nb::numpy, double, nb::shape<-1>> solve_batch(const Vec3N &lo_a, const Vec3N &hi_a, const CoeffsN &c_a,
                                                         const Vec3N &lo_b, const Vec3N &hi_b, const CoeffsN &c_b,
                                                         double t0, double t1, double gap_rel, double rounding,
                                                         int max_steps) {
    check_time_range(t0, t1);
    const size_t n = lo_a.shape(0);
    const Tolerances tol = make_tol(gap_rel, rounding, max_steps);
    std::vector<size_t> bad;
    std::string first_msg;
    int first_kind = -1;
    double first_t = 0.0;
    auto row_error = [&](size_t i, int kind, const std::string &msg, double t = 0.0) {
        if (bad.empty()) { first_msg = msg; first_kind = kind; first_t = t; }
        bad.push_back(i);
    };
    double *out = new double[n];
    nb::capsule owner(out, [](void *p) noexcept { delete[] static_cast<double *>(p); });
    {
        nb::gil_scoped_release release;
        for (size_t i = 0; i < n; ++i) {
            const std::string where = "row " + std::to_string(i) + ": ";
            const BoxInput a{lo_a.data() + 3 * i, hi_a.data() + 3 * i, c_a.data() + 48 * i};
            const BoxInput b{lo_b.data() + 3 * i, hi_b.data() + 3 * i, c_b.data() + 48 * i};
            out[i] = std::numeric_limits<double>::quiet_NaN();
            try {
                check_box(a.lo, a.hi, "lo_a/hi_a", where);
                check_box(b.lo, b.hi, "lo_b/hi_b", where);
                check_motion(a.coeffs, "coeffs_a", where);
                check_motion(b.coeffs, "coeffs_b", where);
                Problem p(a, b, t0, t1, tol);
                p.check_regular((where + "coeffs_a").c_str(), (where + "coeffs_b").c_str());
                if (!bad.empty()) continue;  // keep collecting bad rows, skip the work
                const Hit h = p.solve(false);
                if (h.hit) out[i] = h.t;
            } catch (const NonFiniteError &e) { row_error(i, 0, e.what()); }
            catch (const BoxError &e) { row_error(i, 1, e.what()); }
            catch (const MotionError &e) { row_error(i, 2, e.what()); }
            catch (const SingularMotionError &e) { row_error(i, 3, e.what(), e.t); }
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
    return nb::ndarray<nb::numpy, double, nb::shape<-1>>(out, {n}, owner);
}

nb::ndarray<nb::numpy, double, nb::shape<-1>> sections(const Vec3 &lo_a, const Vec3 &hi_a, const Coeffs &c_a,
                                                       const Vec3 &lo_b, const Vec3 &hi_b, const Coeffs &c_b,
                                                       double t0, double t1, double gap_rel, double rounding,
                                                       int max_steps) {
    const Problem p = make_problem(lo_a, hi_a, c_a, lo_b, hi_b, c_b, t0, t1, make_tol(gap_rel, rounding, max_steps));
    const std::vector<double> s = p.sections();
    double *out = new double[s.size()];
    nb::capsule owner(out, [](void *q) noexcept { delete[] static_cast<double *>(q); });
    for (size_t i = 0; i < s.size(); ++i) out[i] = s[i] >= 1.0 ? t1 : t0 + s[i] * (t1 - t0);
    return nb::ndarray<nb::numpy, double, nb::shape<-1>>(out, {s.size()}, owner);
}

template <class T>
nb::ndarray<nb::numpy, T> owned(std::vector<size_t> shape, size_t count, T *&data) {
    data = new T[count];
    nb::capsule owner(data, [](void *q) noexcept { delete[] static_cast<T *>(q); });
    return nb::ndarray<nb::numpy, T>(data, shape.size(), shape.data(), owner);
}

nb::tuple planes(const Vec3 &lo_a, const Vec3 &hi_a, const Coeffs &c_a, const Vec3 &lo_b, const Vec3 &hi_b,
                 const Coeffs &c_b, double t0, double t1, double t, double gap_rel, double rounding, int max_steps) {
    const Problem p = make_problem(lo_a, hi_a, c_a, lo_b, hi_b, c_b, t0, t1, make_tol(gap_rel, rounding, max_steps));
    if (!(t >= t0 && t <= t1))
        throw TimeRangeError("t = " + std::to_string(t) + " lies outside t_range = (" + std::to_string(t0) + ", " +
                             std::to_string(t1) + ")");
    double *nrm, *off;
    int8_t *fa, *fb;
    auto normals = owned<double>({30, 3}, 90, nrm);
    auto offsets = owned<double>({30}, 30, off);
    auto feat_a = owned<int8_t>({30, 3}, 90, fa);
    auto feat_b = owned<int8_t>({30, 3}, 90, fb);
    p.planes((t - t0) / (t1 - t0), nrm, off, fa, fb);
    return nb::make_tuple(normals, offsets, feat_a, feat_b);
}

void py_check_box(const Vec3 &lo, const Vec3 &hi, const std::string &name) { check_box(lo.data(), hi.data(), name, ""); }
void py_check_motion(const Coeffs &c, const std::string &name) { check_motion(c.data(), name, ""); }

}  // namespace

NB_MODULE(_core, m) {
    m.doc() = "Compiled core of bullet_boxccd: the BMS box-box time-of-impact solver.";

    nb::exception<InputErrorTag> base(m, "InvalidInputError", PyExc_ValueError);
    nb::exception<NonFiniteError>(m, "NonFiniteInputError", base);
    nb::exception<BoxError>(m, "InvalidBoxError", base);
    nb::exception<TimeRangeError>(m, "InvalidTimeRangeError", base);
    nb::exception<MotionError> motion(m, "InvalidMotionError", base);
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

    const char *tol_args = "gap_rel, rounding, max_steps: see Tolerances";
    m.def("check_box", &py_check_box, nb::arg("lo"), nb::arg("hi"), nb::arg("name"));
    m.def("check_motion", &py_check_motion, nb::arg("coeffs"), nb::arg("name"));
    m.def("solve", &solve, tol_args);
    m.def("solve_batch", &solve_batch, tol_args);
    m.def("sections", &sections, tol_args);
    m.def("planes", &planes, tol_args);
}
