// Advancement: the BMS search for the first contact over a window. From s, take
// the facet that separates most (largest Q_k / |n_k| at s, from the vectors
// there), jump to its first root (the first time the origin reaches that
// facet's plane), and repeat until no facet separates (contact). Each jump passes
// a root of one facet polynomial, valid up to the next octant switch of its own
// axis (topology.hpp, route.hpp): s only increases and no contact is skipped,
// since before that root the facet proves the boxes apart. A facet that stays
// positive to its next switch moves s there (apart until then); one that stays
// positive to the window's end ends the search (apart on the window).
#pragma once

#include "solver/topology.hpp"

namespace boxccd {

// The 30 facets at s: q[k] = +-n.d - support - tau[axis] (<= 0: touching), and
// each axis' |n| at s (0: no direction). An axis whose gap |n.d| - support is
// within its rounding allowance cannot have a facet with q > 0: its q is that
// bound, not exact, and its |n| is not computed (-1). Boxes that do not turn have
// constant axes: `fixed` (from fixed_axes) then saves all but n.d.
struct FacetValues {
    double q[30], len[15];
};
struct FixedAxes {
    AxesAt at;
    Vec3 n[15];
    double len[15], tau[15];
};
void fixed_axes(const Pair &pair, FixedAxes &f);
void facet_values(const Pair &pair, double s, FacetValues &f, const FixedAxes *fixed);

// What the search carries from step to step and window to window.
struct SearchState {
    int last = -1;           // the facet whose root was the last jump
    double last_at = -1.0;   // where that jump landed
    int separating = -1;     // a facet that kept the last window apart (a warm start)
    bool clustered = false;  // the last jump landed at the start of a root cluster
    bool capped = false;     // the step cap ended the search
    const FixedAxes *fixed = nullptr;
    uint32_t built = 0;      // facets with a piece below
    FacetPiece pieces[30];   // each facet's last polynomial piece
};

// The BMS search on [start, end]: true with s at the first contact, false if
// the boxes stay apart to `end`. The step cap (Tolerances::max_steps) reports
// contact at s with state.capped set: early, never late.
bool search(const Pair &pair, Cofactors &cof, double start, double end, SearchState &state, double &s);

// The facet and its axis' signs at a contact at s: the facet the last jump
// crossed if it landed at s, else the facet of least penetration at s (the
// range's start, or a point where another facet's piece ended).
int contact_facet(const Pair &pair, const SearchState &state, double s, int8_t *sig);

}  // namespace boxccd
