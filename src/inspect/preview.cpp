// Per-pixel Blinn-Phong of a tangent-space normal map (Blinn 1977; the
// lighting of Sanglard's "Bump Mapping with GLSL" and Saga's "Experimenting
// with Normal Mapping"): diffuse = max(n.l, 0), specular = max(n.h, 0)^s,
// with the eye straight above the surface.
#include "nmbake/preview.hpp"

#include <tbb/parallel_for.h>

#include <algorithm>
#include <cmath>
#include <glm/geometric.hpp>

namespace nmbake {

Image render_lit_map(const Image& map, const LitMapOptions& options) {
  const int factor = std::max(1, (std::max(map.width, map.height) + options.max_size - 1) / options.max_size);
  Image out;
  out.width = map.width / factor;
  out.height = map.height / factor;
  out.channels = 3;
  out.pixels.assign(static_cast<std::size_t>(out.width) * out.height * 3, 0.0f);
  const glm::vec3 key = glm::normalize(options.light);
  const glm::vec3 fill = glm::normalize(glm::vec3(-key.x, -key.y, 1.5f));
  const glm::vec3 eye(0.0f, 0.0f, 1.0f);
  const glm::vec3 half = glm::normalize(key + eye);
  const float flip = options.green == GreenChannel::down ? -1.0f : 1.0f;

  tbb::parallel_for(0, out.height, [&](int y) {
    for (int x = 0; x < out.width; ++x) {
      glm::vec3 colour(0.0f);
      for (int dy = 0; dy < factor; ++dy) {
        for (int dx = 0; dx < factor; ++dx) {
          const float* p = map.at(x * factor + dx, y * factor + dy);
          glm::vec3 n(2.0f * p[0] - 1.0f, flip * (2.0f * p[1] - 1.0f),
                      map.channels > 2 ? 2.0f * p[2] - 1.0f : 1.0f);
          const float l = glm::length(n);
          n = l > 1e-6f && std::isfinite(l) ? n / l : glm::vec3(0.0f, 0.0f, 1.0f);
          const float diffuse = std::max(glm::dot(n, key), 0.0f);
          const float specular = std::pow(std::max(glm::dot(n, half), 0.0f), options.shininess);
          const float shade = 0.06f + 0.8f * diffuse + 0.15f * std::max(glm::dot(n, fill), 0.0f);
          colour += glm::vec3(0.93f, 0.9f, 0.85f) * shade + glm::vec3(0.25f * specular);
        }
      }
      colour /= static_cast<float>(factor * factor);
      float* o = out.at(x, y);
      for (int c = 0; c < 3; ++c) o[c] = std::pow(std::clamp(colour[c], 0.0f, 1.0f), 1.0f / 2.2f);
    }
  });
  return out;
}

}  // namespace nmbake
