// Plain data shared by the unwrap stages (charts -> lscm -> pack). OpenMesh
// and Eigen types stay inside charts.cpp and lscm.cpp.
#pragma once

#include <cstdint>
#include <glm/ext/vector_double2.hpp>
#include <glm/vec2.hpp>
#include <glm/vec3.hpp>
#include <vector>

#include "nmbake/unwrap.hpp"

namespace nmbake::unwrap_detail {

// The low mesh welded by position (bitwise equal, -0 == +0), as topology.
struct Topology {
  std::vector<glm::vec3> positions;     // per welded vertex
  std::vector<std::uint32_t> corners;   // 3 per triangle: welded vertex
  std::vector<glm::vec3> face_normals;  // unit, (0, 0, 1) for zero-area faces
  std::vector<double> face_areas;
  std::vector<std::uint8_t> degenerate;  // 1: zero area (no LSCM weight)
  std::size_t triangle_count() const { return corners.size() / 3; }
};

struct SegmentStats {
  std::uint64_t boundary_edges_kept = 0, nonmanifold_faces = 0, zero_area_triangles = 0,
                small_charts_merged = 0;
};

// Builds the topology and grows charts. Each chart is a list of triangle
// indices in increasing order; charts are ordered by their first triangle.
void segment_charts(const Mesh& mesh, const ChartOptions& options, Topology& topology,
                    std::vector<std::vector<std::uint32_t>>& charts, SegmentStats& stats);

// A parameterized chart: UVs per corner of its faces (3 per face, in `faces`
// order), in scene units (area-preserving on the whole), bounding box
// rotated to minimal area and moved to start at (0, 0).
struct Chart {
  std::vector<std::uint32_t> faces;
  std::vector<glm::vec2> uv;
  glm::vec2 extent{0.0f};  // bounding box size
};

struct ParameterizeStats {
  std::uint64_t charts_split = 0, lscm_fallbacks = 0;
};

// LSCM on every chart, splitting the ones that fold until none does.
void parameterize_charts(const Topology& topology, const std::vector<std::vector<std::uint32_t>>& charts,
                         const ParameterizeOptions& options, std::vector<Chart>& out,
                         ParameterizeStats& stats);

// Where a chart went in the atlas: UV = (offset + R(turns) * uv * scale) / resolution,
// R turning counter-clockwise by 90 degrees per turn (a rotation: never a mirror,
// so no triangle flips), the chart's box kept in the positive quadrant.
struct Placement {
  int x = 0, y = 0;  // texel offset of the chart's footprint
  int turns = 0;     // 0..3
};

struct PackResult {
  double scale = 0.0;  // texels per scene unit
  std::vector<Placement> placements;
  int attempts = 0;
};

// Largest scale at which every chart fits; false when none does.
bool pack_charts(const std::vector<Chart>& charts, const PackOptions& options, PackResult& result);

// The chart UV transformed into atlas texel coordinates (x right, y up).
glm::dvec2 chart_to_texel(const glm::vec2& uv, const Chart& chart, const Placement& p, double scale);

// Indices of triangles whose UV interiors overlap another triangle's
// (3 UVs per triangle). Touching along edges or at corners is not an
// overlap; `tolerance` is the penetration depth (UV units) still ignored.
// Deterministic, grid-accelerated. Returns one flag per triangle.
std::vector<std::uint8_t> find_overlaps(const std::vector<glm::dvec2>& uv, double tolerance);

}  // namespace nmbake::unwrap_detail
