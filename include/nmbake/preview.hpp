// Looking at a bake. For now one view: the normal map itself lit per pixel
// with Blinn-Phong in tangent space (as in the classic normal-mapping
// articles): a flat surface seen head-on, a raking key light and a fill, so
// craters, bevels and seams stand out. Rendering the low mesh lit with the
// map next to the lit high mesh is `nmbake preview --low/--high` (to come).
#pragma once

#include <glm/vec3.hpp>

#include "nmbake/encode.hpp"
#include "nmbake/image.hpp"

namespace nmbake {

struct LitMapOptions {
  glm::vec3 light{-0.6f, 0.6f, 0.55f};  // tangent space, towards the light; normalised inside
  GreenChannel green = GreenChannel::up;
  float shininess = 32.0f;
  int max_size = 1024;  // the longer side is box-filtered down to at most this
};

// `map` is an encoded tangent-space normal map (rgb = 0.5 n + 0.5). Returns
// an RGB image in 0..1 (display-ready, sRGB-ish gamma applied).
Image render_lit_map(const Image& map, const LitMapOptions& options);

}  // namespace nmbake
