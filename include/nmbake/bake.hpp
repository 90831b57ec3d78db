// The whole pipeline in one function (DESIGN.md):
//   load -> prepare (normals, tangents, cage) -> raster -> trace -> encode
//        -> dilate -> write
// Options are plain data, kept apart from argument parsing: the library never
// sees argv. Every numerical fallback taken on the way is counted in the
// report.
#pragma once

#include <cstdint>
#include <functional>
#include <string>
#include <vector>

#include "nmbake/adaptive.hpp"
#include "nmbake/common.hpp"
#include "nmbake/dilate.hpp"
#include "nmbake/encode.hpp"
#include "nmbake/image.hpp"
#include "nmbake/load.hpp"
#include "nmbake/maps.hpp"
#include "nmbake/parts.hpp"
#include "nmbake/raster.hpp"
#include "nmbake/surface.hpp"
#include "nmbake/trace.hpp"
#include "nmbake/unwrap.hpp"

namespace nmbake {

// A ray distance as the user gave it: scene units, percent of the low mesh's
// bounding-box diagonal, or estimated from the meshes.
struct Distance {
  enum class Kind : std::uint8_t { automatic, absolute, percent };
  Kind kind = Kind::automatic;
  float value = 0.0f;
};
// Limits of a ray distance (README, "Limits"): front and back are each at
// most kMaxDistance scene units and at most kMaxDistanceDiagonals times the
// low mesh's bounding-box diagonal. With kMaxCoordinate (mesh.hpp) this keeps
// every ray origin and range finite and far inside what Embree accepts
// (1.8e18); a longer ray could only find surfaces the low mesh does not bake.
constexpr float kMaxDistance = 1e12f;
constexpr float kMaxDistanceDiagonals = 1000.0f;

// "auto", "0.05", "2%". Returns false on anything else (negative, NaN, junk).
bool parse_distance(const std::string& text, Distance& out);
std::string to_string(const Distance& distance);

struct OutputSpec {
  std::string path;  // may hold <UDIM> (udim.hpp): one map per UV tile; <MAP> (maps.hpp): one per map
  PixelFormat format = PixelFormat::png16;
  // Given explicitly (--format, a job file's `format`): every map is written
  // in it. Otherwise `.png` takes each map's own depth (maps.hpp).
  bool format_given = false;
};

// The map set's auto AO and thickness distance: this share of the low mesh's
// bounding-box diagonal.
constexpr float kAutoMapDistancePercent = 10.0f;

struct BakeOptions {
  std::string low_path;
  std::string high_path;
  std::string cage_path;  // empty: averaged cage
  std::vector<OutputSpec> outputs;
  int width = 2048;
  int height = 2048;
  int samples = 4;
  // `--samples adaptive`: one sample per texel, then adaptive.max_samples
  // (the fixed pattern) where the first pass says the normal varies
  // (adaptive.hpp); `samples` is then unused.
  bool adaptive = false;
  AdaptiveOptions adaptive_options;
  NormalSpace space = NormalSpace::tangent;
  GreenChannel green = GreenChannel::up;
  Distance front;  // auto
  Distance back;   // auto
  HitRule hit = HitRule::first;
  CageMode cage_mode = CageMode::banded;  // `mesh` is implied by cage_path
  float edge_band = kDefaultEdgeBand;     // the banded cage's band, in units of front + back
  // Misses traced again out and in up to the distance probes' reach
  // (trace.hpp): `automatic` = when neither distance nor a cage is given.
  enum class Retry : std::uint8_t { automatic, on, off };
  Retry retry_misses = Retry::automatic;
  bool ignore_backfaces = false;
  HighNormals high_normals = HighNormals::smooth;
  TangentEncode tangent_encode = TangentEncode::inverse;
  TangentBasis tangent_basis = TangentBasis::mikktspace;  // file: the low mesh's own tangents; others: comparison only
  int uv_set = 0;  // the low mesh's UV set (glTF TEXCOORD_N, FBX UV channel N)
  BuildQuality build_quality = BuildQuality::low;  // measured: 4-6x faster builds than medium, rays as fast (BENCHMARKS.md)
  BvhMemory bvh_memory = BvhMemory::automatic;
  int padding = 16;
  // A low mesh without UVs is unwrapped (atlas of the map's smaller side,
  // this many texels between charts) and written beside the first map as
  // <map stem>_low_uv.obj, with the normals it was baked with.
  int unwrap_gutter = 4;
  std::string debug_dump_prefix;  // non-empty: also write coverage / miss / distance images
  // Samples per band of rows (raster, trace and encode run band by band);
  // 0 = about 1M. Changes memory use only, never the result (tested).
  std::size_t band_samples = 0;
  // Parts into bake groups (parts.hpp): names matched by suffix, or groups.
  MatchOptions match;
  int groups_per_scene = 0;  // SceneGroups::groups_per_scene: 0 automatic (for benchmarks)
  // A tile (task.hpp): tile_count > 0 bakes only the rows of tile
  // tile_index and writes them, before dilation, to tile_path instead of
  // the outputs (`nmbake merge` dilates and writes). Not with <UDIM>.
  int tile_index = 0;
  int tile_count = 0;
  std::string tile_path;
  // Memory the bake may use (budget.hpp): refused up front, with the numbers,
  // when its estimate is larger. 0: the memory available to the process.
  std::uint64_t max_memory_bytes = 0;
  // Outputs as engines want them (preset.hpp). `preset` names the engine
  // preset the green convention and `decode` came from ("" none; for the
  // report: explicit flags may have overridden parts of it). `decode`: how
  // the engine decodes the map; the encode stores its exact inverse.
  // `dither`: 8-bit outputs (png8, tga) ordered-dithered instead of rounded.
  std::string preset;
  NormalDecode decode;
  bool dither = true;
  // The map set (maps.hpp): the maps baked from the same rays, each output
  // written once per map (with several maps every output path holds <MAP>),
  // and their options. The default, `normal` alone, is the bake as before.
  std::vector<MapKind> maps{MapKind::normal};
  float height_range = 0.0f;     // scene units: heights in [-R, R] fill an integer file; 0: auto
  float curvature_range = 0.0f;  // 1/scene units, the same for mean curvature; 0: auto
  int ao_rays = 64;              // per sample
  Distance ao_distance;          // auto: kAutoMapDistancePercent of the low diagonal
  int thickness_rays = 16;
  Distance thickness_distance;   // auto: as ao_distance
  IdSource id_source = IdSource::automatic;  // what the id map colours (maps.hpp)
};

// One file a bake writes per UV tile: an output for one map.
struct MapOutput {
  std::string path;  // <MAP> replaced; may still hold <UDIM>
  PixelFormat format = PixelFormat::png16;  // resolved for the map (map_format)
  MapKind map = MapKind::normal;
};
// Every output once per map, in output order, the maps in the set's order.
std::vector<MapOutput> map_outputs(const BakeOptions& options);
std::vector<MapOutput> map_outputs(const std::vector<OutputSpec>& outputs, const std::vector<MapKind>& maps);
// The write stage of a map set after MapSet::finish(): every file at once
// (files side by side, each writer parallel inside), integer files of ranged maps stored
// through MapSet::integer_mapping(). 8-bit files dithered when `dither`.
Status write_map_files(MapSet& maps, const std::vector<MapOutput>& files, bool dither);
// The set's reports (MapSet::reports(tile)), each with the files of its map.
std::vector<MapReport> map_file_reports(const MapSet& maps, const std::vector<MapOutput>& files, int tile);
// With several maps every output path must name the map (<MAP>): bad_input
// naming the first that does not.
Status check_map_tokens(const std::vector<OutputSpec>& outputs, const std::vector<MapKind>& maps);

// Checks options that need no file: sizes, sample count, outputs and formats,
// distances against kMaxDistance (and percentages against
// kMaxDistanceDiagonals). The unwrap gutter is checked by bake() when the low
// mesh turns out to need an unwrap; distances against the diagonal once the
// low mesh is loaded.
Status validate_options(const BakeOptions& options);

// Checks what can be known of the input files without loading them, so a
// job finds a bad path in its last bake before the first bake runs: every
// mesh path is non-empty, has no NUL byte, names a regular file with a
// supported extension (.obj, .ply) that can be opened, and starts as its
// format must (PLY: "ply"; OBJ: text, no NUL byte in its first 4 KiB); every
// output, report and debug-dump path has no NUL byte. bad_input naming the
// path (through printable_text) and the reason.
Status check_bake_inputs(const BakeOptions& options);

// Checks what the low mesh alone decides, so that a job finds it in a later
// bake before the first bake writes its maps: the low mesh loads as bake()
// loads it (a glTF's or FBX's UV set `uv_set` exists), its part names fit the
// groups (check_low_parts), and UVs outside [0, 1]^2 come with <UDIM> in the
// outputs. Loads the low mesh (small); never the high mesh or the cage. The
// errors are bake()'s own, word for word.
Status check_bake_low_mesh(const BakeOptions& options);

struct StageTime {
  std::string name;
  double seconds = 0.0;
};

struct BakeReport {
  std::string low_path, high_path, cage_path;
  std::vector<std::string> outputs;
  int width = 0, height = 0, samples = 0;
  std::uint64_t low_triangles = 0, high_triangles = 0, high_vertices = 0;
  float front = 0.0f, back = 0.0f;  // resolved, scene units
  bool distances_estimated = false;
  std::string cage_mode;         // banded | averaged | interpolated | mesh
  float edge_band = 0.0f;        // banded: the band's width / (front + back)
  float retry_reach = 0.0f;      // 0: misses not retried
  bool compact_bvh = false;  // the BVH was built in Embree's compact layout (--bvh)
  float low_diagonal = 0.0f;
  LoadStats low_load, high_load;
  MeshStats low_mesh, high_mesh;
  TangentStats tangents;
  RasterStats raster;
  TraceStats trace;
  EncodeStats encode;
  DilateStats dilate;
  // How the map was encoded (BakeOptions::preset, decode, dither).
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
  // The id map: what it coloured (part or material) and each name's colour.
  IdSource id_source = IdSource::part;
  std::vector<std::pair<std::string, glm::vec3>> id_names;
  std::vector<StageTime> stages;
  double total_seconds = 0.0;
  std::uint64_t peak_rss_bytes = 0;
  int threads = 0;

  double miss_rate() const;   // misses / samples traced
  double coverage() const;    // covered texels / all texels
  std::string to_json() const;
  std::string summary_line() const;
};

// Called with a stage name and the fraction done (0..1) of that stage; from
// the calling thread only.
using ProgressFn = std::function<void(const char* stage, double fraction)>;

// Rows per band of a width x height map at `samples` per texel: about
// `band_samples` samples (0: 1M), a multiple of kRasterTileSize so bands
// start on tile rows, at most `height`.
int band_rows(int width, int height, int samples, std::size_t band_samples = 0);

// Runs one bake. Nothing is written unless every stage succeeded; each output
// is written atomically.
Status bake(const BakeOptions& options, BakeReport& report, const ProgressFn& progress = {});

}  // namespace nmbake
