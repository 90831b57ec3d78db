// Scene generators. The cube sphere is the gnomonic cube-to-sphere map
// d = normalize(s, t, 1) of Wittens, "Making Worlds 1/3" (acko.net, 2009), and
// the moon follows "Making Worlds 3 - That's no Moon": crater brushes whose
// radial coordinate is distorted with fractal noise (noise.hpp), on top of a
// low fBm terrain. Crater sizes follow the cumulative power law N(>R) ~ R^-2
// of small lunar craters (Neukum et al., "Cratering records in the inner solar
// system", 2001, simplified to one exponent).
//
// Analytic functions are evaluated in double and rounded to float once, so
// the meshes are bitwise reproducible and the analytic normals are accurate.
#include "scenes.hpp"

#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <glm/geometric.hpp>
#include <numbers>
#include <string>
#include <unordered_map>
#include <vector>

#include "noise.hpp"

namespace nmbake::scenes {

namespace {

constexpr double kTwoPi = 2.0 * std::numbers::pi;

// Grid of (cells + 1)^2 vertices, two counter-clockwise (seen from +z)
// triangles per cell; vertex (i, j) has index j * (cells + 1) + i.
void append_grid_indices(int cells, std::vector<std::uint32_t>& indices) {
  const std::uint32_t row = static_cast<std::uint32_t>(cells) + 1;
  indices.reserve(static_cast<std::size_t>(cells) * cells * 6);
  for (std::uint32_t j = 0; j < static_cast<std::uint32_t>(cells); ++j) {
    for (std::uint32_t i = 0; i < static_cast<std::uint32_t>(cells); ++i) {
      const std::uint32_t a = j * row + i, b = a + 1, c = a + row + 1, d = a + row;
      indices.insert(indices.end(), {a, b, c, a, c, d});
    }
  }
}

// Grid coordinate i of `cells` mapped to [0, size]; exact at both ends.
double grid_coordinate(int i, int cells, double size) {
  return i == cells ? size : size * static_cast<double>(i) / static_cast<double>(cells);
}

}  // namespace

// --- Heightfield ------------------------------------------------------------

namespace {

// Gaussian bumps in unit coordinates: centre, standard deviation, height.
struct Bump {
  double cx, cy, sigma, height;
};
// The narrowest bump sets the steepest slope: 1.1 * 0.02 / 0.035 * e^-1/2
// ~ 0.38 (21 degrees) at the default amplitude.
constexpr std::array<Bump, 5> kBumps = {{
    {0.28, 0.32, 0.090, 1.0},
    {0.68, 0.28, 0.045, -0.9},
    {0.55, 0.70, 0.070, 0.8},
    {0.22, 0.76, 0.035, 1.1},
    {0.82, 0.74, 0.050, -0.6},
}};
constexpr double kWaveHeight = 0.2;

struct HeightSample {
  double h, dh_dx, dh_dy;
};

HeightSample evaluate_heightfield(const HeightfieldParams& p, double x, double y) {
  NMBAKE_CHECK(p.size > 0.0f, "heightfield size must be positive");
  const double inv_size = 1.0 / static_cast<double>(p.size);
  const double ux = x * inv_size, uy = y * inv_size;
  double f = 0.0, fx = 0.0, fy = 0.0;
  for (const Bump& b : kBumps) {
    const double dx = ux - b.cx, dy = uy - b.cy;
    const double inv_var = 1.0 / (b.sigma * b.sigma);
    const double g = b.height * std::exp(-0.5 * (dx * dx + dy * dy) * inv_var);
    f += g;
    fx -= g * dx * inv_var;
    fy -= g * dy * inv_var;
  }
  // A low-frequency wave so that no region is exactly flat.
  const double ax = kTwoPi * (2.0 * ux + 0.1), ay = kTwoPi * (1.5 * uy + 0.2);
  f += kWaveHeight * std::sin(ax) * std::sin(ay);
  fx += kWaveHeight * kTwoPi * 2.0 * std::cos(ax) * std::sin(ay);
  fy += kWaveHeight * kTwoPi * 1.5 * std::sin(ax) * std::cos(ay);
  const double a = static_cast<double>(p.amplitude);
  return {a * f, a * fx * inv_size, a * fy * inv_size};
}

glm::vec3 heightfield_normal_d(const HeightfieldParams& p, double x, double y) {
  const HeightSample s = evaluate_heightfield(p, x, y);
  // Length >= 1, so the normalisation is always defined.
  const glm::dvec3 n = glm::normalize(glm::dvec3(-s.dh_dx, -s.dh_dy, 1.0));
  return glm::vec3(n);
}

}  // namespace

float heightfield_height(const HeightfieldParams& p, float x, float y) {
  return static_cast<float>(evaluate_heightfield(p, x, y).h);
}

glm::vec3 heightfield_normal(const HeightfieldParams& p, float x, float y) {
  return heightfield_normal_d(p, x, y);
}

ScenePair make_heightfield(const HeightfieldParams& p) {
  NMBAKE_CHECK(p.low_cells >= 1 && p.low_cells <= 8192, "heightfield low_cells out of range");
  NMBAKE_CHECK(p.high_cells >= 1 && p.high_cells <= 8192, "heightfield high_cells out of range");
  NMBAKE_CHECK(p.size > 0.0f, "heightfield size must be positive");
  const double size = p.size;
  ScenePair pair;

  Mesh& low = pair.low;
  const std::size_t low_row = static_cast<std::size_t>(p.low_cells) + 1;
  low.positions.reserve(low_row * low_row);
  for (int j = 0; j <= p.low_cells; ++j) {
    for (int i = 0; i <= p.low_cells; ++i) {
      const double x = grid_coordinate(i, p.low_cells, size), y = grid_coordinate(j, p.low_cells, size);
      low.positions.emplace_back(static_cast<float>(x), static_cast<float>(y), 0.0f);
      low.uvs.emplace_back(static_cast<float>(static_cast<double>(i) / p.low_cells),
                           static_cast<float>(static_cast<double>(j) / p.low_cells));
    }
  }
  low.normals.assign(low.positions.size(), glm::vec3(0.0f, 0.0f, 1.0f));
  append_grid_indices(p.low_cells, low.indices);

  Mesh& high = pair.high;
  const std::size_t high_row = static_cast<std::size_t>(p.high_cells) + 1;
  high.positions.resize(high_row * high_row);
  high.normals.resize(high_row * high_row);
  tbb::parallel_for(tbb::blocked_range<int>(0, p.high_cells + 1), [&](const tbb::blocked_range<int>& rows) {
    for (int j = rows.begin(); j < rows.end(); ++j) {
      for (int i = 0; i <= p.high_cells; ++i) {
        // The height is evaluated at the float vertex position, so the stored
        // normal is the analytic normal of exactly that point.
        const float x = static_cast<float>(grid_coordinate(i, p.high_cells, size));
        const float y = static_cast<float>(grid_coordinate(j, p.high_cells, size));
        const std::size_t k = static_cast<std::size_t>(j) * high_row + static_cast<std::size_t>(i);
        high.positions[k] = glm::vec3(x, y, heightfield_height(p, x, y));
        high.normals[k] = heightfield_normal(p, x, y);
      }
    }
  });
  append_grid_indices(p.high_cells, high.indices);
  return pair;
}

// --- Many parts -----------------------------------------------------------

ScenePair make_parts(const PartsParams& p) {
  NMBAKE_CHECK(p.count >= 1 && p.count <= 10000, "parts count out of range");
  const int side = static_cast<int>(std::ceil(std::sqrt(static_cast<double>(p.count))));
  HeightfieldParams plate;
  plate.size = 1.0f;
  plate.low_cells = p.low_cells;
  plate.high_cells =
      std::max(1, static_cast<int>(std::sqrt(static_cast<double>(p.high_triangles) / (2.0 * p.count))));
  const ScenePair one = make_heightfield(plate);
  ScenePair pair;
  const float cell = 1.0f / static_cast<float>(side);
  const float margin = 0.04f * cell;
  for (int i = 0; i < p.count; ++i) {
    const int cx = i % side, cy = i / side;
    const glm::vec3 offset(static_cast<float>(cx) * (1.0f + p.gap), static_cast<float>(cy) * (1.0f + p.gap),
                           0.0f);
    const auto append = [&](const Mesh& from, Mesh& to, const std::string& name, bool uvs) {
      const auto base = static_cast<std::uint32_t>(to.positions.size());
      to.parts.push_back({name, static_cast<std::uint32_t>(to.triangle_count()),
                          static_cast<std::uint32_t>(from.triangle_count())});
      for (const glm::vec3& v : from.positions) to.positions.push_back(v + offset);
      to.normals.insert(to.normals.end(), from.normals.begin(), from.normals.end());
      if (uvs) {
        for (const glm::vec2& uv : from.uvs) {
          to.uvs.emplace_back(static_cast<float>(cx) * cell + margin + uv.x * (cell - 2.0f * margin),
                              static_cast<float>(cy) * cell + margin + uv.y * (cell - 2.0f * margin));
        }
      }
      for (const std::uint32_t index : from.indices) to.indices.push_back(base + index);
    };
    // Appended piecewise: GCC 12 warns falsely (-Wrestrict) on "p" + string.
    std::string name(1, 'p');
    name.append(std::to_string(i));
    append(one.low, pair.low, name + "_low", true);
    append(one.high, pair.high, name + "_high", false);
  }
  return pair;
}

// --- Displaced sphere ---------------------------------------------------------

namespace {

// Smooth lobes a * exp(kappa * (d.c - 1)) (von Mises-Fisher shaped): their
// slope peaks at about a * sqrt(kappa) * e^-1/2.
struct Lobe {
  glm::dvec3 direction;  // not normalised here; normalised on use
  double kappa, height;
};
constexpr std::array<Lobe, 6> kLobes = {{
    {{1.0, 0.6, 0.3}, 12.0, 1.0},
    {{-0.4, 1.0, -0.5}, 25.0, -0.8},
    {{0.2, -0.7, 1.0}, 8.0, 0.6},
    {{-1.0, -0.3, -0.8}, 18.0, 0.9},
    {{0.7, -0.2, -1.0}, 30.0, -0.6},
    {{-0.5, -1.0, 0.4}, 15.0, 0.7},
}};
constexpr double kQuadraticHeight = 0.15;

// Unit direction of any vector; the zero vector and non-finite input get +z.
glm::dvec3 unit_direction_of(const glm::vec3& v) {
  const glm::dvec3 d(v);
  const double length = std::sqrt(glm::dot(d, d));
  if (!(length > 0.0) || !std::isfinite(length)) return {0.0, 0.0, 1.0};
  return d / length;
}

// f(d) and its gradient in R^3 (not yet projected onto the tangent plane).
double sphere_function(const glm::dvec3& d, glm::dvec3* gradient) {
  double f = 0.0;
  glm::dvec3 g(0.0);
  for (const Lobe& lobe : kLobes) {
    const glm::dvec3 c = glm::normalize(lobe.direction);
    const double value = lobe.height * std::exp(lobe.kappa * (glm::dot(d, c) - 1.0));
    f += value;
    g += value * lobe.kappa * c;
  }
  f += kQuadraticHeight * (d.x * d.y + d.y * d.z - d.z * d.x);
  g += kQuadraticHeight * glm::dvec3(d.y - d.z, d.x + d.z, d.y - d.x);
  if (gradient) *gradient = g;
  return f;
}

// 1 + amplitude * f, kept positive: an absurd amplitude gives a squashed
// sphere, never a radius <= 0.
double sphere_scale(const SphereParams& p, double f) {
  return std::max(1.0 + static_cast<double>(p.amplitude) * f, 1e-6);
}

}  // namespace

float sphere_radius(const SphereParams& p, const glm::vec3& unit_direction) {
  const glm::dvec3 d = unit_direction_of(unit_direction);
  return static_cast<float>(static_cast<double>(p.radius) * sphere_scale(p, sphere_function(d, nullptr)));
}

glm::vec3 sphere_normal(const SphereParams& p, const glm::vec3& unit_direction) {
  const glm::dvec3 d = unit_direction_of(unit_direction);
  glm::dvec3 g;
  const double f = sphere_function(d, &g);
  // grad_s r / r = amplitude * (g - (g.d) d) / (1 + amplitude f); the radius
  // itself cancels.
  const glm::dvec3 tangential = g - glm::dot(g, d) * d;
  const glm::dvec3 n = d - static_cast<double>(p.amplitude) * tangential / sphere_scale(p, f);
  // |n| >= |d| = 1 because the subtracted part is orthogonal to d.
  return glm::vec3(glm::normalize(n));
}

// --- Cube sphere --------------------------------------------------------------

namespace {

// Face frames: cube point = s * u + t * v + n with cross(u, v) = n.
struct FaceFrame {
  glm::ivec3 u, v, n;
};
constexpr std::array<FaceFrame, 6> kFaces = {{
    {{0, 0, -1}, {0, 1, 0}, {1, 0, 0}},   // +X
    {{0, 0, 1}, {0, 1, 0}, {-1, 0, 0}},   // -X
    {{1, 0, 0}, {0, 0, -1}, {0, 1, 0}},   // +Y
    {{1, 0, 0}, {0, 0, 1}, {0, -1, 0}},   // -Y
    {{1, 0, 0}, {0, 1, 0}, {0, 0, 1}},    // +Z
    {{-1, 0, 0}, {0, 1, 0}, {0, 0, -1}},  // -Z
}};

// Integer cube point of grid vertex (i, j) of face f: coordinates in
// [-cells, cells], the same integers for a vertex on a shared edge.
glm::ivec3 lattice_point(int face, int i, int j, int cells) {
  const FaceFrame& frame = kFaces[static_cast<std::size_t>(face)];
  return frame.u * (2 * i - cells) + frame.v * (2 * j - cells) + frame.n * cells;
}

glm::vec3 lattice_direction(const glm::ivec3& q) {
  const glm::dvec3 p(q);
  return glm::vec3(p / std::sqrt(glm::dot(p, p)));
}

std::uint64_t lattice_key(const glm::ivec3& q) {
  // Coordinates fit in 21 bits each (|q| <= 8192).
  const auto part = [](int c) { return static_cast<std::uint64_t>(c + (1 << 20)) & 0x1fffffu; };
  return part(q.x) | (part(q.y) << 21) | (part(q.z) << 42);
}

// Topology and per-vertex cube points of a cube sphere; positions filled later.
struct CubeSphereLayout {
  std::vector<glm::ivec3> lattice;  // per vertex
  Mesh mesh;                        // indices and (optionally) uvs
};

CubeSphereLayout cube_sphere_layout(int cells, bool with_uvs, float uv_gutter) {
  NMBAKE_CHECK(cells >= 1 && cells <= 8192, "cube sphere cells_per_face out of range");
  NMBAKE_CHECK(uv_gutter >= 0.0f && uv_gutter < 1.0f / 6.0f, "cube sphere uv_gutter out of range");
  const std::size_t row = static_cast<std::size_t>(cells) + 1;
  CubeSphereLayout layout;
  std::vector<std::uint32_t> face_vertex(row * row);             // grid (i, j) -> vertex, per face
  std::unordered_map<std::uint64_t, std::uint32_t> seam_vertex;  // only without UVs
  layout.lattice.reserve(6 * row * row);
  if (with_uvs) layout.mesh.uvs.reserve(6 * row * row);
  layout.mesh.indices.reserve(static_cast<std::size_t>(cells) * cells * 36);

  const double chart_width = 1.0 / 3.0 - 2.0 * uv_gutter;
  const double chart_height = 0.5 - 2.0 * uv_gutter;
  for (int face = 0; face < 6; ++face) {
    const double u0 = (face % 3) / 3.0 + uv_gutter;
    const double v0 = (face / 3) / 2.0 + uv_gutter;
    for (int j = 0; j <= cells; ++j) {
      for (int i = 0; i <= cells; ++i) {
        const glm::ivec3 q = lattice_point(face, i, j, cells);
        const bool on_seam = i == 0 || j == 0 || i == cells || j == cells;
        std::uint32_t vertex = static_cast<std::uint32_t>(layout.lattice.size());
        if (!with_uvs && on_seam) {
          // First face to reach a seam point owns it: the numbering only
          // depends on the face order, not on the hash map.
          const auto [it, inserted] = seam_vertex.try_emplace(lattice_key(q), vertex);
          vertex = it->second;
          if (!inserted) {
            face_vertex[static_cast<std::size_t>(j) * row + static_cast<std::size_t>(i)] = vertex;
            continue;
          }
        }
        face_vertex[static_cast<std::size_t>(j) * row + static_cast<std::size_t>(i)] = vertex;
        layout.lattice.push_back(q);
        if (with_uvs) {
          const double s = static_cast<double>(i) / cells, t = static_cast<double>(j) / cells;
          layout.mesh.uvs.emplace_back(static_cast<float>(u0 + s * chart_width),
                                       static_cast<float>(v0 + t * chart_height));
        }
      }
    }
    for (std::size_t j = 0; j < static_cast<std::size_t>(cells); ++j) {
      for (std::size_t i = 0; i < static_cast<std::size_t>(cells); ++i) {
        const std::uint32_t a = face_vertex[j * row + i], b = face_vertex[j * row + i + 1];
        const std::uint32_t c = face_vertex[(j + 1) * row + i + 1], d = face_vertex[(j + 1) * row + i];
        layout.mesh.indices.insert(layout.mesh.indices.end(), {a, b, c, a, c, d});
      }
    }
  }
  return layout;
}

// Fills positions = d * radius(d) and normals = normal(d) for every vertex,
// in parallel; each vertex depends only on its own lattice point.
template <typename RadiusFn, typename NormalFn>
Mesh finish_cube_sphere(CubeSphereLayout&& layout, const RadiusFn& radius_of, const NormalFn& normal_of) {
  Mesh mesh = std::move(layout.mesh);
  const std::vector<glm::ivec3>& lattice = layout.lattice;
  mesh.positions.resize(lattice.size());
  mesh.normals.resize(lattice.size());
  tbb::parallel_for(tbb::blocked_range<std::size_t>(0, lattice.size(), 1024),
                    [&](const tbb::blocked_range<std::size_t>& range) {
                      for (std::size_t k = range.begin(); k < range.end(); ++k) {
                        const glm::vec3 d = lattice_direction(lattice[k]);
                        mesh.positions[k] = d * radius_of(d);
                        mesh.normals[k] = normal_of(d);
                      }
                    });
  return mesh;
}

glm::vec3 direction_as_normal(const glm::vec3& d) { return d; }

}  // namespace

Mesh make_cube_sphere(int cells_per_face, const std::function<float(const glm::vec3&)>& radius_of_direction,
                      bool with_uvs, float uv_gutter) {
  return finish_cube_sphere(cube_sphere_layout(cells_per_face, with_uvs, uv_gutter), radius_of_direction,
                            direction_as_normal);
}

ScenePair make_displaced_sphere(const SphereParams& p) {
  NMBAKE_CHECK(p.radius > 0.0f, "sphere radius must be positive");
  ScenePair pair;
  const float radius = p.radius;
  pair.low = make_cube_sphere(
      p.low_cells, [radius](const glm::vec3&) { return radius; }, true, sphere_uv_gutter);
  pair.high = finish_cube_sphere(
      cube_sphere_layout(p.high_cells, false, 0.0f), [&p](const glm::vec3& d) { return sphere_radius(p, d); },
      [&p](const glm::vec3& d) { return sphere_normal(p, d); });
  return pair;
}

// --- Moon -------------------------------------------------------------------

namespace {

// Crater shape, in units of the crater radius x (distance / crater radius):
// a parabolic bowl from -depth at the centre up to the rim height at x = 1,
// then ejecta falling off as (1 - t)^2 to zero at x = kEjectaReach.
constexpr double kEjectaReach = 2.2;
constexpr double kRimFraction = 0.3;        // rim height / bowl depth
constexpr double kDistortion = 0.3;         // |x' / x - 1| <= this
constexpr double kMinCraterRadius = 0.015;  // angular, radians
constexpr double kMaxCraterRadius = 0.30;
constexpr double kDepthScale = 0.045;     // depth = scale * radius^0.7 (relative to the moon radius)
constexpr double kTerrainHeight = 0.004;  // fBm terrain, relative
constexpr double kBandWidth = 0.05;       // latitude band of the crater lookup, radians

struct Crater {
  glm::dvec3 centre;
  double radius;      // angular
  double depth, rim;  // relative to the moon radius
  glm::dvec3 noise_offset;
  double reach;      // angular distance beyond which the crater adds exactly 0
  double cos_reach;  // cos(reach), lowered a little: a conservative early-out
  std::uint32_t noise_seed;
};

double crater_profile(double x, double depth, double rim) {
  if (x < 1.0) return -depth + (depth + rim) * x * x;
  if (x >= kEjectaReach) return 0.0;
  const double t = (x - 1.0) / (kEjectaReach - 1.0);
  return rim * (1.0 - t) * (1.0 - t);
}

double latitude(const glm::dvec3& d) { return std::asin(std::clamp(d.z, -1.0, 1.0)); }

int band_of(double lat, int band_count) {
  const int b = static_cast<int>(std::floor((lat + 0.5 * std::numbers::pi) / kBandWidth));
  return std::clamp(b, 0, band_count - 1);
}

}  // namespace

struct MoonSurface::Impl {
  MoonParams params;
  std::vector<Crater> craters;
  // Craters that may touch each latitude band, in crater order, so the sum
  // over craters has the same order (and bits) whatever band finds them.
  std::vector<std::vector<std::uint32_t>> bands;
  std::uint32_t terrain_seed = 0;
};

MoonSurface::MoonSurface(const MoonParams& p) : impl_(std::make_unique<Impl>()) {
  NMBAKE_CHECK(p.radius > 0.0f, "moon radius must be positive");
  NMBAKE_CHECK(p.crater_count >= 0, "moon crater_count must not be negative");
  Impl& m = *impl_;
  m.params = p;
  m.terrain_seed = noise::hash(p.seed, 0x7465727au);
  const int band_count = static_cast<int>(std::ceil(std::numbers::pi / kBandWidth));
  m.bands.resize(static_cast<std::size_t>(band_count));
  m.craters.reserve(static_cast<std::size_t>(p.crater_count));
  const double size_ratio = (kMinCraterRadius / kMaxCraterRadius) * (kMinCraterRadius / kMaxCraterRadius);
  for (int index = 0; index < p.crater_count; ++index) {
    const auto sample = [&](std::uint32_t k) {
      return noise::unit_from_hash(noise::hash(p.seed, static_cast<std::uint32_t>(index), k));
    };
    Crater c;
    // Uniform on the sphere: z uniform in [-1, 1], longitude uniform.
    const double z = 2.0 * sample(0) - 1.0;
    const double longitude = kTwoPi * sample(1);
    const double ring = std::sqrt(std::max(0.0, 1.0 - z * z));
    c.centre = glm::dvec3(ring * std::cos(longitude), ring * std::sin(longitude), z);
    // Inverse of the cumulative power law N(>R) ~ R^-2 between the bounds.
    c.radius = kMinCraterRadius / std::sqrt(1.0 - sample(2) * (1.0 - size_ratio));
    c.depth = kDepthScale * std::pow(c.radius, 0.7) * (0.8 + 0.4 * sample(3));
    c.rim = kRimFraction * c.depth;
    c.noise_offset = glm::dvec3(sample(4), sample(5), sample(6)) * 1000.0;
    c.noise_seed = noise::hash(p.seed, static_cast<std::uint32_t>(index), 0x63726174u);
    // x' >= x (1 - kDistortion), so x' >= kEjectaReach beyond this distance;
    // the margin covers rounding in the band test.
    c.reach = kEjectaReach * c.radius / (1.0 - kDistortion) + 1e-6;
    c.cos_reach = std::cos(std::min(c.reach + 1e-4, std::numbers::pi));

    const double lat = latitude(c.centre);
    const int first = band_of(lat - c.reach, band_count), last = band_of(lat + c.reach, band_count);
    // Near a pole the cap covers every longitude; the band test is on
    // latitude only, so that needs no special case.
    for (int b = first; b <= last; ++b)
      m.bands[static_cast<std::size_t>(b)].push_back(static_cast<std::uint32_t>(index));
    m.craters.push_back(c);
  }
}

MoonSurface::~MoonSurface() = default;

double MoonSurface::relative_height(const glm::dvec3& d) const {
  const Impl& m = *impl_;
  noise::FbmParams terrain_fbm;
  terrain_fbm.octave_count = 6;
  double height = kTerrainHeight * noise::fbm(m.terrain_seed, d * 1.5 + 17.0, terrain_fbm);

  noise::FbmParams crater_fbm;
  crater_fbm.octave_count = 3;
  const int band_count = static_cast<int>(m.bands.size());
  for (const std::uint32_t index : m.bands[static_cast<std::size_t>(band_of(latitude(d), band_count))]) {
    const Crater& c = m.craters[index];
    // Cheap rejection first; the exact test below decides (so this only saves time).
    if (glm::dot(d, c.centre) < c.cos_reach) continue;
    // Angular distance via the chord: well conditioned near 0, unlike acos.
    const double chord = glm::length(d - c.centre);
    const double angle = 2.0 * std::asin(std::min(1.0, 0.5 * chord));
    if (angle >= c.reach) continue;
    // The distortion field scales with the crater, so small and large craters
    // get the same amount of rim roughness per crater radius.
    const double warp = noise::fbm(c.noise_seed, d * (2.5 / c.radius) + c.noise_offset, crater_fbm);
    const double x = angle / c.radius * (1.0 + kDistortion * warp);
    height += crater_profile(x, c.depth, c.rim);
  }
  const double limit = moon_relief_limit;
  return limit * std::tanh(height / limit);
}

float MoonSurface::radius(const glm::vec3& direction) const {
  const glm::dvec3 d = unit_direction_of(direction);
  return static_cast<float>(static_cast<double>(impl_->params.radius) * (1.0 + relative_height(d)));
}

ScenePair make_moon(const MoonParams& p) {
  const MoonSurface surface(p);
  ScenePair pair;
  const float radius = p.radius;
  pair.low = make_cube_sphere(
      p.low_cells, [radius](const glm::vec3&) { return radius; }, true, sphere_uv_gutter);
  pair.high = make_cube_sphere(
      p.high_cells, [&surface](const glm::vec3& d) { return surface.radius(d); }, false, 0.0f);
  // The normals of the crater field have no closed form: area-weighted
  // normals of the (welded, closed) high mesh.
  pair.high.normals.clear();
  MeshStats stats;
  compute_vertex_normals(pair.high, stats);
  return pair;
}

}  // namespace nmbake::scenes
