// Tasks, keys and tiles (DESIGN.md, "Growing the pipeline"): a bake is a
// pure function of its inputs' bytes and its options, so
//   * it has a key: XXH3-128 (xxHash) of the low, high and cage files' bytes
//     and of every option that can change an output byte, in a canonical
//     text form (bake_key_text), with the output formats and the nmbake
//     version. Not in the key: paths (the same meshes elsewhere give the
//     same maps), threads and band size (tested not to change a byte), the
//     report and debug-dump paths. `auto` distances enter as "auto": they
//     are a function of the meshes, which are in the key;
//   * any band of rows can be baked alone (a tile: BakeOptions::tile_index of tile_count, bake()) and the
//     tiles merged before dilation give the bytes of the whole bake, for
//     every map of a map set (a tile holds each map's raw texels; the merge
//     takes auto ranges from the whole map, as the whole bake does).
// Scheduling is left to existing engines (plan.hpp writes Ninja files,
// Slurm scripts and JSON task lists).
#pragma once

#include <cstdint>
#include <string>
#include <vector>

#include "nmbake/bake_options.hpp"
#include "nmbake/common.hpp"
#include "nmbake/maps.hpp"

namespace nmbake {

inline constexpr const char* kNmbakeVersion = "0.1.0";

struct BakeKey {
  std::uint64_t high = 0, low = 0;
  std::string hex() const;  // 32 lower-case hex digits
  bool operator==(const BakeKey&) const = default;
};

// The options part of the key, one `name value` line each.
std::string bake_key_text(const BakeOptions& options);
// Hashes the input files and the options. bad_input naming a file that
// cannot be read.
Status bake_key(const BakeOptions& options, BakeKey& key);

// The size and XXH3-64 of a regular file's bytes, for what checks a file is
// still the one a bake read (the cache's input files, a live session's
// kept meshes). Opened without blocking and refused unless regular: a FIFO
// or device put in a file's place is an answer, never a wait. "" or why not
// (the path and the reason).
std::string hash_file_contents(const std::string& path, std::uint64_t& size, std::uint64_t& hash);

// Rows [begin, end) of tile `index` (0-based) of `count` over a map of
// `height` rows: bands of whole kRasterTileSize-row raster tiles, as even as
// that allows (with more tiles than 32-row bands some tiles are empty).
void tile_rows(int height, int index, int count, int& begin, int& end);
// "I/N" with 1 <= I <= N (1-based, as users count), into index = I - 1.
bool parse_tile_spec(const std::string& text, int& index, int& count);

// A baked tile: every map's rows [row_begin, row_end) before dilation, their
// coverage, and what merging needs to finish and write as the whole bake
// does (the key, the map's size and padding, the outputs the bake names, the
// map set's settings and what its bands counted).
struct TileData {
  BakeKey key;
  int width = 0, height = 0;  // of the whole map
  int row_begin = 0, row_end = 0;
  int index = 0, count = 1;
  int padding = 0;
  bool dither = true;               // the bake's BakeOptions::dither, for the 8-bit outputs merge writes
  std::vector<OutputSpec> outputs;  // as the bake names them (<MAP> unreplaced; format_given kept)
  // The maps and what finishing, the files and the report read of their
  // settings: the given height and curvature ranges (0: auto, from the whole
  // map), the resolved AO and thickness rays and distances (thickness: the
  // white of integer files), the position map's box. Nothing else is
  // written (the encode options, the mesh data: encoding only).
  MapSettings maps;
  MapCounts counts;                        // what the tile's bands counted, per map
  std::vector<std::vector<float>> texels;  // per map: (row_end - row_begin) * width * channels
  std::vector<std::uint8_t> coverage;      // (row_end - row_begin) * width
};
// Written to a temporary file and renamed (Status::io on failure).
Status write_tile(const std::string& path, const TileData& tile);
// bad_input naming the file on anything that is not a complete tile file of
// this nmbake's format (one of an older format says so).
Status read_tile(const std::string& path, TileData& tile);

struct MergeReport {
  BakeKey key;
  int width = 0, height = 0, tiles = 0;
  std::vector<std::string> outputs;
  std::vector<MapReport> maps;  // each map's figures, as the whole bake reports them
  DilateStats dilate;
  double read_seconds = 0.0, dilate_seconds = 0.0, write_seconds = 0.0;
  std::string to_json() const;
};

// Checks that the tiles are all of one bake (key, size, count, padding, map
// set) and together hold every tile exactly once, then finishes every map as
// the whole bake does (auto ranges from the whole map, dilation: MapSet) and
// writes `outputs` (empty: the outputs the bake named; with several maps
// each path needs <MAP>). The bytes are those of the whole bake.
// bad_input naming the tile file on a mixed, missing or repeated tile.
// Without `outputs`, the paths a tile names are written only inside the
// current folder or the tile file's folder (a tile is data from another
// machine), unless they are exactly `expected` (what a plan, which read the
// job file, knows the bake names: its merge task passes them).
Status merge_tiles(const std::vector<std::string>& tile_paths, const std::vector<OutputSpec>& outputs,
                   MergeReport& report, const std::vector<std::string>& expected = {});

}  // namespace nmbake
