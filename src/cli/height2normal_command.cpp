// `nmbake height2normal`: a height map (or a cube sphere's six faces) to a
// normal map.
#include <cstdio>
#include <memory>
#include <string>
#include <vector>

#include "commands.hpp"
#include "nmbake/height2normal.hpp"
#include "nmbake/job.hpp"
#include "nmbake/load.hpp"

namespace nmbake::cli {

namespace {

struct Height2NormalFlags {
  std::vector<std::string> inputs;
  std::string output, format, border = "clamp", green = "up", space, low;
  float strength = 1.0f;
  bool cube_sphere = false;
  float gutter = -1.0f;  // < 0: the default of the layout
  int padding = 16;
};

int fail(const Status& status) {
  print_error(status.message());
  return status.code() == StatusCode::internal ? kInternal : kBadInput;
}

int usage_error(const std::string& message) {
  print_error(message);
  return kBadInput;
}

int run_height2normal(const Height2NormalFlags& f, const GlobalOptions& global) {
  PixelFormat format;
  if (!f.format.empty()) {
    if (!parse_word(f.format, format)) return usage_error("--format " + f.format + ": unknown format");
    if (!format_matches_extension(format, f.output)) {
      return usage_error("--format " + f.format + " cannot be written to " + f.output);
    }
  } else if (!pixel_format_from_path(f.output, format)) {
    return usage_error(f.output + ": expected a .png, .tif/.tiff or .exr output");
  }
  GreenChannel green;
  if (!parse_word(f.green, green)) return usage_error("--green " + f.green + ": expected up or down");

  Image out;
  HeightToNormalStats stats;
  if (!f.cube_sphere) {
    if (f.inputs.size() != 1)
      return usage_error("height2normal takes one height map (six only with --cube-sphere)");
    if (!f.space.empty() && f.space != "tangent")
      return usage_error("--space: a flat height map gives a tangent-space map");
    if (!f.low.empty()) return usage_error("--low is only used with --cube-sphere");
    HeightToNormalOptions options;
    options.strength = f.strength;
    options.green = green;
    if (!parse_word(f.border, options.border))
      return usage_error("--border " + f.border + ": expected clamp or wrap");
    Image height;
    const Status read = read_image(f.inputs[0], height);
    if (!read) return fail(read);
    out = height_to_normal(height, options, stats);
  } else {
    if (f.inputs.size() != 1 && f.inputs.size() != 6) {
      return usage_error("--cube-sphere takes one 3x2 atlas or six face maps (+X -X +Y -Y +Z -Z)");
    }
    CubeSphereOptions options;
    options.strength = f.strength;
    options.green = green;
    options.padding = f.padding;
    const std::string space = f.space.empty() ? "object" : f.space;
    if (!parse_word(space, options.space))
      return usage_error("--space " + space + ": expected tangent or object");
    Image atlas;
    if (f.inputs.size() == 6) {
      std::vector<Image> faces(6);
      for (std::size_t i = 0; i < 6; ++i) {
        const Status read = read_image(f.inputs[i], faces[i]);
        if (!read) return fail(read);
      }
      const Status assembled = assemble_cube_atlas(faces, atlas);
      if (!assembled) return fail(assembled);
      options.uv_gutter = 0.0f;
    } else {
      const Status read = read_image(f.inputs[0], atlas);
      if (!read) return fail(read);
    }
    if (f.gutter >= 0.0f) options.uv_gutter = f.gutter;

    Mesh low;
    LowSurface surface;
    if (options.space == NormalSpace::tangent) {
      if (f.low.empty())
        return usage_error("--space tangent with --cube-sphere needs --low (the low cube sphere with UVs)");
      LoadStats load_stats;
      const Status loaded = load_mesh(f.low, LoadOptions{true, true}, low, load_stats);
      if (!loaded) return fail(loaded);
      if (!low.has_uvs()) return usage_error(f.low + ": the low mesh has no UV coordinates");
      MeshStats mesh_stats;
      prepare_low_normals(low, mesh_stats);
      SurfaceStats surface_stats;
      surface = build_low_surface(low, nullptr, surface_stats);
    } else if (!f.low.empty()) {
      return usage_error("--low is only used with --space tangent");
    }
    const Status made = cube_sphere_height_to_normal(
        atlas, options, options.space == NormalSpace::tangent ? &surface : nullptr, out, stats);
    if (!made) return fail(made);
  }
  const Status written = write_image(out, f.output, format);
  if (!written) return fail(written);
  if (!global.quiet) {
    std::printf(
        "height2normal: %s %dx%d; one-sided differences %llu, flat %llu, clamped radii %llu, "
        "degenerate normals %llu, singular frames %llu, texels outside charts %llu (dilated %llu)\n",
        f.output.c_str(), out.width, out.height, static_cast<unsigned long long>(stats.one_sided_texels),
        static_cast<unsigned long long>(stats.flat_texels),
        static_cast<unsigned long long>(stats.clamped_radii),
        static_cast<unsigned long long>(stats.degenerate_normals),
        static_cast<unsigned long long>(stats.singular_frames),
        static_cast<unsigned long long>(stats.uncovered_texels),
        static_cast<unsigned long long>(stats.dilate.filled_texels));
  }
  return kSuccess;
}

}  // namespace

Runner add_height2normal_command(CLI::App& app, const GlobalOptions& global) {
  auto flags = std::make_shared<Height2NormalFlags>();
  CLI::App* cmd =
      app.add_subcommand("height2normal", "turn a height map (or a cube sphere's faces) into a normal map");
  cmd->add_option("heights", flags->inputs,
                  "height map (first channel); with --cube-sphere a 3x2 atlas or six faces")
      ->required();
  cmd->add_option("-o,--output", flags->output, "normal map: .png (16-bit), .tif, .exr")->required();
  cmd->add_option(
      "--format", flags->format,
      "png8 | png16 | tiff16 | exr-half | exr-float | exr-float-piz (default: from the extension)");
  cmd->add_option("--strength", flags->strength,
                  "S: slope = S * height difference per texel; cube sphere: radius = R (1 + S h)")
      ->default_val(1.0f);
  cmd->add_option("--border", flags->border, "clamp (one-sided differences at the edges) | wrap (tiling)")
      ->default_val("clamp");
  cmd->add_option("--green", flags->green, "up (OpenGL) | down (DirectX)")->default_val("up");
  cmd->add_flag("--cube-sphere", flags->cube_sphere,
                "the heights of a cube-sphere planet (3x2 atlas as nmbake-gen lays it out)");
  cmd->add_option("--space", flags->space, "cube sphere: object (default) | tangent (needs --low)");
  cmd->add_option("--low", flags->low,
                  "cube sphere, tangent space: the low cube sphere with UVs in this atlas");
  cmd->add_option("--gutter", flags->gutter,
                  "cube sphere: chart inset in UV units (default 0.01 for an atlas, 0 for six faces)")
      ->check(CLI::Range(0.0, 0.1666));
  cmd->add_option("--padding", flags->padding,
                  "cube sphere, tangent space: texels of dilation past the charts")
      ->default_val(16)
      ->check(CLI::Range(0, 4096));
  return [flags, &global]() { return run_height2normal(*flags, global); };
}

}  // namespace nmbake::cli
