// Route division: the BMS algorithm's octant switches. A vertex of one box's SOR (a face
// normal) switches octant of the other's when it crosses one of that SOR's
// great circles: the sign change of S[q][i][l] = (face normal i of box q) .
// (generator l of the other box), 18 functions of degree <= 6. Between two
// consecutive sign changes (a section) every |n.g| of every axis keeps its sign,
// so the 30 facets are fixed signed sums (topology.hpp).
//
// A facet's own topology depends on only 3 (face axes) or 4 (edge-edge axes) of
// the 18: the search asks for those (axis_switch), and the full division is
// built only for inspection (Route). On a short interval most switch functions
// are proven sign-constant from the generators at its middle (Taylor's theorem,
// no polynomial built); the rest are root-isolated (poly.hpp). A function that
// is zero over the whole range within rounding (aligned boxes) never switches.
#pragma once

#include <array>
#include <vector>

#include "solver/bms.hpp"

namespace boxccd {

constexpr double kNoSwitch = std::numeric_limits<double>::infinity();

// Bounds of the switch functions over [from, to], from the generators at its
// middle, filled on first use per generator and per face.
class SwitchProbe {
public:
    SwitchProbe(const Pair &pair, double from, double to);
    // Whether switch function k keeps its sign on the interval (false: not proven).
    bool constant(int k);

private:
    void bound_generator(int g);
    void face_at_mid(int face);
    void face_derivative_at_mid(int face);

    const Pair &pair_;
    double w_;                  // half width
    Vec3 g_[6], dg_[6];         // generators and derivatives at mid
    double v_[6], d1_[6], d2_[6];  // bounds of |g|, |g'|, |g''| over the interval
    Vec3 n_[6], dn_[6];         // face normals and their derivatives at mid
    uint8_t bounded_ = 0, faces_ = 0, face_derivatives_ = 0;
};

// The first sign change of switch function k in (from, to]; kNoSwitch if none.
double next_switch(const Pair &pair, Cofactors &cof, int k, double from, double to, SwitchProbe &probe);

// The first sign change in (from, to] of the switch functions that decide the
// topology of `axis` (its facets' signs); kNoSwitch if none.
double axis_switch(const Pair &pair, Cofactors &cof, int axis, double from, double to);

// The full route division over [0, 1], one boundary at a time.
class Route {
public:
    Route(const Pair &pair, Cofactors &cof);
    double boundary() const;  // the next section end (1 after the last)
    void pass(double b);      // move past b = boundary()

private:
    const Pair &pair_;
    Cofactors &cof_;
    std::array<double, kSwitches> next_;
};

// 0, every switch in order, 1.
std::vector<double> route_division(const Pair &pair, Cofactors &cof);

}  // namespace boxccd
