// Independent triangulations of a surface for the resolution study
// (bench/python/resolution_study.py): CGAL 5.5's isotropic remeshing
// (Polygon_mesh_processing::isotropic_remeshing) of a mesh to a target edge length.
// Each call remeshes the input afresh, so outputs at h, h/2 and h/4 share no vertex and
// no edge: what two segmentations of one vessel are. Border edges are split to the
// target length and then kept in place (an open end stays where it was). Built only
// when CGAL is found (Debian libcgal-dev); never linked into the library.
//
//   meshpde_remesh IN OUT --edge H [--iterations N] [--seed S]
//
// H in the mesh's units; N smoothing iterations (default 5). The seed rotates the order
// in which faces are given to CGAL, so that two runs at the same H differ too.
#include <CGAL/Polygon_mesh_processing/border.h>
#include <CGAL/Polygon_mesh_processing/remesh.h>
#include <CGAL/Simple_cartesian.h>
#include <CGAL/Surface_mesh.h>
#include <fmt/format.h>

#include <cstdlib>
#include <cstring>
#include <string>
#include <vector>

#include "meshpde/core/errors.h"
#include "meshpde/io/mesh_io.h"

using Kernel = CGAL::Simple_cartesian<double>;
using SurfaceMesh = CGAL::Surface_mesh<Kernel::Point_3>;
namespace PMP = CGAL::Polygon_mesh_processing;

int main(int argc, char** argv) {
  if (argc < 5 || std::strcmp(argv[3], "--edge") != 0) {
    fmt::print(stderr, "usage: meshpde_remesh IN OUT --edge H [--iterations N] [--seed S]\n");
    return 2;
  }
  try {
    const double target = std::atof(argv[4]);
    if (!(target > 0)) throw meshpde::InputError(fmt::format("--edge {}: expected a length > 0", argv[4]));
    int iterations = 5, seed = 0;
    for (int i = 5; i + 1 < argc; i += 2) {
      if (std::strcmp(argv[i], "--iterations") == 0)
        iterations = std::atoi(argv[i + 1]);
      else if (std::strcmp(argv[i], "--seed") == 0)
        seed = std::atoi(argv[i + 1]);
      else
        throw meshpde::InputError(fmt::format("unknown option {}", argv[i]));
    }
    const meshpde::MeshData in = meshpde::read_mesh(argv[1]);
    SurfaceMesh sm;
    std::vector<SurfaceMesh::Vertex_index> v;
    for (Eigen::Index i = 0; i < in.V.rows(); ++i) v.push_back(sm.add_vertex({in.V(i, 0), in.V(i, 1), in.V(i, 2)}));
    const Eigen::Index nf = in.F.rows();
    for (Eigen::Index k = 0; k < nf; ++k) {
      const Eigen::Index f = (k + seed * 7919) % nf;
      if (sm.add_face(v[static_cast<std::size_t>(in.F(f, 0))], v[static_cast<std::size_t>(in.F(f, 1))],
                      v[static_cast<std::size_t>(in.F(f, 2))]) == SurfaceMesh::null_face())
        throw meshpde::InputError(
            fmt::format("{}: CGAL's Surface_mesh refused triangle {} (non-manifold)", argv[1], f));
    }
    std::vector<SurfaceMesh::Edge_index> border;
    PMP::border_halfedges(faces(sm), sm, boost::make_function_output_iterator([&](SurfaceMesh::Halfedge_index h) {
                            border.push_back(edge(h, sm));
                          }));
    PMP::split_long_edges(border, target, sm);
    PMP::isotropic_remeshing(faces(sm), target, sm,
                             CGAL::parameters::number_of_iterations(iterations).protect_constraints(true));
    sm.collect_garbage();
    meshpde::MeshData out;
    out.V.resize(static_cast<Eigen::Index>(sm.number_of_vertices()), 3);
    for (const auto vi : sm.vertices()) {
      const auto& p = sm.point(vi);
      out.V.row(static_cast<Eigen::Index>(vi.idx())) << p.x(), p.y(), p.z();
    }
    out.F.resize(static_cast<Eigen::Index>(sm.number_of_faces()), 3);
    Eigen::Index row = 0;
    for (const auto f : sm.faces()) {
      int k = 0;
      for (const auto vi : vertices_around_face(halfedge(f, sm), sm)) out.F(row, k++) = static_cast<int>(vi.idx());
      ++row;
    }
    out.space = in.space;
    for (const auto& w : meshpde::write_mesh(argv[2], out)) fmt::print(stderr, "warning: {}\n", w);
    fmt::print("{}: {} vertices, {} triangles (edge {})\n", argv[2], out.V.rows(), out.F.rows(), target);
    return 0;
  } catch (const std::exception& e) {
    fmt::print(stderr, "meshpde_remesh: error: {}\n", e.what());
    return 1;
  }
}
