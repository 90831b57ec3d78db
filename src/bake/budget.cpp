// The bake's memory estimate (budget.hpp) against what the process may use
// (memory.hpp).
#include "nmbake/budget.hpp"

#include <algorithm>
#include <cmath>
#include <string>

#include "nmbake/bake_options.hpp"
#include "nmbake/task.hpp"

namespace nmbake {

namespace {

// The rows a bake holds in memory: a tile bake (task.hpp) only its own.
int baked_rows(const BakeOptions& o) {
  if (o.tile_count <= 0 || o.tile_index < 0 || o.tile_index >= o.tile_count) return o.height;
  int begin = 0, end = 0;
  tile_rows(o.height, o.tile_index, o.tile_count, begin, end);
  return end - begin;
}

std::string map_text(const BakeOptions& o) {
  std::string text = std::to_string(o.width) + "x" + std::to_string(o.height) + " map at " +
                     std::to_string(o.samples) + " spp";
  if (baked_rows(o) != o.height) {
    text = "tile " + std::to_string(o.tile_index + 1) + "/" + std::to_string(o.tile_count) + " (" +
           std::to_string(baked_rows(o)) + " rows) of a " + text;
  }
  return text;
}

}  // namespace

BakeMemory estimate_bake_memory(const BakeOptions& o, const MeshSize& low, const MeshSize& high) {
  BakeMemory m;
  // A tile bake's image and coverage hold its rows only (bake_tile).
  const std::uint64_t texels =
      static_cast<std::uint64_t>(o.width) * static_cast<std::uint64_t>(baked_rows(o));
  // Per texel: the float RGB image (12), coverage (1), dilation's rings (2:
  // 20 bytes a ring texel, rings about a tenth of the map at most), the
  // debug images (36). Measured: a 8192^2 bake peaks at 0.92 GB, this says
  // 1.14 GB.
  m.map = texels * (12 + 1 + 2) + (o.debug_dump_prefix.empty() ? 0 : texels * 36);
  // One band of samples: raster (triangle 4 + bary 8) and trace (triangle 4,
  // bary 8, distance 4): 28 bytes, plus a coverage byte per texel.
  const int rows = band_rows(o.width, baked_rows(o), o.samples, o.band_samples);
  const std::uint64_t band_texels = static_cast<std::uint64_t>(rows) * static_cast<std::uint64_t>(o.width);
  m.bands = band_texels * static_cast<std::uint64_t>(o.samples) * 28 + band_texels;
  // Low: the indexed mesh, its half-edge copy for tangents (and unwrap), and
  // the per-corner surface arrays (3 x 72 bytes): about 600 bytes a triangle.
  m.low = low.vertices * 64 + low.triangles * 600;
  // High: positions and normals (24 a vertex, padded), indices (12) and the
  // BVH with its build (DESIGN.md's budget: 100 a triangle all told).
  m.high = high.vertices * 24 + high.triangles * 112;
  // The map set beyond the normal map: each map's float image (4 bytes a
  // channel), its coverage copy for dilation (1) and an integer file's
  // mapped copy (4 a channel); per band sample, AO visibility and the bent
  // direction (16) or thickness (4); the curvature per high vertex (4).
  for (const MapKind map : o.maps) {
    if (map == MapKind::normal) continue;
    const MapTraits t = map_traits(map);
    m.map += texels * (8 * static_cast<std::uint64_t>(t.channels) + 1);
    if (t.occlusion_rays) m.bands += band_texels * static_cast<std::uint64_t>(o.samples) * 16;
    if (t.thickness_rays) m.bands += band_texels * static_cast<std::uint64_t>(o.samples) * 4;
    if (map == MapKind::curvature) m.high += high.vertices * 4;
  }
  // Libraries, TBB and Embree threads, the writers' pieces in flight.
  m.fixed = std::uint64_t{96} << 20;
  return m;
}

Status check_bake_memory(const BakeOptions& o, const MeshSize& low, const MeshSize& high) {
  MemoryLimit limit;
  if (o.max_memory_bytes > 0) {
    limit.bytes = o.max_memory_bytes;
    limit.source = "--max-memory";
  } else {
    limit = available_memory();
    if (limit.bytes == 0) return Status::ok();  // nothing known: no budget
    // What the process holds already (the loaded meshes) is part of the
    // estimate, and no longer part of what is available.
    limit.bytes += resident_memory();
  }
  const BakeMemory m = estimate_bake_memory(o, low, high);
  if (m.total() <= limit.bytes) return Status::ok();
  std::string parts = "map " + memory_text(m.map + m.bands);
  if (low.triangles + high.triangles > 0) parts += ", meshes " + memory_text(m.low + m.high);
  return Status::bad_input("a " + map_text(o) + " needs about " + memory_text(m.total()) + " (" + parts +
                           "); " + memory_text(limit.bytes) + " are available (" + limit.source +
                           "): use a smaller --size" +
                           std::string(baked_rows(o) != o.height ? " or more tiles" : "") +
                           ", or set --max-memory if more can be used");
}

}  // namespace nmbake
