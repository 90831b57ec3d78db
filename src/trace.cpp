// Stage "trace": Embree 3 rays from the cage onto the high mesh.
//
// Rays are traced as 16-wide packets (rtcIntersect16) with the coherent
// context flag, gathered in a fixed order: tiles of 16 x 16 texels, 4 x 4
// texel blocks inside a tile, texels row-major inside a block, samples of a
// texel in pattern order. Neighbouring texels give nearly parallel rays from
// nearby origins, which is what the coherent flag wants (DESIGN.md's
// measurements: 2.5-3.8x faster than single rays). Packet composition depends
// only on the tile, never on the thread that runs it, so results are the
// same for any thread count.
#include "nmbake/trace.hpp"

#include <algorithm>
#include <atomic>
#include <chrono>
#include <cmath>
#include <cstring>
#include <mutex>
#include <string>

#include <embree3/rtcore.h>
#include <glm/geometric.hpp>
#include <tbb/parallel_for.h>

#include "huge_pages.hpp"
#include "simd4.hpp"

namespace nmbake {

namespace {

constexpr int kTile = 16;
constexpr int kBlock = 4;
constexpr int kPacket = 16;

std::mutex g_error_mutex;
std::string g_last_error;

void on_embree_error(void*, RTCError code, const char* message) {
  std::lock_guard<std::mutex> lock(g_error_mutex);
  g_last_error = "Embree error " + std::to_string(static_cast<int>(code)) + ": " + (message ? message : "");
}

std::string take_embree_error() {
  std::lock_guard<std::mutex> lock(g_error_mutex);
  std::string e = g_last_error;
  g_last_error.clear();
  return e.empty() ? std::string("unknown Embree error") : e;
}

glm::vec3 face_normal(const glm::vec3& a, const glm::vec3& b, const glm::vec3& c) {
  return glm::cross(b - a, c - a);
}

// Ignores hits on triangles whose front (counter-clockwise) side faces away
// from the ray: dot(face normal, direction) > 0.
void backface_filter(const RTCFilterFunctionNArguments* args) {
  const Mesh* mesh = static_cast<const Mesh*>(args->geometryUserPtr);
  for (unsigned i = 0; i < args->N; ++i) {
    if (args->valid[i] != -1) continue;
    const unsigned prim = RTCHitN_primID(args->hit, args->N, i);
    const glm::vec3 dir(RTCRayN_dir_x(args->ray, args->N, i), RTCRayN_dir_y(args->ray, args->N, i),
                        RTCRayN_dir_z(args->ray, args->N, i));
    const std::uint32_t* tri = &mesh->indices[3 * static_cast<std::size_t>(prim)];
    const glm::vec3 n = face_normal(mesh->positions[tri[0]], mesh->positions[tri[1]], mesh->positions[tri[2]]);
    if (glm::dot(n, dir) > 0.0f) args->valid[i] = 0;
  }
}

[[gnu::always_inline]] inline glm::vec3 interpolate(const std::vector<glm::vec3>& corner, std::size_t base,
                                                    glm::vec2 b) {
  return corner[base] * (1.0f - b.x - b.y) + corner[base + 1] * b.x + corner[base + 2] * b.y;
}

}  // namespace

struct HighScene::Impl {
  RTCDevice device = nullptr;
  RTCScene scene = nullptr;
  const Mesh* mesh = nullptr;
  bool compact = false;
  ~Impl() {
    if (scene) rtcReleaseScene(scene);
    if (device) rtcReleaseDevice(device);
  }
};

HighScene::HighScene() = default;
HighScene::~HighScene() = default;
HighScene::HighScene(HighScene&&) noexcept = default;
HighScene& HighScene::operator=(HighScene&&) noexcept = default;

bool HighScene::compact() const { return impl_ != nullptr && impl_->compact; }

Status HighScene::build(const Mesh& mesh, BuildQuality quality, bool backface_filter_on, HighScene& out,
                        BvhMemory memory) {
  NMBAKE_CHECK(mesh.positions.capacity() > mesh.positions.size(), "pad_for_embree() before building");
  auto impl = std::make_unique<Impl>();
  impl->mesh = &mesh;
  impl->device = rtcNewDevice(nullptr);
  if (!impl->device) return Status::internal("cannot create an Embree device: " + take_embree_error());
  rtcSetDeviceErrorFunction(impl->device, on_embree_error, nullptr);

  impl->scene = rtcNewScene(impl->device);
  rtcSetSceneBuildQuality(impl->scene, quality == BuildQuality::low    ? RTC_BUILD_QUALITY_LOW
                                       : quality == BuildQuality::high ? RTC_BUILD_QUALITY_HIGH
                                                                       : RTC_BUILD_QUALITY_MEDIUM);
  // Robust mode: the watertight intersection test. Bake rays often pass
  // exactly through shared edges of the high mesh (where its grid lines
  // up with the low one), and the fast test lets such rays slip through.
  impl->compact = memory == BvhMemory::compact ||
                  (memory == BvhMemory::automatic && mesh.triangle_count() > kCompactBvhAbove);
  rtcSetSceneFlags(impl->scene, impl->compact ? RTCSceneFlags(RTC_SCENE_FLAG_ROBUST | RTC_SCENE_FLAG_COMPACT)
                                              : RTC_SCENE_FLAG_ROBUST);

  RTCGeometry geometry = rtcNewGeometry(impl->device, RTC_GEOMETRY_TYPE_TRIANGLE);
  // Shared buffers: the high mesh is never copied.
  rtcSetSharedGeometryBuffer(geometry, RTC_BUFFER_TYPE_VERTEX, 0, RTC_FORMAT_FLOAT3, mesh.positions.data(), 0,
                             sizeof(glm::vec3), mesh.positions.size());
  rtcSetSharedGeometryBuffer(geometry, RTC_BUFFER_TYPE_INDEX, 0, RTC_FORMAT_UINT3, mesh.indices.data(), 0,
                             3 * sizeof(std::uint32_t), mesh.triangle_count());
  rtcSetGeometryBuildQuality(geometry, quality == BuildQuality::low    ? RTC_BUILD_QUALITY_LOW
                                       : quality == BuildQuality::high ? RTC_BUILD_QUALITY_HIGH
                                                                       : RTC_BUILD_QUALITY_MEDIUM);
  if (backface_filter_on) {
    rtcSetGeometryUserData(geometry, const_cast<Mesh*>(&mesh));
    rtcSetGeometryIntersectFilterFunction(geometry, backface_filter);
  }
  rtcCommitGeometry(geometry);
  rtcAttachGeometry(impl->scene, geometry);
  rtcReleaseGeometry(geometry);
  rtcCommitScene(impl->scene);
  if (rtcGetDeviceError(impl->device) != RTC_ERROR_NONE) {
    return Status::internal("building the ray-tracing scene failed: " + take_embree_error());
  }
  out.impl_ = std::move(impl);
  return Status::ok();
}

namespace {

// make_ray()'s body, forced inline into the tracing loops: called once per
// ray, it was about a tenth of the trace stage as a call.
[[gnu::always_inline]] inline Ray build_ray(const LowSurface& surface, std::int32_t tri, glm::vec2 b,
                                            const RayOptions& options, bool& used_fallback) {
  const std::size_t base = 3 * static_cast<std::size_t>(tri);
  Ray ray;
  ray.surface_point = interpolate(surface.position, base, b);
  used_fallback = false;

  if (options.cage == CageMode::mesh && surface.has_cage_mesh()) {
    const glm::vec3 origin = interpolate(surface.cage_position, base, b);
    const glm::vec3 to_surface = ray.surface_point - origin;
    const float length = glm::length(to_surface);
    if (length > 0.0f && std::isfinite(length)) {
      ray.origin = origin;
      ray.direction = to_surface / length;
      ray.t_surface = length;
      ray.tfar = length + options.back;
      return ray;
    }
    // The cage touches the low surface here: search only inwards along the
    // averaged normal.
    used_fallback = true;
    glm::vec3 a = interpolate(surface.cage_normal, base, b);
    const float la = glm::length(a);
    a = la > 0.0f ? a / la : glm::normalize(face_normal(surface.position[base], surface.position[base + 1],
                                                         surface.position[base + 2]) + glm::vec3(0, 0, 1e-30f));
    ray.origin = ray.surface_point;
    ray.direction = -a;
    ray.t_surface = 0.0f;
    ray.tfar = options.back;
    return ray;
  }

  const std::vector<glm::vec3>& normals = options.cage == CageMode::interpolated ? surface.normal : surface.cage_normal;
  glm::vec3 a = interpolate(normals, base, b);
  float length = glm::length(a);
  if (!(length > 1e-12f) || !std::isfinite(length)) {
    used_fallback = true;
    a = face_normal(surface.position[base], surface.position[base + 1], surface.position[base + 2]);
    length = glm::length(a);
    if (!(length > 0.0f) || !std::isfinite(length)) {
      a = glm::vec3(0.0f, 0.0f, 1.0f);
      length = 1.0f;
    }
  }
  a *= 1.0f / length;  // one division, not three
  ray.origin = ray.surface_point + options.front * a;
  ray.direction = -a;
  ray.t_surface = options.front;
  ray.tfar = options.front + options.back;
  return ray;
}

}  // namespace

Ray make_ray(const LowSurface& surface, std::int32_t tri, glm::vec2 b, const RayOptions& options,
             bool& used_fallback) {
  return build_ray(surface, tri, b, options, used_fallback);
}

namespace {

struct alignas(64) Packet {
  RTCRayHit16 rayhit;
  alignas(64) int valid[kPacket];
  std::size_t sample[kPacket];
  std::int32_t triangle[kPacket];  // queued lanes (queue_sample): built by build_queued_rays
  glm::vec2 bary[kPacket];
  float t_surface[kPacket];
  float sign[kPacket];  // +1: distance = t_surface - t; used to turn t into a signed surface distance
  int count = 0;
};

void reset_packet(Packet& p) {
  p.count = 0;
  for (int i = 0; i < kPacket; ++i) p.valid[i] = 0;
}

void add_ray(Packet& p, std::size_t sample, const glm::vec3& origin, const glm::vec3& direction, float tfar,
             float t_surface, float sign) {
  const int i = p.count++;
  RTCRay16& r = p.rayhit.ray;
  r.org_x[i] = origin.x;
  r.org_y[i] = origin.y;
  r.org_z[i] = origin.z;
  r.tnear[i] = 0.0f;
  r.dir_x[i] = direction.x;
  r.dir_y[i] = direction.y;
  r.dir_z[i] = direction.z;
  r.time[i] = 0.0f;
  r.tfar[i] = tfar;
  r.mask[i] = 0xffffffffu;
  r.id[i] = static_cast<unsigned>(i);
  r.flags[i] = 0;
  p.rayhit.hit.geomID[i] = RTC_INVALID_GEOMETRY_ID;
  p.rayhit.hit.primID[i] = RTC_INVALID_GEOMETRY_ID;
  p.valid[i] = -1;
  p.sample[i] = sample;
  p.t_surface[i] = t_surface;
  p.sign[i] = sign;
}

// The common case (first hit, averaged or interpolated cage): samples are
// queued and their rays built together, lane by lane with no branch between
// lanes, so the square roots and divisions of 16 rays overlap instead of
// running one after the other. The arithmetic is build_ray()'s, so the rays
// are bit for bit the same; lanes that need its fallback take build_ray().
bool batched_rays(const RayOptions& options) {
  return options.hit == HitRule::first && options.cage != CageMode::mesh;
}

void queue_sample(Packet& p, std::size_t sample, std::int32_t tri, glm::vec2 b) {
  const int i = p.count++;
  p.sample[i] = sample;
  p.triangle[i] = tri;
  p.bary[i] = b;
}

// An empty packet. A queued one (batched_rays) also gets the ray fields that
// no ray changes and Embree never writes, once: build_queued_rays() sets
// only the rest. (Its hits are read with options.front, not t_surface/sign.)
void start_packet(Packet& p, bool queued) {
  reset_packet(p);
  if (!queued) return;
  RTCRay16& r = p.rayhit.ray;
  for (int i = 0; i < kPacket; ++i) {
    r.tnear[i] = 0.0f;
    r.time[i] = 0.0f;
    r.mask[i] = 0xffffffffu;
    r.id[i] = static_cast<unsigned>(i);
    r.flags[i] = 0;
  }
}

// The texels of one tile and the order their samples are traced in: 4 x 4
// texel blocks, texels row-major inside a block, samples in pattern order.
// trace() and trace_raw() both walk it, so the raw baseline fires the bake's
// packets.
struct TileRect {
  int x0, y0, x1, y1;  // texels [x0, x1) x [y0, y1)
};

TileRect tile_rect(const TexelSamples& samples, int tile, int tiles_x) {
  const int x0 = (tile % tiles_x) * kTile, y0 = (tile / tiles_x) * kTile;
  return {x0, y0, std::min(x0 + kTile, samples.width), std::min(y0 + kTile, samples.height)};
}

template <class F>
[[gnu::always_inline]] inline void for_each_sample_in_trace_order(const TexelSamples& samples, const TileRect& t,
                                                                  F&& f) {
  const std::size_t spp = static_cast<std::size_t>(samples.samples);
  for (int by = t.y0; by < t.y1; by += kBlock) {
    for (int bx = t.x0; bx < t.x1; bx += kBlock) {
      for (int y = by; y < std::min(by + kBlock, t.y1); ++y) {
        for (int x = bx; x < std::min(bx + kBlock, t.x1); ++x) {
          const std::size_t first = (static_cast<std::size_t>(y) * samples.width + x) * spp;
          for (std::size_t s = first; s < first + spp; ++s) f(s);
        }
      }
    }
  }
}

// Builds the queued lanes' rays four at a time in SIMD lanes: per lane the
// point and the cage normal are interpolated, then one vector per axis gives
// the lengths, the unit normals and the origins. The operations are
// build_ray()'s, in its order, so the rays are bit for bit the same; a lane
// whose normal is zero or not finite takes build_ray() and its fallback.
// Of the other fields only those Embree writes (tfar, geomID) and the valid
// mask are set, for all 16 lanes (lanes past the count are invalid); the
// rest are set once per packet by start_packet(). Returns the number
// of lanes that took the fallback.
std::uint64_t build_queued_rays(Packet& p, const LowSurface& surface, const RayOptions& options) {
  using namespace detail;
  const std::vector<glm::vec3>& normals = options.cage == CageMode::interpolated ? surface.normal : surface.cage_normal;
  RTCRay16& r = p.rayhit.ray;
  const int n = p.count;
  const f4 front = splat4(options.front);
  std::uint64_t fallbacks = 0;
  // The lanes of a packet mostly share a low triangle (at 16 spp a packet is
  // one texel): its corners are loaded once for a run of such lanes.
  std::int32_t loaded = -1;
  Corners position, cage;
  for (int g = 0; g < n; g += 4) {
    f4 point[4], normal[4];
    for (int k = 0; k < 4; ++k) {
      const int i = std::min(g + k, n - 1);  // past the count: a copy of the last lane
      if (p.triangle[i] != loaded) {
        loaded = p.triangle[i];
        const std::size_t base = 3 * static_cast<std::size_t>(loaded);
        position = load_corners(&surface.position[base]);
        cage = load_corners(&normals[base]);
      }
      point[k] = corner_mix(position, p.bary[i]);
      normal[k] = corner_mix(cage, p.bary[i]);
    }
    const Axes P = transpose(point[0], point[1], point[2], point[3]);
    const Axes a = transpose(normal[0], normal[1], normal[2], normal[3]);
    const f4 length = sqrt4(a.x * a.x + a.y * a.y + a.z * a.z);
    const i4 ok = (length > splat4(1e-12f)) & finite4(length);
    const f4 inv = splat4(1.0f) / length;
    const f4 ax = a.x * inv, ay = a.y * inv, az = a.z * inv;
    store4(r.org_x + g, P.x + front * ax);
    store4(r.org_y + g, P.y + front * ay);
    store4(r.org_z + g, P.z + front * az);
    store4(r.dir_x + g, -ax);
    store4(r.dir_y + g, -ay);
    store4(r.dir_z + g, -az);
    if (all4(ok)) continue;  // the common case
    for (int k = 0; k < 4 && g + k < n; ++k) {
      if (ok[k]) continue;
      const int i = g + k;
      bool fallback = false;
      const Ray ray = build_ray(surface, p.triangle[i], p.bary[i], options, fallback);
      fallbacks += fallback ? 1 : 0;
      r.org_x[i] = ray.origin.x;
      r.org_y[i] = ray.origin.y;
      r.org_z[i] = ray.origin.z;
      r.dir_x[i] = ray.direction.x;
      r.dir_y[i] = ray.direction.y;
      r.dir_z[i] = ray.direction.z;
    }
  }
  const float tfar = options.front + options.back;
  for (int i = 0; i < kPacket; ++i) {
    r.tfar[i] = tfar;
    p.rayhit.hit.geomID[i] = RTC_INVALID_GEOMETRY_ID;
    p.valid[i] = i < n ? -1 : 0;
  }
  return fallbacks;
}

// A candidate hit per sample while a tile is traced (nearest needs two rays).
struct Candidate {
  std::int32_t triangle = -1;
  glm::vec2 bary{0.0f};
  float distance = 0.0f;  // signed, outward positive
  float abs_distance = 0.0f;
};

}  // namespace

void trace(const HighScene& scene, const LowSurface& surface, const TexelSamples& samples,
           const RayOptions& options, Hits& hits, TraceStats& stats, const std::function<void(double)>& progress) {
  NMBAKE_CHECK(scene.impl() != nullptr, "scene built");
  const std::size_t sample_count = samples.sample_count();
  // Kept from the previous band: every sample's triangle is written below
  // (-1 for no sample or a miss), and bary and distance are read only
  // where a triangle was hit, so the arrays are not refilled each band.
  detail::size_output(hits.triangle, sample_count);
  detail::size_output(hits.bary, sample_count);
  detail::size_output(hits.distance, sample_count);

  const int tiles_x = (samples.width + kTile - 1) / kTile;
  const int tiles_y = (samples.height + kTile - 1) / kTile;
  const int tile_count = tiles_x * tiles_y;
  const int spp = samples.samples;
  RTCScene rtc_scene = scene.impl()->scene;

  struct TileCounts {
    std::uint64_t rays = 0, samples = 0, hits = 0, misses = 0, fallbacks = 0;
  };
  std::vector<TileCounts> tile_counts(tile_count);

  auto trace_tile = [&](int tile) {
    TileCounts& counts = tile_counts[tile];
    const TileRect rect = tile_rect(samples, tile, tiles_x);

    RTCIntersectContext context;
    rtcInitIntersectContext(&context);
    context.flags = RTC_INTERSECT_CONTEXT_FLAG_COHERENT;
    Packet packet;
    const bool queued = batched_rays(options);
    start_packet(packet, queued);

    // The common case (first hit, rays queued and built together): each
    // sample's result is written once, -1 for no sample or a miss, and the
    // hits are counted as the packets come back.
    if (queued) {
      auto flush = [&]() {
        if (packet.count == 0) return;
        counts.fallbacks += build_queued_rays(packet, surface, options);
        rtcIntersect16(packet.valid, rtc_scene, &context, &packet.rayhit);
        counts.rays += static_cast<std::uint64_t>(packet.count);
        for (int i = 0; i < packet.count; ++i) {
          const std::size_t s = packet.sample[i];
          const bool hit = packet.rayhit.hit.geomID[i] != RTC_INVALID_GEOMETRY_ID;
          hits.triangle[s] = hit ? static_cast<std::int32_t>(packet.rayhit.hit.primID[i]) : -1;
          if (!hit) continue;
          ++counts.hits;
          hits.bary[s] = glm::vec2(packet.rayhit.hit.u[i], packet.rayhit.hit.v[i]);
          hits.distance[s] = options.front - packet.rayhit.ray.tfar[i];
        }
        packet.count = 0;
      };
      for_each_sample_in_trace_order(samples, rect, [&](std::size_t s) {
        const std::int32_t tri = samples.triangle[s];
        if (tri < 0) {
          hits.triangle[s] = -1;
          return;
        }
        ++counts.samples;
        if (packet.count == kPacket) flush();
        queue_sample(packet, s, tri, samples.bary[s]);
      });
      flush();
      counts.misses = counts.samples - counts.hits;
      return;
    }

    // `nearest` keeps per sample the best of two rays; a packet holds both
    // rays of up to 8 samples, so the best is settled inside one flush.
    auto flush = [&]() {
      if (packet.count == 0) return;
      rtcIntersect16(packet.valid, rtc_scene, &context, &packet.rayhit);
      counts.rays += static_cast<std::uint64_t>(packet.count);
      for (int i = 0; i < packet.count; ++i) {
        const std::size_t s = packet.sample[i];
        if (packet.rayhit.hit.geomID[i] == RTC_INVALID_GEOMETRY_ID) continue;
        const float t = packet.rayhit.ray.tfar[i];
        const float distance = packet.sign[i] * (packet.t_surface[i] - t);
        const bool better = hits.triangle[s] < 0 || std::fabs(distance) < std::fabs(hits.distance[s]) ||
                            (std::fabs(distance) == std::fabs(hits.distance[s]) && distance > hits.distance[s]);
        if (options.hit == HitRule::first || better) {
          hits.triangle[s] = static_cast<std::int32_t>(packet.rayhit.hit.primID[i]);
          hits.bary[s] = glm::vec2(packet.rayhit.hit.u[i], packet.rayhit.hit.v[i]);
          hits.distance[s] = distance;
        }
      }
      reset_packet(packet);
    };

    for_each_sample_in_trace_order(samples, rect, [&](std::size_t s) {
      const std::int32_t tri = samples.triangle[s];
      hits.triangle[s] = -1;
      if (tri < 0) return;
      ++counts.samples;
      bool fallback = false;
      const Ray ray = build_ray(surface, tri, samples.bary[s], options, fallback);
      counts.fallbacks += fallback ? 1 : 0;
      if (options.hit == HitRule::first) {
        if (packet.count == kPacket) flush();
        add_ray(packet, s, ray.origin, ray.direction, ray.tfar, ray.t_surface, 1.0f);
      } else {
        if (packet.count > kPacket - 2) flush();
        // Outwards from P up to the cage, and inwards up to `back`.
        add_ray(packet, s, ray.surface_point, -ray.direction, ray.t_surface, 0.0f, -1.0f);
        add_ray(packet, s, ray.surface_point, ray.direction, ray.tfar - ray.t_surface, 0.0f, 1.0f);
      }
    });
    flush();
    for (int y = rect.y0; y < rect.y1; ++y) {
      for (int x = rect.x0; x < rect.x1; ++x) {
        const std::size_t first = (static_cast<std::size_t>(y) * samples.width + x) * spp;
        for (int k = 0; k < spp; ++k) {
          const std::size_t s = first + k;
          if (samples.triangle[s] < 0) continue;
          if (hits.triangle[s] >= 0) {
            ++counts.hits;
          } else {
            ++counts.misses;
          }
        }
      }
    }
  };

  // Batches of tiles, so progress can be reported from this thread between
  // parallel loops; the batching does not change any result.
  // Without a listener, one loop: the batches' barriers cost a few percent.
  const int batch = progress ? std::max(1, tile_count / 100) : tile_count;
  for (int begin = 0; begin < tile_count; begin += batch) {
    const int end = std::min(begin + batch, tile_count);
    tbb::parallel_for(begin, end, [&](int tile) { trace_tile(tile); });
    if (progress) progress(static_cast<double>(end) / tile_count);
  }

  for (const TileCounts& c : tile_counts) {
    stats.rays += c.rays;
    stats.samples += c.samples;
    stats.hits += c.hits;
    stats.misses += c.misses;
    stats.ray_fallbacks += c.fallbacks;
  }
}

DistanceEstimate estimate_distances(const HighScene& scene, const LowSurface& surface, float diagonal) {
  // Probe points: a fixed low-discrepancy set of barycentric points per
  // triangle, more on larger triangles, about 64k in all plus four per
  // triangle. From each probe one ray goes outwards and one inwards along
  // the averaged normal, up to a quarter of the diagonal; the nearer hit says
  // where the high surface is at that point.
  const std::size_t triangle_count = surface.triangle_count();
  std::vector<double> areas(triangle_count);
  double total_area = 0.0;
  for (std::size_t t = 0; t < triangle_count; ++t) {
    areas[t] = 0.5 * glm::length(face_normal(surface.position[3 * t], surface.position[3 * t + 1],
                                             surface.position[3 * t + 2]));
    total_area += areas[t];
  }
  std::vector<std::uint32_t> first_probe(triangle_count + 1, 0);
  for (std::size_t t = 0; t < triangle_count; ++t) {
    const double share = total_area > 0.0 ? areas[t] / total_area : 0.0;
    first_probe[t + 1] = first_probe[t] + 4 + static_cast<std::uint32_t>(std::min(4096.0, share * 65536.0));
  }
  const std::size_t probe_count = first_probe[triangle_count];
  std::vector<float> signed_distance(probe_count, 0.0f);
  std::vector<std::uint8_t> found(probe_count, 0);

  const float reach = 0.25f * diagonal;
  RayOptions options;
  options.cage = CageMode::averaged;
  RTCScene rtc_scene = scene.impl()->scene;

  tbb::parallel_for(std::size_t{0}, triangle_count, [&](std::size_t t) {
    RTCIntersectContext context;
    rtcInitIntersectContext(&context);
    for (std::uint32_t p = first_probe[t]; p < first_probe[t + 1]; ++p) {
      const std::uint32_t k = p - first_probe[t];
      // R2 sequence folded into the triangle.
      float r1 = std::fmod(0.5f + 0.7548776662f * static_cast<float>(k + 1), 1.0f);
      float r2 = std::fmod(0.5f + 0.5698402910f * static_cast<float>(k + 1), 1.0f);
      if (r1 + r2 > 1.0f) {
        r1 = 1.0f - r1;
        r2 = 1.0f - r2;
      }
      bool fallback = false;
      const Ray ray = make_ray(surface, static_cast<std::int32_t>(t), glm::vec2(r1, r2), options, fallback);
      float best = 0.0f;
      bool any = false;
      for (int side = 0; side < 2; ++side) {
        const glm::vec3 dir = side == 0 ? -ray.direction : ray.direction;  // outwards, then inwards
        RTCRayHit rh;
        rh.ray.org_x = ray.surface_point.x;
        rh.ray.org_y = ray.surface_point.y;
        rh.ray.org_z = ray.surface_point.z;
        rh.ray.tnear = 0.0f;
        rh.ray.dir_x = dir.x;
        rh.ray.dir_y = dir.y;
        rh.ray.dir_z = dir.z;
        rh.ray.time = 0.0f;
        rh.ray.tfar = reach;
        rh.ray.mask = 0xffffffffu;
        rh.ray.id = 0;
        rh.ray.flags = 0;
        rh.hit.geomID = RTC_INVALID_GEOMETRY_ID;
        rtcIntersect1(rtc_scene, &context, &rh);
        if (rh.hit.geomID == RTC_INVALID_GEOMETRY_ID) continue;
        const float d = side == 0 ? rh.ray.tfar : -rh.ray.tfar;
        if (!any || std::fabs(d) < std::fabs(best)) best = d;
        any = true;
      }
      signed_distance[p] = best;
      found[p] = any ? 1 : 0;
    }
  });

  std::vector<float> outside, inside;
  DistanceEstimate e;
  e.probes = probe_count;
  for (std::size_t p = 0; p < probe_count; ++p) {
    if (!found[p]) {
      ++e.probe_misses;
      continue;
    }
    if (signed_distance[p] >= 0.0f) {
      outside.push_back(signed_distance[p]);
    } else {
      inside.push_back(-signed_distance[p]);
    }
  }
  // A high quantile rather than the maximum: one stray probe that found a
  // far surface must not stretch every ray of the bake.
  auto quantile = [](std::vector<float>& v, double q) {
    if (v.empty()) return 0.0f;
    const std::size_t k = std::min(v.size() - 1, static_cast<std::size_t>(q * static_cast<double>(v.size())));
    std::nth_element(v.begin(), v.begin() + static_cast<std::ptrdiff_t>(k), v.end());
    return v[k];
  };
  const float floor_distance = 0.002f * diagonal;
  e.front = std::max(floor_distance, 1.25f * quantile(outside, 0.995) + floor_distance);
  e.back = std::max(floor_distance, 1.25f * quantile(inside, 0.995) + floor_distance);
  return e;
}

}  // namespace nmbake

