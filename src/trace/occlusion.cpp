// Rays from the stored hits (occlusion.hpp): ambient occlusion with bent
// normals (rtcOccluded16) and thickness (rtcIntersect16), in 16-wide packets
// of one sample's rays each (one origin, spread directions), over the same
// 16 x 16 texel tiles and texel order as trace().
//
// Papers: Wächter and Binder, "A Fast and Robust Method for Avoiding
// Self-Intersection", Ray Tracing Gems (2019), ch. 6 (the ray offset);
// Duff, Burgess, Christensen, Hery, Kensler, Liani, Villemin, "Building an
// Orthonormal Basis, Revisited", JCGT 6(1), 2017 (the frame); Hammersley
// points with a Cranley-Patterson rotation (Cranley and Patterson,
// "Randomization of Number Theoretic Methods for Multiple Integration",
// SIAM J. Numer. Anal. 13(6), 1976); Malley's method for cosine-weighted
// directions (Pharr, Jakob, Humphreys, PBRT 3rd ed., 13.6.3).
#include "nmbake/occlusion.hpp"

#include <tbb/parallel_for.h>

#include <algorithm>
#include <bit>
#include <chrono>
#include <cmath>
#include <cstring>
#include <glm/geometric.hpp>

#include "trace/scene.hpp"

