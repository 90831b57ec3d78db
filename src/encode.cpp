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

#include <glm/geometric.hpp>
#include <tbb/parallel_for.h>

namespace nmbake {

namespace {

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

void encode(const LowSurface& surface, const TexelSamples& samples, const Mesh& high, const Hits& hits,
            const EncodeOptions& options, Image& out, EncodeStats& stats) {
  const int width = samples.width;
  const int height = samples.height;
  const int spp = samples.samples;
  const bool tangent_space = options.space == NormalSpace::tangent;
  const bool smooth = options.high_normals == HighNormals::smooth && high.has_normals();
  const bool inverse = options.tangent_encode == TangentEncode::inverse;
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

  struct RowCounts {
    std::uint64_t singular = 0, zero_high = 0, zero_result = 0;
  };
  std::vector<RowCounts> row_counts(height);

  tbb::parallel_for(0, height, [&](int y) {
    RowCounts& counts = row_counts[y];
    for (int x = 0; x < width; ++x) {
      const std::size_t texel = static_cast<std::size_t>(y) * width + x;
      glm::vec3 value = background;
      if (samples.coverage[texel]) {
        glm::vec3 sum(0.0f);
        glm::vec3 low_normal_sum(0.0f);
        for (int k = 0; k < spp; ++k) {
          const std::size_t s = texel * spp + k;
          const std::int32_t tri = samples.triangle[s];
          if (tri < 0) continue;
          const std::size_t base = 3 * static_cast<std::size_t>(tri);
          const glm::vec2 b = samples.bary[s];
          const glm::vec3 N = interpolate(surface.normal, base, b);
          low_normal_sum += N;
          const std::int32_t hit = hits.triangle[s];
          if (hit < 0) {
            // A miss keeps the low surface's own normal.
            if (tangent_space) {
              sum += glm::vec3(0.0f, 0.0f, 1.0f);
            } else {
              const float ln = glm::length(N);
              sum += ln > 0.0f && std::isfinite(ln) ? N / ln : glm::vec3(0.0f, 0.0f, 1.0f);
            }
            continue;
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
            sum += n_high;
            continue;
          }
          const glm::vec4 tw = interpolate(surface.tangent, base, b);
          const float sign = tw.w < 0.0f ? -1.0f : 1.0f;
          glm::vec3 t;
          if (inverse && inverse_tangent(n_high, glm::vec3(tw), N, sign, t)) {
            // The sample's direction, normalised so every sample weighs the same.
            const float lt2 = glm::dot(t, t);
            if (lt2 > 0.0f && std::isfinite(lt2)) {
              sum += t * (1.0f / std::sqrt(lt2));
              continue;
            }
          }
          if (!world_to_tangent(n_high, glm::vec3(tw), N, sign, options.tangent_encode, t)) ++counts.singular;
          sum += t;
        }
        const float l = glm::length(sum);
        if (l > 1e-12f && std::isfinite(l)) {
          value = sum / l;
        } else {
          ++counts.zero_result;
          if (tangent_space) {
            value = glm::vec3(0.0f, 0.0f, 1.0f);
          } else {
            const float ln = glm::length(low_normal_sum);
            value = ln > 0.0f && std::isfinite(ln) ? low_normal_sum / ln : glm::vec3(0.0f, 0.0f, 1.0f);
          }
        }
        if (tangent_space && options.green == GreenChannel::down) value.y = -value.y;
      }
      float* p = band_pixels + texel * 3;
      p[0] = 0.5f * value.x + 0.5f;
      p[1] = 0.5f * value.y + 0.5f;
      p[2] = 0.5f * value.z + 0.5f;
    }
  });
  for (const RowCounts& c : row_counts) {
    stats.singular_frames += c.singular;
    stats.zero_high_normals += c.zero_high;
    stats.zero_results += c.zero_result;
  }
}

}  // namespace nmbake
