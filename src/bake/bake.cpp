// The pipeline, in one function: load -> prepare -> raster -> trace ->
// encode -> dilate -> write. Each stage is a free function of its own header;
// this file only wires them, times them and collects their counters.
#include "nmbake/bake.hpp"

#include "bake/adaptive_rows.hpp"
#include "bake/debug_images.hpp"
#include "bake/pipeline.hpp"
#include "bake/validate.hpp"
#include "nmbake/budget.hpp"
#include "nmbake/maps.hpp"
#include "nmbake/task.hpp"
#include "nmbake/udim.hpp"

#include <chrono>
#include <cmath>
#include <algorithm>
#include <filesystem>
#include <memory>
#include <string>

#include <tbb/global_control.h>
#include <tbb/info.h>

namespace nmbake {

using detail::AdaptiveRows;
using detail::Clock;
using detail::DebugImages;
using detail::Prepared;
using detail::StageTimer;
using detail::peak_rss_bytes;

namespace {

// High normals: the file's, normalised, or area-weighted ones.
void prepare_high_normals(Mesh& mesh, MeshStats& stats) {
  if (mesh.has_normals()) {
    normalize_normals(mesh, stats);
  } else {
    compute_vertex_normals(mesh, stats);
  }
}

}  // namespace

// About 1M samples a band, so the per-sample arrays (28 bytes a sample, ~28
// MB) stay in the last-level cache between raster, trace and encode, and a
// bake first-touches little fresh memory (slow on these virtual machines,
// BENCHMARKS.md). With the trace no longer split into progress batches
// without a listener, a band costs little: at 2048^2 16 spp, 64 bands of 1M
// bake as fast as 16 of 4M, with 84 MB less peak memory.
namespace {

// raster -> trace -> [occlusion rays] -> encode (every map of the set),
// band of rows by band of rows, then dilate and write, for one map (a UDIM
// tile: `surface` has the tile's UVs shifted into [0, 1]^2). The per-sample
// arrays are reused and bounded, so a 16384^2 map bakes in the memory of a
// small one. Bands change nothing in the result: raster tiles and ray
// packets both start on band rows.
// Rows [first_row, last_row) of the map (all of it, or a tile's: then the
// image and coverage hold only those rows, and nothing is dilated or
// written: `tile` gets them).
Status bake_tile(const Prepared& p, const LowSurface& surface, const std::vector<MapOutput>& outputs,
                 const std::string& debug_prefix, BakeReport& r, StageTimer& timer, const ProgressFn& progress,
                 std::uint64_t& covered_texels, int first_row, int last_row, int udim_tile, TileData* tile) {
  const BakeOptions& o = p.options;
  const int rows = last_row - first_row;
  MapSet maps(p.maps, o.width, first_row, last_row);
  std::vector<std::uint8_t> coverage(static_cast<std::size_t>(o.width) * rows, 0);
  std::unique_ptr<DebugImages> debug;
  if (!debug_prefix.empty()) debug = std::make_unique<DebugImages>(o.width, o.height, o.adaptive);
  TexelSamples samples;
  Hits hits;
  covered_texels = 0;
  if (o.adaptive) {
    // The normal map alone (validate_options); its image holds rows from first_row.
    EncodeOptions encode_options = p.maps.encode;
    encode_options.out_row_begin = first_row;
    AdaptiveRows(p, surface, r, maps.image(MapKind::normal), coverage, encode_options, debug.get())
        .run(first_row, last_row, timer, progress, covered_texels);
  } else {
    const int rows_per_band = band_rows(o.width, o.height, o.samples, o.band_samples);
    for (int row = first_row; row < last_row; row += rows_per_band) {
      const int row_end = std::min(row + rows_per_band, last_row);
      timer.start_quietly("raster");
      RasterStats band_raster;
      rasterize(surface, o.width, o.height, o.samples, samples, band_raster, row, row_end);
      covered_texels += band_raster.covered_texels;
      r.raster.covered_texels += band_raster.covered_texels;
      r.raster.border_samples += band_raster.border_samples;
      r.raster.overlapping_samples += band_raster.overlapping_samples;
      r.raster.degenerate_uv_triangles = band_raster.degenerate_uv_triangles;  // the same in every band
      std::copy(samples.coverage.begin(), samples.coverage.end(),
                coverage.begin() + static_cast<std::ptrdiff_t>(row - first_row) * o.width);
      timer.stop(false);

      timer.start_quietly("trace");
      // Without a listener trace() gets none: it then runs each band as one
      // parallel loop instead of 100 batches with a barrier each.
      std::function<void(double)> trace_progress;
      if (progress) {
        trace_progress = [&](double f) { progress("trace", (row + f * (row_end - row)) / o.height); };
      }
      trace(p.scene, surface, samples, p.rays, hits, r.trace, trace_progress);
      timer.stop(false);

      if (maps.needs_rays()) {
        // AO, bent normals, thickness: their own rays from this band's hits.
        timer.start_quietly("occlusion");
        maps.trace_rays(p.scene, p.high, surface, samples, hits);
        timer.stop(false);
        if (progress) progress("occlusion", static_cast<double>(row_end) / o.height);
      }

      timer.start_quietly("encode");
      maps.encode_band(surface, samples, p.high, hits, r.encode);
      timer.stop(false);
      if (debug) debug->add_band(samples, hits);
    }
  }
  if (debug) NMBAKE_TRY(debug->write(debug_prefix));
  if (tile != nullptr) {
    // Every map's raw texels and what its bands counted: the merge finishes them.
    for (const MapKind map : p.maps.maps) tile->texels.push_back(std::move(maps.image(map).pixels));
    tile->counts = maps.counts();
    tile->coverage = std::move(coverage);
    return Status::ok();
  }

  timer.start("dilate");
  maps.finish(coverage, o.padding, r.dilate);
  timer.stop();

  timer.start("write");
  NMBAKE_TRY(write_map_files(maps, outputs, o.dither));
  timer.stop();
  for (MapReport& m : map_file_reports(maps, outputs, udim_tile)) r.map_reports.push_back(std::move(m));
  return Status::ok();
}


}  // namespace


Status bake(const BakeOptions& o, BakeReport& r, const ProgressFn& progress) {
  const Clock::time_point bake_begin = Clock::now();
  NMBAKE_TRY(validate_options(o));
  const bool tiled = o.tile_count > 0;
  if (tiled) {
    if (o.tile_index < 0 || o.tile_index >= o.tile_count || o.tile_count > 4096) {
      return Status::bad_input("tile " + std::to_string(o.tile_index + 1) + "/" + std::to_string(o.tile_count) +
                               " does not exist (1/N to N/N, N up to 4096)");
    }
    if (o.tile_path.empty()) return Status::bad_input("a tile bake needs a tile file to write");
    for (const OutputSpec& out : o.outputs) {
      if (has_udim_token(out.path)) return Status::bad_input(out.path + ": <UDIM> maps cannot be baked in tiles yet");
    }
  }
  r = BakeReport{};
  r.low_path = o.low_path;
  r.high_path = o.high_path;
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
  StageTimer timer(r, progress);

  // The map's own buffers first (no file needed), then with the meshes'
  // sizes once they are loaded, before the BVH and the map are allocated.
  NMBAKE_TRY(check_bake_memory(o, MeshSize{}, MeshSize{}));

  // load
  timer.start("load");
  Mesh low, high, cage;
  NMBAKE_TRY(load_mesh(o.low_path, detail::low_load_options(o), low, r.low_load));
  const bool smooth_high = o.encode.high_normals == HighNormals::smooth;
  const auto wants = [&](MapKind map) { return std::find(o.maps.begin(), o.maps.end(), map) != o.maps.end(); };
  LoadOptions high_options{false, smooth_high};
  high_options.keep_colors = wants(MapKind::vertex_color);
  NMBAKE_TRY(load_mesh(o.high_path, high_options, high, r.high_load));
  if (high_options.keep_colors && !high.has_colors()) {
    return Status::bad_input(
        o.high_path +
        ": --map vertex-color, but the high mesh has no vertex colours (read from "
        "PLY red/green/blue properties, glTF COLOR_0, FBX and Collada vertex colours, and OBJ "
        "\"v x y z r g b\" lines)");
  }
  if (wants(MapKind::id) && o.id_source == IdSource::material && !high.has_named_materials()) {
    return Status::bad_input(o.high_path +
                             ": --map id with --id-source material, but the high mesh has no named "
                             "materials (OBJ usemtl, glTF primitive materials, FBX and Collada materials)");
  }
  const bool use_cage_mesh = !o.cage_path.empty();
  if (use_cage_mesh) {
    LoadStats cage_load;
    NMBAKE_TRY(load_mesh(o.cage_path, LoadOptions{false, false}, cage, cage_load));
    NMBAKE_TRY(order_cage_by_parts(low, o.match, o.cage_path, cage));
    NMBAKE_TRY(check_cage_topology(low, cage, o.cage_path));
  }
  // Every derived value (diagonal, normals, ray origins) stays finite only
  // within these bounds; Embree aborts on a ray that is not.
  NMBAKE_TRY(check_coordinate_range(low, o.low_path));
  NMBAKE_TRY(check_coordinate_range(high, o.high_path));
  if (use_cage_mesh) NMBAKE_TRY(check_coordinate_range(cage, o.cage_path));
  NMBAKE_TRY(check_bake_memory(o, MeshSize{low.vertex_count(), low.triangle_count()},
                                MeshSize{high.vertex_count(), high.triangle_count()}));
  {
    const float diagonal = compute_bounds(low).diagonal();
    NMBAKE_TRY(detail::check_distance("front", o.rays.front, diagonal));
    NMBAKE_TRY(detail::check_distance("back", o.rays.back, diagonal));
  }
  timer.stop();
  // Parts into groups before anything is baked: a naming mistake is found in
  // a second, not after the unwrap.
  BakeGroups groups;
  NMBAKE_TRY(match_parts(low, high, o.match, o.low_path, o.high_path, groups));
  const bool udim = detail::bakes_udim_tiles(o);
  if (!low.has_uvs()) {
    const int side = std::min(o.width, o.height);
    if (o.unwrap_gutter > side / 4) {
      return Status::bad_input(o.low_path + ": the low mesh has no UVs and a " + std::to_string(o.width) + "x" +
                               std::to_string(o.height) + " map is too small to unwrap it into: unwrap gutter " +
                               std::to_string(o.unwrap_gutter) + " is out of range (0 to size / 4 = " +
                               std::to_string(side / 4) + ")");
    }
    timer.start("unwrap");
    // No UV layout: make one; the map is useless without the mesh, so it is
    // written beside the map (in the write stage, with the maps). The unwrap
    // keeps the triangle order, so the groups stay valid.
    UnwrapOptions unwrap_options;
    unwrap_options.pack.resolution = std::min(o.width, o.height);
    unwrap_options.pack.gutter = o.unwrap_gutter;
    Mesh unwrapped;
    const Status s = unwrap_mesh(low, unwrap_options, unwrapped, r.unwrap);
    if (!s) return Status::bad_input(o.low_path + ": the low mesh has no UVs; " + s.message());
    low = std::move(unwrapped);
    r.unwrapped = true;
    const std::filesystem::path first(udim_path(map_path(o.outputs.front().path, o.maps.front()), 1001));
    r.unwrapped_low_path = (first.parent_path() / (first.stem().string() + "_low_uv.obj")).string();
    timer.stop();
  }
  if (o.tangent_basis == TangentBasis::file && !low.has_tangents()) {
    // Checked after unwrap: a mesh unwrapped here has no file tangents either.
    return Status::bad_input(o.low_path + ": --tangents file, but the low mesh has no tangents (glTF TANGENT or FBX "
                             "tangents on every part, and UVs)");
  }
  std::vector<int> tiles;
  NMBAKE_TRY(find_udim_tiles(low, o.low_path, udim, tiles));
  r.low_triangles = low.triangle_count();
  r.high_triangles = high.triangle_count();
  r.high_vertices = high.vertex_count();

  // prepare: normals, tangents, cage, groups
  timer.start("prepare");
  prepare_low_normals(low, r.low_mesh);
  if (smooth_high) prepare_high_normals(high, r.high_mesh);
  // The map set's data from the whole high mesh (bounds, vertex curvature,
  // parts or materials), before groups reorder its triangles.
  MapMeshData map_mesh;
  prepare_map_mesh(high, o.maps, o.id_source, groups, map_mesh);
  r.curvature_degenerate_triangles = map_mesh.curvature.degenerate_triangles;
  r.curvature_isolated_vertices = map_mesh.curvature.isolated_vertices;
  r.id_source = map_mesh.id_source;
  r.id_names = map_mesh.ids;
  SceneGroups scene_groups;
  if (groups.grouped()) {
    // Normals come from the whole high mesh first; then each group's
    // triangles become one range of the index buffer (unused parts dropped).
    high.indices = group_high_indices(high, groups, scene_groups.first_triangle);
    // The ranges no longer match the triangles (the map set took what it
    // needs of them above).
    high.parts.clear();
    high.materials.clear();
    scene_groups.groups_per_scene = o.groups_per_scene;
  }
  r.high_triangles_used = high.triangle_count();
  pad_for_embree(high);
  SurfaceStats surface_stats;
  LowSurface surface = build_low_surface(low, use_cage_mesh ? &cage : nullptr, o.tangent_basis, surface_stats);
  surface.group = groups.low_group;
  r.low_mesh.zero_area_triangles += surface_stats.mesh.zero_area_triangles;
  r.low_mesh.zero_length_normals += surface_stats.mesh.zero_length_normals;
  r.tangents = surface_stats.tangents;
  r.low_diagonal = compute_bounds(low).diagonal();
  timer.stop();

  timer.start("build");
  HighScene scene;
  NMBAKE_TRY(HighScene::build(high, o.build_quality, o.rays.ignore_backfaces, scene, o.bvh_memory,
                              groups.grouped() ? &scene_groups : nullptr));
  r.compact_bvh = scene.compact();
  r.scenes = scene.scene_count();
  timer.stop();

  // Ray distances: as given, or estimated by probing the two meshes (each
  // group its own).
  const bool need_estimate = o.rays.estimates_distances();
  if (need_estimate) timer.start("distances");
  RayOptions rays;
  const DistanceEstimate estimate =
      resolve_rays(o.rays, scene, surface, r.low_diagonal, groups.groups.size(), rays);
  if (need_estimate) {
    timer.stop();
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

  Prepared prepared{o, high, scene, rays, MapSettings{}};
  MapSettings& map_settings = prepared.maps;
  map_settings.maps = o.maps;
  map_settings.encode = o.encode;
  map_settings.encode.out_row_begin = 0;  // set per tile of rows, on a copy
  map_settings.height_range = o.height_range;
  map_settings.curvature_range = o.curvature_range;
  const float auto_map_distance = kAutoMapDistancePercent * 0.01f * r.low_diagonal;
  map_settings.occlusion.rays = o.ao_rays;
  map_settings.occlusion.distance = resolve_distance(o.ao_distance, r.low_diagonal, auto_map_distance);
  map_settings.occlusion.bent = map_settings.has(MapKind::bent_normal);
  map_settings.thickness.rays = o.thickness_rays;
  map_settings.thickness.distance = resolve_distance(o.thickness_distance, r.low_diagonal, auto_map_distance);
  map_mesh.apply(map_settings);
  r.maps = o.maps;
  const std::vector<MapOutput> map_files = map_outputs(o);
  const std::vector<glm::vec2> file_uvs = udim ? surface.uv : std::vector<glm::vec2>{};
  r.outputs.clear();
  for (const int tile : tiles) {
    BakeReport::Tile done;
    done.tile = tile;
    std::vector<MapOutput> outputs = map_files;
    for (MapOutput& out : outputs) {
      out.path = udim_path(out.path, tile);
      done.outputs.push_back(out.path);
      r.outputs.push_back(out.path);
    }
    std::string debug_prefix = o.debug_dump_prefix;
    if (udim) {
      // The tile's UVs into [0, 1]^2 (exact: whole-number shifts).
      const glm::vec2 offset = udim_offset(tile);
      for (std::size_t i = 0; i < file_uvs.size(); ++i) surface.uv[i] = file_uvs[i] - offset;
      if (!debug_prefix.empty()) debug_prefix += "." + std::to_string(tile);
    }
    if (tiled) {
      TileData rows;
      NMBAKE_TRY(bake_key(o, rows.key));
      r.key = rows.key.hex();
      rows.width = o.width;
      rows.height = o.height;
      tile_rows(o.height, o.tile_index, o.tile_count, rows.row_begin, rows.row_end);
      rows.index = o.tile_index;
      rows.count = o.tile_count;
      rows.padding = o.padding;
      rows.dither = o.dither;
      rows.outputs = o.outputs;  // <MAP> kept: the merge names each map's file as the bake does
      rows.maps = map_settings;
      rows.maps.vertex_curvature = nullptr;  // the mesh data is encoding's alone
      rows.maps.triangle_id = nullptr;
      rows.maps.id_colors = nullptr;
      NMBAKE_TRY(bake_tile(prepared, surface, outputs, debug_prefix, r, timer, progress, done.covered_texels,
                           rows.row_begin, rows.row_end, tile, &rows));
      timer.start("write");
      NMBAKE_TRY(write_tile(o.tile_path, rows));
      timer.stop();
      r.tile_index = rows.index;
      r.tile_count = rows.count;
      r.tile_row_begin = rows.row_begin;
      r.tile_row_end = rows.row_end;
      r.tile_path = o.tile_path;
      r.outputs = {o.tile_path};
      done.outputs = {o.tile_path};
    } else {
      NMBAKE_TRY(bake_tile(prepared, surface, outputs, debug_prefix, r, timer, progress, done.covered_texels, 0,
                           o.height, tile, nullptr));
    }
    r.tiles.push_back(std::move(done));
  }
  if (r.unwrapped) {
    timer.start("write");
    NMBAKE_TRY(save_mesh(r.unwrapped_low_path, low));
    timer.stop();
  }

  r.total_seconds = std::chrono::duration<double>(Clock::now() - bake_begin).count();
  r.peak_rss_bytes = peak_rss_bytes();
  return Status::ok();
}

}  // namespace nmbake
