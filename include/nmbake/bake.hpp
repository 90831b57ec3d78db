// The whole pipeline in one function (DESIGN.md):
//   load -> prepare (normals, tangents, cage) -> raster -> trace -> encode
//        -> dilate -> write
// Options are plain data, kept apart from argument parsing: the library never
// sees argv. Every numerical fallback taken on the way is counted in the
// report.
//
// bake_options.hpp holds what a bake is asked to do, bake_report.hpp what it
// did; this header is the entry point.
#pragma once

#include <cstddef>
#include <cstdint>
#include <functional>
#include <memory>
#include <string>
#include <utility>
#include <vector>

#include "nmbake/bake_options.hpp"
#include "nmbake/bake_report.hpp"
#include "nmbake/common.hpp"
#include "nmbake/load.hpp"
#include "nmbake/maps.hpp"
#include "nmbake/mesh.hpp"
#include "nmbake/trace.hpp"

namespace nmbake {

// The write stage of a map set after MapSet::finish(): every file at once
// (files side by side, each writer parallel inside), integer files of ranged maps stored
// through MapSet::integer_mapping(). 8-bit files dithered when `dither`.
Status write_map_files(MapSet& maps, const std::vector<MapOutput>& files, bool dither);
// The packed outputs of a UDIM tile's finished maps (bake_options.hpp
// PackSpec): each channel as the map's own integer file stores it (mapped,
// sRGB-encoded for colour maps, quantised and dithered with the map's own
// pattern), so it equals that file's channel byte for byte; an inverted
// channel is 1 - that value. `.png` and `.tga`: 8-bit; `.tif`: 16-bit;
// `.exr`: float, the raw texels. Appends the paths written.
Status write_pack_files(MapSet& maps, const std::vector<PackSpec>& packs, int udim_tile, bool dither,
                        std::vector<std::string>& written);
// The set's reports (MapSet::reports(tile)), each with the files of its map.
std::vector<MapReport> map_file_reports(const MapSet& maps, const std::vector<MapOutput>& files, int tile);

// Called with a stage name and the fraction done (0..1) of that stage; from
// the calling thread only. It may throw to cancel the bake: the exception
// leaves bake() as it is. The write stage announces itself ("write", 0)
// before the first file is opened, so a listener that throws there (or
// earlier) leaves no map written; it should not throw from a later call
// (maps are written by then).
using ProgressFn = std::function<void(const char* stage, double fraction)>;

// The high side of a bake, as bake() hands it between its stages: plain
// data a caller may keep and hand back to a later bake (a live session,
// `nmbake serve`), so that a high mesh is read and its BVH built once.
// A file read besides the mesh files (an MTL library, a glTF's buffers, a
// texture) with the XXH3-64 of its bytes (0: it could not be read): checked
// again before the state is reused.
using FileHash = std::pair<std::string, std::uint64_t>;
// What load_inputs() reads of the high files.
struct LoadedHigh {
  Mesh mesh;
  LoadStats load;
  bool normal_maps = false;  // --high-normal-maps resolved
  std::uint64_t normal_textures = 0, normal_textures_skipped = 0;
  std::vector<FileHash> files;  // load.files, hashed
};
// What the rays are traced against on the high side: the mesh with its
// normals prepared, grouped and padded (the BVH's shared buffers), the map
// set's data of it, the groups' ranges and the BVH.
struct BuiltHigh {
  Mesh mesh;
  MapMeshData map_mesh;
  SceneGroups groups;
  HighScene scene;
  MeshStats stats;  // the report's high_mesh counters
  std::uint64_t triangles_used = 0;
  std::vector<FileHash> files;  // the textures the map set read, hashed
};
// Where bake() looks for the high side before it loads or builds it, and
// leaves what it loaded or built. The keys are bake()'s: the high files'
// paths, sizes and XXH3-64 of their bytes, and every option that changes
// what was loaded (LoadedHigh) or built from it (BuiltHigh: also the
// groups' high triangles, the id palette's colours, build quality, backface
// filter, BVH layout). Called from the thread that runs bake().
class HighStore {
 public:
  virtual ~HighStore() = default;
  virtual std::shared_ptr<const LoadedHigh> find_loaded(const std::string& key) = 0;
  virtual void keep_loaded(const std::string& key, std::shared_ptr<const LoadedHigh> high) = 0;
  virtual std::shared_ptr<const BuiltHigh> find_built(const std::string& key) = 0;
  virtual void keep_built(const std::string& key, std::shared_ptr<const BuiltHigh> high) = 0;
};

// What bake() took from a HighStore.
struct HighReuse {
  bool high_mesh = false;   // LoadedHigh found (and its files verified)
  bool high_scene = false;  // BuiltHigh found
};

// Runs one bake. Nothing is written unless every stage succeeded; each output
// is written atomically. With `store`, the high side is taken from it when
// it holds the same (same bytes, same options: the maps are byte for byte a
// cold bake's) and left in it otherwise; `reuse` says which was taken.
Status bake(const BakeOptions& options, BakeReport& report, const ProgressFn& progress = {},
            HighStore* store = nullptr, HighReuse* reuse = nullptr);

}  // namespace nmbake
