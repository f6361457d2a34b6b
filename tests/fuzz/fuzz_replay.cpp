// Replays inputs through a fuzz target without libFuzzer, in any build (ctest runs it
// over tests/fuzz/regressions/TARGET/ in the Release and the sanitizer builds).
//   meshpde_fuzz_replay TARGET FILE|DIR...   replay (a directory: every file in it)
//   meshpde_fuzz_replay --list               the targets of this build: name, suffix, what
//   meshpde_fuzz_replay --seeds DIR          writes seed inputs, DIR/TARGET/NAME
// Exit 0 when every input was read or refused in words; a broken promise aborts.
#include <algorithm>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <string>
#include <vector>

#include "fuzz_seeds.h"
#include "fuzz_targets.h"

int main(int argc, char** argv) {
  namespace fs = std::filesystem;
  if (argc == 2 && std::string(argv[1]) == "--list") {
    for (const auto& t : meshpde::fuzz::targets())
      std::printf("%s %s %s\n", t.name.c_str(), t.suffix.c_str(), t.what.c_str());
    return 0;
  }
  if (argc == 3 && std::string(argv[1]) == "--seeds") {
    std::printf("%d seeds written under %s\n", meshpde::fuzz::write_seeds(argv[2]), argv[2]);
    return 0;
  }
  if (argc < 3) {
    std::fprintf(stderr, "usage: %s TARGET FILE|DIR... | --list | --seeds DIR\n", argv[0]);
    return 2;
  }
  const auto* target = meshpde::fuzz::find_target(argv[1]);
  if (!target) {
    std::fprintf(stderr, "no target '%s' in this build (--list shows them)\n", argv[1]);
    return 2;
  }
  std::vector<fs::path> inputs;
  for (int k = 2; k < argc; ++k) {
    const fs::path p(argv[k]);
    if (fs::is_directory(p)) {
      for (const auto& e : fs::directory_iterator(p))
        if (e.is_regular_file()) inputs.push_back(e.path());
    } else if (fs::is_regular_file(p)) {
      inputs.push_back(p);
    } else {
      std::fprintf(stderr, "%s: no such file or directory\n", p.c_str());
      return 2;
    }
  }
  std::sort(inputs.begin(), inputs.end());
  for (const auto& p : inputs) {
    std::ifstream in(p, std::ios::binary);
    const std::string bytes((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
    target->run(reinterpret_cast<const std::uint8_t*>(bytes.data()), bytes.size());
    const std::string& refusal = meshpde::fuzz::last_refusal();
    std::fprintf(stderr, "%s: %s (%zu bytes): %s%s\n", target->name.c_str(), p.filename().c_str(), bytes.size(),
                 refusal.empty() ? "read" : "refused: ", refusal.substr(0, 200).c_str());
  }
  std::printf("%s: %zu inputs replayed, none crashed\n", target->name.c_str(), inputs.size());
  return 0;
}
