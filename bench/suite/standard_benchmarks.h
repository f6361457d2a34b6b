// The standard benchmarks behind `meshpde bench`: operator applies, interactive drags,
// global steady solves, pokes and haptics, set-up of a real scan. Every figure comes
// with the baseline it is measured against in the same run (machines are shared and
// noisy: compare ratios, not absolute times). The JSON keys are listed, with what each
// measures, in docs/benchmarks.md.
#pragma once

#include <filesystem>
#include <functional>
#include <nlohmann/json.hpp>
#include <string>

namespace meshpde::bench {

struct BenchOptions {
  bool quick = false;  ///< fewer repetitions and steps (the same meshes)
  bool large = false;  ///< also the global solves on the 655k and 2.6M icospheres (minutes, several GB)
  int threads = 0;     ///< thread limit for the whole run; 0: every core
  /// One section alone: "haptic" (the haptic_* figures), "global_real" (the global
  /// bi-Laplacian on the real meshes, global_bilap_*_<mesh>), "paint" (the paint_*
  /// figures), "correct_guard" (correct_guarded_*), "drag" (the drag_* figures of
  /// DragSession on the 655k icosphere) or "direct" (the direct solve of the
  /// million-vertex row: global_bilap_direct_baseline_s_1m, direct_bytes_per_vertex_1m);
  /// empty: everything.
  std::string only;
  /// Where the real meshes are (igea-134k.ply, bunny-36k.obj, fertility-4k.off); a
  /// missing one leaves its figures out with a warning.
  std::filesystem::path data_dir;
  std::function<void(const std::string&)> progress;  ///< told before each step; may be empty
  std::function<void(const std::string&)> warning;   ///< told what was left out and why; may be empty
};

/// Runs every benchmark and returns the figures as one JSON object (keys as
/// `meshpde bench --json` prints them). Takes seconds with `quick`, minutes without.
/// \throw SolverError if a solve it times fails.
nlohmann::json run_standard_benchmarks(const BenchOptions& options);

}  // namespace meshpde::bench
