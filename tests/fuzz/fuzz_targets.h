// The fuzz targets: one function per input the project parses, each taking raw bytes.
// A target returns 0 when the input was read or refused with meshpde's InputError (or
// SolverError); anything else is a bug and ends the process: another exception, a
// crash, a sanitizer report, a result that breaks the reader's promises (a non-finite
// coordinate, an index out of range, a field of the wrong length).
//
// The same functions serve libFuzzer (fuzz_main.cpp, one executable per target, built
// with -DMESHPDE_FUZZ=ON and clang) and the regression replay that ctest runs in every
// build (fuzz_replay.cpp over tests/fuzz/regressions/TARGET/). scripts/fuzz drives both.
#pragma once

#include <cstddef>
#include <cstdint>
#include <string>
#include <vector>

namespace meshpde::fuzz {

using TargetFunction = int (*)(const std::uint8_t* data, std::size_t size);

struct Target {
  std::string name;    ///< fuzz_NAME, tests/fuzz/regressions/NAME
  std::string what;    ///< the input, in words
  std::string suffix;  ///< the file suffix of its seeds (".obj", ".nii.gz", ...)
  TargetFunction run = nullptr;
};

/// Every target of this build: the core formats and files always, the medical
/// formats when meshpde::medical is built.
const std::vector<Target>& targets();
/// What the last call of a target refused the input with (meshpde's error message),
/// or empty if it read the input: the replay prints it.
const std::string& last_refusal();
/// The target called `name`, or nullptr.
const Target* find_target(const std::string& name);

}  // namespace meshpde::fuzz
