// meshpde bench: parses the flags, runs the standard benchmarks (bench/suite) and
// prints their figures.
#include <fmt/format.h>

#include <memory>

#include "commands.h"
#include "suite/standard_benchmarks.h"

namespace meshpde::cli {

void add_bench_command(CLI::App& app) {
  auto* cmd = app.add_subcommand("bench", "Run the standard benchmarks and print figures with their baselines");
  auto options = std::make_shared<bench::BenchOptions>();
  auto json = std::make_shared<bool>(false);
  auto folder = std::make_shared<std::string>();
  cmd->add_flag("--quick", options->quick, "Fewer repetitions and steps (same meshes)");
  cmd->add_flag("--json", *json, "Print a JSON object");
  cmd->add_flag("--large", options->large,
                "Also the global solves on the 655k and 2.6M icospheres (iteration counts; minutes, several GB) and "
                "global_real's every mesh and second subdivision");
  cmd->add_option("--data-dir", *folder,
                  "Folder of the real meshes the bench reads (igea-134k.ply, aorta-103k.vtp, ...; default: the "
                  "environment variable MESHPDE_DATA_DIR; figures whose mesh is missing are skipped with a warning)");
  cmd->add_option("--threads", options->threads, "Thread limit for the whole run (default: every core)");
  cmd->add_option(
         "--only", options->only,
         "One section alone: haptic (the haptic_* figures), global_real (the global bi-Laplacian on every real "
         "mesh of the data folder, as it is and subdivided once and twice, beside CHOLMOD; ten minutes or more), "
         "paint (the editor's paint clicks on igea-134k; with --large also on it subdivided twice, 2.15M vertices), "
         "correct_guard (a correction the self-intersection guard limits, beside the same applied as solved), drag "
         "(DragSession on a 10k-vertex region of the 655k icosphere: set-up and its parts, updates, handles, rings) or "
         "direct (the direct bi-Laplacian solve of fertility-4k subdivided to 1.15M vertices, by CHOLMOD with its own "
         "ordering and in the mesh's nested dissection order: time, fill and memory)")
      ->check(CLI::IsMember({"haptic", "global_real", "paint", "correct_guard", "drag", "direct"}));
  cmd->callback([=] {
    options->data_dir = bench_data_dir(*folder);
    options->progress = [](const std::string& what) { fmt::print(stderr, "[bench] {}\n", what); };
    options->warning = [](const std::string& what) { fmt::print(stderr, "warning: {}\n", what); };
    const nlohmann::json j = bench::run_standard_benchmarks(*options);
    if (*json) {
      print_json(j);
    } else {
      for (auto it = j.begin(); it != j.end(); ++it) fmt::print("{:42} {}\n", it.key(), it.value().dump());
    }
  });
}

}  // namespace meshpde::cli
