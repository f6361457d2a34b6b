// The standard benchmarks behind `meshpde bench`: every figure with the baseline it is
// measured against in the same run (machines are shared and noisy: compare ratios).
#include "standard_benchmarks.h"

#include <fmt/format.h>

#include <algorithm>
#include <chrono>
#include <fstream>
#include <map>
#include <memory>
#include <numeric>
#include <optional>
#include <random>
#include <span>
#include <thread>

#include "meshpde/apps/haptics.h"
#include "meshpde/apps/interpolation.h"
#include "meshpde/apps/local_drag.h"
#include "meshpde/apps/vessel_correction.h"
#include "meshpde/core/errors.h"
#include "meshpde/core/parallel.h"
#include "meshpde/io/mesh_io.h"
#include "real_mesh_problem.h"
#ifdef MESHPDE_HAVE_MEDICAL
#include "meshpde/io/medical_io.h"
#endif
#include "meshpde/mesh/generators.h"
#include "meshpde/mesh/regions.h"
#include "meshpde/mesh/topology.h"
#include "meshpde/operators/fem_operators.h"
#include "meshpde/operators/laplacian.h"
#include "meshpde/pde/global_bilaplacian.h"
#include "meshpde/pde/pde_session.h"
#include "meshpde/pde/steady_direct.h"
#include "meshpde/solvers/direct.h"
#include "meshpde/solvers/ordering.h"

namespace meshpde::bench {

namespace {

using clock_type = std::chrono::steady_clock;
double seconds_since(clock_type::time_point t) {
  return std::chrono::duration<double>(clock_type::now() - t).count();
}

// The JSON name of the preconditioner that finished a global solve.
std::string preconditioner_name(GlobalBilaplacianParams::Preconditioner p) {
  return p == GlobalBilaplacianParams::Preconditioner::Multigrid ? "multigrid" : "laplacian-factor";
}

// One global steady solve with the given preconditioner, timed.
struct TimedGlobalSolve {
  GlobalBilaplacianResult r;
  double seconds = 0;
};
TimedGlobalSolve timed_global_solve(const Mesh& m, const FemOperators& o, const std::vector<int>& free, const Field& u,
                                    GlobalBilaplacianParams::Preconditioner preconditioner) {
  GlobalBilaplacianParams p;
  p.preconditioner = preconditioner;
  const auto t = clock_type::now();
  TimedGlobalSolve out{solve_global_bilaplacian(m, o, free, u, p), 0};
  out.seconds = seconds_since(t);
  return out;
}

// The default solve (Auto) through a GlobalBilaplacianSolver, timed with its set-up
// (what solve_global_bilaplacian costs), then a second solve on the same solver with
// the handle moved in another direction by as much: the preconditioner reused.
struct TimedGlobalResolve {
  GlobalBilaplacianResult first, second;
  double first_seconds = 0, second_seconds = 0;
  Field moved;  // the second solve's values
};
TimedGlobalResolve timed_global_resolve(const Mesh& m, const FemOperators& o, const std::vector<int>& free,
                                        const Field& u, int handle) {
  TimedGlobalResolve out;
  auto t = clock_type::now();
  GlobalBilaplacianSolver solver(m, o, free);
  out.first = solver.solve(u);
  out.first_seconds = seconds_since(t);
  out.moved = u;
  out.moved.row(handle) << u(handle, 2), -u(handle, 0), u(handle, 1);
  t = clock_type::now();
  out.second = solver.solve(out.moved);
  out.second_seconds = seconds_since(t);
  return out;
}

/// STREAM-like triad a = b + s c; bytes counted as STREAM does (3 arrays).
class Triad {
 public:
  explicit Triad(std::size_t n) : a_(n, 0.0), b_(n, 1.0), c_(n, 2.0) {}
  double run(double s) {
    const auto t = clock_type::now();
    const std::size_t n = a_.size();
    for (std::size_t i = 0; i < n; ++i) a_[i] = b_[i] + s * c_[i];
    const double dt = seconds_since(t);
    volatile double sink = a_[n / 2];
    (void)sink;
    return dt;
  }
  double bytes() const { return 3.0 * 8.0 * static_cast<double>(a_.size()); }

