// Stage "unwrap": a low mesh without (or with unwanted) UVs into the same
// mesh with a generated UV atlas, in the manner of xatlas: segment charts,
// parameterize each chart (LSCM), pack the charts into a square atlas.
//
// Contract:
//   * Input: a mesh that passes validate_mesh(); UVs are ignored except that
//     their seams are kept as chart boundaries (re-unwrap keeps old seams).
//   * Output: triangles in the input order, triangle i made of the same
//     corners as input triangle i (positions and normals copied bit for bit);
//     vertices are the distinct (chart, input vertex) pairs, in order of first
//     use by the triangles, so they are split only along chart boundaries.
//     Parts and materials are copied (the triangle order is kept); tangents
//     and colours are not.
//     Every UV lies in [0, 1]^2 (v = 0 at the image bottom, DESIGN.md).
//   * Chart boundaries always include hard edges (an edge whose two faces
//     have different normals at a shared position, i.e. split vertices) and
//     existing UV seams.
//   * No chart folds: after LSCM every chart is checked for flipped, collapsed
//     and mutually overlapping triangles; a chart with any is split in two and
//     parameterized again (down to single triangles, which cannot fold).
//   * Charts keep their area (uniform texel density) and are scaled by one
//     factor for the whole atlas: the largest for which the packer fits every
//     chart into resolution^2 texels with `gutter` free texels between charts
//     (binary search on the scale).
//   * Deterministic: the same mesh and options give the same bytes, whatever
//     the thread count (charts are parameterized in parallel, results kept in
//     chart order).
//   * Degenerate input (zero-area triangles, non-manifold edges) has a defined
//     fallback, counted in the report: zero-area triangles carry no LSCM
//     weight; a face that would make an edge or vertex non-manifold gets its
//     own copies of its vertices for topology (it still keeps its positions).
#pragma once

#include <cstdint>
#include <string>

#include "nmbake/common.hpp"
#include "nmbake/mesh.hpp"

