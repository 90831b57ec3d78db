// Rays cast from the stored hits (DESIGN.md, "A map set, one set of rays"):
// ambient occlusion (and the bent normal from the same rays) and thickness.
// The trace stage found, per sample, the high triangle and barycentrics of
// its hit (Hits); these passes start new rays there, band by band, in 16-wide
// packets, over the same 16 x 16 texel tiles as trace() and in its texel
// order. The implementation (src/trace/occlusion.cpp) shares the Embree
// scene of HighScene; Embree's types stay there.
//
// At a hit: P = the barycentric point of the high triangle, N_s = its
// interpolated shading normal (the face normal when the mesh has none or it
// is ~0: counted), N_g = the face normal turned to N_s's side.
//
// Ray origin (the "ray offset", chosen against self-occlusion acne): P moved
// off the triangle's plane along N_g (outwards for AO, inwards for
// thickness) by a few units in the last place of each coordinate (256 ulps;
// 1/65536 of N_g near the origin where ulps vanish), following Wächter and
// Binder, "A Fast and Robust Method for Avoiding Self-Intersection" (Ray
// Tracing Gems, 2019, ch. 6). The offset scales with the coordinates, so a
// scene a kilometre from the origin is as clean as one at it, and it is far
// below a texel of any map; rays then search [0, distance].
//
// Directions: a fixed low-discrepancy pattern (Hammersley points
// ((i + 0.5) / n, radical inverse of i in base 2), i < n) shifted per sample
// by a toroidal (Cranley-Patterson) offset hashed from the texel's index in
// the map and the sample's index in the texel: deterministic, the same for
// any thread count, band or tile, and with the error of neighbouring texels
// uncorrelated (noise, not bands). AO maps the points to the
// cosine-weighted hemisphere around N_s (Malley: a point of the unit disk
// lifted onto the hemisphere); a direction that points below the hit
// triangle's plane (dot(d, N_g) < 0, possible where N_s and N_g differ) is
// mirrored above it, and counted. The frame around N_s is Duff et al.,
// "Building an Orthonormal Basis, Revisited" (JCGT 2017).
//
// Bake groups: a sample's rays see only its group's high triangles (the same
// scenes and ray masks as its bake ray), so parts of other groups never
// shadow it, as Toolbag's "ignore groups".
#pragma once

#include <array>
#include <cstdint>
#include <glm/vec3.hpp>
#include <vector>

#include "nmbake/mesh.hpp"
#include "nmbake/raster.hpp"
#include "nmbake/surface.hpp"
#include "nmbake/trace.hpp"

namespace nmbake {

struct OcclusionOptions {
  int rays = 64;          // per sample: 1 .. kMaxOcclusionRays
  float distance = 1.0f;  // scene units: occluders further away do not count
  bool bent = false;      // also the mean unoccluded direction (bent normal)
};
inline constexpr int kMaxOcclusionRays = 4096;

struct OcclusionStats {
  std::uint64_t samples = 0;        // hit samples that cast rays
  std::uint64_t rays = 0;           // occlusion rays given to Embree
  std::uint64_t unoccluded = 0;     // of them, found no occluder within the distance
  std::uint64_t mirrored_rays = 0;  // pointed below the hit triangle: mirrored above it
  std::uint64_t normal_fallbacks =
      0;                            // shading normal ~0: face normal used (or the face's ~0: the low normal)
  std::uint64_t all_occluded = 0;   // bent normal: no ray escaped, N_s used
  std::uint64_t untraced_rays = 0;  // a ray Embree would not take: counted as unoccluded
};
// Its counters one by one, in this order (a tile file stores them so; a
// merge adds them up).
inline std::array<std::uint64_t*, 7> counters(OcclusionStats& s) {
  return {&s.samples,          &s.rays,         &s.unoccluded,   &s.mirrored_rays,
          &s.normal_fallbacks, &s.all_occluded, &s.untraced_rays};
}

// Per sample (TexelSamples indexing; vectors resized): the share of
// unoccluded rays, in [0, 1], for a sample whose bake ray hit, 1 for any
// other; with options.bent, `bent` gets the unit mean unoccluded direction
// (world space) of hit samples (N_s when none escaped) and (0, 0, 0) for the
// others. `hits` must be trace()'s for `samples` on this scene and `high`
// (the mesh the scene was built over).
void trace_occlusion(const HighScene& scene, const Mesh& high, const LowSurface& surface,
                     const TexelSamples& samples, const Hits& hits, const OcclusionOptions& options,
                     std::vector<float>& visibility, std::vector<glm::vec3>& bent, OcclusionStats& stats);

// The speed ceiling of trace_occlusion(): the same rays in the same packets,
// built beforehand (a few hundred tiles at a time, to bound memory), and only
// Embree's rtcOccluded16 calls timed. For tools/bench. `hits` as above;
// RawTraceResult::hits counts unoccluded rays.
RawTraceResult trace_occlusion_raw(const HighScene& scene, const Mesh& high, const LowSurface& surface,
                                   const TexelSamples& samples, const Hits& hits,
                                   const OcclusionOptions& options);

// Thickness: rays from inside the high surface at the hit, in a cone of
// half-angle kThicknessConeDegrees around -N_s (uniform in solid angle, the
// same pattern scheme), find where they leave the mesh (the first surface
// they meet, front or back face) within `distance`. A ray's depth is its hit
// distance projected on -N_s (t cos theta), so a slab of thickness T gives
// exactly T and a sphere of radius r gives 2 r (1 + c + c^2) / 3, c = cos of
// the half-angle (0.9663 of the diameter); the sample's thickness is the
// mean over the rays that found an exit, or `distance` when none did
// (counted).
inline constexpr float kThicknessConeDegrees = 15.0f;
struct ThicknessOptions {
  int rays = 16;          // per sample: 1 .. kMaxOcclusionRays
  float distance = 1.0f;  // scene units
};
struct ThicknessStats {
  std::uint64_t samples = 0;
  std::uint64_t rays = 0;
  std::uint64_t exits = 0;            // rays that found where they leave the mesh
  std::uint64_t samples_no_exit = 0;  // no ray did: `distance` used
  std::uint64_t normal_fallbacks = 0;
  std::uint64_t untraced_rays = 0;
};
inline std::array<std::uint64_t*, 6> counters(ThicknessStats& s) {
  return {&s.samples, &s.rays, &s.exits, &s.samples_no_exit, &s.normal_fallbacks, &s.untraced_rays};
}
// Per sample: the thickness (scene units) of hit samples, 0 for any other.
void trace_thickness(const HighScene& scene, const Mesh& high, const LowSurface& surface,
                     const TexelSamples& samples, const Hits& hits, const ThicknessOptions& options,
                     std::vector<float>& thickness, ThicknessStats& stats);

}  // namespace nmbake
