// The high mesh's textures for the texture transfer maps (maps.hpp:
// base-color, roughness, metallic, emissive, opacity): read once per bake,
// decoded to linear light, mip-mapped, and sampled with a filter the size of
// the texel's footprint on the texture.
//
// Sampling (sample_texture): trilinear. The footprint of a low texel on the
// high's texture is estimated per sample from two area ratios, both exact
// for a triangle mapped affinely: a low texel covers
//   l = sqrt(low world area / (low UV area * W * H))
// scene units (the low triangle the sample lies in), and on the hit high
// triangle one scene unit covers d = sqrt(high UV area / high world area) of
// its UV square, so the texel's side on the texture is l * d * texture side
// texels. A texel of S samples gives each sample 1 / sqrt(S) of that side,
// and the texel is the mean of its samples as every map's is (maps.hpp), so
// the filter's width follows the texel's footprint however many samples it
// has. The mip level is log2 of that width; between levels and between texels
// of a level the weights are linear. Bound of the error on a texture that is
// a smooth function f of UV: the box filter of the footprint's width w (in
// UV) plus bilinear reconstruction: |error| <= (w^2 + texel^2) * max|f''| / 8
// per axis (tests/transfer_test.cpp states it for its scene).
//
// Colour textures (base colour, emission) are sRGB-decoded when read and
// filtered in linear light; data textures (roughness, metallic, opacity,
// normal) stay as stored. Textures are shared between the materials (and
// attributes) that name the same file.
#pragma once

#include <cstdint>
#include <glm/vec2.hpp>
#include <glm/vec4.hpp>
#include <map>
#include <string>
#include <utility>
#include <vector>

#include "nmbake/color.hpp"
#include "nmbake/common.hpp"
#include "nmbake/image.hpp"
#include "nmbake/material.hpp"
#include "nmbake/mesh.hpp"

namespace nmbake {

// One level of a mip chain: texels in 4 x 4 blocks, blocks in rows (a
// chart laid across the texture's rows, a rotated UV island, walks it down a
// column, and a block serves four texels of that walk from one cache line:
// BENCHMARKS.md, "Texture transfer"). A grey image keeps one float a texel,
// any other four (RGBA: grey + alpha as (g, g, g, a), RGB with a = 1).
struct MipLevel {
  int width = 0, height = 0;
  int blocks_x = 0;
  int channels = 4;  // 1 or 4
  std::vector<float> data;
  std::size_t index(int x, int y) const {
    const std::size_t block = static_cast<std::size_t>(y >> 2) * static_cast<std::size_t>(blocks_x) +
                              static_cast<std::size_t>(x >> 2);
    return (block * 16 + static_cast<std::size_t>((y & 3) * 4 + (x & 3))) *
           static_cast<std::size_t>(channels);
  }
  glm::vec4 at(int x, int y) const {
    const float* p = &data[index(x, y)];
    return channels == 1 ? glm::vec4(p[0], p[0], p[0], 1.0f) : glm::vec4(p[0], p[1], p[2], p[3]);
  }
};

// One image, mip-mapped: levels[0] as read (linear, colour decoded), each
// next level half the size (rounded down, at least 1) by a 2x2 box filter.
// `channels`: the file's (1 grey, 2 grey + alpha, 3 RGB, 4 RGBA).
struct MipTexture {
  int channels = 3;
  std::vector<MipLevel> levels;
};

// A texture file in memory; a <UDIM> path holds one image per tile found
// (tile number -> image), read from the files that exist. An image embedded
// in the mesh file (`embedded` >= 0, Mesh::embedded_images) has no path and
// one tile.
struct LoadedTexture {
  std::string path;
  int embedded = -1;
  bool color = false;               // sRGB-decoded
  std::map<int, MipTexture> tiles;  // a plain path: one entry, tile 0
  bool udim() const { return tiles.empty() || tiles.begin()->first != 0; }
};

// Builds the mip chain of `image` (level 0 moved in).
MipTexture make_mip_texture(Image image);

// The value at `uv` (nmbake's convention: v = 0 at the bottom) of `ref`'s
// texture: the transform and wrap modes of `ref` applied, `footprint` the
// filter width in UV units of the texture (see above). RGBA: a grey image
// gives (g, g, g, 1), grey + alpha (g, g, g, a), RGB (r, g, b, 1). A UDIM
// tile the texture lacks gives `missing` and sets `tile_missing`.
glm::vec4 sample_texture(const LoadedTexture& texture, const TextureRef& ref, glm::vec2 uv, float footprint,
                         bool& tile_missing);

// The channel `ref.channel` of an RGBA value: 0..3, or the Rec. 709
// luminance of RGB for -1 (and for the alpha of an image without one, which
// sample_texture gives as 1: opacity maps read alpha only where it exists).
float texture_channel(const glm::vec4& value, int channel, bool has_alpha);

// Which attributes a bake reads (the transfer maps it bakes; `normal`: the
// high's normal textures in the normal bake, encode.hpp HighNormalMaps).
struct TextureNeeds {
  bool base_color = false, roughness = false, metallic = false, emissive = false, opacity = false;
  bool normal = false;
  bool any() const { return base_color || roughness || metallic || emissive || opacity || normal; }
};

// Every texture the materials of `high` name for an attribute `needs` asks
// for, read once each (`textures`), and per material definition the index
// of each attribute's texture there (-1: none). A texture that is missing
// or unreadable, or that the loader could not point at (TextureRef::problem),
// is bad_input naming `high_path`, the material, the attribute and the path
// (for an embedded image: "embedded image N", N its index in
// Mesh::embedded_images). Embedded images are decoded from memory with the
// same checks as files (sides, size against the bytes, memory, NaN); raw
// RGBA8 ones (Assimp's uncompressed textures) are taken as 8-bit texels.
struct MaterialTextures {
  int base_color = -1, roughness = -1, metallic = -1, emissive = -1, opacity = -1, normal = -1;
};
struct TextureSet {
  std::vector<LoadedTexture> textures;
  std::vector<MaterialTextures> by_material;  // parallel to Mesh::material_defs
  std::uint64_t bytes = 0;                    // of all levels
  double seconds = 0.0;
  std::vector<std::string> files;  // the texture files read (each UDIM tile's), for the cache (cache.hpp)
};
Status load_material_textures(const Mesh& high, const std::string& high_path, const TextureNeeds& needs,
                              TextureSet& out);

}  // namespace nmbake
