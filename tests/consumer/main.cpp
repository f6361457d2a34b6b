// A downstream project: builds operators on a generated sphere through the
// installed package and checks one identity.
#include <meshpde/mesh/generators.h>
#include <meshpde/operators/fem_operators.h>

#include <cstdio>

int main() {
  const auto g = meshpde::icosphere(2);
  const meshpde::Mesh mesh(g.V, g.F);
  const auto ops = meshpde::build_operators(mesh);
  const meshpde::Field ones = meshpde::Field::Ones(mesh.num_vertices(), 1);
  const double r = meshpde::apply_stiffness(mesh, ops, ones).cwiseAbs().maxCoeff();
  std::printf("%d vertices, K 1 = 0 up to %.1e\n", mesh.num_vertices(), r);
  return r < 1e-12 ? 0 : 1;
}
