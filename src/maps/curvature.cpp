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
#include <cmath>

#include <glm/geometric.hpp>

#include "huge_pages.hpp"
#include "nmbake/maps.hpp"

namespace nmbake {

std::vector<float> vertex_mean_curvature(const Mesh& high, const std::vector<glm::vec3>& normals,
                                         CurvatureStats& stats) {
  NMBAKE_CHECK(normals.size() == high.vertex_count(), "one normal per vertex");
  const std::size_t triangle_count = high.triangle_count();
  // One pass in triangle order, each triangle's H times area and area added
  // to its corners: the same sums for any thread count. (A parallel pass
  // writing per-triangle values before the serial scatter was no faster on
  // the 2M-triangle moon, and needed 16 MB more of fresh memory.)
  std::vector<glm::vec2> sums;
  detail::size_output(sums, high.vertex_count());
  for (std::size_t t = 0; t < triangle_count; ++t) {
    const std::uint32_t* v = &high.indices[3 * t];
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
      ++stats.degenerate_triangles;
      continue;
    }
    const glm::vec2 add(h * a, a);
    sums[v[0]] += add;
    sums[v[1]] += add;
    sums[v[2]] += add;
  }
  std::vector<float> curvature;
  detail::size_output(curvature, high.vertex_count());
  for (std::size_t v = 0; v < curvature.size(); ++v) {
    if (sums[v].y > 0.0f) {
      curvature[v] = sums[v].x / sums[v].y;
    } else {
      curvature[v] = 0.0f;
      ++stats.isolated_vertices;
    }
  }
  return curvature;
}

}  // namespace nmbake
