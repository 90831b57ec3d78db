// The map set's analytic scenes and answers (map_lab.hpp).
#include "map_lab.hpp"

#include <tbb/parallel_for.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <glm/geometric.hpp>
#include <numbers>

#include "eval.hpp"
#include "lab_scenes.hpp"
#include "nmbake/raster.hpp"
#include "nmbake/surface.hpp"

namespace nmbake::scenes {

namespace {

constexpr double kPi = std::numbers::pi;

// The parallelogram origin + s du + t dv, s, t in [0, 1], facing du x dv,
// in nu x nv cells, appended to `mesh`; with UVs (s, t) when `uvs`.
void append_plane(Mesh& mesh, glm::dvec3 origin, glm::dvec3 du, glm::dvec3 dv, int nu, int nv, bool uvs) {
  const std::uint32_t first = static_cast<std::uint32_t>(mesh.positions.size());
  const glm::vec3 normal = glm::vec3(glm::normalize(glm::cross(du, dv)));
  for (int j = 0; j <= nv; ++j) {
    for (int i = 0; i <= nu; ++i) {
      const double s = static_cast<double>(i) / nu, t = static_cast<double>(j) / nv;
      mesh.positions.emplace_back(glm::vec3(origin + s * du + t * dv));
      mesh.normals.push_back(normal);
      if (uvs) mesh.uvs.emplace_back(static_cast<float>(s), static_cast<float>(t));
    }
  }
  for (int j = 0; j < nv; ++j) {
    for (int i = 0; i < nu; ++i) {
      const std::uint32_t a = first + static_cast<std::uint32_t>(j * (nu + 1) + i);
      const std::uint32_t b = a + 1, d = a + static_cast<std::uint32_t>(nu + 1), c = d + 1;
      mesh.indices.insert(mesh.indices.end(), {a, b, c, a, c, d});
    }
  }
}

// Shirley and Chiu's concentric map of the square [-1, 1]^2 onto the unit
// disk ("A Low Distortion Map Between Disk and Square", JGT 1997).
glm::dvec2 concentric_disk(double a, double b) {
  if (a == 0.0 && b == 0.0) return glm::dvec2(0.0);
  double r, phi;
  if (std::fabs(a) > std::fabs(b)) {
    r = a;
    phi = (kPi / 4.0) * (b / a);
  } else {
    r = b;
    phi = kPi / 2.0 - (kPi / 4.0) * (a / b);
  }
  return glm::dvec2(r * std::cos(phi), r * std::sin(phi));
}

// The lower hemisphere of the unit sphere over an n x n grid of the square:
// disk radius rho -> polar angle rho * pi / 2 from the bottom; normals towards
// the centre; counter-clockwise seen from the centre.
Mesh bowl_mesh(int n, bool uvs) {
  Mesh m;
  for (int j = 0; j <= n; ++j) {
    for (int i = 0; i <= n; ++i) {
      const double a = -1.0 + 2.0 * i / n, b = -1.0 + 2.0 * j / n;
      const glm::dvec2 d = concentric_disk(a, b);
      const double rho = std::min(1.0, glm::length(d));
      const double theta = rho * kPi / 2.0;
      const double phi = rho > 0.0 ? std::atan2(d.y, d.x) : 0.0;
      const glm::dvec3 p(std::sin(theta) * std::cos(phi), std::sin(theta) * std::sin(phi), -std::cos(theta));
      m.positions.emplace_back(glm::vec3(p));
      m.normals.emplace_back(glm::vec3(-p));
      if (uvs) m.uvs.emplace_back(static_cast<float>(i) / n, static_cast<float>(j) / n);
    }
  }
  for (int j = 0; j < n; ++j) {
    for (int i = 0; i < n; ++i) {
      const auto a = static_cast<std::uint32_t>(j * (n + 1) + i);
      const std::uint32_t b = a + 1, d = a + static_cast<std::uint32_t>(n + 1), c = d + 1;
      m.indices.insert(m.indices.end(), {a, b, c, a, c, d});
    }
  }
  return m;
}

// A plain sphere and a plain torus as analytic surfaces (eval.hpp), for the
// truth along the bake's rays.
class PlainSphere final : public TrueSurface {
 public:
  double field(int, const glm::dvec3& x) const override { return glm::length(x) - 1.0; }
  glm::dvec3 normal(int, const glm::dvec3& x) const override { return glm::normalize(x); }
  double step() const override { return 0.01; }
};

class PlainTorus final : public TrueSurface {
 public:
  PlainTorus(double major, double minor) : major_(major), minor_(minor) {}
  glm::dvec3 tube(const glm::dvec3& x) const {
    const double rho = std::hypot(x.x, x.y);
    const glm::dvec3 centre =
        rho > 0.0 ? glm::dvec3(x.x, x.y, 0.0) * (major_ / rho) : glm::dvec3(major_, 0.0, 0.0);
    return x - centre;
  }
  double field(int, const glm::dvec3& x) const override { return glm::length(tube(x)) - minor_; }
  glm::dvec3 normal(int, const glm::dvec3& x) const override { return glm::normalize(tube(x)); }
  double step() const override { return 0.01; }

