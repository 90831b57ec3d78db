// Stage "encode": hit normals into a float RGB image.
//
// Tangent space (default) stores the exact inverse of the MikkTSpace decode
// n = normalize(t.x T + t.y B + t.z N) with T, N interpolated and not
// normalised and B = sign * cross(N, T): t = normalize(M^-1 n_high) with
// M = [T B N] (DESIGN.md). Object space stores n_high. rgb = 0.5 n + 0.5;
// green `down` (DirectX) negates t.y (tangent space only).
// Samples of a texel are averaged in the space that is stored, then
// renormalised. A miss keeps the low normal: (0, 0, 1) in tangent space.
//
// Engines do not all decode that way (preset.hpp): NormalDecode says how the
// renderer the map is for decodes it, and the encode stores the exact inverse
// of that decode instead:
//  * bitangent `vertex`: B is computed per vertex, B_c = sign_c cross(N_c, T_c)
//    (LowSurface::bitangent), and interpolated like T and N; `pixel` (the
//    default, MikkTSpace's own) computes B = sign cross(N, T) from the
//    interpolated N and T;
//  * unit_frame: the renderer normalises the interpolated T, B and N before
//    the decode (n = normalize(t.x T/|T| + t.y B/|B| + t.z N/|N|));
//  * rebuild_blue: the renderer ignores the blue channel and rebuilds
//    z = sqrt(max(0, 1 - x^2 - y^2)) (two-channel BC5 / RGTC maps): a texel
//    whose t.z < 0 (below the low surface's horizon, which no such decode can
//    give back) is stored on the horizon, (x, y) normalised and z = 0, and
//    counted; every other texel is already the unit vector the decode rebuilds.
// For any decode: t = normalize(M^-1 n_high), M = [T B N] with the columns
// the renderer uses (Cramer's rule with the rows B x N, N x T, T x B).
#pragma once

#include <cstddef>
#include <cstdint>
#include <string>

#include "nmbake/image.hpp"
#include "nmbake/raster.hpp"
#include "nmbake/surface.hpp"
#include "nmbake/trace.hpp"
#include "nmbake/words.hpp"

