// Private to the library: the one integer quantisation of every integer
// format (PNG here, TIFF in the OpenImageIO module): round(clamp(v, 0, 1) *
// max). Header-only so the module, which links none of the library, uses the
// same code.
#pragma once

#include <algorithm>
#include <cstdint>

namespace nmbake::detail {

// round(p) for p >= 0 without a libm call: p + 0.5 is exact in double and
// truncation is floor, so this is lround(p) bit for bit.
inline std::uint32_t quantise(float v, float max_value) {
  const float p = std::clamp(v, 0.0f, 1.0f) * max_value;
  return static_cast<std::uint32_t>(static_cast<double>(p) + 0.5);
}

}  // namespace nmbake::detail
