// Private to src/bake/: how bake() fills its report (report.cpp), one
// function per thing the pipeline hands over, so the pipeline's phases
// (bake.cpp) only run stages.
#pragma once

#include <string>

#include "bake/pipeline.hpp"
#include "nmbake/bake_options.hpp"
#include "nmbake/bake_report.hpp"
#include "nmbake/maps.hpp"
#include "nmbake/parts.hpp"
#include "nmbake/raster.hpp"
#include "nmbake/surface.hpp"
#include "nmbake/task.hpp"
#include "nmbake/trace.hpp"

namespace nmbake::detail {

// A fresh report with what the options ask for: paths, outputs, size,
// samples, preset, green, decode, dither and the thread count.
void report_options(const BakeOptions& o, BakeReport& r);
// The mesh sizes once the low mesh has its UVs (the high one as loaded).
void report_mesh_sizes(const Mesh& low, const Mesh& high, BakeReport& r);
// A low mesh unwrapped by the bake, written to `path` with the maps.
void report_unwrapped(const std::string& path, BakeReport& r);
// The map set's mesh data: curvature fallbacks, what the id map colours.
void report_map_mesh(const MapMeshData& map_mesh, BakeReport& r);
// The low surface's fallbacks (added to those of its normals) and diagonal.
void report_low_surface(const SurfaceStats& stats, float low_diagonal, BakeReport& r);
void report_scene(const HighScene& scene, BakeReport& r);
// The resolved rays, the estimate when `estimated`, and each group's distances.
void report_rays(const RayOptions& rays, const DistanceEstimate& estimate, bool estimated,
                 const BakeGroups& groups, BakeReport& r);
// The map set about to be baked; the outputs then listed UDIM tile by tile.
void report_map_set(const BakeOptions& o, BakeReport& r);
// One band's raster counts added (degenerate UV triangles: the same in every band).
void report_raster_band(const RasterStats& band, BakeReport& r);
// A tile of rows written to `tile_path` instead of the outputs.
void report_tile_rows(const TileData& rows, const std::string& tile_path, BakeReport& r,
                      BakeReport::Tile& done);
// Total time since `begin` and the peak memory.
void report_finish(Clock::time_point begin, BakeReport& r);

}  // namespace nmbake::detail
