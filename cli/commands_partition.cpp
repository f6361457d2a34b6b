// meshpde partition: cut a mesh into parts for a distributed run (meshpde-mpi).
#include <fmt/format.h>

#include <memory>

#include "commands.h"
#include "meshpde/core/errors.h"
#ifdef MESHPDE_HAVE_DISTRIBUTED
#include "meshpde/distributed/distributed_solve.h"
#include "meshpde/distributed/partition.h"
#endif

namespace meshpde::cli {

void add_partition_command(CLI::App& app) {
  auto* cmd = app.add_subcommand("partition",
                                 "Cut a mesh into N parts (PT-Scotch through PETSc) for `mpirun -n N meshpde-mpi`: "
                                 "DIR/part-P.ply and DIR/partition.json");
  auto in = std::make_shared<std::string>();
  auto out = std::make_shared<std::string>();
  auto parts = std::make_shared<int>(0);
  auto json = std::make_shared<bool>(false);
  cmd->add_option("MESH", *in, "Input mesh")->required();
  cmd->add_option("--parts", *parts, "Number of parts (one a process of the run)")->required();
  cmd->add_option("-o,--output", *out, "Output folder (created)")->required();
  cmd->add_flag("--json", *json, "Print a JSON report");
  cmd->callback([=] {
#ifdef MESHPDE_HAVE_DISTRIBUTED
    MeshData d;
    const Mesh mesh = load_mesh(*in, &d);
    PetscScope petsc(nullptr, nullptr);
    const std::vector<int> part_of = partition_vertices(mesh, *parts);
    const PartitionSummary s = write_partition(d, part_of, *out, *in);
    int most = 0, ghosts = 0;
    for (int k = 0; k < s.parts; ++k) {
      most = std::max(most, s.owned[k]);
      ghosts += s.ghosts[k];
    }
    const double imbalance = s.parts ? most * s.parts / static_cast<double>(mesh.num_vertices()) : 1.0;
    if (*json) {
      print_json({{"parts", s.parts},
                  {"vertices", mesh.num_vertices()},
                  {"owned", s.owned},
                  {"ghosts", s.ghosts},
                  {"part_faces", s.faces},
                  {"cut_edges", s.cut_edges},
                  {"imbalance", imbalance},
                  {"ghost_fraction", static_cast<double>(ghosts) / mesh.num_vertices()},
                  {"output", *out}});
    } else {
      fmt::print("{}: {} parts of {} vertices ({} to {} each, imbalance {:.3f}), {} cut edges, {} ghosts in all\n",
                 *out, s.parts, mesh.num_vertices(), *std::min_element(s.owned.begin(), s.owned.end()), most, imbalance,
                 s.cut_edges, ghosts);
    }
#else
    throw Error(
        "this meshpde was built without the distributed component: configure with -DMESHPDE_WITH_MPI=ON "
        "(Debian libpetsc-real-dev, libopenmpi-dev; MESHPDE_WITH_MPI=ON ./scripts/build installs them)");
#endif
  });
}

}  // namespace meshpde::cli
