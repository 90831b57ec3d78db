// The lab's evaluator (eval.hpp): analytic truth along the bake's rays,
// MikkTSpace decode (Mikkelsen 2008, the per-pixel decode of mikktspace.h),
// angular error statistics.
#include "eval.hpp"

#include <tbb/parallel_for.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <fstream>
#include <glm/geometric.hpp>
#include <glm/trigonometric.hpp>
#include <nlohmann/json.hpp>

#include "hard_scenes.hpp"
#include "nmbake/raster.hpp"
#include "nmbake/surface.hpp"

namespace nmbake::scenes {

namespace {

// Every scene is defined at unit scale; `scale` stretches it (fields are
// distances, so they scale too).
class ScaledSurface : public TrueSurface {
 public:
  explicit ScaledSurface(double scale) : scale_(scale) {}
  double field(int patch, const glm::dvec3& x) const final { return scale_ * unit_field(patch, x / scale_); }
  glm::dvec3 normal(int patch, const glm::dvec3& x) const final { return unit_normal(patch, x / scale_); }
  bool in_patch(int patch, const glm::dvec3& x) const final { return unit_in_patch(patch, x / scale_); }
  double step() const final { return scale_ * unit_step(); }

 protected:
  virtual double unit_field(int patch, const glm::dvec3& x) const = 0;
  virtual glm::dvec3 unit_normal(int patch, const glm::dvec3& x) const = 0;
  virtual bool unit_in_patch(int, const glm::dvec3&) const { return true; }
  virtual double unit_step() const = 0;

