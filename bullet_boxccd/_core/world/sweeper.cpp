#include "world/sweeper.hpp"

#include <algorithm>
#include <cmath>
#include <limits>
#include <stdexcept>
#include <string>

#include "paths/box_path.hpp"

namespace boxccd {

void check_index(int64_t i, size_t n, const char *what) {
    if (i < 0 || size_t(i) >= n) throw std::out_of_range(std::string(what) + " index " + std::to_string(i) + " out of range");
}

// Up to this many bound tests (fast boxes times boxes), testing every pair costs less than
// sorting the boxes.
static constexpr int64_t kBruteForcePairs = 4096;

static bool bounds_meet(const double *a, const double *b) {
    return a[0] <= b[3] && b[0] <= a[3] && a[1] <= b[4] && b[1] <= a[4] && a[2] <= b[5] && b[2] <= a[5];
}

std::vector<std::pair<int64_t, int64_t>> candidate_pairs(const double *bounds, int64_t n, int64_t n_fast,
                                                         const int64_t *frame, const int64_t *frame_body,
                                                         const uint8_t *self_collides, const FrameFilter &filter) {
    std::vector<std::pair<int64_t, int64_t>> out;
    const auto consider = [&](int64_t i, int64_t j) {  // i fast; j any other box
        if (!bounds_meet(bounds + 6 * i, bounds + 6 * j)) return;
        const int64_t fi = frame[i], fj = frame[j];
        if (fi == fj) return;  // boxes of one link never collide with each other
        if (frame_body[fi] == frame_body[fj] && !self_collides[fi]) return;
        if (!filter.allowed(fi, fj)) return;
        out.emplace_back(i, j);
    };
    if (n_fast * n <= kBruteForcePairs) {
        for (int64_t i = 0; i < n_fast; ++i)
            for (int64_t j = 0; j < n; ++j)
                if (j != i && (j >= n_fast || j > i)) consider(i, j);
        return out;
    }
    // Sort and sweep along the axis the boxes spread most on; boxes with a NaN bound meet
    // nothing (as in the comparisons above). The pairs come out in the order above.
    std::vector<int64_t> order;
    order.reserve(size_t(n));
    double lo[3] = {INFINITY, INFINITY, INFINITY}, hi[3] = {-INFINITY, -INFINITY, -INFINITY};
    for (int64_t i = 0; i < n; ++i) {
        const double *b = bounds + 6 * i;
        bool ordered = true;
        for (int k = 0; k < 6; ++k) ordered = ordered && !std::isnan(b[k]);
        if (!ordered) continue;
        order.push_back(i);
        for (int k = 0; k < 3; ++k) {
            const double c = 0.5 * (b[k] + b[k + 3]);
            lo[k] = std::min(lo[k], c);
            hi[k] = std::max(hi[k], c);
        }
    }
    int axis = 0;
    for (int k = 1; k < 3; ++k)
        if (hi[k] - lo[k] > hi[axis] - lo[axis]) axis = k;
    std::sort(order.begin(), order.end(), [&](int64_t a, int64_t b) {
        const double la = bounds[6 * a + axis], lb = bounds[6 * b + axis];
        return la < lb || (la == lb && a < b);
    });
    for (size_t s = 0; s < order.size(); ++s) {
        const int64_t a = order[s];
        const double reach = bounds[6 * a + axis + 3];
        for (size_t t = s + 1; t < order.size() && bounds[6 * order[t] + axis] <= reach; ++t) {
            const int64_t b = order[t];
            if (a < n_fast && b < n_fast)
                consider(std::min(a, b), std::max(a, b));
            else if (a < n_fast)
                consider(a, b);
            else if (b < n_fast)
                consider(b, a);
        }
    }
    std::sort(out.begin(), out.end());
    return out;
}

// For each of the n boxes (indices checked against the table and their frames against
// n_frames): row(box, its frame, its output row).
template <class Row>
static void for_each_box_row(const int64_t *boxes, size_t n, size_t n_frames, const BoxTable &table, double *out,
                             Row row) {
    for (size_t i = 0; i < n; ++i) {
        const int64_t b = boxes[i];
        check_index(b, table.n, "box");
        const int64_t f = table.box_frame[b];
        check_index(f, n_frames, "frame");
        row(b, f, out + kPathBoxSize * i);
    }
}

void path_rows(const double *state, size_t n_frames, double dt, const int64_t *boxes, size_t n,
               const BoxTable &table, double *out) {
    for_each_box_row(boxes, n, n_frames, table, out, [&](int64_t b, int64_t f, double *row) {
        path_row(state + kFrameStateSize * f, dt, table.X_CS + 16 * b, table.half + 3 * b, row);
    });
}

void path_rows_between(const double *poses0, const double *poses1, size_t n_frames, const int64_t *boxes, size_t n,
                       const BoxTable &table, double *out) {
    for_each_box_row(boxes, n, n_frames, table, out, [&](int64_t b, int64_t f, double *row) {
        path_row_between(poses0 + 7 * f, poses1 + 7 * f, table.X_CS + 16 * b, table.half + 3 * b, row);
    });
}

void frame_poses(const double *state, size_t n_frames, double dt, const int64_t *frames, const double *taus,
                 size_t n, double *out) {
    for (size_t i = 0; i < n; ++i) {
        check_index(frames[i], n_frames, "frame");
        frame_pose(state + kFrameStateSize * frames[i], dt, taus[i], out + 7 * i);
    }
}

long first_touches(const double *rows, const int64_t *pairs, size_t n, double fit_tolerance, const Tolerances &tol,
                   double penetration, double creep, double *out, int8_t *state, int64_t *counts) {
    long solves = 0;
    std::vector<RowBoxPath> paths;  // one per row a pair names (rows are shared by a fast box's pairs)
    std::vector<int64_t> path_of;
    for (size_t k = 0; k < 2 * n; ++k) {
        if (size_t(pairs[k]) >= path_of.size()) path_of.resize(size_t(pairs[k]) + 1, -1);
        if (path_of[size_t(pairs[k])] < 0) {
            path_of[size_t(pairs[k])] = int64_t(paths.size());
            paths.emplace_back(rows + kPathBoxSize * pairs[k]);
        }
    }
    for (size_t k = 0; k < n; ++k) {
        const RowBoxPath &a = paths[size_t(path_of[size_t(pairs[2 * k])])];
        const RowBoxPath &b = paths[size_t(path_of[size_t(pairs[2 * k + 1])])];
        const double depth0 = path_depth(a, b, 0.0);
        Outcome o;
        out[k] = first_touch(a, b, fit_tolerance, tol, solves, o, depth0);
        if (out[k] == 0.0 && creep >= 0.0 && !presses_in(a, b, penetration, creep, depth0)) {
            out[k] = std::numeric_limits<double>::quiet_NaN();
            o = Outcome::Separated;
        }
        if (state) state[k] = static_cast<int8_t>(o);
        if (counts) ++counts[static_cast<int>(o)];
    }
    return solves;
}

Sweeper::Sweeper(const Tables &t)
    : n_(t.n_boxes), box_frame_(t.box_frame, t.box_frame + t.n_boxes), radius_(t.radius, t.radius + t.n_boxes),
      X_CS_(t.X_CS, t.X_CS + 16 * t.n_boxes), half_(t.half, t.half + 3 * t.n_boxes),
      sweep_reach_(t.sweep_reach, t.sweep_reach + t.n_boxes), frame_body_(t.frame_body, t.frame_body + t.n_frames),
      self_collides_(t.self_collides, t.self_collides + t.n_frames), group_(t.group, t.group + t.n_frames),
      mask_(t.mask, t.mask + t.n_frames), mode_(t.filter_mode), state_(kFrameStateSize * t.n_frames, 0.0) {
    for (const int64_t f : box_frame_) check_index(f, t.n_frames, "frame");
    for (size_t f = 0; f < t.n_frames; ++f) state_[kFrameStateSize * f + FrameState::kOrientation + 3] = 1.0;
}

Sweeper::Fast Sweeper::fast(double dt, double clamp) const {
    Fast out;
    for (size_t i = 0; i < n_; ++i) {
        const int64_t f = box_frame_[i];
        const double r = step_reach(state_.data() + kFrameStateSize * f, dt, radius_[i]);
        if (!std::isfinite(r)) {  // a broken body (pybullet's NaN) is left to pybullet
            out.broken.push_back(f);
            continue;
        }
        if (std::isfinite(sweep_reach_[i]) && at_clamp(f, clamp)) out.clamped.push_back(f);
        if (r > sweep_reach_[i]) {
            out.boxes.push_back(int64_t(i));
            out.frames.push_back(f);
        } else {
            out.slack = std::fmax(out.slack, r);
        }
    }
    std::sort(out.frames.begin(), out.frames.end());
    out.frames.erase(std::unique(out.frames.begin(), out.frames.end()), out.frames.end());
    for (auto *v : {&out.broken, &out.clamped}) {
        std::sort(v->begin(), v->end());
        v->erase(std::unique(v->begin(), v->end()), v->end());
    }
    return out;
}

bool Sweeper::at_clamp(int64_t f, double speed, double rel_tol) const {
    // pybullet clamps each component of a body's velocity and spin (world axes) on its own.
    const double *twist = state_.data() + kFrameStateSize * f + FrameState::kVelocity;  // v, w
    return std::any_of(twist, twist + 6, [&](double c) { return std::fabs(c) >= speed - rel_tol * speed; });
}

std::vector<int64_t> Sweeper::at_speed(const std::vector<int64_t> &frames, double speed, double rel_tol) const {
    std::vector<int64_t> out;
    for (const int64_t f : frames) {
        check_index(f, n_frames(), "frame");
        if (at_clamp(f, speed, rel_tol)) out.push_back(f);
    }
    return out;
}

double Sweeper::slack(double dt) const {
    double out = 0.0;
    for (size_t i = 0; i < n_; ++i) {
        if (!std::isfinite(sweep_reach_[i])) continue;
        const double r = step_reach(state_.data() + kFrameStateSize * box_frame_[i], dt, radius_[i]);
        if (std::isfinite(r)) out = std::fmax(out, r);
    }
    return out;
}

void Sweeper::velocities_at(double dt, double tau, const int64_t *frames, const int8_t *mode, size_t n,
                            const double *twist0, const double *gravity, const double *damping, double *v,
                            double *w, uint8_t *still) const {
    for (size_t k = 0; k < n; ++k) {
        check_index(frames[k], n_frames(), "frame");
        const double *after = state_.data() + kFrameStateSize * frames[k] + FrameState::kVelocity;  // v, w
        const double *before = twist0 ? twist0 + 6 * frames[k] : nullptr;
        bool rest = before != nullptr;
        for (int i = 0; i < 6; ++i) rest = rest && after[i] == 0.0 && before[i] == 0.0;
        still[k] = rest;
        double out[6];
        velocity_at(after, before, mode[k], dt, tau, gravity, damping ? damping + 2 * frames[k] : nullptr, out);
        std::copy(out, out + 3, v + 3 * k);
        std::copy(out + 3, out + 6, w + 3 * k);
    }
}

void Sweeper::check_boxes(const std::vector<int64_t> &boxes) const {
    for (const int64_t b : boxes) check_index(b, n_, "box");
}

void Sweeper::rows(double dt, const int64_t *boxes, size_t n, double *rows, double *bounds) const {
    for (size_t i = 0; i < n; ++i) check_index(boxes[i], n_, "box");
    path_rows_and_bounds(dt, boxes, n, rows, bounds);
}

void Sweeper::path_rows_and_bounds(double dt, const int64_t *boxes, size_t n, double *rows, double *bounds) const {
    for (size_t i = 0; i < n; ++i) {
        const int64_t b = boxes[i];
        path_row(state_.data() + kFrameStateSize * box_frame_[b], dt, X_CS_.data() + 16 * b, half_.data() + 3 * b,
                 rows + kPathBoxSize * i);
        swept_bounds(rows + kPathBoxSize * i, bounds + 6 * i, bounds + 6 * i + 3);
    }
}

Sweeper::Touches Sweeper::touches(double dt, std::vector<int64_t> boxes, int64_t n_moving, bool all_others,
                                  double fit_tolerance, const Tolerances &tol, double penetration, double creep,
                                  int64_t *counts) const {
    check_boxes(boxes);
    if (n_moving < 0 || size_t(n_moving) > boxes.size())
        throw std::invalid_argument("touches: n_moving out of range");
    Touches out;
    if (all_others) {
        std::vector<uint8_t> in(n_, 0);
        for (const int64_t b : boxes) in[b] = 1;
        for (size_t b = 0; b < n_; ++b)
            if (!in[b]) boxes.push_back(int64_t(b));
    }
    const size_t n = boxes.size();
    out.rows.resize(kPathBoxSize * n);
    std::vector<double> bounds(6 * n);
    path_rows_and_bounds(dt, boxes.data(), n, out.rows.data(), bounds.data());
    std::vector<int64_t> frame(n);
    for (size_t i = 0; i < n; ++i) frame[i] = box_frame_[boxes[i]];
    const FrameFilter filter{group_.data(), mask_.data(), mode_};
    const auto pairs = candidate_pairs(bounds.data(), int64_t(n), n_moving, frame.data(), frame_body_.data(),
                                       self_collides_.data(), filter);
    const size_t m = pairs.size();
    out.pairs = m;
    out.pair_rows.resize(2 * m);
    for (size_t k = 0; k < m; ++k) {
        out.pair_rows[2 * k] = pairs[k].first;
        out.pair_rows[2 * k + 1] = pairs[k].second;
    }
    out.tau.resize(m);
    out.solves = first_touches(out.rows.data(), out.pair_rows.data(), m, fit_tolerance, tol, penetration, creep,
                               out.tau.data(), nullptr, counts);
    out.boxes = std::move(boxes);
    return out;
}

}  // namespace boxccd
