// Stage "trace": rays from the cage to the high mesh through Embree 3.
//
// Where a ray is built: make_ray() below, the one place. For every sample the
// ray starts on the cage and points at the low surface (DESIGN.md, "Rays"):
//   * banded cage (default): the averaged cage near hard edges, the low
//     mesh's own normals away from them. Origin = P + front * D, direction
//     = -D, D = normalize(F + w (A - F)), where P is the low surface point, A
//     the barycentrically interpolated averaged normal and F the same
//     interpolation of A at smooth corners and of the shading normal at
//     corners on a hard edge (split normals); w = smoothstep(1 - d / band)
//     with d the distance from P to the nearest hard edge and band =
//     edge_band * (front + back). At a hard edge D = A on both sides (no gap
//     opens, as with the averaged cage); a band's width from it D is the
//     shading normal (no skew: the averaged normal, interpolated across a
//     whole triangle, slants the rays over the flat face beside a hard edge
//     and moves a bevel's normals to the wrong texels). On a triangle with no
//     hard corner F = A: the averaged cage's rays, bit for bit. Needs
//     prepare_edge_band() first;
//   * averaged cage: origin = P + front * A, direction = -A; the ray
//     searches [0, front + back];
//   * interpolated cage: the same with the low shading normal instead of A
//     (kept for the method comparison; it opens gaps at hard edges);
//   * cage mesh: origin = the cage point with the same barycentrics,
//     direction towards P, searching up to |P - origin| + back.
// Hit rules: `first` keeps the first hit from the cage; `nearest` keeps the
// hit nearest to the low surface point P (two rays from P, outwards up to the
// cage and inwards up to back, the nearer hit wins).
// Retry (RayOptions::retry_reach > 0): a sample whose ray (or rays) found
// nothing is traced once more, from P along the same line, outwards and
// inwards up to retry_reach each (the distance probes' reach); the hit
// nearer to P wins. Counted in TraceStats (retried, retry_hits).
//
// Bake groups (parts.hpp): a scene built with SceneGroups holds group g's
// high triangles as [first[g], first[g + 1]) of its mesh, and a ray of a low
// triangle of group LowSurface::group[t] can hit only those: up to
// groups_per_scene groups share one BVH, each group a geometry with its own
// Embree ray-mask bit, and further groups get further scenes (a packet never
// mixes scenes). Each group has its own ray distances (RayOptions::groups).
//
// Embree's types stay in trace.cpp (and trace_occlusion.cpp, which casts the
// map set's rays from the hits: occlusion.hpp); HighScene is a move-only
// handle.
#pragma once

#include <cstdint>
#include <functional>
#include <glm/vec2.hpp>
#include <glm/vec3.hpp>
#include <memory>
#include <string>
#include <vector>

#include "nmbake/common.hpp"
#include "nmbake/mesh.hpp"
#include "nmbake/raster.hpp"
#include "nmbake/surface.hpp"
#include "nmbake/words.hpp"

