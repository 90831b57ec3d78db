// Stage "encode": world-space hit normals into tangent- or object-space RGB.
//
// The tangent-space encode is the exact inverse of the MikkTSpace decode
// (Mikkelsen 2008; the "per pixel" variant of mikktspace.h): the renderer
// computes n = normalize(t.x T + t.y B + t.z N) with T and N interpolated and
// not normalised and B = sign * cross(N, T). We solve M t = n for
// M = [T B N] and normalise, so decoding our t gives back the direction of
// n_high exactly. The transpose (dot products with a normalised frame) is
// kept only to measure what it costs: it is right only for orthonormal frames.
// Other decodes (a bitangent interpolated per vertex, a frame normalised
// before the decode: NormalDecode) get the same treatment with their own
// M = [T B N] (the general inverse below), in the SIMD lanes too
// (general_lanes(), the same operations in the same order).
#include "nmbake/encode.hpp"

#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>

#include <algorithm>
#include <cmath>
#include <glm/geometric.hpp>
#include <memory>

#include "base/simd4.hpp"

namespace nmbake {

namespace {

using namespace detail;

template <class V>
[[gnu::always_inline]] inline V interpolate(const std::vector<V>& corner, std::size_t base, glm::vec2 b) {
  return corner[base] * (1.0f - b.x - b.y) + corner[base + 1] * b.x + corner[base + 2] * b.y;
}

bool finite3(const glm::vec3& v) { return std::isfinite(v.x) && std::isfinite(v.y) && std::isfinite(v.z); }

// Orthonormal frame from N and T by Gram-Schmidt; any perpendicular when T is
// parallel to N.
void orthonormal_frame(const glm::vec3& T, const glm::vec3& N, float sign, glm::vec3& t, glm::vec3& b,
                       glm::vec3& n) {
  const float ln = glm::length(N);
  n = ln > 0.0f && std::isfinite(ln) ? N / ln : glm::vec3(0.0f, 0.0f, 1.0f);
  glm::vec3 tt = T - n * glm::dot(n, T);
  float lt = glm::length(tt);
  if (!(lt > 1e-12f) || !std::isfinite(lt)) {
    tt = std::fabs(n.x) < 0.9f ? glm::cross(n, glm::vec3(1, 0, 0)) : glm::cross(n, glm::vec3(0, 1, 0));
    lt = glm::length(tt);
  }
  t = tt / lt;
  b = sign * glm::cross(n, t);
}

}  // namespace

glm::vec3 tangent_to_world(const glm::vec3& t, const glm::vec3& T, const glm::vec3& N, float sign) {
  const glm::vec3 B = sign * glm::cross(N, T);
  const glm::vec3 n = t.x * T + t.y * B + t.z * N;
  const float l = glm::length(n);
  return l > 0.0f && std::isfinite(l) ? n / l : glm::vec3(0.0f, 0.0f, 1.0f);
}

namespace {

// The exact inverse, the hot path of the encode: Cramer's rule,
// M^-1 n = (n.(BxN), n.(NxT), n.(TxB)) / det(M), unnormalised (the caller
// normalises; only the sign of det matters). With C = NxT, B = sign C, so
// BxN = sign CxN and TxB = sign TxC (NxT is C itself). The regularity test
// |det| > 1e-6 |T||B||N| is done on squares, without square roots.
// False when the frame is singular (or not finite): `t` is then unset.
inline bool inverse_tangent(const glm::vec3& n, const glm::vec3& T, const glm::vec3& N, float sign,
                            glm::vec3& t) {
  const glm::vec3 c = glm::cross(N, T);
  const glm::vec3 bn = sign * glm::cross(c, N);
  const glm::vec3 tb = sign * glm::cross(T, c);
  const float det = glm::dot(T, bn);
  const float scale2 = glm::dot(T, T) * glm::dot(c, c) * glm::dot(N, N);
  if (!(det * det > 1e-12f * scale2) || !(scale2 > 0.0f) || !std::isfinite(det) || !std::isfinite(scale2))
    return false;
  t = glm::vec3(glm::dot(n, bn), glm::dot(n, c), glm::dot(n, tb));
  if (det < 0.0f) t = -t;
  return true;
}

// The columns the renderer decodes with: as given, or each normalised
// (false when one cannot be).
inline bool decode_columns(bool unit_frame, glm::vec3& T, glm::vec3& B, glm::vec3& N) {
  if (!unit_frame) return true;
  for (glm::vec3* v : {&T, &B, &N}) {
    const float l = glm::length(*v);
    if (!(l > 0.0f) || !std::isfinite(l)) return false;
    *v /= l;
  }
  return true;
}

// The exact inverse for any frame: Cramer's rule, M^-1 n = (n.(BxN),
// n.(NxT), n.(TxB)) / det(M), det(M) = T.(BxN), unnormalised (only the sign
// of det matters). Regular when |det| > 1e-6 |T||B||N| (on squares).
inline bool inverse_general(const glm::vec3& n, glm::vec3 T, glm::vec3 B, glm::vec3 N, bool unit_frame,
                            glm::vec3& t) {
  if (!decode_columns(unit_frame, T, B, N)) return false;
  const glm::vec3 r0 = glm::cross(B, N), r1 = glm::cross(N, T), r2 = glm::cross(T, B);
  const float det = glm::dot(T, r0);
  const float scale2 = glm::dot(T, T) * glm::dot(B, B) * glm::dot(N, N);
  if (!(det * det > 1e-12f * scale2) || !(scale2 > 0.0f) || !std::isfinite(det) || !std::isfinite(scale2))
    return false;
  t = glm::vec3(glm::dot(n, r0), glm::dot(n, r1), glm::dot(n, r2));
  if (det < 0.0f) t = -t;
  return true;
}

}  // namespace

bool world_to_tangent(const glm::vec3& n, const glm::vec3& T, const glm::vec3& B, const glm::vec3& N,
                      float sign, bool unit_frame, glm::vec3& out) {
  glm::vec3 t(0.0f);
  bool regular = inverse_general(n, T, B, N, unit_frame, t);
  if (!regular) {
    glm::vec3 ot, ob, on;
    orthonormal_frame(T, N, sign, ot, ob, on);
    t = glm::vec3(glm::dot(n, ot), glm::dot(n, ob), glm::dot(n, on));
  }
  const float l = glm::length(t);
  if (!(l > 0.0f) || !finite3(t)) {
    out = glm::vec3(0.0f, 0.0f, 1.0f);
    return false;
  }
  out = t / l;
  return regular;
}

glm::vec3 tangent_to_world(const glm::vec3& t, const glm::vec3& T, const glm::vec3& B, const glm::vec3& N,
                           bool unit_frame) {
  glm::vec3 cT = T, cB = B, cN = N;
  if (!decode_columns(unit_frame, cT, cB, cN)) return glm::vec3(0.0f, 0.0f, 1.0f);
  const glm::vec3 n = t.x * cT + t.y * cB + t.z * cN;
  const float l = glm::length(n);
  return l > 0.0f && std::isfinite(l) ? n / l : glm::vec3(0.0f, 0.0f, 1.0f);
}

glm::vec3 decode_bitangent(const LowSurface& surface, std::size_t triangle, glm::vec2 b, Bitangent rule) {
  const std::size_t base = 3 * triangle;
  if (rule == Bitangent::vertex) {
    NMBAKE_CHECK(surface.bitangent.size() == surface.tangent.size(), "per-corner bitangents filled");
    return interpolate(surface.bitangent, base, b);
  }
  const glm::vec4 tw = interpolate(surface.tangent, base, b);
  const float sign = tw.w < 0.0f ? -1.0f : 1.0f;
  return sign * glm::cross(interpolate(surface.normal, base, b), glm::vec3(tw));
}

bool onto_upper_hemisphere(glm::vec3& t) {
  if (!(t.z < 0.0f)) return true;
  const float l = std::sqrt(t.x * t.x + t.y * t.y);
  t = l > 0.0f && std::isfinite(l) ? glm::vec3(t.x / l, t.y / l, 0.0f) : glm::vec3(0.0f, 0.0f, 1.0f);
  return false;
}

bool world_to_tangent(const glm::vec3& n, const glm::vec3& T, const glm::vec3& N, float sign,
                      TangentEncode method, glm::vec3& out) {
  bool regular = true;
  glm::vec3 t(0.0f);
  if (method == TangentEncode::inverse) regular = inverse_tangent(n, T, N, sign, t);
  if (method == TangentEncode::transpose || !regular) {
    glm::vec3 ot, ob, on;
    orthonormal_frame(T, N, sign, ot, ob, on);
    t = glm::vec3(glm::dot(n, ot), glm::dot(n, ob), glm::dot(n, on));
  }
  const float l = glm::length(t);
  if (!(l > 0.0f) || !finite3(t)) {
    out = glm::vec3(0.0f, 0.0f, 1.0f);
    return false;
  }
  out = t / l;
  return regular;
}

namespace {

struct Counts {
  std::uint64_t singular = 0, zero_high = 0, zero_result = 0, below_horizon = 0;
};

// Decodes with a frame of their own: the general inverse, per sample.
bool own_frame(const NormalDecode& decode) {
  return decode.bitangent == Bitangent::vertex || decode.unit_frame;
}

// What one sample adds to its texel's sum: the hit normal in the chosen
// space (tangent: normalised per sample, so every sample weighs the same;
// object: the unit world normal). False for a sample outside the chart.
// The reference path, for every mode; encode_four() is the same arithmetic
// for the common case, four samples at a time.
bool sample_contribution(const LowSurface& surface, const TexelSamples& samples, const Mesh& high,
                         const Hits& hits, const EncodeOptions& options, bool smooth, std::size_t s,
                         Counts& counts, glm::vec3& out, const glm::vec3* hit_normal = nullptr) {
  const bool tangent_space = options.space == NormalSpace::tangent;
  const std::int32_t tri = samples.triangle[s];
  if (tri < 0) return false;
  const std::size_t base = 3 * static_cast<std::size_t>(tri);
  const glm::vec2 b = samples.bary[s];
  const glm::vec3 N = interpolate(surface.normal, base, b);
  const std::int32_t hit = hits.triangle[s];
  if (hit < 0) {
    // A miss keeps the low surface's own normal.
    if (tangent_space) {
      out = glm::vec3(0.0f, 0.0f, 1.0f);
    } else {
      const float ln = glm::length(N);
      out = ln > 0.0f && std::isfinite(ln) ? N / ln : glm::vec3(0.0f, 0.0f, 1.0f);
    }
    return true;
  }
  const std::uint32_t* h = &high.indices[3 * static_cast<std::size_t>(hit)];
  glm::vec3 n_high(0.0f);
  // A normal given for the hit (the high's normal textures applied) is unit.
  bool have = hit_normal != nullptr && *hit_normal != glm::vec3(0.0f);
  if (have) {
    n_high = *hit_normal;
  } else if (smooth) {
    const glm::vec2 hb = hits.bary[s];
    n_high =
        high.normals[h[0]] * (1.0f - hb.x - hb.y) + high.normals[h[1]] * hb.x + high.normals[h[2]] * hb.y;
    const float l2 = glm::dot(n_high, n_high);
    if (l2 > 1e-24f && std::isfinite(l2)) {
      // Tangent space needs only its direction (each sample's t is
      // normalised after the inverse); object space sums unit normals.
      if (!tangent_space) n_high *= 1.0f / std::sqrt(l2);
      have = true;
    } else {
      ++counts.zero_high;
    }
  }
  if (!have) {
    n_high =
        glm::cross(high.positions[h[1]] - high.positions[h[0]], high.positions[h[2]] - high.positions[h[0]]);
    const float l = glm::length(n_high);
    if (l > 0.0f && std::isfinite(l)) {
      n_high /= l;
    } else {
      n_high = N;  // a zero-area high triangle has no direction of its own
      if (options.high_normals == HighNormals::face) ++counts.zero_high;
    }
  }
  if (!tangent_space) {
    out = n_high;
    return true;
  }
  const glm::vec4 tw = interpolate(surface.tangent, base, b);
  const float sign = tw.w < 0.0f ? -1.0f : 1.0f;
  glm::vec3 t;
  if (options.tangent_encode == TangentEncode::inverse && own_frame(options.decode)) {
    const glm::vec3 T(tw);
    const glm::vec3 B = options.decode.bitangent == Bitangent::vertex
                            ? interpolate(surface.bitangent, base, b)
                            : sign * glm::cross(N, T);
    if (inverse_general(n_high, T, B, N, options.decode.unit_frame, t)) {
      const float lt2 = glm::dot(t, t);
      if (lt2 > 0.0f && std::isfinite(lt2)) {
        out = t * (1.0f / std::sqrt(lt2));
        return true;
      }
    }
    // Singular: the per-pixel Gram-Schmidt frame, as for the default decode.
    world_to_tangent(n_high, T, N, sign, TangentEncode::transpose, t);
    ++counts.singular;
    out = t;
    return true;
  }
  if (options.tangent_encode == TangentEncode::inverse &&
      inverse_tangent(n_high, glm::vec3(tw), N, sign, t)) {
    const float lt2 = glm::dot(t, t);
    if (lt2 > 0.0f && std::isfinite(lt2)) {
      out = t * (1.0f / std::sqrt(lt2));
      return true;
    }
  }
  if (!world_to_tangent(n_high, glm::vec3(tw), N, sign, options.tangent_encode, t)) ++counts.singular;
  out = t;
  return true;
}

// The default mode (tangent space, smooth high normals, the exact inverse,
// any NormalDecode) takes four or eight consecutive samples in SIMD lanes (GCC vector
// extensions: SSE for four, AVX2 for eight where the CPU has it, chosen at
// run time). Each lane does exactly the operations of sample_contribution(),
// in the same order and without fused multiply-adds (neither target enables
// FMA), so results are bit-identical to it whatever the width. A lane that is
// not the plain case (no sample, a miss, a zero high normal, a singular
// frame) is redone by sample_contribution(), which also counts it.

bool plain_samples(const TexelSamples& samples, const Hits& hits, std::size_t s0, int count) {
  bool plain = true;
  for (int i = 0; i < count; ++i)
    plain = plain && samples.triangle[s0 + i] >= 0 && hits.triangle[s0 + i] >= 0;
  return plain;
}

// The high normal and the low frame (N, T) of four plain samples, one vector
// per axis. Four samples on one low triangle (nearly all groups) have their
// frame interpolated across the lanes, others lane by lane; the same operations.
[[gnu::always_inline]] inline void gather_four(const LowSurface& surface, const TexelSamples& samples,
                                               const Mesh& high, const Hits& hits, std::size_t s0, Axes& n,
                                               Axes& N, Axes& T, Axes* B) {
  f4 high_n[4];
  for (int i = 0; i < 4; ++i) {
    const std::uint32_t* h = &high.indices[3 * static_cast<std::size_t>(hits.triangle[s0 + i])];
    high_n[i] = corner_mix(high.normals[h[0]], high.normals[h[1]], high.normals[h[2]], hits.bary[s0 + i]);
  }
  n = transpose(high_n[0], high_n[1], high_n[2], high_n[3]);
  const i4 low = load4i(&samples.triangle[s0]);
  if (all4(low == splat4i(low[0]))) {
    const std::size_t base = 3 * static_cast<std::size_t>(low[0]);
    const Weights w = lane_weights(&samples.bary[s0]);
    N = mix_axes(&surface.normal[base], w);
    T = mix_axes(&surface.tangent[base], w);
    if (B) *B = mix_axes(&surface.bitangent[base], w);
    return;
  }
  f4 low_n[4], low_t[4], low_b[4];
  for (int i = 0; i < 4; ++i) {
    const std::size_t base = 3 * static_cast<std::size_t>(samples.triangle[s0 + i]);
    const glm::vec2 b = samples.bary[s0 + i];
    low_n[i] = corner_mix(&surface.normal[base], b);
    low_t[i] = corner_mix(surface.tangent[base], surface.tangent[base + 1], surface.tangent[base + 2], b);
    if (B) low_b[i] = corner_mix(&surface.bitangent[base], b);
  }
  N = transpose(low_n[0], low_n[1], low_n[2], low_n[3]);
  T = transpose(low_t[0], low_t[1], low_t[2], low_t[3]);
  if (B) *B = transpose(low_b[0], low_b[1], low_b[2], low_b[3]);
}

// inverse_tangent() and the normalisation of sample_contribution() in lanes
// of any width V (f4 or f8), up to the square root, which the caller takes
// with its target's instruction: t (flipped to det > 0), |t|^2 and `ok`, the
// mask of the lanes that are the plain case.
template <class V, class M>
[[gnu::always_inline]] inline void inverse_lanes(V nx, V ny, V nz, V Nx, V Ny, V Nz, V Tx, V Ty, V Tz, V Tw,
                                                 V& tx, V& ty, V& tz, V& lt2, M& ok) {
  const V zero = V{} + 0.0f, one = zero + 1.0f;
  const V l2 = nx * nx + ny * ny + nz * nz;
  // finite: v - v is 0 (inf - inf and NaN are NaN)
  ok = (l2 > zero + 1e-24f) & ((l2 - l2) == zero);
  // c = N x T, bn = sign (c x N), tb = sign (T x c).
  const V sign = Tw < zero ? -one : one;
  const V cx = Ny * Tz - Ty * Nz, cy = Nz * Tx - Tz * Nx, cz = Nx * Ty - Tx * Ny;
  const V bnx = sign * (cy * Nz - Ny * cz), bny = sign * (cz * Nx - Nz * cx),
          bnz = sign * (cx * Ny - Nx * cy);
  const V tbx = sign * (Ty * cz - cy * Tz), tby = sign * (Tz * cx - cz * Tx),
          tbz = sign * (Tx * cy - cx * Ty);
  const V det = Tx * bnx + Ty * bny + Tz * bnz;
  const V scale2 =
      (Tx * Tx + Ty * Ty + Tz * Tz) * (cx * cx + cy * cy + cz * cz) * (Nx * Nx + Ny * Ny + Nz * Nz);
  ok &= (det * det > (zero + 1e-12f) * scale2) & (scale2 > zero) & ((det - det) == zero) &
        ((scale2 - scale2) == zero);
  const V flip = det < zero ? -one : one;
  tx = nx * bnx + ny * bny + nz * bnz;
  ty = nx * cx + ny * cy + nz * cz;
  tz = nx * tbx + ny * tby + nz * tbz;
  // t = -t as a multiplication by -1 is exact, as is by +1.
  tx *= flip, ty *= flip, tz *= flip;
  lt2 = tx * tx + ty * ty + tz * tz;
  ok &= (lt2 > zero) & ((lt2 - lt2) == zero);
}

// inverse_general() of sample_contribution() in lanes, for the decodes with
// a frame of their own (own_frame()), in two steps around the square roots,
// which the caller takes with its target's instruction:
// column_squares() makes B (per vertex: given, interpolated like N; per
// pixel: sign (N x T)) and the squared lengths of T, B, N; general_lanes()
// divides the columns by their lengths when the decode normalises them,
// then applies Cramer's rule with the rows B x N, N x T, T x B. The
// operations of the scalar code in its order (glm's cross and dot), so the
// same bits.
template <class V>
struct FrameLanes {
  V Tx, Ty, Tz, Bx, By, Bz, Nx, Ny, Nz;
};

template <class V>
[[gnu::always_inline]] inline void column_squares(FrameLanes<V>& f, V Tw, const NormalDecode& decode, V& t2,
                                                  V& b2, V& n2) {
  const V zero = V{} + 0.0f, one = zero + 1.0f;
  if (decode.bitangent == Bitangent::pixel) {
    const V sign = Tw < zero ? -one : one;
    f.Bx = sign * (f.Ny * f.Tz - f.Ty * f.Nz);
    f.By = sign * (f.Nz * f.Tx - f.Tz * f.Nx);
    f.Bz = sign * (f.Nx * f.Ty - f.Tx * f.Ny);
  }
  t2 = f.Tx * f.Tx + f.Ty * f.Ty + f.Tz * f.Tz;
  b2 = f.Bx * f.Bx + f.By * f.By + f.Bz * f.Bz;
  n2 = f.Nx * f.Nx + f.Ny * f.Ny + f.Nz * f.Nz;
}

template <class V, class M>
[[gnu::always_inline]] inline void general_lanes(V nx, V ny, V nz, FrameLanes<V> f, V lt, V lb, V ln,
                                                 const NormalDecode& decode, V& tx, V& ty, V& tz, V& lt2,
                                                 M& ok) {
  const V zero = V{} + 0.0f, one = zero + 1.0f;
  const V l2 = nx * nx + ny * ny + nz * nz;
  ok = (l2 > zero + 1e-24f) & ((l2 - l2) == zero);
  if (decode.unit_frame) {
    ok &= (lt > zero) & ((lt - lt) == zero) & (lb > zero) & ((lb - lb) == zero) & (ln > zero) &
          ((ln - ln) == zero);
    f.Tx = f.Tx / lt, f.Ty = f.Ty / lt, f.Tz = f.Tz / lt;
    f.Bx = f.Bx / lb, f.By = f.By / lb, f.Bz = f.Bz / lb;
    f.Nx = f.Nx / ln, f.Ny = f.Ny / ln, f.Nz = f.Nz / ln;
  }
  const V r0x = f.By * f.Nz - f.Ny * f.Bz, r0y = f.Bz * f.Nx - f.Nz * f.Bx, r0z = f.Bx * f.Ny - f.Nx * f.By;
  const V r1x = f.Ny * f.Tz - f.Ty * f.Nz, r1y = f.Nz * f.Tx - f.Tz * f.Nx, r1z = f.Nx * f.Ty - f.Tx * f.Ny;
  const V r2x = f.Ty * f.Bz - f.By * f.Tz, r2y = f.Tz * f.Bx - f.Bz * f.Tx, r2z = f.Tx * f.By - f.Bx * f.Ty;
  const V det = f.Tx * r0x + f.Ty * r0y + f.Tz * r0z;
  const V scale2 = (f.Tx * f.Tx + f.Ty * f.Ty + f.Tz * f.Tz) * (f.Bx * f.Bx + f.By * f.By + f.Bz * f.Bz) *
                   (f.Nx * f.Nx + f.Ny * f.Ny + f.Nz * f.Nz);
  ok &= (det * det > (zero + 1e-12f) * scale2) & (scale2 > zero) & ((det - det) == zero) &
        ((scale2 - scale2) == zero);
  const V flip = det < zero ? -one : one;
  tx = nx * r0x + ny * r0y + nz * r0z;
  ty = nx * r1x + ny * r1y + nz * r1z;
  tz = nx * r2x + ny * r2y + nz * r2z;
  tx *= flip, ty *= flip, tz *= flip;
  lt2 = tx * tx + ty * ty + tz * tz;
  ok &= (lt2 > zero) & ((lt2 - lt2) == zero);
}

// The lanes that are not plain, one by one; the plain ones stored as they are.
template <class V, class M>
void finish_lanes(const LowSurface& surface, const TexelSamples& samples, const Mesh& high, const Hits& hits,
                  const EncodeOptions& options, std::size_t s0, const M& ok, const V& ox, const V& oy,
                  const V& oz, Counts& counts, glm::vec3* out, bool* used) {
  constexpr int width = sizeof(V) / sizeof(float);
  for (int i = 0; i < width; ++i) {
    if (!ok[i]) {
      used[i] = sample_contribution(surface, samples, high, hits, options, true, s0 + i, counts, out[i]);
      continue;
    }
    used[i] = true;
    out[i] = glm::vec3(ox[i], oy[i], oz[i]);
  }
}

void encode_four(const LowSurface& surface, const TexelSamples& samples, const Mesh& high, const Hits& hits,
                 const EncodeOptions& options, std::size_t s0, Counts& counts, glm::vec3* out, bool* used) {
  if (!plain_samples(samples, hits, s0, 4)) {
    for (int i = 0; i < 4; ++i)
      used[i] = sample_contribution(surface, samples, high, hits, options, true, s0 + i, counts, out[i]);
    return;
  }
  Axes n, N, T, B{};
  const bool own = own_frame(options.decode), vertex = options.decode.bitangent == Bitangent::vertex;
  gather_four(surface, samples, high, hits, s0, n, N, T, own && vertex ? &B : nullptr);
  f4 tx, ty, tz, lt2;
  i4 ok;
  if (own) {
    FrameLanes<f4> f{T.x, T.y, T.z, B.x, B.y, B.z, N.x, N.y, N.z};
    f4 t2, b2, n2;
    column_squares(f, T.w, options.decode, t2, b2, n2);
    general_lanes(n.x, n.y, n.z, f, sqrt4(t2), sqrt4(b2), sqrt4(n2), options.decode, tx, ty, tz, lt2, ok);
  } else {
    inverse_lanes(n.x, n.y, n.z, N.x, N.y, N.z, T.x, T.y, T.z, T.w, tx, ty, tz, lt2, ok);
  }
  const f4 inv = splat4(1.0f) / sqrt4(lt2);
  const f4 ox = tx * inv, oy = ty * inv, oz = tz * inv;
  if (all4(ok)) {
    store3x4(out, ox, oy, oz);
    used[0] = used[1] = used[2] = used[3] = true;
    return;
  }
  finish_lanes(surface, samples, high, hits, options, s0, ok, ox, oy, oz, counts, out, used);
}

// Not with clang (only the fuzz build uses it): it rejects these AVX
// arguments in functions compiled for the baseline target.
#if defined(__x86_64__) && defined(__GNUC__) && !defined(__clang__)
#define NMBAKE_ENCODE_EIGHT 1
typedef float f8 __attribute__((vector_size(32)));
typedef std::int32_t i8 __attribute__((vector_size(32)));

[[gnu::target("avx2"), gnu::always_inline]] inline f8 join(f4 lo, f4 hi) {
  return __builtin_shufflevector(lo, hi, 0, 1, 2, 3, 4, 5, 6, 7);
}
[[gnu::target("avx2"), gnu::always_inline]] inline f4 low_half(f8 v) {
  return __builtin_shufflevector(v, v, 0, 1, 2, 3);
}
[[gnu::target("avx2"), gnu::always_inline]] inline f4 high_half(f8 v) {
  return __builtin_shufflevector(v, v, 4, 5, 6, 7);
}

// Eight samples: two groups of four gathered as encode_four() does, joined
// into eight-lane vectors for the arithmetic.
[[gnu::target("avx2")]] void encode_eight(const LowSurface& surface, const TexelSamples& samples,
                                          const Mesh& high, const Hits& hits, const EncodeOptions& options,
                                          std::size_t s0, Counts& counts, glm::vec3* out, bool* used) {
  if (!plain_samples(samples, hits, s0, 8)) {
    encode_four(surface, samples, high, hits, options, s0, counts, out, used);
    encode_four(surface, samples, high, hits, options, s0 + 4, counts, out + 4, used + 4);
    return;
  }
  Axes n0, N0, T0, B0{}, n1, N1, T1, B1{};
  const bool own = own_frame(options.decode), vertex = options.decode.bitangent == Bitangent::vertex;
  gather_four(surface, samples, high, hits, s0, n0, N0, T0, own && vertex ? &B0 : nullptr);
  gather_four(surface, samples, high, hits, s0 + 4, n1, N1, T1, own && vertex ? &B1 : nullptr);
  f8 tx, ty, tz, lt2;
  i8 ok;
  if (own) {
    FrameLanes<f8> f{join(T0.x, T1.x), join(T0.y, T1.y), join(T0.z, T1.z), join(B0.x, B1.x), join(B0.y, B1.y),
                     join(B0.z, B1.z), join(N0.x, N1.x), join(N0.y, N1.y), join(N0.z, N1.z)};
    f8 t2, b2, n2;
    column_squares(f, join(T0.w, T1.w), options.decode, t2, b2, n2);
    general_lanes(join(n0.x, n1.x), join(n0.y, n1.y), join(n0.z, n1.z), f, __builtin_ia32_sqrtps256(t2),
                  __builtin_ia32_sqrtps256(b2), __builtin_ia32_sqrtps256(n2), options.decode, tx, ty, tz, lt2,
                  ok);
  } else {
    inverse_lanes(join(n0.x, n1.x), join(n0.y, n1.y), join(n0.z, n1.z), join(N0.x, N1.x), join(N0.y, N1.y),
                  join(N0.z, N1.z), join(T0.x, T1.x), join(T0.y, T1.y), join(T0.z, T1.z), join(T0.w, T1.w),
                  tx, ty, tz, lt2, ok);
  }
  const f8 inv = (f8{} + 1.0f) / __builtin_ia32_sqrtps256(lt2);
  const f8 ox = tx * inv, oy = ty * inv, oz = tz * inv;
  if (__builtin_ia32_movmskps256(reinterpret_cast<f8>(ok)) == 0xFF) {
    store3x4(out, low_half(ox), low_half(oy), low_half(oz));
    store3x4(out + 4, high_half(ox), high_half(oy), high_half(oz));
    for (int i = 0; i < 8; ++i) used[i] = true;
    return;
  }
  finish_lanes(surface, samples, high, hits, options, s0, ok, ox, oy, oz, counts, out, used);
}

bool cpu_has_avx2() {
  static const bool has = __builtin_cpu_supports("avx2");
  return has;
}
#endif

}  // namespace

namespace {

// lanes: 1 (every sample on its own), 4, or 8 (falls back to 4 without AVX2).
// Rows [first_row, last_row) of the band: in parallel, or on the calling thread
// (encode_rows(): `out` must hold them already, as no thread may resize it).
void encode_impl(const LowSurface& surface, const TexelSamples& samples, const Mesh& high, const Hits& hits,
                 const EncodeOptions& options, Image& out, EncodeStats& stats, int lanes, int first_row,
                 int last_row, bool parallel, const glm::vec3* hit_normals = nullptr) {
  const int width = samples.width;
  const int height = samples.height;
  const int spp = samples.samples;
  const bool tangent_space = options.space == NormalSpace::tangent;
  const bool smooth = options.high_normals == HighNormals::smooth && high.has_normals();
  const bool in_lanes =
      lanes > 1 && tangent_space && smooth && options.tangent_encode == TangentEncode::inverse;
  if (tangent_space && options.decode.bitangent == Bitangent::vertex) {
    NMBAKE_CHECK(surface.bitangent.size() == surface.tangent.size(), "per-corner bitangents filled");
  }
#if NMBAKE_ENCODE_EIGHT
  const bool eight = in_lanes && lanes >= 8 && cpu_has_avx2();
#endif
  // A band of rows lands at its place in `out`, which grows to hold it.
  const int row_begin = samples.row_begin - options.out_row_begin;
  NMBAKE_CHECK(row_begin >= 0, "the band lies in the output's rows");
  if (out.width != width || out.channels != 3 || out.height < row_begin + height) {
    NMBAKE_CHECK(parallel, "encode_rows() writes into an image that holds the band");
    out.width = width;
    out.height = std::max(out.height, row_begin + height);
    out.channels = 3;
    out.pixels.resize(static_cast<std::size_t>(width) * out.height * 3, 0.0f);
  }
  float* const band_pixels = out.pixels.data() + static_cast<std::size_t>(row_begin) * width * 3;
  const glm::vec3 background = tangent_space ? glm::vec3(0.0f, 0.0f, 1.0f) : glm::vec3(0.0f);

  std::vector<Counts> row_counts(last_row - first_row);
  const std::size_t row_samples = static_cast<std::size_t>(width) * spp;

  const auto encode_rows_of = [&](const tbb::blocked_range<int>& rows) {
    // Per sample of a row: its contribution, and whether it lies in a chart
    // (neither filled first: every sample's used[] is set, and its
    // contribution wherever used[] is true; the map set calls this for
    // every block of two rows).
    std::unique_ptr<glm::vec3[]> contribution(new glm::vec3[row_samples]);
    std::unique_ptr<bool[]> used(new bool[row_samples]);
    for (int y = rows.begin(); y != rows.end(); ++y) {
      Counts& counts = row_counts[y - first_row];
      const std::size_t first = static_cast<std::size_t>(y) * row_samples;
      std::size_t k = 0;
      // A row with a given hit normal goes sample by sample (the same bits
      // for the samples without one: the lanes are the reference's arithmetic).
      const glm::vec3* row_normals = hit_normals != nullptr
                                         ? hit_normals + static_cast<std::size_t>(y - first_row) * row_samples
                                         : nullptr;
      bool given = false;
      for (std::size_t i = 0; row_normals != nullptr && i < row_samples && !given; ++i)
        given = row_normals[i] != glm::vec3(0.0f);
      if (!given) row_normals = nullptr;
      if (in_lanes && !given) {
#if NMBAKE_ENCODE_EIGHT
        if (eight) {
          for (; k + 8 <= row_samples; k += 8) {
            encode_eight(surface, samples, high, hits, options, first + k, counts, &contribution[k],
                         &used[k]);
          }
        }
#endif
        for (; k + 4 <= row_samples; k += 4) {
          encode_four(surface, samples, high, hits, options, first + k, counts, &contribution[k], &used[k]);
        }
      }
      for (; k < row_samples; ++k) {
        used[k] = sample_contribution(surface, samples, high, hits, options, smooth, first + k, counts,
                                      contribution[k], row_normals != nullptr ? &row_normals[k] : nullptr);
      }

      for (int x = 0; x < width; ++x) {
        const std::size_t texel = static_cast<std::size_t>(y) * width + x;
        glm::vec3 value = background;
        if (samples.coverage[texel]) {
          glm::vec3 sum(0.0f);
          const std::size_t at = static_cast<std::size_t>(x) * spp;
          for (int j = 0; j < spp; ++j) {
            if (used[at + j]) sum += contribution[at + j];
          }
          const float l = glm::length(sum);
          if (l > 1e-12f && std::isfinite(l)) {
            value = sum / l;
          } else {
            ++counts.zero_result;
            value = glm::vec3(0.0f, 0.0f, 1.0f);
            if (!tangent_space) {
              // The low surface's own normal: the mean of the samples' interpolated normals.
              glm::vec3 low_normal_sum(0.0f);
              for (int j = 0; j < spp; ++j) {
                const std::size_t s = texel * spp + j;
                if (samples.triangle[s] < 0) continue;
                low_normal_sum += interpolate(
                    surface.normal, 3 * static_cast<std::size_t>(samples.triangle[s]), samples.bary[s]);
              }
              const float ln = glm::length(low_normal_sum);
              if (ln > 0.0f && std::isfinite(ln)) value = low_normal_sum / ln;
            }
          }
          if (tangent_space && options.decode.rebuild_blue && !onto_upper_hemisphere(value))
            ++counts.below_horizon;
          if (tangent_space && options.green == GreenChannel::down) value.y = -value.y;
        }
        float* p = band_pixels + texel * 3;
        p[0] = 0.5f * value.x + 0.5f;
        p[1] = 0.5f * value.y + 0.5f;
        p[2] = 0.5f * value.z + 0.5f;
      }
    }
  };
  if (parallel) {
    tbb::parallel_for(tbb::blocked_range<int>(first_row, last_row), encode_rows_of);
  } else {
    encode_rows_of(tbb::blocked_range<int>(first_row, last_row));
  }
  for (const Counts& c : row_counts) {
    stats.singular_frames += c.singular;
    stats.zero_high_normals += c.zero_high;
    stats.zero_results += c.zero_result;
    stats.below_horizon += c.below_horizon;
  }
}

}  // namespace

void encode(const LowSurface& surface, const TexelSamples& samples, const Mesh& high, const Hits& hits,
            const EncodeOptions& options, Image& out, EncodeStats& stats) {
  encode_impl(surface, samples, high, hits, options, out, stats, 8, 0, samples.height, true);
}

void encode_rows(const LowSurface& surface, const TexelSamples& samples, const Mesh& high, const Hits& hits,
                 const EncodeOptions& options, Image& out, EncodeStats& stats, int row_begin, int row_end,
                 const glm::vec3* hit_normals) {
  NMBAKE_CHECK(0 <= row_begin && row_begin <= row_end && row_end <= samples.height, "rows of the band");
  encode_impl(surface, samples, high, hits, options, out, stats, 8, row_begin, row_end, false, hit_normals);
}

namespace detail {

void encode_in_lanes(const LowSurface& surface, const TexelSamples& samples, const Mesh& high,
                     const Hits& hits, const EncodeOptions& options, Image& out, EncodeStats& stats,
                     int lanes) {
  encode_impl(surface, samples, high, hits, options, out, stats, lanes, 0, samples.height, true);
}

bool encode_has_eight_lanes() {
#if NMBAKE_ENCODE_EIGHT
  return cpu_has_avx2();
#else
  return false;
#endif
}

}  // namespace detail

}  // namespace nmbake
