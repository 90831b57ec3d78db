// Ray distances as the user gives them (trace.hpp).
#include <charconv>
#include <cmath>
#include <string>

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
    case Distance::Kind::automatic: return "auto";
    case Distance::Kind::percent: return std::to_string(distance.value) + "%";
    case Distance::Kind::absolute: break;
  }
  return std::to_string(distance.value);
}

}  // namespace nmbake
