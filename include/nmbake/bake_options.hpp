// What a bake is asked to do: its options (plain data; one default per
// field, here), the outputs they name, and their checks. How options arrive
// (a flag, a job file's key, a live request) is the option table's business
// (options.hpp); the pipeline itself is bake.hpp.
#pragma once

#include <cstdint>
#include <string>
#include <vector>

#include "nmbake/adaptive.hpp"
#include "nmbake/common.hpp"
#include "nmbake/encode.hpp"
#include "nmbake/image.hpp"
#include "nmbake/maps.hpp"
#include "nmbake/parts.hpp"
#include "nmbake/trace.hpp"

namespace nmbake {

struct OutputSpec {
  std::string path;  // may hold <UDIM> (udim.hpp): one map per UV tile; <MAP> (maps.hpp): one per map
  PixelFormat format = PixelFormat::png16;
  // Given explicitly (--format, a job file's `format`): every map is written
  // in it. Otherwise `.png` takes each map's own depth (maps.hpp).
  bool format_given = false;
};

// A packed output (README, "Packing and naming"): channels of several maps
// in one file, e.g. "orm_<UDIM>.png=r:ao,g:roughness,b:metallic" (glTF's
// ORM) or "mask.png=r:metallic,g:ao,b:0,a:1-roughness" (Unity's mask map).
struct PackChannel {
  bool constant = false;
  float value = 0.0f;  // constant: the value in [0, 1]
  MapKind map = MapKind::normal;
  int component = 0;    // of a map of three channels: .r .g .b (0, 1, 2)
  bool invert = false;  // 1 - the value as the map's integer file stores it
  friend bool operator==(const PackChannel&, const PackChannel&) = default;
};
struct PackSpec {
  std::string path;                   // may hold <UDIM>; never <MAP>
  std::vector<PackChannel> channels;  // r, g, b, a in order: 1, 3 or 4 of them
  friend bool operator==(const PackSpec&, const PackSpec&) = default;
};
// "FILE=r:SRC,g:SRC,..." with SRC a number in [0, 1], MAP, MAP.r|g|b or
// 1-MAP(.c); bad_input saying what is wrong. The maps need not be known
// to be baked here (validate_options() checks that).
Status parse_pack(const std::string& text, PackSpec& out);
std::string pack_text(const PackSpec& pack);
// The format of a packed output's path: `.png` and `.tga` 8-bit, `.tif`
// 16-bit, `.exr` float (write_pack_files(), bake.hpp).
PixelFormat pack_format(const std::string& path);

// The map set's auto AO and thickness distance: this share of the low mesh's
// bounding-box diagonal.
constexpr float kAutoMapDistancePercent = 10.0f;

// The high files for messages: the one path, or "a.obj + b.obj".
std::string high_name(const std::vector<std::string>& high_paths);

struct BakeOptions {
  std::string low_path;
  // One or more files, loaded as one mesh (load_meshes(), load.hpp): --high
  // repeated, a job's `high = [...]`.
  std::vector<std::string> high_paths;
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
  // The rays as asked for (trace.hpp): distances, hit rule, cage, retry,
  // backfaces; a cage mesh (cage_path) implies CageMode::mesh.
  RaySettings rays;
  // How hits become the normal map (encode.hpp): space, green, high
  // normals, tangent encode, and how the engine decodes (`decode`, see
  // `preset` below). out_row_begin is the bake's own (set per tile of rows).
  EncodeOptions encode;
  // The high's normal textures in the normal maps (encode.hpp). auto, the
  // default: on when a material the high's triangles use names one (read
  // from OBJ + MTL and glTF highs); an artist who put a detail normal map on
  // the high expects it in the bake, and a high without one bakes the bytes
  // it always did.
  HighNormalMaps high_normal_maps = HighNormalMaps::automatic;
  TangentBasis tangent_basis =
      TangentBasis::mikktspace;  // file: the low mesh's own tangents; others: comparison only
  int uv_set = 0;                // the low mesh's UV set (glTF TEXCOORD_N, FBX UV channel N)
  BuildQuality build_quality =
      BuildQuality::low;  // measured: 4-6x faster builds than medium, rays as fast (BENCHMARKS.md)
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
  // preset the green convention and encode.decode came from ("" none; for
  // the report: explicit flags may have overridden parts of it).
  // encode.decode: how the engine decodes the map; the encode stores its
  // exact inverse. `dither`: 8-bit outputs (png8, tga) ordered-dithered
  // instead of rounded.
  std::string preset;
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
  Distance thickness_distance;               // auto: as ao_distance
  IdSource id_source = IdSource::automatic;  // what the id map colours (maps.hpp)
  std::string id_palette;                    // the id map's colours by name (IdPalette); empty: none
  std::vector<PackSpec> packs;               // packed outputs, written beside the maps
};

// One file a bake writes per UV tile: an output for one map.
struct MapOutput {
  std::string path;                         // <MAP> replaced; may still hold <UDIM>
  PixelFormat format = PixelFormat::png16;  // resolved for the map (map_format)
  MapKind map = MapKind::normal;
};
// Every output once per map, in output order, the maps in the set's order.
std::vector<MapOutput> map_outputs(const BakeOptions& options);
std::vector<MapOutput> map_outputs(const std::vector<OutputSpec>& outputs, const std::vector<MapKind>& maps);
// With several maps every output path must name the map (<MAP>): bad_input
// naming the first that does not.
Status check_map_tokens(const std::vector<OutputSpec>& outputs, const std::vector<MapKind>& maps);

// <LOW> in the outputs' and packs' paths becomes the low file's stem
// (sets.hpp); the command line and job files call it once every option is
// read (validate_options() refuses a path that still holds it).
void resolve_low_token(BakeOptions& options);

// Checks options that need no file: sizes, sample count, outputs and formats,
// distances against kMaxDistance (and percentages against
// kMaxDistanceDiagonals). The unwrap gutter is checked by bake() when the low
// mesh turns out to need an unwrap; distances against the diagonal once the
// low mesh is loaded.
Status validate_options(const BakeOptions& options);
// The part of validate_options() that reads nothing but the values: sizes,
// samples, ranges, distances. A job file checks each bake with it as it is
// read (the outputs' folders and formats wait for validate_options()).
Status validate_option_values(const BakeOptions& options);

// Checks what can be known of the input files without loading them, so a
// job finds a bad path in its last bake before the first bake runs: every
// mesh path is non-empty, has no NUL byte, names a regular file with a
// supported extension (.obj, .ply, .gltf, .glb, .fbx, .dae, .3ds, .stl) that can be opened, and starts as its
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

}  // namespace nmbake
