// meshpde partition: cut a mesh into parts for a distributed run. The work is done by
// the sibling tool meshpde-mpi (`meshpde-mpi partition`), so that this tool links
// neither MPI nor PETSc: OpenMPI's memory hooks and libraries would come with them into
// every command and the editor's server.
#include <fmt/format.h>
#include <unistd.h>

#include <filesystem>
#include <memory>
#include <vector>

#include "commands.h"
#include "meshpde/core/errors.h"

namespace meshpde::cli {

void add_partition_command(CLI::App& app) {
  auto* cmd = app.add_subcommand("partition",
                                 "Cut a mesh into N parts (PT-Scotch through PETSc) for `mpirun -n N meshpde-mpi`: "
                                 "DIR/part-P.ply and DIR/partition.json (runs meshpde-mpi partition)");
  auto in = std::make_shared<std::string>();
  auto out = std::make_shared<std::string>();
  auto parts = std::make_shared<std::string>();
  auto json = std::make_shared<bool>(false);
  cmd->add_option("MESH", *in, "Input mesh")->required();
  cmd->add_option("--parts", *parts, "Number of parts (one a process of the run)")->required();
  cmd->add_option("-o,--output", *out, "Output folder (created)")->required();
  cmd->add_flag("--json", *json, "Print a JSON report");
  cmd->callback([=] {
    std::error_code ec;
    const auto self = std::filesystem::read_symlink("/proc/self/exe", ec);
    const auto tool = self.parent_path() / "meshpde-mpi";
    if (ec || !std::filesystem::exists(tool))
      throw Error(
          "meshpde partition needs meshpde-mpi beside meshpde, which is built with the distributed component: "
          "configure with -DMESHPDE_WITH_MPI=ON (Debian libpetsc-real-dev, libopenmpi-dev; MESHPDE_WITH_MPI=ON "
          "./scripts/build installs them)");
    std::vector<std::string> args{tool.string(), "partition", *in, "--parts", *parts, "-o", *out};
    if (*json) args.emplace_back("--json");
    std::vector<char*> argv;
    for (auto& a : args) argv.push_back(a.data());
    argv.push_back(nullptr);
    execv(tool.c_str(), argv.data());
    throw Error(fmt::format("could not run {}", tool.string()));
  });
}

}  // namespace meshpde::cli
