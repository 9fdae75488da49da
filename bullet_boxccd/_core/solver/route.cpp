// Octant switches (route division). See route.hpp.
#include "solver/route.hpp"

#include <algorithm>

namespace boxccd {

namespace {

// The three generators of switch function k: (a x b) . c, a x b face `face`.
struct SwitchGenerators {
    int8_t a, b, c, face;
};
struct SwitchTable {
    SwitchGenerators k[kSwitches]{};
    constexpr SwitchTable() {
        for (int n = 0; n < kSwitches; ++n) {
            const int q = n / 9, i = (n % 9) / 3, l = n % 3;
            k[n] = {static_cast<int8_t>(3 * q + (i + 1) % 3), static_cast<int8_t>(3 * q + (i + 2) % 3),
                    static_cast<int8_t>(3 * (1 - q) + l), static_cast<int8_t>(3 * q + i)};
        }
    }
};
constexpr SwitchTable kSwitchTable;
inline const SwitchGenerators &switch_generators(int k) { return kSwitchTable.k[k]; }

// A switch function that stays zero (within rounding) over the whole range is a
// normal component that does not change the topology: ignore it.
bool ignorable(const Pair &pair, Cofactors &cof, int k) {
    const SwitchGenerators sg = switch_generators(k);
    const double noise = pair.tol.rounding * kEps * pair.gmag[sg.a] * pair.gmag[sg.b] * pair.gmag[sg.c];
    const Poly &p = cof.projection(k);
    for (int c = 0; c <= p.deg; ++c)
        if (std::fabs(p.c[c]) > noise) return false;
    return true;
}

}  // namespace

SwitchProbe::SwitchProbe(const Pair &pair, double from, double to) : pair_(pair), w_(0.5 * (to - from)) {
    const double mid = 0.5 * (from + to);
    for (int g = 0; g < 6; ++g) {
        g_[g] = pair.g[g].at(mid);
        dg_[g] = pair.g[g].derivative(mid);
    }
}

// Over the interval: |g| <= |g(mid)| + max|g'| w, |g'| <= max|g'|, |g''| = 2 |c2|,
// with the maxima over the whole range (Pair::gbounds: g' is linear in s).
void SwitchProbe::bound_generator(int g) {
    if (bounded_ & (1u << g)) return;
    const GeneratorBounds &b = pair_.gbounds[g];
    v_[g] = norm3(g_[g]) + b.d1 * w_;
    d1_[g] = b.d1;
    d2_[g] = b.d2;
    bounded_ |= static_cast<uint8_t>(1u << g);
}

void SwitchProbe::face_at_mid(int f) {
    if (faces_ & (1u << f)) return;
    n_[f] = cross3(g_[axis_generator(f, 0)], g_[axis_generator(f, 1)]);
    faces_ |= static_cast<uint8_t>(1u << f);
}

void SwitchProbe::face_derivative_at_mid(int f) {
    if (face_derivatives_ & (1u << f)) return;
    const int ga = axis_generator(f, 0), gb = axis_generator(f, 1);
    const Vec3 da = cross3(dg_[ga], g_[gb]), db = cross3(g_[ga], dg_[gb]);
    dn_[f] = {da[0] + db[0], da[1] + db[1], da[2] + db[2]};
    face_derivatives_ |= static_cast<uint8_t>(1u << f);
}

// First order first: |p(s) - p(mid)| <= max|p'| w, with |p'| <= |a'||b||c| +
// |a||b'||c| + |a||b||c'| over the interval (p and its normal only: no
// derivative of the normal). Then Taylor's theorem at mid, second order:
// |p(s) - p(mid)| <= |p'(mid)| w + max|p''| w^2 / 2 for
// |s - mid| <= w, so p keeps its sign if |p(mid)| exceeds that plus a bound of
// the rounding of p(mid) and p'(mid). Here p = (a x b) . c with quadratic vector
// curves a, b, c (the generators): p' = (a' x b + a x b') . c + (a x b) . c', and
// over the interval |a| <= |a(mid)| + max|a'| w (bound_generator), so
//   |p''| <= |a''||b||c| + |a||b''||c| + |a||b||c''| + 2 (|a'||b'||c| + |a'||b||c'| + |a||b'||c'|).
// The rounding of p and p' is bounded like every other: Tolerances::rounding eps
// times the product of the three generators' magnitudes, kDerivativeRounding
// times that for p' (which is multiplied by w).
bool SwitchProbe::constant(int k) {
    const SwitchGenerators sg = switch_generators(k);
    const int a = sg.a, b = sg.b, c = sg.c;
    bound_generator(a);
    bound_generator(b);
    bound_generator(c);
    face_at_mid(sg.face);
    const double p = dot3(n_[sg.face], g_[c]);
    const double rounding =
        pair_.tol.rounding * kEps * pair_.gmag[a] * pair_.gmag[b] * pair_.gmag[c] * (1.0 + kDerivativeRounding * w_);
    // First order, the cheapest: |p(s) - p(mid)| <= max|p'| w.
    const double slope = d1_[a] * v_[b] * v_[c] + v_[a] * d1_[b] * v_[c] + v_[a] * v_[b] * d1_[c];
    if (std::fabs(p) > slope * w_ + rounding) return true;
    face_derivative_at_mid(sg.face);
    const double dp = dot3(dn_[sg.face], g_[c]) + dot3(n_[sg.face], dg_[c]);
    const double curvature = d2_[a] * v_[b] * v_[c] + v_[a] * d2_[b] * v_[c] + v_[a] * v_[b] * d2_[c] +
                             2.0 * (d1_[a] * d1_[b] * v_[c] + d1_[a] * v_[b] * d1_[c] + v_[a] * d1_[b] * d1_[c]);
    return std::fabs(p) > std::fabs(dp) * w_ + 0.5 * curvature * w_ * w_ + rounding;
}

// The cheapest proof of a constant sign comes first; the polynomial is built
// only if it fails.
double next_switch(const Pair &pair, Cofactors &cof, int k, double from, double to, SwitchProbe &probe) {
    if (!(from < to)) return kNoSwitch;
    const SwitchGenerators sg = switch_generators(k);
    if (!(pair.gdeg[sg.a] | pair.gdeg[sg.b] | pair.gdeg[sg.c])) return kNoSwitch;  // three constant generators
    if (probe.constant(k)) return kNoSwitch;
    if (ignorable(pair, cof, k)) return kNoSwitch;
    bool clustered = false;  // an even cluster has no switch; an odd one is a switch at its middle
    const double r = first_sign_change(cof.projection(k), from, to, clustered);
    return std::isnan(r) ? kNoSwitch : r;
}

double axis_switch(const Pair &pair, Cofactors &cof, int axis, double from, double to) {
    if (!pair.turning || !(from < to)) return kNoSwitch;
    SwitchProbe probe(pair, from, to);
    double first = kNoSwitch;
    for (int g = 0; g < 6; ++g) {
        const int k = kProjection.p[axis][g].index;
        if (k >= 0 && k < kSwitches) first = std::min(first, next_switch(pair, cof, k, from, to, probe));
    }
    return first;
}

Route::Route(const Pair &pair, Cofactors &cof) : pair_(pair), cof_(cof) {
    next_.fill(kNoSwitch);
    if (!pair.turning) return;  // constant edge directions: no octant switches
    SwitchProbe probe(pair, 0.0, 1.0);
    for (int k = 0; k < kSwitches; ++k) next_[k] = next_switch(pair, cof, k, 0.0, 1.0, probe);
}

double Route::boundary() const {
    double b = 1.0;
    for (double r : next_) b = std::min(b, r);
    return b;
}

void Route::pass(double b) {
    // Sign changes within a few root widths of the one just passed are the same switch.
    const double from = b + kSwitchRepeat * kRootWidth;
    SwitchProbe probe(pair_, from, 1.0);
    for (int k = 0; k < kSwitches; ++k)
        if (next_[k] <= b) next_[k] = next_switch(pair_, cof_, k, from, 1.0, probe);
}

std::vector<double> route_division(const Pair &pair, Cofactors &cof) {
    std::vector<double> cuts{0.0};
    Route route(pair, cof);
    for (double b = route.boundary(); b < 1.0; b = route.boundary()) {
        cuts.push_back(b);
        route.pass(b);
    }
    cuts.push_back(1.0);
    return cuts;
}

}  // namespace boxccd