namespace nmbake {

enum class CageMode : std::uint8_t { averaged, interpolated, mesh, banded };
inline constexpr Word<CageMode> kCageModeWords[] = {
    {"banded", CageMode::banded, "averaged normals near hard edges, shading normals elsewhere"},
    {"averaged", CageMode::averaged, "pushed out along averaged normals (hard edges do not open gaps)"},
    {"interpolated", CageMode::interpolated, "pushed out along the shading normals"},
    {"mesh", CageMode::mesh, "a cage mesh was given", WordUse::reported},
};
NMBAKE_WORDS(CageMode, kCageModeWords)

enum class HitRule : std::uint8_t { first, nearest };
inline constexpr Word<HitRule> kHitRuleWords[] = {
    {"first", HitRule::first, "the first hit from the cage"},
    {"nearest", HitRule::nearest, "the hit nearest to the low surface"},
};
NMBAKE_WORDS(HitRule, kHitRuleWords)

enum class BuildQuality : std::uint8_t { low, medium, high };
inline constexpr Word<BuildQuality> kBuildQualityWords[] = {
    {"low", BuildQuality::low, "fastest build; rays as fast (BENCHMARKS.md)"},
    {"medium", BuildQuality::medium, "Embree's default build"},
    {"high", BuildQuality::high, "spatial splits; never traced faster here"},
};
NMBAKE_WORDS(BuildQuality, kBuildQualityWords)

// BVH layout: `fast` lets Embree copy each leaf's triangle vertices into the
// BVH (triangle4v); `compact` keeps only indices into the shared vertex
// buffer: about a third of the BVH's memory, rays ~20% slower (measured in
// BENCHMARKS.md); `automatic` is compact above kCompactBvhAbove triangles.
enum class BvhMemory : std::uint8_t { automatic, fast, compact };
inline constexpr Word<BvhMemory> kBvhMemoryWords[] = {
    {"auto", BvhMemory::automatic, "compact above 16M high triangles"},
    {"fast", BvhMemory::fast, "triangle vertices copied into the BVH"},
    {"compact", BvhMemory::compact, "indices only: a third of the memory, rays ~20% slower"},
};
NMBAKE_WORDS(BvhMemory, kBvhMemoryWords)
constexpr std::size_t kCompactBvhAbove = 16'000'000;

// A ray distance as the user gave it: scene units, percent of the low mesh's
// bounding-box diagonal, or estimated from the meshes.
struct Distance {
  enum class Kind : std::uint8_t { automatic, absolute, percent };
  Kind kind = Kind::automatic;
  float value = 0.0f;
};
// Limits of a ray distance (README, "Limits"): front and back are each at
// most kMaxDistance scene units and at most kMaxDistanceDiagonals times the
// low mesh's bounding-box diagonal. With kMaxCoordinate (mesh.hpp) this keeps
// every ray origin and range finite and far inside what Embree accepts
// (1.8e18); a longer ray could only find surfaces the low mesh does not bake.
constexpr float kMaxDistance = 1e12f;
constexpr float kMaxDistanceDiagonals = 1000.0f;

// "auto", "0.05", "2%". Returns false on anything else (negative, NaN, junk).
bool parse_distance(const std::string& text, Distance& out);
std::string to_string(const Distance& distance);
// In scene units: as given, a percentage of `diagonal` (the low mesh's
// bounding-box diagonal), or `automatic_value` when auto.
float resolve_distance(const Distance& distance, float diagonal, float automatic_value);

// Whether a ray that missed is traced again, out and in up to kProbeReach:
// `automatic` when neither distance nor a cage is given.
enum class RetryMisses : std::uint8_t { automatic, on, off };
inline constexpr Word<RetryMisses> kRetryMissesWords[] = {
    {"auto", RetryMisses::automatic, "when no distance or cage is given"},
    {"on", RetryMisses::on, "always"},
    {"off", RetryMisses::off, "never"},
};
NMBAKE_WORDS(RetryMisses, kRetryMissesWords)

struct GroupDistances {
  float front = 0.0f;
  float back = 0.0f;
};

// The banded cage's band around hard edges, in units of front + back:
// measured in the accuracy lab (README, "Accuracy lab").
constexpr float kDefaultEdgeBand = 2.0f;
// How far the distance probes look, and a retried ray, each way: a share of
// the low mesh's bounding-box diagonal.
constexpr float kProbeReach = 0.25f;

// The rays as resolved for a scene (resolve_rays() below, or by hand).
struct RayOptions {
  // `averaged`, not the bake's `banded` (RaySettings): the trace tests, the
  // evaluators of tools/gen and the distance probes build RayOptions by hand
  // and rely on the averaged cage, which needs no prepare_edge_band().
  CageMode cage = CageMode::averaged;
  float edge_band = kDefaultEdgeBand;  // CageMode::banded: the band's width / (front + back)
  float retry_reach = 0.0f;            // > 0: retry a sample that missed (see above), scene units
  HitRule hit = HitRule::first;
  float front = 0.0f;  // scene units, already resolved from % / auto
  float back = 0.0f;
  bool ignore_backfaces = false;  // skip hits on high triangles facing along the ray
  // With a grouped scene: the distances of each group (front and back above
  // are then unused); empty otherwise.
  std::vector<GroupDistances> groups;
};

// The rays as asked for (BakeOptions::rays, PreviewOptions::rays), one
// default per field, here; resolve_rays() turns them into RayOptions.
struct RaySettings {
  Distance front;  // auto
  Distance back;   // auto
  HitRule hit = HitRule::first;
  CageMode cage_mode = CageMode::banded;  // `mesh` is implied by a cage mesh (LowSurface::has_cage_mesh)
  float edge_band = kDefaultEdgeBand;     // the banded cage's band, in units of front + back
  // Misses traced again out and in up to the distance probes' reach
  // (kProbeReach): `automatic` = when neither distance nor a cage is given.
  RetryMisses retry_misses = RetryMisses::automatic;
  bool ignore_backfaces = false;  // also the scene's backface filter (HighScene::build)

