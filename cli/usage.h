// One exit-status rule for the command-line front ends (meshpde, meshpde-mpi):
// 0 done (--help and --version too), 1 bad input or a failure, 2 a usage error (an
// unknown command or option, a missing one, a value of the wrong kind), each error
// on stderr as "PROGRAM: error: ...".
#pragma once

#include <fmt/format.h>

#include <CLI/CLI.hpp>
#include <string>

namespace meshpde::cli {

/// Reports a parse error of `app` (the program's top level, run as argv) and returns
/// the exit status: help and version are printed as CLI11 prints them (0).
inline int usage_error(const CLI::App& app, const CLI::ParseError& e, const char* program, int argc, char** argv) {
  if (e.get_exit_code() == 0) return app.exit(e);
  std::string message = e.what();
  if (dynamic_cast<const CLI::RequiredError*>(&e) && message.find("subcommand") != std::string::npos) {
    // CLI11 says only "A subcommand is required", also for a misspelt one.
    const std::string first = argc > 1 ? argv[1] : "";
    const bool named = !first.empty() && first[0] != '-' &&
                       app.get_subcommands([&](const CLI::App* s) { return s->check_name(first); }).empty();
    message = named ? fmt::format("unknown command '{}'", first) : std::string("a command is required");
    message += fmt::format(" ({} --help lists the commands)", program);
  }
  fmt::print(stderr, "{}: error: {}\nRun with --help for more information.\n", program, message);
  return 2;
}

}  // namespace meshpde::cli
