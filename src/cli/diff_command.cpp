// `nmbake diff`: the regression-bake gate. Exit 0 within the bounds, 1 when a
// bound is exceeded (the message names it), 2 on bad input.
#include <cstdio>
#include <fstream>
#include <memory>
#include <string>

#include "commands.hpp"
#include "nmbake/diff.hpp"
#include "nmbake/job.hpp"

namespace nmbake::cli {

namespace {

struct DiffFlags {
  std::string a, b, mask, heatmap, json, green_b = "up";
  double max_mean = -1.0, max_p99 = -1.0, max_max = -1.0;  // < 0: no bound
  float heatmap_max = 5.0f;
};

int run_diff(const DiffFlags& f, const GlobalOptions& global) {
  auto fail = [](const Status& s) {
    print_error(s.message());
    return s.code() == StatusCode::internal ? kInternal : kBadInput;
  };
  DiffOptions options;
  if (!parse_word(f.green_b, options.green_b)) {
    std::fprintf(stderr, "nmbake: error: --green-b %s: expected up or down\n", f.green_b.c_str());
    return kBadInput;
  }
  options.heatmap_max_degrees = f.heatmap_max;
  if (!f.heatmap.empty()) {
    PixelFormat format;
    if (!pixel_format_from_path(f.heatmap, format)) {
      std::fprintf(stderr, "nmbake: error: --heatmap %s: expected a .png, .tif or .exr path\n",
                   f.heatmap.c_str());
      return kBadInput;
    }
  }
  DiffStats stats;
  Image heatmap;
  const Status status = diff_files(f.a, f.b, f.mask, options, stats, f.heatmap.empty() ? nullptr : &heatmap);
  if (!status) return fail(status);
  if (!f.heatmap.empty()) {
    PixelFormat format = PixelFormat::png8;
    if (!format_matches_extension(format, f.heatmap)) pixel_format_from_path(f.heatmap, format);
    const Status written = write_image(heatmap, f.heatmap, format);
    if (!written) return fail(written);
  }
  if (!f.json.empty()) {
    std::ofstream out(f.json, std::ios::binary | std::ios::trunc);
    out << stats.to_json() << "\n";
    if (!out) {
      std::fprintf(stderr, "nmbake: error: %s: cannot write the JSON report\n", f.json.c_str());
      return kBadInput;
    }
  }
  if (!global.quiet) std::printf("%s\n", stats.summary_line().c_str());

  int code = kSuccess;
  auto bound = [&code](const char* name, double value, double limit) {
    if (limit >= 0.0 && value > limit) {
      std::fprintf(stderr, "nmbake: diff gate failed: %s %.4f deg > --max-%s %.4f deg\n", name, value, name,
                   limit);
      code = kGateFailed;
    }
  };
  bound("mean", stats.mean, f.max_mean);
  bound("p99", stats.p99, f.max_p99);
  bound("max", stats.max, f.max_max);
  return code;
}

}  // namespace

Runner add_diff_command(CLI::App& app, const GlobalOptions& global) {
  auto flags = std::make_shared<DiffFlags>();
  CLI::App* cmd =
      app.add_subcommand("diff", "compare two normal maps by angle; exit 1 when a bound is exceeded");
  cmd->add_option("a", flags->a, "first map (any format OpenImageIO reads)")->required();
  cmd->add_option("b", flags->b, "second map, same size")->required();
  cmd->add_option("--mask", flags->mask, "compare only texels whose first channel is > 0.5");
  cmd->add_option("--max-mean", flags->max_mean, "exit 1 when the mean angle exceeds this (degrees)")
      ->check(CLI::NonNegativeNumber);
  cmd->add_option("--max-p99", flags->max_p99, "exit 1 when the 99th percentile exceeds this (degrees)")
      ->check(CLI::NonNegativeNumber);
  cmd->add_option("--max-max", flags->max_max, "exit 1 when the largest angle exceeds this (degrees)")
      ->check(CLI::NonNegativeNumber);
  cmd->add_option("--heatmap", flags->heatmap, "write the angle as a heat map (black-blue-yellow-red)");
  cmd->add_option("--heatmap-max", flags->heatmap_max, "degrees at the red end of the heat map")
      ->default_val(5.0f)
      ->check(CLI::PositiveNumber);
  cmd->add_option("--json", flags->json, "write the statistics as JSON");
  cmd->add_option("--green-b", flags->green_b,
                  "down: flip the second map's green before comparing (OpenGL vs DirectX)")
      ->default_val("up");
  return [flags, &global]() { return run_diff(*flags, global); };
}

}  // namespace nmbake::cli
