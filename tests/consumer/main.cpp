// A downstream project: builds operators on a generated sphere through the
// installed package (the one-include header) and checks one identity and a plain
// (V, F) call; with meshpde::medical linked, also writes the sphere as a .vtp file and
// reads it back through the core's read_mesh and write_mesh alone (the component's
// formats are registered without the program calling any of its functions).
#include <meshpde/meshpde.h>
#include <unistd.h>

#include <cstdio>
#include <filesystem>
#include <string>

int main() {
  const auto g = meshpde::icosphere(2);
  const meshpde::Mesh mesh(g.V, g.F);
  const auto ops = meshpde::build_cotan_operators(mesh);
  const meshpde::Field ones = meshpde::Field::Ones(mesh.num_vertices(), 1);
  const double r = meshpde::apply_stiffness(mesh, ops, ones).cwiseAbs().maxCoeff();
  std::printf("%d vertices, K 1 = 0 up to %.1e\n", mesh.num_vertices(), r);
  const Eigen::VectorXd H = meshpde::mean_curvature(g.V, g.F, meshpde::CurvatureScale::Valence);
  std::printf("mean curvature of the unit sphere from (V, F): %.3f .. %.3f\n", H.minCoeff(), H.maxCoeff());
  if (!(H.minCoeff() > 0.9 && H.maxCoeff() < 1.1)) return 1;
#ifdef CONSUMER_HAS_MEDICAL
  meshpde::MeshData d;
  d.V = g.V;
  d.F = g.F;
  const auto path = std::filesystem::temp_directory_path() / ("meshpde-consumer-" + std::to_string(getpid()) + ".vtp");
  meshpde::write_mesh(path, d);
  const auto back = meshpde::read_mesh(path);
  std::filesystem::remove(path);
  std::printf("vtp round trip: %s\n", back.V == d.V && back.F == d.F ? "same" : "DIFFERENT");
  if (!(back.V == d.V && back.F == d.F)) return 1;
#endif
  return r < 1e-12 ? 0 : 1;
}
