// Mesh helpers shared by the test files.
#pragma once

#include <unistd.h>

#include <exception>
#include <filesystem>
#include <functional>
#include <random>
#include <string>
#include <system_error>

#include "meshpde/core/errors.h"
#include "meshpde/mesh/generators.h"
#include "meshpde/mesh/mesh.h"
#include "meshpde/mesh/topology.h"

namespace meshpde::test {

/// True in the AddressSanitizer build (MESHPDE_SANITIZER_BUILD: the tests themselves are
/// compiled without it), whose Debug code runs 20-40 times slower: the few
/// tests that loop over many large real meshes check memory there on the smaller ones
/// and leave the whole list to the Release suite, which runs every one.
#if defined(__SANITIZE_ADDRESS__) || defined(MESHPDE_SANITIZER_BUILD)
inline constexpr bool kSanitized = true;
#elif defined(__has_feature)
#if __has_feature(address_sanitizer)
inline constexpr bool kSanitized = true;
#else
inline constexpr bool kSanitized = false;
#endif
#else
inline constexpr bool kSanitized = false;
#endif

/// A path for a test's scratch file: in a folder of this process's own (tests run in
/// parallel processes; a fixed path would be shared), removed when the process ends.
inline std::filesystem::path scratch_path(const std::string& name) {
  struct Folder {
    std::filesystem::path path;
    Folder() {
      std::random_device rd;
      path = std::filesystem::temp_directory_path() /
             ("meshpde-test-" + std::to_string(::getpid()) + "-" + std::to_string(rd()));
      std::filesystem::create_directories(path);
    }
    ~Folder() {
      std::error_code ec;
      std::filesystem::remove_all(path, ec);
    }
  };
  static const Folder folder;
  return folder.path / name;
}

/// What f throws as E, in words, or "accepted" when it does not throw: for the tests
/// that a bad request is refused with a message naming what is wrong.
template <class E = std::exception, class F>
std::string refusal(F&& f) {
  try {
    f();
  } catch (const E& e) {
    return e.what();
  }
  return "accepted";
}

inline Mesh make(const GeneratedMesh& g) {
  return Mesh(g.V, g.F);
}

/// Icosphere scaled to mean edge length 1, so every level has the same local resolution.
inline Mesh unit_edge_icosphere(int level) {
  GeneratedMesh g = icosphere(level);
  g.V /= mean_edge_length(make(g));
  return make(g);
}

/// Unit-square grid with its interior vertices moved in-plane by up to +-amplitude
/// (seeded), so that it is planar but irregular.
inline GeneratedMesh jittered_plane(int n, double amplitude, unsigned seed) {
  GeneratedMesh g = plane_grid(n, n);
  std::mt19937 rng(seed);
  std::uniform_real_distribution<double> jitter(-amplitude, amplitude);
  for (Eigen::Index i = 0; i < g.V.rows(); ++i)
    if (g.V(i, 0) > 0 && g.V(i, 0) < 1 && g.V(i, 1) > 0 && g.V(i, 1) < 1) {
      g.V(i, 0) += jitter(rng);
      g.V(i, 1) += jitter(rng);
    }
  return g;
}

/// The message of the InputError that f throws, or "(no error)".
inline std::string error_of(const std::function<void()>& f) {
  try {
    f();
  } catch (const InputError& e) {
    return e.what();
  }
  return "(no error)";
}

}  // namespace meshpde::test
