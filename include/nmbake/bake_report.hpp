// What a bake did: the figures of every stage, its fallbacks and its
// outputs (BakeReport::to_json() is the report file of `--report`).
#pragma once

#include <cstdint>
#include <string>
#include <utility>
#include <vector>

#include "nmbake/dilate.hpp"
#include "nmbake/encode.hpp"
#include "nmbake/load.hpp"
#include "nmbake/maps.hpp"
#include "nmbake/parts.hpp"
#include "nmbake/raster.hpp"
#include "nmbake/trace.hpp"
#include "nmbake/unwrap.hpp"

namespace nmbake {

struct StageTime {
  std::string name;
  double seconds = 0.0;
};

struct BakeReport {
  std::string low_path, cage_path;
  std::vector<std::string> high_paths;
  // The other files the bake read: MTL libraries, glTF buffers, textures
  // (LoadStats::files, TextureSet::files), in the order read. A cache entry
  // checks them (cache.hpp).
  std::vector<std::string> input_files;
  std::vector<std::string> outputs;
  int width = 0, height = 0, samples = 0;
  std::uint64_t low_triangles = 0, high_triangles = 0, high_vertices = 0;
  float front = 0.0f, back = 0.0f;  // resolved, scene units
  bool distances_estimated = false;
  std::string cage_mode;     // banded | averaged | interpolated | mesh
  float edge_band = 0.0f;    // banded: the band's width / (front + back)
  float retry_reach = 0.0f;  // 0: misses not retried
  bool compact_bvh = false;  // the BVH was built in Embree's compact layout (--bvh)
  float low_diagonal = 0.0f;
  LoadStats low_load, high_load;
  MeshStats low_mesh, high_mesh;
  TangentStats tangents;
  RasterStats raster;
  TraceStats trace;
  EncodeStats encode;
  DilateStats dilate;
  // How the map was encoded (BakeOptions::preset, encode.decode, dither).
  std::string preset;
  GreenChannel green = GreenChannel::up;
  NormalDecode decode;
  bool dither = true;
  std::uint64_t estimate_probes = 0, estimate_probe_misses = 0;
  // Adaptive sampling: max_samples > 0 when it ran.
  struct Adaptive {
    int max_samples = 0;
    std::uint64_t first_pass_rays = 0;
    std::uint64_t refined_texels = 0;  // taken by level 1 (4 samples)
    // Per level (adaptive_levels(): 4, then max_samples): texels and rays.
    std::vector<std::uint64_t> level_texels, level_rays;
    std::uint64_t halo_rays = 0;  // a tile's first pass of the rows just outside it (not in `trace`)
  } adaptive;
  double rays_per_texel() const;   // rays traced / covered texels
  bool unwrapped = false;          // the low mesh had no UVs and was unwrapped
  std::string unwrapped_low_path;  // where the unwrapped low mesh was written
  UnwrapReport unwrap;
  // Bake groups (empty: every low triangle against every high triangle).
  struct Group {
    BakeGroup parts;
    float front = 0.0f, back = 0.0f;  // resolved for this group
  };
  std::vector<Group> groups;
  std::vector<std::string> unused_high_parts;
  std::uint64_t high_triangles_used = 0;  // in some group (high_triangles without groups)
  int scenes = 0;                         // Embree scenes built
  // UDIM tiles baked, and the maps each wrote (1001 alone without <UDIM>).
  struct Tile {
    int tile = 1001;
    std::string set;  // the texture set's material (sets.hpp); "" without <SET>
    std::vector<std::string> outputs;
    std::uint64_t covered_texels = 0;
  };
  std::vector<Tile> tiles;
  // A tile bake: its rows and file (tile_count 0 otherwise).
  int tile_index = 0, tile_count = 0, tile_row_begin = 0, tile_row_end = 0;
  std::string tile_path;
  std::string key;  // the bake key (task.hpp) when it was computed: tiles, caching
  bool cached = false;
  // The map set: what each map of each UDIM tile used and counted (maps.hpp).
  std::vector<MapKind> maps;
  std::vector<MapReport> map_reports;
  std::uint64_t curvature_degenerate_triangles = 0;  // vertex_mean_curvature(): no weight
  std::uint64_t curvature_isolated_vertices = 0;     // no weighted triangle: H = 0
  // The high's normal textures (--high-normal-maps): whether the normal maps
  // read them, the used materials with one, those auto left out (an image
  // the loader cannot point at), and the high's tangents for them.
  bool high_normal_maps = false;
  std::uint64_t high_normal_textures = 0, high_normal_textures_skipped = 0;
  TangentStats high_tangents;
  double high_tangent_seconds = 0.0;
  // The id map: what it coloured (part or material) and each name's colour.
  IdSource id_source = IdSource::part;
  std::vector<std::pair<std::string, glm::vec3>> id_names;
  std::vector<StageTime> stages;
  double total_seconds = 0.0;
  std::uint64_t peak_rss_bytes = 0;
  int threads = 0;

  double miss_rate() const;  // misses / samples traced
  double coverage() const;   // covered texels / all texels
  std::string to_json() const;
  std::string summary_line() const;
};

}  // namespace nmbake
