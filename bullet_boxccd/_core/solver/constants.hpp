// Every number the solver and the paths decide by: the caller's Tolerances
// (validated here, defaults defined here once; the Python Tolerances reads them)
// and one block of fixed constants, each with its reason. Lengths are relative:
// a constant that compares lengths multiplies a size or a magnitude of the
// inputs, never a bare number of metres.
#pragma once

#include <limits>
#include <stdexcept>

namespace boxccd {

constexpr double kEps = std::numeric_limits<double>::epsilon();

// Bad tolerances (translated to InvalidToleranceError in Python).
struct ToleranceError : std::runtime_error { using std::runtime_error::runtime_error; };

// The caller's tolerances.
struct Tolerances {
    // Boxes closer than gap_rel * (world size of A + world size of B) count as
    // touching. Small enough that a 1e-9 relative gap is a clear miss; >= 0, or
    // "never late" no longer holds; <= 0.1, past any use.
    double gap_rel = 1e-12;
    // Rounding allowance: each facet's evaluation error is bounded by
    // rounding * DBL_EPSILON * (a magnitude bound of its terms), and that much is
    // added to the touching tolerance, so rounding can make the answer early,
    // never late. The same multiple bounds the rounding of every other quantity
    // the solver compares (octant-switch proofs, fixed-axis bounds). <= 1e10
    // (2e-6 relative): past any use.
    double rounding = 64.0;
    // Cap on advancement steps per section; each step passes one root of one
    // facet polynomial (at most 30 * 6 of them), so the cap is never reached in
    // exact arithmetic. If it is, the answer is contact at the current time with
    // the outcome StepCap (early, never late).
    int max_steps = 400;
};

// Throws ToleranceError naming the first bad field.
void validate(const Tolerances &tol);

// ------------------------------------------------------------------ constants
// Root isolation (poly.hpp).
// A root bracket in s counts as converged at 2^-50: a few doubles near s = 1, so
// contact times are resolved to ~1e-15 of the range.
constexpr double kRootWidth = 8.8817841970012523e-16;
// Bernstein halving stops at depth 60: the interval is then 2^-60 of the range,
// below the spacing of doubles near 1, so sign variations left there are roots
// that double precision cannot separate (clustered roots).
constexpr int kMaxSubdivisionDepth = 60;
// Illinois steps before the bracket is finished by bisection: Illinois converges
// superlinearly (~10 steps to kRootWidth), bisection needs at most 52 more.
constexpr int kMaxSecantSteps = 40;
// Sign changes of a switch polynomial within this many root widths of the
// section boundary just passed are that same switch, found again by rounding.
constexpr double kSwitchRepeat = 4.0;

// Axes (bms.hpp). An axis spanned by two generators has no direction when
// |a x b| <= kParallel * |a| |b| (edges parallel within 1e-9 rad): its facets
// are slivers whose normal rounding cannot fix, and skipping an axis only
// weakens the separation tests (the other 14 still decide contact).
constexpr double kParallel = 1e-9;
// The same test on squares, |a x b|^2 <= kParallel2 |a|^2 |b|^2 (no square root).
constexpr double kParallel2 = kParallel * kParallel;
// The same bound serves the edge-edge contact point: edges closer to parallel than
// kParallel2 (relative |u x v|^2 / (|u|^2 |v|^2)) have no unique closest points; the
// midpoint of the overlap is taken instead.

// Octant-switch proofs (route.cpp): the switch values p and p' at an interval's
// middle come from the generators there; p' sums twice as many products, each
// up to twice as large, as p, so its rounding bound is kDerivativeRounding times
// p's (both are also scaled by Tolerances::rounding).
constexpr double kDerivativeRounding = 8.0;

// Conservative advancement before the BMS search (culling.cpp). Each step
// proves the boxes apart along a fixed direction until a bound of its gap
// reaches zero; once the gap is below kHandover * size, the BMS search takes
// over on a window kWindow times the last step long (a window that ends before
// the contact costs one more advancement and a doubled window). kMaxCullSteps
// caps the advancement (slow, grazing approaches converge linearly); the BMS
// search then starts where it stopped. Measured on the benchmark pairs
// (instructions and simulated branch mispredictions, callgrind): kHandover 0.05
// to 0.3 within 5%, 0.1 the least for hits.
constexpr double kHandover = 1e-1;
constexpr double kWindow = 2.0;
// The first steps use the centre line d as the fixed direction (six projections
// instead of 15 axes: boxes far apart are as well separated along it) while it
// separates by more than kCentreLine * size; the 15 axes take over nearer.
// Measured on the benchmark pairs: 0.1 to 0.5 within 1%, 2 or never 3-13% slower.
constexpr double kCentreLine = 0.25;
constexpr int kMaxCullSteps = 12;
// The BMS search runs window after window (each proven apart to its end hands
// back to the advancement); this caps the windows (a pass that grazes the
// boxes for the whole range). Reaching it ends with the outcome StepCap.
constexpr int kMaxWindows = 64;

// Step path (step_path.cpp).
// Bullet clamps a body's turn per step at pi/4 (btMultiBody's and
// btTransformUtil's ANGULAR_MOTION_THRESHOLD), and scales the quaternion so that
// the realised angle is 2 atan(|w| dt / (pi/4) tan(pi/8)): bullet_step_angle.
constexpr double kAngularMotionThreshold = 0.25 * 3.14159265358979323846;
// Quadratic interpolation of f through s = 0, 1/2, 1 errs by at most
// max|f'''| / 3! * max_[0,1] |s (s - 1/2)(s - 1)| = max|f'''| sqrt(3) / 216
// (for a vector f too: the error is w(s) f[0, 1/2, 1, s], and the divided
// difference is an average of f''' / 3! with a non-negative weight, the
// Hermite-Genocchi formula, so its norm is at most max|f'''| / 3!).
constexpr double kInterpolationError = 1.7320508075688772 / 216.0;
// A turn by phi about a fixed axis is I + sin(phi s) K + (1 - cos(phi s)) K^2
// with |K| = |K^2| = 1; the interpolation of sin and of 1 - cos errs by at most
// kInterpolationError phi^3 each, so the fitted 3x3 part by at most twice that.
constexpr double kFitErrorPerCubedAngle = 2.0 * kInterpolationError;
// Swept bounds: the pose at five step fractions is evaluated in double
// precision, each coordinate within a few eps of |centre| + reach radius; the
// bounds are widened by this many eps of that magnitude.
constexpr double kBoundsRounding = 64.0;
// Bisection of the first overlap depth stops at 1e-15 of the step (the
// resolution of the step fraction near 1), after at most 200 halvings.
constexpr double kDepthWidth = 1e-15;
constexpr int kMaxDepthHalvings = 200;
// The depth look-ahead tries offsets 2^-k of the rest of the step, k = 48..0:
// 2^-48 of a step is below any contact's resolution.
constexpr int kDepthLookAhead = 48;
// Between two look-ahead samples below the target, at most this many more depth
// evaluations look for a depth that rose past it and fell back (first_depth).
constexpr int kGapSamples = 32;
// A contact window on the step path shorter than this fraction of the step is
// widened to it (the refit needs a window that double precision can split), and
// the refit's boxes grow by this fraction of their reach radius so that the
// touch found in the window cannot be lost to the refit's rounding.
constexpr double kMinWindow = 1e-12;
// A step's fit is cut into at most this many pieces (powers of two): past it the
// motion is too fast for quadratic pieces to pay, and each piece's box grows by
// its own proven error instead (fit_path's bound, never late).
constexpr int kMaxFitPieces = 64;

// Boxes on any path (box_path.cpp, chain.cpp).
// Rounding of the link poses a fit interpolates, per level of the chain, relative
// to the lengths involved: a few products and sums of eps each; taken generously.
constexpr double kFitRounding = 32.0 * kEps;

}  // namespace boxccd
