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
// Triangles are measured four at a time in SIMD lanes (BM_Curvature
// 10.4/10.4/8.1 -> 7.8/7.9/6.3 ms), with the serial formula's values.
#include <tbb/parallel_for.h>
#include <tbb/task_arena.h>

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <glm/geometric.hpp>

#include "base/huge_pages.hpp"
#include "base/simd4.hpp"
#include "nmbake/maps.hpp"

namespace nmbake {

namespace {

inline float splat(float v, float) { return v; }
inline detail::f4 splat(float v, detail::f4) { return detail::splat4(v); }
inline float root(float v) { return std::sqrt(v); }
inline detail::f4 root(detail::f4 v) { return detail::sqrt4(v); }

template <class T>
struct Vec {
  T x, y, z;
};
// glm::dot's order: (x + y) + z.
template <class T>
T dot(const Vec<T>& a, const Vec<T>& b) {
  return a.x * b.x + a.y * b.y + a.z * b.z;
}

// One triangle's mean curvature h and area a from its edges e1, e2 and
// normal differences d1, d2 (see above), and the bound its determinant
// must exceed; for a float, or four triangles in SIMD lanes (the same IEEE
// operations in the same order per lane, so the same values).
template <class T>
void shape_operator(const Vec<T>& e1, const Vec<T>& e2, const Vec<T>& d1, const Vec<T>& d2, T& h, T& a,
                    T& det, T& bound) {
  const T g11 = dot(e1, e1), g12 = dot(e1, e2), g22 = dot(e2, e2);
  det = g11 * g22 - g12 * g12;
  const T m11 = dot(e1, d1), m12 = dot(e1, d2), m21 = dot(e2, d1), m22 = dot(e2, d2);
  const T half = splat(0.5f, det);
  h = half * (g22 * m11 - g12 * (m12 + m21) + g11 * m22) / det;
  a = half * root(det);
  bound = splat(1e-12f, det) * g11 * g22;
}

}  // namespace

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
    const glm::vec3* const p = high.positions.data();
    const glm::vec3* const n = normals.data();
    const std::uint32_t* const indices = high.indices.data();
    const auto add = [&](const std::uint32_t* v, bool valid, float h, float a) {
      if (!valid) {
        if (owned(v[0])) ++skipped;
        return;
      }
      const glm::vec2 sum(h * a, a);
      for (int c = 0; c < 3; ++c) {
        if (owned(v[c])) sums[v[c]] += sum;
      }
    };
    const auto owns_any = [&](const std::uint32_t* v) { return owned(v[0]) || owned(v[1]) || owned(v[2]); };
    std::size_t t = 0;
    // Four triangles at a time in SIMD lanes, then one by one; each added
    // in triangle order.
    for (; t + 4 <= triangle_count; t += 4) {
      const std::uint32_t* v = indices + 3 * t;
      bool own[4];
      for (int i = 0; i < 4; ++i) own[i] = owns_any(v + 3 * i);
      if (!(own[0] || own[1] || own[2] || own[3])) continue;
      const auto lanes = [&](const glm::vec3* values, int to, int from) {
        const auto axis = [&](int k) {
          return detail::f4{
              values[v[to]][k] - values[v[from]][k], values[v[3 + to]][k] - values[v[3 + from]][k],
              values[v[6 + to]][k] - values[v[6 + from]][k], values[v[9 + to]][k] - values[v[9 + from]][k]};
        };
        return Vec<detail::f4>{axis(0), axis(1), axis(2)};
      };
      detail::f4 h, a, det, bound;
      shape_operator(lanes(p, 1, 0), lanes(p, 2, 0), lanes(n, 1, 0), lanes(n, 2, 0), h, a, det, bound);
      const detail::i4 valid = (det > bound) & detail::finite4(det) & detail::finite4(h) & detail::finite4(a);
      for (int i = 0; i < 4; ++i) {
        if (own[i]) add(v + 3 * i, valid[i] != 0, h[i], a[i]);
      }
    }
    for (; t < triangle_count; ++t) {
      const std::uint32_t* v = indices + 3 * t;
      if (!owns_any(v)) continue;
      const auto edge = [&](const glm::vec3* values, int to, int from) {
        const glm::vec3 e = values[v[to]] - values[v[from]];
        return Vec<float>{e.x, e.y, e.z};
      };
      float h, a, det, bound;
      shape_operator(edge(p, 1, 0), edge(p, 2, 0), edge(n, 1, 0), edge(n, 2, 0), h, a, det, bound);
      add(v, det > bound && std::isfinite(det) && std::isfinite(h) && std::isfinite(a), h, a);
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
