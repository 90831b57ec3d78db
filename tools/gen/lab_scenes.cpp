// The lab's analytic scenes. The torus normal is the gradient of
// |q| - rho(phi, theta) (q the point relative to the tube's centre circle);
// the crater moon's is the radial-heightfield normal d - grad_s H / (1 + H)
// used for the displaced sphere; the rounded box is the exact signed distance
// to a box inflated by a ball (Minkowski sum), whose normal is the direction
// from the nearest core point; the slot's bumps are the classic C-infinity
// bump function exp(1 - 1 / (1 - s^2)) with compact support.
#include "lab_scenes.hpp"

#include <algorithm>
#include <array>
#include <cmath>
#include <glm/geometric.hpp>
#include <numbers>
#include <vector>

#include "noise.hpp"

namespace nmbake::scenes {

namespace {

constexpr double kTwoPi = 2.0 * std::numbers::pi;

// Coordinate k of n in [0, size]: exact at both ends, the same bits for the
// same (k, n, size) everywhere.
double coord(int k, int n, double size) { return k == n ? size : size * static_cast<double>(k) / n; }

// (n + 1)^2 vertex grid, two counter-clockwise triangles per cell; `index`
// maps grid (i, j) to a vertex (lets a welded grid wrap around).
template <typename Index>
void append_cells(int na, int nb, const Index& index, std::vector<std::uint32_t>& indices) {
  for (int j = 0; j < nb; ++j) {
    for (int i = 0; i < na; ++i) {
      const std::uint32_t a = index(i, j), b = index(i + 1, j), c = index(i + 1, j + 1), d = index(i, j + 1);
      indices.insert(indices.end(), {a, b, c, a, c, d});
    }
  }
}

}  // namespace

// --- Torus ---------------------------------------------------------------------

namespace {

struct TorusLobe {
  double phi, theta, kappa_phi, kappa_theta, height;
};
constexpr std::array<TorusLobe, 6> kTorusLobes = {{
    {0.3, 0.5, 40.0, 12.0, 1.0},
    {1.4, 2.6, 60.0, 20.0, -0.9},
    {2.5, -1.2, 30.0, 8.0, 0.8},
    {3.6, 0.0, 80.0, 25.0, 1.1},
    {4.7, 1.9, 50.0, 15.0, -0.7},
    {5.6, -2.4, 35.0, 10.0, 0.9},
}};
constexpr double kTorusWave = 0.3;

// f, df/dphi, df/dtheta: smooth and 2 pi periodic in both angles.
void torus_function(double phi, double theta, double& f, double& f_phi, double& f_theta) {
  f = kTorusWave * std::sin(5.0 * phi) * std::cos(3.0 * theta);
  f_phi = kTorusWave * 5.0 * std::cos(5.0 * phi) * std::cos(3.0 * theta);
  f_theta = -kTorusWave * 3.0 * std::sin(5.0 * phi) * std::sin(3.0 * theta);
  for (const TorusLobe& l : kTorusLobes) {
    const double v = l.height * std::exp(l.kappa_phi * (std::cos(phi - l.phi) - 1.0) +
                                         l.kappa_theta * (std::cos(theta - l.theta) - 1.0));
    f += v;
    f_phi -= v * l.kappa_phi * std::sin(phi - l.phi);
    f_theta -= v * l.kappa_theta * std::sin(theta - l.theta);
  }
}

struct TorusAngles {
  double phi, theta, ring, tube;  // ring: distance from the z axis; tube: |q|
};
TorusAngles torus_angles(const TorusParams& p, const glm::dvec3& x) {
  TorusAngles a;
  a.ring = std::sqrt(x.x * x.x + x.y * x.y);
  a.phi = std::atan2(x.y, x.x);
  const double qx = a.ring - p.major;
  a.tube = std::sqrt(qx * qx + x.z * x.z);
  a.theta = std::atan2(x.z, qx);
  return a;
}

glm::dvec3 torus_point(const TorusParams& p, double phi, double theta, bool displaced) {
  double rho = p.minor;
  if (displaced) {
    double f, fp, ft;
    torus_function(phi, theta, f, fp, ft);
    rho *= 1.0 + static_cast<double>(p.amplitude) * f;
  }
  const double ring = p.major + rho * std::cos(theta);
  return {ring * std::cos(phi), ring * std::sin(phi), rho * std::sin(theta)};
}

}  // namespace

double torus_field(const TorusParams& p, const glm::dvec3& x) {
  const TorusAngles a = torus_angles(p, x);
  double f, fp, ft;
  torus_function(a.phi, a.theta, f, fp, ft);
  return a.tube - static_cast<double>(p.minor) * (1.0 + static_cast<double>(p.amplitude) * f);
}

glm::dvec3 torus_normal(const TorusParams& p, const glm::dvec3& x) {
  const TorusAngles a = torus_angles(p, x);
  double f, fp, ft;
  torus_function(a.phi, a.theta, f, fp, ft);
  const double am = static_cast<double>(p.minor) * p.amplitude;
  const double rho = p.minor + am * f;
  const double cp = std::cos(a.phi), sp = std::sin(a.phi), ct = std::cos(a.theta), st = std::sin(a.theta);
  const glm::dvec3 e_r(ct * cp, ct * sp, st), e_phi(-sp, cp, 0.0), e_theta(-st * cp, -st * sp, ct);
  // grad(|q| - rho) = e_r - rho_phi e_phi / ring - rho_theta e_theta / |q|,
  // evaluated with ring and |q| of the surface point.
  const glm::dvec3 n = e_r - (am * fp / (p.major + rho * ct)) * e_phi - (am * ft / rho) * e_theta;
  return glm::normalize(n);
}

ScenePair make_torus(const TorusParams& p) {
  NMBAKE_CHECK(p.low_cells >= 3 && p.high_cells >= 3 && p.high_cells <= 4096, "torus cells out of range");
  NMBAKE_CHECK(p.minor > 0.0f && p.major > p.minor * (1.0f + 2.0f * p.amplitude), "torus radii out of range");
  ScenePair pair;
  {  // low: split along the seams, UVs (phi, theta) / 2 pi
    Mesh& m = pair.low;
    const int nu = 3 * p.low_cells, nv = p.low_cells;
    for (int j = 0; j <= nv; ++j) {
      for (int i = 0; i <= nu; ++i) {
        // Seam vertices take the angles of index 0, so both copies are bitwise equal.
        const double phi = kTwoPi * (i % nu) / nu, theta = kTwoPi * (j % nv) / nv;
        m.positions.emplace_back(torus_point(p, phi, theta, false));
        m.normals.emplace_back(std::cos(theta) * std::cos(phi), std::cos(theta) * std::sin(phi),
                               std::sin(theta));
        m.uvs.emplace_back(static_cast<float>(coord(i, nu, 1.0)), static_cast<float>(coord(j, nv, 1.0)));
      }
    }
    append_cells(
        nu, nv, [&](int i, int j) { return static_cast<std::uint32_t>(j * (nu + 1) + i); }, m.indices);
  }
  {  // high: welded
    Mesh& m = pair.high;
    const int nu = 3 * p.high_cells, nv = p.high_cells;
    m.positions.resize(static_cast<std::size_t>(nu) * nv);
    m.normals.resize(m.positions.size());
    for (int j = 0; j < nv; ++j) {
      for (int i = 0; i < nu; ++i) {
        const glm::dvec3 x = torus_point(p, kTwoPi * i / nu, kTwoPi * j / nv, true);
        const std::size_t k = static_cast<std::size_t>(j) * nu + i;
        m.positions[k] = glm::vec3(x);
        m.normals[k] = glm::vec3(torus_normal(p, x));
      }
    }
    append_cells(
        nu, nv, [&](int i, int j) { return static_cast<std::uint32_t>((j % nv) * nu + (i % nu)); },
        m.indices);
  }
  return pair;
}

// --- Smooth-crater moon ----------------------------------------------------------

namespace {

constexpr double kCraterReach = 2.0;                    // ejecta end, in crater radii
constexpr double kCraterMin = 0.08, kCraterMax = 0.35;  // angular radii
constexpr double kCraterDepth = 0.15;                   // depth / angular radius
constexpr double kCraterRim = 0.3;                      // rim / depth

struct SmoothCrater {
  glm::dvec3 centre;
  double size, depth, rim, cos_reach;
};

// Profile and its derivative in x = angle / size.
void crater_profile(double x, double depth, double rim, double& value, double& slope) {
  if (x < 1.0) {
    value = -depth + (depth + rim) * x * x * (3.0 - 2.0 * x);
    slope = (depth + rim) * 6.0 * x * (1.0 - x);
  } else if (x < kCraterReach) {
    const double t = (x - 1.0) / (kCraterReach - 1.0);
    value = rim * (1.0 - t * t * (3.0 - 2.0 * t));
    slope = -rim * 6.0 * t * (1.0 - t) / (kCraterReach - 1.0);
  } else {
    value = 0.0;
    slope = 0.0;
  }
}

}  // namespace

struct CraterSurface::Impl {
  CraterParams params;
  std::vector<SmoothCrater> craters;
};

CraterSurface::CraterSurface(const CraterParams& p) : impl_(std::make_unique<Impl>()) {
  NMBAKE_CHECK(p.radius > 0.0f && p.crater_count >= 0, "crater moon parameters out of range");
  impl_->params = p;
  const double ratio = (kCraterMin / kCraterMax) * (kCraterMin / kCraterMax);
  for (int k = 0; k < p.crater_count; ++k) {
    const auto u = [&](std::uint32_t n) {
      return noise::unit_from_hash(noise::hash(p.seed, static_cast<std::uint32_t>(k), n));
    };
    SmoothCrater c;
    const double z = 2.0 * u(0) - 1.0, lon = kTwoPi * u(1), ring = std::sqrt(std::max(0.0, 1.0 - z * z));
    c.centre = {ring * std::cos(lon), ring * std::sin(lon), z};
    c.size = kCraterMin / std::sqrt(1.0 - u(2) * (1.0 - ratio));  // N(>R) ~ R^-2
    c.depth = kCraterDepth * c.size * (0.8 + 0.4 * u(3));
    c.rim = kCraterRim * c.depth;
    c.cos_reach = std::cos(std::min(kCraterReach * c.size + 1e-6, std::numbers::pi));
    impl_->craters.push_back(c);
  }
}

CraterSurface::~CraterSurface() = default;

const CraterParams& CraterSurface::params() const { return impl_->params; }

double CraterSurface::relative_height(const glm::dvec3& d, glm::dvec3* gradient) const {
  double h = 0.0;
  glm::dvec3 g(0.0);
  for (const SmoothCrater& c : impl_->craters) {
    const double cos_angle = glm::dot(d, c.centre);
    if (cos_angle <= c.cos_reach) continue;
    const double chord = glm::length(d - c.centre);
    const double angle = 2.0 * std::asin(std::min(1.0, 0.5 * chord));
    double value, slope;
    crater_profile(angle / c.size, c.depth, c.rim, value, slope);
    h += value;
    if (gradient != nullptr) {
      // grad_s angle = -(c - (c.d) d) / sin(angle); the slope is 0 at the
      // centre, where that direction is undefined.
      const glm::dvec3 away = c.centre - cos_angle * d;
      const double s = glm::length(away);
      if (s > 1e-12) g -= (slope / c.size / s) * away;
    }
  }
  if (gradient != nullptr) *gradient = g;
  return h;
}

double CraterSurface::field(const glm::dvec3& x) const {
  const double r = glm::length(x);
  if (!(r > 0.0)) return -impl_->params.radius;
  return r - impl_->params.radius * (1.0 + relative_height(x / r, nullptr));
}

glm::dvec3 CraterSurface::normal(const glm::dvec3& direction) const {
  const glm::dvec3 d = glm::normalize(direction);
  glm::dvec3 g;
  const double h = relative_height(d, &g);
  return glm::normalize(d - g / (1.0 + h));
}

ScenePair make_craters(const CraterParams& p) {
  const CraterSurface surface(p);
  const float radius = p.radius;
  ScenePair pair;
  pair.low = make_cube_sphere(
      p.low_cells, [radius](const glm::vec3&) { return radius; }, true, sphere_uv_gutter);
  pair.high = make_cube_sphere(
      p.high_cells,
      [&](const glm::vec3& d) {
        return static_cast<float>(p.radius *
                                  (1.0 + surface.relative_height(glm::normalize(glm::dvec3(d)), nullptr)));
      },
      false, 0.0f);
  pair.high.normals.resize(pair.high.positions.size());
  for (std::size_t k = 0; k < pair.high.positions.size(); ++k)
    pair.high.normals[k] = glm::vec3(surface.normal(glm::dvec3(pair.high.positions[k])));
  return pair;
}

// --- Bevelled box ------------------------------------------------------------------

double box_field(const BoxParams& p, const glm::dvec3& x) {
  const double core = static_cast<double>(p.half_extent) - p.bevel;
  const glm::dvec3 q = glm::abs(x) - glm::dvec3(core);
  return glm::length(glm::max(q, 0.0)) + std::min(std::max(q.x, std::max(q.y, q.z)), 0.0) - p.bevel;
}

glm::dvec3 box_normal(const BoxParams& p, const glm::dvec3& x) {
  const double core = static_cast<double>(p.half_extent) - p.bevel;
  const glm::dvec3 v = x - glm::clamp(x, glm::dvec3(-core), glm::dvec3(core));
  const double l = glm::length(v);
  if (l > 1e-12) return v / l;
  // Inside the core (not a surface point): the nearest face's axis.
  const glm::dvec3 a = glm::abs(x);
  const int axis = a.x >= a.y && a.x >= a.z ? 0 : (a.y >= a.z ? 1 : 2);
  glm::dvec3 n(0.0);
  n[axis] = x[axis] < 0.0 ? -1.0 : 1.0;
  return n;
}

ScenePair make_box(const BoxParams& p) {
  NMBAKE_CHECK(p.half_extent > 0.0f && p.bevel >= 0.0f && p.bevel < p.half_extent,
               "box parameters out of range");
  ScenePair pair;
  const float h = p.half_extent;
  pair.low = make_cube_sphere(
      p.low_cells,
      [h](const glm::vec3& d) {
        return h / std::max(std::fabs(d.x), std::max(std::fabs(d.y), std::fabs(d.z)));
      },
      true, sphere_uv_gutter);
  Mesh& low = pair.low;
  // Snap to the exact faces, and give every vertex its face's normal: the
  // vertices are split per face (one UV chart each), so this is a hard edge.
  for (glm::vec3& v : low.positions) {
    for (int c = 0; c < 3; ++c) {
      if (std::fabs(std::fabs(v[c]) - h) < 1e-5f * h) v[c] = v[c] < 0.0f ? -h : h;
    }
  }
  low.normals.assign(low.positions.size(), glm::vec3(0.0f));
  for (std::size_t t = 0; t < low.triangle_count(); ++t) {
    const std::uint32_t* v = &low.indices[3 * t];
    const glm::vec3 centre = (low.positions[v[0]] + low.positions[v[1]] + low.positions[v[2]]) / 3.0f;
    const glm::vec3 a = glm::abs(centre);
    const int axis = a.x >= a.y && a.x >= a.z ? 0 : (a.y >= a.z ? 1 : 2);
    glm::vec3 n(0.0f);
    n[axis] = centre[axis] < 0.0f ? -1.0f : 1.0f;
    for (int k = 0; k < 3; ++k) low.normals[v[k]] = n;
  }
  pair.high = make_cube_sphere(
      p.high_cells,
      [&p](const glm::vec3& d) {
        // The box is star-shaped around the origin: bisect along d.
        const glm::dvec3 u = glm::normalize(glm::dvec3(d));
        double lo = 0.0, hi = 2.0 * p.half_extent;
        for (int i = 0; i < 60; ++i) {
          const double mid = 0.5 * (lo + hi);
          (box_field(p, mid * u) < 0.0 ? lo : hi) = mid;
        }
        return static_cast<float>(0.5 * (lo + hi));
      },
      false, 0.0f);
  pair.high.normals.resize(pair.high.positions.size());
  for (std::size_t k = 0; k < pair.high.positions.size(); ++k)
    pair.high.normals[k] = glm::vec3(box_normal(p, glm::dvec3(pair.high.positions[k])));
  return pair;
}

// --- Slot ----------------------------------------------------------------------------

namespace {

struct SlotBump {
  double a, b, radius, height;  // centre in (across, z) patch coordinates
};
// Across coordinate: y for the walls, x for the floor. Every support stays
// inside its patch, so h = 0 on the patch borders.
constexpr std::array<std::array<SlotBump, 3>, slot_patch_count> kSlotBumps = {{
    {{{0.30, 0.28, 0.20, 1.0}, {0.32, 0.72, 0.16, -0.8}, {0.15, 0.50, 0.10, 0.6}}},
    {{{0.00, 0.30, 0.17, 1.0}, {0.00, 0.70, 0.15, -0.9}, {0.05, 0.50, 0.10, 0.5}}},
    {{{0.25, 0.40, 0.18, -0.9}, {0.35, 0.78, 0.14, 1.0}, {0.45, 0.18, 0.12, 0.7}}},
}};

// h and its gradient in patch coordinates.
double slot_height(const SlotParams& p, int patch, double a, double b, double& ha, double& hb) {
  double h = 0.0;
  ha = hb = 0.0;
  for (const SlotBump& k : kSlotBumps[static_cast<std::size_t>(patch)]) {
    const double da = a - k.a, db = b - k.b;
    const double s2 = (da * da + db * db) / (k.radius * k.radius);
    if (s2 >= 1.0) continue;
    const double psi = k.height * std::exp(1.0 - 1.0 / (1.0 - s2));
    const double factor = -2.0 * psi / (k.radius * k.radius * (1.0 - s2) * (1.0 - s2));
    h += psi;
    ha += factor * da;
    hb += factor * db;
  }
  const double amp = p.amplitude;
  ha *= amp;
  hb *= amp;
  return amp * h;
}

}  // namespace

double slot_field(const SlotParams& p, int patch, const glm::dvec3& x) {
  double ha, hb;
  const double half = 0.5 * p.width;
  switch (patch) {
    case 0:
      return x.x - (-half + slot_height(p, 0, x.y, x.z, ha, hb));
    case 1:
      return x.y - slot_height(p, 1, x.x, x.z, ha, hb);
    default:
      return (half - slot_height(p, 2, x.y, x.z, ha, hb)) - x.x;
  }
}

glm::dvec3 slot_normal(const SlotParams& p, int patch, const glm::dvec3& x) {
  double ha, hb;
  switch (patch) {
    case 0:
      slot_height(p, 0, x.y, x.z, ha, hb);
      return glm::normalize(glm::dvec3(1.0, -ha, -hb));
    case 1:
      slot_height(p, 1, x.x, x.z, ha, hb);
      return glm::normalize(glm::dvec3(-ha, 1.0, -hb));
    default:
      slot_height(p, 2, x.y, x.z, ha, hb);
      return glm::normalize(glm::dvec3(-1.0, -ha, -hb));
  }
}

bool slot_in_patch(const SlotParams& p, int patch, const glm::dvec3& x) {
  const double eps = 1e-9;
  if (x.z < -eps || x.z > p.length + eps) return false;
  if (patch == 1) return x.x >= -0.5 * p.width - eps && x.x <= 0.5 * p.width + eps;
  return x.y >= -eps && x.y <= p.depth + eps;
}

ScenePair make_slot(const SlotParams& p) {
  NMBAKE_CHECK(p.width > 0.0f && p.depth > 0.0f && p.length > 0.0f, "slot sizes must be positive");
  const double W = p.width, H = p.depth, L = p.length, half = 0.5 * W;
  const double longest = std::max(W, std::max(H, L));
  const double across[slot_patch_count] = {H, W, H};
  // UV charts side by side, one texel density, gutter g.
  const double g = 0.01;
  const double scale = std::min((1.0 - 4.0 * g) / (2.0 * H + W), (1.0 - 2.0 * g) / L);
  ScenePair pair;
  for (int pass = 0; pass < 2; ++pass) {
    const bool high = pass == 1;
    Mesh& m = high ? pair.high : pair.low;
    const int cells = high ? p.high_cells : p.low_cells;
    const int nb = std::max(1, static_cast<int>(std::lround(cells * L / longest)));
    double u0 = g;
    for (int patch = 0; patch < slot_patch_count; ++patch) {
      const int na = std::max(1, static_cast<int>(std::lround(cells * across[patch] / longest)));
      const std::uint32_t base = static_cast<std::uint32_t>(m.positions.size());
      for (int j = 0; j <= nb; ++j) {
        for (int i = 0; i <= na; ++i) {
          // Patch parameters chosen so that cross(dP/da, dP/db) points into the groove.
          double ha = 0.0, hb = 0.0;
          glm::dvec3 x;
          if (patch == 0) {
            x = {-half, coord(i, na, H), coord(j, nb, L)};
            if (high) x.x += slot_height(p, 0, x.y, x.z, ha, hb);
          } else if (patch == 1) {
            x = {-half + coord(i, na, W), 0.0, coord(nb - j, nb, L)};
            if (i == na) x.x = half;
            if (high) x.y = slot_height(p, 1, x.x, x.z, ha, hb);
          } else {
            x = {half, coord(na - i, na, H), coord(j, nb, L)};
            if (high) x.x -= slot_height(p, 2, x.y, x.z, ha, hb);
          }
          m.positions.emplace_back(x);
          const glm::dvec3 n = high
                                   ? slot_normal(p, patch, x)
                                   : (patch == 0 ? glm::dvec3(1, 0, 0)
                                                 : (patch == 1 ? glm::dvec3(0, 1, 0) : glm::dvec3(-1, 0, 0)));
          m.normals.emplace_back(n);
          if (!high) {
            m.uvs.emplace_back(static_cast<float>(u0 + coord(i, na, across[patch]) * scale),
                               static_cast<float>(g + coord(j, nb, L) * scale));
          }
        }
      }
      append_cells(
          na, nb, [&](int i, int j) { return base + static_cast<std::uint32_t>(j * (na + 1) + i); },
          m.indices);
      u0 += across[patch] * scale + g;
    }
  }
  return pair;
}

// --- Cage and distances ---------------------------------------------------------------

Mesh make_offset_cage(const Mesh& low, float offset) {
  MeshStats stats;
  const std::vector<glm::vec3> averaged = averaged_normals(low, stats);
  Mesh cage;
  cage.positions.resize(low.positions.size());
  for (std::size_t v = 0; v < low.positions.size(); ++v)
    cage.positions[v] = low.positions[v] + offset * averaged[v];
  cage.uvs = low.uvs;
  cage.indices = low.indices;
  return cage;
}

LabDistances lab_distances(const std::string& scene) {
  if (scene == "heightfield") return {0.05f, 0.05f};
  if (scene == "sphere") return {0.06f, 0.06f};
  if (scene == "torus") return {0.06f, 0.06f};
  if (scene == "craters") return {0.05f, 0.08f};
  if (scene == "box") return {0.05f, 0.25f};
  if (scene == "slot") return {0.5f, 0.05f};  // longer than the groove is wide (0.4)
  // Deeper than the deepest bevel corner ((sqrt 3 - 1) r), the chamfer and the dimple.
  if (scene == "box_r0.05") return {0.05f, 0.1f};
  if (scene == "box_r0.1") return {0.05f, 0.15f};
  if (scene == "box_r0.4") return {0.05f, 0.4f};
  if (scene == "bowl" || scene == "cylinder") return {0.05f, 0.1f};
  if (scene == "panel") return {0.05f, 0.15f};
  return {};
}

}  // namespace nmbake::scenes
