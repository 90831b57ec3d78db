// Tangent bases other than MikkTSpace, kept for the accuracy lab: the classic
// per-vertex accumulation of Eric Lengyel, "Computing Tangent Space Basis
// Vectors for an Arbitrary Mesh" (Terathon, 2001; the method of the old
// bump-mapping tutorials), and plain per-face tangents. Both solve, per
// triangle, [e1 e2] = [T B] [duv1 duv2] for the UV-gradient directions.
#include <algorithm>
#include <cmath>
#include <glm/geometric.hpp>

#include "nmbake/tangents.hpp"

namespace nmbake {

namespace {

bool finite_nonzero(const glm::vec3& v) {
  const float l2 = glm::dot(v, v);
  return std::isfinite(l2) && l2 > 1e-30f;
}

// Same rule as the MikkTSpace stage's fallback (tangents.hpp): the world axis
// least aligned with N, made orthogonal to it.
glm::vec3 axis_fallback(const glm::vec3& n) {
  const glm::vec3 a = glm::abs(n);
  glm::vec3 axis{1.0f, 0.0f, 0.0f};
  if (a.y < a.x && a.y <= a.z) {
    axis = {0.0f, 1.0f, 0.0f};
  } else if (a.z < a.x && a.z < a.y) {
    axis = {0.0f, 0.0f, 1.0f};
  }
  const glm::vec3 t = axis - glm::dot(axis, n) * n;
  return finite_nonzero(t) ? glm::normalize(t) : axis;
}

// Unnormalised UV-gradient tangent and bitangent of one triangle; false when
// the UV or position triangle is degenerate.
bool face_gradients(const Mesh& mesh, std::size_t tri, glm::vec3& t, glm::vec3& b) {
  const std::uint32_t* v = &mesh.indices[3 * tri];
  const glm::vec3 e1 = mesh.positions[v[1]] - mesh.positions[v[0]];
  const glm::vec3 e2 = mesh.positions[v[2]] - mesh.positions[v[0]];
  const glm::vec2 d1 = mesh.uvs[v[1]] - mesh.uvs[v[0]];
  const glm::vec2 d2 = mesh.uvs[v[2]] - mesh.uvs[v[0]];
  const float det = d1.x * d2.y - d2.x * d1.y;
  if (!(std::fabs(det) > 1e-20f) || !std::isfinite(det)) return false;
  const float r = 1.0f / det;
  t = (e1 * d2.y - e2 * d1.y) * r;
  b = (e2 * d1.x - e1 * d2.x) * r;
  return finite_nonzero(t) && finite_nonzero(b) && finite_nonzero(glm::cross(e1, e2));
}

// Gram-Schmidt against n, sign from the bitangent's side; false when t is
// parallel to n.
bool orthogonalize(const glm::vec3& n, const glm::vec3& t, const glm::vec3& b, glm::vec4& out) {
  const glm::vec3 p = t - n * glm::dot(n, t);
  const float l = glm::length(p);
  if (!(l > 1e-12f * std::max(1.0f, glm::length(t))) || !std::isfinite(l)) return false;
  const glm::vec3 tu = p / l;
  out = glm::vec4(tu, glm::dot(glm::cross(n, tu), b) < 0.0f ? -1.0f : 1.0f);
  return true;
}

}  // namespace

void compute_tangents_lengyel(const Mesh& mesh, std::vector<glm::vec4>& corner_tangents,
                              TangentStats& stats) {
  stats = TangentStats{};
  const std::size_t triangles = mesh.triangle_count();
  std::vector<glm::vec3> tan(mesh.vertex_count(), glm::vec3(0.0f)), bit(mesh.vertex_count(), glm::vec3(0.0f));
  for (std::size_t f = 0; f < triangles; ++f) {
    glm::vec3 t, b;
    if (!face_gradients(mesh, f, t, b)) {
      ++stats.degenerate_uv_triangles;
      continue;
    }
    for (int k = 0; k < 3; ++k) {
      tan[mesh.indices[3 * f + k]] += t;
      bit[mesh.indices[3 * f + k]] += b;
    }
  }
  corner_tangents.resize(3 * triangles);
  for (std::size_t c = 0; c < 3 * triangles; ++c) {
    const std::uint32_t v = mesh.indices[c];
    if (!orthogonalize(mesh.normals[v], tan[v], bit[v], corner_tangents[c])) {
      corner_tangents[c] = glm::vec4(axis_fallback(mesh.normals[v]), 1.0f);
      ++stats.fallback_tangents;
    }
  }
}

void compute_tangents_face(const Mesh& mesh, std::vector<glm::vec4>& corner_tangents, TangentStats& stats) {
  stats = TangentStats{};
  const std::size_t triangles = mesh.triangle_count();
  corner_tangents.resize(3 * triangles);
  for (std::size_t f = 0; f < triangles; ++f) {
    glm::vec3 t(0.0f), b(0.0f);
    const bool ok = face_gradients(mesh, f, t, b);
    if (!ok) ++stats.degenerate_uv_triangles;
    for (int k = 0; k < 3; ++k) {
      const std::size_t c = 3 * f + k;
      const glm::vec3& n = mesh.normals[mesh.indices[c]];
      if (!ok || !orthogonalize(n, t, b, corner_tangents[c])) {
        corner_tangents[c] = glm::vec4(axis_fallback(n), 1.0f);
        ++stats.fallback_tangents;
      }
    }
  }
}

void compute_tangents_file(const Mesh& mesh, std::vector<glm::vec4>& corner_tangents, TangentStats& stats) {
  NMBAKE_CHECK(mesh.has_tangents(), "--tangents file needs a mesh with tangents (checked at load)");
  stats = TangentStats{};
  corner_tangents.resize(mesh.indices.size());
  for (std::size_t c = 0; c < mesh.indices.size(); ++c) {
    const std::uint32_t v = mesh.indices[c];
    const glm::vec3& n = mesh.normals[v];
    const glm::vec4& t = mesh.tangents[v];
    // The stored sign is kept (the file's frame); the orthogonalisation only
    // repairs the small drift an exporter's rounding leaves. A tangent
    // parallel to the normal, or zero, gets the fixed fallback.
    glm::vec4 out;
    const float sign = t.w < 0.0f ? -1.0f : 1.0f;
    const glm::vec3 b = sign * glm::cross(n, glm::vec3(t));
    if (orthogonalize(n, glm::vec3(t), b, out)) {
      corner_tangents[c] = glm::vec4(glm::vec3(out), sign);
    } else {
      corner_tangents[c] = glm::vec4(axis_fallback(n), 1.0f);
      ++stats.fallback_tangents;
    }
  }
}

void compute_tangents(const Mesh& mesh, TangentBasis basis, std::vector<glm::vec4>& corner_tangents,
                      TangentStats& stats) {
  switch (basis) {
    case TangentBasis::lengyel:
      compute_tangents_lengyel(mesh, corner_tangents, stats);
      return;
    case TangentBasis::face:
      compute_tangents_face(mesh, corner_tangents, stats);
      return;
    case TangentBasis::file:
      compute_tangents_file(mesh, corner_tangents, stats);
      return;
    case TangentBasis::mikktspace:
      break;
  }
  compute_tangents(mesh, corner_tangents, stats);
}

}  // namespace nmbake