 private:
  std::vector<double> a_, b_, c_;
};

struct Percentiles {
  double p50 = 0, p99 = 0, max = 0, mean = 0;
};
Percentiles percentiles(std::vector<double> v) {
  std::sort(v.begin(), v.end());
  Percentiles p;
  if (v.empty()) return p;
  p.p50 = v[v.size() / 2];
  p.p99 = v[std::min(v.size() - 1, static_cast<std::size_t>(0.99 * static_cast<double>(v.size())))];
  p.max = v.back();
  p.mean = std::accumulate(v.begin(), v.end(), 0.0) / static_cast<double>(v.size());
  return p;
}

/// Icosphere scaled so its mean edge length is 1: meshes of every size then have the
/// same local resolution, and a poke touches the same neighbourhood on each.
Mesh unit_edge_icosphere(int level) {
  GeneratedMesh g = icosphere(level, 1.0);
  Mesh m(g.V, g.F);
  const double e = mean_edge_length(m);
  g.V /= e;
  return Mesh(g.V, g.F);
}

struct PokeFigures {
  Percentiles us;
  double mean_free = 0;
  int max_free = 0;
  double mean_iterations = 0;
  int misses = 0;
  int steps = 0;
};

/// One vertex constrained and moved a little every step along the inward normal
/// (in, then out again), dt = 1 ms, bi-Laplacian, self-adjusting domain.
PokeFigures poke(const Mesh& mesh, const FemOperators& ops, int steps, bool full_domain) {
  const PdeCoefficients coef{.alpha = 1.0, .b1 = 1.0, .b2 = 0.01, .g0 = 1.0, .g1 = 0.0, .g2 = 100.0};
  PdeSession s(mesh, ops, 3, coef,
               DomainOptions{.self_adjusting = !full_domain, .rest_value = 1e-4, .rest_rate = 1e-3});
  s.cg_options = CgOptions{.tolerance = 1e-6, .max_iterations = 200};
  if (full_domain) s.activate_all();
  int handle = 0;
  mesh.positions().col(2).maxCoeff(&handle);
  const Eigen::Vector3d n = mesh.positions().row(handle).normalized();
  PokeFigures out;
  std::vector<double> us;
  us.reserve(steps);
  const double depth = 0.5;  // half an edge length
  for (int k = 0; k < steps; ++k) {
    const double d = depth * std::sin(M_PI * (k + 1) / steps);
    const Eigen::Vector3d target = -d * n;
    const auto t = clock_type::now();
    s.constrain(handle, std::span<const double>(target.data(), 3));
    const StepResult r = s.step(1e-3);
    const double dt_us = seconds_since(t) * 1e6;
    us.push_back(dt_us);
    out.mean_free += r.free_vertices;
    out.max_free = std::max(out.max_free, r.free_vertices);
    out.mean_iterations += r.cg.iterations;
    out.misses += dt_us > 1000.0;
  }
  out.steps = steps;
  out.mean_free /= steps;
  out.mean_iterations /= steps;
  out.us = percentiles(us);
  return out;
}

// The haptic_* figures (BenchOptions::only = "haptic" runs these alone).
// Painting in the editor: InterpolationSolver's kept factor against a fresh direct
// interpolate() of the same constraints (what a paint click cost before), on igea-134k
// as it is and, with `large`, subdivided twice (2.15M vertices: minutes), with
// the editor's operators (LaplacianKind::Auto). Eight values painted and solved first
// (the factorization, paint_first_ms_*); then clicks that alternate a new value at a
// painted vertex and a new vertex, each timed from set_value to the field
// (paint_update_ms_*, the median; _max the slowest; _value_ and _vertex_ the medians of
// each kind), and the fresh solve of the same
// constraints after some of them (paint_resolve_ms_*, the median). The largest
// difference between the two answers is reported relative to the field's largest value.
// The same clicks run first through K D K's own factor (laplacian_factor_up_to 0:
// paint_bilaplacian_factor_*), the route InterpolationSolver takes with g1 or many
// constraints, beside the Laplacian's factor that it takes here; the two routes'
// answers agree to paint_routes_max_relative_difference_*.
// Last, a fresh start of the kept solver with those constraints (max_changes 0), which
// factors in the last factor's order (paint_restart_ms_*, beside paint_first_ms_*, whose
// factorization ordered afresh).
void paint_figures(const BenchOptions& options, nlohmann::json& j, bool large) {
  const auto progress = [&](const std::string& what) {
    if (options.progress) options.progress(what);
  };
  const auto igea = options.data_dir / "igea-134k.ply";
  if (!std::filesystem::exists(igea)) {
    if (options.warning) options.warning(igea.string() + " not found; the paint_* figures skipped");
    return;
  }
  const MeshData d = read_mesh(igea);
  GeneratedMesh g{d.V, d.F, {}};
  for (int level = 0; level < (large ? 3 : 1); ++level) {
    if (level) g = subdivide_midpoint(g.V, g.F);
    if (level == 1) continue;  // 537k: neither of the two sizes
    const std::string tag = level ? "1m" : "134k";
    progress("paint on igea-134k" + std::string(level ? " x2" : "") + ": operators");
    const MeshOperators mo = build_mesh_operators(Mesh(g.V, g.F), LaplacianKind::Auto);
    const int nv = mo.mesh.num_vertices();
    std::uniform_int_distribution<int> vertex(0, nv - 1);
    std::uniform_real_distribution<double> value(-1, 1);
    // The same clicks (the same random sequence) through K D K's own factor first
    // (laplacian_factor_up_to 0: the kept solver's route before the mixed form, the
    // baseline of this run), then as InterpolationSolver chooses.
    struct Clicks {
      std::vector<double> update_ms, by_kind[2];
      std::vector<Field> answers;  // the baseline's, for the other route to compare with
    };
    std::vector<double> resolve_ms;
    double worst = 0, routes = 0;  // routes: the two kept solvers' answers, click by click
    Field last_fresh;
    Clicks base, ours;
    auto run_clicks = [&](InterpolationSolver& solver, std::mt19937& r, Clicks& out, bool fresh) {
      const int clicks = options.quick ? 6 : 20;
      const int resolves = level ? (options.quick ? 1 : 2) : (options.quick ? 2 : 5);
      for (int c = 0; c < clicks; ++c) {
        progress(fmt::format("paint on {}{}: click {} of {}", tag, fresh ? "" : " (K D K's factor)", c + 1, clicks));
        const std::vector<InterpolationConstraint> now = solver.constraints();
        const int v = c % 2 == 0 ? now[r() % now.size()].vertex : vertex(r);
        const double x = value(r);
        const auto t0 = clock_type::now();
        solver.set_value(v, Eigen::VectorXd::Constant(1, x));
        const InterpolationResult kept = solver.solve();
        out.update_ms.push_back(seconds_since(t0) * 1e3);
        out.by_kind[c % 2].push_back(out.update_ms.back());
        if (fresh) {
          const Field& b = base.answers[static_cast<std::size_t>(c)];
          routes = std::max(routes, (kept.values - b).cwiseAbs().maxCoeff() / b.cwiseAbs().maxCoeff());
        } else {
          out.answers.push_back(kept.values);
        }
        if (fresh && c >= clicks - resolves) {
          const auto t1 = clock_type::now();
          const InterpolationResult f =
              interpolate(mo.mesh, mo.ops, FieldKind::Scalar, solver.constraints(),
                          InterpolationParams{.g1 = 0, .g2 = 1, .solver = SteadySolver::Direct});
          resolve_ms.push_back(seconds_since(t1) * 1e3);
          worst = std::max(worst, (kept.values - f.values).cwiseAbs().maxCoeff() / f.values.cwiseAbs().maxCoeff());
          last_fresh = f.values;
        }
      }
    };
    auto first_constraints = [&](InterpolationSolver& solver, std::mt19937& r) {
      for (int k = 0; k < 8; ++k) solver.set_value(vertex(r), Eigen::VectorXd::Constant(1, value(r)));
    };
    {
      std::mt19937 r(7);
      InterpolationSolver solver(mo.mesh, mo.ops, FieldKind::Scalar, InterpolationParams{.g1 = 0, .g2 = 1});
      solver.laplacian_factor_up_to = 0;
      first_constraints(solver, r);
      progress("paint on " + tag + " (K D K's factor): the first solve (factorization)");
      const auto t0 = clock_type::now();
      solver.solve();
      j["paint_bilaplacian_factor_first_ms_" + tag] = seconds_since(t0) * 1e3;
      run_clicks(solver, r, base, false);
    }
    std::mt19937 rng(7);
    InterpolationSolver solver(mo.mesh, mo.ops, FieldKind::Scalar, InterpolationParams{.g1 = 0, .g2 = 1});
    first_constraints(solver, rng);
    progress("paint on " + tag + ": the first solve (factorization)");
    auto t0 = clock_type::now();
    solver.solve();
    j["paint_first_ms_" + tag] = seconds_since(t0) * 1e3;
    run_clicks(solver, rng, ours, true);
    base.answers.clear();
    j["paint_bilaplacian_factor_update_ms_" + tag] = percentiles(base.update_ms).p50;
    j["paint_bilaplacian_factor_update_value_ms_" + tag] = percentiles(base.by_kind[0]).p50;
    j["paint_bilaplacian_factor_update_vertex_ms_" + tag] = percentiles(base.by_kind[1]).p50;
    j["paint_routes_max_relative_difference_" + tag] = routes;
    progress("paint on " + tag + ": a fresh start in the last factor's order");
    solver.max_changes = 0;
    t0 = clock_type::now();
    const InterpolationResult restarted = solver.solve();
    j["paint_restart_ms_" + tag] = seconds_since(t0) * 1e3;
    j["paint_restart_reused_order_" + tag] = solver.reused_orders();
    worst = std::max(worst, (restarted.values - last_fresh).cwiseAbs().maxCoeff() / last_fresh.cwiseAbs().maxCoeff());
    j["paint_vertices_" + tag] = nv;
    j["paint_update_ms_" + tag] = percentiles(ours.update_ms).p50;
    j["paint_update_ms_max_" + tag] = *std::max_element(ours.update_ms.begin(), ours.update_ms.end());
    j["paint_update_value_ms_" + tag] = percentiles(ours.by_kind[0]).p50;
    j["paint_update_vertex_ms_" + tag] = percentiles(ours.by_kind[1]).p50;
    j["paint_resolve_ms_" + tag] = percentiles(resolve_ms).p50;
    j["paint_update_over_resolve_" + tag] = percentiles(ours.update_ms).p50 / percentiles(resolve_ms).p50;
    j["paint_update_speedup_over_bilaplacian_factor_" + tag] =
        percentiles(base.update_ms).p50 / percentiles(ours.update_ms).p50;
    j["paint_max_relative_difference_" + tag] = worst;
    j["paint_factorizations_" + tag] = solver.factorizations();
    j["paint_laplacian_factor_" + tag] = solver.laplacian_factor();
  }
}

void haptic_figures(const BenchOptions& options, nlohmann::json& j) {
  const auto progress = [&](const std::string& what) {
    if (options.progress) options.progress(what);
  };
  const auto warn = [&](const std::string& what) {
    if (options.warning) options.warning(what);
  };
  // Haptic poke on a real scan and on the same scan subdivided twice (2.15M vertices):
  // the default haptic session, pressed along the inward normal to half an edge over
  // the first half of the steps and held, stepped by this thread at 1 kHz (dt = 1 ms;
  // each step followed by a sleep to the next tick, as a device's servo loop does), with
  // the factored solver (the default: haptic_*) and with CG (haptic_cg_*), beside a
  // fixed amount of arithmetic (haptic_fixed_work_*).
  // The settled force is compared with a direct solve of the steady problem on the whole
  // mesh (on the 2.15M mesh, on the 60-edge ball around the contact: the deformation
  // decays like exp(-r / (sqrt 2 L)), L = 3 edges, so beyond it lies below 1e-6 of the
  // contact's).
  const auto igea = options.data_dir / "igea-134k.ply";
  if (std::filesystem::exists(igea)) {
    const int haptic_steps = options.quick ? 1000 : 10000;
    auto haptic = [&](const Mesh& mesh, const std::string& tag) {
      const FemOperators ops = build_cotan_operators(mesh);
      const int v = mesh.num_vertices() / 3;
      Eigen::Vector3d n = Eigen::Vector3d::Zero();
      for (int w : mesh.neighbors(v)) n += (mesh.positions().row(w) - mesh.positions().row(v)).transpose();
      n.normalize();
      const double depth = 0.5 * mean_edge_length(mesh);
      // The factored session, the CG session and the fixed work (below).
      struct Run {
        std::string key;
        std::unique_ptr<HapticSession> session;  // null: the fixed work
        std::vector<double> us;
        int steps = 0, max_free = 0;
        Eigen::Vector3d force = Eigen::Vector3d::Zero();
      };
      std::vector<Run> runs(3);
      runs[0].key = "haptic_";
      runs[0].session = std::make_unique<HapticSession>(mesh, ops, HapticParams{.solver = HapticSolver::Factored});
      runs[1].key = "haptic_cg_";
      runs[1].session = std::make_unique<HapticSession>(mesh, ops, HapticParams{.solver = HapticSolver::Cg});
      runs[2].key = "haptic_fixed_work_";
      // The reference: Kt u = 0 with u held at the contact's final offset.
      progress("haptic reference solve on " + tag);
      const PdeCoefficients c = runs[0].session->pde().coefficients();
      std::vector<int> free;
      if (mesh.num_vertices() <= 500000) {
        for (int i = 0; i < mesh.num_vertices(); ++i)
          if (i != v && ops.mass[i] > 0) free.push_back(i);
      } else {
        for (int i : region_around(mesh, v, {.radius = 60 * mean_edge_length(mesh)}))
          if (i != v && ops.mass[i] > 0) free.push_back(i);
      }
      Field held = Field::Zero(mesh.num_vertices(), 3);
      held.row(v) = depth * n.transpose();
      const Field settled = SteadyDirectSolver(mesh, ops, c, free).solve(held);
      Eigen::Vector3d reference = Eigen::Vector3d::Zero();  // the reaction -row_v(Kt) u, as the probe feels it
      for (const auto& [i, coupling] : steady_coupling(mesh, ops, c, v))
        reference += coupling * settled.row(i).transpose();
      j["haptic_reference_vertices_" + tag] = static_cast<int>(free.size()) + 1;
      j["haptic_vertices_" + tag] = mesh.num_vertices();
      // Three workloads, each stepped at 1 kHz (a step, then a sleep to the next tick) in
      // blocks of 500 steps that take turns, so that the machine's quiet and busy spells
      // fall on all three alike: the factored session, the CG session, and a fixed amount
      // of arithmetic (the machine's own floor: every one of its steps does the same work,
      // so a step of it over 1 ms is the machine, preemption or the hypervisor, not a
      // solver). The fixed work is 400 us, more than either solver's median.
      progress(
          fmt::format("haptic poke on {}: factored, CG and fixed work, {} steps each at 1 kHz", tag, haptic_steps));
      for (int r = 0; r < 2; ++r) runs[static_cast<std::size_t>(r)].session->touch(v);
      std::vector<double> work(20000, 1.0);
      double sink = 0;
      auto fixed_work = [&](int passes) {
        for (int r = 0; r < passes; ++r)
          for (double& x : work) {
            x = x * 0.999999 + 1e-9;
            sink += x;
          }
      };
      int passes = 0;
      const int block = 500;
      for (int b = 0; b < haptic_steps / block; ++b)
        for (Run& run : runs) {
          if (!run.session && passes == 0) {  // calibrated to 400 us once
            const auto t = clock_type::now();
            fixed_work(4);
            passes = std::max(1, static_cast<int>(std::lround(400.0 / std::max(1e-3, seconds_since(t) * 1e6 / 4))));
          }
          auto tick = clock_type::now();
          for (int q = 0; q < block; ++q) {
            const int k = ++run.steps;
            if (run.session) run.session->move_probe(std::min(1.0, k / (0.5 * haptic_steps)) * depth * n);
            const auto t = clock_type::now();
            if (run.session)
              run.force = run.session->step(1e-3);
            else
              fixed_work(passes);
            run.us.push_back(seconds_since(t) * 1e6);
            if (run.session) run.max_free = std::max(run.max_free, run.session->pde().domain().num_free());
            tick += std::chrono::microseconds(1000);
            std::this_thread::sleep_until(tick);
          }
        }
      for (const Run& run : runs) {
        const Percentiles p = percentiles(run.us);
        j[run.key + "p50_us_" + tag] = p.p50;
        j[run.key + "p99_us_" + tag] = p.p99;
        j[run.key + "max_us_" + tag] = p.max;
        j[run.key + "over_1ms_" + tag] =
            static_cast<int>(std::count_if(run.us.begin(), run.us.end(), [](double x) { return x > 1000; }));
        j[run.key + "steps_" + tag] = run.steps;
        if (!run.session) continue;
        // The per-step trace: for each step over 1 ms, the part of the session's step
        // that took longest (install, solve, propose, publish), or "outside" when most
        // of the time was spent outside them (the thread preempted between them, or
        // waiting for the session's lock); the ten slowest steps in full.
        const std::vector<HapticSample> log = run.session->log();
        std::map<std::string, int> where;
        int with_new_factor = 0;
        std::vector<int> order;
        for (std::size_t k = 0; k < run.us.size() && k < log.size(); ++k) {
          if (run.us[k] <= 1000) continue;
          order.push_back(static_cast<int>(k));
          const HapticSample& s = log[k];
          const std::pair<const char*, double> parts[] = {
              {"install", s.install_us},
              {"solve", s.solve_us},
              {"propose", s.propose_us},
              {"publish", s.publish_us},
              {"outside", run.us[k] - s.install_us - s.solve_us - s.propose_us - s.publish_us}};
          ++where[std::max_element(std::begin(parts), std::end(parts), [](const auto& a, const auto& b) {
                    return a.second < b.second;
                  })->first];
          with_new_factor += s.new_factor;
        }
        for (const char* part : {"install", "solve", "propose", "publish", "outside"})
          j[run.key + "over_1ms_in_" + part + "_" + tag] = where[part];
        j[run.key + "over_1ms_new_factor_" + tag] = with_new_factor;
        std::sort(order.begin(), order.end(), [&](int a, int b) { return run.us[a] > run.us[b]; });
        nlohmann::json slow = nlohmann::json::array();
        for (std::size_t q = 0; q < order.size() && q < 10; ++q) {
          const int k = order[q];
          const HapticSample& s = log[static_cast<std::size_t>(k)];
          slow.push_back({{"step", k},
                          {"us", run.us[k]},
                          {"install_us", s.install_us},
                          {"solve_us", s.solve_us},
                          {"propose_us", s.propose_us},
                          {"publish_us", s.publish_us},
                          {"new_factor", s.new_factor},
                          {"factored", s.factored},
                          {"free_vertices", s.free_vertices},
                          {"cg_iterations", s.cg_iterations}});
        }
        j[run.key + "slow_steps_" + tag] = slow;
        j[run.key + "max_free_vertices_" + tag] = run.max_free;
        j[run.key + "settled_force_error_" + tag] = (run.force - reference).norm() / reference.norm();
      }
      int factored = 0;
      for (const HapticSample& sample : runs[0].session->log()) factored += sample.factored;
      j["haptic_factorizations_" + tag] = runs[0].session->factorizations();
      j["haptic_last_factor_ms_" + tag] = 1e3 * runs[0].session->last_factor_seconds();
      j["haptic_factored_steps_" + tag] = factored;
      j["haptic_fixed_work_checksum_" + tag] = sink;  // keeps the arithmetic from being optimized away
      const double p99 = percentiles(runs[0].us).p99;
      return p99;
    };
    MeshData d = read_mesh(igea);
    const Mesh scan(d.V, d.F);
    const double p_scan = haptic(scan, "igea134k");
    GeneratedMesh sub = subdivide_midpoint(d.V, d.F);
    sub = subdivide_midpoint(sub.V, sub.F);
    const double p_big = haptic(Mesh(sub.V, sub.F), "igea_subdivided_2m");
    j["haptic_p99_ratio_2m_over_134k"] = p_big / p_scan;

  } else {
    warn(igea.string() + " not found; haptic figures skipped");
  }
}

// The direct solve in the mesh's nested dissection order (solvers/ordering.h; what
// `interpolate --solver direct` and Auto's direct route run on K D K from
// kMeshOrderingFrom free vertices) against CHOLMOD's own ordering of the same matrix,
// timed just before in the same run: global_bilap_direct_s_<tag>, the speedup, the
// factors' nonzeros and their ratio, and the largest difference of the answers.
void mesh_ordering_figures(const BenchOptions& options, nlohmann::json& j, const std::string& tag, const Mesh& m,
                           const FemOperators& o, const std::vector<int>& free, const Field& u, double baseline_s,
                           double baseline_nonzeros, const Field& baseline) {
  if (!mesh_ordering_available()) {
    if (options.warning) options.warning("built without METIS: global_bilap_direct_s_" + tag + " skipped");
    return;
  }
  if (options.progress) options.progress("global bi-Laplacian on " + tag + " by the direct solve in the mesh's order");
  const auto t = clock_type::now();
  const SteadyDirectSolver direct(m, o, PdeCoefficients{.g0 = 0, .g1 = 0, .g2 = 1}, free, SparseCholesky::Backend::Auto,
                                  Eigen::VectorXd(), DirectOrdering::Auto);
  const Field x = direct.solve(u);
  const double seconds = seconds_since(t);
  j["global_bilap_direct_s_" + tag] = seconds;
  j["global_bilap_direct_speedup_" + tag] = baseline_s / seconds;
  j["global_bilap_direct_mesh_order_nonzeros_" + tag] = direct.factor().factor_nonzeros();
  j["global_bilap_direct_fill_ratio_" + tag] = direct.factor().factor_nonzeros() / baseline_nonzeros;
  j["global_bilap_direct_max_difference_" + tag] =
      (x - baseline).cwiseAbs().maxCoeff() / std::max(baseline.cwiseAbs().maxCoeff(), 1e-300);
}

// The global solvers on real meshes: the handle at the top moved by 0.01 mean edge
// x (1, 2, 10), the lowest 2 % (by height) of each part held (real_mesh_problem.h), as
// on the million-vertex row. Each problem: the default global solve (Auto, the
// operators the commands build), CHOLMOD's direct solve, what `--solver global` and
// `--solver auto` run, and the multigrid's try alone; on a mesh as it is also libigl's
// route (Eigen's simplicial Cholesky) and the multigrid alone on the cotangent and the
// intrinsic Delaunay operators. Always: armadillo-43k, igea-134k and aorta-103k, as
// they are and subdivided once. With `every` (`--only global_real`, or `--large`):
// also every other mesh of the data folder, every mesh subdivided twice (igea-134k
// x2: 2.1M vertices), and the 164k and 655k icospheres. Keys end in the mesh's tag
// (its file's stem; "_x1", "_x2" once or twice subdivided).
void global_real_figures(const BenchOptions& options, nlohmann::json& j, bool every) {
  const auto progress = [&](const std::string& what) {
    if (options.progress) options.progress(what);
  };
  const auto warn = [&](const std::string& what) {
    if (options.warning) options.warning(what);
  };
  using Preconditioner = GlobalBilaplacianParams::Preconditioner;
  struct RealMesh {
    const char* file;  // its stem names the figures (global_bilap_*_<stem>)
    bool first_rows;   // one of the three meshes of every run
  };
  const RealMesh meshes[] = {{"armadillo-43k.obj", true},
                             {"igea-134k.ply", true},
                             {"aorta-103k.vtp", true},
                             {"bunny-36k.obj", false},
                             {"camelhead-11k.off", false},
                             {"coronary-phantom-7k.stl", false},
                             {"aorta-closed-6k.vtp", false},
                             {"aorta-open-6k.stl", false},
                             {"fertility-4k.off", false},
                             {"carotid-ica-4k.vtp", false},
                             {"bunny-3k.off", false},
                             {"cow-3k.off", false},
                             {"vessel-boolean-nonmanifold.vtp", false},
                             {"decimated-knight.off", false},
                             {"nonmanifold-vierbein.obj", false},
                             {"nonmanifold-vertex-hourglass.obj", false}};
  // One problem: the default global solve, CHOLMOD's direct solve, what `--solver
  // global` and `--solver auto` run; on a mesh as it is (as_is) also libigl's route and
  // the multigrid alone on both operators.
  const auto measure = [&](const std::string& tag, const Mesh& input, bool as_is) {
    progress("global bi-Laplacian on " + tag);
    // The operators the commands build (--laplacian auto): intrinsic Delaunay on the
    // marching-cubes aorta, whose cotangent K D K CHOLMOD cannot factor once it is
    // subdivided ("not positive definite"; the conditioning, not the problem).
    const MeshOperators auto_ops = build_mesh_operators(input, LaplacianKind::Auto);
    const Mesh& m = auto_ops.mesh;
    const FemOperators& o = auto_ops.ops;
    const auto [handle, u, free] = top_drag(m, mean_edge_length(input));
    const TimedGlobalSolve a = timed_global_solve(m, o, free, u, Preconditioner::Auto);
    j["global_bilap_laplacian_" + tag] = to_string(auto_ops.kind);
    j["global_bilap_vertices_" + tag] = m.num_vertices();
    j["global_bilap_s_" + tag] = a.seconds;
    j["global_bilap_setup_s_" + tag] = a.r.setup_seconds;
    j["global_bilap_iters_" + tag] = a.r.iterations;
    j["global_bilap_preconditioner_" + tag] = preconditioner_name(a.r.used);
    j["global_bilap_multigrid_iters_" + tag] = a.r.multigrid_iterations;
    j["global_bilap_bytes_per_vertex_" + tag] = a.r.bytes_per_vertex;
    progress("global bi-Laplacian on " + tag + " by CHOLMOD's direct solve (baseline)");
    const auto t_direct = clock_type::now();
    const SteadyDirectSolver direct(m, o, PdeCoefficients{.g0 = 0, .g1 = 0, .g2 = 1}, free,
                                    SparseCholesky::Backend::Auto, Eigen::VectorXd(), DirectOrdering::Cholmod);
    const Field x = direct.solve(u);
    const double direct_s = seconds_since(t_direct);
    j["global_bilap_direct_baseline_s_" + tag] = direct_s;
    j["global_bilap_direct_factor_nonzeros_" + tag] = direct.factor().factor_nonzeros();
    mesh_ordering_figures(options, j, tag, m, o, free, u, direct_s, direct.factor().factor_nonzeros(), x);
    j["global_bilap_speedup_over_direct_" + tag] = direct_s / a.seconds;
    j["global_bilap_max_difference_" + tag] = (a.r.values - x).cwiseAbs().maxCoeff() / x.cwiseAbs().maxCoeff();
    // What `--solver global` runs (solve_steady: the same solver to a relative residual
    // of 1e-10), against the same direct solve: the figures behind SteadySolver::Auto's
    // size rule (pde/steady_direct.h).
    progress("global bi-Laplacian on " + tag + " as the commands' global solver (1e-10)");
    try {
      const auto t_steady = clock_type::now();
      const SteadySolveResult sg =
          solve_steady(m, o, PdeCoefficients{.g0 = 0, .g1 = 0, .g2 = 1}, free, u, SteadySolver::Global);
      const double steady_s = seconds_since(t_steady);
      j["steady_global_s_" + tag] = steady_s;
      j["steady_global_iters_" + tag] = sg.iterations;
      j["steady_global_speedup_over_direct_" + tag] = direct_s / steady_s;
    } catch (const SolverError& e) {
      j["steady_global_error_" + tag] = e.what();
      warn("global bi-Laplacian on " + tag + " at 1e-10: " + e.what());
    }
    // What `--solver auto` (the default) runs: from kAutoGlobalFromFreeVertices free
    // vertices on and on meshes without angles below kAutoMultigridMinAngleDeg, the
    // multigrid's try, kept where it converges, else the direct solve after it; on
    // everything else the direct solve (the baseline's figure). The try alone is timed
    // from 10,000 free vertices on, whatever the angles, so that both rules can be read
    // against it.
    j["global_bilap_smallest_angle_deg_" + tag] = smallest_angle_deg(input.positions(), input.triangles());
    const PdeCoefficients plate{.g0 = 0, .g1 = 0, .g2 = 1};
    if (free.size() >= 10000) {
      progress("global bi-Laplacian on " + tag + ": the multigrid's try (--solver auto)");
      const auto t_try = clock_type::now();
      int probe = 0;
      const std::optional<SteadySolveResult> tried = try_multigrid_solve(m, o, plate, free, u, &probe);
      j["steady_multigrid_try_s_" + tag] = seconds_since(t_try);
      j["steady_multigrid_try_kept_" + tag] = tried.has_value();
      j["steady_multigrid_try_iters_" + tag] = probe;
    }
    if (free.size() >= static_cast<std::size_t>(kAutoGlobalFromFreeVertices)) {
      progress("global bi-Laplacian on " + tag + " as the commands' default solver (auto)");
      const auto t_auto = clock_type::now();
      const SteadySolveResult sa = solve_steady(m, o, plate, free, u, SteadySolver::Auto);
      const double auto_s = seconds_since(t_auto);
      j["steady_auto_s_" + tag] = auto_s;
      j["steady_auto_solver_" + tag] = to_string(sa.solver);
      j["steady_auto_probe_iters_" + tag] = sa.multigrid_probe_iterations;  // 0: not tried (the shape rule)
      j["steady_auto_speedup_over_direct_" + tag] = direct_s / auto_s;
      j["steady_auto_max_difference_" + tag] = (sa.values - x).cwiseAbs().maxCoeff() / x.cwiseAbs().maxCoeff();
    }
    if (!as_is) return;
    progress("global bi-Laplacian on " + tag + " by Eigen's simplicial Cholesky (libigl's route)");
    const auto t_eigen = clock_type::now();
    const SteadyDirectSolver eigen_direct(m, o, PdeCoefficients{.g0 = 0, .g1 = 0, .g2 = 1}, free,
                                          SparseCholesky::Backend::Eigen);
    const Field xe = eigen_direct.solve(u);
    const double eigen_s = seconds_since(t_eigen);
    j["global_bilap_eigen_simplicial_baseline_s_" + tag] = eigen_s;
    j["global_bilap_speedup_over_eigen_simplicial_" + tag] = eigen_s / a.seconds;
    // The multigrid alone, on the cotangent and on the intrinsic Delaunay operators
    // (iterations to 1e-8, at most 300; a count of 300 means it did not get there).
    for (const LaplacianKind kind : {LaplacianKind::Cotan, LaplacianKind::IntrinsicDelaunay}) {
      const std::string which = kind == LaplacianKind::Cotan ? "cotan" : "intrinsic";
      progress("global bi-Laplacian on " + tag + ": the multigrid alone on the " + which + " operators");
      const MeshOperators mo = build_mesh_operators(input, kind);
      GlobalBilaplacianParams p;
      p.preconditioner = Preconditioner::Multigrid;
      p.max_iterations = 300;
      try {
        const GlobalBilaplacianResult r = solve_global_bilaplacian(mo.mesh, mo.ops, free, u, p);
        j["global_bilap_mg_iters_" + which + "_" + tag] = r.iterations;
        j["global_bilap_mg_converged_" + which + "_" + tag] = r.converged;
      } catch (const SolverError& e) {
        // The cotangent K D K of a mesh with slivers can be indefinite in rounding
        // (carotid-ica-4k's coarsest level); the row says so and the run goes on.
        j["global_bilap_mg_error_" + which + "_" + tag] = e.what();
        warn("global bi-Laplacian on " + tag + ", multigrid on the " + which + " operators: " + e.what());
      }
    }
  };
  for (const auto& [file, first_rows] : meshes) {
    if (!every && !first_rows) continue;
    const auto path = options.data_dir / file;
    const std::string name = path.stem().string();
    if (!std::filesystem::exists(path)) {
      warn(path.string() + " not found; its global_bilap_*_" + name + " figures skipped");
      continue;
    }
#ifdef MESHPDE_HAVE_MEDICAL
    const MeshData d = read_mesh(path);
#else
    if (path.extension() == ".vtp") {
      warn(path.string() + ": this build reads no .vtp (meshpde::medical); its figures skipped");
      continue;
    }
    const MeshData d = read_mesh(path);
#endif
    GeneratedMesh g{d.V, d.F, {}};
    const int levels = every ? 3 : 2;
    for (int level = 0; level < levels; ++level) {
      if (level) g = subdivide_midpoint(g.V, g.F);
      const std::string tag = level ? std::string(name) + "_x" + std::to_string(level) : std::string(name);
      measure(tag, Mesh(g.V, g.F), level == 0);
    }
  }
  // Well-shaped meshes of the same sizes (the bench's icospheres, unit edge length):
  // the other side of SteadySolver::Auto's rule, where the multigrid converges.
  if (every)
    for (const int level : {7, 8})
      measure(level == 7 ? "icosphere-164k" : "icosphere-655k", unit_edge_icosphere(level), false);
}

// Resident memory of this process now and at its peak since the last reset (bytes,
// from /proc/self/status: VmRSS, VmHWM); the peak is reset by writing 5 to
// /proc/self/clear_refs (Linux 4.0 on). Negative where unavailable.
double proc_status_bytes(const char* field) {
  std::ifstream in("/proc/self/status");
  std::string line;
  const std::string key = std::string(field) + ":";
  while (std::getline(in, line))
    if (line.rfind(key, 0) == 0) return 1024.0 * std::strtod(line.c_str() + key.size(), nullptr);  // kB
  return -1;
}
bool reset_peak_memory() {
  std::ofstream out("/proc/self/clear_refs");
  out << "5";
  out.flush();
  return static_cast<bool>(out);
}

// The direct solve of the million-vertex row, by CHOLMOD with its default ordering
// (global_bilap_direct_baseline_s_1m) and in the mesh's order (global_bilap_direct_s_1m,
// what `interpolate --solver direct` and Auto's direct route run), one after the other,
// with their memory: direct_bytes_per_vertex_1m (the mesh order's) and
// direct_bytes_per_vertex_baseline_1m, the rise of the process's peak resident memory
// during the solve (factor, assembly and workspace) over the mesh's vertices, and the
// factors' nonzeros. Returns the baseline's answer.
Field direct_million_figures(const BenchOptions& options, nlohmann::json& j, const Mesh& m, const FemOperators& o,
                             const std::vector<int>& free, const Field& u) {
  struct Run {
    double seconds = 0, nonzeros = 0, bytes = -1;
    int refinements = 0;
    Field x;
  };
  const auto run = [&](DirectOrdering ordering) {
    Run r;
    const double before = proc_status_bytes("VmRSS");
    const bool peak = before > 0 && reset_peak_memory();
    const auto t = clock_type::now();
    {
      const SteadyDirectSolver direct(m, o, PdeCoefficients{.g0 = 0, .g1 = 0, .g2 = 1}, free,
                                      SparseCholesky::Backend::Auto, Eigen::VectorXd(), ordering);
      r.x = direct.solve(u);
      r.nonzeros = direct.factor().factor_nonzeros();
      r.refinements = direct.last_refinements();
    }
    r.seconds = seconds_since(t);
    if (peak) r.bytes = (proc_status_bytes("VmHWM") - before) / m.num_vertices();
    return r;
  };
  // A virtual machine may back its memory only when a page is first touched (on the
  // development machine 1.8 GB of fresh pages took 5.7 s to touch, 0.3 s the second
  // time): whichever solve ran first would pay that for both. Touching a block of the
  // baseline's peak once beforehand (3 kB a vertex) puts both on the same footing.
  {
    const auto bytes = static_cast<std::size_t>(3000.0 * m.num_vertices());
    const std::unique_ptr<char[]> warm(new char[bytes]);
    volatile char* page = warm.get();  // volatile: the writes stay
    for (std::size_t k = 0; k < bytes; k += 4096) page[k] = 1;
  }
  if (options.progress)
    options.progress("global bi-Laplacian on fertility-4k subdivided 4 times by CHOLMOD's direct solve (baseline)");
  const Run baseline = run(DirectOrdering::Cholmod);
  j["global_bilap_direct_baseline_s_1m"] = baseline.seconds;
  j["direct_factor_nonzeros_baseline_1m"] = baseline.nonzeros;
  j["global_bilap_direct_baseline_refinements_1m"] = baseline.refinements;
  if (baseline.bytes >= 0) j["direct_bytes_per_vertex_baseline_1m"] = baseline.bytes;
  if (mesh_ordering_available()) {
    if (options.progress)
      options.progress(
          "global bi-Laplacian on fertility-4k subdivided 4 times by the direct solve in the mesh's order");
    const Run ours = run(DirectOrdering::Auto);
    j["global_bilap_direct_s_1m"] = ours.seconds;
    j["global_bilap_direct_speedup_1m"] = baseline.seconds / ours.seconds;
    j["direct_factor_nonzeros_1m"] = ours.nonzeros;
    j["global_bilap_direct_refinements_1m"] = ours.refinements;
    j["global_bilap_direct_fill_ratio_1m"] = ours.nonzeros / baseline.nonzeros;
    j["global_bilap_direct_max_difference_1m"] =
        (ours.x - baseline.x).cwiseAbs().maxCoeff() / baseline.x.cwiseAbs().maxCoeff();
    if (ours.bytes >= 0) j["direct_bytes_per_vertex_1m"] = ours.bytes;
    // Where the mesh order's first solve goes, step by step on the same problem: the
    // assembly of K D K on the free vertices, the ordering, the factorization (both
    // parts' analyses and numeric factors and the separator's), and the ordering's
    // share of the factorization.
    if (SplitCholesky::available()) {
      if (options.progress) options.progress("the mesh order's first solve step by step (assembly, ordering, factor)");
      auto t = clock_type::now();
      const Eigen::SparseMatrix<double> A =
          assemble_steady_matrix(m, o, PdeCoefficients{.g0 = 0, .g1 = 0, .g2 = 1}, free);
      j["direct_assembly_s_1m"] = seconds_since(t);
      t = clock_type::now();
      NestedDissection nd = mesh_nested_dissection(m, free, MeshOrderingParams{.separator_hops = 2});
      const double ordering_s = seconds_since(t);
      std::vector<int> row(static_cast<std::size_t>(m.num_vertices()), -1);
      for (std::size_t k = 0; k < free.size(); ++k) row[static_cast<std::size_t>(free[k])] = static_cast<int>(k);
      for (int& v : nd.order) v = row[static_cast<std::size_t>(v)];
      t = clock_type::now();
      SplitCholesky split;
      split.factorize(A, nd.order, static_cast<Eigen::Index>(nd.parts[0]), static_cast<Eigen::Index>(nd.parts[1]));
      const double factor_s = seconds_since(t);
      j["direct_ordering_s_1m"] = ordering_s;
      j["direct_factor_s_1m"] = factor_s;
      j["direct_ordering_fraction_1m"] = ordering_s / factor_s;
      j["direct_separator_rows_1m"] = nd.order.size() - nd.parts[0] - nd.parts[1];
    }
  } else if (options.warning) {
    options.warning("built without METIS: global_bilap_direct_s_1m skipped");
  }
  if (baseline.bytes < 0 && options.warning)
    options.warning("no peak memory reset here (/proc/self/clear_refs): direct_bytes_per_vertex_1m skipped");
  return baseline.x;
}

// fertility-4k (genus 4) midpoint-subdivided four times (1.15M vertices), the handle
// at its top, the lowest 2 % (by height) held; null where the file is missing.
struct MillionProblem {
  Mesh mesh;
  FemOperators ops;
  TopDrag drag;
};
std::optional<MillionProblem> million_problem(const BenchOptions& options) {
  const auto fertility = options.data_dir / "fertility-4k.off";
  if (!std::filesystem::exists(fertility)) {
    if (options.warning) options.warning(fertility.string() + " not found; the _1m global and direct figures skipped");
    return std::nullopt;
  }
  if (options.progress) options.progress("fertility-4k subdivided 4 times (1.15M vertices)");
  MeshData d = read_mesh(fertility);
  GeneratedMesh g{d.V, d.F, {}};
  for (int k = 0; k < 4; ++k) g = subdivide_midpoint(g.V, g.F);
  MillionProblem p{Mesh(g.V, g.F), {}, {}};
  p.ops = build_cotan_operators(p.mesh);
  p.drag = top_drag(p.mesh, mean_edge_length(p.mesh));
  return p;
}

}  // namespace

// A correction the self-intersection guard has to limit, against the same correction
// applied as solved (--allow-intersections), interleaved, best of a few: the far
// sideways carina drag of the registered aorta (10 mm, R = 12 mm) when
// ../shared/data has it, and the generated bifurcation's (8 mm, R = 10 mm).
void correct_guard_figures(const BenchOptions& options, nlohmann::json& j) {
  auto run = [&](const Mesh& mesh, int handle, const Eigen::Vector3d& move, double radius, const std::string& suffix) {
    CorrectionParams p;
    p.handles = {{handle, move}};
    p.radius = radius;
    double guarded = 1e30, unguarded = 1e30;
    CorrectionResult g, u;
    for (int rep = 0; rep < (options.quick ? 3 : 7); ++rep) {
      p.prevent_intersections = true;
      g = correct_vessel(mesh, p);
      guarded = std::min(guarded, g.time_ms);
      p.prevent_intersections = false;
      u = correct_vessel(mesh, p);
      unguarded = std::min(unguarded, u.time_ms);
    }
    j["correct_guarded_ms" + suffix] = guarded;
    j["correct_unguarded_ms" + suffix] = unguarded;
    j["correct_guarded_ratio" + suffix] = guarded / unguarded;
    j["correct_guarded_applied" + suffix] = g.applied_fraction;
    j["correct_guarded_action" + suffix] = g.intersection_action;
    j["correct_unguarded_new_intersections" + suffix] = u.new_self_intersections;
  };
  if (options.progress) options.progress("correction guard: a limited carina drag");
  const auto aorta = options.data_dir / "aorta-closed-6k.vtp";
#ifdef MESHPDE_HAVE_MEDICAL
  if (std::filesystem::exists(aorta)) {
    const MeshData d = read_mesh(aorta);
    run(Mesh(d.V, d.F), 3178, Eigen::Vector3d(10, 0, 0), 12.0, "");  // the carina vertex
  } else if (options.warning) {
    options.warning(aorta.string() + " not found; correct_guarded_ms and correct_unguarded_ms skipped");
  }
#else
  if (options.warning) options.warning("this build reads no .vtp (meshpde::medical): correct_guarded_ms skipped");
#endif
  const GeneratedMesh b = y_bifurcation(BifurcationParams{});
  const Mesh bif(b.V, b.F);
  int carina = -1;  // the lowest vertex near the axis above the branch point
  for (int i = 0; i < bif.num_vertices(); ++i) {
    const auto q = bif.positions().row(i);
    if (std::abs(q.x()) < 0.6 && std::abs(q.y()) < 0.6 && q.z() > 0 &&
        (carina < 0 || q.z() < bif.positions()(carina, 2)))
      carina = i;
  }
  run(bif, carina, Eigen::Vector3d(8, 0, 0), 10.0, "_bifurcation");
}

// Interactive drags on a region of about 10k free vertices of the 655k mesh
// (DragSession: the region's factor and basis are built once; an update is a
// product with the basis). Baselines from the same run: the update as a full solve
// with the cached factor (the drag path before DragSession), warm-started Jacobi-CG
// on the same region, Eigen's simplicial factorization for the set-up, and a fresh
// factorization for adding a handle and for growing the region.
void drag_figures(const BenchOptions& options, nlohmann::json& j, const Mesh& big, const FemOperators& big_ops) {
  const auto progress = [&](const std::string& what) {
    if (options.progress) options.progress(what);
  };
  const bool quick = options.quick;
  const int nv = big.num_vertices();
  progress("drag session: 10k-vertex region on 655k");
  int handle = 0;
  big.positions().col(2).maxCoeff(&handle);
  // About 10k vertices at unit edge length (surface distance); the default handle (a
  // quarter of the radius: a load, the handle's vertex a free row).
  const DragSessionParams region_params{.radius = 53.0};
  auto best_of = [&](int n, auto&& f) {
    double best = 1e30;
    for (int r = 0; r < n; ++r) {
      const auto t = clock_type::now();
      f();
      best = std::min(best, seconds_since(t));
    }
    return best;
  };
  std::unique_ptr<DragSession> session;
  const double setup_s = best_of(quick ? 2 : 4, [&] {
    session = std::make_unique<DragSession>(big, big_ops, std::vector<int>{handle}, region_params);
  });
  j["drag_setup_ms_10k_region"] = setup_s * 1e3;
  // The same region ended by the clamp (no foundation: the rule before the smooth
  // boundary became the default; the same matrix pattern).
  j["drag_setup_ms_10k_region_clamp"] =
      best_of(quick ? 2 : 4,
              [&] {
                DragSession s(big, big_ops, {handle},
                              DragSessionParams{.radius = 53.0, .boundary = RegionBoundary::Clamp});
              }) *
      1e3;
  // The same with the handle a held vertex (size 0: the rule before handles had a size
  // in sessions; the handle's row out of the factor, no load to integrate).
  j["drag_setup_ms_10k_region_held_handle"] =
      best_of(quick ? 2 : 4,
              [&] { DragSession s(big, big_ops, {handle}, DragSessionParams{.radius = 53.0, .handle_radius = 0}); }) *
      1e3;
  {
    const int limit = max_threads();
    set_max_threads(1);
    j["drag_setup_ms_10k_region_1thread"] =
        best_of(quick ? 2 : 4, [&] { DragSession s(big, big_ops, {handle}, region_params); }) * 1e3;
    set_max_threads(limit);
  }
  j["drag_region_vertices"] = session->region().size();
  const std::vector<int> free = session->region();
  const double eigen_setup_s = best_of(quick ? 1 : 2, [&] {
    const SteadyDirectSolver s(big, big_ops, PdeCoefficients{.g0 = 0, .g1 = 0, .g2 = 1}, free,
                               SparseCholesky::Backend::Eigen);
  });
  j["drag_setup_baseline_ms_eigen_simplicial"] = eigen_setup_s * 1e3;
  j["drag_split_factor"] = session->split_factor();
  {
    // The set-up's steps one by one (best of each, interleaved): the region (surface
    // distance within the radius) beside the edge-path ball of about as many vertices
    // (radius 59), the order, the assembly, the factorization and the basis (one solve).
    // The factorization two ways on the same matrix: the two halves at once
    // (SplitCholesky, what the session uses) and one CHOLMOD factor of the whole region
    // (LeadingBlockCholesky).
    double region_best = 1e30, edge_best = 1e30, order_best = 1e30, assembly_best = 1e30, basis_best = 1e30;
    double split_best = 1e30, whole_best = 1e30;
    std::size_t edge_vertices = 0;
    const std::vector<int> sources{handle};
    for (int r = 0; r < (quick ? 3 : 8); ++r) {
      auto t = clock_type::now();
      const std::vector<int> region = region_around(big, handle, RegionSpec{.radius = region_params.radius});
      region_best = std::min(region_best, seconds_since(t));
      t = clock_type::now();
      edge_vertices = geodesic_distances(big, sources, 59.0).size();
      edge_best = std::min(edge_best, seconds_since(t));
      t = clock_type::now();
      const NestedDissection nd = nested_dissection(big, free);
      order_best = std::min(order_best, seconds_since(t));
      t = clock_type::now();
      Eigen::SparseMatrix<double> A =
          assemble_steady_matrix(big, big_ops, PdeCoefficients{.g0 = 0, .g1 = 0, .g2 = 1}, nd.order);
      A.makeCompressed();
      assembly_best = std::min(assembly_best, seconds_since(t));
      if (SplitCholesky::available() && nd.parts[1] > 0) {
        t = clock_type::now();
        SplitCholesky f;
        f.factorize(A, static_cast<Eigen::Index>(nd.parts[0]), static_cast<Eigen::Index>(nd.parts[1]));
        split_best = std::min(split_best, seconds_since(t));
        const Eigen::MatrixXd b = Eigen::MatrixXd::Ones(A.rows(), 1);
        t = clock_type::now();
        const Eigen::MatrixXd x = f.solve(b);
        basis_best = std::min(basis_best, seconds_since(t));
      }
      t = clock_type::now();
      LeadingBlockCholesky f;
      f.factorize(A);
      whole_best = std::min(whole_best, seconds_since(t));
    }
    j["drag_setup_region_ms_10k_region"] = region_best * 1e3;
    j["drag_setup_region_baseline_ms_edge_paths"] = edge_best * 1e3;
    j["drag_setup_region_vertices_edge_paths"] = edge_vertices;
    j["drag_setup_order_ms_10k_region"] = order_best * 1e3;
    j["drag_setup_assembly_ms_10k_region"] = assembly_best * 1e3;
    if (split_best < 1e30) j["drag_factor_ms_10k_region_split"] = split_best * 1e3;
    j["drag_factor_ms_10k_region_one_factor"] = whole_best * 1e3;
    if (basis_best < 1e30) j["drag_setup_basis_ms_10k_region"] = basis_best * 1e3;
  }
  std::unique_ptr<DragSession> with_margin;
  j["drag_setup_ms_10k_region_with_margin"] =
      best_of(quick ? 2 : 4,
              [&] {
                with_margin = std::make_unique<DragSession>(
                    big, big_ops, std::vector<int>{handle},
                    DragSessionParams{.radius = 53.0, .boundary = RegionBoundary::Clamp, .margin = true});
              }) *
      1e3;
  {
    // The same region on a mesh of a quarter the size (164k, same edge length): the
    // set-up follows the region, not the mesh.
    const Mesh mid = unit_edge_icosphere(7);
    const FemOperators mid_ops = build_cotan_operators(mid);
    int h = 0;
    mid.positions().col(2).maxCoeff(&h);
    std::size_t mid_region = 0;
    const double mid_s = best_of(quick ? 2 : 4, [&] {
      DragSession s(mid, mid_ops, {h}, region_params);
      mid_region = s.region().size();
    });
    j["drag_setup_ms_10k_region_on_164k"] = mid_s * 1e3;
    j["drag_region_vertices_on_164k"] = mid_region;
  }
  const Eigen::Vector3d nrm = big.positions().row(handle).normalized();
  std::vector<double> us, solve_us;
  Positions V = big.positions();
  for (int k = 1; k <= (quick ? 200 : 1000); ++k) {
    const Eigen::MatrixXd d = (0.01 * k) * nrm.transpose();
    const auto t = clock_type::now();
    // What an editor does per mouse move: the region's new positions.
    const Eigen::MatrixXd x = session->displacements(d);
    for (std::size_t i = 0; i < free.size(); ++i)
      V.row(free[i]) = big.positions().row(free[i]) + x.row(static_cast<Eigen::Index>(i));
    us.push_back(seconds_since(t) * 1e6);
    if (!x.allFinite()) throw SolverError("drag benchmark produced non-finite values");
  }
  Field u = Field::Zero(nv, 3);
  const SteadyDirectSolver solver(big, big_ops, PdeCoefficients{.g0 = 0, .g1 = 0, .g2 = 1}, free);
  for (int k = 1; k <= (quick ? 20 : 50); ++k) {
    u.row(handle) = (0.01 * k) * nrm.transpose();
    const auto t = clock_type::now();
    const Eigen::MatrixXd x = solver.solve_free(u);
    solve_us.push_back(seconds_since(t) * 1e6);
  }
  const Percentiles dp = percentiles(us), sp = percentiles(solve_us);
  j["drag_p50_us_10k_region"] = dp.p50;
  j["drag_p99_us_10k_region"] = dp.p99;
  j["drag_solve_with_factor_p99_us_10k_region"] = sp.p99;
  PdeSession cg(big, big_ops, 3, PdeCoefficients{.alpha = 0, .b1 = 0, .b2 = 0, .g0 = 0, .g1 = 0, .g2 = 1},
                DomainOptions{.seed_rings = 0});
  cg.cg_options.tolerance = 1e-8;
  std::vector<int> cg_region = free;
  cg_region.push_back(handle);
  cg.activate(cg_region);
  std::vector<double> cg_us;
  int iterations = 0;
  for (int k = 1; k <= 3; ++k) {
    const Eigen::Vector3d target = (0.01 * k) * nrm;
    cg.constrain(handle, std::span<const double>(target.data(), 3));
    const auto t = clock_type::now();
    iterations += cg.solve_steady().cg.iterations;
    cg_us.push_back(seconds_since(t) * 1e6);
  }
  j["drag_cg_baseline_us_per_update"] = percentiles(cg_us).p50;
  j["drag_cg_baseline_iterations_per_update"] = iterations / 3.0;
  j["drag_speedup_over_cg"] = percentiles(cg_us).p50 / dp.p50;
  j["drag_speedup_over_solve_with_factor"] = sp.p99 / dp.p99;
  // A second handle 20 edges from the first: one solve with the same factor.
  int second = free[0];
  for (int v : free)
    if (std::abs((big.positions().row(v) - big.positions().row(handle)).norm() - 20.0) <
        std::abs((big.positions().row(second) - big.positions().row(handle)).norm() - 20.0))
      second = v;
  auto t_add = clock_type::now();
  session->add_handle(second);
  j["drag_add_handle_ms"] = seconds_since(t_add) * 1e3;
  // The baseline: a new factor of the same region with both handles (the region given
  // as a list, so that it is the session's and not the two handles' surface ball).
  std::vector<int> with_first = free;
  with_first.push_back(handle);
  j["drag_add_handle_baseline_ms_refactor"] =
      best_of(1,
              [&] {
                DragSession fresh(big, big_ops, {handle, second}, with_first, region_params);
              }) *
      1e3;
  // Growth by one ring: with the margin factored at set-up (one multi-column solve
  // for all handles) against growing the session without a margin (a new factor),
  // same run. A growth uses the margin up, so each sample is a new margin session
  // (set-up not timed); the median of the samples is reported.
  std::vector<double> grow_ms;
  for (int k = 0; k < (quick ? 3 : 5); ++k) {
    if (k > 0)
      with_margin = std::make_unique<DragSession>(
          big, big_ops, std::vector<int>{handle},
          DragSessionParams{.radius = 53.0, .boundary = RegionBoundary::Clamp, .margin = true});
    with_margin->add_handle(second);
    const auto t_grow = clock_type::now();
    with_margin->grow(1);
    grow_ms.push_back(seconds_since(t_grow) * 1e3);
  }
  j["drag_grow_ring_ms"] = percentiles(grow_ms).p50;
  j["drag_grow_ring_max_ms"] = percentiles(grow_ms).max;
  j["drag_grow_ring_factorizations"] = with_margin->factorizations();
  j["drag_grown_region_vertices"] = with_margin->region().size();
  // The baselines grow and shrink a session without margins: the clamp's, since the
  // smooth boundary's region is fixed by its radius.
  DragSession plain(big, big_ops, {handle}, DragSessionParams{.radius = 53.0, .boundary = RegionBoundary::Clamp});
  plain.add_handle(second);
  const auto t_refactor = clock_type::now();
  plain.grow(1);
  j["drag_grow_ring_baseline_ms_refactor"] = seconds_since(t_refactor) * 1e3;
  // Shrink by one ring: with the region's outer ring ordered last at set-up
  // (inner_margin) against a session without it (a new factor), same run.
  std::vector<double> shrink_ms, inner_setup_ms;
  for (int k = 0; k < (quick ? 3 : 5); ++k) {
    const auto t_setup = clock_type::now();
    DragSession inner(big, big_ops, {handle},
                      DragSessionParams{.radius = 53.0, .boundary = RegionBoundary::Clamp, .inner_margin = true});
    inner_setup_ms.push_back(seconds_since(t_setup) * 1e3);
    inner.add_handle(second);
    const auto t_shrink = clock_type::now();
    inner.shrink(1);
    shrink_ms.push_back(seconds_since(t_shrink) * 1e3);
    if (k == 0) j["drag_shrunk_region_vertices"] = inner.region().size();
  }
  j["drag_shrink_ring_ms"] = percentiles(shrink_ms).p50;
  j["drag_setup_ms_10k_region_with_inner_margin"] = percentiles(inner_setup_ms).p50;
  const auto t_shrink_refactor = clock_type::now();
  plain.shrink(1);
  j["drag_shrink_ring_baseline_ms_refactor"] = seconds_since(t_shrink_refactor) * 1e3;
  j["drag_setup_ms_10k_region_with_both_margins"] =
      best_of(quick ? 1 : 2,
              [&] {
                DragSession both(
                    big, big_ops, {handle},
                    DragSessionParams{
                        .radius = 53.0, .boundary = RegionBoundary::Clamp, .margin = true, .inner_margin = true});
              }) *
      1e3;
  j["drag_setup_ms_2k_region"] =
      best_of(quick ? 2 : 4, [&] { DragSession s(big, big_ops, {handle}, DragSessionParams{.radius = 26.0}); }) * 1e3;
}

nlohmann::json run_standard_benchmarks(const BenchOptions& options) {
  const auto progress = [&](const std::string& what) {
    if (options.progress) options.progress(what);
  };
  const auto warn = [&](const std::string& what) {
    if (options.warning) options.warning(what);
  };
  const bool quick = options.quick, large = options.large;
  nlohmann::json j;
  if (!options.only.empty() && options.only != "haptic" && options.only != "global_real" && options.only != "paint" &&
      options.only != "correct_guard" && options.only != "drag" && options.only != "direct")
    throw InputError(
        fmt::format("bench: no section '{}' (--only takes: haptic, global_real, paint, correct_guard, drag, direct)",
                    options.only));
  const int reps = quick ? 3 : 10;
  const int steps = quick ? 300 : 1000;
  j["quick"] = quick;
  if (options.threads > 0) set_max_threads(options.threads);
  j["threads"] = max_threads();
  j["openmp"] = openmp_available();
  if (options.only == "haptic") {
    haptic_figures(options, j);
    return j;
  }
  if (options.only == "global_real") {
    global_real_figures(options, j, /*every=*/true);
    return j;
  }
  if (options.only == "paint") {
    paint_figures(options, j, large);
    return j;
  }
  if (options.only == "correct_guard") {
    correct_guard_figures(options, j);
    return j;
  }
  if (options.only == "direct") {
    if (const std::optional<MillionProblem> million = million_problem(options)) {
      j["global_bilap_vertices_1m"] = million->mesh.num_vertices();
      direct_million_figures(options, j, million->mesh, million->ops, million->drag.free, million->drag.u);
    }
    return j;
  }

  progress("icosphere level 8 (655k vertices): build");
  auto t0 = clock_type::now();
  const Mesh big = unit_edge_icosphere(8);
  const FemOperators big_ops = build_cotan_operators(big);
  j["build_655k_s"] = seconds_since(t0);
  if (options.only == "drag") {
    drag_figures(options, j, big, big_ops);
    return j;
  }
  const int nv = big.num_vertices();
  const auto S = static_cast<double>(big.neighbors().size());
  {
    // Triad and K D K repetitions alternate, so both see the same machine state;
    // the best of each is kept.
    progress("K D K apply on 655k against a STREAM-like triad, interleaved");
    Triad triad(std::size_t{1} << 24);
    std::vector<double> u(nv), t(nv), y(nv);
    for (int i = 0; i < nv; ++i) u[i] = std::sin(0.001 * i);
    double best = 1e30, best_triad = 1e30;
    for (int r = 0; r < 2 * reps; ++r) {
      best_triad = std::min(best_triad, triad.run(0.5 + r));
      const auto tt = clock_type::now();
      apply_bilaplacian_scalar(big, big_ops, u.data(), t.data(), y.data());
      best = std::min(best, seconds_since(tt));
    }
    // The same apply on one and on two threads (OpenMP), interleaved.
    double best1 = 1e30, best2 = 1e30;
    const int limit = max_threads();
    for (int r = 0; r < 2 * reps; ++r) {
      for (const int count : {1, 2}) {
        set_max_threads(count);
        const auto tt = clock_type::now();
        apply_bilaplacian_scalar(big, big_ops, u.data(), t.data(), y.data());
        (count == 1 ? best1 : best2) = std::min(count == 1 ? best1 : best2, seconds_since(tt));
      }
    }
    set_max_threads(limit);
    j["kdk_apply_ms_655k_1thread"] = best1 * 1e3;
    j["kdk_apply_ms_655k_2threads"] = best2 * 1e3;
    j["kdk_apply_speedup_2threads"] = best1 / best2;
    // Bytes an ideal K D K apply must move: the operator twice (offsets, neighbours,
    // K_ij, K_ii), u read, t written and read back, the mass read, y written.
    const double op_bytes = 4.0 * (nv + 1) + 4.0 * S + 8.0 * S + 8.0 * nv;
    const double bytes = 2 * op_bytes + 8.0 * nv * 5;
    // Against the single-threaded triad: the one-thread apply (the two-thread figures
    // are kdk_apply_ms_655k_2threads and the speedup).
    const double gbps = bytes / best1 / 1e9;
    const double triad_gbps = triad.bytes() / best_triad / 1e9;
    j["triad_GBps"] = triad_gbps;
    j["kdk_apply_ms_655k"] = best * 1e3;
    j["kdk_apply_GBps_655k"] = gbps;
    j["kdk_apply_bandwidth_fraction_655k"] = gbps / triad_gbps;
    j["kdk_apply_bytes_counted"] = bytes;
  }
  {
    const double bytes = 24.0 * nv + static_cast<double>(big_ops.bytes()) + 4.0 * (nv + 1) + 4.0 * S;
    j["operator_bytes_per_vertex"] = bytes / nv;
    j["operator_bytes_breakdown"] =
        "positions 24 + K_ii 8 + M 8 per vertex; CSR offsets 4 per vertex; "
        "neighbour index 4 + K_ij 8 per adjacency slot";
    j["mesh_topology_bytes_per_vertex"] = static_cast<double>(big.connectivity_bytes()) / nv;
  }

  drag_figures(options, j, big, big_ops);

  // Global steady bi-Laplacian (three right-hand sides; the handle moved, a far cap of
  // about 1 % of the vertices held): the default (Auto) preconditioned CG, then each
  // preconditioner forced, against the direct CHOLMOD factorization of K D K, same
  // problem, same run.
  std::vector<int> global_levels{5, 6, 7};
  if (large) global_levels.insert(global_levels.end(), {8, 9});
  for (const int level : global_levels) {
    const int vertices = 10 * (1 << (2 * level)) + 2;
    const std::string tag = level == 5   ? "10k"
                            : level == 6 ? "41k"
                            : level == 7 ? "164k"
                            : level == 8 ? "655k"
                                         : "2600k";
    progress("global bi-Laplacian on " + tag);
    const GeneratedMesh g = icosphere(level);
    const Mesh m(g.V, g.F);
    const FemOperators o = build_cotan_operators(m);
    int handle = 0;
    m.positions().col(2).maxCoeff(&handle);
    Field u = Field::Zero(vertices, 3);
    u.row(handle) << 0.01, 0.02, 0.1;
    std::vector<int> free;
    for (int v = 0; v < vertices; ++v)
      if (v != handle && m.positions()(v, 2) > -0.98) free.push_back(v);
    using Preconditioner = GlobalBilaplacianParams::Preconditioner;
    const TimedGlobalResolve resolve = timed_global_resolve(m, o, free, u, handle);
    const GlobalBilaplacianResult& ra = resolve.first;
    const double auto_s = resolve.first_seconds;
    j["global_bilap_resolve_s_" + tag] = resolve.second_seconds;
    j["global_bilap_resolve_iters_" + tag] = resolve.second.iterations;
    j["global_bilap_resolve_speedup_over_first_" + tag] = auto_s / resolve.second_seconds;
    j["global_bilap_iters_" + tag] = ra.iterations;
    j["global_bilap_s_" + tag] = auto_s;
    j["global_bilap_bytes_per_vertex_" + tag] = ra.bytes_per_vertex;
    j["global_bilap_preconditioner_" + tag] = preconditioner_name(ra.used);
    j["global_bilap_multigrid_iters_" + tag] = ra.multigrid_iterations;
    j["global_bilap_residual_" + tag] = ra.relative_residual;
    progress("global bi-Laplacian on " + tag + " with the Laplacian-factor preconditioner");
    const auto [r, pcg_s] = timed_global_solve(m, o, free, u, Preconditioner::LaplacianFactor);
    j["global_bilap_factor_iters_" + tag] = r.iterations;
    j["global_bilap_factor_s_" + tag] = pcg_s;
    j["global_bilap_factor_bytes_per_vertex_" + tag] = r.bytes_per_vertex;
    j["global_bilap_speedup_over_factor_" + tag] = pcg_s / auto_s;
    // The same problem with the surface multigrid preconditioner, against the
    // Laplacian-factor solve just measured.
    progress("global bi-Laplacian on " + tag + " with the multigrid preconditioner");
    const auto [rmg, mg_s] = timed_global_solve(m, o, free, u, Preconditioner::Multigrid);
    j["global_bilap_mg_s_" + tag] = mg_s;
    j["global_bilap_mg_iters_" + tag] = rmg.iterations;
    j["global_bilap_mg_setup_s_" + tag] = rmg.setup_seconds;
    j["global_bilap_mg_levels_" + tag] = rmg.level_unknowns.size();
    j["global_bilap_mg_bytes_per_vertex_" + tag] = rmg.bytes_per_vertex;
    j["global_bilap_mg_speedup_over_factor_" + tag] = pcg_s / mg_s;
    j["global_bilap_mg_max_difference_" + tag] =
        (rmg.values - r.values).cwiseAbs().maxCoeff() / r.values.cwiseAbs().maxCoeff();
    if (level == 7) {
      // Both cores against one: the same solve with the thread limit at 1 (OpenMP
      // applies and the BLAS under CHOLMOD).
      const int limit = max_threads();
      set_max_threads(1);
      j["global_bilap_s_164k_1thread"] = timed_global_solve(m, o, free, u, Preconditioner::Auto).seconds;
      j["global_bilap_factor_s_164k_1thread"] =
          timed_global_solve(m, o, free, u, Preconditioner::LaplacianFactor).seconds;
      set_max_threads(limit);
      j["global_bilap_speedup_2threads_164k"] = j["global_bilap_s_164k_1thread"].get<double>() / auto_s;
      j["global_bilap_factor_speedup_2threads_164k"] = j["global_bilap_factor_s_164k_1thread"].get<double>() / pcg_s;
      const auto t_direct = clock_type::now();
      const SteadyDirectSolver direct(m, o, PdeCoefficients{.g0 = 0, .g1 = 0, .g2 = 1}, free);
      const Field x = direct.solve(u);
      const double direct_s = seconds_since(t_direct);
      j["global_bilap_setup_s_164k"] = ra.setup_seconds;
      j["global_bilap_factor_setup_s_164k"] = r.setup_seconds;
      j["global_bilap_direct_baseline_s_164k"] = direct_s;
      j["global_bilap_speedup_over_direct_164k"] = direct_s / auto_s;
      j["global_bilap_resolve_speedup_over_direct_164k"] = direct_s / resolve.second_seconds;
      j["global_bilap_factor_speedup_over_direct_164k"] = direct_s / pcg_s;
      j["global_bilap_mg_speedup_over_direct_164k"] = direct_s / j["global_bilap_mg_s_164k"].get<double>();
      // libigl's route (harmonic k = 2: Eigen's simplicial Cholesky with AMD on the
      // assembled system), same problem, same run; about 20 s on this machine.
      progress("global bi-Laplacian on 164k by Eigen's simplicial Cholesky (libigl's route)");
      const auto t_eigen = clock_type::now();
      const SteadyDirectSolver eigen_direct(m, o, PdeCoefficients{.g0 = 0, .g1 = 0, .g2 = 1}, free,
                                            SparseCholesky::Backend::Eigen);
      const Field xe = eigen_direct.solve(u);
      const double eigen_s = seconds_since(t_eigen);
      j["global_bilap_eigen_simplicial_baseline_s_164k"] = eigen_s;
      j["global_bilap_speedup_over_eigen_simplicial_164k"] = eigen_s / auto_s;
      j["global_bilap_resolve_speedup_over_eigen_simplicial_164k"] = eigen_s / resolve.second_seconds;
      j["global_bilap_eigen_simplicial_max_difference_164k"] = (xe - x).cwiseAbs().maxCoeff() / x.cwiseAbs().maxCoeff();
      set_max_threads(1);
      j["global_bilap_mg_s_164k_1thread"] = timed_global_solve(m, o, free, u, Preconditioner::Multigrid).seconds;
      set_max_threads(limit);
      j["global_bilap_mg_speedup_2threads_164k"] =
          j["global_bilap_mg_s_164k_1thread"].get<double>() / j["global_bilap_mg_s_164k"].get<double>();
      // The direct path's triangular sweeps (solvers/supernodal_sweeps.h) against
      // cholmod_solve with the same factor: K_FF of this problem, three columns.
      if (SparseCholesky::cholmod_available()) {
        progress("triangular sweeps on the 164k Laplacian factor");
        SparseCholesky lap(SparseCholesky::Backend::Cholmod);
        lap.factorize(assemble_steady_matrix(m, o, PdeCoefficients{.g0 = 0, .g1 = 1, .g2 = 0}, free));
        const Eigen::MatrixXd rhs = Eigen::MatrixXd::Random(static_cast<Eigen::Index>(free.size()), 3);
        auto best_solve_ms = [&] {
          double best = 1e300;
          for (int rep = 0; rep < (quick ? 3 : 8); ++rep) {
            const auto t = clock_type::now();
            const Eigen::MatrixXd xs = lap.solve(rhs);
            best = std::min(best, seconds_since(t) * 1e3);
          }
          return best;
        };
        lap.set_sweeps(SparseCholesky::Sweeps::Cholmod);
        const double cholmod_ms = best_solve_ms();
        lap.set_sweeps(SparseCholesky::Sweeps::WrittenOut);
        const double sweeps_ms = best_solve_ms();
        set_max_threads(1);
        const double sweeps_1thread_ms = best_solve_ms();
        set_max_threads(limit);
        j["direct_sweeps_ms_164k_laplacian"] = sweeps_ms;
        j["direct_sweeps_cholmod_solve_baseline_ms_164k_laplacian"] = cholmod_ms;
        j["direct_sweeps_speedup_164k_laplacian"] = cholmod_ms / sweeps_ms;
        j["direct_sweeps_ms_164k_laplacian_1thread"] = sweeps_1thread_ms;
        j["direct_sweeps_speedup_2threads_164k_laplacian"] = sweeps_1thread_ms / sweeps_ms;
      }
      j["global_bilap_max_difference_164k"] = (ra.values - x).cwiseAbs().maxCoeff() / x.cwiseAbs().maxCoeff();
      // The direct path's own second solve: its factor of K D K kept (SteadyDirectSolver),
      // two triangular sweeps; the fair baseline for a re-solve, at about three times
      // the global solver's memory.
      const auto t_direct_again = clock_type::now();
      const Field x_moved = direct.solve(resolve.moved);
      j["global_bilap_resolve_direct_baseline_s_164k"] = seconds_since(t_direct_again);
      j["global_bilap_resolve_max_difference_164k"] =
          (resolve.second.values - x_moved).cwiseAbs().maxCoeff() / x_moved.cwiseAbs().maxCoeff();
      j["global_bilap_factor_max_difference_164k"] = (r.values - x).cwiseAbs().maxCoeff() / x.cwiseAbs().maxCoeff();
    }
  }

  {
    // About a million vertices of a real mesh (million_problem).
    if (const std::optional<MillionProblem> million = million_problem(options)) {
      progress("global bi-Laplacian on fertility-4k subdivided 4 times");
      const Mesh& m = million->mesh;
      const FemOperators& o = million->ops;
      const auto& [handle, u, free] = million->drag;
      using Preconditioner = GlobalBilaplacianParams::Preconditioner;
      const TimedGlobalResolve resolve = timed_global_resolve(m, o, free, u, handle);
      const GlobalBilaplacianResult& r = resolve.first;
      const double auto_s = resolve.first_seconds;
      j["global_bilap_resolve_s_1m"] = resolve.second_seconds;
      j["global_bilap_resolve_iters_1m"] = resolve.second.iterations;
      j["global_bilap_resolve_preconditioner_1m"] = preconditioner_name(resolve.second.used);
      j["global_bilap_resolve_speedup_over_first_1m"] = auto_s / resolve.second_seconds;
      j["global_bilap_s_1m"] = auto_s;
      j["global_bilap_iters_1m"] = r.iterations;
      j["global_bilap_vertices_1m"] = m.num_vertices();
      j["global_bilap_bytes_per_vertex_1m"] = r.bytes_per_vertex;
      j["global_bilap_setup_s_1m"] = r.setup_seconds;
      j["global_bilap_residual_1m"] = r.relative_residual;
      j["global_bilap_preconditioner_1m"] = preconditioner_name(r.used);
      j["global_bilap_multigrid_iters_1m"] = r.multigrid_iterations;
      j["global_bilap_multigrid_predicted_iters_1m"] = r.multigrid_predicted_iterations;
      progress("global bi-Laplacian on fertility-4k subdivided 4 times with the Laplacian-factor preconditioner");
      const auto [rf, factor_s] = timed_global_solve(m, o, free, u, Preconditioner::LaplacianFactor);
      j["global_bilap_factor_s_1m"] = factor_s;
      j["global_bilap_factor_iters_1m"] = rf.iterations;
      j["global_bilap_factor_bytes_per_vertex_1m"] = rf.bytes_per_vertex;
      j["global_bilap_speedup_over_factor_1m"] = factor_s / auto_s;
      progress("global bi-Laplacian on fertility-4k subdivided 4 times with the multigrid preconditioner");
      const auto [rmg, mg_s] = timed_global_solve(m, o, free, u, Preconditioner::Multigrid);
      j["global_bilap_mg_s_1m"] = mg_s;
      j["global_bilap_mg_iters_1m"] = rmg.iterations;
      j["global_bilap_mg_bytes_per_vertex_1m"] = rmg.bytes_per_vertex;
      j["global_bilap_mg_speedup_over_factor_1m"] = factor_s / mg_s;
      // The names for this row, and CHOLMOD's direct solve of the same problem.
      j["global_bilap_s_fertility-1m"] = auto_s;
      j["global_bilap_iters_fertility-1m"] = r.iterations;
      const Field x = direct_million_figures(options, j, m, o, free, u);
      j["global_bilap_speedup_over_direct_1m"] = j["global_bilap_direct_baseline_s_1m"].get<double>() / auto_s;
      j["global_bilap_max_difference_1m"] = (r.values - x).cwiseAbs().maxCoeff() / x.cwiseAbs().maxCoeff();
    }
  }
  if (!quick) global_real_figures(options, j, /*every=*/large);

  progress("poke on 10k (level 5)");
  const Mesh small = unit_edge_icosphere(5);
  const FemOperators small_ops = build_cotan_operators(small);
  const PokeFigures p10 = poke(small, small_ops, steps, false);
  progress("poke on 10k with the whole mesh active (baseline)");
  const PokeFigures p10full = poke(small, small_ops, std::min(steps, 200), true);
  progress("poke on 655k (level 8)");
  const PokeFigures p655 = poke(big, big_ops, steps, false);
  auto put = [&](const std::string& tag, const PokeFigures& p) {
    j["poke_p50_us_" + tag] = p.us.p50;
    j["poke_p99_us_" + tag] = p.us.p99;
    j["poke_max_us_" + tag] = p.us.max;
    j["poke_mean_free_vertices_" + tag] = p.mean_free;
    j["poke_max_free_vertices_" + tag] = p.max_free;
    j["poke_mean_cg_iterations_" + tag] = p.mean_iterations;
    j["poke_deadline_misses_" + tag] = p.misses;
  };
  put("10k", p10);
  put("655k", p655);
  j["poke_p50_us_10k_full_domain"] = p10full.us.p50;
  j["poke_p99_ratio_655k_over_10k"] = p655.us.p99 / p10.us.p99;
  j["poke_p50_speedup_local_over_full_10k"] = p10full.us.p50 / p10.us.p50;
  j["poke_steps"] = steps;
  j["poke_setup"] =
      "icospheres scaled to mean edge length 1; alpha 1, b1 1, b2 0.01, g0 1, g1 0, g2 100; dt 1 ms; "
      "handle moved along the inward normal to depth 0.5 and back; CG rel. tol 1e-6";

  haptic_figures(options, j);
  paint_figures(options, j, large);
  correct_guard_figures(options, j);

  const auto bunny = options.data_dir / "bunny-36k.obj";
  if (std::filesystem::exists(bunny)) {
    progress("setup on bunny-36k");
    double load = 1e30, total = 1e30;
    for (int r = 0; r < reps; ++r) {
      auto ta = clock_type::now();
      MeshData d = read_mesh(bunny);
      const double tl = seconds_since(ta);
      Mesh m(std::move(d.V), std::move(d.F));
      const FemOperators o = build_cotan_operators(m);
      total = std::min(total, seconds_since(ta));
      load = std::min(load, tl);
    }
    j["setup_load_ms_bunny36k"] = load * 1e3;
    j["setup_total_ms_bunny36k"] = total * 1e3;
    j["setup_ratio_bunny36k"] = total / load;
  } else {
    warn(bunny.string() + " not found; setup_ratio_bunny36k skipped");
    j["setup_ratio_bunny36k"] = nullptr;
  }
  return j;
}

}  // namespace meshpde::bench
