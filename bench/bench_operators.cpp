// Google Benchmark microbenchmarks of the kernels behind `meshpde bench`.
// Run: build/release/bench/meshpde_bench --benchmark_counters_tabular=true
#include <benchmark/benchmark.h>

#include <map>
#include <memory>
#include <numeric>

#include "meshpde/mesh/generators.h"
#include "meshpde/mesh/topology.h"
#include "meshpde/operators/fem_operators.h"
#include "meshpde/pde/pde_session.h"

using namespace meshpde;

namespace {

struct Fixture {
  Mesh mesh;
  FemOperators ops;
  std::vector<int> rows;
  explicit Fixture(int level) {
    // Scaled to mean edge length 1, as in `meshpde bench`: every level has the same
    // local resolution, so a poke touches the same neighbourhood.
    GeneratedMesh g = icosphere(level);
    g.V /= mean_edge_length(Mesh(g.V, g.F));
    mesh = Mesh(g.V, g.F);
    ops = build_cotan_operators(mesh);
    rows.resize(mesh.num_vertices());
    std::iota(rows.begin(), rows.end(), 0);
  }
};

Fixture& fixture(int level) {
  static std::map<int, std::unique_ptr<Fixture>> cache;
  auto& f = cache[level];
  if (!f) f = std::make_unique<Fixture>(level);
  return *f;
}

void BM_Triad(benchmark::State& state) {
  const std::size_t n = static_cast<std::size_t>(state.range(0));
  std::vector<double> a(n), b(n, 1.0), c(n, 2.0);
  for (auto _ : state) {
    for (std::size_t i = 0; i < n; ++i) a[i] = b[i] + 0.5 * c[i];
    benchmark::DoNotOptimize(a.data());
  }
  state.SetBytesProcessed(static_cast<int64_t>(state.iterations() * 24 * n));
}
BENCHMARK(BM_Triad)->Arg(1 << 22)->Arg(1 << 24);

void BM_StiffnessApply(benchmark::State& state) {
  Fixture& f = fixture(static_cast<int>(state.range(0)));
  const int m = static_cast<int>(state.range(1));
  std::vector<double> u(static_cast<std::size_t>(f.mesh.num_vertices()) * m, 1.0), y(u.size());
  for (auto _ : state) {
    apply_stiffness_rows(f.mesh, f.ops, u.data(), y.data(), m, f.rows);
    benchmark::DoNotOptimize(y.data());
  }
  state.counters["vertices"] = f.mesh.num_vertices();
  state.SetItemsProcessed(state.iterations() * f.mesh.num_vertices());
}
BENCHMARK(BM_StiffnessApply)->Args({5, 1})->Args({5, 3})->Args({8, 1})->Unit(benchmark::kMicrosecond);

void BM_PokeStep(benchmark::State& state) {
  Fixture& f = fixture(static_cast<int>(state.range(0)));
  PdeSession s(f.mesh, f.ops, 3, PdeCoefficients{.alpha = 1, .b1 = 1, .b2 = 0.01, .g0 = 1, .g1 = 0, .g2 = 100},
               DomainOptions{.self_adjusting = true, .rest_value = 1e-4, .rest_rate = 1e-3});
  s.cg_options = CgOptions{.tolerance = 1e-6, .max_iterations = 200};
  const Eigen::Vector3d n = f.mesh.positions().row(0).normalized();
  int k = 0;
  for (auto _ : state) {
    const Eigen::Vector3d target = -0.5 * std::abs(std::sin(0.003 * ++k)) * n;
    s.constrain(0, std::span<const double>(target.data(), 3));
    benchmark::DoNotOptimize(s.step(1e-3));
  }
  state.counters["free"] = s.domain().num_free();
}
BENCHMARK(BM_PokeStep)->Arg(5)->Arg(8)->Unit(benchmark::kMicrosecond);

}  // namespace

BENCHMARK_MAIN();
