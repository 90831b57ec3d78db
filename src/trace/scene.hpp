// What the trace-side sources share (trace.cpp builds the scene and casts the
// bake's rays; trace_occlusion.cpp casts the map set's rays from the hits):
// the Embree scene behind HighScene, and the guard every ray passes. Private
// to src/: Embree's types stay in the trace files.
#pragma once

#include <embree3/rtcore.h>

#include <cmath>
#include <cstdint>
#include <glm/vec3.hpp>
#include <vector>

#include "nmbake/mesh.hpp"
#include "nmbake/trace.hpp"

namespace nmbake {

namespace detail {

// What a geometry's filter needs: the mesh and the first triangle of the
// geometry's index range (a bake group's).
struct GeometryRef {
  const Mesh* mesh = nullptr;
  std::uint32_t first_triangle = 0;
};

// A ray whose id has this bit set keeps hits on back faces even when the
// scene was built with the backface filter (--ignore-backfaces): thickness
// rays start inside the mesh and must find its back faces.
inline constexpr unsigned kKeepBackfacesRayId = 0x80000000u;

// Embree 3 asserts (Debian keeps its assertions on: an abort) that a ray's
// origin and direction components are within FLT_LARGE (1.844e18) and its
// range finite. The bake's limits (kMaxCoordinate, kMaxDistance) keep every
// ray well inside; this is the last guard: a ray outside is not traced.
inline bool embree_accepts(const glm::vec3& origin, const glm::vec3& direction, float tfar) {
  constexpr float kLargest = 1.8e18f;
  const auto within = [](const glm::vec3& v) {
    return std::fabs(v.x) <= kLargest && std::fabs(v.y) <= kLargest && std::fabs(v.z) <= kLargest;
  };
  return within(origin) && within(direction) && tfar >= 0.0f && tfar <= kLargest;
}

}  // namespace detail

struct HighScene::Impl {
  RTCDevice device = nullptr;
  RTCScene scene = nullptr;  // scenes[0]
  std::vector<RTCScene> scenes;
  std::vector<std::uint32_t> first_triangle{0};  // per group, + the end
  std::vector<detail::GeometryRef> refs;         // per group; addresses handed to Embree
  int groups_per_scene = 1;
  const Mesh* mesh = nullptr;
  bool compact = false;
  int group_count() const { return static_cast<int>(first_triangle.size()) - 1; }
  ~Impl() {
    for (RTCScene s : scenes) rtcReleaseScene(s);
    if (device) rtcReleaseDevice(device);
  }
};

}  // namespace nmbake
