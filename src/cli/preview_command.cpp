// `nmbake preview`: look at a bake. With --map only: the map lit per pixel.
// With --low and --high too: the 3D sheet [high | low + map | error] of
// preview.hpp, one row per view.
#include <cstdio>
#include <sstream>

#include "commands.hpp"
#include "nmbake/image.hpp"
#include "nmbake/job.hpp"
#include "nmbake/preset.hpp"
#include "nmbake/preview.hpp"

namespace nmbake::cli {

namespace {

bool parse_direction(const std::string& text, glm::vec3& out) {
  std::istringstream in(text);
  glm::vec3 v(0.0f);
  char comma = 0;
  if (!(in >> v.x >> comma) || comma != ',' || !(in >> v.y >> comma) || comma != ',' || !(in >> v.z))
    return false;
  in >> std::ws;
  if (!in.eof()) return false;
  out = v;
  return true;
}

}  // namespace

Status parse_view_flags(const ViewFlags& f, ViewOptions& view) {
  view.size = f.size;
  view.yaw_degrees = f.yaw;
  view.pitch_degrees = f.pitch;
  view.supersample = f.supersample;
  if (f.up == "y") {
    view.up = UpAxis::y;
  } else if (f.up == "z") {
    view.up = UpAxis::z;
  } else {
    return Status::bad_input("--up " + f.up + ": expected y or z");
  }
  if (!parse_direction(f.light, view.light)) {
    return Status::bad_input("--light " + f.light + ": expected X,Y,Z (camera space, towards the light)");
  }
  return validate_view_options(view);
}

void add_view_flags(CLI::App* cmd, ViewFlags& f, int default_size) {
  f.size = default_size;
  cmd->add_option("--size", f.size, "pixels per side of a panel")->default_val(default_size);
  cmd->add_option("--yaw", f.yaw, "camera turn around the up axis, degrees")->default_val(30.0f);
  cmd->add_option("--pitch", f.pitch, "camera elevation, degrees (-89 to 89)")->default_val(20.0f);
  cmd->add_option("--up", f.up, "the scene's up axis: y | z")->default_val("y");
  cmd->add_option("--light", f.light, "key light X,Y,Z in camera space (x right, y up, z to the viewer)")
      ->default_val("-0.55,0.6,0.6");
  cmd->add_option("--aa", f.supersample, "antialiasing: k x k samples per pixel (1 to 8)")->default_val(3);
}

namespace {

struct PreviewFlags {
  std::string map, output, low, high;
  // How the map was baked: the bake's own options (options.hpp).
  TableFlags baked;
  int max_size = 1024;
  int turntable = 1;
  float heat_max = 5.0f;
  ViewFlags view;
};

int fail(const Status& s) {
  print_error(s.message());
  return s.code() == StatusCode::internal ? kInternal : kBadInput;
}

int run_preview_3d(const PreviewFlags& f, const GlobalOptions& global, const Image& map) {
  PreviewOptions options;
  if (const Status s = parse_view_flags(f.view, options.view); !s) return fail(s);
  options.turntable = f.turntable;
  options.heat_max_degrees = f.heat_max;
  // How the map was baked, read as `bake` reads it.
  BakeOptions baked;
  if (const Status s = apply_table_flags(f.baked, baked); !s) return fail(s);
  options.green = baked.encode.green;
  options.decode = baked.encode.decode;
  options.space = baked.encode.space;
  options.rays = baked.rays;
  Mesh low, high;
  LowSurface surface;
  if (const Status s = load_preview_meshes(f.low, f.high, low, surface, high); !s) return fail(s);
  Image sheet;
  PreviewStats stats;
  if (const Status s = render_preview(surface, high, map, options, sheet, stats); !s) return fail(s);
  if (const Status s = write_image(sheet, f.output, PixelFormat::png8); !s) return fail(s);
  if (!global.quiet) {
    std::printf(
        "preview: %s (%dx%d, %zu view%s): error mean %.3f deg, p99 %.3f deg, max %.2f deg over %llu samples",
        f.output.c_str(), sheet.width, sheet.height, stats.views.size(), stats.views.size() == 1 ? "" : "s",
        stats.all.mean_degrees, stats.all.p99_degrees, stats.all.max_degrees,
        static_cast<unsigned long long>(stats.all.low_samples - stats.all.bake_misses));
    if (stats.all.bake_misses > 0) {
      std::printf(", %llu bake-ray misses", static_cast<unsigned long long>(stats.all.bake_misses));
    }
    std::printf("\n");
    if (global.verbose) {
      std::printf("preview: front %.5g back %.5g; decode fallbacks %llu, high normal fallbacks %llu\n",
                  stats.front, stats.back, static_cast<unsigned long long>(stats.decode_fallbacks),
                  static_cast<unsigned long long>(stats.high_normal_fallbacks));
      for (const PreviewViewStats& v : stats.views) {
        std::printf("preview: yaw %7.2f: mean %.3f p99 %.3f max %.2f deg, %llu samples, %llu misses\n",
                    v.yaw_degrees, v.mean_degrees, v.p99_degrees, v.max_degrees,
                    static_cast<unsigned long long>(v.low_samples),
                    static_cast<unsigned long long>(v.bake_misses));
      }
    }
  }
  return kSuccess;
}

int run_preview(const PreviewFlags& f, const GlobalOptions& global) {
  PixelFormat format;
  if (!pixel_format_from_path(f.output, format)) {
    std::fprintf(stderr, "nmbake: error: %s: unknown image extension (use .png, .tif, .exr)\n",
                 f.output.c_str());
    return kBadInput;
  }
  if (format == PixelFormat::png16) format = PixelFormat::png8;
  const bool three_d = !f.low.empty() || !f.high.empty();
  if (three_d && (f.low.empty() || f.high.empty())) {
    std::fprintf(stderr,
                 "nmbake: error: the 3D preview needs both --low and --high (or neither, for the lit map)\n");
    return kBadInput;
  }
  if (three_d && format != PixelFormat::png8) {
    std::fprintf(stderr, "nmbake: error: %s: the 3D preview is written as PNG (.png)\n", f.output.c_str());
    return kBadInput;
  }
  Image map;
  if (const Status s = read_image(f.map, map); !s) return fail(s);
  if (map.channels < 3) {
    std::fprintf(stderr, "nmbake: error: %s: a normal map needs 3 channels, this image has %d\n",
                 f.map.c_str(), map.channels);
    return kBadInput;
  }
  if (three_d) return run_preview_3d(f, global, map);

  LitMapOptions options;
  BakeOptions baked;  // the green convention, as `bake` reads it (a preset's, or --green)
  if (const Status s = apply_table_flags(f.baked, baked); !s) return fail(s);
  options.green = baked.encode.green;
  options.max_size = f.max_size;
  const Image lit = render_lit_map(map, options);
  if (const Status s = write_image(lit, f.output, format); !s) return fail(s);
  if (!global.quiet) std::printf("preview: %s (%dx%d)\n", f.output.c_str(), lit.width, lit.height);
  return kSuccess;
}

}  // namespace

Runner add_preview_command(CLI::App& app, const GlobalOptions& global) {
  auto flags = std::make_shared<PreviewFlags>();
  CLI::App* cmd = app.add_subcommand("preview",
                                     "look at a bake: the map lit per pixel (--map only), or with "
                                     "--low/--high the sheet [high | low+map | error]");
  cmd->add_option("--map", flags->map, "the normal map")->required();
  cmd->add_option("-o,--output", flags->output, "the preview image (.png: 8-bit)")->required();
  cmd->add_option("--max-size", flags->max_size, "lit map only: longest side of the preview")
      ->default_val(1024)
      ->check(CLI::Range(16, 16384));
  cmd->add_option("--low", flags->low, "3D: the low mesh the map was baked for (OBJ, PLY, with UVs)");
  cmd->add_option("--high", flags->high, "3D: the high mesh it was baked from");
  // How the map was baked (3D: all of them; the lit map: green and preset),
  // the rows of `bake`'s own option table.
  add_table_flags(
      cmd, flags->baked,
      {"space", "preset", "green", "bitangent", "tbn", "blue", "front", "back", "hit", "cage_mode"});
  cmd->add_option("--turntable", flags->turntable, "3D: views in the sheet, one row each, yaw + 360 k / N")
      ->default_val(1)
      ->check(CLI::Range(1, 64));
  cmd->add_option("--heat-max", flags->heat_max, "3D: degrees at the top of the error colour ramp")
      ->default_val(5.0f);
  add_view_flags(cmd, flags->view, 384);
  return [flags, &global]() { return run_preview(*flags, global); };
}

}  // namespace nmbake::cli
