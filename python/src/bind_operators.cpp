// meshpde's operators in Python: K and M as scipy.sparse matrices, the intrinsic
// Delaunay pair, and mean curvature.
#include <fmt/format.h>
#include <pybind11/stl.h>

#include <optional>

#include "bindings.h"
#include "convert.h"
#include "meshpde/operators/curvature.h"
#include "meshpde/operators/fem_operators.h"
#include "meshpde/operators/intrinsic_delaunay.h"
#include "meshpde/operators/laplacian.h"

namespace meshpde::python {

namespace {

// K and M of the requested kind. The cotangent kind is built on the caller's mesh
// directly (build_mesh_operators would keep a copy of it).
struct Operators {
  Mesh mesh;                           // the input mesh, or the intrinsic operator mesh
  std::optional<MeshOperators> kinds;  // set for the other kinds
  FemOperators cotan;
  const Mesh& operator_mesh() const { return kinds ? kinds->mesh : mesh; }
  const FemOperators& ops() const { return kinds ? kinds->ops : cotan; }
};

Operators operators_of(const py::handle& V, const py::handle& F, const std::string& laplacian) {
  Operators o{mesh_arg(V, F), std::nullopt, {}};
  const LaplacianKind kind = parse_laplacian_kind(laplacian);
  py::gil_scoped_release release;
  if (kind == LaplacianKind::Cotan)
    o.cotan = build_cotan_operators(o.mesh);
  else
    o.kinds = build_mesh_operators(o.mesh, kind);
  return o;
}

}  // namespace

void bind_operators(py::module_& m) {
  m.def(
      "stiffness",
      [](const ArrayLike& V, const ArrayLike& F, const std::string& laplacian) {
        const Operators o = operators_of(V, F, laplacian);
        // Written straight into the arrays scipy keeps (no intermediate matrix).
        const auto n = static_cast<std::size_t>(o.operator_mesh().num_vertices());
        const std::size_t nnz = stiffness_nonzeros(o.operator_mesh());
        py::array_t<double> data(static_cast<py::ssize_t>(nnz));
        py::array_t<int> indices(static_cast<py::ssize_t>(nnz));
        py::array_t<int> indptr(static_cast<py::ssize_t>(n + 1));
        {
          py::gil_scoped_release release;
          stiffness_csr(o.operator_mesh(), o.ops(), std::span<int>(indptr.mutable_data(), n + 1),
                        std::span<int>(indices.mutable_data(), nnz), std::span<double>(data.mutable_data(), nnz));
        }
        return csr_from_arrays(data, indices, indptr, n, n);
      },
      R"doc(stiffness(V, F, laplacian="cotan") -> scipy.sparse.csr_matrix (n x n)

K, symmetric positive semi-definite, K 1 = 0: minus libigl's cotmatrix
(K_ij = -(cot a_ij + cot b_ij) / 2). laplacian: "cotan", "intrinsic" (intrinsic
Delaunay, an M-matrix on any mesh) or "auto" (intrinsic on badly shaped meshes).)doc",
      py::arg("V"), py::arg("F"), py::arg("laplacian") = "cotan");
  m.def(
      "mass",
      [](const ArrayLike& V, const ArrayLike& F, const std::string& laplacian) {
        const Operators o = operators_of(V, F, laplacian);
        return to_csr(mass_matrix(o.ops()));
      },
      R"doc(mass(V, F, laplacian="cotan") -> scipy.sparse.csr_matrix (n x n)

Lumped mass M: M_ii = a third of the area of the triangles at i (length^2).)doc",
      py::arg("V"), py::arg("F"), py::arg("laplacian") = "cotan");
  m.def(
      "intrinsic_delaunay",
      [](const ArrayLike& V, const ArrayLike& F, double mollify_epsilon) {
        const Mesh mesh = mesh_arg(V, F);
        if (!(mollify_epsilon >= 0) || !std::isfinite(mollify_epsilon))
          throw InputError(fmt::format("mollify_epsilon: expected a finite value >= 0, got {}", mollify_epsilon));
        IntrinsicOperators o;
        {
          py::gil_scoped_release release;
          o = build_intrinsic_delaunay_operators(
              mesh, IntrinsicDelaunayOptions{.mollify_epsilon = mollify_epsilon, .vertex_weights = {}});
        }
        py::dict stats;
        stats["flips"] = o.stats.flips;
        stats["mollify_delta"] = o.stats.mollify_delta;
        stats["non_delaunay_edges_before"] = o.stats.non_delaunay_edges_before;
        stats["nonmanifold_edges"] = o.stats.nonmanifold_edges;
        stats["delaunay"] = o.stats.delaunay;
        return py::make_tuple(to_csr(stiffness_matrix(o.operator_mesh, o.ops)), to_csr(mass_matrix(o.ops)), stats);
      },
      R"doc(intrinsic_delaunay(V, F, mollify_epsilon=1e-2) -> (K, M, stats)

K and M on the intrinsic Delaunay triangulation of the same surface (Sharp and Crane
2020): non-negative edge weights on any mesh, slivers and non-manifold ones included.)doc",
      py::arg("V"), py::arg("F"), py::arg("mollify_epsilon") = IntrinsicDelaunayOptions{}.mollify_epsilon);
  m.def(
      "curvature",
      [](const ArrayLike& V, const ArrayLike& F, const std::string& scale, const std::string& laplacian) {
        if (scale != "area" && scale != "valence")
          throw InputError(fmt::format("scale: expected 'area' or 'valence', got '{}'", scale));
        const LaplacianKind kind = parse_laplacian_kind(laplacian);
        const Mesh mesh = mesh_arg(V, F);
        Eigen::VectorXd H;
        {
          py::gil_scoped_release release;
          H = mean_curvature(mesh, scale == "area" ? CurvatureScale::Area : CurvatureScale::Valence, kind).H;
        }
        return to_numpy(H);
      },
      R"doc(curvature(V, F, scale="area", laplacian="auto") -> (n,)

Mean curvature H_i = |row_i(K V)| c_i / 2 (1 / length): 1/R on a sphere of radius R.
scale: "area" (c_i = 3 / area around i) or "valence" (Kim and Rossignac's flat-umbrella fit).
laplacian: "auto" (intrinsic Delaunay on badly shaped or non-manifold meshes), "cotan"
or "intrinsic", as ``meshpde curvature --laplacian``.)doc",
      py::arg("V"), py::arg("F"), py::arg("scale") = "area", py::arg("laplacian") = "auto");
}

}  // namespace meshpde::python
