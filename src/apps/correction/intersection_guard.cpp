// Corrections that would make the surface intersect itself: split into steps that do
// not, or limited to the largest fraction that does not.
#include <fmt/format.h>

#include <algorithm>

#include "correction_internal.h"

namespace meshpde::correction {

// The guard's continuation, for a one-shot field `one_shot` (the whole displacement
// solved at once) that creates the new intersections `found`. From each surface
// reached (first the mesh itself) it takes the largest step of the rest of the
// displacement (all of it, its half, its quarter ... down to 1 / max_substeps of the
// whole; from the mesh itself at most half) that creates none, and solves again on
// the operators of the surface reached. When no step fits, the smallest one tried is
// limited by bisection to the largest fraction that creates none, and so is the
// one-shot field: the one that applies more is kept. A step of a static, unguided
// solve is linear in its size (the handles' share), so trying a smaller one costs an
// intersection check, not a solve: the solves are the surfaces reached. With an image
// each step is solved at its size.
//
// Checks: `new_pairs(V)` finds the pairs intersecting at V that did not at the start
// (all triangles of the region: the costly check); `among(V, pairs)` tests given pairs
// only. A state is tried against the pairs met so far first, and only when none of them
// intersects against all. A bisection runs on the pairs met so far, and its answer is
// then checked against all; pairs found there join, and it goes on below that answer.
Field guarded_steps(const Mesh& mesh, const CorrectionParams& p, const FemProblem& problem, const Field& one_shot,
                    const TrianglePairs& found, const std::function<TrianglePairs(const Positions&)>& new_pairs,
                    const std::function<TrianglePairs(const Positions&, const TrianglePairs&)>& among,
                    CorrectionResult& r) {
  const Positions& V0 = mesh.positions();
  TrianglePairs met;  // new intersections seen so far
  auto meet = [&](const TrianglePairs& more) {
    met.insert(met.end(), more.begin(), more.end());
    std::sort(met.begin(), met.end());
    met.erase(std::unique(met.begin(), met.end()), met.end());
  };
  meet(found);
  auto clean = [&](const Positions& V) {
    if (!among(V, met).empty()) return false;
    const TrianglePairs more = new_pairs(V);
    meet(more);
    return more.empty();
  };
  // The largest t in [0, 1] (to 2^-12) with no new intersection at base + t step; base
  // has none.
  auto limit = [&](const Field& base, const Field& step) {
    double lo = 0, hi = 1;
    for (int round = 0; round < 8; ++round) {
      for (int it = 0; it < 12; ++it) {
        const double mid = 0.5 * (lo + hi);
        (among(V0 + base + mid * step, met).empty() ? lo : hi) = mid;
      }
      if (lo == 0) return 0.0;
      const TrianglePairs more = new_pairs(V0 + base + lo * step);
      if (more.empty()) return lo;
      meet(more);
      hi = lo;
      lo = 0;
    }
    return 0.0;
  };
  const bool linear = p.image.edges == nullptr;
  const double smallest = 1.0 / std::max(1, p.max_substeps);
  Field total = Field::Zero(mesh.num_vertices(), 3);
  double done = 0;
  int steps = 0;
  Mesh cur = mesh;
  Field unit = one_shot;  // linear case: the whole displacement's field from the current state
  bool fresh = true;      // whether `unit` belongs to the current state
  auto step_of = [&](double size) {
    if (!linear) return fem_solve(cur, p, problem, size, r);
    if (!fresh) {
      unit = fem_solve(cur, p, problem, 1.0, r);
      fresh = true;
    }
    return Field(size * unit);
  };
  for (;;) {
    const double remainder = 1 - done;
    double failed = remainder;  // the smallest step tried here (all intersect)
    Field failed_step;          // its field
    bool taken = false;
    // From V0 the whole displacement is the one-shot field, which intersects.
    for (double size = steps == 0 ? 0.5 : remainder; size == remainder || size >= smallest * (1 - 1e-12); size *= 0.5) {
      const Field step = step_of(size);
      if (clean(V0 + total + step)) {
        total += step;
        done += size;
        ++steps;
        taken = true;
        break;
      }
      failed = size;
      failed_step = step;
    }
    if (!taken) {
      // (No step tried when max_substeps allows none smaller than the first: the whole.)
      const Field step = failed_step.size() > 0 ? failed_step : step_of(failed);
      const double t = limit(total, step);
      // The one-shot field limited as a whole may reach farther.
      const double whole = limit(Field::Zero(mesh.num_vertices(), 3), one_shot);
      if (whole >= done + t * failed) {
        total = whole * one_shot;
        done = whole;
        steps = 1;
      } else {
        total += t * step;
        done += t * failed;
        steps += t > 0;
      }
      break;
    }
    if (done >= 1 - 1e-12) break;
    cur.set_positions(V0 + total);
    fresh = false;
  }
  r.substeps = std::max(steps, 1);
  if (done >= 1 - 1e-12) {
    r.intersection_action = fmt::format("split into {} steps", steps);
  } else {
    r.applied_fraction = done;
    r.intersection_action = fmt::format("limited to {:.3f} of the displacement", done);
  }
  r.new_self_intersections = 0;  // every state taken was checked against all pairs
  return total;
}

}  // namespace meshpde::correction
