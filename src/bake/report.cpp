// The bake report: every counter of every stage, as JSON and as one line.
#include <tbb/global_control.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <nlohmann/json.hpp>

#include "bake/map_report_json.hpp"
#include "bake/report_fill.hpp"
#include "nmbake/bake.hpp"
#include "nmbake/preset.hpp"

namespace nmbake {

nlohmann::ordered_json detail::map_reports_json(const std::vector<MapReport>& reports) {
  nlohmann::ordered_json out = nlohmann::ordered_json::array();
  for (const MapReport& m : reports) {
    nlohmann::ordered_json entry = {{"map", to_string(m.map)}, {"tile", m.tile}, {"outputs", m.outputs}};
    for (const auto& [name, value] : m.figures) entry[name] = value;
    out.push_back(entry);
  }
  return out;
}

double BakeReport::miss_rate() const {
  return trace.samples > 0 ? static_cast<double>(trace.misses) / static_cast<double>(trace.samples) : 0.0;
}

double BakeReport::rays_per_texel() const {
  return raster.covered_texels > 0
             ? static_cast<double>(trace.rays) / static_cast<double>(raster.covered_texels)
             : 0.0;
}

double BakeReport::coverage() const {
  const double texels = static_cast<double>(width) * static_cast<double>(height);
  return texels > 0.0 ? static_cast<double>(raster.covered_texels) / texels : 0.0;
}

namespace {

using nlohmann::ordered_json;

// Adaptive sampling's figures: rays of the first pass, each level's texels and rays.
ordered_json adaptive_json(const BakeReport& r) {
  ordered_json levels = ordered_json::array();
  const std::vector<int> level_samples =
      r.adaptive.max_samples > 4 ? std::vector<int>{4, r.adaptive.max_samples} : std::vector<int>{4};
  for (std::size_t l = 0; l < r.adaptive.level_texels.size() && l < level_samples.size(); ++l) {
    levels.push_back({{"samples", level_samples[l]},
                      {"texels", r.adaptive.level_texels[l]},
                      {"rays", r.adaptive.level_rays.size() > l ? r.adaptive.level_rays[l] : 0}});
  }
  return {{"max_samples", r.adaptive.max_samples},
          {"first_pass_rays", r.adaptive.first_pass_rays},
          {"refined_texels", r.adaptive.refined_texels},
          {"refined_fraction", r.raster.covered_texels > 0 ? static_cast<double>(r.adaptive.refined_texels) /
                                                                 static_cast<double>(r.raster.covered_texels)
                                                           : 0.0},
          {"levels", levels},
          {"halo_rays", r.adaptive.halo_rays},
          {"rays_per_texel", r.rays_per_texel()}};
}

// Every counted fallback of every stage (curvature's added by to_json() when baked).
ordered_json fallbacks_json(const BakeReport& r) {
  return {
      {"low_zero_area_triangles", r.low_mesh.zero_area_triangles},
      {"low_zero_length_normals", r.low_mesh.zero_length_normals},
      {"low_normals_computed", r.low_mesh.normals_computed},
      {"high_zero_area_triangles", r.high_mesh.zero_area_triangles},
      {"high_zero_length_normals", r.high_mesh.zero_length_normals},
      {"high_normals_computed", r.high_mesh.normals_computed},
      {"tangent_degenerate_triangles", r.tangents.degenerate_triangles},
      {"tangent_degenerate_uv_triangles", r.tangents.degenerate_uv_triangles},
      {"tangent_fallbacks", r.tangents.fallback_tangents},
      {"raster_degenerate_uv_triangles", r.raster.degenerate_uv_triangles},
      {"raster_border_samples", r.raster.border_samples},
      {"raster_overlapping_samples", r.raster.overlapping_samples},
      {"ray_fallbacks", r.trace.ray_fallbacks},
      {"encode_singular_frames", r.encode.singular_frames},
      {"encode_zero_high_normals", r.encode.zero_high_normals},
      {"encode_zero_results", r.encode.zero_results},
      {"encode_below_horizon", r.encode.below_horizon},
      {"dilate_filled_texels", r.dilate.filled_texels},
      {"load_skipped_faces", r.low_load.degenerate_faces + r.high_load.degenerate_faces},
  };
}

// The high's normal textures: only in the reports of bakes that read them
// (or looked and left some out), so every other report is as it was.
ordered_json high_normal_maps_json(const BakeReport& r) {
  return {{"on", r.high_normal_maps},
          {"materials", r.high_normal_textures},
          {"skipped_materials", r.high_normal_textures_skipped},
          {"samples", r.encode.high_normal_map_samples},
          {"tangent_seconds", r.high_tangent_seconds},
          {"unread_material_libraries", r.high_load.unread_material_libraries}};
}

// The counted fallbacks of the high's normal textures (fallbacks_json() adds them).
void add_high_normal_map_fallbacks(const BakeReport& r, ordered_json& fallbacks) {
  fallbacks["high_normal_map_no_uv"] = r.encode.high_normal_map_no_uv;
  fallbacks["high_normal_map_degenerate_tangent"] = r.encode.high_normal_map_degenerate_tangent;
  fallbacks["high_normal_map_zero_normal"] = r.encode.high_normal_map_zero_normal;
  fallbacks["high_normal_map_tile_missing"] = r.encode.high_normal_map_tile_missing;
  fallbacks["high_tangent_degenerate_triangles"] = r.high_tangents.degenerate_triangles;
  fallbacks["high_tangent_degenerate_uv_triangles"] = r.high_tangents.degenerate_uv_triangles;
  fallbacks["high_tangent_fallbacks"] = r.high_tangents.fallback_tangents;
}

// Every fallback of the high's normal textures, for the one-line summary.
std::uint64_t high_normal_map_fallbacks(const BakeReport& r) {
  return r.encode.high_normal_map_no_uv + r.encode.high_normal_map_degenerate_tangent +
         r.encode.high_normal_map_zero_normal + r.encode.high_normal_map_tile_missing +
         r.high_tangents.fallback_tangents;
}

ordered_json groups_json(const std::vector<BakeReport::Group>& groups) {
  ordered_json group_json = ordered_json::array();
  for (const BakeReport::Group& g : groups) {
    group_json.push_back({{"name", g.parts.name},
                          {"low_parts", g.parts.low_parts},
                          {"high_parts", g.parts.high_parts},
                          {"low_triangles", g.parts.low_triangles},
                          {"high_triangles", g.parts.high_triangles},
                          {"front", g.front},
                          {"back", g.back}});
  }
  return group_json;
}

// Each name under the key of what it names: "part" or "material".
ordered_json id_colors_json(IdSource id_source, const decltype(BakeReport::id_names)& id_names) {
  const char* what = to_string(id_source);
  ordered_json ids = ordered_json::array();
  for (const auto& [name, color] : id_names) {
    ids.push_back(
        {{what, name},
         {"rgb8",
          {std::lround(255.0f * color.r), std::lround(255.0f * color.g), std::lround(255.0f * color.b)}}});
  }
  return ids;
}

// How the map was encoded: the engine preset (if any) and the rules in
// force after explicit flags (README, "Outputs as engines want them").
ordered_json encoding_json(const BakeReport& r) {
  return {{"preset", r.preset.empty() ? ordered_json(nullptr) : ordered_json(r.preset)},
          {"green", r.green == GreenChannel::up ? "up" : "down"},
          {"bitangent", to_string(r.decode.bitangent)},
          {"tbn", word_of(kFrameRuleWords, r.decode.unit_frame)},
          {"blue", word_of(kBlueRuleWords, r.decode.rebuild_blue)},
          {"dither_8bit", r.dither}};
}

ordered_json distances_json(const BakeReport& r) {
  return {{"front", r.front},
          {"back", r.back},
          {"estimated", r.distances_estimated},
          {"low_bbox_diagonal", r.low_diagonal},
          {"probes", r.estimate_probes},
          {"probe_misses", r.estimate_probe_misses}};
}

ordered_json rays_json(const BakeReport& r) {
  return {{"samples_traced", r.trace.samples}, {"rays", r.trace.rays},         {"hits", r.trace.hits},
          {"misses", r.trace.misses},          {"miss_rate", r.miss_rate()},   {"cage", r.cage_mode},
          {"edge_band", r.edge_band},          {"retry_reach", r.retry_reach}, {"retried", r.trace.retried},
          {"retry_hits", r.trace.retry_hits}};
}

ordered_json udim_tiles_json(const std::vector<BakeReport::Tile>& tiles) {
  ordered_json tile_json = ordered_json::array();
  for (const BakeReport::Tile& t : tiles) {
    ordered_json one{{"tile", t.tile}};
    if (!t.set.empty()) one["set"] = t.set;  // a texture set's material (<SET>)
    one["outputs"] = t.outputs;
    one["covered_texels"] = t.covered_texels;
    tile_json.push_back(std::move(one));
  }
  return tile_json;
}

ordered_json stage_seconds_json(const std::vector<StageTime>& stages) {
  ordered_json stage_json = ordered_json::object();
  for (const StageTime& s : stages) stage_json[s.name] = s.seconds;
  return stage_json;
}

// Rays traced per second of the trace stage.
double rays_per_second(const BakeReport& r) {
  const double trace_seconds = [&] {
    for (const StageTime& s : r.stages)
      if (s.name == "trace") return s.seconds;
    return 0.0;
  }();
  return trace_seconds > 0.0 ? static_cast<double>(r.trace.rays) / trace_seconds : 0.0;
}

}  // namespace

std::string BakeReport::to_json() const {
  using nlohmann::ordered_json;
  ordered_json j;
  j["low"] = low_path;
  // One file: its path, as ever; several: the list.
  if (high_paths.size() == 1) {
    j["high"] = high_paths.front();
  } else {
    j["high"] = high_paths;
  }
  j["cage"] = cage_path;
  if (!input_files.empty()) j["input_files"] = input_files;  // MTL libraries, glTF buffers, textures
  j["outputs"] = outputs;
  j["width"] = width;
  j["height"] = height;
  if (adaptive.max_samples > 0) {
    j["samples_per_texel"] = "adaptive";
    j["adaptive"] = adaptive_json(*this);
  } else {
    j["samples_per_texel"] = samples;
  }
  j["threads"] = threads;
  j["low_triangles"] = low_triangles;
  j["high_triangles"] = high_triangles;
  j["high_vertices"] = high_vertices;
  j["bvh"] = compact_bvh ? "compact" : "fast";
  j["encoding"] = encoding_json(*this);
  j["distances"] = distances_json(*this);
  j["coverage"] = {{"covered_texels", raster.covered_texels}, {"fraction", coverage()}};
  j["rays"] = rays_json(*this);
  j["fallbacks"] = fallbacks_json(*this);
  const bool normal_textures_looked =
      high_normal_maps || high_normal_textures_skipped > 0 || high_load.unread_material_libraries > 0;
  if (normal_textures_looked) {
    add_high_normal_map_fallbacks(*this, j["fallbacks"]);
    j["high_normal_maps"] = high_normal_maps_json(*this);
  }
  if (!key.empty()) j["key"] = key;
  j["cached"] = cached;
  if (tile_count > 0) {
    j["tile"] = {{"index", tile_index + 1},
                 {"count", tile_count},
                 {"rows", {tile_row_begin, tile_row_end}},
                 {"file", tile_path}};
  }
  j["high_triangles_used"] = high_triangles_used;
  j["embree_scenes"] = scenes;
  j["groups"] = groups_json(groups);
  j["unused_high_parts"] = unused_high_parts;
  j["udim_tiles"] = udim_tiles_json(tiles);
  // Units as the files state them (FBX UnitScaleFactor, glTF metres); 0:
  // the format does not say. Positions are baked in file units.
  j["units"] = {{"low_unit_meters", low_load.unit_meters}, {"high_unit_meters", high_load.unit_meters}};
  if (unwrapped) {
    j["unwrap"] = ordered_json::parse(unwrap.to_json());
    j["unwrap"]["mesh"] = unwrapped_low_path;
  }
  // The map set: each map of each UDIM tile, with the ranges it used and
  // its counters (maps.hpp).
  j["maps"] = detail::map_reports_json(map_reports);
  if (!id_names.empty()) {
    j["id_source"] = to_string(id_source);
    j["id_colors"] = id_colors_json(id_source, id_names);
  }
  if (std::find(maps.begin(), maps.end(), MapKind::curvature) != maps.end()) {
    j["fallbacks"]["curvature_degenerate_triangles"] = curvature_degenerate_triangles;
    j["fallbacks"]["curvature_isolated_vertices"] = curvature_isolated_vertices;
  }
  j["seconds"] = stage_seconds_json(stages);
  j["total_seconds"] = total_seconds;
  j["rays_per_second"] = rays_per_second(*this);
  j["peak_rss_bytes"] = peak_rss_bytes;
  j["input_bytes"] = {{"low", low_load.bytes}, {"high", high_load.bytes}};
  j["load_mb_per_second"] = {{"low", low_load.mb_per_second()}, {"high", high_load.mb_per_second()}};
  // Metres per file unit where the file says (FBX UnitScaleFactor, glTF), 0
  // where it does not (OBJ, PLY); positions are baked in file units.
  j["unit_meters"] = {{"low", low_load.unit_meters}, {"high", high_load.unit_meters}};
  return j.dump(2) + "\n";
}

std::string BakeReport::summary_line() const {
  char line[512];
  double trace_seconds = 0.0;
  for (const StageTime& s : stages)
    if (s.name == "trace") trace_seconds = s.seconds;
  const double mrays_per_second =
      trace_seconds > 0.0 ? 1e-6 * static_cast<double>(trace.rays) / trace_seconds : 0.0;
  char spp[64];
  if (adaptive.max_samples > 0) {
    std::snprintf(spp, sizeof spp, "adaptive (1-%d spp, %.2f rays a texel)", adaptive.max_samples,
                  rays_per_texel());
  } else {
    std::snprintf(spp, sizeof spp, "x%d spp", samples);
  }
  std::snprintf(line, sizeof line,
                "baked %dx%d %s: %.1f%% texels covered, %llu rays (%.1f Mrays/s), %llu misses (%.3f%%), "
                "front %.4g back %.4g%s, %.2f s, peak %.0f MiB",
                width, height, spp, 100.0 * coverage(), static_cast<unsigned long long>(trace.rays),
                mrays_per_second, static_cast<unsigned long long>(trace.misses), 100.0 * miss_rate(), front,
                back, distances_estimated ? " (auto)" : "", total_seconds,
                static_cast<double>(peak_rss_bytes) / (1024.0 * 1024.0));
  std::string text = line;
  if (trace.retried > 0) {
    std::snprintf(line, sizeof line, "; %llu missed samples retried, %llu found a surface",
                  static_cast<unsigned long long>(trace.retried),
                  static_cast<unsigned long long>(trace.retry_hits));
    text += line;
  }
  if (!groups.empty()) {
    std::snprintf(line, sizeof line, "; %zu bake groups", groups.size());
    text += line;
    if (!unused_high_parts.empty()) {
      std::snprintf(line, sizeof line, " (%zu high parts in none, ignored)", unused_high_parts.size());
      text += line;
    }
  }
  if (maps.size() > 1 || (!maps.empty() && maps.front() != MapKind::normal)) {
    text += "; maps " + map_list_text(maps);
    std::uint64_t extra_rays = 0;
    double extra_seconds = 0.0;
    for (const MapReport& m : map_reports) {
      if (m.map == MapKind::ao || m.map == MapKind::thickness ||
          (m.map == MapKind::bent_normal && std::find(maps.begin(), maps.end(), MapKind::ao) == maps.end())) {
        extra_rays += static_cast<std::uint64_t>(m.figure("rays"));
      }
    }
    for (const StageTime& s : stages)
      if (s.name == "occlusion") extra_seconds = s.seconds;
    if (extra_rays > 0) {
      std::snprintf(line, sizeof line, " (+%llu rays from the hits, %.1f Mrays/s)",
                    static_cast<unsigned long long>(extra_rays),
                    extra_seconds > 0.0 ? 1e-6 * static_cast<double>(extra_rays) / extra_seconds : 0.0);
      text += line;
    }
    if (!id_names.empty()) {
      std::snprintf(line, sizeof line, "; id map of %zu %s%s", id_names.size(),
                    id_source == IdSource::vertex_color ? "vertex colour" : to_string(id_source),
                    id_names.size() == 1 ? "" : "s");
      text += line;
    }
  }
  if (high_normal_maps) {
    std::snprintf(line, sizeof line, "; high normal maps of %llu material%s on %llu samples (%llu fallbacks)",
                  static_cast<unsigned long long>(high_normal_textures), high_normal_textures == 1 ? "" : "s",
                  static_cast<unsigned long long>(encode.high_normal_map_samples),
                  static_cast<unsigned long long>(high_normal_map_fallbacks(*this)));
    text += line;
  }
  if (high_normal_textures_skipped > 0) {
    std::snprintf(line, sizeof line,
                  "; %llu high normal texture%s not read (embedded in the file, or --samples adaptive; "
                  "--high-normal-maps on refuses)",
                  static_cast<unsigned long long>(high_normal_textures_skipped),
                  high_normal_textures_skipped == 1 ? "" : "s");
    text += line;
  }
  if (tiles.size() > 1 || (!tiles.empty() && tiles.front().tile != 1001)) {
    std::snprintf(line, sizeof line, "; %zu UDIM tiles (%d to %d)", tiles.size(), tiles.front().tile,
                  tiles.back().tile);
    text += line;
  }
  if (low_load.unit_meters > 0.0 && high_load.unit_meters > 0.0 &&
      low_load.unit_meters != high_load.unit_meters) {
    std::snprintf(line, sizeof line, "; WARNING: low unit %g m, high unit %g m (positions are not rescaled)",
                  low_load.unit_meters, high_load.unit_meters);
    text += line;
  }
  if (unwrapped) {
    std::snprintf(line, sizeof line, "; no UVs: unwrapped into %llu charts (%.1f%% of the map), mesh %s",
                  static_cast<unsigned long long>(unwrap.chart_count), 100.0 * unwrap.utilization,
                  unwrapped_low_path.c_str());
    text += line;
  }
  return text;
}

}  // namespace nmbake

