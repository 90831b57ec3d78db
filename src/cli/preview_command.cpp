// `nmbake preview`: the normal map lit per pixel, to look at a bake.
#include <cstdio>

#include "commands.hpp"
#include "nmbake/image.hpp"
#include "nmbake/job.hpp"
#include "nmbake/preview.hpp"

namespace nmbake::cli {

namespace {

struct PreviewFlags {
  std::string map, output, green = "up";
  int max_size = 1024;
};

int run_preview(const PreviewFlags& f, const GlobalOptions& global) {
  LitMapOptions options;
  if (!parse_green_channel(f.green, options.green)) {
    std::fprintf(stderr, "nmbake: error: --green %s: expected up or down\n", f.green.c_str());
    return kBadInput;
  }
  options.max_size = f.max_size;
  PixelFormat format;
  if (!pixel_format_from_path(f.output, format)) {
    std::fprintf(stderr, "nmbake: error: %s: unknown image extension (use .png, .tif, .exr)\n", f.output.c_str());
    return kBadInput;
  }
  if (format == PixelFormat::png16) format = PixelFormat::png8;
  Image map;
  if (const Status s = read_image(f.map, map); !s) {
    std::fprintf(stderr, "nmbake: error: %s\n", s.message().c_str());
    return kBadInput;
  }
  if (map.channels < 3) {
    std::fprintf(stderr, "nmbake: error: %s: a normal map needs 3 channels, this image has %d\n", f.map.c_str(), map.channels);
    return kBadInput;
  }
  const Image lit = render_lit_map(map, options);
  if (const Status s = write_image(lit, f.output, format); !s) {
    std::fprintf(stderr, "nmbake: error: %s\n", s.message().c_str());
    return s.code() == StatusCode::internal ? kInternal : kBadInput;
  }
  if (!global.quiet) std::printf("preview: %s (%dx%d)\n", f.output.c_str(), lit.width, lit.height);
  return kSuccess;
}

}  // namespace

Runner add_preview_command(CLI::App& app, const GlobalOptions& global) {
  auto flags = std::make_shared<PreviewFlags>();
  CLI::App* cmd = app.add_subcommand("preview", "render a tangent-space normal map lit per pixel (Blinn-Phong), to PNG");
  cmd->add_option("--map", flags->map, "the normal map")->required();
  cmd->add_option("-o,--output", flags->output, "the preview image (.png: 8-bit)")->required();
  cmd->add_option("--green", flags->green, "the map's green convention: up | down")->default_val("up");
  cmd->add_option("--max-size", flags->max_size, "longest side of the preview")->default_val(1024)->check(CLI::Range(16, 16384));
  return [flags, &global]() { return run_preview(*flags, global); };
}

}  // namespace nmbake::cli