  // Whether resolve_rays() probes the meshes (a distance is auto).
  bool estimates_distances() const {
    return front.kind == Distance::Kind::automatic || back.kind == Distance::Kind::automatic;
  }
};

// How a scene holds bake groups (see above).
struct SceneGroups {
  std::vector<std::uint32_t> first_triangle;  // group count + 1 entries, ascending, last = triangle count
  // Groups told apart by ray masks in one BVH: 1 (a scene per group) to 32;
  // 0: automatic (the measured choice, BENCHMARKS.md).
  int groups_per_scene = 0;
};

struct Ray {
  glm::vec3 origin{0.0f};
  glm::vec3 direction{0.0f, 0.0f, -1.0f};  // unit
  float tfar = 0.0f;
  glm::vec3 surface_point{0.0f};  // P: where the ray crosses the low surface (t = distance to P)
  float t_surface = 0.0f;
};

// CageMode::banded needs, per low triangle with a hard corner, the hard
// edges within reach of it: prepare_edge_band() finds them for rays whose
// band (edge_band * (front + back), every group's) is at most `reach`;
// edge_band_reach() is that largest band of `options`.
float edge_band_reach(const RayOptions& options);
void prepare_edge_band(LowSurface& surface, float reach);

// Builds the ray of one sample on triangle `tri` at barycentrics `b`
// (weights of corners 1 and 2). Counted fallback: a zero-length interpolated
// normal uses the triangle's face normal (`used_fallback` set).
Ray make_ray(const LowSurface& surface, std::int32_t tri, glm::vec2 b, const RayOptions& options,
             bool& used_fallback);

// An Embree device + scene over a high mesh's shared buffers. The mesh must
// outlive the scene and must not be modified while the scene exists.
class HighScene {
 public:
  HighScene();
  ~HighScene();
  HighScene(HighScene&&) noexcept;
  HighScene& operator=(HighScene&&) noexcept;
  HighScene(const HighScene&) = delete;
  HighScene& operator=(const HighScene&) = delete;

  // Builds the BVH. `mesh` positions must be padded (pad_for_embree).
  static Status build(const Mesh& mesh, BuildQuality quality, bool backface_filter, HighScene& out,
                      BvhMemory memory = BvhMemory::automatic, const SceneGroups* groups = nullptr);
  // Whether the built BVH is the compact layout (automatic resolved).
  bool compact() const;
  // Bake groups held (1 without SceneGroups) and Embree scenes built for them.
  int group_count() const;
  int scene_count() const;

  struct Impl;
  Impl* impl() const { return impl_.get(); }

