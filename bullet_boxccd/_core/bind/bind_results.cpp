// Solver results as Python objects, built here without running Python code:
// Contact(t, point, normal, feature, initial, outcome), bullet_boxccd.solver's
// subclass of ContactCore (below), and Feature(kind, a, b), its NamedTuple
// (both registered at its import). A contact costs one object and one float: its
// point and normal become numpy arrays when first read (an array costs more than
// the solve of a simple pair, and most callers read only t).
#include <nanobind/stl/array.h>
#include <nanobind/stl/string.h>

#include <initializer_list>
#include <limits>
#include <new>
#include <stdexcept>
#include <string>

// numpy's own C API makes the two small arrays of a contact: an array made
// through nanobind's ndarray export (numpy.asarray on a buffer) costs several
// times more than the solve of a simple pair.
#define NPY_NO_DEPRECATED_API NPY_1_7_API_VERSION
#include <numpy/arrayobject.h>

#include "bind/common.hpp"

namespace boxccd::bind {

namespace {

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

int feature_index(const std::array<int8_t, 3> &s) { return 9 * (s[0] + 1) + 3 * (s[1] + 1) + s[2] + 1; }

// The Python strings of the 27 feature names and 3 kinds, made once (a hit then
// allocates none). Never freed: they live as long as the module.
struct Names {
    nb::object feature[27], kind[3];
    Names() {
        const char *kinds[3] = {"OV", "VO", "EE"};
        for (int k = 0; k < 27; ++k)
            feature[k] = nb::str(feature_name({int8_t(k / 9 - 1), int8_t(k / 3 % 3 - 1), int8_t(k % 3 - 1)}).c_str());
        for (int k = 0; k < 3; ++k) kind[k] = nb::str(kinds[k]);
    }
};
const Names &names() {
    static const Names *n = new Names;
    return *n;
}

// A contact's fields as Python objects; point and normal are made from p and n
// when first read (then kept: a contact always gives the same arrays). Read-only
// from Python, so that a contact never changes.
struct ContactCore {
    nb::object t, point, normal, feature, initial, outcome;
    Vec3 p{}, n{};
};

// The Python result types, registered by bullet_boxccd.solver at import: Contact
// (a subclass of ContactCore), the NamedTuple class Feature (with the allocator of
// its instances, the type's public tp_alloc slot), and the members of the Outcome
// enum (by value).
struct ResultTypes {
    nb::object contact, feature, outcome[kOutcomes];
    allocfunc alloc_feature = nullptr;
    nb::object features[3 * 27 * 27];  // Feature instances made so far (feature_of)
};
ResultTypes &result_types() {
    static ResultTypes *r = new ResultTypes;  // never freed: lives as long as the module
    return *r;
}

bool subclass_of(nb::handle t, PyTypeObject *base) {
    return PyType_Check(t.ptr()) && PyType_IsSubtype((PyTypeObject *)t.ptr(), base);
}

void set_result_types(nb::handle contact, nb::handle feature, nb::handle outcome) {
    if (!subclass_of(contact, (PyTypeObject *)nb::type<ContactCore>().ptr()))
        throw nb::type_error("set_result_types: expected a subclass of ContactCore");
    if (!subclass_of(feature, &PyTuple_Type)) throw nb::type_error("set_result_types: expected a NamedTuple class");
    const allocfunc alloc_feature = reinterpret_cast<allocfunc>(PyType_GetSlot((PyTypeObject *)feature.ptr(), Py_tp_alloc));
    if (!alloc_feature) throw nb::type_error("set_result_types: expected a NamedTuple class");
    ResultTypes &r = result_types();
    for (int k = 0; k < kOutcomes; ++k) r.outcome[k] = outcome(k);  // Outcome(k): the enum member
    r.contact = nb::borrow(contact);
    r.feature = nb::borrow(feature);
    r.alloc_feature = alloc_feature;
    for (nb::object &f : r.features) f = nb::object();  // instances of an earlier Feature type
}

// A new reference from the C API, or the pending Python error as an exception.
nb::object checked(PyObject *o) {
    if (!o) throw nb::python_error();
    return nb::steal(o);
}

// An instance of tuple subclass `type` holding `items`: what NamedTuple._make and
// tuple.__new__(type, items) make, allocated directly by the type's allocator (one
// allocation, no Python code). A NamedTuple is a tuple (__slots__ = ()), so the
// allocator gives a tuple of that type with its items to fill.
nb::object new_named(const nb::object &type, allocfunc alloc, std::initializer_list<nb::handle> items) {
    nb::object t = checked(alloc((PyTypeObject *)type.ptr(), (Py_ssize_t)items.size()));
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

// The Feature(kind, a, b) of a facet and its features, made once per combination
// (3 x 27 x 27 at most; Features are immutable) and shared by every contact.
nb::object feature_of(int facet, const std::array<int8_t, 3> &feat_a, const std::array<int8_t, 3> &feat_b) {
    const int kind = static_cast<int>(facet_kind(facet));
    ResultTypes &types = result_types();
    nb::object &slot = types.features[(kind * 27 + feature_index(feat_a)) * 27 + feature_index(feat_b)];
    if (!slot.is_valid()) {
        const Names &n = names();
        slot = new_named(types.feature, types.alloc_feature,
                         {n.kind[kind], n.feature[feature_index(feat_a)], n.feature[feature_index(feat_b)]});
    }
    return slot;
}

}  // namespace

nb::object hit_result(const Hit &h) {
    if (h.outcome == Outcome::Separated) return nb::none();
    const ResultTypes &types = result_types();
    if (!types.contact.is_valid()) throw std::logic_error("bullet_boxccd.solver did not register its result types");
    // Without a facet (NonFinite) the feature is None and the point and normal are NaN.
    const bool facet = h.facet >= 0;
    constexpr double nan = std::numeric_limits<double>::quiet_NaN();
    const Vec3 none{nan, nan, nan};
    nb::object c = nb::inst_alloc(types.contact);
    new (nb::inst_ptr<ContactCore>(c)) ContactCore{checked(PyFloat_FromDouble(h.t)),
                                                   nb::object(),
                                                   nb::object(),
                                                   facet ? feature_of(h.facet, h.feat_a, h.feat_b) : nb::none(),
                                                   nb::bool_(h.initial()),
                                                   types.outcome[static_cast<int>(h.outcome)],
                                                   facet ? h.point : none,
                                                   facet ? h.normal : none};
    nb::inst_mark_ready(c);
    return c;
}

nb::list plane_features(const int8_t *feat_a, const int8_t *feat_b) {
    const Names &n = names();
    nb::list features;
    for (int k = 0; k < 30; ++k)
        features.append(nb::make_tuple(n.kind[static_cast<int>(facet_kind(k))],
                                       n.feature[feature_index({feat_a[3 * k], feat_a[3 * k + 1], feat_a[3 * k + 2]})],
                                       n.feature[feature_index({feat_b[3 * k], feat_b[3 * k + 1], feat_b[3 * k + 2]})]));
    return features;
}

namespace {

// The contact's references for the cyclic garbage collector (a contact made in
// Python may hold anything), nanobind's pattern: the type, then the fields once
// the C++ object is built.
int contact_traverse(PyObject *self, visitproc visit, void *arg) {
    Py_VISIT(Py_TYPE(self));
    if (!nb::inst_ready(self)) return 0;
    const ContactCore *c = nb::inst_ptr<ContactCore>(self);
    for (const nb::object *f : {&c->t, &c->point, &c->normal, &c->feature, &c->initial, &c->outcome})
        Py_VISIT(f->ptr());
    return 0;
}
int contact_clear(PyObject *self) {
    ContactCore *c = nb::inst_ptr<ContactCore>(self);
    for (nb::object *f : {&c->t, &c->point, &c->normal, &c->feature, &c->initial, &c->outcome}) f->reset();
    return 0;
}
PyType_Slot contact_slots[] = {{Py_tp_traverse, (void *)contact_traverse}, {Py_tp_clear, (void *)contact_clear}, {0, nullptr}};

// Field `field` of a contact, an array made from `v` when first read.
const nb::object &array_field(nb::object &field, const Vec3 &v) {
    if (!field.is_valid()) field = new_vec3(v);
    return field;
}

}  // namespace

void bind_results(nb::module_ &m) {
    if (_import_array() < 0) throw nb::python_error();
    nb::class_<ContactCore>(m, "ContactCore",
                            "The fields of a contact (bullet_boxccd.solver.Contact), read-only; point and normal "
                            "are made as arrays when first read.",
                            nb::type_slots(contact_slots))
        .def(
            "__init__",
            [](ContactCore *c, nb::object t, nb::object point, nb::object normal, nb::object feature,
               nb::object initial, nb::object outcome) {
                new (c) ContactCore{t, point, normal, feature, initial, outcome};
            },
            nb::arg("t"), nb::arg("point"), nb::arg("normal"), nb::arg("feature"), nb::arg("initial"),
            nb::arg("outcome"))
        .def_prop_ro("t", [](const ContactCore &c) { return c.t; })
        .def_prop_ro("point", [](ContactCore &c) { return array_field(c.point, c.p); })
        .def_prop_ro("normal", [](ContactCore &c) { return array_field(c.normal, c.n); })
        .def_prop_ro("feature", [](const ContactCore &c) { return c.feature; })
        .def_prop_ro("initial", [](const ContactCore &c) { return c.initial; })
        .def_prop_ro("outcome", [](const ContactCore &c) { return c.outcome; });
    m.def("feature_name", &feature_name, nb::arg("signs"));
    m.def("set_result_types", &set_result_types, nb::arg("contact"), nb::arg("feature"), nb::arg("outcome"));
}

}  // namespace boxccd::bind
