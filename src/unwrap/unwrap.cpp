// The unwrap stage: charts -> LSCM -> packing (include/nmbake/unwrap.hpp),
// and the quality measures of a UV layout: the L2 and L-infinity texture
// stretch of Sander, Snyder, Gortler and Hoppe, "Texture Mapping Progressive
// Meshes" (SIGGRAPH 2001), normalised by the ratio of UV to surface area so
// that 1 means no stretch, plus flipped, collapsed and overlapping triangles
// (overlaps by a separating-axis test on every pair sharing a grid cell).
#include "nmbake/unwrap.hpp"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <glm/geometric.hpp>
#include <limits>
#include <nlohmann/json.hpp>
#include <unordered_map>

#include "unwrap/unwrap_internal.hpp"

namespace nmbake {

namespace unwrap_detail {

namespace {

// True when the interiors of two triangles overlap by more than `tolerance`
// along every separating axis candidate (the six edge normals).
bool interiors_overlap(const glm::dvec2* a, const glm::dvec2* b, double tolerance) {
  for (const glm::dvec2* t : {a, b}) {
    for (int k = 0; k < 3; ++k) {
      const glm::dvec2 e = t[(k + 1) % 3] - t[k];
      const glm::dvec2 n(-e.y, e.x);
      const double len = glm::length(n);
      if (!(len > 0.0)) return false;  // zero-length edge: no interior
      double a_lo = std::numeric_limits<double>::infinity(), a_hi = -a_lo, b_lo = a_lo, b_hi = -a_lo;
      for (int j = 0; j < 3; ++j) {
        const double pa = glm::dot(n, a[j]), pb = glm::dot(n, b[j]);
        a_lo = std::min(a_lo, pa), a_hi = std::max(a_hi, pa);
        b_lo = std::min(b_lo, pb), b_hi = std::max(b_hi, pb);
      }
      const double slack = tolerance * len;
      if (a_hi <= b_lo + slack || b_hi <= a_lo + slack) return false;
    }
  }
  return true;
}

}  // namespace

std::vector<std::uint8_t> find_overlaps(const std::vector<glm::dvec2>& uv, double tolerance) {
  const std::size_t n = uv.size() / 3;
  std::vector<std::uint8_t> flag(n, 0);
  if (n < 2) return flag;
  std::vector<glm::dvec2> lo(n), hi(n);
  glm::dvec2 all_lo(std::numeric_limits<double>::infinity()),
      all_hi(-std::numeric_limits<double>::infinity());
  double extent_sum = 0.0;
  for (std::size_t t = 0; t < n; ++t) {
    lo[t] = glm::min(glm::min(uv[3 * t], uv[3 * t + 1]), uv[3 * t + 2]);
    hi[t] = glm::max(glm::max(uv[3 * t], uv[3 * t + 1]), uv[3 * t + 2]);
    all_lo = glm::min(all_lo, lo[t]);
    all_hi = glm::max(all_hi, hi[t]);
    extent_sum += std::max(hi[t].x - lo[t].x, hi[t].y - lo[t].y);
  }
  const glm::dvec2 size = all_hi - all_lo;
  if (!(size.x > 0.0) || !(size.y > 0.0) || !std::isfinite(size.x + size.y)) return flag;
  // About one triangle per cell, at most ~4 cells per triangle in total.
  double cell = std::max(extent_sum / static_cast<double>(n), 1e-12 * std::max(size.x, size.y));
  while ((size.x / cell + 1.0) * (size.y / cell + 1.0) > 4.0 * static_cast<double>(n) + 16.0) cell *= 1.5;
  const int gx = std::max(1, static_cast<int>(size.x / cell) + 1);
  const int gy = std::max(1, static_cast<int>(size.y / cell) + 1);
  auto cell_of = [&](const glm::dvec2& p, int& cx, int& cy) {
    cx = std::clamp(static_cast<int>((p.x - all_lo.x) / cell), 0, gx - 1);
    cy = std::clamp(static_cast<int>((p.y - all_lo.y) / cell), 0, gy - 1);
  };
  // Counting sort of (cell, triangle) entries.
  std::vector<std::uint32_t> start(static_cast<std::size_t>(gx) * gy + 1, 0);
  auto for_cells = [&](std::size_t t, auto&& fn) {
    int x0, y0, x1, y1;
    cell_of(lo[t], x0, y0);
    cell_of(hi[t], x1, y1);
    for (int y = y0; y <= y1; ++y)
      for (int x = x0; x <= x1; ++x) fn(static_cast<std::size_t>(y) * gx + x);
  };
  for (std::size_t t = 0; t < n; ++t) for_cells(t, [&](std::size_t c) { ++start[c + 1]; });
  for (std::size_t c = 1; c < start.size(); ++c) start[c] += start[c - 1];
  std::vector<std::uint32_t> entries(start.back());
  std::vector<std::uint32_t> fill(start.begin(), start.end() - 1);
  for (std::size_t t = 0; t < n; ++t)
    for_cells(t, [&](std::size_t c) { entries[fill[c]++] = static_cast<std::uint32_t>(t); });

  for (std::size_t c = 0; c + 1 < start.size(); ++c) {
    for (std::uint32_t i = start[c]; i < start[c + 1]; ++i) {
      const std::uint32_t a = entries[i];
      for (std::uint32_t j = i + 1; j < start[c + 1]; ++j) {
        const std::uint32_t b = entries[j];
        if (flag[a] && flag[b]) continue;
        if (hi[a].x <= lo[b].x || hi[b].x <= lo[a].x || hi[a].y <= lo[b].y || hi[b].y <= lo[a].y) continue;
        // Each pair is tested once: in the cell holding its boxes' common corner.
        int ox, oy;
        cell_of(glm::max(lo[a], lo[b]), ox, oy);
        if (static_cast<std::size_t>(oy) * gx + ox != c) continue;
        if (interiors_overlap(&uv[3 * a], &uv[3 * b], tolerance)) flag[a] = flag[b] = 1;
      }
    }
  }
  return flag;
}

}  // namespace unwrap_detail

UvQuality measure_uv_quality(const Mesh& mesh, float min_area_ratio) {
  UvQuality q;
  const std::size_t n = mesh.triangle_count();
  if (!mesh.has_uvs() || n == 0) return q;
  std::vector<double> area_3d(n, 0.0), area_uv(n, 0.0);
  std::vector<std::uint8_t> skip(n, 0);
  double sum_3d = 0.0, sum_uv = 0.0;
  std::vector<glm::dvec2> corner_uv(n * 3);
  for (std::size_t t = 0; t < n; ++t) {
    const glm::dvec3 p0 = mesh.positions[mesh.indices[3 * t]];
    const glm::dvec3 e1 = glm::dvec3(mesh.positions[mesh.indices[3 * t + 1]]) - p0;
    const glm::dvec3 e2 = glm::dvec3(mesh.positions[mesh.indices[3 * t + 2]]) - p0;
    const double cross = glm::length(glm::cross(e1, e2));
    const double longest = std::max({glm::dot(e1, e1), glm::dot(e2, e2), glm::dot(e2 - e1, e2 - e1)});
    for (int k = 0; k < 3; ++k) corner_uv[3 * t + k] = mesh.uvs[mesh.indices[3 * t + k]];
    const glm::dvec2 a = corner_uv[3 * t], b = corner_uv[3 * t + 1], c = corner_uv[3 * t + 2];
    area_uv[t] = 0.5 * ((b.x - a.x) * (c.y - a.y) - (b.y - a.y) * (c.x - a.x));
    if (!(cross > 1e-7 * longest) || !(cross > 0.0)) {
      skip[t] = 1;
      ++q.zero_area_triangles;
      continue;
    }
    area_3d[t] = 0.5 * cross;
    sum_3d += area_3d[t];
    sum_uv += std::abs(area_uv[t]);
  }
  q.uv_area = 0.0;
  for (std::size_t t = 0; t < n; ++t) q.uv_area += std::abs(area_uv[t]);
  const double density = sum_3d > 0.0 ? sum_uv / sum_3d : 0.0;  // UV area per surface area
  double l2_sum = 0.0, l2_weight = 0.0, linf = 0.0;
  for (std::size_t t = 0; t < n; ++t) {
    if (skip[t]) continue;
    if (!(std::abs(area_uv[t]) >= min_area_ratio * density * area_3d[t]) || density == 0.0) {
      ++q.collapsed_triangles;
      continue;
    }
    if (area_uv[t] < 0.0) ++q.flipped_triangles;
    // Sander et al. 2001: derivatives of the surface point along s and t.
    const glm::dvec3 q1 = mesh.positions[mesh.indices[3 * t]];
    const glm::dvec3 q2 = mesh.positions[mesh.indices[3 * t + 1]];
    const glm::dvec3 q3 = mesh.positions[mesh.indices[3 * t + 2]];
    const glm::dvec2 u1 = corner_uv[3 * t], u2 = corner_uv[3 * t + 1], u3 = corner_uv[3 * t + 2];
    const double twice = 2.0 * area_uv[t];
    const glm::dvec3 ss = (q1 * (u2.y - u3.y) + q2 * (u3.y - u1.y) + q3 * (u1.y - u2.y)) / twice;
    const glm::dvec3 st = (q1 * (u3.x - u2.x) + q2 * (u1.x - u3.x) + q3 * (u2.x - u1.x)) / twice;
    const double a = glm::dot(ss, ss), b = glm::dot(ss, st), c = glm::dot(st, st);
    const double big = std::sqrt(std::max(0.0, 0.5 * (a + c + std::sqrt((a - c) * (a - c) + 4.0 * b * b))));
    l2_sum += 0.5 * (a + c) * area_3d[t];
    l2_weight += area_3d[t];
    linf = std::max(linf, big);
  }
  const double norm = std::sqrt(density);
  q.stretch_l2 = l2_weight > 0.0 ? std::sqrt(l2_sum / l2_weight) * norm : 0.0;
  q.stretch_linf = linf * norm;
  if (!std::isfinite(q.stretch_l2)) q.stretch_l2 = 0.0;
  if (!std::isfinite(q.stretch_linf)) q.stretch_linf = 0.0;
  glm::dvec2 lo(std::numeric_limits<double>::infinity()), hi(-std::numeric_limits<double>::infinity());
  for (const glm::dvec2& p : corner_uv) lo = glm::min(lo, p), hi = glm::max(hi, p);
  const std::vector<std::uint8_t> overlap =
      unwrap_detail::find_overlaps(corner_uv, 1e-7 * std::max({hi.x - lo.x, hi.y - lo.y, 1e-30}));
  q.overlapping_triangles = static_cast<std::uint64_t>(std::count(overlap.begin(), overlap.end(), 1));
  return q;
}

Status unwrap_mesh(const Mesh& in, const UnwrapOptions& o, Mesh& out, UnwrapReport& r) {
  using Clock = std::chrono::steady_clock;
  const Clock::time_point begin = Clock::now();
  r = UnwrapReport{};
  const PackOptions& pack = o.pack;
  if (pack.resolution < 8 || pack.resolution > 32768)
    return Status::bad_input("unwrap: atlas size " + std::to_string(pack.resolution) +
                             " is out of range (8 to 32768)");
  if (pack.gutter < 0 || pack.gutter > pack.resolution / 4)
    return Status::bad_input("unwrap: gutter " + std::to_string(pack.gutter) +
                             " is out of range (0 to size / 4)");
  if (!(o.chart.max_normal_deviation_deg > 0.0f && o.chart.max_normal_deviation_deg < 180.0f))
    return Status::bad_input("unwrap: the normal deviation limit must be in (0, 180) degrees");
  NMBAKE_TRY(validate_mesh(in, "unwrap input"));
  NMBAKE_CHECK(&in != &out, "unwrap_mesh: out may not alias in");
  r.input_triangles = in.triangle_count();
  r.input_vertices = in.vertex_count();
  r.resolution = pack.resolution;
  r.gutter = pack.gutter;

  unwrap_detail::Topology topology;
  std::vector<std::vector<std::uint32_t>> groups;
  unwrap_detail::SegmentStats segment;
  unwrap_detail::segment_charts(in, o.chart, topology, groups, segment);
  r.boundary_edges_kept = segment.boundary_edges_kept;
  r.nonmanifold_faces = segment.nonmanifold_faces;
  r.zero_area_triangles = segment.zero_area_triangles;
  r.small_charts_merged = segment.small_charts_merged;
  const Clock::time_point charted = Clock::now();
  r.seconds_charts = std::chrono::duration<double>(charted - begin).count();

  std::vector<unwrap_detail::Chart> charts;
  unwrap_detail::ParameterizeStats param;
  unwrap_detail::parameterize_charts(topology, groups, o.parameterize, charts, param);
  r.charts_split = param.charts_split;
  r.lscm_fallbacks = param.lscm_fallbacks;
  r.chart_count = charts.size();
  const Clock::time_point parameterized = Clock::now();
  r.seconds_parameterize = std::chrono::duration<double>(parameterized - charted).count();

  unwrap_detail::PackResult packed;
  const bool fits = unwrap_detail::pack_charts(charts, pack, packed);
  r.pack_attempts = packed.attempts;
  r.seconds_pack = std::chrono::duration<double>(Clock::now() - parameterized).count();
  if (!fits) {
    return Status::bad_input("unwrap: " + std::to_string(charts.size()) + " charts do not fit into a " +
                             std::to_string(pack.resolution) + "^2 atlas with a gutter of " +
                             std::to_string(pack.gutter) + " texels; use a larger size or a smaller gutter");
  }
  r.texels_per_unit = packed.scale;

  // Output: triangle order kept; a vertex per (chart, input vertex).
  const std::size_t tri_count = in.triangle_count();
  std::vector<glm::vec2> corner_uv(tri_count * 3);
  std::vector<std::uint32_t> chart_of(tri_count);
  const double inv = 1.0 / pack.resolution;
  for (std::size_t c = 0; c < charts.size(); ++c) {
    const unwrap_detail::Chart& chart = charts[c];
    for (std::size_t i = 0; i < chart.faces.size(); ++i) {
      chart_of[chart.faces[i]] = static_cast<std::uint32_t>(c);
      for (int k = 0; k < 3; ++k) {
        const glm::dvec2 texel =
            unwrap_detail::chart_to_texel(chart.uv[3 * i + k], chart, packed.placements[c], packed.scale);
        corner_uv[3 * chart.faces[i] + k] =
            glm::vec2(glm::clamp(texel * inv, glm::dvec2(0.0), glm::dvec2(1.0)));
      }
    }
  }
  out = Mesh{};
  // Triangle i is input triangle i: the parts and materials still hold.
  out.parts = in.parts;
  out.materials = in.materials;
  out.indices.resize(in.indices.size());
  std::unordered_map<std::uint64_t, std::uint32_t> vertex_of;
  vertex_of.reserve(in.vertex_count() * 2);
  for (std::size_t t = 0; t < tri_count; ++t) {
    for (int k = 0; k < 3; ++k) {
      const std::uint32_t source = in.indices[3 * t + k];
      const std::uint64_t key = static_cast<std::uint64_t>(chart_of[t]) << 32 | source;
      const auto [it, inserted] = vertex_of.emplace(key, static_cast<std::uint32_t>(out.positions.size()));
      if (inserted) {
        out.positions.push_back(in.positions[source]);
        if (in.has_normals()) out.normals.push_back(in.normals[source]);
        out.uvs.push_back(corner_uv[3 * t + k]);
      }
      out.indices[3 * t + k] = it->second;
    }
  }
  r.output_vertices = out.vertex_count();

  const UvQuality quality = measure_uv_quality(out, o.parameterize.min_area_ratio);
  r.flipped_triangles = quality.flipped_triangles;
  r.overlapping_triangles = quality.overlapping_triangles;
  r.collapsed_triangles = quality.collapsed_triangles;
  r.utilization = quality.uv_area;
  r.stretch_l2 = quality.stretch_l2;
  r.stretch_linf = quality.stretch_linf;
  r.seconds_total = std::chrono::duration<double>(Clock::now() - begin).count();
  return Status::ok();
}

std::string UnwrapReport::to_json() const {
  nlohmann::ordered_json j;
  j["input_triangles"] = input_triangles;
  j["input_vertices"] = input_vertices;
  j["output_vertices"] = output_vertices;
  j["charts"] = chart_count;
  j["atlas"] = {{"size", resolution},
                {"gutter", gutter},
                {"texels_per_unit", texels_per_unit},
                {"utilization", utilization},
                {"pack_attempts", pack_attempts}};
  j["stretch"] = {{"l2", stretch_l2}, {"linf", stretch_linf}};
  j["quality"] = {{"flipped_triangles", flipped_triangles},
                  {"overlapping_triangles", overlapping_triangles},
                  {"collapsed_triangles", collapsed_triangles}};
  j["fallbacks"] = {
      {"boundary_edges_kept", boundary_edges_kept}, {"nonmanifold_faces", nonmanifold_faces},
      {"zero_area_triangles", zero_area_triangles}, {"charts_split", charts_split},
      {"lscm_fallbacks", lscm_fallbacks},           {"small_charts_merged", small_charts_merged}};
  j["seconds"] = {{"charts", seconds_charts},
                  {"parameterize", seconds_parameterize},
                  {"pack", seconds_pack},
                  {"total", seconds_total}};
  return j.dump(2) + "\n";
}

std::string UnwrapReport::summary_line() const {
  char line[384];
  std::snprintf(line, sizeof line,
                "unwrapped %llu triangles: %llu charts, %dx%d gutter %d, utilization %.1f%%, stretch L2 %.3f "
                "Linf %.3f, "
                "%llu flipped, %llu overlapping, %.2f s",
                static_cast<unsigned long long>(input_triangles),
                static_cast<unsigned long long>(chart_count), resolution, resolution, gutter,
                100.0 * utilization, stretch_l2, stretch_linf,
                static_cast<unsigned long long>(flipped_triangles),
                static_cast<unsigned long long>(overlapping_triangles), seconds_total);
  return line;
}

}  // namespace nmbake
