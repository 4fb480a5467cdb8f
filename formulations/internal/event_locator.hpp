// Event location for fixed-step steppers (no SUNDIALS root finder): after an accepted step
// [t_n, t_n + h] whose event values changed sign, the earliest root s* ∈ (0, h] of the
// event functions g(s), evaluated on the stepper's dense output, is bracketed and narrowed
// by the Illinois variant of the secant rule (Dowell & Jarratt 1971: the retained end's
// value is halved when the same end is kept twice, so the bracket shrinks superlinearly
// even on convex g) until it is `resolution` wide. Used by `newmark` and
// `generalized-alpha` (newmark.cpp); any stepper with a dense output can call it.
//
// Accuracy: the located time is the root of g on the dense output, so its error is the
// dense output's error divided by |ġ|, on top of the stepper's global error at t*. For the
// Newmark family the dense output is cubic Hermite in (q, q̇) (O(h⁴)) and linear in q̈ and
// the multipliers (O(h²), consistent with the scheme's order); the split between location
// and global error on the chapter scene: benchmarks/README.md, "Work-precision sweep".
//
// No allocation once the workspace has been sized (Reserve at the start of a phase).
#pragma once

#include <algorithm>
#include <vector>

#include "solver/events.hpp"

namespace kneedyn {

// Whether g went from a to b through zero in the spec's direction (SUNDIALS convention:
// −1 decreasing only, +1 increasing only, 0 both). A start exactly on zero does not fire
// (a driver restarts a phase on the root just passed).
inline bool EventCrosses(int direction, double a, double b) {
  const bool down = a > 0.0 && b <= 0.0;
  const bool up = a < 0.0 && b >= 0.0;
  return direction < 0 ? down : direction > 0 ? up : (down || up);
}

// Indices of the events that crossed between the values a and b (into *out, cleared).
inline void CrossedEvents(const std::vector<EventSpec>& specs, const std::vector<double>& a,
                          const std::vector<double>& b, std::vector<int>* out) {
  out->clear();
  for (size_t i = 0; i < specs.size(); ++i) {
    if (EventCrosses(specs[i].direction, a[i], b[i])) out->push_back(static_cast<int>(i));
  }
}

struct EventLocatorWorkspace {
  std::vector<double> g_lo, g_hi, g_mid;
  std::vector<int> crossed;
  void Reserve(size_t events) {
    g_lo.reserve(events);
    g_hi.reserve(events);
    g_mid.resize(events);
    crossed.reserve(events);
  }
};

struct LocatedEvent {
  double s = 0.0;          // right end of the final bracket (just past the root), in (0, h]
  std::vector<int> fired;  // events that crossed between s = 0 and s
  int iterations = 0;      // evaluations of g
};

// Narrows the earliest root in (0, h] of the events that crossed between g_start (s = 0)
// and g_end (s = h). evaluate(s, double* g) fills g (specs.size() values) at t_n + s. On
// return ws->g_hi holds g at out->s. At most max_iterations evaluations; each trial point
// stays resolution/2 inside the bracket.
template <typename Evaluate>
void LocateEarliestEvent(const std::vector<EventSpec>& specs, const std::vector<double>& g_start,
                         const std::vector<double>& g_end, double h, double resolution, int max_iterations,
                         Evaluate&& evaluate, EventLocatorWorkspace* ws, LocatedEvent* out) {
  double lo = 0.0, hi = h;
  ws->g_lo.assign(g_start.begin(), g_start.end());
  ws->g_hi.assign(g_end.begin(), g_end.end());
  ws->g_mid.resize(specs.size());
  double w_lo = 1.0, w_hi = 1.0;  // Illinois weights on the retained ends
  int last_moved = 0;             // −1 lo moved, +1 hi moved
  out->iterations = 0;
  while (out->iterations < max_iterations && hi - lo > resolution) {
    // Secant (regula falsi) point of the earliest crossing among the events still bracketed.
    double fraction = 1.0;
    CrossedEvents(specs, ws->g_lo, ws->g_hi, &ws->crossed);
    for (int e : ws->crossed) {
      const double a = w_lo * ws->g_lo[e], b = w_hi * ws->g_hi[e];
      fraction = std::min(fraction, a / (a - b));
    }
    const double s_mid = std::clamp(lo + fraction * (hi - lo), lo + 0.5 * resolution, hi - 0.5 * resolution);
    evaluate(s_mid, ws->g_mid.data());
    ++out->iterations;
    CrossedEvents(specs, ws->g_lo, ws->g_mid, &ws->crossed);
    if (!ws->crossed.empty()) {
      hi = s_mid;
      ws->g_hi.swap(ws->g_mid);
      w_hi = 1.0;
      if (last_moved == +1) w_lo *= 0.5;
      last_moved = +1;
    } else {
      lo = s_mid;
      ws->g_lo.swap(ws->g_mid);
      w_lo = 1.0;
      if (last_moved == -1) w_hi *= 0.5;
      last_moved = -1;
    }
  }
  out->s = hi;
  CrossedEvents(specs, g_start, ws->g_hi, &out->fired);
}

}  // namespace kneedyn
