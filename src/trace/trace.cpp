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

#include <embree3/rtcore.h>
#include <tbb/parallel_for.h>

#include <algorithm>
#include <atomic>
#include <chrono>
#include <cmath>
#include <cstring>
#include <glm/geometric.hpp>
#include <glm/vec3.hpp>
#include <glm/vector_relational.hpp>
#include <mutex>
#include <string>

#include "base/huge_pages.hpp"
#include "base/simd4.hpp"
#include "trace/scene.hpp"

namespace nmbake {

using detail::embree_accepts;
using detail::GeometryRef;

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
  const auto* ref = static_cast<const GeometryRef*>(args->geometryUserPtr);
  const Mesh* mesh = ref->mesh;
  for (unsigned i = 0; i < args->N; ++i) {
    if (args->valid[i] != -1) continue;
    // Thickness rays run from inside the mesh to its back faces (trace_occlusion.cpp).
    if ((RTCRayN_id(args->ray, args->N, i) & detail::kKeepBackfacesRayId) != 0) continue;
    const unsigned prim = RTCHitN_primID(args->hit, args->N, i) + ref->first_triangle;
    const glm::vec3 dir(RTCRayN_dir_x(args->ray, args->N, i), RTCRayN_dir_y(args->ray, args->N, i),
                        RTCRayN_dir_z(args->ray, args->N, i));
    const std::uint32_t* tri = &mesh->indices[3 * static_cast<std::size_t>(prim)];
    const glm::vec3 n =
        face_normal(mesh->positions[tri[0]], mesh->positions[tri[1]], mesh->positions[tri[2]]);
    if (glm::dot(n, dir) > 0.0f) args->valid[i] = 0;
  }
}

[[gnu::always_inline]] inline glm::vec3 interpolate(const std::vector<glm::vec3>& corner, std::size_t base,
                                                    glm::vec2 b) {
  return corner[base] * (1.0f - b.x - b.y) + corner[base + 1] * b.x + corner[base + 2] * b.y;
}
[[gnu::always_inline]] inline glm::vec3 interpolate_corners(const glm::vec3* corner, glm::vec2 b) {
  return corner[0] * (1.0f - b.x - b.y) + corner[1] * b.x + corner[2] * b.y;
}

}  // namespace

HighScene::HighScene() = default;
HighScene::~HighScene() = default;
HighScene::HighScene(HighScene&&) noexcept = default;
HighScene& HighScene::operator=(HighScene&&) noexcept = default;

bool HighScene::compact() const { return impl_ != nullptr && impl_->compact; }
int HighScene::group_count() const { return impl_ != nullptr ? impl_->group_count() : 0; }
int HighScene::scene_count() const { return impl_ != nullptr ? static_cast<int>(impl_->scenes.size()) : 0; }

// Measured (BENCHMARKS.md, "Bake groups"): groups sharing a BVH through ray
// masks against one scene per group.
constexpr int kGroupsPerSceneDefault = 32;

Status HighScene::build(const Mesh& mesh, BuildQuality quality, bool backface_filter_on, HighScene& out,
                        BvhMemory memory, const SceneGroups* groups) {
  NMBAKE_CHECK(mesh.positions.capacity() > mesh.positions.size(), "pad_for_embree() before building");
  auto impl = std::make_unique<Impl>();
  impl->mesh = &mesh;
  if (groups != nullptr && groups->first_triangle.size() > 2) {
    NMBAKE_CHECK(
        groups->first_triangle.front() == 0 && groups->first_triangle.back() == mesh.triangle_count(),
        "groups cover the mesh");
    impl->first_triangle = groups->first_triangle;
    impl->groups_per_scene =
        groups->groups_per_scene > 0 ? std::min(groups->groups_per_scene, 32) : kGroupsPerSceneDefault;
  } else {
    impl->first_triangle = {0, static_cast<std::uint32_t>(mesh.triangle_count())};
    impl->groups_per_scene = 1;
  }
  impl->device = rtcNewDevice(nullptr);
  if (!impl->device) return Status::internal("cannot create an Embree device: " + take_embree_error());
  rtcSetDeviceErrorFunction(impl->device, on_embree_error, nullptr);

  const RTCBuildQuality rtc_quality = quality == BuildQuality::low    ? RTC_BUILD_QUALITY_LOW
                                      : quality == BuildQuality::high ? RTC_BUILD_QUALITY_HIGH
                                                                      : RTC_BUILD_QUALITY_MEDIUM;
  // Robust mode: the watertight intersection test. Bake rays often pass
  // exactly through shared edges of the high mesh (where its grid lines
  // up with the low one), and the fast test lets such rays slip through.
  impl->compact = memory == BvhMemory::compact ||
                  (memory == BvhMemory::automatic && mesh.triangle_count() > kCompactBvhAbove);
  const int group_count = impl->group_count();
  const int per_scene = impl->groups_per_scene;
  impl->refs.resize(static_cast<std::size_t>(group_count));
  for (int first_group = 0; first_group < group_count; first_group += per_scene) {
    RTCScene scene = rtcNewScene(impl->device);
    impl->scenes.push_back(scene);
    rtcSetSceneBuildQuality(scene, rtc_quality);
    rtcSetSceneFlags(scene, impl->compact ? RTCSceneFlags(RTC_SCENE_FLAG_ROBUST | RTC_SCENE_FLAG_COMPACT)
                                          : RTC_SCENE_FLAG_ROBUST);
    for (int g = first_group; g < std::min(group_count, first_group + per_scene); ++g) {
      const std::uint32_t first = impl->first_triangle[g];
      const std::uint32_t count = impl->first_triangle[g + 1] - first;
      RTCGeometry geometry = rtcNewGeometry(impl->device, RTC_GEOMETRY_TYPE_TRIANGLE);
      // Shared buffers: the high mesh is never copied; a group is a range of
      // its index buffer.
      rtcSetSharedGeometryBuffer(geometry, RTC_BUFFER_TYPE_VERTEX, 0, RTC_FORMAT_FLOAT3,
                                 mesh.positions.data(), 0, sizeof(glm::vec3), mesh.positions.size());
      rtcSetSharedGeometryBuffer(geometry, RTC_BUFFER_TYPE_INDEX, 0, RTC_FORMAT_UINT3, mesh.indices.data(),
                                 3 * sizeof(std::uint32_t) * first, 3 * sizeof(std::uint32_t), count);
      rtcSetGeometryBuildQuality(geometry, rtc_quality);
      // Geometry IDs are the group's place in its scene; its mask bit too.
      if (per_scene > 1) rtcSetGeometryMask(geometry, 1u << (g - first_group));
      impl->refs[g] = GeometryRef{&mesh, first};
      if (backface_filter_on) {
        rtcSetGeometryUserData(geometry, &impl->refs[g]);
        rtcSetGeometryIntersectFilterFunction(geometry, backface_filter);
      }
      rtcCommitGeometry(geometry);
      rtcAttachGeometryByID(scene, geometry, static_cast<unsigned>(g - first_group));
      rtcReleaseGeometry(geometry);
    }
    rtcCommitScene(scene);
  }
  impl->scene = impl->scenes.front();
  if (rtcGetDeviceError(impl->device) != RTC_ERROR_NONE) {
    return Status::internal("building the ray-tracing scene failed: " + take_embree_error());
  }
  out.impl_ = std::move(impl);
  return Status::ok();
}

