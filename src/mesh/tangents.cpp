// MikkTSpace tangent frames: Morten S. Mikkelsen, "Simulation of wrinkled
// surfaces revisited", MSc thesis, University of Copenhagen, 2008, as fixed by
// his reference implementation mikktspace.c (www.mikktspace.com), default
// angular threshold of 180 degrees, triangles only (no quad splitting).
//
// The reference is a de-facto standard: renderers decode normal maps with
// exactly its frames, so every decision below that looks arbitrary (the order
// in which groups are grown, which corner a degenerate triangle copies from,
// the float thresholds) is the reference's, kept so that our tangents match
// it corner by corner (tests/tangents_test.cpp checks against a WASM build).
//
// Where we deliberately differ: a corner the reference leaves without a
// tangent space (it writes (1, 0, 0) with sign -1 whatever the normal, or a
// zero vector when every contribution had zero weight) gets fallback_tangent()
// below with sign +1 and is counted, so that no later stage sees a tangent
// that is not a unit vector orthogonal to its normal.
#include "nmbake/tangents.hpp"

#include <algorithm>
#include <array>
#include <bit>
#include <cfloat>
#include <cmath>
#include <cstdint>
#include <cstring>
#include <glm/geometric.hpp>
#include <map>
#include <numeric>
#include <tuple>
#include <vector>

#include "nmbake/udim.hpp"