namespace nmbake {

// Chart segmentation (src/unwrap/charts.cpp): charts grown one at a time from
// seeds taken in breadth-first face order; the face with the lowest cost on
// the chart's border joins next. cost = normal deviation from the chart's
// area-weighted mean normal (scaled so the limit is 1) + straightness_weight *
// share of the face's perimeter that would become new chart border +
// roundness_weight * squared distance from the chart's centroid relative to
// a disc of the chart's area.
struct ChartOptions {
  // Hard limit: a face joins only if its normal is within this angle of the
  // chart's mean normal. Bounds the distortion of curved charts.
  float max_normal_deviation_deg = 60.0f;
  // Weights tuned with the packer on the test meshes (BENCHMARKS.md, Unwrap):
  // straighter, rounder charts than 0.5 / 0.5 / 1.75 packed 1-8 points tighter
  // on 7 of 9 meshes.
  float straightness_weight = 1.0f;  // prefers short, straight boundaries
  // Prefers round charts: weight of (distance from the chart's centroid)^2
  // / (chart area / pi), which is ~1 on the border of a disc (not applied to
  // faces within flat_angle_deg of the chart's normal).
  float roundness_weight = 0.75f;
  float max_cost = 2.0f;  // a face costing more starts a new chart later
  // Charts with fewer faces are merged into the neighbour they share the
  // longest border with, when the merged chart keeps every normal within
  // max_normal_deviation_deg * merge_deviation_slack of its mean.
  // Curved charts stop growing at this share of the mesh's surface area
  // (bounds their stretch). A face within flat_angle_deg of the chart's mean
  // normal is exempt, so flat regions stay whole. 0.06 packed 1-5 points
  // tighter than 0.04 on 5 of the 9 benchmark meshes (the two 100k ones
  // most), 0.1 was better still on the 100k meshes but worse on the small ones.
  float max_chart_area_fraction = 0.06f;
  float flat_angle_deg = 5.0f;
  int min_chart_faces = 6;
  float merge_deviation_slack = 1.25f;
  // Normals at a shared position further apart than this make a hard edge.
  float hard_edge_angle_deg = 0.5f;
};

// LSCM parameterization (src/unwrap/lscm.cpp).
struct ParameterizeOptions {
  // A UV triangle whose area is below this fraction of its 3D area (after
  // the chart is scaled to its 3D area) counts as collapsed: its chart is split.
  float min_area_ratio = 1e-3f;
  int max_split_depth = 24;  // deeper charts are cut to single triangles
};

// Packing (src/unwrap/pack.cpp): bitmap packing of each chart's
// conservatively rasterized footprint, dilated by the gutter (exact shapes,
// so charts interlock); charts sorted by bounding-box area, each placed at
// the lowest-then-leftmost free position of whichever of its four 90-degree
// turns ends with the lowest centre.
struct PackOptions {
  int resolution = 2048;  // atlas width = height, texels
  int gutter = 4;         // free texels between any two charts
  bool rotate = true;     // also try each chart turned by 90, 180 and 270 degrees
  int search_steps = 6;   // bisection steps of the coarse (quarter-size) scale search
};

struct UnwrapOptions {
  ChartOptions chart;
  ParameterizeOptions parameterize;
  PackOptions pack;
};

struct UnwrapReport {
  std::uint64_t input_triangles = 0, input_vertices = 0, output_vertices = 0;
  std::uint64_t chart_count = 0;
  std::uint64_t boundary_edges_kept = 0;  // hard edges and UV seams kept as chart boundaries
  std::uint64_t nonmanifold_faces = 0;    // faces given their own vertex copies for topology
  std::uint64_t zero_area_triangles = 0;  // no LSCM weight (kept, UVs from their neighbours)
  std::uint64_t charts_split = 0;         // charts split because LSCM folded or overlapped them
  std::uint64_t lscm_fallbacks = 0;       // solver failures: planar projection used, then checked
  std::uint64_t small_charts_merged = 0;
  // Quality of the final atlas (must be zero: tests assert it).
  std::uint64_t flipped_triangles = 0;      // UV winding opposite to the 3D winding
  std::uint64_t overlapping_triangles = 0;  // UV interiors overlapping another triangle's
  std::uint64_t collapsed_triangles = 0;    // non-degenerate 3D triangle with ~zero UV area
  double utilization = 0.0;                 // UV area of all triangles / atlas area
  double stretch_l2 = 0.0;                  // Sander et al. 2001, normalised: 1 = no stretch
  double stretch_linf = 0.0;                // worst triangle, same normalisation
  int resolution = 0, gutter = 0;
  double texels_per_unit = 0.0;  // the atlas scale: texels per scene unit of length
  int pack_attempts = 0;
  double seconds_charts = 0.0, seconds_parameterize = 0.0, seconds_pack = 0.0, seconds_total = 0.0;

  std::string to_json() const;       // one JSON object, newline-terminated
  std::string summary_line() const;  // charts, utilization, stretch, flips, overlaps, time
};

// Unwraps `in` into `out` (see the contract above). Returns bad_input when
// the options are out of range or the charts cannot be packed at this
// resolution and gutter (the message says which). `out` may not alias `in`.
Status unwrap_mesh(const Mesh& in, const UnwrapOptions& options, Mesh& out, UnwrapReport& report);

// Quality measures of any mesh with UVs (used by unwrap_mesh for its report
// and usable on a loaded mesh): counts of flipped, overlapping and collapsed
// triangles, L2/Linf stretch, and UV area / unit square (utilization).
struct UvQuality {
  std::uint64_t flipped_triangles = 0, overlapping_triangles = 0, collapsed_triangles = 0;
  std::uint64_t zero_area_triangles = 0;  // 3D area ~0: left out of the measures
  double uv_area = 0.0, stretch_l2 = 0.0, stretch_linf = 0.0;
};
UvQuality measure_uv_quality(const Mesh& mesh, float min_area_ratio = 1e-3f);

}  // namespace nmbake