namespace {

// Whether the banded cage's rays on triangle `tri` differ from the averaged
// cage's: it has a corner on a hard edge.
[[gnu::always_inline]] inline bool banded_triangle(const LowSurface& surface, std::int32_t tri) {
  return !surface.hard_corners.empty() && surface.hard_corners[static_cast<std::size_t>(tri)] != 0;
}

float point_segment_distance(const glm::vec3& p, const glm::vec3& a, const glm::vec3& b) {
  const glm::vec3 ab = b - a;
  const float ab2 = glm::dot(ab, ab);
  const float t = ab2 > 0.0f ? std::clamp(glm::dot(p - a, ab) / ab2, 0.0f, 1.0f) : 0.0f;
  return glm::length(p - (a + t * ab));
}

// The banded cage's (unnormalised) direction on a triangle with a hard
// corner (trace.hpp): F + w (A - F), A the averaged normal `averaged`
// interpolated at `b`, F the shading normal at hard corners and A elsewhere,
// w = smoothstep(1 - d / band) of the distance d from P to the nearest hard
// edge.
glm::vec3 banded_direction(const LowSurface& surface, std::int32_t tri, glm::vec2 b,
                           const RayOptions& options, const glm::vec3& point, const glm::vec3& averaged) {
  const std::size_t t = static_cast<std::size_t>(tri);
  const std::size_t base = 3 * t;
  const std::uint8_t hard = surface.hard_corners[t];
  glm::vec3 corner[3];
  for (int k = 0; k < 3; ++k)
    corner[k] = (hard >> k) & 1 ? surface.normal[base + k] : surface.cage_normal[base + k];
  const glm::vec3 own = interpolate_corners(corner, b);
  const float band = options.edge_band * (options.front + options.back);
  if (!(band > 0.0f)) return own;
  NMBAKE_CHECK(surface.band_reach >= band, "prepare_edge_band() for this band first");
  float nearest = band;
  for (std::uint32_t e = surface.band_first[t]; e < surface.band_first[t + 1]; ++e) {
    const std::uint32_t edge = surface.band_edges[e];
    nearest = std::min(nearest,
                       point_segment_distance(point, surface.hard_edge_a[edge], surface.hard_edge_b[edge]));
  }
  const float x = 1.0f - nearest / band;  // 1 on a hard edge, 0 a band away
  const float w = x * x * (3.0f - 2.0f * x);
  return own + w * (averaged - own);
}

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
    a = la > 0.0f ? a / la
                  : glm::normalize(face_normal(surface.position[base], surface.position[base + 1],
                                               surface.position[base + 2]) +
                                   glm::vec3(0, 0, 1e-30f));
    ray.origin = ray.surface_point;
    ray.direction = -a;
    ray.t_surface = 0.0f;
    ray.tfar = options.back;
    return ray;
  }

  const std::vector<glm::vec3>& normals =
      options.cage == CageMode::interpolated ? surface.normal : surface.cage_normal;
  glm::vec3 a = interpolate(normals, base, b);
  if (options.cage == CageMode::banded && banded_triangle(surface, tri))
    a = banded_direction(surface, tri, b, options, ray.surface_point, a);
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

float edge_band_reach(const RayOptions& options) {
  float reach = options.edge_band * (options.front + options.back);
  for (const GroupDistances& g : options.groups)
    reach = std::max(reach, options.edge_band * (g.front + g.back));
  return reach;
}

