// Stage "encode": world-space hit normals into tangent- or object-space RGB.
//
// The tangent-space encode is the exact inverse of the MikkTSpace decode
// (Mikkelsen 2008; the "per pixel" variant of mikktspace.h): the renderer
// computes n = normalize(t.x T + t.y B + t.z N) with T and N interpolated and
// not normalised and B = sign * cross(N, T). We solve M t = n for
// M = [T B N] and normalise, so decoding our t gives back the direction of
// n_high exactly. The transpose (dot products with a normalised frame) is
// kept only to measure what it costs: it is right only for orthonormal frames.
#include "nmbake/encode.hpp"

#include <algorithm>
#include <cmath>
#include <memory>

#include <glm/geometric.hpp>
#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>

#include "simd4.hpp"

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
inline bool inverse_tangent(const glm::vec3& n, const glm::vec3& T, const glm::vec3& N, float sign, glm::vec3& t) {
  const glm::vec3 c = glm::cross(N, T);
  const glm::vec3 bn = sign * glm::cross(c, N);
  const glm::vec3 tb = sign * glm::cross(T, c);
  const float det = glm::dot(T, bn);
  const float scale2 = glm::dot(T, T) * glm::dot(c, c) * glm::dot(N, N);
  if (!(det * det > 1e-12f * scale2) || !(scale2 > 0.0f) || !std::isfinite(det) || !std::isfinite(scale2)) return false;
  t = glm::vec3(glm::dot(n, bn), glm::dot(n, c), glm::dot(n, tb));
  if (det < 0.0f) t = -t;
  return true;
}

}  // namespace

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
  std::uint64_t singular = 0, zero_high = 0, zero_result = 0;
};