namespace nmbake {
namespace {

// cos(180 degrees) in float: the reference's default threshold. Two
// triangles of a group only split into separate tangent spaces when their
// projected UV gradients are exactly opposite.
constexpr float threshold_cos = -1.0f;

constexpr std::uint32_t flag_group_with_any = 1u;     // no usable UV gradient: joins any group
constexpr std::uint32_t flag_orient_preserving = 2u;  // UV area > 0: bitangent sign +1

constexpr std::int32_t none = -1;

// The reference's notion of zero: anything not above the smallest normal float.
bool not_zero(float x) { return std::fabs(x) > FLT_MIN; }
bool not_zero(const glm::vec3& v) { return not_zero(v.x) || not_zero(v.y) || not_zero(v.z); }

// Normalises like the reference (only vectors with a non-zero component);
// a vector whose squared length underflows is left as it is instead of
// becoming Inf/NaN, and is rejected later by is_unit().
glm::vec3 normalize_if_not_zero(const glm::vec3& v) {
  if (!not_zero(v)) return v;
  const float length = std::sqrt(glm::dot(v, v));
  if (!(length > 0.0f) || !std::isfinite(length)) return v;
  return v * (1.0f / length);
}

// The component of v in the plane orthogonal to the unit vector n.
glm::vec3 project(const glm::vec3& v, const glm::vec3& n) { return v - glm::dot(n, v) * n; }

bool is_unit(const glm::vec3& v) {
  const float length_squared = glm::dot(v, v);
  return std::isfinite(length_squared) && length_squared > 0.25f && length_squared < 4.0f;
}

// The tangent of a corner that has none: the world axis least aligned with N
// (x before y before z on ties), made orthogonal to N (Gram-Schmidt). For a
// unit N that axis is at least 54.7 degrees away from N, so the projection is
// well conditioned. A zero or broken N gets the axis itself.
glm::vec3 fallback_tangent(const glm::vec3& n) {
  const glm::vec3 a = glm::abs(n);
  glm::vec3 axis{1.0f, 0.0f, 0.0f};
  if (a.y < a.x && a.y <= a.z) {
    axis = {0.0f, 1.0f, 0.0f};
  } else if (a.z < a.x && a.z < a.y) {
    axis = {0.0f, 0.0f, 1.0f};
  }
  if (!is_unit(n)) return axis;
  const glm::vec3 t = axis - glm::dot(axis, n) * n;
  const float length = std::sqrt(glm::dot(t, t));
  if (!(length > 1e-6f) || !std::isfinite(length)) return axis;
  return t / length;
}

// Float equality as the reference compares attributes (-0 == +0).
bool same_position(const glm::vec3& a, const glm::vec3& b) { return a.x == b.x && a.y == b.y && a.z == b.z; }

// Bit pattern of a float with -0 folded into +0, so that bitwise equal keys
// mean float-equal values (validated meshes hold no NaN).
std::uint32_t key_bits(float x) { return std::bit_cast<std::uint32_t>(x + 0.0f); }

// The reference welds corners whose position, normal and UV are all equal;
// an indexed mesh may still hold such duplicates, so weld by value. Returns
// for every vertex the smallest vertex index with the same attributes.
std::vector<std::uint32_t> weld_vertices(const Mesh& mesh) {
  const std::size_t vertex_count = mesh.vertex_count();
  using Key = std::array<std::uint32_t, 8>;
  std::vector<Key> keys(vertex_count);
  for (std::size_t v = 0; v < vertex_count; ++v) {
    const glm::vec3& p = mesh.positions[v];
    const glm::vec3& n = mesh.normals[v];
    const glm::vec2& t = mesh.uvs[v];
    keys[v] = {key_bits(p.x), key_bits(p.y), key_bits(p.z), key_bits(n.x),
               key_bits(n.y), key_bits(n.z), key_bits(t.x), key_bits(t.y)};
  }
  std::vector<std::uint32_t> order(vertex_count);
  std::iota(order.begin(), order.end(), 0u);
  std::sort(order.begin(), order.end(),
            [&](std::uint32_t a, std::uint32_t b) { return keys[a] != keys[b] ? keys[a] < keys[b] : a < b; });
  std::vector<std::uint32_t> representative(vertex_count);
  std::size_t run_start = 0;
  for (std::size_t i = 0; i < vertex_count; ++i) {
    if (keys[order[i]] != keys[order[run_start]]) run_start = i;
    representative[order[i]] = order[run_start];
  }
  return representative;
}

// Per-triangle data of the reference (its STriInfo), for the triangles that
// have three distinct positions.
struct TriangleInfo {
  std::array<std::uint32_t, 3> vertex{};                   // welded vertex per corner
  std::array<std::int32_t, 3> neighbor{none, none, none};  // across edge i: vertex[i] -> vertex[i + 1]
  std::array<std::int32_t, 3> group{none, none, none};     // vertex group of each corner
  glm::vec3 os{0.0f};                                      // unit dP/ds (sign-corrected), or zero
  glm::vec3 ot{0.0f};                                      // unit dP/dt (sign-corrected), or zero
  std::uint32_t flags = 0;
  std::uint32_t triangle = 0;  // index in the mesh
};

// The triangles around one welded vertex, connected through shared edges, of
// one UV orientation: they share one tangent space at that vertex.
struct VertexGroup {
  std::uint32_t vertex = 0;
  bool orient_preserving = false;
  std::uint32_t first = 0;  // range in the flat group-member buffer
  std::uint32_t count = 0;
};

// The tangent space given to one corner.
struct CornerFrame {
  glm::vec3 tangent{1.0f, 0.0f, 0.0f};
  bool orient_preserving = false;
  bool assigned = false;
};

int corner_of(const TriangleInfo& info, std::uint32_t vertex) {
  for (int i = 0; i < 3; ++i) {
    if (info.vertex[i] == vertex) return i;
  }
  return -1;
}

// UV gradients (the thesis' equations 18 and 19), orientation and whether the
// triangle can define a tangent at all.
void init_triangle(const Mesh& mesh, TriangleInfo& info) {
  const glm::vec3& p1 = mesh.positions[info.vertex[0]];
  const glm::vec3& p2 = mesh.positions[info.vertex[1]];
  const glm::vec3& p3 = mesh.positions[info.vertex[2]];
  const glm::vec2& t1 = mesh.uvs[info.vertex[0]];
  const glm::vec2& t2 = mesh.uvs[info.vertex[1]];
  const glm::vec2& t3 = mesh.uvs[info.vertex[2]];
  const float t21x = t2.x - t1.x;
  const float t21y = t2.y - t1.y;
  const float t31x = t3.x - t1.x;
  const float t31y = t3.y - t1.y;
  const glm::vec3 d1 = p2 - p1;
  const glm::vec3 d2 = p3 - p1;
  const float signed_area_x2 = t21x * t31y - t21y * t31x;
  const glm::vec3 os = t31y * d1 - t21y * d2;
  const glm::vec3 ot = -t31x * d1 + t21x * d2;

  info.flags = flag_group_with_any;
  if (signed_area_x2 > 0.0f) info.flags |= flag_orient_preserving;
  if (!not_zero(signed_area_x2)) return;

  const float abs_area = std::fabs(signed_area_x2);
  const float length_os = std::sqrt(glm::dot(os, os));
  const float length_ot = std::sqrt(glm::dot(ot, ot));
  const float sign = (info.flags & flag_orient_preserving) != 0 ? 1.0f : -1.0f;
  if (not_zero(length_os)) info.os = (sign / length_os) * os;
  if (not_zero(length_ot)) info.ot = (sign / length_ot) * ot;
  if (not_zero(length_os / abs_area) && not_zero(length_ot / abs_area)) info.flags &= ~flag_group_with_any;
}

// Pairs each edge with one opposite-running edge of another triangle. For
// non-manifold edges the reference pairs in order of triangle index, the
// first free partner wins; so do we.
void build_neighbors(std::vector<TriangleInfo>& triangles) {
  struct EdgeEntry {
    std::uint32_t lo, hi, face, edge;
  };
  std::vector<EdgeEntry> edges;
  edges.reserve(triangles.size() * 3);
  for (std::uint32_t f = 0; f < triangles.size(); ++f) {
    for (std::uint32_t i = 0; i < 3; ++i) {
      const std::uint32_t a = triangles[f].vertex[i];
      const std::uint32_t b = triangles[f].vertex[(i + 1) % 3];
      edges.push_back({std::min(a, b), std::max(a, b), f, i});
    }
  }
  std::sort(edges.begin(), edges.end(), [](const EdgeEntry& x, const EdgeEntry& y) {
    if (x.lo != y.lo) return x.lo < y.lo;
    if (x.hi != y.hi) return x.hi < y.hi;
    return x.face < y.face;
  });
  for (std::size_t i = 0; i < edges.size(); ++i) {
    const EdgeEntry& a = edges[i];
    TriangleInfo& ta = triangles[a.face];
    if (ta.neighbor[a.edge] != none) continue;
    const std::uint32_t a0 = ta.vertex[a.edge];
    const std::uint32_t a1 = ta.vertex[(a.edge + 1) % 3];
    for (std::size_t j = i + 1; j < edges.size() && edges[j].lo == a.lo && edges[j].hi == a.hi; ++j) {
      const EdgeEntry& b = edges[j];
      TriangleInfo& tb = triangles[b.face];
      if (tb.vertex[b.edge] == a1 && tb.vertex[(b.edge + 1) % 3] == a0 && tb.neighbor[b.edge] == none) {
        ta.neighbor[a.edge] = static_cast<std::int32_t>(b.face);
        tb.neighbor[b.edge] = static_cast<std::int32_t>(a.face);
        break;
      }
    }
  }
}

// Grows the vertex groups (the reference's Build4RuleGroups/AssignRecur).
// Depth first, left edge before right edge, with an explicit stack in the
// same visiting order as the reference's recursion: the order matters,
// because the first group that reaches a triangle without a UV gradient gives
// it its orientation. The stack keeps high-valence vertices off the call stack.
void build_groups(std::vector<TriangleInfo>& triangles, std::vector<VertexGroup>& groups,
                  std::vector<std::uint32_t>& members) {
  std::vector<std::int32_t> stack;
  for (std::uint32_t f = 0; f < triangles.size(); ++f) {
    if ((triangles[f].flags & flag_group_with_any) != 0) continue;
    for (int i = 0; i < 3; ++i) {
      if (triangles[f].group[i] != none) continue;
      const auto group_index = static_cast<std::int32_t>(groups.size());
      VertexGroup group;
      group.vertex = triangles[f].vertex[i];
      group.orient_preserving = (triangles[f].flags & flag_orient_preserving) != 0;
      group.first = static_cast<std::uint32_t>(members.size());
      triangles[f].group[i] = group_index;
      members.push_back(f);

      stack.clear();
      stack.push_back(triangles[f].neighbor[(i + 2) % 3]);
      stack.push_back(triangles[f].neighbor[i]);
      while (!stack.empty()) {
        const std::int32_t t = stack.back();
        stack.pop_back();
        if (t == none) continue;
        TriangleInfo& info = triangles[t];
        const int k = corner_of(info, group.vertex);
        if (k < 0 || info.group[k] != none) continue;
        if ((info.flags & flag_group_with_any) != 0 && info.group[0] == none && info.group[1] == none &&
            info.group[2] == none) {
          info.flags &= ~flag_orient_preserving;
          if (group.orient_preserving) info.flags |= flag_orient_preserving;
        }
        if (((info.flags & flag_orient_preserving) != 0) != group.orient_preserving) continue;
        members.push_back(static_cast<std::uint32_t>(t));
        info.group[k] = group_index;
        stack.push_back(info.neighbor[(k + 2) % 3]);
        stack.push_back(info.neighbor[k]);
      }
      group.count = static_cast<std::uint32_t>(members.size()) - group.first;
      groups.push_back(group);
    }
  }
}

// Tangent of one subgroup at `vertex`: the members' projected UV gradients
// weighted by the corner angle (measured in the tangent plane), summed in
// increasing triangle order, normalised.
glm::vec3 evaluate_tangent(const Mesh& mesh, const std::vector<TriangleInfo>& triangles,
                           const std::vector<std::uint32_t>& subgroup, std::uint32_t vertex,
                           const glm::vec3& n) {
  glm::vec3 sum{0.0f};
  for (const std::uint32_t t : subgroup) {
    const TriangleInfo& info = triangles[t];
    if ((info.flags & flag_group_with_any) != 0) continue;
    const int i = corner_of(info, vertex);
    if (i < 0) continue;
    const glm::vec3 os = normalize_if_not_zero(project(info.os, n));
    const glm::vec3& p0 = mesh.positions[info.vertex[(i + 2) % 3]];
    const glm::vec3& p1 = mesh.positions[info.vertex[i]];
    const glm::vec3& p2 = mesh.positions[info.vertex[(i + 1) % 3]];
    const glm::vec3 v1 = normalize_if_not_zero(project(p0 - p1, n));
    const glm::vec3 v2 = normalize_if_not_zero(project(p2 - p1, n));
    const float cos_angle = std::clamp(glm::dot(v1, v2), -1.0f, 1.0f);
    sum += std::acos(cos_angle) * os;
  }
  return normalize_if_not_zero(sum);
}

// One tangent space per (group, subgroup); a triangle's subgroup is the
// group's triangles whose projected gradients are not opposite to its own
// (with the 180 degree threshold: almost always the whole group).
void generate_group_frames(const Mesh& mesh, const std::vector<TriangleInfo>& triangles,
                           const std::vector<VertexGroup>& groups, const std::vector<std::uint32_t>& members,
                           std::vector<CornerFrame>& frames) {
  std::vector<glm::vec3> projected_os;
  std::vector<glm::vec3> projected_ot;
  std::vector<std::uint32_t> subgroup;
  std::vector<std::vector<std::uint32_t>> unique_subgroups;
  std::vector<glm::vec3> unique_tangents;
  for (std::size_t g = 0; g < groups.size(); ++g) {
    const VertexGroup& group = groups[g];
    const std::uint32_t* faces = members.data() + group.first;
    // Every member shares the welded vertex, hence its normal.
    const glm::vec3& n = mesh.normals[group.vertex];
    projected_os.resize(group.count);
    projected_ot.resize(group.count);
    for (std::uint32_t m = 0; m < group.count; ++m) {
      projected_os[m] = normalize_if_not_zero(project(triangles[faces[m]].os, n));
      projected_ot[m] = normalize_if_not_zero(project(triangles[faces[m]].ot, n));
    }
    unique_subgroups.clear();
    unique_tangents.clear();
    for (std::uint32_t k = 0; k < group.count; ++k) {
      const std::uint32_t f = faces[k];
      const TriangleInfo& info = triangles[f];
      int corner = -1;
      for (int i = 0; i < 3; ++i) {
        if (info.group[i] == static_cast<std::int32_t>(g)) corner = i;
      }
      NMBAKE_CHECK(corner >= 0, "a group member does not reference its group");

      subgroup.clear();
      for (std::uint32_t m = 0; m < group.count; ++m) {
        const std::uint32_t t = faces[m];
        const bool any = ((info.flags | triangles[t].flags) & flag_group_with_any) != 0;
        const bool joined = glm::dot(projected_os[k], projected_os[m]) > threshold_cos &&
                            glm::dot(projected_ot[k], projected_ot[m]) > threshold_cos;
        if (any || t == f || joined) subgroup.push_back(t);
      }
      std::sort(subgroup.begin(), subgroup.end());

      std::size_t found = 0;
      while (found < unique_subgroups.size() && unique_subgroups[found] != subgroup) ++found;
      if (found == unique_subgroups.size()) {
        unique_subgroups.push_back(subgroup);
        unique_tangents.push_back(evaluate_tangent(mesh, triangles, subgroup, group.vertex, n));
      }

      CornerFrame& frame = frames[3 * static_cast<std::size_t>(info.triangle) + corner];
      frame.tangent = unique_tangents[found];
      frame.orient_preserving = group.orient_preserving;
      frame.assigned = true;
    }
  }
}

}  // namespace

void compute_tangents(const Mesh& mesh, std::vector<glm::vec4>& corner_tangents, TangentStats& stats) {
  NMBAKE_CHECK(mesh.normals.size() == mesh.vertex_count(), "compute_tangents needs one normal per vertex");
  NMBAKE_CHECK(mesh.uvs.size() == mesh.vertex_count(), "compute_tangents needs one UV per vertex");
  stats = TangentStats{};
  const std::size_t triangle_count = mesh.triangle_count();
  const std::size_t corner_count = 3 * triangle_count;
  corner_tangents.assign(corner_count, glm::vec4(0.0f));
  if (triangle_count == 0) return;

  const std::vector<std::uint32_t> welded = weld_vertices(mesh);

  // Triangles with a repeated position take no part in grouping; their
  // corners copy a frame afterwards. Good ones keep their order.
  std::vector<TriangleInfo> triangles;
  std::vector<std::uint32_t> degenerate;
  triangles.reserve(triangle_count);
  for (std::uint32_t t = 0; t < triangle_count; ++t) {
    TriangleInfo info;
    info.triangle = t;
    for (int i = 0; i < 3; ++i) info.vertex[i] = welded[mesh.indices[3 * static_cast<std::size_t>(t) + i]];
    const glm::vec3& p0 = mesh.positions[info.vertex[0]];
    const glm::vec3& p1 = mesh.positions[info.vertex[1]];
    const glm::vec3& p2 = mesh.positions[info.vertex[2]];
    if (same_position(p0, p1) || same_position(p0, p2) || same_position(p1, p2)) {
      degenerate.push_back(t);
      ++stats.degenerate_triangles;
      continue;
    }
    init_triangle(mesh, info);
    // Collinear corners: the reference still groups such a triangle, but it
    // has no area; count it with the degenerate ones, not as a UV problem.
    const glm::vec3 d1 = p1 - p0;
    const glm::vec3 d2 = p2 - p0;
    const float cross_length = glm::length(glm::cross(d1, d2));
    if (!(cross_length > 1e-7f * glm::length(d1) * glm::length(d2))) {
      ++stats.degenerate_triangles;
    } else if ((info.flags & flag_group_with_any) != 0) {
      ++stats.degenerate_uv_triangles;
    }
    triangles.push_back(info);
  }

  build_neighbors(triangles);
  std::vector<VertexGroup> groups;
  std::vector<std::uint32_t> members;
  members.reserve(triangles.size() * 3);
  build_groups(triangles, groups, members);

  std::vector<CornerFrame> frames(corner_count);
  generate_group_frames(mesh, triangles, groups, members, frames);

  // A corner of a degenerate triangle copies the frame of the first corner
  // of a good triangle (in triangle order) at the same welded vertex.
  if (!degenerate.empty()) {
    std::vector<std::int64_t> first_good_corner(mesh.vertex_count(), -1);
    for (const TriangleInfo& info : triangles) {
      for (int i = 0; i < 3; ++i) {
        if (first_good_corner[info.vertex[i]] < 0) {
          first_good_corner[info.vertex[i]] = 3 * static_cast<std::int64_t>(info.triangle) + i;
        }
      }
    }
    for (const std::uint32_t t : degenerate) {
      for (int i = 0; i < 3; ++i) {
        const std::size_t corner = 3 * static_cast<std::size_t>(t) + i;
        const std::int64_t source = first_good_corner[welded[mesh.indices[corner]]];
        if (source >= 0) frames[corner] = frames[static_cast<std::size_t>(source)];
      }
    }
  }

  for (std::size_t c = 0; c < corner_count; ++c) {
    const CornerFrame& frame = frames[c];
    if (frame.assigned && is_unit(frame.tangent)) {
      corner_tangents[c] = glm::vec4(frame.tangent, frame.orient_preserving ? 1.0f : -1.0f);
    } else {
      corner_tangents[c] = glm::vec4(fallback_tangent(mesh.normals[mesh.indices[c]]), 1.0f);
      ++stats.fallback_tangents;
    }
  }
}

void compute_corner_uv_tangents(const Mesh& mesh, const std::vector<std::uint8_t>& selected,
                                std::vector<glm::vec4>& corner_tangents, TangentStats& stats) {
  NMBAKE_CHECK(mesh.corner_uvs.size() == 3 * mesh.triangle_count(), "corner UVs for every triangle");
  NMBAKE_CHECK(selected.empty() || selected.size() == mesh.triangle_count(), "one flag per triangle");
  // The selected triangles as a mesh with one vertex per distinct (vertex,
  // UV, normal) of their corners: split where the UVs (or, without vertex
  // normals, the face normals) differ, as a renderer's vertex buffer is.
  // compute_tangents() welds by value again, so the frames are those of
  // any split of the same corners (one vertex per corner gives the same,
  // and costs a sort of three times as many keys).
  constexpr std::uint32_t kNone = 0xffffffffu;
  Mesh split;
  std::vector<std::uint32_t> source;                             // the selected triangles, in order
  std::vector<std::uint32_t> first(mesh.vertex_count(), kNone);  // a source vertex's first split vertex
  std::vector<std::uint32_t> next;                               // per split vertex: the next of its source
  for (std::size_t t = 0; t < mesh.triangle_count(); ++t) {
    if (!selected.empty() && selected[t] == 0) continue;
    source.push_back(static_cast<std::uint32_t>(t));
    const std::uint32_t* v = &mesh.indices[3 * t];
    glm::vec3 face(0.0f, 0.0f, 1.0f);
    if (!mesh.has_normals()) {
      const glm::vec3 f = glm::cross(mesh.positions[v[1]] - mesh.positions[v[0]],
                                     mesh.positions[v[2]] - mesh.positions[v[0]]);
      const float l = glm::length(f);
      if (l > 0.0f && std::isfinite(l)) face = f / l;
    }
    for (std::size_t k = 0; k < 3; ++k) {
      const glm::vec2 uv = mesh.corner_uvs[3 * t + k];
      const glm::vec3 n = mesh.has_normals() ? mesh.normals[v[k]] : face;
      std::uint32_t id = first[v[k]];
      while (id != kNone && (split.uvs[id] != uv || split.normals[id] != n)) id = next[id];
      if (id == kNone) {
        id = static_cast<std::uint32_t>(split.positions.size());
        split.positions.push_back(mesh.positions[v[k]]);
        split.normals.push_back(n);
        split.uvs.push_back(uv);
        next.push_back(first[v[k]]);
        first[v[k]] = id;
      }
      split.indices.push_back(id);
    }
  }
  std::vector<std::uint32_t>().swap(first);
  std::vector<std::uint32_t>().swap(next);
  std::vector<glm::vec4> tangents;
  compute_tangents(split, tangents, stats);
  corner_tangents.assign(3 * mesh.triangle_count(), glm::vec4(0.0f));
  for (std::size_t i = 0; i < source.size(); ++i) {
    for (std::size_t k = 0; k < 3; ++k)
      corner_tangents[3 * static_cast<std::size_t>(source[i]) + k] = tangents[3 * i + k];
  }
}

Mesh vertex_tangent_mesh(const Mesh& low, const std::vector<glm::vec4>& corner_tangents,
                         const std::vector<int>& triangle_tile) {
  const bool tiled = !triangle_tile.empty();
  const std::size_t triangle_count = low.triangle_count();
  // The source triangle of each output triangle: within each part, by tile.
  std::vector<std::uint32_t> order(triangle_count);
  std::iota(order.begin(), order.end(), 0u);
  Mesh out;
  out.parts = low.parts;  // the parts keep their ranges
  if (tiled) {
    const std::vector<MeshPart> parts =
        low.parts.empty() ? std::vector<MeshPart>{MeshPart{"", 0, static_cast<std::uint32_t>(triangle_count)}}
                          : low.parts;
    for (const MeshPart& part : parts) {
      const auto first = order.begin() + part.first_triangle;
      const auto last = first + part.triangle_count;
      std::stable_sort(first, last,
                       [&](std::uint32_t a, std::uint32_t b) { return triangle_tile[a] < triangle_tile[b]; });
      for (std::uint32_t t = part.first_triangle; t < part.first_triangle + part.triangle_count; ++t) {
        const std::string name = "tile_" + std::to_string(triangle_tile[order[t]]);
        if (!out.materials.empty() && out.materials.back().name == name &&
            out.materials.back().first_triangle + out.materials.back().triangle_count == t) {
          ++out.materials.back().triangle_count;
        } else {
          out.materials.push_back(MeshPart{name, t, 1});
        }
      }
    }
  } else {
    out.materials = low.materials;
  }
  std::map<std::tuple<std::uint32_t, int, std::uint32_t, std::uint32_t, std::uint32_t, std::uint32_t>,
           std::uint32_t>
      ids;
  out.indices.resize(low.indices.size());
  for (std::size_t t = 0; t < triangle_count; ++t) {
    const std::size_t source = order[t];
    const int tile = tiled ? triangle_tile[source] : 1001;
    for (std::size_t k = 0; k < 3; ++k) {
      const std::size_t c = 3 * source + k;
      const std::uint32_t v = low.indices[c];
      const glm::vec4& tangent = corner_tangents[c];
      std::uint32_t bits[4];
      std::memcpy(bits, &tangent, sizeof(bits));
      const auto [it, added] = ids.emplace(std::tuple(v, tile, bits[0], bits[1], bits[2], bits[3]),
                                           static_cast<std::uint32_t>(out.positions.size()));
      if (added) {
        out.positions.push_back(low.positions[v]);
        out.normals.push_back(low.normals[v]);
        out.uvs.push_back(tiled ? low.uvs[v] - udim_offset(tile) : low.uvs[v]);
        out.tangents.push_back(tangent);
      }
      out.indices[3 * t + k] = it->second;
    }
  }
  return out;
}

}  // namespace nmbake
