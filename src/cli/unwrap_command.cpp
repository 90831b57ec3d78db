// `nmbake unwrap`: a low mesh in, the same mesh with a generated UV atlas out.
#include <unistd.h>

#include <cstdio>
#include <fstream>

#include "commands.hpp"
#include "nmbake/cleanup.hpp"
#include "nmbake/load.hpp"
#include "nmbake/unwrap.hpp"

namespace nmbake::cli {

namespace {

struct UnwrapFlags {
  std::string input, output, report;
  int size = 2048;
  int gutter = 4;
  float max_deviation = ChartOptions{}.max_normal_deviation_deg;
  bool no_rotate = false;
};

int fail(const Status& s) {
  print_error(s.message());
  return s.code() == StatusCode::internal ? kInternal : kBadInput;
}

Status write_text_atomically(const std::string& path, const std::string& text) {
  // The pid keeps two processes writing the same report apart.
  NMBAKE_TRY(check_output_target(path));
  const std::string tmp = path + ".tmp" + std::to_string(::getpid());
  const TempFileGuard guard(tmp);
  {
    std::ofstream out(tmp, std::ios::binary | std::ios::trunc);
    out << text;
    // flush(): a full disk shows when the buffer is written, not at <<.
    if (!out.flush()) {
      out.close();
      std::remove(tmp.c_str());
      return Status::io(path + ": cannot write the report");
    }
  }
  if (std::rename(tmp.c_str(), path.c_str()) != 0) {
    std::remove(tmp.c_str());
    return Status::io(path + ": cannot write the report");
  }
  return Status::ok();
}

int run_unwrap(const UnwrapFlags& f, const GlobalOptions& global) {
  UnwrapOptions options;
  options.pack.resolution = f.size;
  options.pack.gutter = f.gutter;
  options.pack.rotate = !f.no_rotate;
  options.chart.max_normal_deviation_deg = f.max_deviation;
  Mesh in, out;
  LoadStats load_stats;
  if (const Status s = load_mesh(f.input, LoadOptions{true, true}, in, load_stats); !s) return fail(s);
  UnwrapReport report;
  if (const Status s = check_coordinate_range(in, f.input); !s) return fail(s);
  // unwrap_mesh() does not know the file: its messages get the input's name.
  if (const Status s = unwrap_mesh(in, options, out, report); !s) {
    return fail(Status::bad_input(f.input + ": " + s.message()));
  }
  if (const Status s = save_mesh(f.output, out); !s) return fail(s);
  if (!f.report.empty()) {
    if (const Status s = write_text_atomically(f.report, report.to_json()); !s) return fail(s);
  }
  if (!global.quiet) std::printf("%s: %s\n", f.output.c_str(), report.summary_line().c_str());
  if (global.verbose) {
    std::printf("  charts %8.3f s\n  lscm   %8.3f s\n  pack   %8.3f s (%d attempts)\n", report.seconds_charts,
                report.seconds_parameterize, report.seconds_pack, report.pack_attempts);
  }
  return kSuccess;
}

}  // namespace

Runner add_unwrap_command(CLI::App& app, const GlobalOptions& global) {
  auto flags = std::make_shared<UnwrapFlags>();
  CLI::App* cmd = app.add_subcommand("unwrap", "generate a UV atlas for a low mesh (charts, LSCM, packing)");
  cmd->add_option("input", flags->input,
                  "the low mesh (OBJ, PLY); existing UV seams are kept as chart boundaries")
      ->required();
  cmd->add_option("-o,--output", flags->output, "the mesh with UVs (.obj or .ply)")->required();
  cmd->add_option("--size", flags->size, "atlas size in texels (the map size it is made for)")
      ->default_val(2048)
      ->check(CLI::Range(8, 32768));
  cmd->add_option("--gutter", flags->gutter, "free texels between charts")
      ->default_val(4)
      ->check(CLI::Range(0, 1024));
  cmd->add_option("--max-deviation", flags->max_deviation, "largest normal deviation within a chart, degrees")
      ->default_val(flags->max_deviation)
      ->check(CLI::Range(1.0f, 179.0f));
  cmd->add_flag("--no-rotate", flags->no_rotate, "do not turn charts by 90 degrees when packing");
  cmd->add_option("--report", flags->report, "write the unwrap report (JSON) here");
  return [flags, &global]() { return run_unwrap(*flags, global); };
}

}  // namespace nmbake::cli
