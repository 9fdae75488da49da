// Every link of an articulated body (Bullet's btMultiBody, as pybullet builds it)
// on its exact within-step path, and conservative quadratic fits of those paths.
//
// tau in [0, 1] is the fraction of the step (0: its start, 1: after it). The
// state is the one read after the step; the path runs back from it by Bullet's
// own rules (btMultiBody::stepPositionsMultiDof, measured on pybullet 3.2.7 to
// 1e-15, docs/design.md "Link paths"):
//   base      the free-frame rule of step_path.hpp (frame_pose): its centre of
//             mass moves by v dt, it turns about the fixed world axis of w by
//             bullet_step_angle(|w|, dt) (pi/4 clamp). A fixed base has v = w =
//             0 unless the user gave it a velocity; then it moves the same way.
//   revolute  q(tau) = q1 - (1 - tau) qdot dt (no clamp); prismatic likewise.
//   spherical q(tau) = q1 Rot(qdot / |qdot|, -(1 - tau) bullet_step_angle(|qdot|, dt)):
//             qdot is the angular velocity in the link's centre-of-mass frame,
//             clamped like the base.
//   fixed     nothing moves.
// Planar joints are not supported: pybullet reports 2 of their 3 coordinates
// and no axis (PhysicsDirect::getJointInfo, BodyJointInfoUtility.h).
//
// Frames. Every link pose here is the link's centre-of-mass (inertial) frame,
// as pybullet's getLinkState()[0:2] and getBasePositionAndOrientation() report
// it. Link i's frame follows from its parent P's (the base for parent -1):
//   R_WC = R_WP Z^T J(q),   p_WC = p_WP + R_WP e + R_WC (d + s a)
// with, as pybullet reports them: e = getJointInfo parentFramePos (the pivot,
// in P's centre-of-mass frame), Z = parentFrameOrn (P's frame to C's at q = 0),
// a = jointAxis (C's centre-of-mass frame), d = R_I^T p_I from getDynamicsInfo's
// local inertial frame (p_I, R_I) (the pivot to C's centre of mass, in C's
// frame), J(q) = Rot(a / |a|, q) (revolute), the quaternion q (spherical), else
// I; s = q for a prismatic joint (a as reported, not normalised), else 0.
#pragma once

#include <cstdint>
#include <vector>

#include "paths/box_path.hpp"

namespace boxccd {

// pybullet's joint type numbers (p.JOINT_REVOLUTE ...).
enum class JointType : int { Revolute = 0, Prismatic = 1, Spherical = 2, Planar = 3, Fixed = 4 };

struct ChainLink {
    int parent;          // -1: the base; always an earlier link (pybullet orders parents first)
    JointType type;
    double axis[3];      // a: the joint axis in this link's frame (unit for revolute joints)
    double e[3];         // the pivot, in the parent's frame
    double zero_rot[4];  // Z^T as a quaternion x y z w: this link's frame in the parent's at q = 0
    double d[3];         // the pivot to this link's centre of mass, in this link's frame
    int q_index;         // first coordinate in the flat q (1: revolute, prismatic; 4: spherical; 0: fixed)
    int qdot_index;      // first velocity in the flat qdot (1; 3: spherical; 0: fixed)
};

// The constant description of one body's links. Throws std::invalid_argument
// (bad value) or std::out_of_range (bad index) saying which link is wrong.
class Chain {
  public:
    // n links, arrays as pybullet reports them (see the file comment): parent (n),
    // joint_type (n), axis (n, 3), parent_pos (n, 3), parent_orn (n, 4),
    // inertial_pos (n, 3), inertial_orn (n, 4), q_index (n), qdot_index (n).
    Chain(int64_t n, const int64_t *parent, const int64_t *joint_type, const double *axis, const double *parent_pos,
          const double *parent_orn, const double *inertial_pos, const double *inertial_orn, const int64_t *q_index,
          const int64_t *qdot_index);
    int n_links() const { return int(links_.size()); }
    int n_q() const { return n_q_; }        // length of the flat q
    int n_qdot() const { return n_qdot_; }  // length of the flat qdot
    const ChainLink &link(int i) const { return links_[i]; }

  private:
    std::vector<ChainLink> links_;
    int n_q_ = 0, n_qdot_ = 0;
};

// How far the fitted motion of a link's frame can be from its true path over a
// piece of the step (ChainMotion::fit). Each bound is affine in r, the distance of
// a point from the frame's origin; the point bound is the smaller of two.
struct FitBound {
    // From the rates alone, factor by factor (chain.cpp): a point within r of the
    // frame's origin is off its fitted place by at most factor0 + factor1 r.
    double factor0, factor1;
    // From the exact third derivative at the piece's middle plus how much it can
    // change over the piece: at most local0 + local1 r.
    double local0, local1;
    // The fitted 3x3 part is off the true rotation by at most this (spectral norm).
    double rotation;
    // A point within r of the frame's origin stays within sweep0 + sweep1 r of
    // where it is at the piece's middle (what a constant fit errs by).
    double sweep0, sweep1;
    // How far a point within r of the frame's origin can be from its fitted place (a length, world).
    double point(double r) const {
        const double a = factor0 + factor1 * r, b = local0 + local1 * r;
        return a < b ? a : b;
    }
    double sweep(double r) const { return sweep0 + sweep1 * r; }
};

// One body's links over one step: the chain and the state read after the step.
// The chain must outlive the motion.
class ChainMotion {
  public:
    // state: the base's frame state after the step (FrameState, 13: centre of
    // mass, quaternion x y z w, v, w, world); q (chain.n_q()), qdot
    // (chain.n_qdot()): the joints after the step; dt > 0 the step. Throws
    // std::invalid_argument for values that are not finite or dt <= 0.
    ChainMotion(const Chain &chain, const double *state, const double *q, const double *qdot, double dt);

