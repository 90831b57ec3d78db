// `nmbake tangents low.obj --view frames.png [--uv-view uv.png]`: the low
// mesh's MikkTSpace frames drawn over the shaded mesh, and its UV layout
// coloured by tangent with mirrored triangles hatched.
// `nmbake tangents low.fbx --write low_tangents.glb`: the low mesh with its
// MikkTSpace tangents as glTF TANGENT, so that an engine that imports
// tangents gets exactly the frame the map is baked in.
#include <cctype>
#include <cstdio>
#include <filesystem>

#include "commands.hpp"
#include "nmbake/image.hpp"
#include "nmbake/load.hpp"
#include "nmbake/preview.hpp"
#include "nmbake/tangents.hpp"

namespace nmbake::cli {

namespace {

struct TangentFlags {
  std::string low, view, uv_view, write;
  float length = 0.0f;
  int uv_size = 512;
  ViewFlags camera;
};

int fail(const Status& s) {
  print_error(s.message());
  return s.code() == StatusCode::internal ? kInternal : kBadInput;
}

int write_tangents(const TangentFlags& f, const GlobalOptions& global) {
  std::string extension = std::filesystem::path(f.write).extension().string();
  for (char& c : extension) c = static_cast<char>(std::tolower(static_cast<unsigned char>(c)));
  if (extension != ".gltf" && extension != ".glb") {
    std::fprintf(stderr, "nmbake: error: %s: tangents are written as glTF (.glb or .gltf)\n",
                 f.write.c_str());
    return kBadInput;
  }
  Mesh low;
  LoadStats load_stats;
  if (const Status s = load_mesh(f.low, LoadOptions{true, true}, low, load_stats); !s) return fail(s);
  if (!low.has_uvs())
    return fail(Status::bad_input(f.low + ": the low mesh has no UVs: MikkTSpace needs them"));
  // The normals the bake uses (prepare_low_normals), so the written frame is
  // the one the map was baked in.
  MeshStats mesh_stats;
  prepare_low_normals(low, mesh_stats);
  std::vector<glm::vec4> corner_tangents;
  TangentStats tangent_stats;
  compute_tangents(low, corner_tangents, tangent_stats);
  const Mesh out = vertex_tangent_mesh(low, corner_tangents);
  if (const Status s = save_mesh(f.write, out); !s) return fail(s);
  if (!global.quiet) {
    std::printf("tangents: %s: %zu vertices (%zu in %s), %zu triangles, %llu fallback tangents\n",
                f.write.c_str(), out.vertex_count(), low.vertex_count(), f.low.c_str(), out.triangle_count(),
                static_cast<unsigned long long>(tangent_stats.fallback_tangents));
  }
  return kSuccess;
}

int run_tangents(const TangentFlags& f, const GlobalOptions& global) {
  if (f.view.empty() && f.uv_view.empty() && f.write.empty()) {
    std::fprintf(
        stderr,
        "nmbake: error: nothing to do: give --view FILE.png, --uv-view FILE.png and/or --write FILE.glb\n");
    return kBadInput;
  }
  if (!f.write.empty()) {
    if (const int code = write_tangents(f, global); code != kSuccess) return code;
    if (f.view.empty() && f.uv_view.empty()) return kSuccess;
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
  CLI::App* cmd = app.add_subcommand("tangents",
                                     "draw a low mesh's tangent frames (T red, B green, N blue) and UV "
                                     "layout, or write them as glTF TANGENT");
  cmd->add_option("low", flags->low, "the low mesh (OBJ, PLY, glTF, FBX..., with UVs)")->required();
  cmd->add_option("--write", flags->write,
                  "write the low mesh with its MikkTSpace tangents as glTF TANGENT (.glb or .gltf)");
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
