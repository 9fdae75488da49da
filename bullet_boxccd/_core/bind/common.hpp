// What the binding files share: the array types they take and give, output
// buffers handed to numpy, and the Contact a solver result becomes in Python.
// The bindings convert and check arguments, call the core and convert its
// results; every decision is the core's (solver/, paths/, world/).
#pragma once

#include <nanobind/nanobind.h>
#include <nanobind/ndarray.h>

#include <cmath>
#include <cstddef>
#include <initializer_list>
#include <string>
#include <utility>
#include <vector>

#include "solver/box_ccd.hpp"

namespace boxccd::bind {

namespace nb = nanobind;

// Inputs: float64 / int64 / uint8 C-contiguous arrays of the given shape (-1: any length).
template <long... Shape>
using In = nb::ndarray<const double, nb::shape<Shape...>, nb::c_contig, nb::device::cpu>;
template <long... Shape>
using Index = nb::ndarray<const int64_t, nb::shape<Shape...>, nb::c_contig, nb::device::cpu>;
using Bytes = nb::ndarray<const uint8_t, nb::shape<-1>, nb::c_contig, nb::device::cpu>;
// Outputs: numpy arrays.
template <class T, long... Shape>
using Out = nb::ndarray<nb::numpy, T, nb::shape<Shape...>>;

// A new buffer of n elements, owned by the returned capsule (the output array's owner).
template <class T>
std::pair<T *, nb::capsule> new_buffer(size_t n) {
    T *d = new T[n ? n : 1];
    return {d, nb::capsule(d, [](void *q) noexcept { delete[] static_cast<T *>(q); })};
}

// A vector's data handed to numpy: the capsule owns the vector (no copy).
template <class T>
std::pair<T *, nb::capsule> hand_over(std::vector<T> &&v) {
    auto *held = new std::vector<T>(std::move(v));
    if (held->empty()) held->resize(1);  // a valid pointer for an empty array (its shape says 0)
    return {held->data(), nb::capsule(held, [](void *q) noexcept { delete static_cast<std::vector<T> *>(q); })};
}

// Arrays of any shape, checked by `expect` (the link paths' bindings: their
// messages name the argument and both shapes).
using Doubles = nb::ndarray<const double, nb::c_contig, nb::device::cpu>;
using Ints = nb::ndarray<const int64_t, nb::c_contig, nb::device::cpu>;

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

// A new float64 array of the given shape; `data` points at its elements.
template <long... Shape>
Out<double, Shape...> new_array(std::initializer_list<size_t> shape, double *&data) {
    size_t n = 1;
    for (const size_t s : shape) n *= s;
    auto [d, owner] = new_buffer<double>(n);
    data = d;
    return Out<double, Shape...>(data, shape.size(), shape.begin(), owner);
}

// Value checks of the path bindings' arguments (ValueError).
inline void check_tau(double tau) {
    if (!std::isfinite(tau)) throw nb::value_error(("tau must be finite, got " + std::to_string(tau)).c_str());
}
inline void check_piece(double lo, double hi) {
    if (!(0.0 <= lo && lo < hi && hi <= 1.0))
        throw nb::value_error(
            ("expected 0 <= lo < hi <= 1, got lo = " + std::to_string(lo) + ", hi = " + std::to_string(hi)).c_str());
}
inline void check_fit_tolerance(double fit_tolerance) {
    if (!(fit_tolerance > 0.0))
        throw nb::value_error(("fit_tolerance must be > 0, got " + std::to_string(fit_tolerance)).c_str());
}

// A solver result as a Contact (bullet_boxccd.solver's NamedTuple), or None when
// the boxes stay apart (bind_results.cpp).
nb::object hit_result(const Hit &h);
// The (kind, feature of A, feature of B) string triples of the 30 facets, from
// their features' sign triples ((30, 3) each, as Query::planes writes them).
nb::list plane_features(const int8_t *feat_a, const int8_t *feat_b);

// Each binding file's part of the module, called in this order by module.cpp.
void bind_results(nb::module_ &m);
void bind_solver(nb::module_ &m);
void bind_paths(nb::module_ &m);
void bind_chain(nb::module_ &m);
void bind_world(nb::module_ &m);

}  // namespace boxccd::bind
