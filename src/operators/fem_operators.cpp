#include "meshpde/operators/fem_operators.h"

#include <fmt/format.h>

#include <Eigen/Geometry>
#include <cmath>
#include <vector>

#include "csr_row.h"
#include "meshpde/core/errors.h"
#include "meshpde/core/parallel.h"
#include "meshpde/mesh/topology.h"

namespace meshpde {

namespace {
// Below this many rows an apply stays on the calling thread: waking a second one
// costs more than half of a small apply (measured in meshpde bench, docs/solvers-measurements.md).
constexpr std::ptrdiff_t kParallelRows = 20000;
}  // namespace

Eigen::VectorXd face_areas(const Mesh& mesh) {
  Eigen::VectorXd a(mesh.num_faces());
  for (int f = 0; f < mesh.num_faces(); ++f) a[f] = is_degenerate(mesh, f) ? 0.0 : triangle_area(mesh, f);
  return a;
}

Eigen::VectorXd vertex_to_face_average(const Mesh& mesh, const Eigen::VectorXd& field) {
  if (field.size() != mesh.num_vertices())
    throw InputError(fmt::format("vertex field has {} values for {} vertices", field.size(), mesh.num_vertices()));
  const auto& F = mesh.triangles();
  Eigen::VectorXd w(mesh.num_faces());
  for (int f = 0; f < mesh.num_faces(); ++f) w[f] = (field[F(f, 0)] + field[F(f, 1)] + field[F(f, 2)]) / 3.0;
  return w;
}

FemOperators build_cotan_operators(const Mesh& mesh, const OperatorOptions& options) {
  const int nv = mesh.num_vertices(), nf = mesh.num_faces();
  const bool weighted = options.face_weights.size() > 0;
  if (weighted) {
    if (options.face_weights.size() != nf)
      throw InputError(fmt::format("face_weights has {} values for {} triangles", options.face_weights.size(), nf));
    for (int f = 0; f < nf; ++f)
      if (!(options.face_weights[f] >= 0) || !std::isfinite(options.face_weights[f]))
        throw InputError(fmt::format("face weight {} of triangle {} is not a finite non-negative number",
                                     options.face_weights[f], f));
  }
  FemOperators ops;
  ops.Kii = Eigen::VectorXd::Zero(nv);
  ops.mass = Eigen::VectorXd::Zero(nv);
  Eigen::VectorXd edge_value = Eigen::VectorXd::Zero(mesh.num_edges());
  const auto& V = mesh.positions();
  const auto& F = mesh.triangles();
  for (int f = 0; f < nf; ++f) {
    if (is_degenerate(mesh, f)) {
      ++ops.degenerate_faces;
      continue;
    }
    const int v[3] = {F(f, 0), F(f, 1), F(f, 2)};
    Eigen::Vector3d p[3];
    for (int c = 0; c < 3; ++c) p[c] = V.row(v[c]).transpose();
    // e[a] is the edge opposite corner a.
    const Eigen::Vector3d e[3] = {p[1] - p[2], p[2] - p[0], p[0] - p[1]};
    const double A = 0.5 * e[2].cross(-e[1]).norm();
    const double s = (weighted ? options.face_weights[f] : 1.0) / (4.0 * A);
    for (int a = 0; a < 3; ++a) {
      ops.Kii[v[a]] += s * e[a].squaredNorm();
      ops.mass[v[a]] += A / 3.0;
      // The edge opposite corner a joins corners b and c and receives Ke[b][c].
      const int b = (a + 1) % 3, c = (a + 2) % 3;
      edge_value[mesh.edge_ids()[mesh.find_slot(v[b], v[c])]] += s * e[b].dot(e[c]);
    }
  }
  ops.Kij.resize(static_cast<Eigen::Index>(mesh.neighbors().size()));
  for (std::size_t s = 0; s < mesh.neighbors().size(); ++s)
    ops.Kij[static_cast<Eigen::Index>(s)] = edge_value[mesh.edge_ids()[s]];
  for (int i = 0; i < nv; ++i) ops.zero_area_vertices += ops.mass[i] <= 0;
  return ops;
}

double bilaplacian_diagonal(const Mesh& mesh, const FemOperators& ops, int i) {
  double d = ops.Kii[i] * ops.Kii[i] * ops.D(i);
  const auto off = mesh.offsets();
  const auto nbr = mesh.neighbors();
  for (int s = off[i]; s < off[i + 1]; ++s) d += ops.Kij[s] * ops.Kij[s] * ops.D(nbr[s]);
  return d;
}

namespace {

// The CSR streams (K_ij and neighbour indices) run alongside gathers from the input
// field; the hardware prefetcher falls behind on that mix. Asking for the data half a
// kilobyte ahead makes the whole-mesh K D K apply about 25 % faster (bench: 655k
// icosphere). A prefetch past the end of an array is harmless.
inline void prefetch_row(int slot, const double* kij, const int* nbr) {
  __builtin_prefetch(kij + slot + 64);
  __builtin_prefetch(nbr + slot + 128);
}

}  // namespace

void apply_stiffness_rows(const Mesh& mesh, const FemOperators& ops, const double* U, double* Y, int m,
                          std::span<const int> rows) {
  const int* off = mesh.offsets().data();
  const int* nbr = mesh.neighbors().data();
  const double* kij = ops.Kij.data();
  const double* kii = ops.Kii.data();
  const auto count = static_cast<std::ptrdiff_t>(rows.size());
  [[maybe_unused]] const bool parallel = count >= kParallelRows;
  [[maybe_unused]] const int threads = max_threads();
  // Rows are independent (each writes only its own Y), so they split across threads.
  if (m == 1) {
#ifdef MESHPDE_HAVE_OPENMP
#pragma omp parallel for schedule(static) if (parallel) num_threads(threads)
#endif
    for (std::ptrdiff_t k = 0; k < count; ++k) {
      const int i = rows[static_cast<std::size_t>(k)];
      prefetch_row(off[i], kij, nbr);
      detail::csr_row<1>(i, off, nbr, kij, kii, U, Y);
    }
  } else if (m == 3) {
#ifdef MESHPDE_HAVE_OPENMP
#pragma omp parallel for schedule(static) if (parallel) num_threads(threads)
#endif
    for (std::ptrdiff_t k = 0; k < count; ++k) {
      const int i = rows[static_cast<std::size_t>(k)];
      prefetch_row(off[i], kij, nbr);
      detail::csr_row<3>(i, off, nbr, kij, kii, U, Y);
    }
  } else {
#ifdef MESHPDE_HAVE_OPENMP
#pragma omp parallel for schedule(static) if (parallel) num_threads(threads)
#endif
    for (std::ptrdiff_t k = 0; k < count; ++k) {
      const int i = rows[static_cast<std::size_t>(k)];
      for (int c = 0; c < m; ++c) Y[m * i + c] = kii[i] * U[m * i + c];
      for (int s = off[i]; s < off[i + 1]; ++s)
        for (int c = 0; c < m; ++c) Y[m * i + c] += kij[s] * U[m * nbr[s] + c];
    }
  }
}

void apply_bilaplacian_scalar(const Mesh& mesh, const FemOperators& ops, const double* u, double* T, double* Y) {
  const int n = mesh.num_vertices();
  const int* off = mesh.offsets().data();
  const int* nbr = mesh.neighbors().data();
  const double* kij = ops.Kij.data();
  const double* kii = ops.Kii.data();
  const double* mass = ops.mass.data();
  [[maybe_unused]] const bool parallel = n >= kParallelRows;
  auto k_row = [&](const double* x, int i) {  // (K x)_i
    prefetch_row(off[i], kij, nbr);
    double y = kii[i] * x[i];
    for (int s = off[i]; s < off[i + 1]; ++s) y += kij[s] * x[nbr[s]];
    return y;
  };
  // Two sweeps; the second reads T of neighbours, so all of T must be written first
  // (the barrier at the end of the first omp for).
#ifdef MESHPDE_HAVE_OPENMP
#pragma omp parallel if (parallel) num_threads(max_threads())
#endif
  {
#ifdef MESHPDE_HAVE_OPENMP
#pragma omp for schedule(static)
#endif
    for (int i = 0; i < n; ++i) T[i] = mass[i] > 0 ? k_row(u, i) / mass[i] : 0.0;
#ifdef MESHPDE_HAVE_OPENMP
#pragma omp for schedule(static)
#endif
    for (int i = 0; i < n; ++i) Y[i] = k_row(T, i);
  }
}

namespace {

std::vector<int> all_rows(int n) {
  std::vector<int> r(n);
  for (int i = 0; i < n; ++i) r[i] = i;
  return r;
}

void check_field(const Mesh& mesh, const Field& U) {
  if (U.rows() != mesh.num_vertices())
    throw InputError(fmt::format("field has {} rows for {} vertices", U.rows(), mesh.num_vertices()));
}

}  // namespace

Field apply_stiffness(const Mesh& mesh, const FemOperators& ops, const Field& U) {
  check_field(mesh, U);
  Field Y(U.rows(), U.cols());
  const auto rows = all_rows(mesh.num_vertices());
  apply_stiffness_rows(mesh, ops, U.data(), Y.data(), static_cast<int>(U.cols()), rows);
  return Y;
}

Field apply_mass(const FemOperators& ops, const Field& U) {
  Field Y = U;
  for (Eigen::Index i = 0; i < U.rows(); ++i) Y.row(i) *= ops.mass[i];
  return Y;
}

Field apply_bilaplacian(const Mesh& mesh, const FemOperators& ops, const Field& U) {
  Field T = apply_stiffness(mesh, ops, U);
  for (Eigen::Index i = 0; i < T.rows(); ++i) T.row(i) *= ops.D(static_cast<int>(i));
  return apply_stiffness(mesh, ops, T);
}

std::size_t stiffness_nonzeros(const Mesh& mesh) {
  return static_cast<std::size_t>(mesh.num_vertices()) + mesh.neighbors().size();
}

void stiffness_csr(const Mesh& mesh, const FemOperators& ops, std::span<int> row_offsets, std::span<int> columns,
                   std::span<double> values) {
  const int n = mesh.num_vertices();
  const std::size_t nnz = stiffness_nonzeros(mesh);
  if (row_offsets.size() != static_cast<std::size_t>(n) + 1 || columns.size() != nnz || values.size() != nnz)
    throw InputError(fmt::format("stiffness_csr: arrays of {}, {} and {} entries for {} rows and {} nonzeros",
                                 row_offsets.size(), columns.size(), values.size(), n, nnz));
  const auto off = mesh.offsets();
  const auto nbr = mesh.neighbors();
  // Row i is its neighbours (sorted ascending in the mesh's CSR) with i inserted in
  // order; row i starts i + off[i] entries in.
  for (int i = 0; i < n; ++i) {
    int k = i + off[i];
    row_offsets[static_cast<std::size_t>(i)] = k;
    int s = off[i];
    for (; s < off[i + 1] && nbr[s] < i; ++s, ++k) {
      columns[static_cast<std::size_t>(k)] = nbr[s];
      values[static_cast<std::size_t>(k)] = ops.Kij[s];
    }
    columns[static_cast<std::size_t>(k)] = i;
    values[static_cast<std::size_t>(k++)] = ops.Kii[i];
    for (; s < off[i + 1]; ++s, ++k) {
      columns[static_cast<std::size_t>(k)] = nbr[s];
      values[static_cast<std::size_t>(k)] = ops.Kij[s];
    }
  }
  row_offsets[static_cast<std::size_t>(n)] = static_cast<int>(nnz);
}

Eigen::SparseMatrix<double> stiffness_matrix(const Mesh& mesh, const FemOperators& ops) {
  // Filled in place: K's compressed-column arrays are its compressed-row ones.
  const int n = mesh.num_vertices();
  const std::size_t nnz = stiffness_nonzeros(mesh);
  Eigen::SparseMatrix<double> K(n, n);
  K.resizeNonZeros(static_cast<Eigen::Index>(nnz));
  stiffness_csr(mesh, ops, std::span<int>(K.outerIndexPtr(), static_cast<std::size_t>(n) + 1),
                std::span<int>(K.innerIndexPtr(), nnz), std::span<double>(K.valuePtr(), nnz));
  return K;
}

Eigen::SparseMatrix<double> mass_matrix(const FemOperators& ops) {
  Eigen::SparseMatrix<double> M(ops.mass.size(), ops.mass.size());
  std::vector<Eigen::Triplet<double>> t;
  for (Eigen::Index i = 0; i < ops.mass.size(); ++i) t.emplace_back(i, i, ops.mass[i]);
  M.setFromTriplets(t.begin(), t.end());
  return M;
}

}  // namespace meshpde
