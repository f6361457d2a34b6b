// Peer comparison, side by side in one run: meshpde against CGAL 5.5
// (Surface_mesh_deformation and Polygon_mesh_processing::fair) and a plain Eigen
// direct solve, on the same meshes, regions and handles. Built only when CGAL is
// found (Debian libcgal-dev); never linked into the library.
//
//   meshpde_peer_bench [--level L] [--json]
//
// Problems (icosphere of the given level, scaled to mean edge length 1):
//   drag:  region of about 7k vertices (geodesic radius 50; smaller on small meshes) around the top vertex,
//          the handle moved 5 edge lengths along its normal.
//          meshpde DragSession (linear bi-Laplacian; set-up, then one update) against
//          CGAL Surface_mesh_deformation, SPOKES_AND_RIMS (its default) and SRE_ARAP
//          (preprocess, then deform() with its default 5 iterations). The models differ
//          (ARAP is nonlinear, rotation-aware); the table compares what a user waits for.
//   fair:  the vertices of a cap of 5 % of the mesh re-solved with the rest fixed:
//          meshpde fair (order 1 and 2) against PMP::fair (continuity 0 and 1: CGAL's
//          continuity k solves Delta^(k+1) x = 0), and the same system solved by Eigen's
//          SimplicialLDLT (libigl's route). CGAL's continuity 2 (tri-harmonic, no
//          meshpde counterpart) is timed for reference.
// The answers are compared too: the faired surfaces by their Hausdorff distance (the
// peers' weights place vertices differently along the surface), the Eigen solve
// entry by entry, and the drag's handle position in both.
#include <CGAL/Polygon_mesh_processing/fair.h>
#include <CGAL/Simple_cartesian.h>
#include <CGAL/Surface_mesh.h>
#include <CGAL/Surface_mesh_deformation.h>
#include <fmt/format.h>

#include <chrono>
#include <cstring>
#include <nlohmann/json.hpp>
#include <random>
#include <string>

#include "meshpde/apps/fairing.h"
#include "meshpde/apps/local_drag.h"
#include "meshpde/mesh/generators.h"
#include "meshpde/mesh/surface_distance.h"
#include "meshpde/mesh/topology.h"
#include "meshpde/pde/steady_direct.h"

using Kernel = CGAL::Simple_cartesian<double>;
using SurfaceMesh = CGAL::Surface_mesh<Kernel::Point_3>;
using VertexIndex = SurfaceMesh::Vertex_index;

namespace {

using clock_type = std::chrono::steady_clock;
double seconds_since(clock_type::time_point t) {
  return std::chrono::duration<double>(clock_type::now() - t).count();
}

SurfaceMesh to_cgal(const meshpde::Mesh& m) {
  SurfaceMesh sm;
  std::vector<VertexIndex> v;
  v.reserve(static_cast<std::size_t>(m.num_vertices()));
  for (int i = 0; i < m.num_vertices(); ++i)
    v.push_back(sm.add_vertex(Kernel::Point_3(m.positions()(i, 0), m.positions()(i, 1), m.positions()(i, 2))));
  for (int f = 0; f < m.num_faces(); ++f)
    if (sm.add_face(v[static_cast<std::size_t>(m.triangles()(f, 0))], v[static_cast<std::size_t>(m.triangles()(f, 1))],
                    v[static_cast<std::size_t>(m.triangles()(f, 2))]) == SurfaceMesh::null_face())
      throw std::runtime_error(fmt::format("CGAL Surface_mesh refused triangle {}", f));
  return sm;
}

template <class Deformation>
nlohmann::json cgal_drag(const meshpde::Mesh& mesh, const std::vector<int>& roi, int handle,
                         const Eigen::Vector3d& target, const char* name) {
  SurfaceMesh sm = to_cgal(mesh);
  const auto t0 = clock_type::now();
  Deformation deform(sm);
  for (int v : roi) deform.insert_roi_vertex(VertexIndex(static_cast<SurfaceMesh::size_type>(v)));
  deform.insert_control_vertex(VertexIndex(static_cast<SurfaceMesh::size_type>(handle)));
  if (!deform.preprocess()) throw std::runtime_error(fmt::format("CGAL {}: preprocess failed", name));
  const double pre = seconds_since(t0);
  deform.set_target_position(VertexIndex(static_cast<SurfaceMesh::size_type>(handle)),
                             Kernel::Point_3(target.x(), target.y(), target.z()));
  const auto t1 = clock_type::now();
  deform.deform();
  const double def = seconds_since(t1);
  const auto p = sm.point(VertexIndex(static_cast<SurfaceMesh::size_type>(handle)));
  const double miss = (Eigen::Vector3d(p.x(), p.y(), p.z()) - target).norm();
  return {{"preprocess_ms", pre * 1e3}, {"deform_ms", def * 1e3}, {"handle_miss", miss}};
}

}  // namespace