void prepare_edge_band(LowSurface& surface, float reach) {
  const std::size_t triangle_count = surface.triangle_count();
  surface.band_first.assign(triangle_count + 1, 0);
  surface.band_edges.clear();
  surface.band_reach = reach;
  const std::size_t edge_count = surface.hard_edge_a.size();
  if (surface.hard_corners.empty() || edge_count == 0) return;
  // A uniform grid over the hard edges, each entered in the cells its box
  // grown by `reach` overlaps; a triangle's candidates are the edges of the
  // cells its box overlaps whose grown box overlaps its own.
  glm::vec3 lo = surface.hard_edge_a[0], hi = lo;
  for (std::size_t e = 0; e < edge_count; ++e) {
    lo = glm::min(lo, glm::min(surface.hard_edge_a[e], surface.hard_edge_b[e]));
    hi = glm::max(hi, glm::max(surface.hard_edge_a[e], surface.hard_edge_b[e]));
  }
  lo -= glm::vec3(reach);
  hi += glm::vec3(reach);
  const glm::vec3 extent = hi - lo;
  const float largest = std::max(extent.x, std::max(extent.y, extent.z));
  const float cell = std::max({reach, largest / 48.0f, 1e-30f});
  glm::ivec3 dims;
  for (int k = 0; k < 3; ++k) dims[k] = std::clamp(static_cast<int>(extent[k] / cell) + 1, 1, 64);
  const auto cell_of = [&](const glm::vec3& p) {
    glm::ivec3 c;
    for (int k = 0; k < 3; ++k) c[k] = std::clamp(static_cast<int>((p[k] - lo[k]) / cell), 0, dims[k] - 1);
    return c;
  };
  const auto index = [&](int x, int y, int z) {
    return (static_cast<std::size_t>(z) * dims.y + y) * dims.x + x;
  };
  std::vector<std::uint32_t> count(static_cast<std::size_t>(dims.x) * dims.y * dims.z + 1, 0);
  std::vector<std::pair<std::size_t, std::uint32_t>> entries;
  std::vector<glm::vec3> edge_lo(edge_count), edge_hi(edge_count);
  for (std::size_t e = 0; e < edge_count; ++e) {
    edge_lo[e] = glm::min(surface.hard_edge_a[e], surface.hard_edge_b[e]) - glm::vec3(reach);
    edge_hi[e] = glm::max(surface.hard_edge_a[e], surface.hard_edge_b[e]) + glm::vec3(reach);
    const glm::ivec3 a = cell_of(edge_lo[e]), b = cell_of(edge_hi[e]);
    for (int z = a.z; z <= b.z; ++z)
      for (int y = a.y; y <= b.y; ++y)
        for (int x = a.x; x <= b.x; ++x) entries.emplace_back(index(x, y, z), static_cast<std::uint32_t>(e));
  }
  std::sort(entries.begin(), entries.end());
  std::vector<std::uint32_t> cell_first(count.size(), 0);
  for (const auto& entry : entries) ++cell_first[entry.first + 1];
  for (std::size_t c = 1; c < cell_first.size(); ++c) cell_first[c] += cell_first[c - 1];
  std::vector<std::uint32_t> candidates;
  for (std::size_t t = 0; t < triangle_count; ++t) {
    surface.band_first[t] = static_cast<std::uint32_t>(surface.band_edges.size());
    if (surface.hard_corners[t] == 0) continue;
    const glm::vec3& p0 = surface.position[3 * t];
    const glm::vec3& p1 = surface.position[3 * t + 1];
    const glm::vec3& p2 = surface.position[3 * t + 2];
    const glm::vec3 tlo = glm::min(p0, glm::min(p1, p2)), thi = glm::max(p0, glm::max(p1, p2));
    const glm::ivec3 a = cell_of(tlo), b = cell_of(thi);
    candidates.clear();
    for (int z = a.z; z <= b.z; ++z)
      for (int y = a.y; y <= b.y; ++y)
        for (int x = a.x; x <= b.x; ++x) {
          const std::size_t c = index(x, y, z);
          for (std::uint32_t i = cell_first[c]; i < cell_first[c + 1]; ++i) {
            const std::uint32_t e = entries[i].second;
            if (glm::all(glm::lessThanEqual(edge_lo[e], thi)) &&
                glm::all(glm::lessThanEqual(tlo, edge_hi[e])))
              candidates.push_back(e);
          }
        }
    std::sort(candidates.begin(), candidates.end());
    candidates.erase(std::unique(candidates.begin(), candidates.end()), candidates.end());
    surface.band_edges.insert(surface.band_edges.end(), candidates.begin(), candidates.end());
  }
  surface.band_first[triangle_count] = static_cast<std::uint32_t>(surface.band_edges.size());
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

// False (the lane left invalid: a miss) for a ray Embree would not take.
bool add_ray(Packet& p, std::size_t sample, const glm::vec3& origin, const glm::vec3& direction, float tfar,
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
  p.valid[i] = embree_accepts(origin, direction, tfar) ? -1 : 0;
  p.sample[i] = sample;
  p.t_surface[i] = t_surface;
  p.sign[i] = sign;
  return p.valid[i] != 0;
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

// Queues samples first .. first + M - 1 (M <= free lanes), all with a
// triangle: the arrays are copied in one go.
template <int M>
[[gnu::always_inline]] inline void queue_run(Packet& p, std::size_t first, const std::int32_t* tri,
                                             const glm::vec2* bary) {
  const int c = p.count;
  std::memcpy(p.triangle + c, tri, M * sizeof *tri);
  std::memcpy(p.bary + c, bary, M * sizeof *bary);
  for (int k = 0; k < M; ++k) p.sample[c + k] = first + static_cast<std::size_t>(k);
  p.count = c + M;
}

// Queues the samples of the texel whose first sample is `first` that have a
// triangle, in pattern order, one at a time as queue_sample() would: `full`
// gets the packet whenever it is full before a sample goes in (it must
// empty it), `empty` each sample without a triangle. A whole texel (or, at
// 64 spp, a packet's worth of one) whose samples all have a triangle is
// copied in one go by queue_run(): every texel but those on chart borders.
// trace() and trace_raw() both queue through it, so their packets are the
// same.
template <class Full, class Empty>
[[gnu::always_inline]] inline void queue_texel(Packet& p, const TexelSamples& samples, std::size_t first,
                                               Full&& full, Empty&& empty) {
  const int spp = samples.samples;
  const std::int32_t* tri = samples.triangle.data() + first;
  const glm::vec2* bary = samples.bary.data() + first;
  int k = 0;
  while (k < spp) {
    if (p.count == kPacket) full();
    const int m = std::min(kPacket - p.count, spp - k);
    std::int32_t any_negative = 0;
    for (int j = 0; j < m; ++j) any_negative |= tri[k + j];
    if (any_negative >= 0 && (m == 1 || m == 4 || m == 16)) {  // whole texels of 1, 4 or 16 samples
      const std::size_t s = first + static_cast<std::size_t>(k);
      if (m == 1) queue_run<1>(p, s, tri + k, bary + k);
      if (m == 4) queue_run<4>(p, s, tri + k, bary + k);
      if (m == 16) queue_run<16>(p, s, tri + k, bary + k);
      k += m;
      continue;
    }
    for (const int end = k + m; k < end; ++k) {
      if (tri[k] < 0) {
        empty(first + static_cast<std::size_t>(k));
      } else {
        queue_sample(p, first + static_cast<std::size_t>(k), tri[k], bary[k]);
      }
    }
  }
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

// f(first sample of the texel), texel by texel.
template <class F>
[[gnu::always_inline]] inline void for_each_texel_in_trace_order(const TexelSamples& samples,
                                                                 const TileRect& t, F&& f) {
  const std::size_t spp = static_cast<std::size_t>(samples.samples);
  for (int by = t.y0; by < t.y1; by += kBlock) {
    for (int bx = t.x0; bx < t.x1; bx += kBlock) {
      for (int y = by; y < std::min(by + kBlock, t.y1); ++y) {
        for (int x = bx; x < std::min(bx + kBlock, t.x1); ++x) {
          f((static_cast<std::size_t>(y) * samples.width + x) * spp);
        }
      }
    }
  }
}

// f(sample), sample by sample.
template <class F>
[[gnu::always_inline]] inline void for_each_sample_in_trace_order(const TexelSamples& samples,
                                                                  const TileRect& t, F&& f) {
  const std::size_t spp = static_cast<std::size_t>(samples.samples);
  for_each_texel_in_trace_order(samples, t, [&](std::size_t first) {
    for (std::size_t s = first; s < first + spp; ++s) f(s);
  });
}

// banded_direction() for four lanes on one triangle with a hard corner: the
// same operations per lane, in the same order (simd4.hpp), so the lanes are
// make_ray()'s bit for bit. P and A are the lanes' points and averaged
// normals.
detail::Axes banded_axes(const LowSurface& surface, std::int32_t tri, const detail::Weights& w,
                         const detail::Axes& P, const detail::Axes& A, const RayOptions& options) {
  using namespace detail;
  const std::size_t t = static_cast<std::size_t>(tri);
  const std::size_t base = 3 * t;
  const std::uint8_t hard = surface.hard_corners[t];
  glm::vec3 corner[3];
  for (int k = 0; k < 3; ++k)
    corner[k] = (hard >> k) & 1 ? surface.normal[base + k] : surface.cage_normal[base + k];
  const Axes own = mix_axes(corner, w);
  const float band = options.edge_band * (options.front + options.back);
  if (!(band > 0.0f)) return own;
  NMBAKE_CHECK(surface.band_reach >= band, "prepare_edge_band() for this band first");
  const auto blend = [](i4 mask, f4 yes, f4 no) {
    return reinterpret_cast<f4>((reinterpret_cast<i4>(yes) & mask) | (reinterpret_cast<i4>(no) & ~mask));
  };
  const f4 zero = splat4(0.0f), one = splat4(1.0f);
  f4 nearest = splat4(band);
  for (std::uint32_t e = surface.band_first[t]; e < surface.band_first[t + 1]; ++e) {
    const std::uint32_t edge = surface.band_edges[e];
    const glm::vec3 ea = surface.hard_edge_a[edge];
    const glm::vec3 ab = surface.hard_edge_b[edge] - ea;
    const float ab2 = glm::dot(ab, ab);
    const f4 px = P.x - splat4(ea.x), py = P.y - splat4(ea.y), pz = P.z - splat4(ea.z);
    f4 s = zero;
    if (ab2 > 0.0f) {
      s = (px * splat4(ab.x) + py * splat4(ab.y) + pz * splat4(ab.z)) / splat4(ab2);
      s = blend(s < zero, zero, blend(one < s, one, s));  // std::clamp(s, 0, 1)
    }
    const f4 qx = P.x - (splat4(ea.x) + s * splat4(ab.x));
    const f4 qy = P.y - (splat4(ea.y) + s * splat4(ab.y));
    const f4 qz = P.z - (splat4(ea.z) + s * splat4(ab.z));
    const f4 d = sqrt4(qx * qx + qy * qy + qz * qz);
    nearest = blend(d < nearest, d, nearest);  // std::min(nearest, d)
  }
  const f4 x = one - nearest / splat4(band);
  const f4 weight = x * x * (splat4(3.0f) - splat4(2.0f) * x);
  return {own.x + weight * (A.x - own.x), own.y + weight * (A.y - own.y), own.z + weight * (A.z - own.z),
          f4{}};
}

// Builds the queued lanes' rays four at a time in SIMD lanes, one vector per
// axis: the point and the cage normal are interpolated, then come the
// lengths, the unit normals and the origins. Four lanes on one low triangle
// (nearly all of them: at 16 spp a packet is one texel) are interpolated
// across the lanes; otherwise lane by lane, then transposed. The operations
// are build_ray()'s, in its order, so the rays are bit for bit the same; a
// lane whose normal is zero or not finite takes build_ray() and its fallback.
// Banded cage: four lanes on one triangle with a hard corner take
// banded_axes(); in a group of lanes on several triangles, those on a
// triangle with a hard corner take build_ray(). Of the other fields only
// those Embree writes (tfar, geomID) and the valid mask are set, for all 16
// lanes (lanes past the count are invalid); the rest are set once per
// packet by start_packet(). Returns the number of lanes that took the
// fallback.
std::uint64_t build_queued_rays(Packet& p, const LowSurface& surface, const RayOptions& options) {
  using namespace detail;
  const std::vector<glm::vec3>& normals =
      options.cage == CageMode::interpolated ? surface.normal : surface.cage_normal;
  // The banded cage's rays are the averaged cage's except on triangles with a
  // hard corner: a surface without hard edges never looks.
  const bool banded = options.cage == CageMode::banded && !surface.hard_corners.empty();
  RTCRay16& r = p.rayhit.ray;
  const int n = p.count;
  const f4 front = splat4(options.front);
  std::uint64_t fallbacks = 0;
  // Lanes past the count up to a multiple of four copy the last lane, so
  // every group of four is whole (their rays are built and not traced).
  for (int i = n; i < ((n + 3) & ~3); ++i) {
    p.triangle[i] = p.triangle[n - 1];
    p.bary[i] = p.bary[n - 1];
  }
  // A lane-by-lane run of lanes on one triangle loads its corners once.
  std::int32_t loaded = -1;
  Corners position, cage;
  for (int g = 0; g < n; g += 4) {
    Axes P, a;
    const i4 tri = load4i(p.triangle + g);
    const bool one_triangle = all4(tri == splat4i(tri[0]));
    if (one_triangle) {
      const std::size_t base = 3 * static_cast<std::size_t>(tri[0]);
      const Weights w = lane_weights(&p.bary[g]);
      P = mix_axes(&surface.position[base], w);
      a = mix_axes(&normals[base], w);
      if (banded && banded_triangle(surface, tri[0])) a = banded_axes(surface, tri[0], w, P, a, options);
    } else {
      f4 point[4], normal[4];
      for (int k = 0; k < 4; ++k) {
        const int i = g + k;
        if (p.triangle[i] != loaded) {
          loaded = p.triangle[i];
          const std::size_t base = 3 * static_cast<std::size_t>(loaded);
          position = load_corners(&surface.position[base]);
          cage = load_corners(&normals[base]);
        }
        point[k] = corner_mix(position, p.bary[i]);
        normal[k] = corner_mix(cage, p.bary[i]);
      }
      P = transpose(point[0], point[1], point[2], point[3]);
      a = transpose(normal[0], normal[1], normal[2], normal[3]);
    }
    const f4 length = sqrt4(a.x * a.x + a.y * a.y + a.z * a.z);
    i4 ok = (length > splat4(1e-12f)) & finite4(length);
    if (banded && !one_triangle) {
      // Lanes of several triangles, some with a hard corner: build_ray's banded direction.
      for (int k = 0; k < 4; ++k) ok[k] = banded_triangle(surface, p.triangle[g + k]) ? 0 : ok[k];
    }
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
    const bool accepted = i < n && embree_accepts(glm::vec3(r.org_x[i], r.org_y[i], r.org_z[i]),
                                                  glm::vec3(r.dir_x[i], r.dir_y[i], r.dir_z[i]), tfar);
    fallbacks += i < n && !accepted ? 1 : 0;  // not traced: a miss
    p.valid[i] = accepted ? -1 : 0;
  }
  return fallbacks;
}

// Writes a traced queued packet's first hits to the sample arrays (-1 for a
// miss, whose bary and distance are left 0) and returns the number of hits.
// Four lanes that hold consecutive samples, as they mostly do (a texel's
// samples, or a row of a 4 x 4 texel block at 1 spp), are written at once.
// A returned packet of two-ray samples (`nearest`, and the retry of misses):
// per sample the hit nearer the low surface is kept (a tie goes to the one
// outside), over what the sample holds; `always` keeps every hit (first hit:
// one ray a sample). `first_triangle`: the mesh's first triangle of each of
// the packet scene's geometries.
void keep_nearer_hits(const Packet& p, const std::uint32_t* first_triangle, bool always, Hits& hits) {
  for (int i = 0; i < p.count; ++i) {
    const std::size_t s = p.sample[i];
    const unsigned geometry = p.rayhit.hit.geomID[i];
    if (geometry == RTC_INVALID_GEOMETRY_ID) continue;
    const float distance = p.sign[i] * (p.t_surface[i] - p.rayhit.ray.tfar[i]);
    const bool better = hits.triangle[s] < 0 || std::fabs(distance) < std::fabs(hits.distance[s]) ||
                        (std::fabs(distance) == std::fabs(hits.distance[s]) && distance > hits.distance[s]);
    if (always || better) {
      // The hit's triangle in the mesh: its group's range + Embree's primID.
      hits.triangle[s] = static_cast<std::int32_t>(first_triangle[geometry] + p.rayhit.hit.primID[i]);
      hits.bary[s] = glm::vec2(p.rayhit.hit.u[i], p.rayhit.hit.v[i]);
      hits.distance[s] = distance;
    }
  }
}

std::uint64_t store_first_hits(const Packet& p, float front, Hits& hits) {
  using namespace detail;
  const RTCHit16& h = p.rayhit.hit;
  const int n = p.count;
  std::uint64_t hit_count = 0;
  const auto store_one = [&](int i) {
    const std::size_t s = p.sample[i];
    const bool hit = h.geomID[i] != RTC_INVALID_GEOMETRY_ID;
    hits.triangle[s] = hit ? static_cast<std::int32_t>(h.primID[i]) : -1;
    hits.bary[s] = hit ? glm::vec2(h.u[i], h.v[i]) : glm::vec2(0.0f);
    hits.distance[s] = hit ? front - p.rayhit.ray.tfar[i] : 0.0f;
    hit_count += hit ? 1 : 0;
  };
  int i = 0;
  for (; i + 4 <= n; i += 4) {
    const std::size_t s = p.sample[i];
    if (p.sample[i + 1] != s + 1 || p.sample[i + 2] != s + 2 || p.sample[i + 3] != s + 3) {
      for (int k = i; k < i + 4; ++k) store_one(k);
      continue;
    }
    const i4 hit = load4i(h.geomID + i) != splat4i(static_cast<std::int32_t>(RTC_INVALID_GEOMETRY_ID));
    store4i(hits.triangle.data() + s, load4i(h.primID + i) | ~hit);  // a miss: all bits set, -1
    const f4 u = select4(hit, load4(h.u + i)), v = select4(hit, load4(h.v + i));
    float* bary = &hits.bary[s].x;
    store4(bary, __builtin_shuffle(u, v, i4{0, 4, 1, 5}));
    store4(bary + 4, __builtin_shuffle(u, v, i4{2, 6, 3, 7}));
    store4(hits.distance.data() + s, select4(hit, splat4(front) - load4(p.rayhit.ray.tfar + i)));
    hit_count += static_cast<std::uint64_t>(count4(hit));
  }
  for (; i < n; ++i) store_one(i);
  return hit_count;
}

}  // namespace

void trace(const HighScene& scene, const LowSurface& surface, const TexelSamples& samples,
           const RayOptions& options, Hits& hits, TraceStats& stats,
           const std::function<void(double)>& progress) {
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
  const HighScene::Impl& impl = *scene.impl();
  RTCScene rtc_scene = impl.scene;
  // Bake groups: each sample's ray gets its group's distances and mask bit,
  // and a packet holds the rays of one scene only.
  const int group_count = impl.group_count();
  const bool grouped = group_count > 1;
  const int per_scene = impl.groups_per_scene;
  std::vector<RayOptions> group_options;
  if (grouped) {
    NMBAKE_CHECK(surface.group.size() == surface.triangle_count(), "a group per low triangle");
    NMBAKE_CHECK(options.groups.size() == static_cast<std::size_t>(group_count), "distances per group");
    group_options.assign(static_cast<std::size_t>(group_count), options);
    for (int g = 0; g < group_count; ++g) {
      group_options[g].groups.clear();
      group_options[g].front = options.groups[g].front;
      group_options[g].back = options.groups[g].back;
    }
  }

  struct TileCounts {
    std::uint64_t rays = 0, samples = 0, hits = 0, misses = 0, fallbacks = 0, retried = 0, retry_hits = 0;
  };
  std::vector<TileCounts> tile_counts(tile_count);

  auto trace_tile = [&](int tile) {
    TileCounts& counts = tile_counts[tile];
    const TileRect rect = tile_rect(samples, tile, tiles_x);

    RTCIntersectContext context;
    rtcInitIntersectContext(&context);
    context.flags = RTC_INTERSECT_CONTEXT_FLAG_COHERENT;
    Packet packet;
    const bool queued = !grouped && batched_rays(options);
    start_packet(packet, queued);
    int packet_scene = 0;

    // Every sample of the tile that found nothing is traced once more (the
    // retry, trace.hpp), in trace order: two rays from P along its ray's
    // line, out and in up to retry_reach, the hit nearer to P kept.
    auto retry = [&]() {
      if (!(options.retry_reach > 0.0f) || counts.misses == 0) return;
      Packet again;
      reset_packet(again);
      int again_scene = 0;
      std::vector<std::size_t> retried;
      auto flush = [&]() {
        if (again.count == 0) return;
        rtcIntersect16(again.valid, impl.scenes[again_scene], &context, &again.rayhit);
        counts.rays += static_cast<std::uint64_t>(again.count);
        keep_nearer_hits(again, &impl.first_triangle[static_cast<std::size_t>(again_scene * per_scene)],
                         false, hits);
        reset_packet(again);
      };
      for_each_sample_in_trace_order(samples, rect, [&](std::size_t s) {
        const std::int32_t tri = samples.triangle[s];
        if (tri < 0 || hits.triangle[s] >= 0) return;
        const RayOptions* ray_options = &options;
        unsigned mask = 0xffffffffu;
        if (grouped) {
          const std::uint32_t g = surface.group[static_cast<std::size_t>(tri)];
          ray_options = &group_options[g];
          const int scene_index = static_cast<int>(g) / per_scene;
          if (per_scene > 1) mask = 1u << (static_cast<int>(g) % per_scene);
          if (scene_index != again_scene) flush();
          again_scene = scene_index;
        }
        bool fallback = false;  // counted when the sample was first traced
        const Ray ray = build_ray(surface, tri, samples.bary[s], *ray_options, fallback);
        if (again.count > kPacket - 2) flush();
        add_ray(again, s, ray.surface_point, -ray.direction, options.retry_reach, 0.0f, -1.0f);
        add_ray(again, s, ray.surface_point, ray.direction, options.retry_reach, 0.0f, 1.0f);
        again.rayhit.ray.mask[again.count - 2] = mask;
        again.rayhit.ray.mask[again.count - 1] = mask;
        retried.push_back(s);
      });
      flush();
      counts.retried += retried.size();
      for (const std::size_t s : retried) counts.retry_hits += hits.triangle[s] >= 0 ? 1 : 0;
    };

    // The common case (first hit, rays queued and built together): each
    // sample's result is written once, -1 for no sample or a miss, and the
    // hits are counted as the packets come back.
    if (queued) {
      auto flush = [&]() {
        if (packet.count == 0) return;
        counts.fallbacks += build_queued_rays(packet, surface, options);
        rtcIntersect16(packet.valid, rtc_scene, &context, &packet.rayhit);
        counts.rays += static_cast<std::uint64_t>(packet.count);
        counts.hits += store_first_hits(packet, options.front, hits);
        packet.count = 0;
      };
      for_each_texel_in_trace_order(samples, rect, [&](std::size_t first) {
        queue_texel(packet, samples, first, flush, [&](std::size_t s) { hits.triangle[s] = -1; });
      });
      flush();
      counts.samples = counts.rays;
      counts.misses = counts.samples - counts.hits;
      retry();
      counts.hits += counts.retry_hits;
      counts.misses -= counts.retry_hits;
      return;
    }

    // `nearest` keeps per sample the best of two rays; a packet holds both
    // rays of up to 8 samples, so the best is settled inside one flush.
    auto flush = [&]() {
      if (packet.count == 0) return;
      rtcIntersect16(packet.valid, impl.scenes[packet_scene], &context, &packet.rayhit);
      counts.rays += static_cast<std::uint64_t>(packet.count);
      keep_nearer_hits(packet, &impl.first_triangle[static_cast<std::size_t>(packet_scene * per_scene)],
                       options.hit == HitRule::first, hits);
      reset_packet(packet);
    };

    for_each_sample_in_trace_order(samples, rect, [&](std::size_t s) {
      const std::int32_t tri = samples.triangle[s];
      hits.triangle[s] = -1;
      if (tri < 0) return;
      ++counts.samples;
      const RayOptions* ray_options = &options;
      unsigned mask = 0xffffffffu;
      if (grouped) {
        const std::uint32_t g = surface.group[static_cast<std::size_t>(tri)];
        ray_options = &group_options[g];
        const int scene_index = static_cast<int>(g) / per_scene;
        if (per_scene > 1) mask = 1u << (static_cast<int>(g) % per_scene);
        if (scene_index != packet_scene) flush();
        packet_scene = scene_index;
      }
      bool fallback = false;
      const Ray ray = build_ray(surface, tri, samples.bary[s], *ray_options, fallback);
      counts.fallbacks += fallback ? 1 : 0;
      // A ray Embree would not take is not traced (add_ray): a miss, counted.
      if (options.hit == HitRule::first) {
        if (packet.count == kPacket) flush();
        counts.fallbacks +=
            add_ray(packet, s, ray.origin, ray.direction, ray.tfar, ray.t_surface, 1.0f) ? 0 : 1;
        packet.rayhit.ray.mask[packet.count - 1] = mask;
      } else {
        if (packet.count > kPacket - 2) flush();
        // Outwards from P up to the cage, and inwards up to `back`.
        counts.fallbacks +=
            add_ray(packet, s, ray.surface_point, -ray.direction, ray.t_surface, 0.0f, -1.0f) ? 0 : 1;
        counts.fallbacks +=
            add_ray(packet, s, ray.surface_point, ray.direction, ray.tfar - ray.t_surface, 0.0f, 1.0f) ? 0
                                                                                                       : 1;
        packet.rayhit.ray.mask[packet.count - 2] = mask;
        packet.rayhit.ray.mask[packet.count - 1] = mask;
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
    retry();
    counts.hits += counts.retry_hits;
    counts.misses -= counts.retry_hits;
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
    stats.retried += c.retried;
    stats.retry_hits += c.retry_hits;
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

  const float reach = kProbeReach * diagonal;
  RayOptions options;
  options.cage = CageMode::averaged;
  const HighScene::Impl& impl = *scene.impl();
  const int group_count = impl.group_count();
  const bool grouped = group_count > 1;
  const int per_scene = impl.groups_per_scene;
  if (grouped) NMBAKE_CHECK(surface.group.size() == triangle_count, "a group per low triangle");

  tbb::parallel_for(std::size_t{0}, triangle_count, [&](std::size_t t) {
    RTCIntersectContext context;
    rtcInitIntersectContext(&context);
    // A probe sees only its own group's high triangles.
    const int g = grouped ? static_cast<int>(surface.group[t]) : 0;
    RTCScene rtc_scene = impl.scenes[g / per_scene];
    const unsigned mask = per_scene > 1 ? 1u << (g % per_scene) : 0xffffffffu;
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
        if (!embree_accepts(ray.surface_point, dir, reach)) continue;      // not traced: a probe miss
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
        rh.ray.mask = mask;
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

  // A high quantile rather than the maximum: one stray probe that found a
  // far surface must not stretch every ray of the bake.
  auto quantile = [](std::vector<float>& v, double q) {
    if (v.empty()) return 0.0f;
    const std::size_t k = std::min(v.size() - 1, static_cast<std::size_t>(q * static_cast<double>(v.size())));
    std::nth_element(v.begin(), v.begin() + static_cast<std::ptrdiff_t>(k), v.end());
    return v[k];
  };
  const float floor_distance = 0.002f * diagonal;
  // One pass over the probes, in probe order: the outside and inside
  // distances of all probes and of each group's.
  const std::size_t lists = grouped ? static_cast<std::size_t>(group_count) + 1 : 1;
  std::vector<std::vector<float>> outside(lists), inside(lists);
  DistanceEstimate e;
  e.probes = probe_count;
  for (std::size_t t = 0; t < triangle_count; ++t) {
    const std::size_t g = grouped ? surface.group[t] + std::size_t{1} : 0;
    for (std::uint32_t p = first_probe[t]; p < first_probe[t + 1]; ++p) {
      if (!found[p]) {
        ++e.probe_misses;
        continue;
      }
      const bool out = signed_distance[p] >= 0.0f;
      const float d = out ? signed_distance[p] : -signed_distance[p];
      (out ? outside : inside)[0].push_back(d);
      if (g > 0) (out ? outside : inside)[g].push_back(d);
    }
  }
  const auto estimate = [&](std::size_t list, GroupDistances& d) {
    d.front = std::max(floor_distance, 1.25f * quantile(outside[list], 0.995) + floor_distance);
    d.back = std::max(floor_distance, 1.25f * quantile(inside[list], 0.995) + floor_distance);
  };
  GroupDistances all;
  estimate(0, all);
  e.front = all.front;
  e.back = all.back;
  // One entry per group of the scene, always: a scene of one group (one low
  // part matched while other high parts are left out) is traced like an
  // ungrouped one, and its group's estimate is that of all probes. It once
  // got no entry, and the bake read past the empty list (SIGSEGV).
  e.groups.resize(static_cast<std::size_t>(group_count));
  for (std::size_t g = 0; g < e.groups.size(); ++g) {
    if (grouped) {
      estimate(g + 1, e.groups[g]);
    } else {
      e.groups[g] = all;
    }
  }
  return e;
}

}  // namespace nmbake

namespace nmbake {

namespace {

// A tile's packets as trace() fires them, rays built: queued and built
// together where trace() does so, one by one where it does not.
void build_tile_packets(const LowSurface& surface, const TexelSamples& samples, const RayOptions& options,
                        const TileRect& rect, std::vector<Packet>& packets) {
  const bool batched = batched_rays(options);
  Packet current;
  start_packet(current, batched);
  const auto keep = [&]() {
    if (batched) build_queued_rays(current, surface, options);
    packets.push_back(current);
    start_packet(current, batched);
  };
  if (batched) {
    for_each_texel_in_trace_order(samples, rect, [&](std::size_t first) {
      queue_texel(current, samples, first, keep, [](std::size_t) {});
    });
  } else {
    for_each_sample_in_trace_order(samples, rect, [&](std::size_t s) {
      if (samples.triangle[s] < 0) return;
      if (current.count == kPacket) keep();
      bool fallback = false;
      const Ray ray = build_ray(surface, samples.triangle[s], samples.bary[s], options, fallback);
      add_ray(current, s, ray.origin, ray.direction, ray.tfar, ray.t_surface, 1.0f);
    });
  }
  if (current.count > 0) keep();
}

}  // namespace

RawTraceResult trace_raw(const HighScene& scene, const LowSurface& surface, const TexelSamples& samples,
                         const RayOptions& options) {
  NMBAKE_CHECK(scene.impl() != nullptr, "scene built");
  NMBAKE_CHECK(options.hit == HitRule::first, "the raw baseline measures first-hit rays");
  // The same rays in the same packets as trace(): the same tiles, walked in
  // the same order and queued by the same code (for_each_texel_in_trace_order,
  // queue_texel). They are built before the clock starts, so only Embree is
  // timed.
  const int tiles_x = (samples.width + kTile - 1) / kTile;
  const int tiles_y = (samples.height + kTile - 1) / kTile;
  std::vector<std::vector<Packet>> tile_packets(static_cast<std::size_t>(tiles_x) * tiles_y);
  tbb::parallel_for(0, tiles_x * tiles_y, [&](int tile) {
    build_tile_packets(surface, samples, options, tile_rect(samples, tile, tiles_x),
                       tile_packets[static_cast<std::size_t>(tile)]);
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

std::vector<PacketRay> packet_rays(const LowSurface& surface, const TexelSamples& samples,
                                   const RayOptions& options) {
  NMBAKE_CHECK(options.hit == HitRule::first, "first-hit rays");
  std::vector<PacketRay> rays(samples.sample_count());
  const int tiles_x = (samples.width + kTile - 1) / kTile;
  const int tiles_y = (samples.height + kTile - 1) / kTile;
  std::vector<Packet> packets;
  for (int tile = 0; tile < tiles_x * tiles_y; ++tile) {
    packets.clear();
    build_tile_packets(surface, samples, options, tile_rect(samples, tile, tiles_x), packets);
    for (const Packet& p : packets) {
      const RTCRay16& r = p.rayhit.ray;
      for (int i = 0; i < p.count; ++i) {
        PacketRay& out = rays[p.sample[i]];
        out.traced = p.valid[i] == -1;
        out.origin = glm::vec3(r.org_x[i], r.org_y[i], r.org_z[i]);
        out.direction = glm::vec3(r.dir_x[i], r.dir_y[i], r.dir_z[i]);
        out.tnear = r.tnear[i];
        out.tfar = r.tfar[i];
      }
    }
  }
  return rays;
}

std::string embree_version() {
  RTCDevice device = rtcNewDevice("verbose=0");
  if (!device) return "unknown (no Embree device)";
  const long long version = static_cast<long long>(rtcGetDeviceProperty(device, RTC_DEVICE_PROPERTY_VERSION));
  rtcReleaseDevice(device);
  return std::to_string(version / 10000) + "." + std::to_string(version / 100 % 100) + "." +
         std::to_string(version % 100);
}

}  // namespace nmbake
