// Chart parameterization by Least Squares Conformal Maps: Lévy, Petitjean,
// Ray and Maillot, "Least Squares Conformal Maps for Automatic Texture Atlas
// Generation" (SIGGRAPH 2002). Per triangle, in a local orthonormal frame,
// the Cauchy-Riemann residuals of the map (u_x - v_y, u_y + v_x) weighted by
// sqrt(area); two vertices pinned (the two furthest apart), the normal
// equations solved with Eigen's sparse LDLT. A chart whose result folds
// (flipped or collapsed triangles, or overlapping parts) is cut in two along
// its longest axis and parameterized again.
#include <tbb/parallel_for.h>

#include <Eigen/SparseCholesky>
#include <Eigen/SparseCore>
#include <algorithm>
#include <cmath>
#include <glm/geometric.hpp>
#include <limits>
#include <numeric>

#include "unwrap/unwrap_internal.hpp"

namespace nmbake::unwrap_detail {

namespace {

// Tiny membrane energy on every edge: keeps the system definite when a
// vertex only touches zero-area triangles (such a vertex lands at the mean of
// its neighbours); far too small to move anything else.
constexpr double kRegularization = 1e-9;

struct LocalChart {
  std::vector<std::uint32_t> vertices;      // welded ids, sorted
  std::vector<std::uint32_t> corner_local;  // 3 per face
};

LocalChart make_local(const Topology& topo, const std::vector<std::uint32_t>& faces) {
  LocalChart local;
  local.vertices.reserve(faces.size() * 3);
  for (std::uint32_t f : faces)
    for (int k = 0; k < 3; ++k) local.vertices.push_back(topo.corners[3 * f + k]);
  std::sort(local.vertices.begin(), local.vertices.end());
  local.vertices.erase(std::unique(local.vertices.begin(), local.vertices.end()), local.vertices.end());
  local.corner_local.resize(faces.size() * 3);
  for (std::size_t i = 0; i < faces.size(); ++i)
    for (int k = 0; k < 3; ++k) {
      const auto it =
          std::lower_bound(local.vertices.begin(), local.vertices.end(), topo.corners[3 * faces[i] + k]);
      local.corner_local[3 * i + k] = static_cast<std::uint32_t>(it - local.vertices.begin());
    }
  return local;
}

// Orthogonal projection onto the plane of the chart's mean normal: the
// defined fallback when the solver fails (checked like any other result).
void project_planar(const Topology& topo, const std::vector<std::uint32_t>& faces, const LocalChart& local,
                    std::vector<glm::dvec2>& uv) {
  glm::dvec3 n(0.0);
  for (std::uint32_t f : faces) n += glm::dvec3(topo.face_normals[f]) * topo.face_areas[f];
  if (!(glm::length(n) > 0.0)) n = glm::dvec3(0.0, 0.0, 1.0);
  n = glm::normalize(n);
  const glm::dvec3 helper = std::abs(n.x) < 0.9 ? glm::dvec3(1.0, 0.0, 0.0) : glm::dvec3(0.0, 1.0, 0.0);
  const glm::dvec3 x = glm::normalize(glm::cross(helper, n));
  const glm::dvec3 y = glm::cross(n, x);
  uv.resize(local.vertices.size());
  for (std::size_t i = 0; i < local.vertices.size(); ++i) {
    const glm::dvec3 p = topo.positions[local.vertices[i]];
    uv[i] = {glm::dot(p, x), glm::dot(p, y)};
  }
}

// Returns false when the solver failed (uv is then untouched).
bool solve_lscm(const Topology& topo, const std::vector<std::uint32_t>& faces, const LocalChart& local,
                std::vector<glm::dvec2>& uv) {
  const std::size_t n = local.vertices.size();
  auto position = [&](std::uint32_t l) { return glm::dvec3(topo.positions[local.vertices[l]]); };
  // Pins: the vertex furthest from the first, and the one furthest from it.
  auto furthest = [&](std::uint32_t from) {
    std::uint32_t best = from;
    double best_d = -1.0;
    for (std::uint32_t l = 0; l < n; ++l) {
      const glm::dvec3 d = position(l) - position(from);
      if (glm::dot(d, d) > best_d) {
        best_d = glm::dot(d, d);
        best = l;
      }
    }
    return best;
  };
  const std::uint32_t pin_a = furthest(0);
  const std::uint32_t pin_b = furthest(pin_a);
  const double pin_distance = glm::length(position(pin_b) - position(pin_a));
  if (pin_a == pin_b || !(pin_distance > 0.0)) return false;

  // Unknowns: u of every free vertex, then v.
  std::vector<std::int32_t> free_index(n, -1);
  std::int32_t free_count = 0;
  for (std::uint32_t l = 0; l < n; ++l)
    if (l != pin_a && l != pin_b) free_index[l] = free_count++;
  const glm::dvec2 pin_uv[2] = {{0.0, 0.0}, {pin_distance, 0.0}};
  auto pinned_value = [&](std::uint32_t l, int component) {
    return l == pin_a ? pin_uv[0][component] : pin_uv[1][component];
  };
  auto variable = [&](std::uint32_t l, int component) {
    return free_index[l] < 0 ? -1 : free_index[l] + component * free_count;
  };

  // Each face adds x^T Q x over its six unknowns (u0 u1 u2 v0 v1 v2):
  // the two Cauchy-Riemann rows plus the regularization of its edges.
  std::vector<Eigen::Triplet<double>> triplets;
  triplets.reserve(faces.size() * 36);
  Eigen::VectorXd rhs = Eigen::VectorXd::Zero(2 * free_count);
  for (std::size_t i = 0; i < faces.size(); ++i) {
    const std::uint32_t* c = &local.corner_local[3 * i];
    double q[6][6] = {};
    auto add_row = [&](const double(&coef)[6]) {
      for (int a = 0; a < 6; ++a)
        for (int b = 0; b < 6; ++b) q[a][b] += coef[a] * coef[b];
    };
    for (int k = 0; k < 3; ++k) {
      double row_u[6] = {}, row_v[6] = {};
      row_u[k] = row_v[3 + k] = 1.0;
      row_u[(k + 1) % 3] = row_v[3 + (k + 1) % 3] = -1.0;
      for (int a = 0; a < 6; ++a)
        row_u[a] *= std::sqrt(kRegularization), row_v[a] *= std::sqrt(kRegularization);
      add_row(row_u);
      add_row(row_v);
    }
    if (!topo.degenerate[faces[i]]) {
      // Local frame: p0 at the origin, p1 on the x axis.
      const glm::dvec3 p0 = position(c[0]), p1 = position(c[1]), p2 = position(c[2]);
      const glm::dvec3 e1 = p1 - p0, e2 = p2 - p0;
      const double l1 = glm::length(e1);
      const glm::dvec3 x = e1 / l1;
      const glm::dvec3 y = glm::cross(glm::normalize(glm::cross(e1, e2)), x);
      const glm::dvec2 t[3] = {{0.0, 0.0}, {l1, 0.0}, {glm::dot(e2, x), glm::dot(e2, y)}};
      const double twice_area = t[1].x * t[2].y;
      if (twice_area > 0.0 && std::isfinite(twice_area)) {
        // Gradient of corner j's barycentric function: perp(opposite edge) / 2A.
        double gx[3], gy[3];
        for (int j = 0; j < 3; ++j) {
          const glm::dvec2 e = t[(j + 2) % 3] - t[(j + 1) % 3];
          gx[j] = -e.y / twice_area;
          gy[j] = e.x / twice_area;
        }
        const double w = std::sqrt(0.5 * twice_area);
        add_row({w * gx[0], w * gx[1], w * gx[2], -w * gy[0], -w * gy[1], -w * gy[2]});  // u_x - v_y
        add_row({w * gy[0], w * gy[1], w * gy[2], w * gx[0], w * gx[1], w * gx[2]});     // u_y + v_x
      }
    }
    int vars[6];
    for (int a = 0; a < 6; ++a) vars[a] = variable(c[a % 3], a / 3);
    for (int a = 0; a < 6; ++a) {
      if (vars[a] < 0) continue;
      for (int b = 0; b < 6; ++b) {
        if (q[a][b] == 0.0) continue;
        if (vars[b] < 0) {
          rhs[vars[a]] -= q[a][b] * pinned_value(c[b % 3], b / 3);
        } else {
          triplets.emplace_back(vars[a], vars[b], q[a][b]);
        }
      }
    }
  }

  Eigen::SparseMatrix<double> matrix(2 * free_count, 2 * free_count);
  matrix.setFromTriplets(triplets.begin(), triplets.end());
  Eigen::SimplicialLDLT<Eigen::SparseMatrix<double>> solver;
  solver.compute(matrix);
  if (solver.info() != Eigen::Success) return false;
  const Eigen::VectorXd solution = solver.solve(rhs);
  if (solver.info() != Eigen::Success || !solution.allFinite()) return false;
  uv.resize(n);
  for (std::uint32_t l = 0; l < n; ++l) {
    if (free_index[l] < 0) {
      uv[l] = l == pin_a ? pin_uv[0] : pin_uv[1];
    } else {
      uv[l] = {solution[free_index[l]], solution[free_index[l] + free_count]};
    }
  }
  return true;
}

double signed_area(const glm::dvec2& a, const glm::dvec2& b, const glm::dvec2& c) {
  return 0.5 * ((b.x - a.x) * (c.y - a.y) - (b.y - a.y) * (c.x - a.x));
}

// Andrew's monotone chain; returns the hull counter-clockwise.
std::vector<glm::dvec2> convex_hull(std::vector<glm::dvec2> points) {
  std::sort(points.begin(), points.end(),
            [](const glm::dvec2& a, const glm::dvec2& b) { return a.x != b.x ? a.x < b.x : a.y < b.y; });
  if (points.size() < 3) return points;
  std::vector<glm::dvec2> hull(2 * points.size());
  std::size_t k = 0;
  for (std::size_t i = 0; i < points.size(); ++i) {
    while (k >= 2 && signed_area(hull[k - 2], hull[k - 1], points[i]) <= 0.0) --k;
    hull[k++] = points[i];
  }
  for (std::size_t i = points.size() - 1, t = k + 1; i > 0; --i) {
    while (k >= t && signed_area(hull[k - 2], hull[k - 1], points[i - 1]) <= 0.0) --k;
    hull[k++] = points[i - 1];
  }
  hull.resize(k - 1);
  return hull;
}

// Rotates the chart so its bounding box has the least area (an edge of the
// convex hull is always on the best box) and moves it to start at (0, 0).
void orient_chart(std::vector<glm::dvec2>& uv, glm::vec2& extent) {
  const std::vector<glm::dvec2> hull = convex_hull(uv);
  glm::dvec2 best_axis(1.0, 0.0);
  double best_area = std::numeric_limits<double>::infinity();
  for (std::size_t i = 0; i < hull.size() && hull.size() >= 3; ++i) {
    glm::dvec2 axis = hull[(i + 1) % hull.size()] - hull[i];
    const double len = glm::length(axis);
    if (!(len > 0.0)) continue;
    axis /= len;
    double min_x = std::numeric_limits<double>::infinity(), max_x = -min_x, min_y = min_x, max_y = -min_x;
    for (const glm::dvec2& p : hull) {
      const double px = glm::dot(p, axis), py = axis.x * p.y - axis.y * p.x;
      min_x = std::min(min_x, px), max_x = std::max(max_x, px);
      min_y = std::min(min_y, py), max_y = std::max(max_y, py);
    }
    const double area = (max_x - min_x) * (max_y - min_y);
    if (area < best_area * (1.0 - 1e-9)) {
      best_area = area;
      best_axis = axis;
    }
  }
  glm::dvec2 lo(std::numeric_limits<double>::infinity()), hi(-std::numeric_limits<double>::infinity());
  for (glm::dvec2& p : uv) {
    p = {glm::dot(p, best_axis), best_axis.x * p.y - best_axis.y * p.x};
    lo = glm::min(lo, p);
    hi = glm::max(hi, p);
  }
  for (glm::dvec2& p : uv) p -= lo;
  extent = glm::vec2(hi - lo);
}

struct Work {
  std::vector<std::uint32_t> faces;
  int depth = 0;
};

struct Outcome {
  bool ok = false;
  bool fallback = false;
  Chart chart;
  std::vector<Work> parts;  // when not ok
};

// Cuts the faces in two at the median of their centroids along the longest
// axis, then into connected pieces (faces sharing a welded edge).
std::vector<Work> split(const Topology& topo, const Work& work, int max_depth) {
  const std::vector<std::uint32_t>& faces = work.faces;
  std::vector<std::uint8_t> side(faces.size(), 0);
  if (work.depth < max_depth) {
    std::vector<glm::dvec3> centroid(faces.size());
    glm::dvec3 lo(std::numeric_limits<double>::infinity()), hi(-std::numeric_limits<double>::infinity());
    for (std::size_t i = 0; i < faces.size(); ++i) {
      centroid[i] = (glm::dvec3(topo.positions[topo.corners[3 * faces[i]]]) +
                     glm::dvec3(topo.positions[topo.corners[3 * faces[i] + 1]]) +
                     glm::dvec3(topo.positions[topo.corners[3 * faces[i] + 2]])) /
                    3.0;
      lo = glm::min(lo, centroid[i]);
      hi = glm::max(hi, centroid[i]);
    }
    const glm::dvec3 size = hi - lo;
    const int axis = size.x >= size.y && size.x >= size.z ? 0 : (size.y >= size.z ? 1 : 2);
    std::vector<std::uint32_t> order(faces.size());
    std::iota(order.begin(), order.end(), 0u);
    std::sort(order.begin(), order.end(), [&](std::uint32_t a, std::uint32_t b) {
      return centroid[a][axis] != centroid[b][axis] ? centroid[a][axis] < centroid[b][axis] : a < b;
    });
    for (std::size_t i = order.size() / 2; i < order.size(); ++i) side[order[i]] = 1;
  }
  // Connected pieces of each side; past the depth limit, single faces.
  std::vector<std::int32_t> piece(faces.size(), -1);
  std::int32_t piece_count = 0;
  if (work.depth >= max_depth) {
    for (std::size_t i = 0; i < faces.size(); ++i) piece[i] = piece_count++;
  } else {
    // Edge -> faces, sorted so the grouping is deterministic.
    struct EdgeUse {
      std::uint64_t key;
      std::uint32_t face;
    };
    std::vector<EdgeUse> edges;
    edges.reserve(faces.size() * 3);
    for (std::size_t i = 0; i < faces.size(); ++i)
      for (int k = 0; k < 3; ++k) {
        const std::uint64_t a = topo.corners[3 * faces[i] + k], b = topo.corners[3 * faces[i] + (k + 1) % 3];
        edges.push_back({std::min(a, b) << 32 | std::max(a, b), static_cast<std::uint32_t>(i)});
      }
    std::sort(edges.begin(), edges.end(), [](const EdgeUse& a, const EdgeUse& b) {
      return a.key != b.key ? a.key < b.key : a.face < b.face;
    });
    std::vector<std::uint32_t> parent(faces.size());
    std::iota(parent.begin(), parent.end(), 0u);
    auto find = [&](std::uint32_t x) {
      while (parent[x] != x) x = parent[x] = parent[parent[x]];
      return x;
    };
    for (std::size_t i = 0; i + 1 < edges.size(); ++i) {
      if (edges[i].key != edges[i + 1].key) continue;
      const std::uint32_t a = edges[i].face, b = edges[i + 1].face;
      if (side[a] != side[b]) continue;
      const std::uint32_t ra = find(a), rb = find(b);
      if (ra != rb) parent[std::max(ra, rb)] = std::min(ra, rb);
    }
    std::vector<std::int32_t> piece_of_root(faces.size(), -1);
    for (std::size_t i = 0; i < faces.size(); ++i) {
      const std::uint32_t r = find(static_cast<std::uint32_t>(i));
      if (piece_of_root[r] < 0) piece_of_root[r] = piece_count++;
      piece[i] = piece_of_root[r];
    }
  }
  std::vector<Work> parts(piece_count);
  for (std::size_t i = 0; i < faces.size(); ++i) {
    parts[piece[i]].faces.push_back(faces[i]);
    parts[piece[i]].depth = work.depth + 1;
  }
  return parts;
}

Outcome parameterize_one(const Topology& topo, const Work& work, const ParameterizeOptions& options) {
  Outcome out;
  const std::vector<std::uint32_t>& faces = work.faces;
  const LocalChart local = make_local(topo, faces);
  std::vector<glm::dvec2> uv;
  if (!solve_lscm(topo, faces, local, uv)) {
    out.fallback = true;
    project_planar(topo, faces, local, uv);
  }
  // Scale so the chart's UV area is its 3D area.
  double area_3d = 0.0, area_uv = 0.0;
  for (std::size_t i = 0; i < faces.size(); ++i) {
    if (topo.degenerate[faces[i]]) continue;
    area_3d += topo.face_areas[faces[i]];
    area_uv += signed_area(uv[local.corner_local[3 * i]], uv[local.corner_local[3 * i + 1]],
                           uv[local.corner_local[3 * i + 2]]);
  }
  bool folded = !(area_uv > 0.0) && area_3d > 0.0;
  const double scale = area_3d > 0.0 && area_uv > 0.0 ? std::sqrt(area_3d / area_uv) : 1.0;
  for (glm::dvec2& p : uv) p *= scale;
  std::vector<glm::dvec2> corner_uv(faces.size() * 3);
  for (std::size_t c = 0; c < corner_uv.size(); ++c) corner_uv[c] = uv[local.corner_local[c]];
  for (std::size_t i = 0; i < faces.size() && !folded; ++i) {
    if (topo.degenerate[faces[i]]) continue;
    const double a = signed_area(corner_uv[3 * i], corner_uv[3 * i + 1], corner_uv[3 * i + 2]);
    if (!(a >= options.min_area_ratio * topo.face_areas[faces[i]])) folded = true;
  }
  if (!folded && faces.size() > 1) {
    glm::dvec2 lo(std::numeric_limits<double>::infinity()), hi(-std::numeric_limits<double>::infinity());
    for (const glm::dvec2& p : corner_uv) lo = glm::min(lo, p), hi = glm::max(hi, p);
    const std::vector<std::uint8_t> overlap =
        find_overlaps(corner_uv, 1e-7 * std::max(hi.x - lo.x, hi.y - lo.y));
    folded = std::find(overlap.begin(), overlap.end(), 1) != overlap.end();
  }
  if (folded && faces.size() > 1) {
    out.parts = split(topo, work, options.max_split_depth);
    return out;
  }
  // A single face cannot fold; a degenerate one stays as it is (counted by
  // the caller's quality measure, not split further).
  orient_chart(uv, out.chart.extent);
  out.chart.faces = faces;
  out.chart.uv.resize(corner_uv.size());
  for (std::size_t c = 0; c < corner_uv.size(); ++c) out.chart.uv[c] = glm::vec2(uv[local.corner_local[c]]);
  out.ok = true;
  return out;
}

}  // namespace

void parameterize_charts(const Topology& topo, const std::vector<std::vector<std::uint32_t>>& charts,
                         const ParameterizeOptions& options, std::vector<Chart>& out,
                         ParameterizeStats& stats) {
  out.clear();
  std::vector<Work> pending(charts.size());
  for (std::size_t i = 0; i < charts.size(); ++i) pending[i].faces = charts[i];
  // Rounds: every pending chart in parallel, results consumed in order.
  while (!pending.empty()) {
    std::vector<Outcome> outcomes(pending.size());
    tbb::parallel_for(std::size_t{0}, pending.size(),
                      [&](std::size_t i) { outcomes[i] = parameterize_one(topo, pending[i], options); });
    std::vector<Work> next;
    for (Outcome& o : outcomes) {
      if (o.fallback) ++stats.lscm_fallbacks;
      if (o.ok) {
        out.push_back(std::move(o.chart));
      } else {
        ++stats.charts_split;
        for (Work& w : o.parts) next.push_back(std::move(w));
      }
    }
    pending = std::move(next);
  }
}

}  // namespace nmbake::unwrap_detail
