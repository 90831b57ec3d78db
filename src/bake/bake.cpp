// The pipeline: load -> prepare -> raster -> trace -> encode -> dilate ->
// write, as bake() at the end of this file lists it. Each stage is a free
// function of its own header; this file only wires them, times them and
// hands their counters to the report (report_fill.hpp).
#include "nmbake/bake.hpp"

#include <tbb/parallel_invoke.h>
#include <xxhash.h>

#include <algorithm>
#include <cctype>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <functional>
#include <memory>
#include <string>
#include <vector>

#include "bake/adaptive_rows.hpp"
#include "bake/debug_images.hpp"
#include "bake/pipeline.hpp"
#include "bake/report_fill.hpp"
#include "bake/validate.hpp"
#include "nmbake/budget.hpp"
#include "nmbake/maps.hpp"
#include "nmbake/sets.hpp"
#include "nmbake/task.hpp"
#include "nmbake/udim.hpp"

namespace nmbake {

using detail::AdaptiveRows;
using detail::Clock;
using detail::DebugImages;
using detail::Prepared;
using detail::StageTimer;

// About 1M samples a band, so the per-sample arrays (28 bytes a sample, ~28
// MB) stay in the last-level cache between raster, trace and encode, and a
// bake first-touches little fresh memory (slow on these virtual machines,
// BENCHMARKS.md). With the trace no longer split into progress batches
// without a listener, a band costs little: at 2048^2 16 spp, 64 bands of 1M
// bake as fast as 16 of 4M, with 84 MB less peak memory.
namespace {

// Rows [row_begin, row_end) of a map with a fixed sample count, band of rows
// by band of rows: raster -> trace -> [occlusion rays] -> encode (every map
// of the set). The per-sample arrays are reused and bounded, so a 16384^2
// map bakes in the memory of a small one. Bands change nothing in the
// result: raster tiles and ray packets both start on band rows. `coverage`
// holds the rows from first_row.
void bake_bands(const Prepared& p, const LowSurface& surface, MapSet& maps,
                std::vector<std::uint8_t>& coverage, DebugImages* debug, BakeReport& r, StageTimer& timer,
                const ProgressFn& progress, std::uint64_t& covered_texels, int first_row, int last_row) {
  const BakeOptions& o = p.options;
  TexelSamples samples;
  Hits hits;
  const int rows_per_band = band_rows(o.width, o.height, o.samples, o.band_samples);
  for (int row = first_row; row < last_row; row += rows_per_band) {
    const int row_end = std::min(row + rows_per_band, last_row);
    timer.start_quietly("raster");
    RasterStats band_raster;
    rasterize(surface, o.width, o.height, o.samples, samples, band_raster, row, row_end);
    covered_texels += band_raster.covered_texels;
    detail::report_raster_band(band_raster, r);
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
    if (debug != nullptr) debug->add_band(samples, hits);
  }
}

// The baked rows of every map: into `tile` (raw texels and what the bands
// counted: the merge finishes them), or dilated and written to `outputs`.
Status finish_rows(const Prepared& p, MapSet& maps, std::vector<std::uint8_t>& coverage,
                   const std::vector<MapOutput>& outputs, BakeReport& r, StageTimer& timer, int udim_tile,
                   TileData* tile) {
  if (tile != nullptr) {
    for (const MapKind map : p.maps.maps) tile->texels.push_back(std::move(maps.image(map).pixels));
    tile->counts = maps.counts();
    tile->coverage = std::move(coverage);
    return Status::ok();
  }
  timer.start("dilate");
  maps.finish(coverage, p.options.padding, r.dilate);
  timer.stop();

  timer.start("write");
  NMBAKE_TRY(write_map_files(maps, outputs, p.options.dither));
  std::vector<std::string> packed;
  NMBAKE_TRY(write_pack_files(maps, p.options.packs, udim_tile, p.options.dither, packed));
  timer.stop();
  for (std::string& path : packed) r.outputs.push_back(std::move(path));
  for (MapReport& m : map_file_reports(maps, outputs, udim_tile)) r.map_reports.push_back(std::move(m));
  return Status::ok();
}

// Every map of the set for one UDIM tile (`surface` has the tile's UVs
// shifted into [0, 1]^2): the rows baked (adaptively or band by band), then
// finished. Rows [first_row, last_row) of the map (all of it, or a tile's:
// then the image and coverage hold only those rows, and nothing is dilated or
// written: `tile` gets them).
Status bake_tile(const Prepared& p, const LowSurface& surface, const std::vector<MapOutput>& outputs,
                 const std::string& debug_prefix, BakeReport& r, StageTimer& timer,
                 const ProgressFn& progress, std::uint64_t& covered_texels, int first_row, int last_row,
                 int udim_tile, TileData* tile) {
  const BakeOptions& o = p.options;
  MapSet maps(p.maps, o.width, first_row, last_row);
  std::vector<std::uint8_t> coverage(static_cast<std::size_t>(o.width) * (last_row - first_row), 0);
  std::unique_ptr<DebugImages> debug;
  if (!debug_prefix.empty()) debug = std::make_unique<DebugImages>(o.width, o.height, o.adaptive);
  covered_texels = 0;
  if (o.adaptive) {
    // The normal map alone (validate_options); its image holds rows from first_row.
    EncodeOptions encode_options = p.maps.encode;
    encode_options.out_row_begin = first_row;
    AdaptiveRows(p, surface, r, maps.image(MapKind::normal), coverage, encode_options, debug.get())
        .run(first_row, last_row, timer, progress, covered_texels);
  } else {
    bake_bands(p, surface, maps, coverage, debug.get(), r, timer, progress, covered_texels, first_row,
               last_row);
  }
  if (debug) NMBAKE_TRY(debug->write(debug_prefix));
  return finish_rows(p, maps, coverage, outputs, r, timer, udim_tile, tile);
}

// A tile bake (task.hpp): tile_index / tile_count must name a tile, with a
// file to write it to, and no <UDIM> output.
Status check_tile_request(const BakeOptions& o) {
  if (o.tile_count <= 0) return Status::ok();
  if (o.tile_index < 0 || o.tile_index >= o.tile_count || o.tile_count > 4096) {
    return Status::bad_input("tile " + std::to_string(o.tile_index + 1) + "/" + std::to_string(o.tile_count) +
                             " does not exist (1/N to N/N, N up to 4096)");
  }
  if (o.tile_path.empty()) return Status::bad_input("a tile bake needs a tile file to write");
  for (const OutputSpec& out : o.outputs) {
    if (has_udim_token(out.path) || has_set_token(out.path)) {
      return Status::bad_input(out.path + ": " + (has_udim_token(out.path) ? kUdimToken : kSetToken) +
                               " maps cannot be baked in tiles yet");
    }
  }
  return Status::ok();
}

// The meshes through the pipeline: as loaded, then the low one with UVs,
// its groups and UDIM tiles.
struct Meshes {
  Mesh low, cage;
  // The high mesh as loaded: this bake's own, or a HighStore's (shared,
  // never changed). `own_high` is set when the bake may move the mesh out of
  // it (no store keeps it); `high_key` is its store key.
  std::shared_ptr<const LoadedHigh> high;
  LoadedHigh* own_high = nullptr;
  std::string high_key;
  bool has_cage = false;
  BakeGroups groups;
  bool udim = false;              // outputs hold <UDIM>: a map per UV tile
  std::vector<int> tiles;         // the UDIM tiles baked (1001 alone without <UDIM>)
  std::vector<LowSet> sets;       // outputs hold <SET>: a map set per low material (sets.hpp); else empty
  IdPalette palette;              // the id map's colours by name (--id-palette)
  bool high_normal_maps = false;  // resolved: the normal maps read the high's normal textures
};

// XXH3-64 of a file's bytes (hash_file_contents(), task.hpp); false when it
// cannot be read.
bool hash_file_bytes(const std::string& path, std::uint64_t& out) {
  std::uint64_t size = 0;
  return hash_file_contents(path, size, out).empty();
}

std::vector<FileHash> hash_files(const std::vector<std::string>& paths) {
  std::vector<FileHash> out;
  for (const std::string& path : paths) {
    std::uint64_t h = 0;
    if (!hash_file_bytes(path, h)) h = 0;
    out.emplace_back(path, h);
  }
  return out;
}

// Whether every file still has the bytes it had.
bool files_unchanged(const std::vector<FileHash>& files) {
  return std::all_of(files.begin(), files.end(), [](const FileHash& f) {
    std::uint64_t h = 0;
    return hash_file_bytes(f.first, h) == (f.second != 0) && h == f.second;
  });
}

// A store key's part: "name=value;".
void add_key(std::string& key, const char* name, const std::string& value) {
  key.append(name).append("=").append(value).append(";");
}

// The high's normal textures (--high-normal-maps): its materials and corner
// UVs are read from the files that carry them (OBJ + MTL, glTF) when the
// option may be on and a normal map is baked.
bool reads_high_normal_maps(const BakeOptions& o) {
  const bool normal_map = std::find(o.maps.begin(), o.maps.end(), MapKind::normal) != o.maps.end() ||
                          std::find(o.maps.begin(), o.maps.end(), MapKind::object_normal) != o.maps.end();
  if (!normal_map || o.high_normal_maps == HighNormalMaps::off) return false;
  if (o.high_normal_maps == HighNormalMaps::on) return true;
  return std::any_of(o.high_paths.begin(), o.high_paths.end(), [](const std::string& path) {
    std::string extension = std::filesystem::path(path).extension().string();
    for (char& c : extension) c = static_cast<char>(std::tolower(static_cast<unsigned char>(c)));
    return extension == ".obj" || extension == ".gltf" || extension == ".glb";
  });
}

// Whether the normal maps read the high's normal textures: `on`, or `auto`
// and a material the high's triangles use names one. auto leaves out, and
// counts, a texture the loader could not point at (an image embedded in a
// .glb: TextureRef::problem), which `on` refuses (load_material_textures()),
// and every one under --samples adaptive (which `on` refuses too).
// Without them, corner UVs read for them alone are dropped before the BVH is built.
void resolve_high_normal_maps(const BakeOptions& o, Mesh& high, BakeReport& r, bool& on) {
  on = false;
  r.high_normal_textures = r.high_normal_textures_skipped = 0;
  if (!reads_high_normal_maps(o)) return;
  for (Material& m : high.material_defs) {
    if (m.normal_texture.empty()) continue;
    const bool used = std::any_of(high.materials.begin(), high.materials.end(), [&](const MeshPart& range) {
      return range.name == m.name && range.triangle_count > 0;
    });
    if (!used) continue;
    // Adaptive sampling encodes outside the map set, without them (`on` is
    // refused by validate_options()).
    if (o.high_normal_maps == HighNormalMaps::automatic &&
        (!m.normal_texture.problem.empty() || o.adaptive)) {
      ++r.high_normal_textures_skipped;
      m.normal_texture = TextureRef{};
      continue;
    }
    ++r.high_normal_textures;
    on = true;
  }
  r.high_normal_maps = on;
  if (!on && !texture_needs(o.maps).any()) std::vector<glm::vec2>().swap(high.corner_uvs);
}

// What the high mesh must hold for the map set: vertex colours, named materials.
Status check_high_for_maps(const BakeOptions& o, const Mesh& high) {
  if (std::find(o.maps.begin(), o.maps.end(), MapKind::vertex_color) != o.maps.end() && !high.has_colors()) {
    return Status::bad_input(
        high_name(o.high_paths) +
        ": --map vertex-color, but the high mesh has no vertex colours (read from "
        "PLY red/green/blue properties, glTF COLOR_0, FBX and Collada vertex colours, and OBJ "
        "\"v x y z r g b\" lines)");
  }
  const bool id_map = std::find(o.maps.begin(), o.maps.end(), MapKind::id) != o.maps.end();
  if (id_map && o.id_source == IdSource::vertex_color && !high.has_colors()) {
    return Status::bad_input(
        high_name(o.high_paths) +
        ": --map id with --id-source vertex-color, but the high mesh has no vertex colours "
        "(PLY red/green/blue, glTF COLOR_0, FBX and Collada vertex colours, OBJ \"v x y z r "
        "g b\")");
  }
  if (id_map && o.id_source == IdSource::material && !high.has_named_materials()) {
    return Status::bad_input(high_name(o.high_paths) +
                             ": --map id with --id-source material, but the high mesh has no named "
                             "materials (OBJ usemtl, glTF primitive materials, FBX and Collada materials)");
  }
  return Status::ok();
}

// How the high files are read: only what the map set and the options need.
LoadOptions high_load_options(const BakeOptions& o) {
  const bool id_map = std::find(o.maps.begin(), o.maps.end(), MapKind::id) != o.maps.end();
  LoadOptions high_options{false, o.encode.high_normals == HighNormals::smooth};
  high_options.keep_colors = std::find(o.maps.begin(), o.maps.end(), MapKind::vertex_color) != o.maps.end() ||
                             (id_map && o.id_source == IdSource::vertex_color);
  // The transfer maps read the high's corner UVs and materials; the mesh
  // itself (vertices, triangles, normals) is the same as without them.
  high_options.corner_uvs = texture_needs(o.maps).any();
  // The id map colours materials in their own colours where the file gives them.
  high_options.material_defs = high_options.corner_uvs || (id_map && o.id_source != IdSource::part &&
                                                           o.id_source != IdSource::vertex_color);
  if (reads_high_normal_maps(o)) {
    // auto only looks: an MTL it cannot read is no normal texture (counted),
    // not a failed bake, unless the maps need the materials anyway.
    high_options.material_libraries_optional =
        !high_options.material_defs && o.high_normal_maps == HighNormalMaps::automatic;
    high_options.material_defs = true;
    if (o.high_normal_maps == HighNormalMaps::on) high_options.corner_uvs = true;
  }
  return high_options;
}

// The high files read into `high` (and the report's high_load and normal
// texture counts).
Status load_high_files(const BakeOptions& o, BakeReport& r, LoadedHigh& high) {
  LoadOptions high_options = high_load_options(o);
  NMBAKE_TRY(load_meshes(o.high_paths, high_options, high.mesh, r.high_load));
  resolve_high_normal_maps(o, high.mesh, r, high.normal_maps);
  if (high.normal_maps && !high.mesh.has_corner_uvs()) {
    // auto found a normal texture: the high's corner UVs, in a second read
    // (a high without one, the common case, pays for its MTL alone: the
    // corner UVs of a 2M-triangle OBJ cost about 0.14 s and 24 bytes a triangle).
    const double first_seconds = r.high_load.seconds;
    high_options.corner_uvs = true;
    NMBAKE_TRY(load_meshes(o.high_paths, high_options, high.mesh, r.high_load));
    r.high_load.seconds += first_seconds;
    resolve_high_normal_maps(o, high.mesh, r, high.normal_maps);
  }
  NMBAKE_TRY(check_high_for_maps(o, high.mesh));
  high.load = r.high_load;
  high.normal_textures = r.high_normal_textures;
  high.normal_textures_skipped = r.high_normal_textures_skipped;
  return Status::ok();
}

// The store key of the loaded high: each file's path, size and XXH3-64 (the
// bytes, not a date: a file rewritten with other bytes in the same second
// is another mesh), and every option that changes what is read.
// False when a file cannot be read (the load then says why).
bool loaded_high_key(const BakeOptions& o, std::string& key) {
  key.clear();
  for (const std::string& path : o.high_paths) {
    std::uint64_t size = 0, h = 0;
    if (!hash_file_contents(path, size, h).empty()) return false;
    add_key(key, "high", path + "," + std::to_string(size) + "," + std::to_string(h));
  }
  const LoadOptions l = high_load_options(o);
  add_key(key, "load",
          std::to_string(l.keep_uvs) + std::to_string(l.keep_normals) + std::to_string(l.uv_set) +
              std::to_string(l.keep_tangents) + std::to_string(l.keep_colors) + std::to_string(l.corner_uvs) +
              std::to_string(l.material_defs) + std::to_string(l.material_libraries_optional));
  add_key(key, "high_normal_maps", std::to_string(static_cast<int>(o.high_normal_maps)));
  add_key(key, "adaptive", std::to_string(o.adaptive));
  add_key(key, "maps",
          std::to_string(reads_high_normal_maps(o)) + std::to_string(texture_needs(o.maps).any()));
  return true;
}

// The high mesh as loaded: from the store when it holds the same, else read
// (and left in the store).
Status load_high(const BakeOptions& o, HighStore* store, BakeReport& r, Meshes& m, bool& reused) {
  reused = false;
  if (store != nullptr && loaded_high_key(o, m.high_key)) {
    if (std::shared_ptr<const LoadedHigh> found = store->find_loaded(m.high_key);
        found && files_unchanged(found->files)) {
      m.high = std::move(found);
      r.high_load = m.high->load;
      r.high_load.seconds = 0.0;  // not read by this bake
      r.high_normal_maps = m.high->normal_maps;
      r.high_normal_textures = m.high->normal_textures;
      r.high_normal_textures_skipped = m.high->normal_textures_skipped;
      reused = true;
      return Status::ok();
    }
  } else {
    m.high_key.clear();
  }
  auto loaded = std::make_shared<LoadedHigh>();
  NMBAKE_TRY(load_high_files(o, r, *loaded));
  if (!m.high_key.empty()) {
    loaded->files = hash_files(loaded->load.files);
    store->keep_loaded(m.high_key, loaded);
  } else {
    m.own_high = loaded.get();
  }
  m.high = std::move(loaded);
  return Status::ok();
}

// load: the low, high and cage meshes, and what can be checked of them
// before anything is built: the map set's needs, the cage's topology,
// coordinate ranges, memory, distances against the low diagonal.
Status load_inputs(const BakeOptions& o, HighStore* store, BakeReport& r, StageTimer& timer, Meshes& m,
                   bool& reused) {
  timer.start("load");
  const bool id_map = std::find(o.maps.begin(), o.maps.end(), MapKind::id) != o.maps.end();
  if (id_map && !o.id_palette.empty()) NMBAKE_TRY(read_id_palette(o.id_palette, m.palette));
  NMBAKE_TRY(load_mesh(o.low_path, detail::low_load_options(o), m.low, r.low_load));
  NMBAKE_TRY(load_high(o, store, r, m, reused));
  m.high_normal_maps = m.high->normal_maps;
  const Mesh& high = m.high->mesh;
  for (const LoadStats* stats : {&r.low_load, &r.high_load})
    r.input_files.insert(r.input_files.end(), stats->files.begin(), stats->files.end());
  m.has_cage = !o.cage_path.empty();
  if (m.has_cage) {
    LoadStats cage_load;
    NMBAKE_TRY(load_mesh(o.cage_path, LoadOptions{false, false}, m.cage, cage_load));
    r.input_files.insert(r.input_files.end(), cage_load.files.begin(), cage_load.files.end());
    NMBAKE_TRY(order_cage_by_parts(m.low, o.match, o.cage_path, m.cage));
    NMBAKE_TRY(check_cage_topology(m.low, m.cage, o.cage_path));
  }
  // Every derived value (diagonal, normals, ray origins) stays finite only
  // within these bounds; Embree aborts on a ray that is not.
  NMBAKE_TRY(check_coordinate_range(m.low, o.low_path));
  NMBAKE_TRY(check_coordinate_range(high, high_name(o.high_paths)));
  if (m.has_cage) NMBAKE_TRY(check_coordinate_range(m.cage, o.cage_path));
  NMBAKE_TRY(check_bake_memory(o, MeshSize{m.low.vertex_count(), m.low.triangle_count()},
                               MeshSize{high.vertex_count(), high.triangle_count()}));
  const float diagonal = compute_bounds(m.low).diagonal();
  NMBAKE_TRY(detail::check_distance("front", o.rays.front, diagonal));
  NMBAKE_TRY(detail::check_distance("back", o.rays.back, diagonal));
  timer.stop();
  return Status::ok();
}

// The low mesh's UVs when it has none: an atlas of the map's smaller side,
// written beside the first map (in the write stage, with the maps). The
// unwrap keeps the triangle order, so the groups stay valid.
Status unwrap_low(const BakeOptions& o, BakeReport& r, StageTimer& timer, Mesh& low) {
  const int side = std::min(o.width, o.height);
  if (o.unwrap_gutter > side / 4) {
    return Status::bad_input(o.low_path + ": the low mesh has no UVs and a " + std::to_string(o.width) + "x" +
                             std::to_string(o.height) +
                             " map is too small to unwrap it into: unwrap gutter " +
                             std::to_string(o.unwrap_gutter) +
                             " is out of range (0 to size / 4 = " + std::to_string(side / 4) + ")");
  }
  timer.start("unwrap");
  UnwrapOptions unwrap_options;
  unwrap_options.pack.resolution = side;
  unwrap_options.pack.gutter = o.unwrap_gutter;
  Mesh unwrapped;
  const Status s = unwrap_mesh(low, unwrap_options, unwrapped, r.unwrap);
  if (!s) return Status::bad_input(o.low_path + ": the low mesh has no UVs; " + s.message());
  low = std::move(unwrapped);
  const std::filesystem::path first(
      replace_token(udim_path(map_path(o.outputs.front().path, o.maps.front()), 1001), kSetToken, "all"));
  detail::report_unwrapped((first.parent_path() / (first.stem().string() + "_low_uv.obj")).string(), r);
  timer.stop();
  return Status::ok();
}

// The low mesh ready to bake: parts into groups (before anything is baked:
// a naming mistake is found in a second, not after the unwrap), UVs, the
// file tangents it was asked to keep, its UDIM tiles.
Status prepare_low_mesh(const BakeOptions& o, BakeReport& r, StageTimer& timer, Meshes& m) {
  NMBAKE_TRY(match_parts(m.low, m.high->mesh, o.match, o.low_path, high_name(o.high_paths), m.groups));
  m.udim = detail::bakes_udim_tiles(o);
  if (!m.low.has_uvs()) NMBAKE_TRY(unwrap_low(o, r, timer, m.low));
  if (o.tangent_basis == TangentBasis::file && !m.low.has_tangents()) {
    // Checked after unwrap: a mesh unwrapped here has no file tangents either.
    return Status::bad_input(o.low_path +
                             ": --tangents file, but the low mesh has no tangents (glTF TANGENT or FBX "
                             "tangents on every part, and UVs)");
  }
  NMBAKE_TRY(find_udim_tiles(m.low, o.low_path, m.udim, m.tiles));
  if (detail::bakes_texture_sets(o)) NMBAKE_TRY(find_low_sets(m.low, o.low_path, m.sets));
  detail::report_mesh_sizes(m.low, m.high->mesh, r);
  return Status::ok();
}

// What the rays are traced against: the high side (BuiltHigh: the map set's
// mesh data, the groups' ranges, the high mesh's BVH) and the low surface
// (per-corner arrays, the cage).
struct Scene {
  std::shared_ptr<const BuiltHigh> high;
  LowSurface surface;
};

// High normals: the file's, normalised, or area-weighted ones.
void prepare_high_normals(Mesh& mesh, MeshStats& stats) {
  if (mesh.has_normals()) {
    normalize_normals(mesh, stats);
  } else {
    compute_vertex_normals(mesh, stats);
  }
}

// Each group's high triangles as one range of the index buffer (unused parts
// dropped); the parts' and materials' ranges no longer match the triangles
// then (the map set took what it needs of them before).
void group_high_mesh(const BakeOptions& o, const BakeGroups& groups, Mesh& high, SceneGroups& scene_groups) {
  high.indices = group_high_indices(high, groups, scene_groups.first_triangle);
  high.parts.clear();
  high.materials.clear();
  scene_groups.groups_per_scene = o.groups_per_scene;
}

// The store key of the built high side: the loaded high's, and what the
// build reads besides: high normals, the map set and its id options (the
// palette's colours), the groups' high triangles, the BVH's options.
std::string built_high_key(const BakeOptions& o, const Meshes& m) {
  std::string key = m.high_key;
  add_key(key, "high_normals", std::to_string(static_cast<int>(o.encode.high_normals)));
  std::string maps;
  for (const MapKind map : o.maps) maps += std::to_string(static_cast<int>(map)) + ",";
  add_key(key, "maps", maps);
  add_key(key, "id_source", std::to_string(static_cast<int>(o.id_source)));
  add_key(key, "high_normal_maps", std::to_string(m.high_normal_maps));
  std::unique_ptr<XXH3_state_t, decltype(&XXH3_freeState)> state(XXH3_createState(), &XXH3_freeState);
  XXH3_64bits_reset(state.get());
  for (const auto& [name, colour] : m.palette.colors) {
    XXH3_64bits_update(state.get(), name.data(), name.size() + 1);
    XXH3_64bits_update(state.get(), &colour, sizeof colour);
  }
  add_key(key, "palette", std::to_string(XXH3_64bits_digest(state.get())));
  XXH3_64bits_reset(state.get());
  for (const std::vector<std::uint32_t>& triangles : m.groups.high_triangles) {
    const std::uint64_t count = triangles.size();
    XXH3_64bits_update(state.get(), &count, sizeof count);
    XXH3_64bits_update(state.get(), triangles.data(), triangles.size() * sizeof(std::uint32_t));
  }
  add_key(key, "groups",
          std::to_string(m.groups.grouped()) + "," + std::to_string(m.groups.high_triangles.size()) + "," +
              std::to_string(XXH3_64bits_digest(state.get())) + "," + std::to_string(o.groups_per_scene));
  add_key(key, "bvh",
          std::to_string(static_cast<int>(o.build_quality)) + "," + std::to_string(o.rays.ignore_backfaces) +
              "," + std::to_string(static_cast<int>(o.bvh_memory)));
  return key;
}

// The report's figures of a built high side (also when it was reused).
void report_built_high(const BuiltHigh& b, BakeReport& r) {
  r.high_mesh = b.stats;
  for (const FileHash& f : b.files) r.input_files.push_back(f.first);
  detail::report_map_mesh(b.map_mesh, r);
  r.high_triangles_used = b.triangles_used;
}

// prepare (the high side): normals, the map set's data from the whole high
// mesh (bounds, vertex curvature, parts or materials, before groups reorder
// its triangles), the groups' ranges.
Status prepare_high(const BakeOptions& o, Meshes& m, BuiltHigh& b, std::vector<std::string>& texture_files) {
  // The loaded mesh itself when this bake owns it, else a copy (a store keeps it).
  b.mesh = m.own_high != nullptr ? std::move(m.own_high->mesh) : m.high->mesh;
  if (o.encode.high_normals == HighNormals::smooth) prepare_high_normals(b.mesh, b.stats);
  TextureSet textures;
  TextureNeeds needs = texture_needs(o.maps);
  needs.normal = m.high_normal_maps;
  // The textures' reading and the high's tangents side by side (each mostly on one core).
  Status textures_read;
  HighTangents high_tangents;
  tbb::parallel_invoke(
      [&] {
        if (needs.any())
          textures_read = load_material_textures(b.mesh, high_name(o.high_paths), needs, textures);
      },
      [&] {
        if (m.high_normal_maps) high_tangents = compute_high_tangents(b.mesh);
      });
  NMBAKE_TRY(textures_read);
  texture_files = textures.files;
  prepare_map_mesh(b.mesh, o.maps, o.id_source, m.palette, m.groups, std::move(textures), b.map_mesh,
                   std::move(high_tangents));
  // The map set holds its own copy, in the scene's order.
  std::vector<glm::vec2>().swap(b.mesh.corner_uvs);
  if (m.groups.grouped()) group_high_mesh(o, m.groups, b.mesh, b.groups);
  b.triangles_used = b.mesh.triangle_count();
  pad_for_embree(b.mesh);
  return Status::ok();
}

// prepare: the low normals and surface, and the high side (from the store
// when it holds the same); then build: the high mesh's BVH.
Status prepare_scene(const BakeOptions& o, HighStore* store, BakeReport& r, StageTimer& timer, Meshes& m,
                     Scene& s, bool& reused) {
  reused = false;
  timer.start("prepare");
  prepare_low_normals(m.low, r.low_mesh);
  const std::string key = store != nullptr && !m.high_key.empty() ? built_high_key(o, m) : std::string();
  if (!key.empty()) {
    if (std::shared_ptr<const BuiltHigh> found = store->find_built(key);
        found && files_unchanged(found->files)) {
      s.high = std::move(found);
      reused = true;
    }
  }
  std::shared_ptr<BuiltHigh> built;
  std::vector<std::string> texture_files;
  if (!s.high) {
    built = std::make_shared<BuiltHigh>();
    NMBAKE_TRY(prepare_high(o, m, *built, texture_files));
  }
  SurfaceStats surface_stats;
  s.surface = build_low_surface(m.low, m.has_cage ? &m.cage : nullptr, o.tangent_basis, surface_stats);
  s.surface.group = m.groups.low_group;
  detail::report_low_surface(surface_stats, compute_bounds(m.low).diagonal(), r);
  timer.stop();

  if (built) {
    timer.start("build");
    NMBAKE_TRY(HighScene::build(built->mesh, o.build_quality, o.rays.ignore_backfaces, built->scene,
                                o.bvh_memory, m.groups.grouped() ? &built->groups : nullptr));
    timer.stop();
    built->files = key.empty() ? std::vector<FileHash>(texture_files.size()) : hash_files(texture_files);
    for (std::size_t i = 0; i < texture_files.size(); ++i) built->files[i].first = texture_files[i];
    if (!key.empty()) store->keep_built(key, built);
    s.high = std::move(built);
  }
  report_built_high(*s.high, r);
  detail::report_scene(s.high->scene, r);
  return Status::ok();
}

// Ray distances: as given, or estimated by probing the two meshes (each
// group its own); the banded cage's edge band (resolve_rays()).
RayOptions resolve_bake_rays(const BakeOptions& o, const Meshes& m, Scene& s, BakeReport& r,
                             StageTimer& timer) {
  const bool estimated = o.rays.estimates_distances();
  if (estimated) timer.start("distances");
  RayOptions rays;
  const DistanceEstimate estimate =
      resolve_rays(o.rays, s.high->scene, s.surface, r.low_diagonal, m.groups.groups.size(), rays);
  if (estimated) timer.stop();
  detail::report_rays(rays, estimate, estimated, m.groups, r);
  return rays;
}

// The map set's settings: the maps, the normal map's encode options, ranges,
// and the AO and thickness rays (auto distances: kAutoMapDistancePercent of
// the low diagonal); then the mesh data they read.
MapSettings map_settings(const BakeOptions& o, float low_diagonal, const MapMeshData& map_mesh) {
  MapSettings settings;
  settings.maps = o.maps;
  settings.encode = o.encode;
  settings.encode.out_row_begin = 0;  // set per tile of rows, on a copy
  settings.height_range = o.height_range;
  settings.curvature_range = o.curvature_range;
  const float auto_map_distance = kAutoMapDistancePercent * 0.01f * low_diagonal;
  settings.occlusion.rays = o.ao_rays;
  settings.occlusion.distance = resolve_distance(o.ao_distance, low_diagonal, auto_map_distance);
  settings.occlusion.bent = settings.has(MapKind::bent_normal);
  settings.thickness.rays = o.thickness_rays;
  settings.thickness.distance = resolve_distance(o.thickness_distance, low_diagonal, auto_map_distance);
  settings.map_height = o.height;
  map_mesh.apply(settings);
  return settings;
}

// A tile bake's rows of one map (task.hpp): baked, then written before
// dilation to the tile file with what the merge needs to finish them.
Status bake_tile_rows(const Prepared& p, const LowSurface& surface, const std::vector<MapOutput>& outputs,
                      const std::string& debug_prefix, BakeReport& r, StageTimer& timer,
                      const ProgressFn& progress, int udim_tile, BakeReport::Tile& done) {
  const BakeOptions& o = p.options;
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
  rows.maps = p.maps;
  rows.maps.vertex_curvature = nullptr;  // the mesh data is encoding's alone
  rows.maps.triangle_id = nullptr;
  rows.maps.id_colors = nullptr;
  NMBAKE_TRY(bake_tile(p, surface, outputs, debug_prefix, r, timer, progress, done.covered_texels,
                       rows.row_begin, rows.row_end, udim_tile, &rows));
  timer.start("write");
  NMBAKE_TRY(write_tile(o.tile_path, rows));
  timer.stop();
  detail::report_tile_rows(rows, o.tile_path, r, done);
  return Status::ok();
}

// One UDIM tile (1001 alone without <UDIM>): its outputs, the surface's UVs
// of the tile shifted into [0, 1]^2 (exact: whole-number shifts; `file_uvs`
// are the surface's own), then the whole map or the tile of rows asked for.
Status bake_udim_tile(const Prepared& p, const Meshes& m, const std::vector<glm::vec2>& file_uvs,
                      const LowSet* set, LowSurface& surface, int udim_tile, BakeReport& r, StageTimer& timer,
                      const ProgressFn& progress) {
  const BakeOptions& o = p.options;
  BakeReport::Tile done;
  done.tile = udim_tile;
  if (set != nullptr) done.set = set->name;
  std::vector<MapOutput> outputs = map_outputs(o);
  for (MapOutput& out : outputs) {
    out.path = udim_path(out.path, udim_tile);
    done.outputs.push_back(out.path);
    r.outputs.push_back(out.path);
  }
  std::string debug_prefix = o.debug_dump_prefix;
  if (m.udim || set != nullptr) {
    const glm::vec2 offset = m.udim ? udim_offset(udim_tile) : glm::vec2(0.0f);
    for (std::size_t i = 0; i < file_uvs.size(); ++i) surface.uv[i] = file_uvs[i] - offset;
    // (Appended in two steps: GCC 12 warns falsely (-Wrestrict) on "." + std::string here.)
    if (m.udim && !debug_prefix.empty()) debug_prefix.append(".").append(std::to_string(udim_tile));
  }
  if (set != nullptr) {
    // The other sets' triangles to another tile, out of the map (a whole
    // number: exact; UDIM UVs shifted into any tile stay within [-10, 100]).
    for (std::size_t t = 0; t < set->triangles.size(); ++t) {
      if (set->triangles[t]) continue;
      for (std::size_t k = 3 * t; k < 3 * t + 3; ++k) surface.uv[k].x -= 1024.0f;
    }
    if (!debug_prefix.empty()) debug_prefix.append(".").append(set->path_name);
  }
  if (o.tile_count > 0) {
    NMBAKE_TRY(bake_tile_rows(p, surface, outputs, debug_prefix, r, timer, progress, udim_tile, done));
  } else {
    NMBAKE_TRY(bake_tile(p, surface, outputs, debug_prefix, r, timer, progress, done.covered_texels, 0,
                         o.height, udim_tile, nullptr));
  }
  r.tiles.push_back(std::move(done));
  return Status::ok();
}

// Every map set the outputs name: each texture set's (<SET>; one for the
// whole low without it), for each UDIM tile.
Status bake_sets_and_tiles(const Prepared& p, const Meshes& m, LowSurface& surface, BakeReport& r,
                           StageTimer& timer, const ProgressFn& progress) {
  const std::vector<glm::vec2> file_uvs = m.udim || !m.sets.empty() ? surface.uv : std::vector<glm::vec2>{};
  if (m.sets.empty()) {
    for (const int tile : m.tiles)
      NMBAKE_TRY(bake_udim_tile(p, m, file_uvs, nullptr, surface, tile, r, timer, progress));
  }
  for (const LowSet& set : m.sets) {
    // The set's own options: its name in the outputs' and packs' paths.
    BakeOptions set_options = p.options;
    for (OutputSpec& out : set_options.outputs) out.path = replace_token(out.path, kSetToken, set.path_name);
    for (PackSpec& pack : set_options.packs) pack.path = replace_token(pack.path, kSetToken, set.path_name);
    const Prepared set_prepared{set_options, p.high, p.scene, p.rays, p.maps};
    for (const int tile : m.tiles)
      NMBAKE_TRY(bake_udim_tile(set_prepared, m, file_uvs, &set, surface, tile, r, timer, progress));
  }
  return Status::ok();
}

// The low mesh this bake unwrapped, with the normals it was baked with.
Status write_unwrapped_low(const BakeReport& r, StageTimer& timer, const Mesh& low) {
  timer.start("write");
  NMBAKE_TRY(save_mesh(r.unwrapped_low_path, low));
  timer.stop();
  return Status::ok();
}

}  // namespace

Status bake(const BakeOptions& o, BakeReport& r, const ProgressFn& progress, HighStore* store,
            HighReuse* reuse) {
  const Clock::time_point bake_begin = Clock::now();
  NMBAKE_TRY(validate_options(o));
  NMBAKE_TRY(check_tile_request(o));
  detail::report_options(o, r);
  StageTimer timer(r, progress);
  // The map's own buffers first (no file needed), then with the meshes'
  // sizes once they are loaded, before the BVH and the map are allocated.
  NMBAKE_TRY(check_bake_memory(o, MeshSize{}, MeshSize{}));

  HighReuse reused;
  Meshes meshes;
  NMBAKE_TRY(load_inputs(o, store, r, timer, meshes, reused.high_mesh));
  NMBAKE_TRY(prepare_low_mesh(o, r, timer, meshes));
  Scene scene;
  NMBAKE_TRY(prepare_scene(o, store, r, timer, meshes, scene, reused.high_scene));
  if (reuse != nullptr) *reuse = reused;
  const RayOptions rays = resolve_bake_rays(o, meshes, scene, r, timer);
  const BuiltHigh& high = *scene.high;
  const Prepared prepared{o, high.mesh, high.scene, rays, map_settings(o, r.low_diagonal, high.map_mesh)};
  detail::report_map_set(o, r);
  NMBAKE_TRY(bake_sets_and_tiles(prepared, meshes, scene.surface, r, timer, progress));
  if (r.unwrapped) NMBAKE_TRY(write_unwrapped_low(r, timer, meshes.low));
  detail::report_finish(bake_begin, r);
  return Status::ok();
}

}  // namespace nmbake