 private:
  double scale_;
};

class HeightfieldTruth final : public ScaledSurface {
 public:
  using ScaledSurface::ScaledSurface;
  double unit_field(int, const glm::dvec3& x) const override {
    return x.z - heightfield_height(p_, static_cast<float>(x.x), static_cast<float>(x.y));
  }
  glm::dvec3 unit_normal(int, const glm::dvec3& x) const override {
    return glm::dvec3(heightfield_normal(p_, static_cast<float>(x.x), static_cast<float>(x.y)));
  }
  double unit_step() const override { return 0.004; }
  HeightfieldParams p_;
};

class SphereTruth final : public ScaledSurface {
 public:
  using ScaledSurface::ScaledSurface;
  double unit_field(int, const glm::dvec3& x) const override {
    const double r = glm::length(x);
    return r - sphere_radius(p_, glm::vec3(x / r));
  }
  glm::dvec3 unit_normal(int, const glm::dvec3& x) const override {
    return glm::dvec3(sphere_normal(p_, glm::vec3(glm::normalize(x))));
  }
  double unit_step() const override { return 0.01; }
  SphereParams p_;
};

class TorusTruth final : public ScaledSurface {
 public:
  using ScaledSurface::ScaledSurface;
  double unit_field(int, const glm::dvec3& x) const override { return torus_field(p_, x); }
  glm::dvec3 unit_normal(int, const glm::dvec3& x) const override { return torus_normal(p_, x); }
  double unit_step() const override { return 0.01; }
  TorusParams p_;
};

class CraterTruth final : public ScaledSurface {
 public:
  explicit CraterTruth(double scale) : ScaledSurface(scale), s_(CraterParams{}) {}
  double unit_field(int, const glm::dvec3& x) const override { return s_.field(x); }
  glm::dvec3 unit_normal(int, const glm::dvec3& x) const override { return s_.normal(x); }
  double unit_step() const override { return 0.01; }
  CraterSurface s_;
};

class BoxTruth final : public ScaledSurface {
 public:
  BoxTruth(double scale, double bevel) : ScaledSurface(scale) { p_.bevel = static_cast<float>(bevel); }
  double unit_field(int, const glm::dvec3& x) const override { return box_field(p_, x); }
  glm::dvec3 unit_normal(int, const glm::dvec3& x) const override { return box_normal(p_, x); }
  double unit_step() const override { return std::min(0.02, 0.25 * static_cast<double>(p_.bevel)); }
  BoxParams p_;
};

class RevolveTruth final : public ScaledSurface {
 public:
  RevolveTruth(double scale, const RevolveParams& p) : ScaledSurface(scale), profile_(p.profile) {}
  double unit_field(int, const glm::dvec3& x) const override { return revolve_field(profile_, x); }
  glm::dvec3 unit_normal(int, const glm::dvec3& x) const override { return revolve_normal(profile_, x); }
  double unit_step() const override { return 0.01; }
  RevolveProfile profile_;
};

class PanelTruth final : public ScaledSurface {
 public:
  explicit PanelTruth(double scale) : ScaledSurface(scale), p_(panel_params()) {}
  double unit_field(int, const glm::dvec3& x) const override { return panel_field(p_, x); }
  glm::dvec3 unit_normal(int, const glm::dvec3& x) const override { return panel_normal(p_, x); }
  double unit_step() const override { return 0.004; }  // the dimple is 0.12 across
  PanelParams p_;
};

class SlotTruth final : public ScaledSurface {
 public:
  using ScaledSurface::ScaledSurface;
  int patch_count() const override { return slot_patch_count; }
  double unit_field(int patch, const glm::dvec3& x) const override { return slot_field(p_, patch, x); }
  glm::dvec3 unit_normal(int patch, const glm::dvec3& x) const override { return slot_normal(p_, patch, x); }
  bool unit_in_patch(int patch, const glm::dvec3& x) const override { return slot_in_patch(p_, patch, x); }
  double unit_step() const override { return 0.01; }
  SlotParams p_;
};

// atan2 of |a x b| and a.b in double: acos of a float dot product cannot
// resolve angles below ~0.02 degrees, which would hide the float floor.
float angle_degrees(const glm::vec3& a, const glm::vec3& b) {
  const glm::dvec3 da(a), db(b);
  const double la = glm::length(da), lb = glm::length(db);
  if (!(la > 0.0) || !(lb > 0.0) || !std::isfinite(la) || !std::isfinite(lb)) return 180.0f;
  return static_cast<float>(glm::degrees(std::atan2(glm::length(glm::cross(da, db)), glm::dot(da, db))));
}

template <class V>
V lerp(const std::vector<V>& c, std::size_t base, glm::vec2 b) {
  return c[base] * (1.0f - b.x - b.y) + c[base + 1] * b.x + c[base + 2] * b.y;
}

// Refines an entering crossing in [a, b] (field(a) > 0 >= field(b)) by
// regula falsi with the Illinois modification (converges superlinearly,
// keeps the bracket), down to a 1e-13 relative interval.
double refine(const TrueSurface& s, int patch, const glm::dvec3& o, const glm::dvec3& d, double a, double b) {
  double fa = s.field(patch, o + a * d), fb = s.field(patch, o + b * d);
  const double tolerance = 1e-13 * std::max({1.0, std::fabs(a), std::fabs(b), s.step()});
  int side = 0;
  for (int i = 0; i < 100 && b - a > tolerance; ++i) {
    double c = fa - fb > 0.0 ? (a * (-fb) + b * fa) / (fa - fb) : 0.5 * (a + b);
    if (!(c > a && c < b)) c = 0.5 * (a + b);
    const double fc = s.field(patch, o + c * d);
    if (fc > 0.0) {
      a = c;
      fa = fc;
      if (side == -1) fb *= 0.5;
      side = -1;
    } else {
      b = c;
      fb = fc;
      if (side == 1) fa *= 0.5;
      side = 1;
    }
    if (fc == 0.0) return c;
  }
  return fa < -fb ? a : b;
}

}  // namespace

const std::vector<std::string>& lab_scene_names() {
  static const std::vector<std::string> names = [] {
    std::vector<std::string> n = {"heightfield", "sphere", "torus", "craters", "box", "slot"};
    n.insert(n.end(), hard_scene_names().begin(), hard_scene_names().end());
    return n;
  }();
  return names;
}

std::unique_ptr<TrueSurface> make_true_surface(const std::string& scene, double scale) {
  if (scene == "heightfield") return std::make_unique<HeightfieldTruth>(scale);
  if (scene == "sphere") return std::make_unique<SphereTruth>(scale);
  if (scene == "torus") return std::make_unique<TorusTruth>(scale);
  if (scene == "craters") return std::make_unique<CraterTruth>(scale);
  if (const double bevel = lab_box_bevel(scene); bevel > 0.0) return std::make_unique<BoxTruth>(scale, bevel);
  if (scene == "bowl") return std::make_unique<RevolveTruth>(scale, bowl_params());
  if (scene == "cylinder") return std::make_unique<RevolveTruth>(scale, cylinder_params());
  if (scene == "panel") return std::make_unique<PanelTruth>(scale);
  if (scene == "slot") return std::make_unique<SlotTruth>(scale);
  return nullptr;
}

bool intersect_true_surface(const TrueSurface& s, const glm::dvec3& o, const glm::dvec3& d, double t_max,
                            double t_target, glm::dvec3& hit, glm::dvec3& normal) {
  const double step = s.step();
  t_target = std::clamp(t_target, 0.0, t_max);
  double best_t = 0.0, best_distance = INFINITY;
  int best_patch = -1;
  for (int patch = 0; patch < s.patch_count(); ++patch) {
    // March outwards from t_target both ways in lockstep: the first bracket
    // found on either side (or both at the same step) holds the nearest root.
    const double f_target = s.field(patch, o + t_target * d);
    double up_t = t_target, up_f = f_target, down_t = t_target, down_f = f_target;
    const int max_steps = static_cast<int>(std::ceil(t_max / step)) + 1;
    for (int k = 0; k < max_steps; ++k) {
      bool any_left = false;
      double found = -1.0;
      if (up_t < t_max) {  // towards larger t: entering means + then <= 0
        any_left = true;
        const double t = std::min(t_max, up_t + step);
        const double f = s.field(patch, o + t * d);
        if (up_f > 0.0 && f <= 0.0) {
          const double r = refine(s, patch, o, d, up_t, t);
          if (s.in_patch(patch, o + r * d)) found = r;
        }
        up_t = t;
        up_f = f;
      }
      if (down_t > 0.0) {
        any_left = true;
        const double t = std::max(0.0, down_t - step);
        const double f = s.field(patch, o + t * d);
        if (f > 0.0 && down_f <= 0.0) {
          const double r = refine(s, patch, o, d, t, down_t);
          if (s.in_patch(patch, o + r * d) &&
              (found < 0.0 || std::fabs(r - t_target) < std::fabs(found - t_target)))
            found = r;
        }
        down_t = t;
        down_f = f;
      }
      if (found >= 0.0) {
        if (std::fabs(found - t_target) < best_distance) {
          best_distance = std::fabs(found - t_target);
          best_t = found;
          best_patch = patch;
        }
        break;
      }
      if (!any_left || static_cast<double>(k) * step > best_distance) break;
    }
  }
  if (best_patch < 0) return false;
  hit = o + best_t * d;
  normal = s.normal(best_patch, hit);
  return true;
}

Expected compute_expected(const TrueSurface& truth, const Mesh& low, const Mesh* cage, int width, int height,
                          const EvalOptions& options) {
  SurfaceStats surface_stats;
  LowSurface surface = build_low_surface(low, cage, surface_stats);  // MikkTSpace: what renderers decode with
  TexelSamples raster;
  RasterStats raster_stats;
  rasterize(surface, width, height, options.samples, raster, raster_stats);
  RayOptions rays = options.rays;
  if (cage != nullptr) rays.cage = CageMode::mesh;
  if (rays.cage == CageMode::banded) prepare_edge_band(surface, edge_band_reach(rays));

  Expected e;
  e.width = width;
  e.height = height;
  const std::size_t texels = static_cast<std::size_t>(width) * height;
  e.scored.assign(texels, 0);
  e.value.assign(texels, glm::vec3(0.0f));
  e.frame_t.assign(texels, glm::vec3(0.0f));
  e.frame_n.assign(texels, glm::vec3(0.0f));
  e.frame_sign.assign(texels, 1.0f);
  e.covered = raster_stats.covered_texels;
  const bool tangent = options.space == NormalSpace::tangent;
  const int spp = options.samples;

  tbb::parallel_for(0, height, [&](int y) {
    for (int x = 0; x < width; ++x) {
      const std::size_t texel = static_cast<std::size_t>(y) * width + x;
      if (!raster.coverage[texel]) continue;
      glm::vec3 sum(0.0f);
      bool first = true, any_truth = false;
      for (int k = 0; k < spp; ++k) {
        const std::size_t s = texel * spp + k;
        const std::int32_t tri = raster.triangle[s];
        if (tri < 0) continue;
        const glm::vec2 b = raster.bary[s];
        const std::size_t base = 3 * static_cast<std::size_t>(tri);
        const glm::vec4 tw = lerp(surface.tangent, base, b);
        const glm::vec3 N = lerp(surface.normal, base, b);
        const float sign = tw.w < 0.0f ? -1.0f : 1.0f;
        if (first) {
          e.frame_t[texel] = glm::vec3(tw);
          e.frame_n[texel] = N;
          e.frame_sign[texel] = sign;
          first = false;
        }
        bool fallback = false;
        const Ray ray = make_ray(surface, tri, b, rays, fallback);
        glm::dvec3 hit, n;
        if (!intersect_true_surface(truth, glm::dvec3(ray.origin), glm::dvec3(ray.direction), ray.tfar,
                                    ray.t_surface, hit, n)) {
          // The bake retries a miss along the same line, out and in up to
          // retry_reach from the low surface point: so does the truth.
          const double reach = rays.retry_reach;
          if (!(reach > 0.0) || !intersect_true_surface(
                                    truth, glm::dvec3(ray.surface_point) - reach * glm::dvec3(ray.direction),
                                    glm::dvec3(ray.direction), 2.0 * reach, reach, hit, n))
            continue;
        }
        any_truth = true;
        if (tangent) {
          glm::vec3 t;
          world_to_tangent(glm::vec3(n), glm::vec3(tw), N, sign, TangentEncode::inverse, t);
          sum += t;
        } else {
          sum += glm::vec3(n);
        }
      }
      const float l = glm::length(sum);
      if (!any_truth || !(l > 1e-12f) || !std::isfinite(l)) continue;
      e.value[texel] = sum / l;
      e.scored[texel] = 1;
    }
  });
  return e;
}

EvalResult evaluate(const Expected& e, const Image& map, const EvalOptions& options) {
  NMBAKE_CHECK(map.width == e.width && map.height == e.height && map.channels >= 3,
               "map size differs from the expected");
  EvalResult r;
  r.texels = static_cast<std::size_t>(e.width) * e.height;
  r.covered = e.covered;
  const bool tangent = options.space == NormalSpace::tangent;
  std::vector<std::vector<float>> rows(e.height);
  std::vector<std::size_t> row_non_finite(e.height, 0), row_without(e.height, 0);
  tbb::parallel_for(0, e.height, [&](int y) {
    for (int x = 0; x < e.width; ++x) {
      const std::size_t texel = static_cast<std::size_t>(y) * e.width + x;
      const float* p = map.at(x, y);
      for (int c = 0; c < map.channels; ++c) row_non_finite[y] += std::isfinite(p[c]) ? 0 : 1;
      if (!e.scored[texel]) continue;
      glm::vec3 v(2.0f * p[0] - 1.0f, 2.0f * p[1] - 1.0f, 2.0f * p[2] - 1.0f);
      if (tangent && options.green == GreenChannel::down) v.y = -v.y;
      if (!std::isfinite(v.x) || !std::isfinite(v.y) || !std::isfinite(v.z)) {
        rows[y].push_back(180.0f);
        continue;
      }
      if (tangent) {
        const glm::vec3 baked = tangent_to_world(v, e.frame_t[texel], e.frame_n[texel], e.frame_sign[texel]);
        const glm::vec3 want =
            tangent_to_world(e.value[texel], e.frame_t[texel], e.frame_n[texel], e.frame_sign[texel]);
        rows[y].push_back(angle_degrees(baked, want));
      } else {
        rows[y].push_back(angle_degrees(v, e.value[texel]));
      }
    }
  });
  std::vector<float> all;
  std::size_t non_finite = 0, scored = 0;
  for (int y = 0; y < e.height; ++y) {
    all.insert(all.end(), rows[y].begin(), rows[y].end());
    non_finite += row_non_finite[y];
  }
  scored = all.size();
  r.without_truth = r.covered >= scored ? r.covered - scored : 0;
  r.error = summarize_errors(std::move(all), non_finite);
  return r;
}

Image expected_image(const Expected& e, const EvalOptions& options) {
  Image out{e.width, e.height, 3, {}};
  const bool tangent = options.space == NormalSpace::tangent;
  out.pixels.resize(static_cast<std::size_t>(e.width) * e.height * 3);
  for (std::size_t t = 0; t < e.scored.size(); ++t) {
    glm::vec3 v = tangent ? glm::vec3(0.0f, 0.0f, 1.0f) : glm::vec3(0.0f);
    if (e.scored[t]) v = e.value[t];
    if (tangent && options.green == GreenChannel::down) v.y = -v.y;
    for (int c = 0; c < 3; ++c) out.pixels[3 * t + c] = 0.5f * v[c] + 0.5f;
  }
  return out;
}

namespace {
template <class T>
void put(std::ofstream& f, const std::vector<T>& v) {
  const std::uint64_t n = v.size();
  f.write(reinterpret_cast<const char*>(&n), sizeof n);
  f.write(reinterpret_cast<const char*>(v.data()), static_cast<std::streamsize>(n * sizeof(T)));
}
template <class T>
bool get(std::ifstream& f, std::vector<T>& v, std::size_t expected_size) {
  std::uint64_t n = 0;
  f.read(reinterpret_cast<char*>(&n), sizeof n);
  if (!f || n != expected_size) return false;
  v.resize(n);
  f.read(reinterpret_cast<char*>(v.data()), static_cast<std::streamsize>(n * sizeof(T)));
  return static_cast<bool>(f);
}
}  // namespace

bool save_expected(const std::string& path, const std::string& key, const Expected& e) {
  const std::string tmp = path + ".tmp";
  {
    std::ofstream f(tmp, std::ios::binary | std::ios::trunc);
    const std::uint64_t header[4] = {key.size(), static_cast<std::uint64_t>(e.width),
                                     static_cast<std::uint64_t>(e.height), e.covered};
    f.write(reinterpret_cast<const char*>(header), sizeof header);
    f.write(key.data(), static_cast<std::streamsize>(key.size()));
    put(f, e.scored);
    put(f, e.value);
    put(f, e.frame_t);
    put(f, e.frame_n);
    put(f, e.frame_sign);
    if (!f.flush()) return false;
  }
  return std::rename(tmp.c_str(), path.c_str()) == 0;
}

bool load_expected(const std::string& path, const std::string& key, Expected& e) {
  std::ifstream f(path, std::ios::binary);
  std::uint64_t header[4] = {};
  f.read(reinterpret_cast<char*>(header), sizeof header);
  if (!f || header[0] != key.size() || header[1] > 65536 || header[2] > 65536) return false;
  std::string stored(key.size(), '\0');
  f.read(stored.data(), static_cast<std::streamsize>(stored.size()));
  if (!f || stored != key) return false;
  e.width = static_cast<int>(header[1]);
  e.height = static_cast<int>(header[2]);
  e.covered = header[3];
  const std::size_t n = static_cast<std::size_t>(e.width) * e.height;
  return get(f, e.scored, n) && get(f, e.value, n) && get(f, e.frame_t, n) && get(f, e.frame_n, n) &&
         get(f, e.frame_sign, n);
}

Image quantize(const Image& image, int levels) {
  Image out = image;
  for (float& v : out.pixels) v = std::round(std::clamp(v, 0.0f, 1.0f) * levels) / static_cast<float>(levels);
  return out;
}

std::string EvalResult::to_text() const {
  char line[160];
  std::snprintf(line, sizeof line, "coverage %.4f (%zu of %zu texels), without truth %zu\n",
                texels ? static_cast<double>(covered) / texels : 0.0, covered, texels, without_truth);
  return line + error.to_text();
}

std::string EvalResult::to_json() const {
  nlohmann::ordered_json j;
  j["texels"] = texels;
  j["covered"] = covered;
  j["coverage"] = texels ? static_cast<double>(covered) / texels : 0.0;
  j["without_truth"] = without_truth;
  j["scored"] = error.texels;
  j["mean_deg"] = error.mean;
  j["median_deg"] = error.median;
  j["p95_deg"] = error.p95;
  j["p99_deg"] = error.p99;
  j["max_deg"] = error.max;
  j["share_over_1deg"] = error.over_1deg;
  j["share_over_5deg"] = error.over_5deg;
  j["nan_count"] = error.non_finite;
  return j.dump(2);
}

}  // namespace nmbake::scenes
