// Access to the real meshes in ../shared/data. Under CI (CI=true) a missing file is
// a failure; elsewhere the test is skipped with a message naming the file.
#pragma once

#include <gtest/gtest.h>

#include <cstdlib>
#include <filesystem>
#include <string>

#include "meshpde/io/mesh_io.h"
#include "meshpde/mesh/mesh.h"

namespace meshpde::test {

inline std::filesystem::path data_dir() {
  if (const char* env = std::getenv("MESHPDE_DATA_DIR")) return env;
  return MESHPDE_DATA_DIR;
}

inline bool under_ci() {
  const char* ci = std::getenv("CI");
  return ci && std::string(ci) == "true";
}

/// True when ../shared/data/NAME exists; otherwise fails (CI) or skips the test.
/// Use as: if (!have_data(...)) return;
inline bool have_data(const std::string& name) {
  const auto path = data_dir() / name;
  if (!std::filesystem::exists(path)) {
    if (under_ci()) {
      ADD_FAILURE() << "missing test data " << path << " (CI=true: data must be present)";
    } else {
      GTEST_MESSAGE_AT_(__FILE__, __LINE__, ("missing test data " + path.string()).c_str(),
                        ::testing::TestPartResult::kSkip);
    }
    return false;
  }
  return true;
}

/// Loads ../shared/data/NAME (a core format) into `mesh`; returns false (after
/// failing or skipping) when the file is absent.
inline bool load_data(const std::string& name, Mesh& mesh, MeshData* data = nullptr) {
  if (!have_data(name)) return false;
  MeshData d = read_mesh(data_dir() / name);
  mesh = Mesh(d.V, d.F);
  if (data) *data = std::move(d);
  return true;
}

}  // namespace meshpde::test
