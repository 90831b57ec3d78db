// A mesh's materials as its file defines them: factors and the textures that
// modulate them, for the texture transfer maps (maps.hpp: base-color,
// roughness, metallic, emissive, opacity), the id map's colours, and the
// high's normal textures. Plain data: the loaders fill it (OBJ + MTL, glTF),
// the map set reads it (textures.hpp samples the images).
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

// A texture an attribute reads: the image file and which of its channels
// hold the value. Empty path: no texture (the factor alone).
struct TextureRef {
  std::string path;  // as resolved by the loader (relative to the mesh file's folder); may hold <UDIM>
  int texcoord = 0;  // glTF texCoord set (only set 0 is read: Mesh::corner_uvs)
  // The channel a scalar reads (0 R, 1 G, 2 B, 3 A; -1: the luminance of
  // RGB, as MTL's scalar maps are read when no -imfchan is given).
  int channel = -1;
  TextureWrap wrap_u = TextureWrap::repeat, wrap_v = TextureWrap::repeat;
  // KHR_texture_transform / MTL -o -s: uv' = offset + R(rotation) * (scale * uv),
  // in the image's top-left convention of glTF (applied by the loader's rule).
  glm::vec2 offset{0.0f}, scale{1.0f};
  float rotation = 0.0f;
  // Set when the file names a texture nmbake will not read (a glTF image
  // embedded in the file or a data: URI, a uri leaving the glTF's folder):
  // why. A bake that needs it is bad_input naming the material and this.
  std::string problem;
  bool empty() const { return path.empty() && problem.empty(); }
  friend bool operator==(const TextureRef&, const TextureRef&) = default;
};

// The attributes of one material. Colours are linear (the loaders decode
// MTL's and glTF's factors as their specs say: glTF factors are linear, MTL
// Kd/Ke are read as linear too, as Blender's and three.js's importers do).
struct Material {
  std::string name;               // the Mesh::materials range name it describes
  glm::vec4 base_color{1.0f};     // RGB, A = opacity factor
  TextureRef base_color_texture;  // sRGB-encoded RGB(A)
  bool has_color = false;         // the file gave a colour (Kd, baseColorFactor): the id map uses it
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
