// Chart segmentation by greedy chart growing, after Sander, Gortler, Snyder
// and Hoppe, "Signal-specialized parametrization" (EGWR 2002) and the
// xatlas chart builder: charts grow from seeds across non-seam edges, the
// cheapest border face first, where the cost weighs the face's normal
// deviation from the chart's mean normal against how much new border it
// adds; tiny charts are merged into their neighbours afterwards.
// Topology (edges, faces around edges) comes from an OpenMesh half-edge mesh.
#include <OpenMesh/Core/Mesh/TriMesh_ArrayKernelT.hh>
#include <OpenMesh/Core/System/omstream.hh>
#include <algorithm>
#include <cmath>
#include <cstring>
#include <glm/geometric.hpp>
#include <glm/trigonometric.hpp>
#include <limits>
#include <queue>
#include <unordered_map>

#include "unwrap/unwrap_internal.hpp"

namespace nmbake::unwrap_detail {

namespace {

using OMesh = OpenMesh::TriMesh_ArrayKernelT<>;

struct PositionKey {
  std::uint32_t bits[3];
  bool operator==(const PositionKey& o) const { return std::memcmp(bits, o.bits, sizeof bits) == 0; }
};
struct PositionHash {
  std::size_t operator()(const PositionKey& k) const {
    std::uint64_t h = 1469598103934665603ull;
    for (std::uint32_t b : k.bits) h = (h ^ b) * 1099511628211ull;
    return static_cast<std::size_t>(h ^ (h >> 29));
  }
};

PositionKey key_of(const glm::vec3& p) {
  PositionKey k{};
  for (int i = 0; i < 3; ++i) {
    const float v = p[i] == 0.0f ? 0.0f : p[i];  // -0 == +0
    std::memcpy(&k.bits[i], &v, sizeof v);
  }
  return k;
}

// OpenMesh refuses faces that would make an edge or a vertex non-manifold.
// Checked here first so that refusal never reaches its error stream.
bool can_add_face(const OMesh& m, const OMesh::VertexHandle v[3]) {
  if (v[0] == v[1] || v[1] == v[2] || v[0] == v[2]) return false;
  for (int i = 0; i < 3; ++i) {
    if (!m.is_boundary(v[i]) && !m.is_isolated(v[i])) return false;
    const OMesh::HalfedgeHandle h = m.find_halfedge(v[i], v[(i + 1) % 3]);
    if (h.is_valid() && !m.is_boundary(h)) return false;
  }
  return true;
}

glm::vec3 unit_or_zero(const glm::vec3& n) {
  const float len = glm::length(n);
  return len > 0.0f && std::isfinite(len) ? n / len : glm::vec3(0.0f);
}

// Per-chart running sums for the cost of a candidate face.
struct Growth {
  glm::dvec3 normal_sum{0.0};
  glm::vec3 mean_normal{0.0f, 0.0f, 1.0f};
  double area = 0.0;
  glm::dvec3 centroid_sum{0.0};
  glm::dvec3 centroid() const { return area > 0.0 ? centroid_sum / area : centroid_sum; }
  void add(const glm::vec3& n, double face_area, const glm::dvec3& face_centroid) {
    area += face_area;
    centroid_sum += face_centroid * face_area;
    normal_sum += glm::dvec3(n) * std::max(face_area, 1e-30);
    const double len = glm::length(normal_sum);
    if (len > 0.0) mean_normal = glm::vec3(normal_sum / len);
  }
};

}  // namespace

void segment_charts(const Mesh& mesh, const ChartOptions& options, Topology& topo,
                    std::vector<std::vector<std::uint32_t>>& charts, SegmentStats& stats) {
  const std::size_t tri_count = mesh.triangle_count();
  topo = Topology{};
  topo.corners.resize(tri_count * 3);
  topo.face_normals.resize(tri_count);
  topo.face_areas.resize(tri_count);
  topo.degenerate.assign(tri_count, 0);

  // Weld by position.
  std::unordered_map<PositionKey, std::uint32_t, PositionHash> welded;
  welded.reserve(mesh.vertex_count());
  std::vector<std::uint32_t> weld_of(mesh.vertex_count());
  for (std::size_t v = 0; v < mesh.vertex_count(); ++v) {
    const auto [it, inserted] =
        welded.emplace(key_of(mesh.positions[v]), static_cast<std::uint32_t>(topo.positions.size()));
    if (inserted) topo.positions.push_back(mesh.positions[v]);
    weld_of[v] = it->second;
  }

  // OpenMesh reports refused faces on its error stream; they are expected
  // here (handled below and counted), so that stream is silenced once. nmbake
  // never uses OpenMesh's streams for anything else.
  static const bool silenced = [] {
    omerr().disable();
    return true;
  }();
  (void)silenced;

  // The half-edge mesh; a face that would be non-manifold gets its own
  // vertex copies, so om_corner (OpenMesh vertex per corner) may differ from
  // the welded vertex.
  OMesh om;
  om.reserve(topo.positions.size(), tri_count * 3 / 2, tri_count);
  for (const glm::vec3& p : topo.positions) om.add_vertex(OMesh::Point(p.x, p.y, p.z));
  std::vector<std::uint32_t> om_corner(tri_count * 3);
  for (std::size_t t = 0; t < tri_count; ++t) {
    OMesh::VertexHandle vh[3];
    for (int k = 0; k < 3; ++k) {
      topo.corners[3 * t + k] = weld_of[mesh.indices[3 * t + k]];
      vh[k] = OMesh::VertexHandle(static_cast<int>(topo.corners[3 * t + k]));
    }
    OMesh::FaceHandle fh;
    if (can_add_face(om, vh)) fh = om.add_face(vh[0], vh[1], vh[2]);
    if (!fh.is_valid()) {  // non-manifold, or a patch OpenMesh cannot re-link (it then changes nothing)
      ++stats.nonmanifold_faces;
      for (int k = 0; k < 3; ++k) {
        // A copy: add_vertex may grow the point array that point() refers into.
        const OMesh::Point p = om.point(vh[k]);
        vh[k] = om.add_vertex(p);
      }
      fh = om.add_face(vh[0], vh[1], vh[2]);
    }
    NMBAKE_CHECK(fh.is_valid() && static_cast<std::size_t>(fh.idx()) == t,
                 "unwrap: face insertion out of order");
    for (int k = 0; k < 3; ++k) om_corner[3 * t + k] = static_cast<std::uint32_t>(vh[k].idx());

    const glm::dvec3 p0 = topo.positions[topo.corners[3 * t]];
    const glm::dvec3 e1 = glm::dvec3(topo.positions[topo.corners[3 * t + 1]]) - p0;
    const glm::dvec3 e2 = glm::dvec3(topo.positions[topo.corners[3 * t + 2]]) - p0;
    const glm::dvec3 c = glm::cross(e1, e2);
    const double longest = std::max({glm::dot(e1, e1), glm::dot(e2, e2), glm::dot(e2 - e1, e2 - e1)});
    const double len = glm::length(c);
    topo.face_areas[t] = 0.5 * len;
    if (!(len > 1e-7 * longest) || !(len > 0.0)) {
      topo.degenerate[t] = 1;
      topo.face_normals[t] = glm::vec3(0.0f, 0.0f, 1.0f);
      ++stats.zero_area_triangles;
    } else {
      topo.face_normals[t] = glm::vec3(c / len);
    }
  }

  // Seams: edges whose two faces disagree on a normal or a UV at either end.
  const float hard_cos = std::cos(glm::radians(options.hard_edge_angle_deg));
  auto input_vertex = [&](std::size_t face, std::uint32_t om_vertex) {
    for (int k = 0; k < 3; ++k)
      if (om_corner[3 * face + k] == om_vertex) return mesh.indices[3 * face + k];
    NMBAKE_CHECK(false, "unwrap: corner not found");
    return std::uint32_t{0};
  };
  auto same_attributes = [&](std::uint32_t a, std::uint32_t b) {
    if (a == b) return true;
    if (mesh.has_normals()) {
      const glm::vec3 na = unit_or_zero(mesh.normals[a]), nb = unit_or_zero(mesh.normals[b]);
      if (glm::dot(na, nb) < hard_cos) return false;
    }
    if (mesh.has_uvs() && mesh.uvs[a] != mesh.uvs[b]) return false;
    return true;
  };
  // Per face, the three neighbours across its edges (or -1: border / seam),
  // and the edge lengths, in corner order (edge k from corner k to k + 1).
  std::vector<std::int32_t> neighbour(tri_count * 3, -1);
  std::vector<float> edge_length(tri_count * 3);
  for (std::size_t t = 0; t < tri_count; ++t) {
    for (int k = 0; k < 3; ++k) {
      edge_length[3 * t + k] = glm::length(topo.positions[topo.corners[3 * t + (k + 1) % 3]] -
                                           topo.positions[topo.corners[3 * t + k]]);
      const OMesh::VertexHandle a(static_cast<int>(om_corner[3 * t + k]));
      const OMesh::VertexHandle b(static_cast<int>(om_corner[3 * t + (k + 1) % 3]));
      const OMesh::HalfedgeHandle h = om.find_halfedge(a, b);
      const OMesh::HalfedgeHandle opposite = om.opposite_halfedge_handle(h);
      if (om.is_boundary(opposite)) continue;
      const std::size_t other = static_cast<std::size_t>(om.face_handle(opposite).idx());
      if (same_attributes(input_vertex(t, a.idx()), input_vertex(other, a.idx())) &&
          same_attributes(input_vertex(t, b.idx()), input_vertex(other, b.idx()))) {
        neighbour[3 * t + k] = static_cast<std::int32_t>(other);
      } else if (t < other) {
        ++stats.boundary_edges_kept;
      }
    }
  }

  // Seeds in breadth-first order, so each new chart starts beside the
  // previous ones and no slivers are left between them.
  std::vector<std::uint32_t> seed_order;
  seed_order.reserve(tri_count);
  {
    std::vector<std::uint8_t> seen(tri_count, 0);
    for (std::size_t start = 0; start < tri_count; ++start) {
      if (seen[start]) continue;
      std::size_t head = seed_order.size();
      seen[start] = 1;
      seed_order.push_back(static_cast<std::uint32_t>(start));
      while (head < seed_order.size()) {
        const std::uint32_t f = seed_order[head++];
        for (int k = 0; k < 3; ++k) {
          const std::int32_t n = neighbour[3 * f + k];
          if (n >= 0 && !seen[n]) {
            seen[n] = 1;
            seed_order.push_back(static_cast<std::uint32_t>(n));
          }
        }
      }
    }
  }

  const float max_cos = std::cos(glm::radians(std::clamp(options.max_normal_deviation_deg, 1.0f, 179.0f)));
  const float flat_cos = std::cos(glm::radians(std::clamp(options.flat_angle_deg, 0.0f, 179.0f)));
  double total_area = 0.0;
  for (double a : topo.face_areas) total_area += a;
  const double max_area = std::max(0.0, static_cast<double>(options.max_chart_area_fraction)) * total_area;
  std::vector<std::int32_t> chart_of(tri_count, -1);
  std::vector<Growth> growth;
  struct Candidate {
    float cost;
    std::uint32_t face;
    bool operator>(const Candidate& o) const { return cost != o.cost ? cost > o.cost : face > o.face; }
  };
  auto face_centroid = [&](std::uint32_t f) {
    return (glm::dvec3(topo.positions[topo.corners[3 * f]]) +
            glm::dvec3(topo.positions[topo.corners[3 * f + 1]]) +
            glm::dvec3(topo.positions[topo.corners[3 * f + 2]])) /
           3.0;
  };
  auto face_cost = [&](std::uint32_t f, std::int32_t chart) {
    const float deviation = 1.0f - glm::dot(topo.face_normals[f], growth[chart].mean_normal);
    if (!topo.degenerate[f] && deviation > 1.0f - max_cos) return std::numeric_limits<float>::infinity();
    if (deviation > 1.0f - flat_cos && growth[chart].area + topo.face_areas[f] > max_area)
      return std::numeric_limits<float>::infinity();
    float shared = 0.0f, perimeter = 0.0f;
    for (int k = 0; k < 3; ++k) {
      perimeter += edge_length[3 * f + k];
      const std::int32_t n = neighbour[3 * f + k];
      if (n >= 0 && chart_of[n] == chart) shared += edge_length[3 * f + k];
    }
    const float new_border = perimeter > 0.0f ? (perimeter - shared) / perimeter : 0.0f;
    const float normal_term = topo.degenerate[f] ? 0.0f : deviation / std::max(1.0f - max_cos, 1e-6f);
    const glm::dvec3 d = face_centroid(f) - growth[chart].centroid();
    const double disc = (growth[chart].area + topo.face_areas[f]) / 3.14159265358979;
    // Flat regions stay whole whatever their shape: only curved growth is kept round.
    const bool flat = deviation <= 1.0f - flat_cos;
    const float round_term =
        disc > 0.0 && !flat ? static_cast<float>(std::min(glm::dot(d, d) / disc, 4.0)) : 0.0f;
    return normal_term + options.straightness_weight * new_border + options.roundness_weight * round_term;
  };

  std::priority_queue<Candidate, std::vector<Candidate>, std::greater<>> heap;
  for (std::uint32_t seed : seed_order) {
    if (chart_of[seed] >= 0) continue;
    const std::int32_t c = static_cast<std::int32_t>(growth.size());
    growth.emplace_back();
    heap = {};
    auto add_face = [&](std::uint32_t f) {
      chart_of[f] = c;
      if (!topo.degenerate[f]) growth[c].add(topo.face_normals[f], topo.face_areas[f], face_centroid(f));
      for (int k = 0; k < 3; ++k) {
        const std::int32_t n = neighbour[3 * f + k];
        if (n >= 0 && chart_of[n] < 0)
          heap.push({face_cost(static_cast<std::uint32_t>(n), c), static_cast<std::uint32_t>(n)});
      }
    };
    if (topo.degenerate[seed]) growth[c].mean_normal = topo.face_normals[seed];
    add_face(seed);
    while (!heap.empty()) {
      const Candidate top = heap.top();
      heap.pop();
      if (chart_of[top.face] >= 0) continue;
      const float cost = face_cost(top.face, c);
      if (cost > top.cost + 1e-6f) {  // the chart changed since it was queued
        if (cost <= options.max_cost) heap.push({cost, top.face});
        continue;
      }
      if (cost > options.max_cost) continue;
      add_face(top.face);
    }
  }

  // Merge small charts into the neighbour they share the longest border with.
  std::vector<std::vector<std::uint32_t>> members(growth.size());
  for (std::size_t t = 0; t < tri_count; ++t) members[chart_of[t]].push_back(static_cast<std::uint32_t>(t));
  const float merge_cos = std::cos(
      glm::radians(std::min(options.max_normal_deviation_deg * options.merge_deviation_slack, 179.0f)));
  for (std::size_t c = 0; c < members.size(); ++c) {
    if (members[c].empty() ||
        members[c].size() >= static_cast<std::size_t>(std::max(options.min_chart_faces, 1)))
      continue;
    std::vector<std::pair<std::int32_t, float>> shared;  // (chart, border length), few entries
    for (std::uint32_t f : members[c]) {
      for (int k = 0; k < 3; ++k) {
        const std::int32_t n = neighbour[3 * f + k];
        if (n < 0 || chart_of[n] == static_cast<std::int32_t>(c)) continue;
        auto it =
            std::find_if(shared.begin(), shared.end(), [&](const auto& s) { return s.first == chart_of[n]; });
        if (it == shared.end()) {
          shared.emplace_back(chart_of[n], edge_length[3 * f + k]);
        } else {
          it->second += edge_length[3 * f + k];
        }
      }
    }
    std::sort(shared.begin(), shared.end(), [](const auto& a, const auto& b) {
      return a.second != b.second ? a.second > b.second : a.first < b.first;
    });
    for (const auto& [target, length] : shared) {
      Growth merged = growth[target];
      for (std::uint32_t f : members[c])
        if (!topo.degenerate[f]) merged.add(topo.face_normals[f], topo.face_areas[f], face_centroid(f));
      bool fits = true;
      for (const auto* list : {&members[c], &members[target]}) {
        for (std::uint32_t f : *list) {
          if (!topo.degenerate[f] && glm::dot(topo.face_normals[f], merged.mean_normal) < merge_cos) {
            fits = false;
            break;
          }
        }
        if (!fits) break;
      }
      if (!fits) continue;
      growth[target] = merged;
      for (std::uint32_t f : members[c]) chart_of[f] = target;
      members[target].insert(members[target].end(), members[c].begin(), members[c].end());
      std::sort(members[target].begin(), members[target].end());
      members[c].clear();
      ++stats.small_charts_merged;
      break;
    }
  }

  charts.clear();
  for (auto& m : members)
    if (!m.empty()) charts.push_back(std::move(m));
  std::sort(charts.begin(), charts.end(), [](const auto& a, const auto& b) { return a.front() < b.front(); });
}

}  // namespace nmbake::unwrap_detail
