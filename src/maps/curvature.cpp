// Mean curvature per vertex of the high mesh, for the curvature map.
//
// Per triangle, the shape operator S (the derivative of the unit normal
// along the surface) is estimated from the triangle's vertex normals, as
// Rusinkiewicz does per face ("Estimating Curvatures and Their Derivatives
// on Triangle Meshes", 3DPVT 2004): with edges e1 = p1 - p0, e2 = p2 - p0 and
// normal differences d1 = n1 - n0, d2 = n2 - n0, S e_j = d_j in the plane, so
// E^T S E = M with M_ij = e_i . d_j and G = E^T E, and the mean curvature is
// H = tr(S) / 2 = tr(G^-1 M) / 2 (outward normals: a sphere of radius r gives
// +1/r). No adjacency is needed; a vertex takes the area-weighted mean of its
// triangles' H, and the map interpolates it at the hit. Measured against the
// alternatives on the analytic sphere and torus in tests/maps_test.cpp.
#include <algorithm>
#include <cmath>
#include <cstdint>

#include <glm/geometric.hpp>
#include <tbb/parallel_for.h>
#include <tbb/task_arena.h>

#include "huge_pages.hpp"
#include "nmbake/maps.hpp"

namespace nmbake {

std::vector<float> vertex_mean_curvature(const Mesh& high, const std::vector<glm::vec3>& normals,
                                         CurvatureStats& stats) {
  NMBAKE_CHECK(normals.size() == high.vertex_count(), "one normal per vertex");
  const std::size_t triangle_count = high.triangle_count();
  const std::size_t vertex_count = high.vertex_count();
  // Each task owns a range of vertices and walks every triangle in order,
  // adding each triangle's H times area and area to the corners it owns: a
  // vertex's sums are added in triangle order whatever the ranges, so the
  // result is the serial pass's for any thread count. A triangle is
  // measured by every task owning one of its corners (on meshes whose
  // triangles use nearby vertices, nearly always one); its degenerate case
  // is counted by the owner of its first corner. Each task then divides
  // its own vertices' sums (a serial pass after the loop was 3-9 ms of the
  // moon's ~25). (A pass writing
  // per-triangle values before a serial scatter was no faster on the
  // 2M-triangle moon, and needed 16 MB more of fresh memory.)
  std::vector<glm::vec2> sums;
  std::vector<float> curvature;
  detail::size_output(sums, vertex_count);
  detail::size_output(curvature, vertex_count);
  const std::size_t tasks = std::max<std::size_t>(
      1, std::min<std::size_t>(static_cast<std::size_t>(tbb::this_task_arena::max_concurrency()),
                               vertex_count / 4096));
  std::vector<std::uint64_t> degenerate(tasks, 0), isolated(tasks, 0);
  tbb::parallel_for(std::size_t{0}, tasks, [&](std::size_t task) {
    const std::uint32_t begin = static_cast<std::uint32_t>(vertex_count * task / tasks);
    const std::uint32_t end = static_cast<std::uint32_t>(vertex_count * (task + 1) / tasks);
    const auto owned = [&](std::uint32_t v) { return v >= begin && v < end; };
    std::uint64_t skipped = 0;
    for (std::size_t t = 0; t < triangle_count; ++t) {
      const std::uint32_t* v = &high.indices[3 * t];
      if (!owned(v[0]) && !owned(v[1]) && !owned(v[2])) continue;
      const glm::vec3 e1 = high.positions[v[1]] - high.positions[v[0]];
      const glm::vec3 e2 = high.positions[v[2]] - high.positions[v[0]];
      const glm::vec3 d1 = normals[v[1]] - normals[v[0]];
      const glm::vec3 d2 = normals[v[2]] - normals[v[0]];
      const float g11 = glm::dot(e1, e1), g12 = glm::dot(e1, e2), g22 = glm::dot(e2, e2);
      const float det = g11 * g22 - g12 * g12;
      const float m11 = glm::dot(e1, d1), m12 = glm::dot(e1, d2), m21 = glm::dot(e2, d1), m22 = glm::dot(e2, d2);
      const float h = 0.5f * (g22 * m11 - g12 * (m12 + m21) + g11 * m22) / det;
      const float a = 0.5f * std::sqrt(det);
      if (!(det > 1e-12f * g11 * g22) || !std::isfinite(det) || !std::isfinite(h) || !std::isfinite(a)) {
        if (owned(v[0])) ++skipped;
        continue;
      }
      const glm::vec2 add(h * a, a);
      for (int c = 0; c < 3; ++c) {
        if (owned(v[c])) sums[v[c]] += add;
      }
    }
    degenerate[task] = skipped;
    // The task's vertices are done: their weighted means.
    std::uint64_t alone = 0;
    for (std::uint32_t v = begin; v < end; ++v) {
      if (sums[v].y > 0.0f) {
        curvature[v] = sums[v].x / sums[v].y;
      } else {
        curvature[v] = 0.0f;
        ++alone;
      }
    }
    isolated[task] = alone;
  });
  for (const std::uint64_t n : degenerate) stats.degenerate_triangles += n;
  for (const std::uint64_t n : isolated) stats.isolated_vertices += n;
  return curvature;
}

}  // namespace nmbake
