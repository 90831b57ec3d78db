// Subcommands of the nmbake program. Each registers its options on the CLI11
// app and returns a function that runs it and gives the exit code.
#pragma once

#include <CLI/CLI.hpp>
#include <functional>
#include <initializer_list>
#include <map>
#include <string>
#include <string_view>
#include <vector>

#include "nmbake/common.hpp"
#include "nmbake/options.hpp"
#include "nmbake/preview.hpp"

namespace nmbake::cli {

// Exit codes (DESIGN.md).
enum ExitCode : int { kSuccess = 0, kGateFailed = 1, kBadInput = 2, kInternal = 3 };

struct GlobalOptions {
  int threads = 0;  // 0: all cores
  bool quiet = false;
  bool verbose = false;
};

using Runner = std::function<int()>;

// "nmbake: error: MESSAGE" on stderr, through printable_text(): a message
// may carry a path from a job file (a NUL must not cut it) or bytes of a
// broken file (which must not reach the terminal as escape codes).
void print_error(const std::string& message);

Runner add_bake_command(CLI::App& app, const GlobalOptions& global);
Runner add_preview_command(CLI::App& app, const GlobalOptions& global);
Runner add_diff_command(CLI::App& app, const GlobalOptions& global);
Runner add_height2normal_command(CLI::App& app, const GlobalOptions& global);
Runner add_tangents_command(CLI::App& app, const GlobalOptions& global);

// Camera flags shared by `preview` and `tangents` (preview_command.cpp).
struct ViewFlags {
  int size = 384;
  float yaw = 30.0f, pitch = 20.0f;
  std::string up = "y", light = "-0.55,0.6,0.6";
  int supersample = 3;
};
void add_view_flags(CLI::App* cmd, ViewFlags& flags, int default_size);
Status parse_view_flags(const ViewFlags& flags, ViewOptions& view);
// Rows of the option table (options.hpp) as flags: the words given per
// key, and the switches.
struct TableFlags {
  std::map<std::string, std::vector<std::string>, std::less<>> values;
  std::map<std::string, bool, std::less<>> switches;
};
// Registers the rows named in `keys` (every row when empty) on `cmd`.
void add_table_flags(CLI::App* cmd, TableFlags& flags, std::initializer_list<std::string_view> keys = {});
// Applies the flags given to `options` (apply_options()).
Status apply_table_flags(const TableFlags& flags, BakeOptions& options);

Runner add_unwrap_command(CLI::App& app, const GlobalOptions& global);
Runner add_merge_command(CLI::App& app, const GlobalOptions& global);  // merge_command.cpp
Runner add_plan_command(CLI::App& app, const GlobalOptions& global);   // plan_command.cpp
Runner add_serve_command(CLI::App& app, const GlobalOptions& global);  // serve_command.cpp
Runner add_view_command(CLI::App& app, const GlobalOptions& global);   // view_command.cpp

// `nmbake docs` (docs_command.cpp; not in --help): man pages, bash completion and
// the Markdown reference from the app's own definitions. Register it last.
Runner add_docs_command(CLI::App& app, const GlobalOptions& global);

// What `nmbake --version` prints (version.cpp).
std::string version_text();

}  // namespace nmbake::cli