    const Chain &chain() const { return *chain_; }
    const double *state() const { return state_; }  // the base's frame state after the step (13)
    double dt() const { return dt_; }
    // The base's centre-of-mass frame at tau: position (3), quaternion x y z w (4).
    void base_pose(double tau, double *pose) const;
    // Link `link`'s centre-of-mass frame at tau (position, quaternion: 7).
    void link_pose(int link, double tau, double *pose) const;
    // Every link's frame at tau: (n_links, 7).
    void link_poses(double tau, double *poses) const;
    // The joints' coordinates at tau, flat as q (chain.n_q()): what
    // resetJointStateMultiDof takes to put the body where it is at tau.
    void joint_positions(double tau, double *q) const;
    // The quadratic motion of link `link`'s frame over [lo, hi] (on s in [0, 1],
    // interpolating its pose at lo, mid and hi; 3x4x4 row-major, as fit_path)
    // and how far it can be from the true path (see FitBound and chain.cpp).
    FitBound fit(int link, double lo, double hi, double *coeffs) const;
    // The bound alone (cheaper: one pose of the link's ancestors).
    FitBound fit_bound(int link, double lo, double hi) const;
    // The frame-state row (FrameState, 13) of link `link` (-1: the base): its pose
    // after the step, then the velocities (v, w) that carry its pose before the step
    // to it in the step's dt linearly and about a fixed axis at a constant rate: the
    // chord of its step (the turn the short way round, as path_row_between takes it).
    void chord_state(int link, double *row) const;

  private:
    struct JointStep {  // a joint's motion over the step
        double q1[4];        // its coordinates after the step (spherical: unit quaternion)
        double axis[3];      // the axis it turns about (unit, link frame; spherical: qdot's direction)
        double angle;        // turned over the step (revolute, spherical), signed for revolute
        double shift;        // slid over the step along `axis` as reported (prismatic)
    };
    // The joint's transform at tau: child frame in the parent's, as J(q(tau)) and s(tau).
    void joint_at(int link, double tau, double *J, double &s) const;
    // The child's pose from its parent's (7 each).
    void child_pose(int link, const double *parent, double tau, double *out) const;
    // Link and ancestors, innermost first.
    int ancestors(int link, int *out) const;

    const Chain *chain_;
    double state_[13], dt_;
    std::vector<JointStep> joints_;
    double base_angle_;  // turned over the step (bullet_step_angle)
    double base_axis_[3];
    double base_shift_;  // |v| dt
};

// A box fixed to a link (X_CS: the box in the link's centre-of-mass frame, 4x4;
// half extents), on the link's path. The motion must outlive it.
class LinkBoxPath : public BoxPath {
  public:
    LinkBoxPath(const ChainMotion &motion, int link, const double *X_CS, const double *half);
    void pose(double tau, double *X_WS) const override;
    const double *half_extents() const override { return half_; }
    double fit(double lo, double hi, double *coeffs) const override;
    int pieces(double fit_tolerance) const override;
    bool finite() const override { return true; }  // checked when built
    double travel(double lo, double hi) const override;
    double reach() const override { return reach_; }

  private:
    struct Growth {
        double length;  // how much the half extents grow
        bool still;     // the box held at the middle pose (else the quadratic fit)
    };
    Growth growth(double lo, double hi) const;  // of the better fit on [lo, hi]

    const ChainMotion *motion_;
    int link_;
    double X_CS_[16], half_[3];
    double reach_;  // the farthest point of the box from the link frame's origin
};

// A body's boxes that move farther than their sweep reach over the step: box k
// sits on link links[k] (-1: the base, on the free-frame path of the motion's
// base state) at X_CS + 16 k with half extents half + 3 k. For each box whose
// points move more than reach[k] from the step's start to its end (step_reach
// of its frame's chord_state), its index k, that move and its world bounds over
// the step (path_bounds: one piece when it moves less than its smallest half
// extent, else four).
struct FastBox {
    int64_t index;
    double move;
    double lo[3], hi[3];
};
std::vector<FastBox> fast_boxes(const ChainMotion &motion, size_t n, const int64_t *links, const double *X_CS,
                                const double *half, const double *reach);

}  // namespace boxccd
