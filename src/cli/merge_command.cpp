// `nmbake merge TILE... [-o map.png ...]`: the tiles of one bake (`nmbake
// bake --tile I/N`) into its maps (every map of a map set), finished and
// written as the whole bake would write them, byte for byte.
#include <cstdio>

#include "commands.hpp"
#include "nmbake/cleanup.hpp"
#include "nmbake/task.hpp"

namespace nmbake::cli {

namespace {

struct MergeFlags {
  std::vector<std::string> tiles, outputs, expected;
  std::string format, report;
};

int run_merge(const MergeFlags& f, const GlobalOptions& global) {
  std::vector<OutputSpec> outputs;
  for (const std::string& path : f.outputs) {
    OutputSpec out;
    out.path = path;
    out.format_given = !f.format.empty();  // else `.png` takes each map's own depth, as in the bake
    const bool ok =
        f.format.empty() ? pixel_format_from_path(path, out.format) : parse_word(f.format, out.format);
    if (!ok) {
      print_error(path + ": unknown image extension or --format");
      return kBadInput;
    }
    outputs.push_back(out);
  }
  MergeReport report;
  const Status s = merge_tiles(f.tiles, outputs, report, f.expected);
  if (!s) {
    print_error(s.message());
    return s.code() == StatusCode::internal ? kInternal : kBadInput;
  }
  if (!f.report.empty()) {
    Status written = check_output_target(f.report);
    if (written) written = write_file_atomically(f.report, {report.to_json()}, "the report");
    if (!written) {
      print_error(written.message());
      return kBadInput;
    }
  }
  if (!global.quiet) {
    std::printf("merged %d tiles of %dx%d (key %s) into", report.tiles, report.width, report.height,
                report.key.hex().c_str());
    // The paths may come from a tile file: no escape codes reach the terminal.
    for (const std::string& o : report.outputs) std::printf(" %s", printable_text(o).c_str());
    std::printf(": read %.3f s, dilate %.3f s, write %.3f s\n", report.read_seconds, report.dilate_seconds,
                report.write_seconds);
  }
  return kSuccess;
}

}  // namespace

Runner add_merge_command(CLI::App& app, const GlobalOptions& global) {
  auto flags = std::make_shared<MergeFlags>();
  CLI::App* cmd =
      app.add_subcommand("merge", "merge the tile files of one bake (bake --tile I/N) into its maps");
  cmd->add_option("tiles", flags->tiles, "every tile file of the bake, in any order")->required();
  cmd->add_option("-o,--output", flags->outputs,
                  "output map(s), with <MAP> for a map set (default: the maps the bake names)")
      ->allow_extra_args(false);
  cmd->add_option("--format", flags->format, "png8 | png16 | tiff16 | exr-half | exr-float | exr-float-piz");
  cmd->add_option("--report", flags->report, "write the merge report (JSON) here");
  cmd->add_option(
         "--expect-output", flags->expected,
         "the outputs the tiles must name, in order (a plan's merge task gives them): written wherever they "
         "are; tiles naming others are refused")
      ->allow_extra_args(false);
  return [flags, &global]() { return run_merge(*flags, global); };
}

}  // namespace nmbake::cli
