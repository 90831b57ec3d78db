// Private to the library: the one integer quantisation of every integer
// format (PNG here, TIFF and TGA in the OpenImageIO module): round(clamp(v, 0,
// 1) * max), or for 8-bit maps dithered: floor(clamp(v, 0, 1) * max + d) with
// d a dither threshold of the texel (a fixed quasirandom pattern). Header-only so the module, which
// links none of the library, uses the same code.
#pragma once

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <cstring>

#if defined(__SSE2__)
#include <emmintrin.h>
#endif

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
constexpr double kDitherX = 0.75487766624669276, kDitherY = 0.56984029099805327,
                 kDitherChannel = 0.41421356237309515;

inline float dither_threshold(std::uint32_t x, std::uint32_t y, std::uint32_t c) {
  double v = kDitherX * static_cast<double>(x) + kDitherY * static_cast<double>(y) +
             kDitherChannel * static_cast<double>(c);
  // v >= 0 and far below 2^63: truncation is floor (inline, no libm call).
  v -= static_cast<double>(static_cast<std::int64_t>(v));
  return static_cast<float>((v * 126.0 + 1.0) / 128.0);
}

// floor(clamp(v, 0, 1) * max + threshold), at most max: the mean over the
// pattern is v * max (no bias), the error of one texel below one step.
inline std::uint32_t quantise_dithered(float v, float max_value, std::uint32_t x, std::uint32_t y,
                                       std::uint32_t c) {
  const float p = std::clamp(v, 0.0f, 1.0f) * max_value;
  const auto q = static_cast<std::uint32_t>(
      static_cast<std::int64_t>(static_cast<double>(p) + static_cast<double>(dither_threshold(x, y, c))));
  return std::min(q, static_cast<std::uint32_t>(max_value));
}

#if defined(__SSE2__)
// Four 32-bit lanes in [0, 255] stored as four bytes (saturating packs: a
// larger lane stores 255).
inline void store_bytes4(__m128i q, std::uint8_t* out) {
  const __m128i bytes = _mm_packus_epi16(_mm_packs_epi32(q, q), _mm_setzero_si128());
  const std::int32_t four = _mm_cvtsi128_si32(bytes);
  std::memcpy(out, &four, 4);
}
#endif

// quantise_dithered() to 8 bits of the four values v[0..3] (already mapped)
// of channel c at texels x..x+3 of row y, into out[0..3]: per lane the same
// IEEE operations in the same order (SSE2, two doubles a register), so the
// same bytes. The 8-bit maps (curvature, AO) spent half their write in the
// scalar version. The truncations go through 32-bit integers: every value
// truncated here lies in [0, 2^31) (below 0.76 x + 0.57 y + 2 for the
// threshold, below 256 for the quantised value), where that is the 64-bit
// truncation; the saturating packs are the final min(q, 255).
inline void quantise_dithered4_8bit(const float* v, std::uint32_t x, std::uint32_t y, std::uint32_t c,
                                    std::uint8_t* out) {
#if defined(__SSE2__)
  const __m128 clamped = _mm_min_ps(_mm_max_ps(_mm_loadu_ps(v), _mm_setzero_ps()), _mm_set1_ps(1.0f));
  const __m128 p = _mm_mul_ps(clamped, _mm_set1_ps(255.0f));
  const __m128d row = _mm_set1_pd(kDitherY * static_cast<double>(y)),
                ch = _mm_set1_pd(kDitherChannel * static_cast<double>(c));
  const __m128d first = _mm_set1_pd(static_cast<double>(x));
  const auto two = [&](__m128d xs, __m128d p2) {
    __m128d t = _mm_add_pd(_mm_add_pd(_mm_mul_pd(_mm_set1_pd(kDitherX), xs), row), ch);
    t = _mm_sub_pd(t, _mm_cvtepi32_pd(_mm_cvttpd_epi32(t)));
    // / 128 as * 2^-7: the same double (a power of two, no underflow).
    t = _mm_mul_pd(_mm_add_pd(_mm_mul_pd(t, _mm_set1_pd(126.0)), _mm_set1_pd(1.0)), _mm_set1_pd(0x1p-7));
    t = _mm_cvtps_pd(_mm_cvtpd_ps(t));  // the threshold as a float, as dither_threshold() returns it
    return _mm_cvttpd_epi32(_mm_add_pd(p2, t));
  };
  const __m128i lo = two(_mm_add_pd(first, _mm_set_pd(1.0, 0.0)), _mm_cvtps_pd(p));
  const __m128i hi = two(_mm_add_pd(first, _mm_set_pd(3.0, 2.0)), _mm_cvtps_pd(_mm_movehl_ps(p, p)));
  store_bytes4(_mm_unpacklo_epi64(lo, hi), out);
#else
  for (std::uint32_t k = 0; k < 4; ++k) {
    out[k] = static_cast<std::uint8_t>(quantise_dithered(v[k], 255.0f, x + k, y, c));
  }
#endif
}

}  // namespace nmbake::detail