 private:
  double major_, minor_;
};

// f(sample's low point, sample's ray) averaged per texel over the bake's
// samples; NaN where a sample's f is NaN.
ExpectedMap expected_per_sample(const Mesh& low, int width, int height, int samples, const RayOptions& rays,
                                const std::function<double(const glm::dvec3&, const Ray&)>& f) {
  SurfaceStats stats;
  const LowSurface surface = build_low_surface(low, nullptr, stats);
  TexelSamples ts;
  RasterStats rs;
  rasterize(surface, width, height, samples, ts, rs);
  ExpectedMap e;
  e.width = width;
  e.height = height;
  e.value.assign(static_cast<std::size_t>(width) * height, std::nan(""));
  tbb::parallel_for(0, height, [&](int y) {
    for (int x = 0; x < width; ++x) {
      const std::size_t texel = static_cast<std::size_t>(y) * width + x;
      if (!ts.coverage[texel]) continue;
      double sum = 0.0;
      int used = 0;
      for (int k = 0; k < samples; ++k) {
        const std::size_t s = texel * samples + static_cast<std::size_t>(k);
        const std::int32_t tri = ts.triangle[s];
        if (tri < 0) continue;
        const std::size_t base = 3 * static_cast<std::size_t>(tri);
        const glm::vec2 b = ts.bary[s];
        const glm::dvec3 p = glm::dvec3(surface.position[base]) * double(1.0f - b.x - b.y) +
                             glm::dvec3(surface.position[base + 1]) * double(b.x) +
                             glm::dvec3(surface.position[base + 2]) * double(b.y);
        bool fallback = false;
        const Ray ray = make_ray(surface, tri, b, rays, fallback);
        sum += f(p, ray);
        ++used;
      }
      if (used > 0) e.value[texel] = sum / used;
    }
  });
  return e;
}

// The analytic surface's crossing along the bake's ray (eval.hpp's rule:
// front-facing, nearest the low surface); false if none.
bool true_hit(const TrueSurface& surface, const Ray& ray, glm::dvec3& hit, double& t) {
  glm::dvec3 normal;
  const glm::dvec3 o(ray.origin), d(ray.direction);
  if (!intersect_true_surface(surface, o, d, ray.tfar, ray.t_surface, hit, normal)) return false;
  t = glm::dot(hit - o, d);
  return true;
}

}  // namespace

ScenePair make_wall_scene() {
  ScenePair s;
  append_plane(s.low, {0, 0, 0}, {1, 0, 0}, {0, 1, 0}, 4, 4, true);
  // High: the floor under the texels, and the wall x = 0 facing +x.
  append_plane(s.high, {0, -0.1, 0}, {1.1, 0, 0}, {0, 1.2, 0}, 8, 8, false);
  const double reach = 1.25 * kWallDistance;
  append_plane(s.high, {0, -reach, 0}, {0, 1.0 + 2.0 * reach, 0}, {0, 0, reach}, 8, 4, false);
  return s;
}

ScenePair make_bowl_scene(int low_cells, int high_cells) {
  ScenePair s;
  s.low = bowl_mesh(low_cells, true);
  s.high = bowl_mesh(high_cells, false);
  return s;
}

ScenePair make_groove_scene() {
  ScenePair s;
  append_plane(s.low, {0, 0, 0}, {1, 0, 0}, {0, 1, 0}, 4, 4, true);
  append_plane(s.high, {0, -0.1, 0}, {1, 0, 0}, {0, 1.2, 0}, 8, 8, false);
  const double half = 30.0;
  append_plane(s.high, {0, 0.5 - half, 0}, {0, 2.0 * half, 0}, {0, 0, 1}, 64, 4, false);   // x = 0, facing +x
  append_plane(s.high, {1, 0.5 + half, 0}, {0, -2.0 * half, 0}, {0, 0, 1}, 64, 4, false);  // x = 1, facing -x
  return s;
}

ScenePair make_slab_scene() {
  ScenePair s;
  append_plane(s.low, {0, 0, 0}, {1, 0, 0}, {0, 1, 0}, 4, 4, true);
  const double t = kSlabThickness;
  append_plane(s.high, {0, 0, 0}, {1, 0, 0}, {0, 1, 0}, 8, 8, false);    // top, +z
  append_plane(s.high, {0, 1, -t}, {1, 0, 0}, {0, -1, 0}, 8, 8, false);  // bottom, -z
  append_plane(s.high, {0, 0, -t}, {1, 0, 0}, {0, 0, t}, 8, 1, false);   // y = 0, -y
  append_plane(s.high, {1, 1, -t}, {-1, 0, 0}, {0, 0, t}, 8, 1, false);  // y = 1, +y
  append_plane(s.high, {0, 1, -t}, {0, -1, 0}, {0, 0, t}, 8, 1, false);  // x = 0, -x
  append_plane(s.high, {1, 0, -t}, {0, 1, 0}, {0, 0, t}, 8, 1, false);   // x = 1, +x
  return s;
}

double wall_visibility(double x, double distance) {
  const double a = std::clamp(x / distance, 0.0, 1.0);
  return 1.0 - (std::acos(a) - a * std::sqrt(1.0 - a * a)) / kPi;
}

double groove_visibility(double x) {
  const double w = 1.0, h = 1.0;
  return 0.5 * ((w - x) / std::sqrt((w - x) * (w - x) + h * h) + x / std::sqrt(x * x + h * h));
}

glm::dvec3 groove_bent_normal(double x) {
  const double p1 = -std::atan(x), p2 = std::atan(1.0 - x);
  const glm::dvec3 d(0.5 * (std::sin(p2) * std::sin(p2) - std::sin(p1) * std::sin(p1)), 0.0,
                     0.5 * (p2 - p1) + 0.25 * (std::sin(2.0 * p2) - std::sin(2.0 * p1)));
  return glm::normalize(d);
}

double sphere_thickness(double radius) {
  const double c = std::cos(static_cast<double>(kThicknessConeDegrees) * kPi / 180.0);
  return 2.0 * radius * (1.0 + c + c * c) / 3.0;
}

double torus_mean_curvature(double major, double minor, const glm::dvec3& p) {
  const double rho = std::hypot(p.x, p.y) - major;
  const double cos_theta = rho / std::hypot(rho, p.z);
  return 0.5 * (1.0 / minor + cos_theta / (major + minor * cos_theta));
}

ExpectedMap expected_from_low_points(const Mesh& low, int width, int height, int samples,
                                     const std::function<double(const glm::dvec3&)>& of_point) {
  return expected_per_sample(low, width, height, samples, RayOptions{},
                             [&](const glm::dvec3& p, const Ray&) { return of_point(p); });
}

ExpectedMap expected_height(const std::string& scene, const Mesh& low, int width, int height, int samples,
                            const RayOptions& rays) {
  std::unique_ptr<TrueSurface> truth;
  if (scene == "sphere-plain") {
    truth = std::make_unique<PlainSphere>();
  } else {
    truth = make_true_surface(scene);
  }
  NMBAKE_CHECK(truth != nullptr, "a known scene");
  return expected_per_sample(low, width, height, samples, rays, [&](const glm::dvec3&, const Ray& ray) {
    glm::dvec3 hit;
    double t = 0.0;
    if (!true_hit(*truth, ray, hit, t)) return std::nan("");
    return static_cast<double>(ray.t_surface) - t;
  });
}

ExpectedMap expected_at_true_hits(const std::string& scene, const Mesh& low, int width, int height,
                                  int samples, const RayOptions& rays,
                                  const std::function<double(const glm::dvec3&)>& f) {
  const TorusParams torus;
  std::unique_ptr<TrueSurface> truth;
  if (scene == "sphere-plain") {
    truth = std::make_unique<PlainSphere>();
  } else if (scene == "torus-plain") {
    truth = std::make_unique<PlainTorus>(torus.major, torus.minor);
  } else {
    truth = make_true_surface(scene);
  }
  NMBAKE_CHECK(truth != nullptr, "a known scene");
  return expected_per_sample(low, width, height, samples, rays, [&](const glm::dvec3&, const Ray& ray) {
    glm::dvec3 hit;
    double t = 0.0;
    return true_hit(*truth, ray, hit, t) ? f(hit) : std::nan("");
  });
}

ExpectedMap expected_curvature(const std::string& scene, const Mesh& low, int width, int height, int samples,
                               const RayOptions& rays) {
  const TorusParams torus;
  std::unique_ptr<TrueSurface> truth;
  if (scene == "sphere") truth = std::make_unique<PlainSphere>();
  if (scene == "torus") truth = std::make_unique<PlainTorus>(torus.major, torus.minor);
  NMBAKE_CHECK(truth != nullptr, "sphere or torus");
  return expected_per_sample(low, width, height, samples, rays, [&](const glm::dvec3&, const Ray& ray) {
    glm::dvec3 hit;
    double t = 0.0;
    if (!true_hit(*truth, ray, hit, t)) return std::nan("");
    return scene == "sphere" ? 1.0 : torus_mean_curvature(torus.major, torus.minor, hit);
  });
}

std::string MapError::to_text() const {
  char text[256];
  std::snprintf(text, sizeof text,
                "%zu texels: mean |error| %.6f, bias %+.6f, p99 %.6f, max %.6f, non-finite %zu", texels,
                mean_abs, mean_signed, p99, max, non_finite);
  return text;
}

MapError score_map(const Image& map, int channel, const ExpectedMap& expected) {
  NMBAKE_CHECK(map.width == expected.width && map.height == expected.height, "map and answer of one size");
  MapError e;
  std::vector<double> errors;
  double sum = 0.0, signed_sum = 0.0;
  for (int y = 0; y < map.height; ++y) {
    for (int x = 0; x < map.width; ++x) {
      const double want = expected.value[static_cast<std::size_t>(y) * map.width + x];
      if (std::isnan(want)) continue;
      const double got = map.at(x, y)[channel];
      if (!std::isfinite(got)) {
        ++e.non_finite;
        continue;
      }
      errors.push_back(std::fabs(got - want));
      sum += std::fabs(got - want);
      signed_sum += got - want;
    }
  }
  e.texels = errors.size();
  if (errors.empty()) return e;
  e.mean_abs = sum / static_cast<double>(errors.size());
  e.mean_signed = signed_sum / static_cast<double>(errors.size());
  std::sort(errors.begin(), errors.end());
  e.p99 = errors[std::min(errors.size() - 1, errors.size() * 99 / 100)];
  e.max = errors.back();
  return e;
}

}  // namespace nmbake::scenes
