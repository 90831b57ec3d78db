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
#include <functional>
#include <vector>

#include "nmbake/bake_options.hpp"
#include "nmbake/bake_report.hpp"
#include "nmbake/common.hpp"
#include "nmbake/maps.hpp"

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
// the calling thread only.
using ProgressFn = std::function<void(const char* stage, double fraction)>;

// Runs one bake. Nothing is written unless every stage succeeded; each output
// is written atomically.
Status bake(const BakeOptions& options, BakeReport& report, const ProgressFn& progress = {});

}  // namespace nmbake