// What one sample adds to its texel's sum: the hit normal in the chosen
// space (tangent: normalised per sample, so every sample weighs the same;
// object: the unit world normal). False for a sample outside the chart.
// The reference path, for every mode; encode_four() is the same arithmetic
// for the common case, four samples at a time.
bool sample_contribution(const LowSurface& surface, const TexelSamples& samples, const Mesh& high,
                         const Hits& hits, const EncodeOptions& options, bool smooth, std::size_t s,
                         Counts& counts, glm::vec3& out) {
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
  bool have = false;
  if (smooth) {
    const glm::vec2 hb = hits.bary[s];
    n_high = high.normals[h[0]] * (1.0f - hb.x - hb.y) + high.normals[h[1]] * hb.x + high.normals[h[2]] * hb.y;
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
    n_high = glm::cross(high.positions[h[1]] - high.positions[h[0]], high.positions[h[2]] - high.positions[h[0]]);
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
  if (options.tangent_encode == TangentEncode::inverse && inverse_tangent(n_high, glm::vec3(tw), N, sign, t)) {
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

// Four consecutive samples in SIMD lanes (GCC vector extensions; SSE on
// x86-64), for the default mode: tangent space, smooth high normals, the
// exact inverse. Each lane does exactly the operations of
// sample_contribution(), in the same order and without fused multiply-adds,
// so results are bit-identical to it. A lane that is not the plain case (no
// sample, a miss, a zero high normal, a singular frame) is redone by
// sample_contribution(), which also counts it.
void encode_four(const LowSurface& surface, const TexelSamples& samples, const Mesh& high, const Hits& hits,
                 const EncodeOptions& options, std::size_t s0, Counts& counts, glm::vec3* out, bool* used) {
  bool plain = true;
  for (int i = 0; i < 4; ++i) plain = plain && samples.triangle[s0 + i] >= 0 && hits.triangle[s0 + i] >= 0;
  if (!plain) {
    for (int i = 0; i < 4; ++i)
      used[i] = sample_contribution(surface, samples, high, hits, options, true, s0 + i, counts, out[i]);
    return;
  }
  f4 high_n[4];
  for (int i = 0; i < 4; ++i) {
    const std::uint32_t* h = &high.indices[3 * static_cast<std::size_t>(hits.triangle[s0 + i])];
    high_n[i] = corner_mix(high.normals[h[0]], high.normals[h[1]], high.normals[h[2]], hits.bary[s0 + i]);
  }
  const Axes n = transpose(high_n[0], high_n[1], high_n[2], high_n[3]);
  // The low frame: four samples on one low triangle (nearly all groups) are
  // interpolated across the lanes, others lane by lane; the same operations.
  Axes N, T;
  const i4 low = load4i(&samples.triangle[s0]);
  if (all4(low == splat4i(low[0]))) {
    const std::size_t base = 3 * static_cast<std::size_t>(low[0]);
    f4 bx, by;
    load_bary4(&samples.bary[s0], bx, by);
    const f4 w0 = splat4(1.0f) - bx - by;
    N = mix_axes(&surface.normal[base], w0, bx, by);
    T = mix_axes(&surface.tangent[base], w0, bx, by);
  } else {
    f4 low_n[4], low_t[4];
    for (int i = 0; i < 4; ++i) {
      const std::size_t base = 3 * static_cast<std::size_t>(samples.triangle[s0 + i]);
      const glm::vec2 b = samples.bary[s0 + i];
      low_n[i] = corner_mix(&surface.normal[base], b);
      low_t[i] = corner_mix(surface.tangent[base], surface.tangent[base + 1], surface.tangent[base + 2], b);
    }
    N = transpose(low_n[0], low_n[1], low_n[2], low_n[3]);
    T = transpose(low_t[0], low_t[1], low_t[2], low_t[3]);
  }
  const f4 one = {1.0f, 1.0f, 1.0f, 1.0f}, zero = {0.0f, 0.0f, 0.0f, 0.0f};
  const f4 l2 = n.x * n.x + n.y * n.y + n.z * n.z;
  i4 ok = (l2 > f4{1e-24f, 1e-24f, 1e-24f, 1e-24f}) & finite4(l2);
  // inverse_tangent(): c = N x T, bn = sign (c x N), tb = sign (T x c).
  const f4 sign = T.w < zero ? -one : one;
  const f4 cx = N.y * T.z - T.y * N.z, cy = N.z * T.x - T.z * N.x, cz = N.x * T.y - T.x * N.y;
  const f4 bnx = sign * (cy * N.z - N.y * cz), bny = sign * (cz * N.x - N.z * cx), bnz = sign * (cx * N.y - N.x * cy);
  const f4 tbx = sign * (T.y * cz - cy * T.z), tby = sign * (T.z * cx - cz * T.x), tbz = sign * (T.x * cy - cx * T.y);
  const f4 det = T.x * bnx + T.y * bny + T.z * bnz;
  const f4 scale2 = (T.x * T.x + T.y * T.y + T.z * T.z) * (cx * cx + cy * cy + cz * cz) * (N.x * N.x + N.y * N.y + N.z * N.z);
  const f4 eps = {1e-12f, 1e-12f, 1e-12f, 1e-12f};
  ok &= (det * det > eps * scale2) & (scale2 > zero) & finite4(det) & finite4(scale2);
  const f4 flip = det < zero ? -one : one;
  f4 tx = n.x * bnx + n.y * bny + n.z * bnz, ty = n.x * cx + n.y * cy + n.z * cz, tz = n.x * tbx + n.y * tby + n.z * tbz;
  // t = -t as a multiplication by -1 is exact, as is by +1.
  tx *= flip, ty *= flip, tz *= flip;
  const f4 lt2 = tx * tx + ty * ty + tz * tz;
  ok &= (lt2 > zero) & finite4(lt2);
  const f4 inv = one / sqrt4(lt2);
  const f4 ox = tx * inv, oy = ty * inv, oz = tz * inv;
  if (all4(ok)) {
    store3x4(out, ox, oy, oz);
    used[0] = used[1] = used[2] = used[3] = true;
    return;
  }
  for (int i = 0; i < 4; ++i) {
    if (!ok[i]) {
      used[i] = sample_contribution(surface, samples, high, hits, options, true, s0 + i, counts, out[i]);
      continue;
    }
    used[i] = true;
    out[i] = glm::vec3(ox[i], oy[i], oz[i]);
  }
}

}  // namespace

namespace {

void encode_impl(const LowSurface& surface, const TexelSamples& samples, const Mesh& high, const Hits& hits,
                 const EncodeOptions& options, Image& out, EncodeStats& stats, bool per_sample) {
  const int width = samples.width;
  const int height = samples.height;
  const int spp = samples.samples;
  const bool tangent_space = options.space == NormalSpace::tangent;
  const bool smooth = options.high_normals == HighNormals::smooth && high.has_normals();
  const bool four_at_a_time =
      !per_sample && tangent_space && smooth && options.tangent_encode == TangentEncode::inverse;
  // A band of rows lands at its place in `out`, which grows to hold it.
  const int row_begin = samples.row_begin;
  if (out.width != width || out.channels != 3 || out.height < row_begin + height) {
    out.width = width;
    out.height = std::max(out.height, row_begin + height);
    out.channels = 3;
    out.pixels.resize(static_cast<std::size_t>(width) * out.height * 3, 0.0f);
  }
  float* const band_pixels = out.pixels.data() + static_cast<std::size_t>(row_begin) * width * 3;
  const glm::vec3 background = tangent_space ? glm::vec3(0.0f, 0.0f, 1.0f) : glm::vec3(0.0f);

  std::vector<Counts> row_counts(height);
  const std::size_t row_samples = static_cast<std::size_t>(width) * spp;

  tbb::parallel_for(tbb::blocked_range<int>(0, height), [&](const tbb::blocked_range<int>& rows) {
    // Per sample of a row: its contribution, and whether it lies in a chart.
    std::vector<glm::vec3> contribution(row_samples);
    std::unique_ptr<bool[]> used(new bool[row_samples]);
    for (int y = rows.begin(); y != rows.end(); ++y) {
      Counts& counts = row_counts[y];
      const std::size_t first = static_cast<std::size_t>(y) * row_samples;
      std::size_t k = 0;
      if (four_at_a_time) {
        for (; k + 4 <= row_samples; k += 4) {
          encode_four(surface, samples, high, hits, options, first + k, counts, &contribution[k], &used[k]);
        }
      }
      for (; k < row_samples; ++k) {
        used[k] = sample_contribution(surface, samples, high, hits, options, smooth, first + k, counts, contribution[k]);
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
                low_normal_sum += interpolate(surface.normal, 3 * static_cast<std::size_t>(samples.triangle[s]),
                                              samples.bary[s]);
              }
              const float ln = glm::length(low_normal_sum);
              if (ln > 0.0f && std::isfinite(ln)) value = low_normal_sum / ln;
            }
          }
          if (tangent_space && options.green == GreenChannel::down) value.y = -value.y;
        }
        float* p = band_pixels + texel * 3;
        p[0] = 0.5f * value.x + 0.5f;
        p[1] = 0.5f * value.y + 0.5f;
        p[2] = 0.5f * value.z + 0.5f;
      }
    }
  });
  for (const Counts& c : row_counts) {
    stats.singular_frames += c.singular;
    stats.zero_high_normals += c.zero_high;
    stats.zero_results += c.zero_result;
  }
}

}  // namespace

void encode(const LowSurface& surface, const TexelSamples& samples, const Mesh& high, const Hits& hits,
            const EncodeOptions& options, Image& out, EncodeStats& stats) {
  encode_impl(surface, samples, high, hits, options, out, stats, false);
}

namespace detail {

void encode_per_sample(const LowSurface& surface, const TexelSamples& samples, const Mesh& high, const Hits& hits,
                       const EncodeOptions& options, Image& out, EncodeStats& stats) {
  encode_impl(surface, samples, high, hits, options, out, stats, true);
}

}  // namespace detail

}  // namespace nmbake
