// `nmbake tangents low.obj --view frames.png [--uv-view uv.png]`: the low
// mesh's MikkTSpace frames drawn over the shaded mesh, and its UV layout
// coloured by tangent with mirrored triangles hatched.
#include <cstdio>

#include "commands.hpp"
#include "nmbake/image.hpp"
#include "nmbake/preview.hpp"

namespace nmbake::cli {

namespace {

struct TangentFlags {
  std::string low, view, uv_view;
  float length = 0.0f;
  int uv_size = 512;
  ViewFlags camera;
};

int fail(const Status& s) {
  print_error(s.message());
  return s.code() == StatusCode::internal ? kInternal : kBadInput;
}

int run_tangents(const TangentFlags& f, const GlobalOptions& global) {
  if (f.view.empty() && f.uv_view.empty()) {
    std::fprintf(stderr, "nmbake: error: nothing to draw: give --view FILE.png and/or --uv-view FILE.png\n");
    return kBadInput;
  }
  for (const std::string* path : {&f.view, &f.uv_view}) {
    if (!path->empty() && !format_matches_extension(PixelFormat::png8, *path)) {
      std::fprintf(stderr, "nmbake: error: %s: tangent views are written as PNG (.png)\n", path->c_str());
      return kBadInput;
    }
  }
  TangentViewOptions options;
  options.length = f.length;
  if (const Status s = parse_view_flags(f.camera, options.view); !s) return fail(s);
  Mesh low, unused;
  LowSurface surface;
  if (const Status s = load_preview_meshes(f.low, "", low, surface, unused); !s) return fail(s);
  TangentViewStats stats;
  if (!f.view.empty()) {
    Image image;
    if (const Status s = render_tangent_frames(surface, options, image, stats); !s) return fail(s);
    if (const Status s = write_image(image, f.view, PixelFormat::png8); !s) return fail(s);
    if (!global.quiet) {
      std::printf("tangents: %s (%dx%d): %llu frames, %llu mirrored triangles of %zu\n", f.view.c_str(),
                  image.width, image.height, static_cast<unsigned long long>(stats.frames),
                  static_cast<unsigned long long>(stats.mirrored_triangles), surface.triangle_count());
    }
  }
  if (!f.uv_view.empty()) {
    Image image;
    if (const Status s = render_uv_layout(surface, f.uv_size, image, stats); !s) return fail(s);
    if (const Status s = write_image(image, f.uv_view, PixelFormat::png8); !s) return fail(s);
    if (!global.quiet) {
      std::printf("tangents: %s (%dx%d): %llu mirrored triangles of %zu\n", f.uv_view.c_str(), image.width,
                  image.height, static_cast<unsigned long long>(stats.mirrored_triangles),
                  surface.triangle_count());
    }
  }
  return kSuccess;
}

}  // namespace

Runner add_tangents_command(CLI::App& app, const GlobalOptions& global) {
  auto flags = std::make_shared<TangentFlags>();
  CLI::App* cmd = app.add_subcommand(
      "tangents", "draw a low mesh's tangent frames (T red, B green, N blue) and UV layout");
  cmd->add_option("low", flags->low, "the low mesh (OBJ, PLY, with UVs)")->required();
  cmd->add_option("--view", flags->view, "the shaded mesh with its frames (.png)");
  cmd->add_option("--uv-view", flags->uv_view,
                  "the UV layout coloured by tangent, mirrored triangles hatched (.png)");
  cmd->add_option("--uv-size", flags->uv_size, "pixels per side of the UV view")->default_val(512);
  cmd->add_option("--length", flags->length,
                  "length of the drawn vectors, scene units (0: 40% of the mean edge)")
      ->default_val(0.0f);
  add_view_flags(cmd, flags->camera, 512);
  return [flags, &global]() { return run_tangents(*flags, global); };
}

}  // namespace nmbake::cli