 private:
  std::unique_ptr<Impl> impl_;
};

// One hit per sample (same indexing as TexelSamples).
struct Hits {
  std::vector<std::int32_t> triangle;  // high triangle, -1 = miss or no sample
  std::vector<glm::vec2> bary;         // Embree's (u, v): weights of corners 1 and 2
  std::vector<float> distance;         // signed distance from the low surface along the outward normal
};

struct TraceStats {
  std::uint64_t rays = 0;     // Embree queries issued
  std::uint64_t samples = 0;  // samples traced (a `nearest` sample issues two rays)
  std::uint64_t hits = 0;
  std::uint64_t misses = 0;
  // Zero-length interpolated normal: face normal used; or a ray Embree would
  // not take (a component beyond 1.8e18 or not finite): not traced, a miss.
  std::uint64_t ray_fallbacks = 0;
  std::uint64_t retried = 0;     // samples traced again after a miss (retry_reach)
  std::uint64_t retry_hits = 0;  // of those, found a surface (counted in hits, not in misses)
};

// Traces every sample with triangle >= 0. Parallel over tiles of texels;
// the result does not depend on the thread count. `progress` (may be empty)
// is called from the calling thread with the fraction done.
// A grouped scene needs surface.group (one per low triangle, < group count)
// and options.groups (one per group).
void trace(const HighScene& scene, const LowSurface& surface, const TexelSamples& samples,
           const RayOptions& options, Hits& hits, TraceStats& stats,
           const std::function<void(double)>& progress = {});

// The speed ceiling of trace(): the same first-hit rays in the same packets,
// built beforehand, and only Embree's rtcIntersect16 calls timed (no hit
// bookkeeping, no shading). For tools/bench.
struct RawTraceResult {
  std::uint64_t rays = 0;
  std::uint64_t hits = 0;
  double seconds = 0.0;
};
RawTraceResult trace_raw(const HighScene& scene, const LowSurface& surface, const TexelSamples& samples,
                         const RayOptions& options);

// The rays trace() gives Embree for first-hit rays, per sample (same
// indexing as TexelSamples; `traced` is false for samples without a
// triangle): built by trace()'s own packet code, so tests can hold them to
// make_ray() bit for bit.
struct PacketRay {
  bool traced = false;
  glm::vec3 origin{0.0f};
  glm::vec3 direction{0.0f};
  float tnear = 0.0f;
  float tfar = 0.0f;
};
std::vector<PacketRay> packet_rays(const LowSurface& surface, const TexelSamples& samples,
                                   const RayOptions& options);

// Ray distances found by probing: rays from fixed points of every low
// triangle, outwards and inwards along the averaged normal, find how far the
// high surface lies outside (front) and inside (back) the low one.
struct DistanceEstimate {
  float front = 0.0f;
  float back = 0.0f;
  // Per group of the scene (one entry for an ungrouped scene or a scene of
  // one group: the estimate over all probes), from that group's probes alone
  // (a group without a found probe gets the floor distance); front/back above
  // are the estimate over all probes.
  std::vector<GroupDistances> groups;
  std::uint64_t probes = 0;
  std::uint64_t probe_misses = 0;  // probe points with no high surface within reach
};
DistanceEstimate estimate_distances(const HighScene& scene, const LowSurface& surface, float diagonal);

// `settings` resolved into `rays` for `scene` and the low `surface` (the
// bake's and the preview's one rule):
//   * the cage: CageMode::mesh when the surface has a cage mesh, else
//     settings.cage_mode;
//   * distances: as given in scene units, a percentage of `low_diagonal`
//     (the low mesh's bounding-box diagonal), or auto: estimate_distances()
//     with `low_diagonal`, run once when either distance is auto;
//   * with `group_count` > 0 (a scene built with SceneGroups of that many
//     groups), rays.groups gets each group's distances, auto ones from that
//     group's own probes; 0: rays.groups stays empty;
//   * retry_reach = kProbeReach * low_diagonal when misses are retried (on;
//     automatic: both distances auto and no cage mesh), else 0;
//   * the banded cage: prepare_edge_band(surface) for the resolved rays.
// Returns the estimate (empty when no distance is auto) for the report.
DistanceEstimate resolve_rays(const RaySettings& settings, const HighScene& scene, LowSurface& surface,
                              float low_diagonal, std::size_t group_count, RayOptions& rays);

// The version of the Embree library in use (asked of a device: the shared
// library loaded, not the headers built against), "3.13.5".
std::string embree_version();

}  // namespace nmbake
