// The checks of a bake's options and inputs (bake_options.hpp): those that
// need no file, those that read the mesh files' first bytes, and those that
// load the low mesh.
#include "bake/validate.hpp"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <string>
#include <utility>
#include <vector>

#include "nmbake/bake_options.hpp"
#include "nmbake/image.hpp"
#include "nmbake/load.hpp"
#include "nmbake/maps.hpp"
#include "nmbake/parts.hpp"
#include "nmbake/sets.hpp"
#include "nmbake/udim.hpp"

namespace nmbake {

namespace {

std::string number_text(double value) {
  char text[32];
  std::snprintf(text, sizeof text, "%g", value);
  return text;
}

// The map set's options (maps.hpp).
Status check_output_spec(const OutputSpec& out);

// Packed outputs: their maps are baked, their files writable and named once
// (no map output or other pack resolves to the same path), whole bakes only.
Status check_packs(const BakeOptions& o) {
  std::vector<std::string> paths;
  for (const MapOutput& out : map_outputs(o)) {
    if (std::find(paths.begin(), paths.end(), out.path) != paths.end()) {
      return Status::bad_input(printable_text(out.path) + ": two outputs write this file");
    }
    paths.push_back(out.path);
  }
  for (const PackSpec& pack : o.packs) {
    const std::string text = "--pack '" + printable_text(pack_text(pack)) + "'";
    if (o.tile_count > 0)
      return Status::bad_input(text + ": packs are written by whole bakes, not by tiles (yet)");
    bool any_map = false;
    for (const PackChannel& c : pack.channels) {
      if (c.constant) continue;
      any_map = true;
      if (std::find(o.maps.begin(), o.maps.end(), c.map) == o.maps.end()) {
        return Status::bad_input(text + ": it packs " + to_string(c.map) + ", which --map does not bake (" +
                                 map_list_text(o.maps) + ")");
      }
    }
    if (!any_map) return Status::bad_input(text + ": a pack needs at least one map");
    if (pack.path.find('\0') != std::string::npos)
      return Status::bad_input(text + ": the path holds a NUL byte");
    OutputSpec spec;
    spec.path = pack.path;
    spec.format = pack_format(pack.path);
    PixelFormat from_path = PixelFormat::png8;
    if (!pixel_format_from_path(pack.path, from_path)) {
      return Status::bad_input(text + ": " + printable_text(pack.path) +
                               ": a packed file is .png or .tga (8-bit), .tif (16-bit) or .exr (float)");
    }
    NMBAKE_TRY(check_output_spec(spec));
    if (std::find(paths.begin(), paths.end(), pack.path) != paths.end()) {
      return Status::bad_input(text + ": " + printable_text(pack.path) +
                               " is also written by another output");
    }
    paths.push_back(pack.path);
  }
  return Status::ok();
}

// A path token that makes a file per tile or set must be in every output
// and pack: one without it would be written once per tile or set, each
// time over the last. <LOW> must have been resolved (resolve_low_token()).
Status check_path_tokens(const BakeOptions& o) {
  std::vector<std::string> paths;
  for (const OutputSpec& out : o.outputs) paths.push_back(out.path);
  for (const PackSpec& pack : o.packs) paths.push_back(pack.path);
  for (const std::string& path : paths) {
    if (path.find(kLowToken) != std::string::npos) {
      return Status::bad_input(printable_text(path) +
                               ": <LOW> is not resolved (the command line and job files " +
                               "resolve it with the low file's name)");
    }
  }
  for (const char* token : {kUdimToken, kSetToken}) {
    const auto holds = [&](const std::string& p) { return p.find(token) != std::string::npos; };
    if (!std::any_of(paths.begin(), paths.end(), holds)) continue;
    for (const std::string& path : paths) {
      if (!holds(path)) {
        return Status::bad_input(printable_text(path) + ": other outputs hold " + token + " (a file per " +
                                 (std::string(token) == kSetToken ? "texture set" : "UV tile") +
                                 "), so this one would be written once for each, over the last: add " +
                                 token);
      }
    }
  }
  return Status::ok();
}

Status validate_map_set(const BakeOptions& o) {
  if (o.maps.empty()) return Status::bad_input("no map to bake (--map)");
  for (const MapKind map : o.maps) {
    if (!map_traits(map).implemented)
      return Status::bad_input(std::string("--map ") + to_string(map) + ": not implemented yet");
  }
  NMBAKE_TRY(check_map_tokens(o.outputs, o.maps));
  for (const MapOutput& out : map_outputs(o)) {
    if (const Status target = check_output_target(out.path); !target)
      return Status::bad_input(target.message());
  }
  NMBAKE_TRY(check_path_tokens(o));
  NMBAKE_TRY(check_packs(o));
  const auto check_range = [](const char* name, float value) {
    if (!(value >= 0.0f) || !std::isfinite(value)) {
      return Status::bad_input(std::string(name) + " " + number_text(value) +
                               " is out of range: a number > 0, or auto");
    }
    return Status::ok();
  };
  NMBAKE_TRY(check_range("--height-range", o.height_range));
  NMBAKE_TRY(check_range("--curvature-range", o.curvature_range));
  for (const auto& [name, rays] :
       {std::pair{"--ao-rays", o.ao_rays}, std::pair{"--thickness-rays", o.thickness_rays}}) {
    if (rays < 1 || rays > kMaxOcclusionRays) {
      return Status::bad_input(std::string(name) + " " + std::to_string(rays) + " is out of range (1 to " +
                               std::to_string(kMaxOcclusionRays) + ")");
    }
  }
  for (const auto& [name, d] :
       {std::pair{"--ao-distance", o.ao_distance}, std::pair{"--thickness-distance", o.thickness_distance}}) {
    if (d.kind != Distance::Kind::automatic && !(d.value > 0.0f)) {
      return Status::bad_input(std::string(name) + " " + to_string(d) +
                               " is out of range: a distance > 0, N% or auto");
    }
    if (d.kind == Distance::Kind::absolute && !(d.value <= kMaxDistance)) {
      return Status::bad_input(std::string(name) + " " + number_text(d.value) + " is out of range: at most " +
                               number_text(kMaxDistance) + " scene units");
    }
    if (d.kind == Distance::Kind::percent && !(d.value <= 100.0f * kMaxDistanceDiagonals)) {
      return Status::bad_input(std::string(name) + " " + number_text(d.value) +
                               "% is out of range: at most " + number_text(100.0f * kMaxDistanceDiagonals) +
                               "% of the low mesh's diagonal");
    }
  }
  if (!o.id_palette.empty() && o.id_source == IdSource::vertex_color) {
    return Status::bad_input(
        "--id-palette colours parts or materials by name; --id-source vertex-color takes "
        "the colours as painted");
  }
  if (o.adaptive && (o.maps.size() != 1 || o.maps.front() != MapKind::normal)) {
    return Status::bad_input("--samples adaptive bakes the normal map alone; the map set (" +
                             map_list_text(o.maps) + ") needs a fixed sample count (1, 4, 16 or 64)");
  }
  if (o.adaptive && o.high_normal_maps == HighNormalMaps::on) {
    return Status::bad_input(
        "--samples adaptive does not read the high's normal textures yet: --high-normal-maps on needs a "
        "fixed sample count (1, 4, 16 or 64)");
  }
  return Status::ok();
}

// The sample count, or adaptive sampling's levels and thresholds.
Status check_sampling(const BakeOptions& o) {
  if (o.adaptive) {
    const int m = o.adaptive_options.max_samples;
    if (m != 4 && m != 16 && m != 64) {
      return Status::bad_input("--adaptive-max " + std::to_string(m) + " is not supported: use 4, 16 or 64");
    }
    const AdaptiveOptions& a = o.adaptive_options;
    for (const float t : {a.normal_threshold, a.depth_threshold, a.border_threshold, a.spread_threshold}) {
      if (!(t >= 0.0f) || !std::isfinite(t))
        return Status::bad_input("adaptive thresholds must be finite and >= 0");
    }
  } else if (!is_supported_sample_count(o.samples)) {
    return Status::bad_input("--samples " + std::to_string(o.samples) +
                             " is not supported: use 1, 4, 16 or 64");
  }
  return Status::ok();
}

// The rays' options against kMaxDistance and kMaxDistanceDiagonals (against
// the diagonal itself once the low mesh is loaded: check_distance()).
Status check_ray_limits(const RaySettings& rays) {
  const auto check_limit = [](const char* name, const Distance& d) {
    if (d.kind == Distance::Kind::absolute && !(d.value <= kMaxDistance)) {
      return Status::bad_input(std::string(name) + " distance " + number_text(d.value) +
                               " is out of range: at most " + number_text(kMaxDistance) + " scene units");
    }
    if (d.kind == Distance::Kind::percent && !(d.value <= 100.0f * kMaxDistanceDiagonals)) {
      return Status::bad_input(std::string(name) + " distance " + number_text(d.value) +
                               "% is out of range: at most " + number_text(100.0f * kMaxDistanceDiagonals) +
                               "% of the low mesh's diagonal");
    }
    return Status::ok();
  };
  if (!(rays.edge_band >= 0.0f && rays.edge_band <= 100.0f)) {
    return Status::bad_input("--edge-band " + number_text(rays.edge_band) + " is out of range (0 to 100)");
  }
  NMBAKE_TRY(check_limit("front", rays.front));
  NMBAKE_TRY(check_limit("back", rays.back));
  return Status::ok();
}

// One output: a path the file system takes as given, a format its extension
// allows, an existing folder, a writer that can be loaded.
Status check_output_spec(const OutputSpec& out) {
  // The file system would see the path cut at the NUL: another file.
  if (out.path.find('\0') != std::string::npos) {
    return Status::bad_input(printable_text(out.path) + ": the output path holds a NUL byte");
  }
  if (const Status target = check_output_target(out.path); !target)
    return Status::bad_input(target.message());
  if (!format_matches_extension(out.format, out.path)) {
    return Status::bad_input(out.path + ": format " + to_string(out.format) +
                             " cannot be written to a file with this extension");
  }
  std::filesystem::path folder = std::filesystem::path(out.path).parent_path();
  if (folder.empty()) folder = ".";
  std::error_code ec;
  if (!std::filesystem::is_directory(folder, ec)) {
    return Status::bad_input(out.path + ": the output folder " + folder.string() + " does not exist");
  }
  // TIFF needs the OpenImageIO module: known before the bake, not after.
  if (const Status writer = check_image_writer(out.format); !writer) {
    return Status::internal(out.path + ": " + writer.message());  // names the output once
  }
  return Status::ok();
}

}  // namespace

namespace detail {

// Resolved distances against the low mesh's diagonal (kMaxDistanceDiagonals).
// A zero diagonal (every low vertex in one place) has only kMaxDistance.
Status check_distance(const char* name, const Distance& d, float diagonal) {
  const double limit = static_cast<double>(kMaxDistanceDiagonals) * diagonal;
  if (d.kind != Distance::Kind::absolute || diagonal <= 0.0f || d.value <= limit) return Status::ok();
  return Status::bad_input(std::string(name) + " distance " + number_text(d.value) +
                           " is out of range: at most " + number_text(kMaxDistanceDiagonals) +
                           " times the low mesh's diagonal " + number_text(diagonal) + " = " +
                           number_text(limit) + " scene units");
}

// How bake() loads the low mesh; check_bake_low_mesh() loads it the same way.
LoadOptions low_load_options(const BakeOptions& o) {
  LoadOptions options{true, true};
  options.uv_set = o.uv_set;
  options.keep_tangents = o.tangent_basis == TangentBasis::file;
  return options;
}

bool bakes_texture_sets(const BakeOptions& o) {
  return std::any_of(o.outputs.begin(), o.outputs.end(),
                     [](const OutputSpec& out) { return has_set_token(out.path); }) ||
         std::any_of(o.packs.begin(), o.packs.end(), [](const PackSpec& p) { return has_set_token(p.path); });
}

bool bakes_udim_tiles(const BakeOptions& o) {
  return std::any_of(o.outputs.begin(), o.outputs.end(),
                     [](const OutputSpec& out) { return has_udim_token(out.path); });
}

}  // namespace detail

Status validate_option_values(const BakeOptions& o) {
  constexpr int kMaxSize = 32768;
  if (o.width <= 0 || o.height <= 0 || o.width > kMaxSize || o.height > kMaxSize) {
    return Status::bad_input("map size " + std::to_string(o.width) + "x" + std::to_string(o.height) +
                             " is out of range: width and height must be 1 to " + std::to_string(kMaxSize));
  }
  NMBAKE_TRY(check_sampling(o));
  // Against the map size only when an unwrap happens (bake()): a small map
  // of a mesh with UVs must not be refused for a gutter it never uses.
  if (o.unwrap_gutter < 0) {
    return Status::bad_input("unwrap gutter " + std::to_string(o.unwrap_gutter) +
                             " is out of range (0 to size / 4)");
  }
  NMBAKE_TRY(check_ray_limits(o.rays));
  if (o.padding < 0 || o.padding > 4096) {
    return Status::bad_input("--padding " + std::to_string(o.padding) + " is out of range (0 to 4096)");
  }
  if (o.uv_set < 0 || o.uv_set > 7) {
    return Status::bad_input("--uv-set " + std::to_string(o.uv_set) + " is out of range (0 to 7)");
  }
  if (o.groups_per_scene < 0 || o.groups_per_scene > 32) {
    return Status::bad_input("--groups-per-scene " + std::to_string(o.groups_per_scene) +
                             " is out of range (0 to 32)");
  }
  return Status::ok();
}

Status validate_options(const BakeOptions& o) {
  if (o.low_path.empty()) return Status::bad_input("no low mesh given (--low)");
  if (o.high_paths.empty()) return Status::bad_input("no high mesh given (--high)");
  if (o.outputs.empty()) return Status::bad_input("no output map given (-o)");
  NMBAKE_TRY(validate_option_values(o));
  for (const OutputSpec& out : o.outputs) NMBAKE_TRY(check_output_spec(out));
  return validate_map_set(o);
}

Status check_bake_inputs(const BakeOptions& o) {
  NMBAKE_TRY(check_mesh_file("low", o.low_path));
  for (const std::string& high : o.high_paths) NMBAKE_TRY(check_mesh_file("high", high));
  if (!o.cage_path.empty()) NMBAKE_TRY(check_mesh_file("cage", o.cage_path));
  if (!o.id_palette.empty() && std::find(o.maps.begin(), o.maps.end(), MapKind::id) != o.maps.end()) {
    IdPalette palette;
    NMBAKE_TRY(read_id_palette(o.id_palette, palette));
  }
  if (o.debug_dump_prefix.find('\0') != std::string::npos) {
    return Status::bad_input(printable_text(o.debug_dump_prefix) + ": the debug-dump path holds a NUL byte");
  }
  return Status::ok();
}

Status check_bake_low_mesh(const BakeOptions& o) {
  Mesh low;
  LoadStats stats;
  NMBAKE_TRY(load_mesh(o.low_path, detail::low_load_options(o), low, stats));
  NMBAKE_TRY(check_low_parts(low, o.match, o.low_path));
  // A low mesh without UVs is unwrapped into [0, 1]^2: one tile, whatever
  // the outputs say.
  if (low.has_uvs()) {
    std::vector<int> tiles;
    NMBAKE_TRY(find_udim_tiles(low, o.low_path, detail::bakes_udim_tiles(o), tiles));
  }
  if (detail::bakes_texture_sets(o)) {
    std::vector<LowSet> sets;
    NMBAKE_TRY(find_low_sets(low, o.low_path, sets));
  }
  return Status::ok();
}

}  // namespace nmbake
