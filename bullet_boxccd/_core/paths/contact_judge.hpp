// How pybullet resolves a contact from where its step leaves it: the geometry of the
// plugin's judgement of one contact (pybullet_ccd/contacts.py says what is done with it).
//
// pybullet pushes an overlap out along its least axis, away from the first box's centre.
// From a pair's state at the end of a window of the step, that goes wrong when the boxes
// end deeper than a tolerance, when the least axis points out of the far side of the box
// whose face was struck, when the second box has gone in past half the pair's depth along
// the contact normal, when the boxes end apart but overlapped deeply on the way, or when
// they end in a shallow overlap but went past the thinner box's middle on the way (a
// contact pybullet never saw).
#pragma once

#include <limits>

#include "paths/box_path.hpp"
#include "solver/vec.hpp"

namespace boxccd {

struct Judgement {
    Hit contact;  // the first touch over [s_touch, 1] of the window; Separated: the boxes stayed apart
    bool wrong = false;  // pybullet would resolve the pair wrongly from the window's end
    // The first s in (s_touch, 1] at which the pair's depth reaches the target: the
    // impact depth for a pair met inside the window; for one touching as it began, its
    // depth then plus the larger of the penetration and its creep (creep times the
    // thinner box's smallest half extent, at most depth_tolerance). NaN if never.
    double depth_time = std::numeric_limits<double>::quiet_NaN();
    // The pair's depth at the window's end (negative: apart); NaN where it is not judged.
    double depth_end = std::numeric_limits<double>::quiet_NaN();
    // The contact's normal turned to the window's end with the body whose face it is (for
    // an edge-edge contact, the one that turns less); NaN without a contact or a facet.
    Vec3 normal_at_end{std::numeric_limits<double>::quiet_NaN(), std::numeric_limits<double>::quiet_NaN(),
                       std::numeric_limits<double>::quiet_NaN()};
    // A pair touching as the window began and judged wrong: whether it was seen apart by
    // more than the penetration before reaching the target depth (pybullet's solver
    // parted it; sampled at 2^-k of the window, k = 8 .. 5, then every sixteenth), and
    // then when it touches again (a new contact, an impact; first_depth to 0), NaN if never.
    bool parted = false;
    double again = std::numeric_limits<double>::quiet_NaN();
    // A pair touching as the window began at its impact (after_impact), judged wrong and
    // not parted: whether a corner of one box that was apart from the other by more than the
    // penetration then is inside it by the impact depth before the pair reaches the target
    // (depth_time is then that time, and contact the corner's at its touch): the next corner
    // of a turning box striking, an impact rather than a press.
    bool fresh = false;
};

// The judgement of the pair of path rows a, b (PathRow) over the window [lo, 1] of the
// step, first touching at s_touch (a fraction of the window; 0: touching as it began).
// Without `judge`, only the contact. depth_time is found where the pair goes wrong, or
// always with `with_time`.
Judgement judge_contact(const double *row_a, const double *row_b, double lo, double s_touch, bool judge,
                        bool with_time, bool after_impact, double penetration, double impact_depth,
                        double depth_tolerance, double creep, const Tolerances &tol);

// The judgement of a link box's contact (pybullet_ccd/articulated.py): any two box paths
// over the whole step. A link's contact that ends merely deep is pybullet's (motors press
// links into what they touch); it goes wrong only where pybullet pushes it out the far
// side or never sees it.
struct LinkJudgement {
    double touch = std::numeric_limits<double>::quiet_NaN();  // the first touch; NaN: the boxes stay apart
    Hit contact;  // its geometry (from the first touch's solve; no facet at a touch at the start)
    long solves = 0;
    // Touching, or all but (within creep times the thinner box's smallest half extent),
    // when the step began: pybullet's solver saw the pair.
    bool initial = false, pressing = false;
    // When the pair first overlaps by the target (the penetration; a pressing pair: its
    // depth at the start plus the larger of the penetration and the creep), if pybullet
    // would resolve it wrongly from the step's end; NaN otherwise.
    double act = std::numeric_limits<double>::quiet_NaN();
    // Where there is no facet: the centres' midpoint at the touch and the least-overlap axis there.
    Vec3 point{}, normal{};
};

LinkJudgement judge_link_contact(const BoxPath &a, const BoxPath &b, double fit_tolerance, double penetration,
                                 double creep, const Tolerances &tol);

}  // namespace boxccd
