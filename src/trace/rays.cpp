// Rays as the user asks for them (trace.hpp): distances and their parser,
// and RaySettings resolved into RayOptions.
#include <algorithm>
#include <charconv>
#include <cmath>
#include <string>

#include "nmbake/common.hpp"
#include "nmbake/trace.hpp"

namespace nmbake {

bool parse_distance(const std::string& text, Distance& out) {
  if (text == "auto") {
    out = Distance{};
    return true;
  }
  std::string number = text;
  Distance::Kind kind = Distance::Kind::absolute;
  if (!number.empty() && number.back() == '%') {
    number.pop_back();
    kind = Distance::Kind::percent;
  }
  if (number.empty()) return false;
  float value = 0.0f;
  const char* end = number.data() + number.size();
  const auto result = std::from_chars(number.data(), end, value);
  if (result.ec != std::errc() || result.ptr != end || !std::isfinite(value) || value < 0.0f) return false;
  out.kind = kind;
  out.value = value;
  return true;
}

std::string to_string(const Distance& distance) {
  switch (distance.kind) {
    case Distance::Kind::automatic:
      return "auto";
    case Distance::Kind::percent:
      return std::to_string(distance.value) + "%";
    case Distance::Kind::absolute:
      break;
  }
  return std::to_string(distance.value);
}

float resolve_distance(const Distance& d, float diagonal, float automatic_value) {
  switch (d.kind) {
    case Distance::Kind::absolute:
      return d.value;
    case Distance::Kind::percent:
      return d.value * 0.01f * diagonal;
    case Distance::Kind::automatic:
      break;
  }
  return automatic_value;
}

DistanceEstimate resolve_rays(const RaySettings& settings, const HighScene& scene, LowSurface& surface,
                              float low_diagonal, std::size_t group_count, RayOptions& rays) {
  const bool cage_mesh = surface.has_cage_mesh();
  rays = RayOptions{};
  rays.cage = cage_mesh ? CageMode::mesh : settings.cage_mode;
  rays.hit = settings.hit;
  rays.ignore_backfaces = settings.ignore_backfaces;
  DistanceEstimate estimate;
  const bool need_estimate = settings.estimates_distances();
  if (need_estimate) estimate = estimate_distances(scene, surface, low_diagonal);
  rays.front = resolve_distance(settings.front, low_diagonal, estimate.front);
  rays.back = resolve_distance(settings.back, low_diagonal, estimate.back);
  rays.edge_band = settings.edge_band;
  const bool both_auto =
      settings.front.kind == Distance::Kind::automatic && settings.back.kind == Distance::Kind::automatic;
  const bool retry = settings.retry_misses == RetryMisses::on ||
                     (settings.retry_misses == RetryMisses::automatic && !cage_mesh && both_auto);
  rays.retry_reach = retry ? kProbeReach * low_diagonal : 0.0f;
  if (need_estimate) {
    NMBAKE_CHECK(estimate.groups.size() == std::max<std::size_t>(group_count, 1), "an estimate per group");
  }
  for (std::size_t g = 0; g < group_count; ++g) {
    const GroupDistances e = need_estimate ? estimate.groups[g] : GroupDistances{};
    rays.groups.push_back({resolve_distance(settings.front, low_diagonal, e.front),
                           resolve_distance(settings.back, low_diagonal, e.back)});
  }
  if (rays.cage == CageMode::banded) prepare_edge_band(surface, edge_band_reach(rays));
  return estimate;
}

}  // namespace nmbake
