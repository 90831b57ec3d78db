// Stage "encode": hit normals into a float RGB image.
//
// Tangent space (default) stores the exact inverse of the MikkTSpace decode
// n = normalize(t.x T + t.y B + t.z N) with T, N interpolated and not
// normalised and B = sign * cross(N, T): t = normalize(M^-1 n_high) with
// M = [T B N] (DESIGN.md). Object space stores n_high. rgb = 0.5 n + 0.5;
// green `down` (DirectX) negates t.y (tangent space only).
// Samples of a texel are averaged in the space that is stored, then
// renormalised. A miss keeps the low normal: (0, 0, 1) in tangent space.
#pragma once

#include <cstdint>

#include "nmbake/image.hpp"
#include "nmbake/raster.hpp"
#include "nmbake/surface.hpp"
#include "nmbake/trace.hpp"

namespace nmbake {

enum class NormalSpace : std::uint8_t { tangent, object };
enum class GreenChannel : std::uint8_t { up, down };
enum class HighNormals : std::uint8_t { smooth, face };
enum class TangentEncode : std::uint8_t { inverse, transpose };  // transpose: for the method comparison only

struct EncodeOptions {
  NormalSpace space = NormalSpace::tangent;
  GreenChannel green = GreenChannel::up;
  HighNormals high_normals = HighNormals::smooth;
  TangentEncode tangent_encode = TangentEncode::inverse;
  // Map row held by row 0 of `out`: 0 for a whole map; a tile of rows
  // (task.hpp) keeps only its own rows.
  int out_row_begin = 0;
};

struct EncodeStats {
  std::uint64_t singular_frames = 0;    // det(M) ~ 0: Gram-Schmidt frame + transpose used
  std::uint64_t zero_high_normals = 0;  // interpolated high normal of length ~0: face normal used
  std::uint64_t zero_results = 0;       // averaged texel normal of length ~0: low normal kept
};

// Writes the rows of `samples` (a whole image, or the band of rows starting
// at samples.row_begin) into a width x height x 3 `out`, which is resized
// when it is too small; texels without coverage get the
// background value of the space (tangent (0, 0, 1), object (0, 0, 0)
// encoded). Also computes the world-space high normal per sample from `hits`.
void encode(const LowSurface& surface, const TexelSamples& samples, const Mesh& high, const Hits& hits,
            const EncodeOptions& options, Image& out, EncodeStats& stats);

// One tangent-space vector for a world normal, given the un-normalised frame
// at a point: the function the image encoder uses, exposed for tests and the
// evaluator. Returns false (and a Gram-Schmidt fallback result) when the
// frame is singular.
bool world_to_tangent(const glm::vec3& n, const glm::vec3& T, const glm::vec3& N, float sign,
                      TangentEncode method, glm::vec3& out);

// The MikkTSpace decode a renderer does.
glm::vec3 tangent_to_world(const glm::vec3& t, const glm::vec3& T, const glm::vec3& N, float sign);

namespace detail {
// For tests: encode() with `lanes` samples at a time: 1 (every sample on its
// own, the reference), 4 (SSE) or 8 (AVX2, where encode_has_eight_lanes();
// else 4). encode() takes 8 where it can; every width gives the same bytes.
void encode_in_lanes(const LowSurface& surface, const TexelSamples& samples, const Mesh& high, const Hits& hits,
                     const EncodeOptions& options, Image& out, EncodeStats& stats, int lanes);
bool encode_has_eight_lanes();
}  // namespace detail

}  // namespace nmbake