namespace nmbake {

namespace {

constexpr int kTile = 16;  // texels, as trace()
constexpr int kBlock = 4;
constexpr int kPacket = 16;
constexpr float kTwoPi = 6.28318530717958647692f;

// --- The ray offset (Wächter and Binder) ------------------------------------

// `p` moved off its surface along the unit `n` by 256 units in the last place
// of each coordinate; a coordinate within 1/32 of zero, whose ulps are too
// small to matter, moves by 1/65536 of n instead.
glm::vec3 offset_origin(const glm::vec3& p, const glm::vec3& n) {
  constexpr float kNearZero = 1.0f / 32.0f;
  constexpr float kFloatScale = 1.0f / 65536.0f;
  constexpr float kIntScale = 256.0f;
  glm::vec3 out;
  for (int i = 0; i < 3; ++i) {
    const auto steps = static_cast<std::int32_t>(kIntScale * n[i]);
    const auto bits = std::bit_cast<std::int32_t>(p[i]);
    // Away from zero in the float's own direction: the integer step of a
    // negative float moves it the other way.
    const float moved = std::bit_cast<float>(bits + (p[i] < 0.0f ? -steps : steps));
    out[i] = std::fabs(p[i]) < kNearZero ? p[i] + kFloatScale * n[i] : moved;
  }
  return out;
}

// --- Directions --------------------------------------------------------------

// Van der Corput radical inverse in base 2, in [0, 1).
float radical_inverse(std::uint32_t i) {
  i = (i << 16) | (i >> 16);
  i = ((i & 0x00ff00ffu) << 8) | ((i & 0xff00ff00u) >> 8);
  i = ((i & 0x0f0f0f0fu) << 4) | ((i & 0xf0f0f0f0u) >> 4);
  i = ((i & 0x33333333u) << 2) | ((i & 0xccccccccu) >> 2);
  i = ((i & 0x55555555u) << 1) | ((i & 0xaaaaaaaau) >> 1);
  return static_cast<float>(i >> 8) * 0x1p-24f;  // 24 bits: exact in a float, below 1
}

// The pattern: Hammersley points, u = (i + 0.5) / n and the radical inverse
// of i; the angle's cosine and sine kept so a per-sample rotation is four
// multiplications.
struct Pattern {
  std::vector<float> u;
  std::vector<float> cos_v, sin_v;  // of 2 pi v
  explicit Pattern(int n) {
    for (int i = 0; i < n; ++i) {
      u.push_back((static_cast<float>(i) + 0.5f) / static_cast<float>(n));
      const float v = radical_inverse(static_cast<std::uint32_t>(i));
      cos_v.push_back(std::cos(kTwoPi * v));
      sin_v.push_back(std::sin(kTwoPi * v));
    }
  }
};

// A 64-bit mix (the splitmix64 finalizer): the per-sample shift from the
// texel's index in the map and the sample's index in the texel.
std::uint64_t mix64(std::uint64_t x) {
  x ^= x >> 30;
  x *= 0xbf58476d1ce4e5b9ull;
  x ^= x >> 27;
  x *= 0x94d049bb133111ebull;
  x ^= x >> 31;
  return x;
}

// Toroidal shift of the pattern for one sample, and the rotation it makes of
// the angle: cos and sin of 2 pi (v + shift_v).
struct Shift {
  float u = 0.0f;
  float cos_v = 1.0f, sin_v = 0.0f;
};
Shift sample_shift(std::uint64_t texel, int k, std::uint64_t salt) {
  const std::uint64_t h = mix64((texel << 6 | static_cast<std::uint64_t>(k)) ^ salt);
  Shift s;
  s.u = static_cast<float>(h >> 40) * 0x1p-24f;
  const float v = static_cast<float>(h & 0xffffffu) * 0x1p-24f;
  s.cos_v = std::cos(kTwoPi * v);
  s.sin_v = std::sin(kTwoPi * v);
  return s;
}
constexpr std::uint64_t kOcclusionSalt = 0x6a09e667f3bcc909ull;
constexpr std::uint64_t kThicknessSalt = 0xbb67ae8584caa73bull;

// An orthonormal frame (t, b, n) around the unit n (Duff et al.).
void frame_around(const glm::vec3& n, glm::vec3& t, glm::vec3& b) {
  const float sign = std::copysign(1.0f, n.z);
  const float a = -1.0f / (sign + n.z);
  const float c = n.x * n.y * a;
  t = glm::vec3(1.0f + sign * n.x * n.x * a, sign * c, -sign * n.x);
  b = glm::vec3(c, sign + n.y * n.y * a, -n.y);
}

// --- One sample's hit --------------------------------------------------------

struct HitFrame {
  glm::vec3 point;        // on the high triangle
  glm::vec3 origin;       // offset off the surface (outwards: AO; inwards: thickness)
  glm::vec3 n_shading;    // unit
  glm::vec3 n_geometric;  // unit, on n_shading's side
  glm::vec3 t, b;         // frame around n_shading
  bool fallback = false;
};

glm::vec3 interpolate_corners(const glm::vec3& a, const glm::vec3& b, const glm::vec3& c, glm::vec2 w) {
  return a * (1.0f - w.x - w.y) + b * w.x + c * w.y;
}

HitFrame hit_frame(const Mesh& high, const LowSurface& surface, std::int32_t low_triangle, glm::vec2 low_bary,
                   std::int32_t triangle, glm::vec2 bary, bool inwards) {
  const std::uint32_t* v = &high.indices[3 * static_cast<std::size_t>(triangle)];
  const glm::vec3& p0 = high.positions[v[0]];
  const glm::vec3& p1 = high.positions[v[1]];
  const glm::vec3& p2 = high.positions[v[2]];
  HitFrame f;
  const glm::vec3 p = interpolate_corners(p0, p1, p2, bary);
  glm::vec3 ng = glm::cross(p1 - p0, p2 - p0);
  const float lg = glm::length(ng);
  const bool face_ok = lg > 0.0f && std::isfinite(lg);
  if (face_ok) ng /= lg;
  glm::vec3 ns(0.0f);
  bool shading_ok = false;
  if (high.has_normals()) {
    ns = interpolate_corners(high.normals[v[0]], high.normals[v[1]], high.normals[v[2]], bary);
    const float ls = glm::length(ns);
    shading_ok = ls > 1e-12f && std::isfinite(ls);
    if (shading_ok) ns /= ls;
  }
  if (!shading_ok) {
    // Without smooth normals (--high-normals face) the face normal is the
    // surface's; a ~0 one is a fallback.
    f.fallback = high.has_normals();
    ns = ng;
    if (!face_ok) {
      // Neither: the low surface's own normal at the sample.
      f.fallback = true;
      const std::size_t base = 3 * static_cast<std::size_t>(low_triangle);
      ns = interpolate_corners(surface.normal[base], surface.normal[base + 1], surface.normal[base + 2],
                               low_bary);
      const float l = glm::length(ns);
      ns = l > 0.0f && std::isfinite(l) ? ns / l : glm::vec3(0.0f, 0.0f, 1.0f);
      ng = ns;
    }
  } else if (!face_ok) {
    ng = ns;  // a zero-area triangle has no plane of its own
    f.fallback = true;
  }
  if (glm::dot(ng, ns) < 0.0f) ng = -ng;
  f.n_shading = ns;
  f.n_geometric = ng;
  f.point = p;
  f.origin = offset_origin(p, inwards ? -ng : ng);
  frame_around(ns, f.t, f.b);
  return f;
}

// --- Packets -----------------------------------------------------------------

struct alignas(64) OcclusionPacket {
  RTCRay16 ray;
  alignas(64) int valid[kPacket];
  int count = 0;
};

struct alignas(64) ThicknessPacket {
  RTCRayHit16 rayhit;
  alignas(64) int valid[kPacket];
  float cos_theta[kPacket];
  int count = 0;
};

// Where a sample's rays go: its scene and mask (bake groups, as trace()).
struct Target {
  RTCScene scene;
  unsigned mask;
};
Target sample_target(const HighScene::Impl& impl, const LowSurface& surface, std::int32_t low_triangle) {
  const int per_scene = impl.groups_per_scene;
  if (impl.group_count() <= 1) return {impl.scene, 0xffffffffu};
  const int g = static_cast<int>(surface.group[static_cast<std::size_t>(low_triangle)]);
  return {impl.scenes[static_cast<std::size_t>(g / per_scene)],
          per_scene > 1 ? 1u << (g % per_scene) : 0xffffffffu};
}

// Rays [first, first + count) of one sample's AO pattern into `p`; returns
// the number mirrored above the hit triangle. Embree writes only tfar, so
// every field is set here.
int fill_occlusion_packet(OcclusionPacket& p, const HitFrame& f, const Pattern& pattern, const Shift& shift,
                          int first, int count, float distance, unsigned mask, std::uint64_t& untraced) {
  RTCRay16& r = p.ray;
  int mirrored = 0;
  for (int i = 0; i < kPacket; ++i) {
    const int k = first + i;
    const bool live = i < count;
    glm::vec3 d = f.n_shading;
    if (live) {
      float a = pattern.u[static_cast<std::size_t>(k)] + shift.u;
      if (a >= 1.0f) a -= 1.0f;
      const float radius = std::sqrt(a);
      const float c = pattern.cos_v[static_cast<std::size_t>(k)] * shift.cos_v -
                      pattern.sin_v[static_cast<std::size_t>(k)] * shift.sin_v;
      const float s = pattern.sin_v[static_cast<std::size_t>(k)] * shift.cos_v +
                      pattern.cos_v[static_cast<std::size_t>(k)] * shift.sin_v;
      const float z = std::sqrt(std::max(0.0f, 1.0f - a));
      d = (radius * c) * f.t + (radius * s) * f.b + z * f.n_shading;
      const float below = glm::dot(d, f.n_geometric);
      if (below < 0.0f) {
        d -= (2.0f * below) * f.n_geometric;
        ++mirrored;
      }
    }
    r.org_x[i] = f.origin.x;
    r.org_y[i] = f.origin.y;
    r.org_z[i] = f.origin.z;
    r.dir_x[i] = d.x;
    r.dir_y[i] = d.y;
    r.dir_z[i] = d.z;
    r.tnear[i] = 0.0f;
    r.tfar[i] = distance;
    r.time[i] = 0.0f;
    r.mask[i] = mask;
    r.id[i] = static_cast<unsigned>(i);
    r.flags[i] = 0;
    const bool ok = live && detail::embree_accepts(f.origin, d, distance);
    if (live && !ok) ++untraced;
    p.valid[i] = ok ? -1 : 0;
  }
  p.count = count;
  return mirrored;
}

void fill_thickness_packet(ThicknessPacket& p, const HitFrame& f, const Pattern& pattern, const Shift& shift,
                           int first, int count, float distance, float cone_cos, unsigned mask,
                           std::uint64_t& untraced) {
  RTCRay16& r = p.rayhit.ray;
  for (int i = 0; i < kPacket; ++i) {
    const int k = first + i;
    const bool live = i < count;
    glm::vec3 d = -f.n_shading;
    float cos_theta = 1.0f;
    if (live) {
      float a = pattern.u[static_cast<std::size_t>(k)] + shift.u;
      if (a >= 1.0f) a -= 1.0f;
      cos_theta = 1.0f - a * (1.0f - cone_cos);
      const float sin_theta = std::sqrt(std::max(0.0f, 1.0f - cos_theta * cos_theta));
      const float c = pattern.cos_v[static_cast<std::size_t>(k)] * shift.cos_v -
                      pattern.sin_v[static_cast<std::size_t>(k)] * shift.sin_v;
      const float s = pattern.sin_v[static_cast<std::size_t>(k)] * shift.cos_v +
                      pattern.cos_v[static_cast<std::size_t>(k)] * shift.sin_v;
      d = (sin_theta * c) * f.t + (sin_theta * s) * f.b - cos_theta * f.n_shading;
    }
    r.org_x[i] = f.origin.x;
    r.org_y[i] = f.origin.y;
    r.org_z[i] = f.origin.z;
    r.dir_x[i] = d.x;
    r.dir_y[i] = d.y;
    r.dir_z[i] = d.z;
    r.tnear[i] = 0.0f;
    r.tfar[i] = distance;
    r.time[i] = 0.0f;
    r.mask[i] = mask;
    r.id[i] = static_cast<unsigned>(i) | detail::kKeepBackfacesRayId;
    r.flags[i] = 0;
    p.rayhit.hit.geomID[i] = RTC_INVALID_GEOMETRY_ID;
    p.cos_theta[i] = cos_theta;
    const bool ok = live && detail::embree_accepts(f.origin, d, distance);
    if (live && !ok) ++untraced;
    p.valid[i] = ok ? -1 : 0;
  }
  p.count = count;
}

// --- Walking the samples -----------------------------------------------------

// f(sample, texel index in the map, sample index in the texel) for every
// sample of tile `tile` with a bake hit, in trace()'s texel order.
template <class F>
void for_each_hit_sample(const TexelSamples& samples, const Hits& hits, int tile, int tiles_x, F&& f) {
  const int x0 = (tile % tiles_x) * kTile, y0 = (tile / tiles_x) * kTile;
  const int x1 = std::min(x0 + kTile, samples.width), y1 = std::min(y0 + kTile, samples.height);
  const int spp = samples.samples;
  for (int by = y0; by < y1; by += kBlock) {
    for (int bx = x0; bx < x1; bx += kBlock) {
      for (int y = by; y < std::min(by + kBlock, y1); ++y) {
        for (int x = bx; x < std::min(bx + kBlock, x1); ++x) {
          const std::size_t first = (static_cast<std::size_t>(y) * samples.width + x) * spp;
          const std::uint64_t texel =
              static_cast<std::uint64_t>(samples.row_begin + y) * static_cast<std::uint64_t>(samples.width) +
              static_cast<std::uint64_t>(x);
          for (int k = 0; k < spp; ++k) {
            const std::size_t s = first + static_cast<std::size_t>(k);
            if (samples.triangle[s] < 0 || hits.triangle[s] < 0) continue;
            f(s, texel, k);
          }
        }
      }
    }
  }
}

int tile_count_of(const TexelSamples& samples, int& tiles_x) {
  tiles_x = (samples.width + kTile - 1) / kTile;
  const int tiles_y = (samples.height + kTile - 1) / kTile;
  return tiles_x * tiles_y;
}

}  // namespace

void trace_occlusion(const HighScene& scene, const Mesh& high, const LowSurface& surface,
                     const TexelSamples& samples, const Hits& hits, const OcclusionOptions& options,
                     std::vector<float>& visibility, std::vector<glm::vec3>& bent, OcclusionStats& stats) {
  NMBAKE_CHECK(scene.impl() != nullptr, "scene built");
  NMBAKE_CHECK(options.rays >= 1 && options.rays <= kMaxOcclusionRays, "occlusion ray count in range");
  const HighScene::Impl& impl = *scene.impl();
  const std::size_t sample_count = samples.sample_count();
  visibility.assign(sample_count, 1.0f);
  if (options.bent) bent.assign(sample_count, glm::vec3(0.0f));
  const Pattern pattern(options.rays);
  int tiles_x = 0;
  const int tile_count = tile_count_of(samples, tiles_x);
  struct Counts {
    std::uint64_t samples = 0, rays = 0, unoccluded = 0, mirrored = 0, fallbacks = 0, all_occluded = 0,
                  untraced = 0;
  };
  std::vector<Counts> tile_counts(static_cast<std::size_t>(tile_count));
  tbb::parallel_for(0, tile_count, [&](int tile) {
    Counts& c = tile_counts[static_cast<std::size_t>(tile)];
    RTCIntersectContext context;
    rtcInitIntersectContext(&context);
    OcclusionPacket packet;
    for_each_hit_sample(samples, hits, tile, tiles_x, [&](std::size_t s, std::uint64_t texel, int k) {
      const HitFrame f = hit_frame(high, surface, samples.triangle[s], samples.bary[s], hits.triangle[s],
                                   hits.bary[s], false);
      c.fallbacks += f.fallback ? 1 : 0;
      const Target target = sample_target(impl, surface, samples.triangle[s]);
      const Shift shift = sample_shift(texel, k, kOcclusionSalt);
      int open = 0;
      glm::vec3 sum(0.0f);
      for (int first = 0; first < options.rays; first += kPacket) {
        const int count = std::min(kPacket, options.rays - first);
        c.mirrored += static_cast<std::uint64_t>(fill_occlusion_packet(
            packet, f, pattern, shift, first, count, options.distance, target.mask, c.untraced));
        rtcOccluded16(packet.valid, target.scene, &context, &packet.ray);
        for (int i = 0; i < count; ++i) {
          // Occluded: Embree set tfar to -inf. A ray not traced counts as open.
          if (packet.ray.tfar[i] >= 0.0f) {
            ++open;
            if (options.bent) sum += glm::vec3(packet.ray.dir_x[i], packet.ray.dir_y[i], packet.ray.dir_z[i]);
          }
        }
      }
      ++c.samples;
      c.rays += static_cast<std::uint64_t>(options.rays);
      c.unoccluded += static_cast<std::uint64_t>(open);
      visibility[s] = static_cast<float>(open) / static_cast<float>(options.rays);
      if (options.bent) {
        const float l = glm::length(sum);
        if (open > 0 && l > 0.0f && std::isfinite(l)) {
          bent[s] = sum / l;
        } else {
          bent[s] = f.n_shading;
          ++c.all_occluded;
        }
      }
    });
  });
  for (const Counts& c : tile_counts) {
    stats.samples += c.samples;
    stats.rays += c.rays;
    stats.unoccluded += c.unoccluded;
    stats.mirrored_rays += c.mirrored;
    stats.normal_fallbacks += c.fallbacks;
    stats.all_occluded += c.all_occluded;
    stats.untraced_rays += c.untraced;
  }
}

RawTraceResult trace_occlusion_raw(const HighScene& scene, const Mesh& high, const LowSurface& surface,
                                   const TexelSamples& samples, const Hits& hits,
                                   const OcclusionOptions& options) {
  NMBAKE_CHECK(scene.impl() != nullptr, "scene built");
  const HighScene::Impl& impl = *scene.impl();
  const Pattern pattern(options.rays);
  int tiles_x = 0;
  const int tile_count = tile_count_of(samples, tiles_x);
  // Tiles in chunks: each chunk's packets are built, then fired with the
  // clock on. A 16 x 16 tile at 1 spp and 64 rays is 1,024 packets (~0.9 MB);
  // 16 tiles stay in the last-level cache, as the bake's packets, built just
  // before each call, are in L1 (with 256 tiles the raw side streamed its
  // packets from memory).
  constexpr int kChunkTiles = 16;
  RawTraceResult result;
  std::vector<std::vector<OcclusionPacket>> packets(kChunkTiles);
  std::vector<std::vector<RTCScene>> scenes(kChunkTiles);
  std::vector<std::uint64_t> tile_rays(kChunkTiles), tile_open(kChunkTiles);
  for (int chunk = 0; chunk < tile_count; chunk += kChunkTiles) {
    const int end = std::min(tile_count, chunk + kChunkTiles);
    tbb::parallel_for(chunk, end, [&](int tile) {
      const std::size_t slot = static_cast<std::size_t>(tile - chunk);
      packets[slot].clear();
      scenes[slot].clear();
      std::uint64_t untraced = 0;
      for_each_hit_sample(samples, hits, tile, tiles_x, [&](std::size_t s, std::uint64_t texel, int k) {
        const HitFrame f = hit_frame(high, surface, samples.triangle[s], samples.bary[s], hits.triangle[s],
                                     hits.bary[s], false);
        const Target target = sample_target(impl, surface, samples.triangle[s]);
        const Shift shift = sample_shift(texel, k, kOcclusionSalt);
        for (int first = 0; first < options.rays; first += kPacket) {
          packets[slot].emplace_back();
          scenes[slot].push_back(target.scene);
          fill_occlusion_packet(packets[slot].back(), f, pattern, shift, first,
                                std::min(kPacket, options.rays - first), options.distance, target.mask,
                                untraced);
        }
      });
    });
    const auto begin = std::chrono::steady_clock::now();
    tbb::parallel_for(chunk, end, [&](int tile) {
      const std::size_t slot = static_cast<std::size_t>(tile - chunk);
      RTCIntersectContext context;
      rtcInitIntersectContext(&context);
      std::uint64_t rays = 0, open = 0;
      for (std::size_t i = 0; i < packets[slot].size(); ++i) {
        OcclusionPacket& p = packets[slot][i];
        rtcOccluded16(p.valid, scenes[slot][i], &context, &p.ray);
        rays += static_cast<std::uint64_t>(p.count);
        for (int l = 0; l < p.count; ++l) open += p.ray.tfar[l] >= 0.0f ? 1 : 0;
      }
      tile_rays[slot] = rays;
      tile_open[slot] = open;
    });
    result.seconds += std::chrono::duration<double>(std::chrono::steady_clock::now() - begin).count();
    for (int tile = chunk; tile < end; ++tile) {
      result.rays += tile_rays[static_cast<std::size_t>(tile - chunk)];
      result.hits += tile_open[static_cast<std::size_t>(tile - chunk)];
    }
  }
  return result;
}

void trace_thickness(const HighScene& scene, const Mesh& high, const LowSurface& surface,
                     const TexelSamples& samples, const Hits& hits, const ThicknessOptions& options,
                     std::vector<float>& thickness, ThicknessStats& stats) {
  NMBAKE_CHECK(scene.impl() != nullptr, "scene built");
  NMBAKE_CHECK(options.rays >= 1 && options.rays <= kMaxOcclusionRays, "thickness ray count in range");
  const HighScene::Impl& impl = *scene.impl();
  thickness.assign(samples.sample_count(), 0.0f);
  const Pattern pattern(options.rays);
  const float cone_cos = std::cos(kThicknessConeDegrees * (kTwoPi / 360.0f));
  int tiles_x = 0;
  const int tile_count = tile_count_of(samples, tiles_x);
  struct Counts {
    std::uint64_t samples = 0, rays = 0, exits = 0, no_exit = 0, fallbacks = 0, untraced = 0;
  };
  std::vector<Counts> tile_counts(static_cast<std::size_t>(tile_count));
  tbb::parallel_for(0, tile_count, [&](int tile) {
    Counts& c = tile_counts[static_cast<std::size_t>(tile)];
    RTCIntersectContext context;
    rtcInitIntersectContext(&context);
    ThicknessPacket packet;
    for_each_hit_sample(samples, hits, tile, tiles_x, [&](std::size_t s, std::uint64_t texel, int k) {
      const HitFrame f = hit_frame(high, surface, samples.triangle[s], samples.bary[s], hits.triangle[s],
                                   hits.bary[s], true);
      c.fallbacks += f.fallback ? 1 : 0;
      const Target target = sample_target(impl, surface, samples.triangle[s]);
      const Shift shift = sample_shift(texel, k, kThicknessSalt);
      int found = 0;
      float sum = 0.0f;
      for (int first = 0; first < options.rays; first += kPacket) {
        const int count = std::min(kPacket, options.rays - first);
        fill_thickness_packet(packet, f, pattern, shift, first, count, options.distance, cone_cos,
                              target.mask, c.untraced);
        rtcIntersect16(packet.valid, target.scene, &context, &packet.rayhit);
        for (int i = 0; i < count; ++i) {
          if (packet.valid[i] == 0 || packet.rayhit.hit.geomID[i] == RTC_INVALID_GEOMETRY_ID) continue;
          ++found;
          sum += packet.rayhit.ray.tfar[i] * packet.cos_theta[i];
        }
      }
      ++c.samples;
      c.rays += static_cast<std::uint64_t>(options.rays);
      c.exits += static_cast<std::uint64_t>(found);
      if (found > 0) {
        // Depths from the surface point, not from the offset origin below it.
        thickness[s] = sum / static_cast<float>(found) + glm::dot(f.point - f.origin, f.n_shading);
      } else {
        thickness[s] = options.distance;
        ++c.no_exit;
      }
    });
  });
  for (const Counts& c : tile_counts) {
    stats.samples += c.samples;
    stats.rays += c.rays;
    stats.exits += c.exits;
    stats.samples_no_exit += c.no_exit;
    stats.normal_fallbacks += c.fallbacks;
    stats.untraced_rays += c.untraced;
  }
}

}  // namespace nmbake
