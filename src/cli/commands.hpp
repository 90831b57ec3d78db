// Subcommands of the nmbake program. Each registers its options on the CLI11
// app and returns a function that runs it and gives the exit code.
#pragma once

#include <functional>

#include <CLI/CLI.hpp>

namespace nmbake::cli {

// Exit codes (DESIGN.md).
enum ExitCode : int { kSuccess = 0, kGateFailed = 1, kBadInput = 2, kInternal = 3 };

struct GlobalOptions {
  int threads = 0;  // 0: all cores
  bool quiet = false;
  bool verbose = false;
};

using Runner = std::function<int()>;

Runner add_bake_command(CLI::App& app, const GlobalOptions& global);
Runner add_preview_command(CLI::App& app, const GlobalOptions& global);
Runner add_unwrap_command(CLI::App& app, const GlobalOptions& global);

}  // namespace nmbake::cli
