// The bake report: every counter of every stage, as JSON and as one line.
#include <cstdio>

#include <nlohmann/json.hpp>

#include "nmbake/bake.hpp"

namespace nmbake {

double BakeReport::miss_rate() const {
  return trace.samples > 0 ? static_cast<double>(trace.misses) / static_cast<double>(trace.samples) : 0.0;
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
  j["samples_per_texel"] = samples;
  j["threads"] = threads;
  j["low_triangles"] = low_triangles;
  j["high_triangles"] = high_triangles;
  j["high_vertices"] = high_vertices;
  j["bvh"] = compact_bvh ? "compact" : "fast";
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
  const double mrays_per_second = trace_seconds > 0.0 ? 1e-6 * static_cast<double>(trace.rays) / trace_seconds : 0.0;
  std::snprintf(line, sizeof line,
                "baked %dx%d x%d spp: %.1f%% texels covered, %llu rays (%.1f Mrays/s), %llu misses (%.3f%%), "
                "front %.4g back %.4g%s, %.2f s, peak %.0f MiB",
                width, height, samples, 100.0 * coverage(), static_cast<unsigned long long>(trace.rays),
                mrays_per_second, static_cast<unsigned long long>(trace.misses), 100.0 * miss_rate(), front, back,
                distances_estimated ? " (auto)" : "", total_seconds,
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
