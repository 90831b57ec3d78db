// The bake report: every counter of every stage, as JSON and as one line.
#include <algorithm>
#include <cmath>
#include <cstdio>

#include <nlohmann/json.hpp>

#include "bake/map_report_json.hpp"
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

std::string BakeReport::to_json() const {
  using nlohmann::ordered_json;
  ordered_json j;
  j["low"] = low_path;
  j["high"] = high_path;
  j["cage"] = cage_path;
  j["outputs"] = outputs;
  j["width"] = width;
  j["height"] = height;
  if (adaptive.max_samples > 0) {
    j["samples_per_texel"] = "adaptive";
    ordered_json levels = ordered_json::array();
    const std::vector<int> level_samples =
        adaptive.max_samples > 4 ? std::vector<int>{4, adaptive.max_samples} : std::vector<int>{4};
    for (std::size_t l = 0; l < adaptive.level_texels.size() && l < level_samples.size(); ++l) {
      levels.push_back({{"samples", level_samples[l]},
                        {"texels", adaptive.level_texels[l]},
                        {"rays", adaptive.level_rays.size() > l ? adaptive.level_rays[l] : 0}});
    }
    j["adaptive"] = {
        {"max_samples", adaptive.max_samples},
        {"first_pass_rays", adaptive.first_pass_rays},
        {"refined_texels", adaptive.refined_texels},
        {"refined_fraction", raster.covered_texels > 0 ? static_cast<double>(adaptive.refined_texels) /
                                                             static_cast<double>(raster.covered_texels)
                                                       : 0.0},
        {"levels", levels},
        {"halo_rays", adaptive.halo_rays},
        {"rays_per_texel", rays_per_texel()}};
  } else {
    j["samples_per_texel"] = samples;
  }
  j["threads"] = threads;
  j["low_triangles"] = low_triangles;
  j["high_triangles"] = high_triangles;
  j["high_vertices"] = high_vertices;
  j["bvh"] = compact_bvh ? "compact" : "fast";
  // How the map was encoded: the engine preset (if any) and the rules in
  // force after explicit flags (README, "Outputs as engines want them").
  j["encoding"] = {{"preset", preset.empty() ? ordered_json(nullptr) : ordered_json(preset)},
                   {"green", green == GreenChannel::up ? "up" : "down"},
                   {"bitangent", to_string(decode.bitangent)},
                   {"tbn", word_of(kFrameRuleWords, decode.unit_frame)},
                   {"blue", word_of(kBlueRuleWords, decode.rebuild_blue)},
                   {"dither_8bit", dither}};
  j["distances"] = {{"front", front},
                    {"back", back},
                    {"estimated", distances_estimated},
                    {"low_bbox_diagonal", low_diagonal},
                    {"probes", estimate_probes},
                    {"probe_misses", estimate_probe_misses}};
  j["coverage"] = {{"covered_texels", raster.covered_texels}, {"fraction", coverage()}};
  j["rays"] = {{"samples_traced", trace.samples},
               {"rays", trace.rays},
               {"hits", trace.hits},
               {"misses", trace.misses},
               {"miss_rate", miss_rate()},
               {"cage", cage_mode},
               {"edge_band", edge_band},
               {"retry_reach", retry_reach},
               {"retried", trace.retried},
               {"retry_hits", trace.retry_hits}};
  j["fallbacks"] = {
      {"low_zero_area_triangles", low_mesh.zero_area_triangles},
      {"low_zero_length_normals", low_mesh.zero_length_normals},
      {"low_normals_computed", low_mesh.normals_computed},
      {"high_zero_area_triangles", high_mesh.zero_area_triangles},
      {"high_zero_length_normals", high_mesh.zero_length_normals},
      {"high_normals_computed", high_mesh.normals_computed},
      {"tangent_degenerate_triangles", tangents.degenerate_triangles},
      {"tangent_degenerate_uv_triangles", tangents.degenerate_uv_triangles},
      {"tangent_fallbacks", tangents.fallback_tangents},
      {"raster_degenerate_uv_triangles", raster.degenerate_uv_triangles},
      {"raster_border_samples", raster.border_samples},
      {"raster_overlapping_samples", raster.overlapping_samples},
      {"ray_fallbacks", trace.ray_fallbacks},
      {"encode_singular_frames", encode.singular_frames},
      {"encode_zero_high_normals", encode.zero_high_normals},
      {"encode_zero_results", encode.zero_results},
      {"encode_below_horizon", encode.below_horizon},
      {"dilate_filled_texels", dilate.filled_texels},
      {"load_skipped_faces", low_load.degenerate_faces + high_load.degenerate_faces},
  };
  if (!key.empty()) j["key"] = key;
  j["cached"] = cached;
  if (tile_count > 0) {
    j["tile"] = {{"index", tile_index + 1}, {"count", tile_count}, {"rows", {tile_row_begin, tile_row_end}},
                 {"file", tile_path}};
  }
  j["high_triangles_used"] = high_triangles_used;
  j["embree_scenes"] = scenes;
  ordered_json group_json = ordered_json::array();
  for (const Group& g : groups) {
    group_json.push_back({{"name", g.parts.name},
                          {"low_parts", g.parts.low_parts},
                          {"high_parts", g.parts.high_parts},
                          {"low_triangles", g.parts.low_triangles},
                          {"high_triangles", g.parts.high_triangles},
                          {"front", g.front},
                          {"back", g.back}});
  }
  j["groups"] = group_json;
  j["unused_high_parts"] = unused_high_parts;
  ordered_json tile_json = ordered_json::array();
  for (const Tile& t : tiles) {
    tile_json.push_back({{"tile", t.tile}, {"outputs", t.outputs}, {"covered_texels", t.covered_texels}});
  }
  j["udim_tiles"] = tile_json;
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
    // Each name under the key of what it names: "part" or "material".
    const char* what = to_string(id_source);
    ordered_json ids = ordered_json::array();
    for (const auto& [name, color] : id_names) {
      ids.push_back(
          {{what, name},
           {"rgb8",
            {std::lround(255.0f * color.r), std::lround(255.0f * color.g), std::lround(255.0f * color.b)}}});
    }
    j["id_source"] = what;
    j["id_colors"] = ids;
  }
  if (std::find(maps.begin(), maps.end(), MapKind::curvature) != maps.end()) {
    j["fallbacks"]["curvature_degenerate_triangles"] = curvature_degenerate_triangles;
    j["fallbacks"]["curvature_isolated_vertices"] = curvature_isolated_vertices;
  }
  ordered_json stage_json = ordered_json::object();
  for (const StageTime& s : stages) stage_json[s.name] = s.seconds;
  j["seconds"] = stage_json;
  j["total_seconds"] = total_seconds;
  const double trace_seconds = [&] {
    for (const StageTime& s : stages)
      if (s.name == "trace") return s.seconds;
    return 0.0;
  }();
  j["rays_per_second"] = trace_seconds > 0.0 ? static_cast<double>(trace.rays) / trace_seconds : 0.0;
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
                  static_cast<unsigned long long>(trace.retried), static_cast<unsigned long long>(trace.retry_hits));
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
          (m.map == MapKind::bent_normal &&
           std::find(maps.begin(), maps.end(), MapKind::ao) == maps.end())) {
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
      std::snprintf(line, sizeof line, "; id map of %zu %s%s", id_names.size(), to_string(id_source),
                    id_names.size() == 1 ? "" : "s");
      text += line;
    }
  }
  if (tiles.size() > 1 || (!tiles.empty() && tiles.front().tile != 1001)) {
    std::snprintf(line, sizeof line, "; %zu UDIM tiles (%d to %d)", tiles.size(), tiles.front().tile,
                  tiles.back().tile);
    text += line;
  }
  if (low_load.unit_meters > 0.0 && high_load.unit_meters > 0.0 && low_load.unit_meters != high_load.unit_meters) {
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