namespace nmbake {

RawTraceResult trace_raw(const HighScene& scene, const LowSurface& surface, const TexelSamples& samples,
                         const RayOptions& options) {
  NMBAKE_CHECK(scene.impl() != nullptr, "scene built");
  NMBAKE_CHECK(options.hit == HitRule::first, "the raw baseline measures first-hit rays");
  // The same rays in the same packets as trace(): the same tiles, walked in
  // the same order (for_each_sample_in_trace_order). They are built before
  // the clock starts, so only Embree is timed.
  const int tiles_x = (samples.width + kTile - 1) / kTile;
  const int tiles_y = (samples.height + kTile - 1) / kTile;
  // Built by the bake's own code: queued and built together where trace()
  // does so, one by one where it does not.
  const bool batched = batched_rays(options);
  const auto finish_packet = [&](Packet& p) {
    if (batched) build_queued_rays(p, surface, options);
  };
  std::vector<std::vector<Packet>> tile_packets(static_cast<std::size_t>(tiles_x) * tiles_y);
  tbb::parallel_for(0, tiles_x * tiles_y, [&](int tile) {
    std::vector<Packet>& packets = tile_packets[static_cast<std::size_t>(tile)];
    packets.emplace_back();
    start_packet(packets.back(), batched);
    for_each_sample_in_trace_order(samples, tile_rect(samples, tile, tiles_x), [&](std::size_t s) {
      if (samples.triangle[s] < 0) return;
      if (packets.back().count == kPacket) {
        finish_packet(packets.back());
        packets.emplace_back();
        start_packet(packets.back(), batched);
      }
      if (batched) {
        queue_sample(packets.back(), s, samples.triangle[s], samples.bary[s]);
        return;
      }
      bool fallback = false;
      const Ray ray = build_ray(surface, samples.triangle[s], samples.bary[s], options, fallback);
      add_ray(packets.back(), s, ray.origin, ray.direction, ray.tfar, ray.t_surface, 1.0f);
    });
    finish_packet(packets.back());
  });
  RTCScene rtc_scene = scene.impl()->scene;
  std::vector<std::uint64_t> tile_rays(tile_packets.size(), 0), tile_hits(tile_packets.size(), 0);
  const auto begin = std::chrono::steady_clock::now();
  tbb::parallel_for(std::size_t{0}, tile_packets.size(), [&](std::size_t tile) {
    RTCIntersectContext context;
    rtcInitIntersectContext(&context);
    context.flags = RTC_INTERSECT_CONTEXT_FLAG_COHERENT;
    for (Packet& p : tile_packets[tile]) {
      if (p.count == 0) continue;
      rtcIntersect16(p.valid, rtc_scene, &context, &p.rayhit);
      tile_rays[tile] += static_cast<std::uint64_t>(p.count);
      for (int i = 0; i < p.count; ++i) tile_hits[tile] += p.rayhit.hit.geomID[i] != RTC_INVALID_GEOMETRY_ID;
    }
  });
  RawTraceResult result;
  result.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - begin).count();
  for (std::size_t t = 0; t < tile_packets.size(); ++t) {
    result.rays += tile_rays[t];
    result.hits += tile_hits[t];
  }
  return result;
}

}  // namespace nmbake
