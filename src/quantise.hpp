// Private to the library: the one integer quantisation of every integer
// format (PNG here, TIFF and TGA in the OpenImageIO module): round(clamp(v, 0,
// 1) * max), or for 8-bit maps dithered: floor(clamp(v, 0, 1) * max + d) with
// d a dither threshold of the texel (a fixed quasirandom pattern). Header-only so the module, which
// links none of the library, uses the same code.
#pragma once

#include <algorithm>
#include <cmath>
#include <cstdint>

namespace nmbake::detail {

// round(p), halves up, for 0 <= p <= max_value < 2^31 without a libm call:
// the whole part by truncation and the fraction p - whole, which is exact
// in float, against 0.5 (the same as floor(p + 0.5) in double; p + 0.5f in
// float is not: the float below 0.5 plus 0.5 rounds to 1). All in float and
// through a signed conversion, so the PNG writer's SIMD lanes
// (image_png.cpp) do the same operations per lane.
inline std::uint32_t quantise(float v, float max_value) {
  const float p = std::clamp(v, 0.0f, 1.0f) * max_value;
  const auto whole = static_cast<std::int32_t>(p);
  return static_cast<std::uint32_t>(whole + (p - static_cast<float>(whole) >= 0.5f ? 1 : 0));
}

// Ordered dithering with a quasirandom threshold (Roberts 2018, "The
// unreasonable effectiveness of quasirandom sequences": the R2 sequence as
// a dither mask): t(x, y) = frac(a1 x + a2 y) with a1 = 1/g, a2 = 1/g^2, g
// the plastic number (x^3 = x + 1). Every row and every column is itself an
// equidistributed sequence, so a slow gradient changes value within a few
// texels in both directions; an 8x8 Bayer matrix was tried first and left
// rows whose eight thresholds all lie above 0.27 (one-texel-wide streaks
// 160 texels long on the sphere). Channel c is offset by c (sqrt(2) - 1) so
// the three components of a normal do not step up together; the threshold
// is mapped into [1/128, 127/128] (mean 1/2) so values exactly on a step
// stay there. A pure function of the texel's index: the same bytes with any
// thread count. Double precision: exact enough for any map side nmbake writes.
inline float dither_threshold(std::uint32_t x, std::uint32_t y, std::uint32_t c) {
  constexpr double a1 = 0.75487766624669276, a2 = 0.56984029099805327, channel = 0.41421356237309515;
  double v = a1 * static_cast<double>(x) + a2 * static_cast<double>(y) + channel * static_cast<double>(c);
  // v >= 0 and far below 2^63: truncation is floor (inline, no libm call).
  v -= static_cast<double>(static_cast<std::int64_t>(v));
  return static_cast<float>((v * 126.0 + 1.0) / 128.0);
}

// floor(clamp(v, 0, 1) * max + threshold), at most max: the mean over the
// pattern is v * max (no bias), the error of one texel below one step.
inline std::uint32_t quantise_dithered(float v, float max_value, std::uint32_t x, std::uint32_t y, std::uint32_t c) {
  const float p = std::clamp(v, 0.0f, 1.0f) * max_value;
  const auto q = static_cast<std::uint32_t>(
      static_cast<std::int64_t>(static_cast<double>(p) + static_cast<double>(dither_threshold(x, y, c))));
  return std::min(q, static_cast<std::uint32_t>(max_value));
}

}  // namespace nmbake::detail
