// The sRGB transfer functions (IEC 61966-2-1) on [0, 1] (clamped): colour
// textures and glTF colours decoded to linear, colour maps and vertex
// colours encoded for display.
#pragma once

#include <algorithm>
#include <cmath>

namespace nmbake {

inline float srgb_to_linear(float v) {
  v = std::clamp(v, 0.0f, 1.0f);
  return v <= 0.04045f ? v / 12.92f : std::pow((v + 0.055f) / 1.055f, 2.4f);
}

inline float linear_to_srgb(float v) {
  v = std::clamp(v, 0.0f, 1.0f);
  return v <= 0.0031308f ? 12.92f * v : 1.055f * std::pow(v, 1.0f / 2.4f) - 0.055f;
}

}  // namespace nmbake
