// A mesh's materials as its file defines them: factors and the textures that
// modulate them, for the texture transfer maps (maps.hpp: base-color,
// roughness, metallic, emissive, opacity), the id map's colours, and the
// high's normal textures. Plain data: the loaders fill it (OBJ + MTL, glTF,
// FBX and Collada through Assimp), the map set reads it (textures.hpp
// decodes and samples the images).
//
// Images embedded in the mesh file (a .glb's buffer views, glTF data: URIs,
// FBX embedded media, Assimp's aiScene::mTextures) are held by the Mesh
// (Mesh::embedded_images) as the file stores them, still compressed; a
// TextureRef points at one by index (TextureRef::embedded), and
// load_material_textures() decodes it as it decodes a file.
#pragma once

#include <cstdint>
#include <glm/vec2.hpp>
#include <glm/vec3.hpp>
#include <glm/vec4.hpp>
#include <string>
#include <vector>

#include "nmbake/words.hpp"

namespace nmbake {

// How texture coordinates outside [0, 1] are read (glTF sampler wrap modes;
// MTL `-clamp on` is clamp).
enum class TextureWrap : std::uint8_t { repeat, clamp, mirror };

// An image stored inside the mesh file. Either compressed (`width` 0:
// `bytes` is a whole image file, PNG, JPEG, ..., decoded by OpenImageIO
// from memory; `format` the file's hint: glTF's mimeType or Assimp's
// achFormatHint, e.g. "png", "image/jpeg", may be empty) or raw (Assimp's
// uncompressed aiTexel: `bytes` is width * height * 4 bytes of 8-bit RGBA,
// rows from the top, converted from Assimp's BGRA by the loader).
// The texture reads it as an sRGB-encoded or data image like any file.
struct EmbeddedImage {
  std::string format;
  int width = 0, height = 0;
  std::vector<unsigned char> bytes;
  friend bool operator==(const EmbeddedImage&, const EmbeddedImage&) = default;
};

// A texture an attribute reads: the image file (or embedded image) and which
// of its channels hold the value. Empty path, no embedded image: no texture
// (the factor alone).
struct TextureRef {
  std::string path;  // as resolved by the loader (relative to the mesh file's folder); may hold <UDIM>
  // >= 0: the image is Mesh::embedded_images[embedded] (and `path` is empty).
  int embedded = -1;
  int texcoord = 0;  // glTF texCoord / Assimp UV channel (only set 0 is read: Mesh::corner_uvs)
  // The channel a scalar reads (0 R, 1 G, 2 B, 3 A; -1: the luminance of
  // RGB, as MTL's scalar maps are read when no -imfchan is given).
  int channel = -1;
  TextureWrap wrap_u = TextureWrap::repeat, wrap_v = TextureWrap::repeat;
  // KHR_texture_transform / MTL -o -s: uv' = offset + R(rotation) * (scale * uv),
  // in the image's top-left convention of glTF (applied by the loader's rule).
  glm::vec2 offset{0.0f}, scale{1.0f};
  float rotation = 0.0f;
  // Set when the file names a texture nmbake will not read (a glTF uri
  // leaving the glTF's folder, a buffer view out of its buffer, an Assimp
  // embedded texture that does not exist): why. A bake that needs it is
  // bad_input naming the material and this.
  std::string problem;
  bool empty() const { return path.empty() && embedded < 0 && problem.empty(); }
  friend bool operator==(const TextureRef&, const TextureRef&) = default;
};

// The attributes of one material. Colours are linear (the loaders decode
// MTL's and glTF's factors as their specs say: glTF factors are linear, MTL
// Kd/Ke are read as linear too, as Blender's and three.js's importers do;
// Assimp's diffuse and emissive colours likewise, as stored).
struct Material {
  std::string name;               // the Mesh::materials range name it describes
  glm::vec4 base_color{1.0f};     // RGB, A = opacity factor
  TextureRef base_color_texture;  // sRGB-encoded RGB(A)
  bool has_color =
      false;  // the file gave a colour (Kd, baseColorFactor, Assimp's diffuse): the id map uses it
  float roughness = 1.0f;
  TextureRef roughness_texture;  // linear, `channel` (glTF: G of metallicRoughness)
  float metallic = 0.0f;
  TextureRef metallic_texture;  // linear, `channel` (glTF: B of metallicRoughness)
  glm::vec3 emissive{0.0f};
  TextureRef emissive_texture;  // sRGB-encoded RGB
  TextureRef opacity_texture;   // linear, `channel` (glTF: A of the base colour texture; MTL map_d)
  TextureRef normal_texture;    // tangent space, +Y up (glTF, MTL norm / map_Bump -bm)
  float normal_scale = 1.0f;
  friend bool operator==(const Material&, const Material&) = default;
};

}  // namespace nmbake