int main(int argc, char** argv) {
  int level = 7;
  bool json = false;
  for (int a = 1; a < argc; ++a) {
    if (!std::strcmp(argv[a], "--level") && a + 1 < argc)
      level = std::atoi(argv[++a]);
    else if (!std::strcmp(argv[a], "--json"))
      json = true;
    else {
      fmt::print(stderr, "usage: meshpde_peer_bench [--level L] [--json]\n");
      return 2;
    }
  }
  try {
    using namespace meshpde;
    GeneratedMesh g = icosphere(level, 1.0);
    g.V /= mean_edge_length(Mesh(g.V, g.F));
    const Mesh mesh(g.V, g.F);
    const FemOperators ops = build_cotan_operators(mesh);
    nlohmann::json j;
    j["vertices"] = mesh.num_vertices();
    int handle = 0;
    mesh.positions().col(2).maxCoeff(&handle);
    const double radius = std::min(50.0, 0.4 * std::sqrt(mesh.num_vertices() / 10.0));
    std::vector<int> roi = geodesic_ball(mesh, handle, radius);
    roi.erase(std::remove(roi.begin(), roi.end(), handle), roi.end());
    const Eigen::Vector3d normal = mesh.positions().row(handle).normalized();
    const Eigen::Vector3d move = 5.0 * normal;
    const Eigen::Vector3d target = mesh.positions().row(handle).transpose() + move;
    j["drag_region_vertices"] = roi.size();
    fmt::print(stderr, "[peer] drag: meshpde DragSession\n");
    {
      const auto t0 = clock_type::now();
      // A handle of size 0: the vertex held at its target, as CGAL's handle is.
      DragSession s(mesh, ops, {handle}, DragSessionParams{.radius = radius, .handle_radius = 0});
      const double setup = seconds_since(t0);
      // An update: the region's new displacements (what CGAL's deform() computes for
      // its region of interest).
      const auto t1 = clock_type::now();
      const Eigen::MatrixXd x = s.displacements(move.transpose());
      const double update = seconds_since(t1);
      const Positions P = s.positions(move.transpose());
      if (!x.allFinite()) throw std::runtime_error("meshpde drag produced non-finite values");
      j["meshpde_drag"] = {{"setup_ms", setup * 1e3},
                           {"update_ms", update * 1e3},
                           {"handle_miss", (P.row(handle).transpose() - target).norm()}};
    }
    fmt::print(stderr, "[peer] drag: CGAL Surface_mesh_deformation (SPOKES_AND_RIMS, SRE_ARAP)\n");
    j["cgal_drag_spokes_and_rims"] =
        cgal_drag<CGAL::Surface_mesh_deformation<SurfaceMesh>>(mesh, roi, handle, target, "SPOKES_AND_RIMS");
    j["cgal_drag_sre_arap"] =
        cgal_drag<CGAL::Surface_mesh_deformation<SurfaceMesh, CGAL::Default, CGAL::Default, CGAL::SRE_ARAP>>(
            mesh, roi, handle, target, "SRE_ARAP");
    const double ours = j["meshpde_drag"]["setup_ms"].get<double>() + j["meshpde_drag"]["update_ms"].get<double>();
    j["drag_ratio_cgal_spokes_over_meshpde"] = (j["cgal_drag_spokes_and_rims"]["preprocess_ms"].get<double>() +
                                                j["cgal_drag_spokes_and_rims"]["deform_ms"].get<double>()) /
                                               ours;
    j["drag_update_ratio_cgal_deform_over_meshpde_update"] =
        j["cgal_drag_spokes_and_rims"]["deform_ms"].get<double>() / j["meshpde_drag"]["update_ms"].get<double>();

    // Fairing a cap of 5 % of the vertices (the lowest z), everything else fixed.
    std::vector<int> order(static_cast<std::size_t>(mesh.num_vertices()));
    for (int i = 0; i < mesh.num_vertices(); ++i) order[static_cast<std::size_t>(i)] = i;
    std::sort(order.begin(), order.end(),
              [&](int a, int b) { return mesh.positions()(a, 2) < mesh.positions()(b, 2); });
    const std::size_t cap = order.size() / 20;
    const std::vector<int> free(order.begin(), order.begin() + static_cast<std::ptrdiff_t>(cap));
    const std::vector<int> fixed(order.begin() + static_cast<std::ptrdiff_t>(cap), order.end());
    // Roughen the cap first so that fairing has something to do: every free vertex
    // moved along its normal by up to half an edge length (fixed seed). The smooth
    // continuum answer is the same at every resolution, so the peers' surfaces should
    // approach each other as the mesh is refined (a dent with a crease at its rim would
    // make the thin plate singular there).
    Positions dented = mesh.positions();
    std::mt19937 rng(7);
    std::uniform_real_distribution<double> noise(-0.5, 0.5);
    for (int v : free) dented.row(v) += noise(rng) * mesh.positions().row(v).normalized();
    const Mesh dented_mesh(dented, mesh.triangles());
    j["fair_free_vertices"] = free.size();
    for (const int c : {1, 2}) {
      fmt::print(stderr, "[peer] fair, order {}: meshpde, CGAL, Eigen SimplicialLDLT\n", c);
      const auto t0 = clock_type::now();
      const FairResult ours_fair = fair(dented_mesh, fixed, FairParams{.order = c});
      const double ours_s = seconds_since(t0);
      SurfaceMesh sm = to_cgal(dented_mesh);
      std::vector<VertexIndex> vs;
      for (int v : free) vs.push_back(VertexIndex(static_cast<SurfaceMesh::size_type>(v)));
      const auto t1 = clock_type::now();
      // CGAL's continuity k solves Delta^(k+1) x = 0: continuity 0 is our order 1
      // (membrane), continuity 1 our order 2 (thin plate).
      const bool ok = CGAL::Polygon_mesh_processing::fair(sm, vs, CGAL::parameters::fairing_continuity(c - 1));
      const double cgal_s = seconds_since(t1);
      if (!ok) throw std::runtime_error("CGAL fair failed");
      // The two fairings may place vertices differently along the surface (their weights
      // differ), so compare surfaces: the symmetric Hausdorff distance.
      Positions theirs = dented;
      double scale = 0, cgal_scale = 0;
      for (int v : free) {
        const auto p = sm.point(VertexIndex(static_cast<SurfaceMesh::size_type>(v)));
        theirs.row(v) << p.x(), p.y(), p.z();
        scale = std::max(scale, (ours_fair.V.row(v) - dented.row(v)).norm());
        cgal_scale = std::max(cgal_scale, (theirs.row(v) - dented.row(v)).norm());
      }
      const double diff = hausdorff_distance(ours_fair.V, mesh.triangles(), theirs, mesh.triangles());
      // libigl's route: the same system by Eigen's simplicial LDL^T (AMD ordering).
      const auto t2 = clock_type::now();
      Field held = Field::Zero(mesh.num_vertices(), 3);
      for (int v : fixed) held.row(v) = dented.row(v);
      const FemOperators dops = build_cotan_operators(dented_mesh);
      const SteadyDirectSolver eigen(dented_mesh, dops,
                                     PdeCoefficients{.g0 = 0, .g1 = c == 1 ? 1.0 : 0.0, .g2 = c == 2 ? 1.0 : 0.0}, free,
                                     SparseCholesky::Backend::Eigen);
      const Field e = eigen.solve(held);
      const double eigen_s = seconds_since(t2);
      double eigen_diff = 0;
      for (int v : free) eigen_diff = std::max(eigen_diff, (e.row(v) - ours_fair.V.row(v)).norm());
      const std::string key = fmt::format("fair_order{}", c);
      j[key] = {{"meshpde_s", ours_s},
                {"cgal_s", cgal_s},
                {"eigen_simplicial_s", eigen_s},
                {"ratio_cgal_over_meshpde", cgal_s / ours_s},
                {"ratio_eigen_over_meshpde", eigen_s / ours_s},
                {"hausdorff_to_cgal", diff},
                {"max_difference_to_eigen", eigen_diff},
                {"largest_fairing_move", scale},
                {"largest_cgal_move", cgal_scale}};
    }
    {
      fmt::print(stderr, "[peer] fair: CGAL continuity 2 (tri-harmonic), for reference\n");
      SurfaceMesh sm = to_cgal(dented_mesh);
      std::vector<VertexIndex> vs;
      for (int v : free) vs.push_back(VertexIndex(static_cast<SurfaceMesh::size_type>(v)));
      const auto t = clock_type::now();
      if (!CGAL::Polygon_mesh_processing::fair(sm, vs, CGAL::parameters::fairing_continuity(2)))
        throw std::runtime_error("CGAL fair (continuity 2) failed");
      j["cgal_fair_c2_s"] = seconds_since(t);
    }
    if (json) {
      fmt::print("{}\n", j.dump(2));
    } else {
      fmt::print("peer comparison on a {}-vertex icosphere (unit edges)\n", mesh.num_vertices());
      fmt::print(
          "drag, {} region vertices: meshpde set-up {:.1f} ms + update {:.3f} ms; CGAL spokes-and-rims "
          "preprocess {:.1f} ms + deform {:.1f} ms; SRE_ARAP {:.1f} + {:.1f} ms\n",
          roi.size(), j["meshpde_drag"]["setup_ms"].get<double>(), j["meshpde_drag"]["update_ms"].get<double>(),
          j["cgal_drag_spokes_and_rims"]["preprocess_ms"].get<double>(),
          j["cgal_drag_spokes_and_rims"]["deform_ms"].get<double>(),
          j["cgal_drag_sre_arap"]["preprocess_ms"].get<double>(), j["cgal_drag_sre_arap"]["deform_ms"].get<double>());
      for (const int c : {1, 2}) {
        const auto& f = j[fmt::format("fair_order{}", c)];
        fmt::print(
            "fair order {}, {} free vertices: meshpde {:.3f} s, CGAL {:.3f} s ({:.1f}x), Eigen simplicial {:.3f} s "
            "({:.1f}x); surfaces {:.2g} apart (Hausdorff, CGAL), answers {:.1e} apart (Eigen), largest move {:.3g}\n",
            c, free.size(), f["meshpde_s"].get<double>(), f["cgal_s"].get<double>(),
            f["ratio_cgal_over_meshpde"].get<double>(), f["eigen_simplicial_s"].get<double>(),
            f["ratio_eigen_over_meshpde"].get<double>(), f["hausdorff_to_cgal"].get<double>(),
            f["max_difference_to_eigen"].get<double>(), f["largest_fairing_move"].get<double>());
      }
      fmt::print("CGAL continuity 2 (tri-harmonic, no meshpde counterpart): {:.3f} s\n",
                 j["cgal_fair_c2_s"].get<double>());
    }
    return 0;
  } catch (const std::exception& e) {
    fmt::print(stderr, "error: {}\n", e.what());
    return 1;
  }
}
