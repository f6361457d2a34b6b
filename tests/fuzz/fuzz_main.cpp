// libFuzzer's entry points for one target, chosen when the executable is built
// (MESHPDE_FUZZ_TARGET, a string): fuzz_obj, fuzz_vtp, ...
#include <cstdio>
#include <cstdlib>

#include "fuzz_targets.h"
#include "meshpde/core/warnings.h"

namespace {
const meshpde::fuzz::Target* target = nullptr;
}

extern "C" int LLVMFuzzerInitialize(int*, char***) {
  target = meshpde::fuzz::find_target(MESHPDE_FUZZ_TARGET);
  if (!target) {
    std::fprintf(stderr, "fuzz: no target '%s' in this build\n", MESHPDE_FUZZ_TARGET);
    std::exit(2);
  }
  return 0;
}

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  // Warnings (a far @X,Y,Z, ...) are collected and dropped: printed, one an input, they
  // would slow the run and bury its report.
  const meshpde::WarningCollector quiet;
  return target->run(data, size);
}
