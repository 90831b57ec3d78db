// Pieces shared by the 3D views of preview.hpp (internal to the library):
// the camera, the Blinn-Phong lights, a primary-ray scene that hides Embree,
// a 5x7 bitmap font, lines and the heat colour ramp.
#pragma once

#include <cstdint>
#include <glm/vec2.hpp>
#include <glm/vec3.hpp>
#include <memory>
#include <string>
#include <vector>

#include "nmbake/common.hpp"
#include "nmbake/image.hpp"
#include "nmbake/mesh.hpp"
#include "nmbake/preview.hpp"

namespace nmbake::preview_detail {

inline const glm::vec3 kBackground{0.11f, 0.115f, 0.125f};  // display values (after gamma)

struct Camera {
  glm::vec3 eye{0.0f};
  glm::vec3 forward{0.0f, 0.0f, -1.0f}, right{1.0f, 0.0f, 0.0f}, up{0.0f, 1.0f, 0.0f};
  float tan_half_fov = 0.0f;
  int size = 0;
  // Unit direction of the ray through image point (x, y), in pixels, y down.
  glm::vec3 direction(float x, float y) const;
  // Camera-space depth (along forward) and image position of a world point;
  // false when behind the camera.
  bool project(const glm::vec3& p, glm::vec2& pixel, float& depth) const;
  // Camera space (x right, y up, z towards the viewer) to world.
  glm::vec3 to_world(const glm::vec3& v) const { return v.x * right + v.y * up - v.z * forward; }
};

// The sphere around the centre of the bounding box of `point_sets` that holds
// every point (tighter than the box's own sphere for round objects).
struct Framing {
  glm::vec3 centre{0.0f};
  float radius = 0.0f;
};
Framing frame_points(const std::vector<const std::vector<glm::vec3>*>& point_sets);
// Frames that sphere for `view` at `yaw_degrees`.
Camera make_camera(const Framing& framing, const ViewOptions& view, float yaw_degrees);

struct Lights {
  glm::vec3 key{0.0f}, fill{0.0f};  // world, unit, towards the light
};
Lights make_lights(const Camera& camera, const ViewOptions& view);

// Blinn-Phong (Blinn 1977) with a key light (diffuse + specular highlight), a
// weaker fill (diffuse) and ambient, for a grey material; `to_eye` unit.
// Returns display values (gamma 1/2.2), in 0..1.
glm::vec3 shade(const glm::vec3& normal, const glm::vec3& to_eye, const Lights& lights);

// The high normal at a hit, as encode() computes it: interpolated vertex
// normals, else the face normal (`fallback` set), else `otherwise`.
glm::vec3 high_normal(const Mesh& high, std::int32_t tri, glm::vec2 b, const glm::vec3& otherwise,
                      bool& fallback);

// One triangle soup or indexed mesh for primary rays. Triangle ids and
// barycentrics (weights of corners 1 and 2) follow the given index order.
struct RayHit {
  std::int32_t triangle = -1;
  glm::vec2 bary{0.0f};
  float t = 0.0f;
};
class RayScene {
 public:
  RayScene();
  ~RayScene();
  RayScene(const RayScene&) = delete;
  RayScene& operator=(const RayScene&) = delete;
  // The arrays must outlive the scene; `positions` needs one spare element of
  // capacity (Embree reads 16 bytes for the last float3).
  Status build(const std::vector<glm::vec3>& positions, const std::vector<std::uint32_t>& indices);
  RayHit intersect(const glm::vec3& origin, const glm::vec3& direction) const;

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

// The low surface's corners as a triangle soup for primary rays (triangle
// id = low triangle), with the arrays Embree shares.
struct LowSoup {
  std::vector<glm::vec3> positions;
  std::vector<std::uint32_t> indices;
  RayScene scene;
  Status build(const LowSurface& surface);
};

// A corner attribute at barycentrics b (weights of corners 1 and 2).
template <class V>
V interpolate(const std::vector<V>& corner, std::size_t base, glm::vec2 b) {
  return corner[base] * (1.0f - b.x - b.y) + corner[base + 1] * b.x + corner[base + 2] * b.y;
}

// For each sample of a view (row-major over a (size k) x (size k) grid): the
// primary ray's hit. Parallel over rows; each result depends only on its index.
void trace_primary(const RayScene& scene, const Camera& camera, int supersample, std::vector<RayHit>& hits);
// The sample's image position (pixels) in that grid.
glm::vec2 sample_position(std::size_t sample, int size, int supersample);

// 5x7 bitmap font (own data; g, p, y use an 8th descender row): digits, '.', '%', '+', '-', ':', ' ' and the
// lowercase letters a d e g h i l m n o p r s w x y. Other characters draw as
// a box. Glyphs are 6 * scale pixels apart, lines need 10 * scale; a 1-pixel dark shadow keeps them
// readable on any background.
int text_width(const std::string& text, int scale);
void draw_text(Image& image, int x, int y, const std::string& text, int scale, const glm::vec3& colour);

// Fills a rectangle (clipped to the image).
void fill_rect(Image& image, int x0, int y0, int x1, int y1, const glm::vec3& colour);

// Heat ramp: 0 -> dark blue, then blue, green, yellow, red at 1 (clamped).
glm::vec3 heat_colour(float fraction);

// Text of a number with `decimals` digits after the point ("0.12").
std::string format_number(double value, int decimals);

}  // namespace nmbake::preview_detail