namespace nmbake {

enum class NormalSpace : std::uint8_t { tangent, object };
inline constexpr Word<NormalSpace> kNormalSpaceWords[] = {
    {"tangent", NormalSpace::tangent, "in the low mesh's MikkTSpace frame"},
    {"object", NormalSpace::object, "in the mesh's own axes"},
};
NMBAKE_WORDS(NormalSpace, kNormalSpaceWords)

enum class GreenChannel : std::uint8_t { up, down };
inline constexpr Word<GreenChannel> kGreenChannelWords[] = {
    {"up", GreenChannel::up, "OpenGL: Blender, Unity, glTF, Maya"},
    {"down", GreenChannel::down, "DirectX: Unreal, 3ds Max"},
    {"opengl", GreenChannel::up, "", WordUse::alias},
    {"directx", GreenChannel::down, "", WordUse::alias},
};
NMBAKE_WORDS(GreenChannel, kGreenChannelWords)

enum class HighNormals : std::uint8_t { smooth, face };
inline constexpr Word<HighNormals> kHighNormalsWords[] = {
    {"smooth", HighNormals::smooth, "interpolated vertex normals"},
    {"face", HighNormals::face, "the hit triangle's own normal"},
};
NMBAKE_WORDS(HighNormals, kHighNormalsWords)

// Whether the hit normal carries the high's own normal textures (Material::
// normal_texture: OBJ + MTL `norm` / `map_Bump -bm`, glTF `normalTexture`):
// the high's shading normal perturbed in the high's MikkTSpace frame (from
// its corner UVs), as a renderer of the high would show it. `auto` (the
// default): on when a material the high's triangles use names a normal
// texture; an artist who put a detail normal map on the high expects it in
// the bake. (xNormal, Marmoset Toolbag and Substance bake the high's
// geometry alone unless told otherwise; a high without normal textures
// bakes the same bytes either way.)
enum class HighNormalMaps : std::uint8_t { automatic, on, off };
inline constexpr Word<HighNormalMaps> kHighNormalMapsWords[] = {
    {"auto", HighNormalMaps::automatic, "on when a high material names a normal texture"},
    {"on", HighNormalMaps::on, "the high's normal textures perturb its normals"},
    {"off", HighNormalMaps::off, "the high's geometry alone"},
};
NMBAKE_WORDS(HighNormalMaps, kHighNormalMapsWords)

enum class TangentEncode : std::uint8_t { inverse, transpose };  // transpose: for the method comparison only
inline constexpr Word<TangentEncode> kTangentEncodeWords[] = {
    {"inverse", TangentEncode::inverse, "the exact inverse of the decode"},
    {"transpose", TangentEncode::transpose, "dot products (for comparison only)"},
};
NMBAKE_WORDS(TangentEncode, kTangentEncodeWords)

enum class Bitangent : std::uint8_t { pixel, vertex };
inline constexpr Word<Bitangent> kBitangentWords[] = {
    {"pixel", Bitangent::pixel, "sign * cross(N, T) from the interpolated N, T"},
    {"vertex", Bitangent::vertex, "per vertex, interpolated"},
};
NMBAKE_WORDS(Bitangent, kBitangentWords)

// How the renderer a map is baked for decodes it (see the top of this file).
// The default is MikkTSpace's per-pixel decode, what nmbake always baked.
struct NormalDecode {
  Bitangent bitangent = Bitangent::pixel;
  bool unit_frame = false;    // T, B, N normalised before the decode
  bool rebuild_blue = false;  // z rebuilt from x and y; blue ignored
  bool is_default() const { return bitangent == Bitangent::pixel && !unit_frame && !rebuild_blue; }
  bool operator==(const NormalDecode&) const = default;
};
// The words of the decode's other two rules (NormalDecode::unit_frame, rebuild_blue).
inline constexpr Word<bool> kFrameRuleWords[] = {
    {"raw", false, "T, B, N as interpolated"},
    {"normalized", true, "T, B, N normalised before the decode"},
    {"normalised", true, "", WordUse::alias},
};
inline constexpr Word<bool> kBlueRuleWords[] = {
    {"stored", false, "z read from blue"},
    {"rebuilt", true, "z = sqrt(1 - x^2 - y^2) (BC5)"},
};

struct EncodeOptions {
  NormalSpace space = NormalSpace::tangent;
  GreenChannel green = GreenChannel::up;
  HighNormals high_normals = HighNormals::smooth;
  TangentEncode tangent_encode = TangentEncode::inverse;
  NormalDecode decode;  // tangent space only
  // Map row held by row 0 of `out`: 0 for a whole map; a tile of rows
  // (task.hpp) keeps only its own rows.
  int out_row_begin = 0;
};

struct EncodeStats {
  std::uint64_t singular_frames = 0;    // det(M) ~ 0: Gram-Schmidt frame + transpose used
  std::uint64_t zero_high_normals = 0;  // interpolated high normal of length ~0: face normal used
  std::uint64_t zero_results = 0;       // averaged texel normal of length ~0: low normal kept
  std::uint64_t below_horizon = 0;      // rebuild_blue: texels with t.z < 0 stored on the horizon
  // The high's normal textures (HighNormalMaps), per sample: perturbed,
  // and the fallbacks that kept the unperturbed high normal.
  std::uint64_t high_normal_map_samples = 0;             // hits whose material has a normal texture
  std::uint64_t high_normal_map_no_uv = 0;               // hit triangle without UV area: unperturbed
  std::uint64_t high_normal_map_degenerate_tangent = 0;  // high frame singular: unperturbed
  std::uint64_t high_normal_map_zero_normal = 0;         // texture or perturbed normal of length ~0
  std::uint64_t high_normal_map_tile_missing = 0;        // UV in a UDIM tile the texture lacks
  void add(const EncodeStats& more) {
    high_normal_map_samples += more.high_normal_map_samples;
    high_normal_map_no_uv += more.high_normal_map_no_uv;
    high_normal_map_degenerate_tangent += more.high_normal_map_degenerate_tangent;
    high_normal_map_zero_normal += more.high_normal_map_zero_normal;
    high_normal_map_tile_missing += more.high_normal_map_tile_missing;
    singular_frames += more.singular_frames;
    zero_high_normals += more.zero_high_normals;
    zero_results += more.zero_results;
    below_horizon += more.below_horizon;
  }
};

// Writes the rows of `samples` (a whole image, or the band of rows starting
// at samples.row_begin) into a width x height x 3 `out`, which is resized
// when it is too small; texels without coverage get the
// background value of the space (tangent (0, 0, 1), object (0, 0, 0)
// encoded). Also computes the world-space high normal per sample from `hits`.
void encode(const LowSurface& surface, const TexelSamples& samples, const Mesh& high, const Hits& hits,
            const EncodeOptions& options, Image& out, EncodeStats& stats);

// encode() for rows [row_begin, row_end) of the band in `samples`, on the
// calling thread, its counts added to `stats`: for a caller that runs
// several maps over a block of rows at a time (MapSet), so each reads the
// block's samples and hits while they are in cache. `out` must hold the
// band's rows already (encode() sizes it; blocks in parallel must not).
// `hit_normals` (optional): per sample of rows [row_begin, row_end), from
// the first sample of row_begin, a unit world-space high normal that
// replaces the interpolated one (the high's normal textures applied), or
// (0, 0, 0) where the sample keeps it; samples with one are encoded one by
// one (the reference path), the others exactly as without it.
void encode_rows(const LowSurface& surface, const TexelSamples& samples, const Mesh& high, const Hits& hits,
                 const EncodeOptions& options, Image& out, EncodeStats& stats, int row_begin, int row_end,
                 const glm::vec3* hit_normals = nullptr);

// One tangent-space vector for a world normal, given the un-normalised frame
// at a point: the function the image encoder uses, exposed for tests and the
// evaluator. Returns false (and a Gram-Schmidt fallback result) when the
// frame is singular.
bool world_to_tangent(const glm::vec3& n, const glm::vec3& T, const glm::vec3& N, float sign,
                      TangentEncode method, glm::vec3& out);

// The MikkTSpace decode a renderer does.
glm::vec3 tangent_to_world(const glm::vec3& t, const glm::vec3& T, const glm::vec3& N, float sign);

// The same pair for any decode: B is the bitangent the renderer uses (sign
// cross(N, T) per pixel, or the interpolated per-vertex one), unit_frame as
// in NormalDecode. world_to_tangent returns false (and the Gram-Schmidt
// fallback of the per-pixel frame) when [T B N] is singular. rebuild_blue is
// not applied here (it acts on the stored texel, see encode()).
bool world_to_tangent(const glm::vec3& n, const glm::vec3& T, const glm::vec3& B, const glm::vec3& N,
                      float sign, bool unit_frame, glm::vec3& out);
glm::vec3 tangent_to_world(const glm::vec3& t, const glm::vec3& T, const glm::vec3& B, const glm::vec3& N,
                           bool unit_frame);
// The bitangent a decode uses at barycentrics b of low triangle `triangle`.
glm::vec3 decode_bitangent(const LowSurface& surface, std::size_t triangle, glm::vec2 b, Bitangent rule);
// What rebuild_blue stores for a unit t: t itself when t.z >= 0, else the
// horizon direction (x, y, 0) normalised ((0, 0, 1) when x = y = 0). False
// when t was moved.
bool onto_upper_hemisphere(glm::vec3& t);

namespace detail {
// For tests: encode() with `lanes` samples at a time: 1 (every sample on its
// own, the reference), 4 (SSE) or 8 (AVX2, where encode_has_eight_lanes();
// else 4). encode() takes 8 where it can; every width gives the same bytes.
void encode_in_lanes(const LowSurface& surface, const TexelSamples& samples, const Mesh& high,
                     const Hits& hits, const EncodeOptions& options, Image& out, EncodeStats& stats,
                     int lanes);
bool encode_has_eight_lanes();
}  // namespace detail

}  // namespace nmbake
