// Hard-edged and concave scenes (hard_scenes.hpp). Surfaces of revolution
// are exact: the signed distance to a surface turned around an axis is the
// signed distance, in the (rho, y) half-plane, to its profile, here a chain
// of segments and circular arcs (fillets), its sign from the pseudo-normal
// at the nearest point (Baerentzen and Aanaes, "Signed distance computation
// using the angle weighted pseudonormal", 2005, in 2D). The panel's pockets
// are the signed distance of a rounded rectangle (Quilez's 2D box distance)
// through a smoothstep wall profile.
#include "hard_scenes.hpp"

#include <algorithm>
#include <cmath>
#include <glm/geometric.hpp>
#include <numbers>

#include "lab_scenes.hpp"

namespace nmbake::scenes {

namespace {

constexpr double kPi = std::numbers::pi;

double cross2(const glm::dvec2& a, const glm::dvec2& b) { return a.x * b.y - a.y * b.x; }

// The corner point k of n on [lo, hi], exact at both ends.
double at(int k, int n, double lo, double hi) {
  if (k <= 0) return lo;
  if (k >= n) return hi;
  return lo + (hi - lo) * static_cast<double>(k) / n;
}

// Counter-clockwise in (rho, y) (the solid on the left of the walk):
// +1; clockwise: -1. The polygon is closed along the axis.
double orientation(const std::vector<ProfileCorner>& c) {
  double area = 0.0;
  for (std::size_t i = 0; i < c.size(); ++i) {
    const ProfileCorner& a = c[i];
    const ProfileCorner& b = c[(i + 1) % c.size()];
    area += a.rho * b.y - b.rho * a.y;
  }
  return area > 0.0 ? 1.0 : -1.0;
}

// Outward normal of a walk along `d` (unit), the solid on the side `orient` says.
glm::dvec2 outward_of(const glm::dvec2& d, double orient) {
  return orient > 0.0 ? glm::dvec2(d.y, -d.x) : glm::dvec2(-d.y, d.x);
}

// A triangle's winding made to agree with its vertices' normals.
void add_triangle(Mesh& m, std::uint32_t a, std::uint32_t b, std::uint32_t c) {
  const glm::dvec3 pa(m.positions[a]), pb(m.positions[b]), pc(m.positions[c]);
  const glm::dvec3 face = glm::cross(pb - pa, pc - pa);
  const glm::dvec3 shading = glm::dvec3(m.normals[a]) + glm::dvec3(m.normals[b]) + glm::dvec3(m.normals[c]);
  if (glm::dot(face, shading) < 0.0) std::swap(b, c);
  m.indices.insert(m.indices.end(), {a, b, c});
}

// --- UV charts ---------------------------------------------------------------

// A chart of the low mesh: its vertices [first, end) carry UVs in scene
// units within [0, width] x [0, height] until pack_charts() places them.
struct Chart {
  std::uint32_t first = 0, end = 0;
  double width = 0.0, height = 0.0;
};

// Turns a chart's u around when its triangles are mirrored in UV space
// (MikkTSpace would handle it; plain charts are easier to read).
void unmirror(Mesh& m, const Chart& chart, std::size_t first_index) {
  for (std::size_t t = first_index; t + 2 < m.indices.size(); t += 3) {
    const std::uint32_t a = m.indices[t], b = m.indices[t + 1], c = m.indices[t + 2];
    const glm::dvec2 ua(m.uvs[a]), ub(m.uvs[b]), uc(m.uvs[c]);
    const double area = cross2(ub - ua, uc - ua);
    if (area == 0.0) continue;
    if (area < 0.0) {
      for (std::uint32_t v = chart.first; v < chart.end; ++v)
        m.uvs[v].x = static_cast<float>(chart.width) - m.uvs[v].x;
    }
    return;
  }
}

// Shelf packing at one texel density: charts by decreasing height, left to
// right, `gap` UV units around each; the largest scale that fits (bisection).
void pack_charts(Mesh& m, const std::vector<Chart>& charts, double gap) {
  std::vector<std::size_t> order(charts.size());
  for (std::size_t i = 0; i < order.size(); ++i) order[i] = i;
  std::stable_sort(order.begin(), order.end(),
                   [&](std::size_t a, std::size_t b) { return charts[a].height > charts[b].height; });
  std::vector<glm::dvec2> place(charts.size());
  const auto fits = [&](double s) {
    double x = gap, y = gap, shelf = 0.0;
    for (std::size_t i : order) {
      const double w = charts[i].width * s, h = charts[i].height * s;
      if (w > 1.0 - 2.0 * gap) return false;
      if (x + w > 1.0 - gap) {
        y += shelf + gap;
        x = gap;
        shelf = 0.0;
      }
      place[i] = {x, y};
      x += w + gap;
      shelf = std::max(shelf, h);
    }
    return y + shelf <= 1.0 - gap;
  };
  double lo = 0.0, hi = 10.0;
  for (int i = 0; i < 60; ++i) {
    const double mid = 0.5 * (lo + hi);
    (fits(mid) ? lo : hi) = mid;
  }
  NMBAKE_CHECK(fits(lo), "charts packed");
  for (std::size_t i = 0; i < charts.size(); ++i) {
    for (std::uint32_t v = charts[i].first; v < charts[i].end; ++v) {
      m.uvs[v] = glm::vec2(place[i] + lo * glm::dvec2(m.uvs[v]));
    }
  }
}

}  // namespace

// --- Surfaces of revolution ----------------------------------------------------

glm::dvec2 RevolveProfile::Element::point(double s) const {
  if (s <= 0.0) return a;
  if (s >= 1.0) return b;
  if (!arc) return a + s * (b - a);
  const double angle = angle0 + s * sweep;
  return centre + radius * glm::dvec2(std::cos(angle), std::sin(angle));
}

glm::dvec2 RevolveProfile::Element::normal_at(double s) const {
  if (!arc) return normal;
  const double angle = angle0 + std::clamp(s, 0.0, 1.0) * sweep;
  return outward * glm::dvec2(std::cos(angle), std::sin(angle));
}

RevolveProfile::RevolveProfile(const std::vector<ProfileCorner>& c) {
  NMBAKE_CHECK(c.size() >= 3 && c.front().rho == 0.0 && c.back().rho == 0.0,
               "a profile from the axis to the axis");
  const double orient = orientation(c);
  const auto segment = [&](const glm::dvec2& a, const glm::dvec2& b) {
    Element e;
    e.a = a;
    e.b = b;
    e.length = glm::length(b - a);
    NMBAKE_CHECK(e.length > 0.0, "profile corners too close for their fillets");
    e.normal = outward_of((b - a) / e.length, orient);
    elements_.push_back(e);
  };
  glm::dvec2 start(c.front().rho, c.front().y);
  for (std::size_t i = 1; i + 1 < c.size(); ++i) {
    const glm::dvec2 p(c[i].rho, c[i].y), prev(c[i - 1].rho, c[i - 1].y), next(c[i + 1].rho, c[i + 1].y);
    const glm::dvec2 d_in = glm::normalize(p - prev), d_out = glm::normalize(next - p);
    const double turn = cross2(d_in, d_out);
    const double theta = std::atan2(std::fabs(turn), glm::dot(d_in, d_out));
    if (c[i].fillet > 0.0 && theta > 1e-9) {
      const double r = c[i].fillet;
      const double t = r * std::tan(0.5 * theta);
      const glm::dvec2 t1 = p - t * d_in, t2 = p + t * d_out;
      segment(start, t1);
      const glm::dvec2 side = turn > 0.0 ? glm::dvec2(-d_in.y, d_in.x) : glm::dvec2(d_in.y, -d_in.x);
      Element e;
      e.arc = true;
      e.a = t1;
      e.b = t2;
      e.centre = t1 + r * side;
      e.radius = r;
      e.angle0 = std::atan2(t1.y - e.centre.y, t1.x - e.centre.x);
      e.sweep = turn > 0.0 ? theta : -theta;
      e.length = r * theta;
      e.outward = glm::dot(elements_.back().normal, (t1 - e.centre) / r) > 0.0 ? 1.0 : -1.0;
      elements_.push_back(e);
      start = t2;
    } else if (c[i].chamfer > 0.0) {
      const glm::dvec2 t1 = p - c[i].chamfer * d_in, t2 = p + c[i].chamfer * d_out;
      segment(start, t1);
      segment(t1, t2);
      start = t2;
    } else {
      segment(start, p);
      start = p;
    }
  }
  segment(start, glm::dvec2(c.back().rho, c.back().y));
}

double RevolveProfile::signed_distance(const glm::dvec2& q, glm::dvec2* normal) const {
  double best = INFINITY, best_s = 0.0;
  std::size_t best_k = 0;
  glm::dvec2 best_point(0.0);
  for (std::size_t k = 0; k < elements_.size(); ++k) {
    const Element& e = elements_[k];
    double s = 0.0;
    if (!e.arc) {
      const glm::dvec2 d = e.b - e.a;
      s = std::clamp(glm::dot(q - e.a, d) / glm::dot(d, d), 0.0, 1.0);
    } else {
      const glm::dvec2 v = q - e.centre;
      bool on = false;
      if (glm::dot(v, v) > 0.0) {
        const double phi = std::atan2(v.y, v.x);
        double delta = e.sweep > 0.0 ? phi - e.angle0 : e.angle0 - phi;
        delta = std::fmod(std::fmod(delta, 2.0 * kPi) + 2.0 * kPi, 2.0 * kPi);
        on = delta <= std::fabs(e.sweep);
        s = on ? delta / std::fabs(e.sweep) : 0.0;
      }
      if (!on) s = glm::length(q - e.a) <= glm::length(q - e.b) ? 0.0 : 1.0;
    }
    const glm::dvec2 point = e.point(s);
    const double d = glm::length(q - point);
    if (d < best) {
      best = d;
      best_s = s;
      best_k = k;
      best_point = point;
    }
  }
  // The pseudo-normal: at an end shared with a neighbour, both normals.
  glm::dvec2 n = elements_[best_k].normal_at(best_s);
  if (best_s <= 0.0 && best_k > 0) n = glm::normalize(n + elements_[best_k - 1].normal_at(1.0));
  if (best_s >= 1.0 && best_k + 1 < elements_.size())
    n = glm::normalize(n + elements_[best_k + 1].normal_at(0.0));
  if (normal != nullptr) *normal = n;
  return glm::dot(q - best_point, n) >= 0.0 ? best : -best;
}

double revolve_field(const RevolveProfile& profile, const glm::dvec3& x) {
  return profile.signed_distance(glm::dvec2(std::sqrt(x.x * x.x + x.z * x.z), x.y), nullptr);
}

glm::dvec3 revolve_normal(const RevolveProfile& profile, const glm::dvec3& x) {
  const double rho = std::sqrt(x.x * x.x + x.z * x.z);
  glm::dvec2 n;
  profile.signed_distance(glm::dvec2(rho, x.y), &n);
  const glm::dvec2 radial = rho > 1e-12 ? glm::dvec2(x.x, x.z) / rho : glm::dvec2(1.0, 0.0);
  return glm::normalize(glm::dvec3(n.x * radial.x, n.y, n.x * radial.y));
}

RevolveParams bowl_params() {
  RevolveParams p;
  p.profile = {
      {0.0, -0.5},        {0.45, -0.5, 0.12},  // floor to inner wall: concave
      {0.8, 0.0, 0.05},                        // inner wall to rim
      {0.95, 0.0, 0.05},                       // rim to outer wall
      {0.6, -0.62, 0.08},                      // outer wall to foot
      {0.0, -0.62},
  };
  return p;
}

RevolveParams cylinder_params() {
  RevolveParams p;
  p.profile = {
      {0.0, 0.8},
      {0.6, 0.8, 0.0, 0.1},
      {0.6, -0.8, 0.0, 0.1},
      {0.0, -0.8},
  };
  return p;
}

namespace {

struct ProfilePoint {
  glm::dvec2 p{0.0}, n{0.0};
};

glm::vec3 revolved(const glm::dvec2& p, double c, double s) {
  return glm::vec3(static_cast<float>(p.x * c), static_cast<float>(p.y), static_cast<float>(p.x * s));
}

}  // namespace

ScenePair make_revolved(const RevolveParams& p) {
  NMBAKE_CHECK(p.low_segments >= 8 && p.low_segments % 4 == 0 && p.high_segments >= 8,
               "segments around the axis");
  ScenePair pair;
  {  // High: the rounded profile, welded around, split at sharp profile corners.
    const RevolveProfile profile(p.profile);
    std::vector<std::vector<ProfilePoint>> strips;
    for (std::size_t k = 0; k < profile.elements().size(); ++k) {
      const RevolveProfile::Element& e = profile.elements()[k];
      int count = std::max(1, static_cast<int>(std::ceil(e.length / p.high_step)));
      if (e.arc)
        count = std::max(count, static_cast<int>(std::ceil(std::fabs(e.sweep) / (2.0 * kPi / 180.0))));
      const bool smooth =
          k > 0 && glm::dot(profile.elements()[k - 1].normal_at(1.0), e.normal_at(0.0)) > 1.0 - 1e-12;
      if (!smooth) strips.emplace_back();
      for (int j = smooth ? 1 : 0; j <= count; ++j) {
        const double s = static_cast<double>(j) / count;
        strips.back().push_back({e.point(s), e.normal_at(s)});
      }
    }
    Mesh& m = pair.high;
    const int n = p.high_segments;
    std::vector<double> cs(n), sn(n);
    for (int j = 0; j < n; ++j) {
      cs[j] = std::cos(2.0 * kPi * j / n);
      sn[j] = std::sin(2.0 * kPi * j / n);
    }
    for (const std::vector<ProfilePoint>& strip : strips) {
      std::vector<std::uint32_t> first(strip.size());
      for (std::size_t i = 0; i < strip.size(); ++i) {
        first[i] = static_cast<std::uint32_t>(m.positions.size());
        const int ring = strip[i].p.x > 0.0 ? n : 1;  // a point on the axis is one pole vertex
        for (int j = 0; j < ring; ++j) {
          m.positions.push_back(revolved(strip[i].p, cs[j], sn[j]));
          m.normals.push_back(glm::vec3(
              glm::normalize(glm::dvec3(strip[i].n.x * cs[j], strip[i].n.y, strip[i].n.x * sn[j]))));
        }
      }
      for (std::size_t i = 0; i + 1 < strip.size(); ++i) {
        const bool pole_a = strip[i].p.x <= 0.0, pole_b = strip[i + 1].p.x <= 0.0;
        for (int j = 0; j < n; ++j) {
          const std::uint32_t j1 = static_cast<std::uint32_t>((j + 1) % n),
                              j0 = static_cast<std::uint32_t>(j);
          const std::uint32_t a0 = first[i] + (pole_a ? 0 : j0), a1 = first[i] + (pole_a ? 0 : j1);
          const std::uint32_t b0 = first[i + 1] + (pole_b ? 0 : j0), b1 = first[i + 1] + (pole_b ? 0 : j1);
          if (!pole_a && !pole_b) {
            add_triangle(m, a0, a1, b1);
            add_triangle(m, a0, b1, b0);
          } else if (pole_a) {
            add_triangle(m, a0, b1, b0);
          } else {
            add_triangle(m, a0, a1, b0);
          }
        }
      }
    }
  }
  {  // Low: straight segments, one band (four charts) or disc chart each.
    const std::vector<ProfileCorner>& c = p.profile;
    const double orient = orientation(c);
    const std::size_t segments = c.size() - 1;
    std::vector<glm::dvec2> seg_normal(segments);
    for (std::size_t k = 0; k < segments; ++k) {
      const glm::dvec2 d = glm::normalize(glm::dvec2(c[k + 1].rho - c[k].rho, c[k + 1].y - c[k].y));
      seg_normal[k] = outward_of(d, orient);
    }
    // The normal of segment k at its corner i (k or k + 1).
    const auto corner_normal = [&](std::size_t k, std::size_t i) {
      if (i > 0 && i < segments && c[i].low_smooth) return glm::normalize(seg_normal[i - 1] + seg_normal[i]);
      return seg_normal[k];
    };
    Mesh& m = pair.low;
    std::vector<Chart> charts;
    const int n = p.low_segments;
    std::vector<double> cs(n + 1), sn(n + 1);
    for (int j = 0; j <= n; ++j) {
      cs[j] = std::cos(2.0 * kPi * (j % n) / n);
      sn[j] = std::sin(2.0 * kPi * (j % n) / n);
    }
    const auto vertex = [&](const glm::dvec2& q, const glm::dvec2& normal, int j, glm::dvec2 uv) {
      m.positions.push_back(revolved(q, cs[j], sn[j]));
      m.normals.push_back(
          glm::vec3(glm::normalize(glm::dvec3(normal.x * cs[j], normal.y, normal.x * sn[j]))));
      m.uvs.push_back(glm::vec2(uv));
      return static_cast<std::uint32_t>(m.positions.size() - 1);
    };
    for (std::size_t k = 0; k < segments; ++k) {
      const glm::dvec2 A(c[k].rho, c[k].y), B(c[k + 1].rho, c[k + 1].y);
      const glm::dvec2 nA = corner_normal(k, k), nB = corner_normal(k, k + 1);
      if (A.x <= 0.0 || B.x <= 0.0) {  // a disc: planar UVs
        const bool pole_first = A.x <= 0.0;
        const glm::dvec2 pole = pole_first ? A : B, rim = pole_first ? B : A;
        const glm::dvec2 n_pole = pole_first ? nA : nB, n_rim = pole_first ? nB : nA;
        Chart chart;
        chart.first = static_cast<std::uint32_t>(m.positions.size());
        chart.width = chart.height = 2.0 * rim.x;
        const std::size_t first_index = m.indices.size();
        const std::uint32_t centre = vertex(pole, n_pole, 0, {rim.x, rim.x});
        std::vector<std::uint32_t> ring(n);
        for (int j = 0; j < n; ++j)
          ring[j] = vertex(rim, n_rim, j, {rim.x + rim.x * cs[j], rim.x + rim.x * sn[j]});
        for (int j = 0; j < n; ++j) add_triangle(m, centre, ring[j], ring[(j + 1) % n]);
        chart.end = static_cast<std::uint32_t>(m.positions.size());
        unmirror(m, chart, first_index);
        charts.push_back(chart);
        continue;
      }
      const double length = glm::length(B - A);
      const int quarter = n / 4;
      for (int q = 0; q < 4; ++q) {
        Chart chart;
        chart.first = static_cast<std::uint32_t>(m.positions.size());
        chart.width = 0.5 * kPi * 0.5 * (A.x + B.x);
        chart.height = length;
        const std::size_t first_index = m.indices.size();
        std::vector<std::uint32_t> a(quarter + 1), b(quarter + 1);
        for (int j = 0; j <= quarter; ++j) {
          const double u = chart.width * j / quarter;
          a[j] = vertex(A, nA, q * quarter + j, {u, 0.0});
          b[j] = vertex(B, nB, q * quarter + j, {u, length});
        }
        for (int j = 0; j < quarter; ++j) {
          add_triangle(m, a[j], a[j + 1], b[j + 1]);
          add_triangle(m, a[j], b[j + 1], b[j]);
        }
        chart.end = static_cast<std::uint32_t>(m.positions.size());
        unmirror(m, chart, first_index);
        charts.push_back(chart);
      }
    }
    pack_charts(m, charts, 0.01);
  }
  return pair;
}

// --- Panel ---------------------------------------------------------------------

PanelParams panel_params() {
  PanelParams p;
  p.pockets = {
      {-0.35, -0.3, 0.4, 0.25, 0.08, 0.05, 0.05},  // a rounded rectangle
      {0.86, 0.15, 0.05, 0.45, 0.05, 0.05, 0.04},  // a slot 0.09 from the +x edge
      {0.3, 0.45, 0.2, 0.2, 0.2, 0.05, 0.06},      // a round pocket
      // The dimple: a wall wider than its radius never levels off, so it is a
      // steep cone (65 degrees at the tip) 0.148 * smoothstep(2/3) = 0.11 deep.
      {-0.55, 0.5, 0.06, 0.06, 0.06, 0.148, 0.09},
      {-0.1, 0.88, 0.6, 0.035, 0.035, 0.04, 0.03},  // a groove 0.085 from the +z edge
  };
  return p;
}

double panel_depth(const PanelParams& p, double x, double z, double* ddx, double* ddz) {
  double depth = 0.0, gx = 0.0, gz = 0.0;
  for (const PanelPocket& k : p.pockets) {
    const double sx = x >= k.x ? 1.0 : -1.0, sz = z >= k.z ? 1.0 : -1.0;
    const double dx = std::fabs(x - k.x) - (k.half_x - k.radius),
                 dz = std::fabs(z - k.z) - (k.half_z - k.radius);
    const double ox = std::max(dx, 0.0), oz = std::max(dz, 0.0);
    const double outside = std::sqrt(ox * ox + oz * oz);
    const double s = outside + std::min(std::max(dx, dz), 0.0) - k.radius;
    const double t = std::clamp(-s / k.wall, 0.0, 1.0);
    if (t <= 0.0) continue;
    depth += k.depth * t * t * (3.0 - 2.0 * t);
    // d depth / d s = -depth * 6 t (1 - t) / wall; grad s of the rounded box.
    const double slope = -k.depth * 6.0 * t * (1.0 - t) / k.wall;
    double grad_x = 0.0, grad_z = 0.0;
    if (outside > 0.0) {
      grad_x = sx * ox / outside;
      grad_z = sz * oz / outside;
    } else if (dx > dz) {
      grad_x = sx;
    } else {
      grad_z = sz;
    }
    gx += slope * grad_x;
    gz += slope * grad_z;
  }
  if (ddx != nullptr) *ddx = gx;
  if (ddz != nullptr) *ddz = gz;
  return depth;
}

namespace {

// The slab as a box: exact signed distance and its gradient.
double slab_distance(const PanelParams& p, const glm::dvec3& x, glm::dvec3* gradient) {
  const glm::dvec3 centre(0.0, 0.5 * (p.top + p.bottom), 0.0),
      extent(p.half, 0.5 * (p.top - p.bottom), p.half);
  const glm::dvec3 d = x - centre;
  const glm::dvec3 q = glm::abs(d) - extent;
  const glm::dvec3 o = glm::max(q, 0.0);
  const double outside = glm::length(o);
  const double inside = std::min(std::max(q.x, std::max(q.y, q.z)), 0.0);
  if (gradient != nullptr) {
    const glm::dvec3 sign(d.x >= 0.0 ? 1.0 : -1.0, d.y >= 0.0 ? 1.0 : -1.0, d.z >= 0.0 ? 1.0 : -1.0);
    if (outside > 0.0) {
      *gradient = sign * o / outside;
    } else {
      const int axis = q.x >= q.y && q.x >= q.z ? 0 : (q.y >= q.z ? 1 : 2);
      *gradient = glm::dvec3(0.0);
      (*gradient)[axis] = sign[axis];
    }
  }
  return outside + inside;
}

}  // namespace

double panel_field(const PanelParams& p, const glm::dvec3& x) {
  const double carved = x.y - (p.top - panel_depth(p, x.x, x.z, nullptr, nullptr));
  return std::max(slab_distance(p, x, nullptr), carved);
}

glm::dvec3 panel_normal(const PanelParams& p, const glm::dvec3& x) {
  glm::dvec3 slab;
  const double box = slab_distance(p, x, &slab);
  double gx = 0.0, gz = 0.0;
  const double carved = x.y - (p.top - panel_depth(p, x.x, x.z, &gx, &gz));
  if (carved >= box && std::fabs(x.x) <= p.half && std::fabs(x.z) <= p.half)
    return glm::normalize(glm::dvec3(gx, 1.0, gz));
  return slab;
}

namespace {

// One face of the panel as a grid: corner `origin`, edges `e1` (cells1) and
// `e2` (cells2) given as functions of the grid index, so vertices shared
// with the neighbouring faces are computed by the same expression.
template <class Position, class Normal>
void add_grid(Mesh& m, int cells1, int cells2, const Position& position, const Normal& normal, bool with_uvs,
              double width, double height) {
  const std::uint32_t first = static_cast<std::uint32_t>(m.positions.size());
  for (int j = 0; j <= cells2; ++j) {
    for (int i = 0; i <= cells1; ++i) {
      const glm::dvec3 x = position(i, j);
      m.positions.push_back(glm::vec3(x));
      m.normals.push_back(glm::vec3(normal(x)));
      if (with_uvs) m.uvs.push_back(glm::vec2(glm::dvec2(width * i / cells1, height * j / cells2)));
    }
  }
  const auto id = [&](int i, int j) { return first + static_cast<std::uint32_t>(j * (cells1 + 1) + i); };
  for (int j = 0; j < cells2; ++j) {
    for (int i = 0; i < cells1; ++i) {
      add_triangle(m, id(i, j), id(i + 1, j), id(i + 1, j + 1));
      add_triangle(m, id(i, j), id(i + 1, j + 1), id(i, j + 1));
    }
  }
}

// The six faces of the slab (the top through `top_y`), each a grid of
// `cells` along the slab's sides and `cells_y` up its height.
template <class TopY, class TopNormal>
std::vector<Chart> add_slab(Mesh& m, const PanelParams& p, int cells, int cells_y, const TopY& top_y,
                            const TopNormal& top_normal, bool with_uvs) {
  const double h = p.half;
  const auto c = [&](int k) { return at(k, cells, -h, h); };
  const auto y = [&](int k) { return at(k, cells_y, p.bottom, p.top); };
  const double side = 2.0 * h, height = p.top - p.bottom;
  std::vector<Chart> charts;
  const auto face = [&](auto position, auto normal, int c1, int c2, double w, double hgt) {
    Chart chart;
    chart.first = static_cast<std::uint32_t>(m.positions.size());
    chart.width = w;
    chart.height = hgt;
    const std::size_t first_index = m.indices.size();
    add_grid(m, c1, c2, position, normal, with_uvs, w, hgt);
    chart.end = static_cast<std::uint32_t>(m.positions.size());
    if (with_uvs) unmirror(m, chart, first_index);
    charts.push_back(chart);
  };
  face([&](int i, int j) { return glm::dvec3(c(i), top_y(c(i), c(j)), c(j)); }, top_normal, cells, cells,
       side, side);
  face([&](int i, int j) { return glm::dvec3(c(i), p.bottom, c(j)); },
       [](const glm::dvec3&) { return glm::dvec3(0, -1, 0); }, cells, cells, side, side);
  face([&](int i, int j) { return glm::dvec3(h, y(j), c(i)); },
       [](const glm::dvec3&) { return glm::dvec3(1, 0, 0); }, cells, cells_y, side, height);
  face([&](int i, int j) { return glm::dvec3(-h, y(j), c(i)); },
       [](const glm::dvec3&) { return glm::dvec3(-1, 0, 0); }, cells, cells_y, side, height);
  face([&](int i, int j) { return glm::dvec3(c(i), y(j), h); },
       [](const glm::dvec3&) { return glm::dvec3(0, 0, 1); }, cells, cells_y, side, height);
  face([&](int i, int j) { return glm::dvec3(c(i), y(j), -h); },
       [](const glm::dvec3&) { return glm::dvec3(0, 0, -1); }, cells, cells_y, side, height);
  return charts;
}

}  // namespace

ScenePair make_panel(const PanelParams& p) {
  NMBAKE_CHECK(p.half > 0.0 && p.top > p.bottom && p.low_cells >= 1 && p.high_cells >= 1, "panel sizes");
  for (const PanelPocket& k : p.pockets) {
    NMBAKE_CHECK(std::fabs(k.x) + k.half_x < p.half && std::fabs(k.z) + k.half_z < p.half,
                 "pockets inside the top");
    NMBAKE_CHECK(k.radius <= std::min(k.half_x, k.half_z) && k.wall > 0.0 && k.depth < p.top - p.bottom,
                 "pocket shape");
  }
  ScenePair pair;
  const std::vector<Chart> charts = add_slab(
      pair.low, p, p.low_cells, 1, [&](double, double) { return p.top; },
      [](const glm::dvec3&) { return glm::dvec3(0, 1, 0); }, true);
  pack_charts(pair.low, charts, 0.01);
  add_slab(
      pair.high, p, p.high_cells, 16,
      [&](double x, double z) { return p.top - panel_depth(p, x, z, nullptr, nullptr); },
      [&](const glm::dvec3& x) {
        double gx = 0.0, gz = 0.0;
        panel_depth(p, x.x, x.z, &gx, &gz);
        return glm::normalize(glm::dvec3(gx, 1.0, gz));
      },
      false);
  return pair;
}

// --- Names ---------------------------------------------------------------------

double lab_box_bevel(const std::string& scene) {
  if (scene == "box") return 0.2;
  if (scene == "box_r0.05") return 0.05;
  if (scene == "box_r0.1") return 0.1;
  if (scene == "box_r0.4") return 0.4;
  return -1.0;
}

const std::vector<std::string>& hard_scene_names() {
  static const std::vector<std::string> names = {"box_r0.05", "box_r0.1", "box_r0.4",
                                                 "bowl",      "cylinder", "panel"};
  return names;
}

bool make_hard_scene(const std::string& scene, ScenePair& out) {
  const double bevel = lab_box_bevel(scene);
  if (bevel > 0.0) {
    BoxParams p;
    p.bevel = static_cast<float>(bevel);
    // About as many high vertices across every bevel.
    p.high_cells = bevel < 0.08 ? 320 : 160;
    out = make_box(p);
    return true;
  }
  if (scene == "bowl") {
    out = make_revolved(bowl_params());
    return true;
  }
  if (scene == "cylinder") {
    out = make_revolved(cylinder_params());
    return true;
  }
  if (scene == "panel") {
    out = make_panel(panel_params());
    return true;
  }
  return false;
}

}  // namespace nmbake::scenes
