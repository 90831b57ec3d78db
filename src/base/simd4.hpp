// Private to the library: four floats in SIMD lanes (GCC vector extensions;
// SSE on x86-64) for the per-sample loops of trace and encode.
//
// Every helper does, per lane, exactly the IEEE operations of the scalar code
// it stands for, in the same order (no fused multiply-adds: the baseline
// x86-64 target has none), so lane results are bit-identical to the scalar
// path and maps do not depend on which path a sample took.
#pragma once

#include <cmath>
#include <cstdint>
#include <cstring>
#include <glm/vec2.hpp>
#include <glm/vec3.hpp>
#include <glm/vec4.hpp>

#include "base/shuffle_compat.hpp"

#if defined(__SSE__)
#include <xmmintrin.h>  // __v4sf
#endif

static_assert(sizeof(glm::vec3) == 3 * sizeof(float), "glm::vec3 is three packed floats");

namespace nmbake::detail {

typedef float f4 __attribute__((vector_size(16)));
typedef std::int32_t i4 __attribute__((vector_size(16)));

inline f4 splat4(float v) { return f4{v, v, v, v}; }

inline i4 finite4(f4 v) { return (v - v) == f4{0.0f, 0.0f, 0.0f, 0.0f}; }  // inf - inf and NaN are NaN

inline f4 sqrt4(f4 v) {
#if defined(__SSE__)
  return reinterpret_cast<f4>(__builtin_ia32_sqrtps(reinterpret_cast<__v4sf>(v)));
#else
  f4 r;
  for (int i = 0; i < 4; ++i) r[i] = std::sqrt(v[i]);
  return r;
#endif
}

// a > b ? a : b and a < b ? a : b per lane (SSE's maxps and minps).
inline f4 max4(f4 a, f4 b) {
#if defined(__SSE__)
  return reinterpret_cast<f4>(__builtin_ia32_maxps(reinterpret_cast<__v4sf>(a), reinterpret_cast<__v4sf>(b)));
#else
  f4 r;
  for (int i = 0; i < 4; ++i) r[i] = a[i] > b[i] ? a[i] : b[i];
  return r;
#endif
}

inline f4 min4(f4 a, f4 b) {
#if defined(__SSE__)
  return reinterpret_cast<f4>(__builtin_ia32_minps(reinterpret_cast<__v4sf>(a), reinterpret_cast<__v4sf>(b)));
#else
  f4 r;
  for (int i = 0; i < 4; ++i) r[i] = a[i] < b[i] ? a[i] : b[i];
  return r;
#endif
}

// Whether every lane of a comparison mask is set.
inline bool all4(i4 mask) {
#if defined(__SSE__)
  return __builtin_ia32_movmskps(reinterpret_cast<__v4sf>(mask)) == 0xF;
#else
  return mask[0] && mask[1] && mask[2] && mask[3];
#endif
}

// The number of set lanes of a comparison mask.
inline int count4(i4 mask) {
#if defined(__SSE__)
  // A nibble's bit count from a 16-entry table in one word: baseline x86-64
  // has no popcnt, and __builtin_popcount would call libgcc.
  const unsigned bits = static_cast<unsigned>(__builtin_ia32_movmskps(reinterpret_cast<__v4sf>(mask)));
  return static_cast<int>(0x4332322132212110ull >> (4 * bits) & 0xF);
#else
  return (mask[0] != 0) + (mask[1] != 0) + (mask[2] != 0) + (mask[3] != 0);
#endif
}

inline i4 splat4i(std::int32_t v) { return i4{v, v, v, v}; }

// v where the mask is set, +0.0 elsewhere.
inline f4 select4(i4 mask, f4 v) { return reinterpret_cast<f4>(reinterpret_cast<i4>(v) & mask); }

// Four consecutive floats or 32-bit integers from / to memory, any alignment.
inline f4 load4(const float* p) {
  f4 v;
  std::memcpy(&v, p, sizeof v);
  return v;
}
inline void store4(float* p, f4 v) { std::memcpy(p, &v, sizeof v); }
template <class T>
inline i4 load4i(const T* p) {
  static_assert(sizeof(T) == 4, "32-bit lanes");
  i4 v;
  std::memcpy(&v, p, sizeof v);
  return v;
}
inline void store4i(std::int32_t* p, i4 v) { std::memcpy(p, &v, sizeof v); }

// (x, y, z, 0) from one 8-byte and one 4-byte load, never past z.
inline f4 load4(const glm::vec3& v) {
  typedef double d2 __attribute__((vector_size(16)));
  double xy;
  std::memcpy(&xy, &v.x, sizeof xy);
  const f4 low = reinterpret_cast<f4>(d2{xy, 0.0});
  return __builtin_shuffle(low, f4{v.z, 0.0f, 0.0f, 0.0f}, i4{0, 1, 4, 5});
}
inline f4 load4(const glm::vec4& v) { return f4{v.x, v.y, v.z, v.w}; }

// Three corners interpolated in array-of-structures form: the products and
// sums of c0 * (1 - b.x - b.y) + c1 * b.x + c2 * b.y on glm vectors.
template <class V>
inline f4 corner_mix(const V& c0, const V& c1, const V& c2, glm::vec2 b) {
  const float w0 = 1.0f - b.x - b.y;
  return load4(c0) * w0 + load4(c1) * b.x + load4(c2) * b.y;
}

// A triangle's three corners stored one after the other (9 floats), as
// three vectors: three overlapping 16-byte loads and one shuffle (SSE2 has no
// two-source byte shift), never reading past the ninth float. The w lanes
// hold other corners' values and are not meaningful.
struct Corners {
  f4 c0, c1, c2;
};

inline Corners load_corners(const glm::vec3* c) {
  const float* f = &c[0].x;
  const f4 last = load4(f + 5);
  return {load4(f), load4(f + 3), __builtin_shuffle(last, i4{1, 2, 3, 3})};
}

inline f4 corner_mix(const Corners& c, glm::vec2 b) {
  const float w0 = 1.0f - b.x - b.y;
  return c.c0 * w0 + c.c1 * b.x + c.c2 * b.y;
}

inline f4 corner_mix(const glm::vec3* c, glm::vec2 b) { return corner_mix(load_corners(c), b); }

struct Axes {
  f4 x, y, z, w;
};

// The corner weights of four consecutive barycentric pairs, one vector per
// corner: w0 = 1 - b.x - b.y as corner_mix() computes it, then b.x and b.y.
struct Weights {
  f4 w0, bx, by;
};

inline Weights lane_weights(const glm::vec2* b) {
  const f4 b01 = load4(&b[0].x), b23 = load4(&b[2].x);
  const f4 bx = __builtin_shuffle(b01, b23, i4{0, 2, 4, 6}), by = __builtin_shuffle(b01, b23, i4{1, 3, 5, 7});
  return {splat4(1.0f) - bx - by, bx, by};
}

// Three corners of one triangle interpolated across four lanes (structure of
// arrays, the corners splatted): per lane the products and sums of
// corner_mix(), in its order. w is +0.0 for vec3 corners.
[[gnu::always_inline]] inline Axes mix_axes(const glm::vec3* c, const Weights& w) {
  return {splat4(c[0].x) * w.w0 + splat4(c[1].x) * w.bx + splat4(c[2].x) * w.by,
          splat4(c[0].y) * w.w0 + splat4(c[1].y) * w.bx + splat4(c[2].y) * w.by,
          splat4(c[0].z) * w.w0 + splat4(c[1].z) * w.bx + splat4(c[2].z) * w.by, f4{}};
}
[[gnu::always_inline]] inline Axes mix_axes(const glm::vec4* c, const Weights& w) {
  return {splat4(c[0].x) * w.w0 + splat4(c[1].x) * w.bx + splat4(c[2].x) * w.by,
          splat4(c[0].y) * w.w0 + splat4(c[1].y) * w.bx + splat4(c[2].y) * w.by,
          splat4(c[0].z) * w.w0 + splat4(c[1].z) * w.bx + splat4(c[2].z) * w.by,
          splat4(c[0].w) * w.w0 + splat4(c[1].w) * w.bx + splat4(c[2].w) * w.by};
}

// Four lanes of (x, y, z, w) to one vector per axis.
inline Axes transpose(f4 r0, f4 r1, f4 r2, f4 r3) {
  const f4 t0 = __builtin_shuffle(r0, r1, i4{0, 4, 1, 5}), t1 = __builtin_shuffle(r2, r3, i4{0, 4, 1, 5});
  const f4 t2 = __builtin_shuffle(r0, r1, i4{2, 6, 3, 7}), t3 = __builtin_shuffle(r2, r3, i4{2, 6, 3, 7});
  return {__builtin_shuffle(t0, t1, i4{0, 1, 4, 5}), __builtin_shuffle(t0, t1, i4{2, 3, 6, 7}),
          __builtin_shuffle(t2, t3, i4{0, 1, 4, 5}), __builtin_shuffle(t2, t3, i4{2, 3, 6, 7})};
}

// One vector per axis back to four glm::vec3 at out[0..3]: three 16-byte
// stores in order (each one's fourth float is overwritten by the next) and
// an 8 + 4-byte store for the last, never past out[3].
inline void store3x4(glm::vec3* out, f4 x, f4 y, f4 z) {
  const Axes rows = transpose(x, y, z, f4{0.0f, 0.0f, 0.0f, 0.0f});
  float* f = &out[0].x;
  store4(f, rows.x);
  store4(f + 3, rows.y);
  store4(f + 6, rows.z);
  std::memcpy(f + 9, &rows.w, 2 * sizeof(float));
  f[11] = rows.w[2];
}

}  // namespace nmbake::detail