// How bake() fills the report (report_fill.hpp).
namespace nmbake::detail {

void report_options(const BakeOptions& o, BakeReport& r) {
  r = BakeReport{};
  r.low_path = o.low_path;
  r.high_paths = o.high_paths;
  r.cage_path = o.cage_path;
  for (const OutputSpec& out : o.outputs) r.outputs.push_back(out.path);
  r.width = o.width;
  r.height = o.height;
  r.samples = o.samples;
  r.preset = o.preset;
  r.green = o.encode.green;
  r.decode = o.encode.decode;
  r.dither = o.dither;
  r.threads = tbb::global_control::active_value(tbb::global_control::max_allowed_parallelism);
}

void report_mesh_sizes(const Mesh& low, const Mesh& high, BakeReport& r) {
  r.low_triangles = low.triangle_count();
  r.high_triangles = high.triangle_count();
  r.high_vertices = high.vertex_count();
}

void report_unwrapped(const std::string& path, BakeReport& r) {
  r.unwrapped = true;
  r.unwrapped_low_path = path;
}

void report_map_mesh(const MapMeshData& map_mesh, BakeReport& r) {
  r.high_tangents = map_mesh.transfer.tangent_stats;
  r.high_tangent_seconds = map_mesh.transfer.tangent_seconds;
  r.curvature_degenerate_triangles = map_mesh.curvature.degenerate_triangles;
  r.curvature_isolated_vertices = map_mesh.curvature.isolated_vertices;
  r.id_source = map_mesh.id_source;
  r.id_names = map_mesh.ids;
}

void report_low_surface(const SurfaceStats& stats, float low_diagonal, BakeReport& r) {
  r.low_mesh.zero_area_triangles += stats.mesh.zero_area_triangles;
  r.low_mesh.zero_length_normals += stats.mesh.zero_length_normals;
  r.tangents = stats.tangents;
  r.low_diagonal = low_diagonal;
}

void report_scene(const HighScene& scene, BakeReport& r) {
  r.compact_bvh = scene.compact();
  r.scenes = scene.scene_count();
}

void report_rays(const RayOptions& rays, const DistanceEstimate& estimate, bool estimated,
                 const BakeGroups& groups, BakeReport& r) {
  if (estimated) {
    r.distances_estimated = true;
    r.estimate_probes = estimate.probes;
    r.estimate_probe_misses = estimate.probe_misses;
  }
  r.cage_mode = to_string(rays.cage);
  r.edge_band = rays.cage == CageMode::banded ? rays.edge_band : 0.0f;
  r.retry_reach = rays.retry_reach;
  r.front = rays.front;
  r.back = rays.back;
  for (std::size_t g = 0; g < groups.groups.size(); ++g) {
    r.groups.push_back({groups.groups[g], rays.groups[g].front, rays.groups[g].back});
  }
  r.unused_high_parts = groups.unused_high_parts;
}

void report_map_set(const BakeOptions& o, BakeReport& r) {
  r.maps = o.maps;
  r.outputs.clear();
}

void report_raster_band(const RasterStats& band, BakeReport& r) {
  r.raster.covered_texels += band.covered_texels;
  r.raster.border_samples += band.border_samples;
  r.raster.overlapping_samples += band.overlapping_samples;
  r.raster.degenerate_uv_triangles = band.degenerate_uv_triangles;  // the same in every band
}

void report_tile_rows(const TileData& rows, const std::string& tile_path, BakeReport& r,
                      BakeReport::Tile& done) {
  r.tile_index = rows.index;
  r.tile_count = rows.count;
  r.tile_row_begin = rows.row_begin;
  r.tile_row_end = rows.row_end;
  r.tile_path = tile_path;
  r.outputs = {tile_path};
  done.outputs = {tile_path};
}

void report_finish(Clock::time_point begin, BakeReport& r) {
  r.total_seconds = std::chrono::duration<double>(Clock::now() - begin).count();
  r.peak_rss_bytes = peak_rss_bytes();
}

}  // namespace nmbake::detail
