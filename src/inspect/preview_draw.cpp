// Camera, Blinn-Phong lights (Blinn, "Models of light reflection for computer
// synthesized pictures", 1977, as used by the classic normal-mapping
// articles), Embree 3 primary rays, a 5x7 bitmap font and a heat ramp for the
// 3D views of preview.hpp.
#include "inspect/preview_draw.hpp"

#include <embree3/rtcore.h>
#include <tbb/parallel_for.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <glm/geometric.hpp>
#include <limits>
#include <mutex>
#include <numeric>

namespace nmbake::preview_detail {

namespace {

constexpr float kPi = 3.14159265358979f;
constexpr float kHalfFovDegrees = 15.0f;

float radians(float degrees) { return degrees * kPi / 180.0f; }

}  // namespace

glm::vec3 Camera::direction(float x, float y) const {
  const float sx = (2.0f * x / static_cast<float>(size) - 1.0f) * tan_half_fov;
  const float sy = (1.0f - 2.0f * y / static_cast<float>(size)) * tan_half_fov;
  return glm::normalize(forward + sx * right + sy * up);
}

bool Camera::project(const glm::vec3& p, glm::vec2& pixel, float& depth) const {
  const glm::vec3 v = p - eye;
  depth = glm::dot(v, forward);
  if (!(depth > 1e-6f)) return false;
  const float sx = glm::dot(v, right) / (depth * tan_half_fov);
  const float sy = glm::dot(v, up) / (depth * tan_half_fov);
  pixel =
      glm::vec2((sx + 1.0f) * 0.5f * static_cast<float>(size), (1.0f - sy) * 0.5f * static_cast<float>(size));
  return std::isfinite(pixel.x) && std::isfinite(pixel.y);
}

Framing frame_points(const std::vector<const std::vector<glm::vec3>*>& point_sets) {
  glm::vec3 lo(std::numeric_limits<float>::max()), hi(-std::numeric_limits<float>::max());
  bool any = false;
  for (const auto* points : point_sets) {
    for (const glm::vec3& p : *points) {
      lo = glm::min(lo, p);
      hi = glm::max(hi, p);
      any = true;
    }
  }
  Framing f;
  if (!any) return f;
  f.centre = 0.5f * (lo + hi);
  float r2 = 0.0f;
  for (const auto* points : point_sets) {
    for (const glm::vec3& p : *points) r2 = std::max(r2, glm::dot(p - f.centre, p - f.centre));
  }
  f.radius = std::sqrt(r2);
  return f;
}

Camera make_camera(const Framing& framing, const ViewOptions& view, float yaw_degrees) {
  const glm::vec3 centre = framing.centre;
  // A scene of one point still gets a camera (and an empty-looking image).
  const float radius = std::max(framing.radius, 1e-6f);
  const float yaw = radians(yaw_degrees);
  const float pitch = radians(view.pitch_degrees);
  glm::vec3 out, world_up;
  if (view.up == UpAxis::y) {
    out = glm::vec3(std::cos(pitch) * std::sin(yaw), std::sin(pitch), std::cos(pitch) * std::cos(yaw));
    world_up = glm::vec3(0.0f, 1.0f, 0.0f);
  } else {
    out = glm::vec3(std::cos(pitch) * std::sin(yaw), -std::cos(pitch) * std::cos(yaw), std::sin(pitch));
    world_up = glm::vec3(0.0f, 0.0f, 1.0f);
  }
  Camera c;
  c.size = view.size;
  c.tan_half_fov = std::tan(radians(kHalfFovDegrees));
  // The bounding sphere touches the edges of the view cone (a small margin).
  const float distance = 1.04f * radius / std::sin(radians(kHalfFovDegrees));
  c.eye = centre + distance * out;
  c.forward = -out;
  c.right = glm::normalize(glm::cross(c.forward, world_up));  // pitch is within +-89: never parallel
  c.up = glm::cross(c.right, c.forward);
  return c;
}

Lights make_lights(const Camera& camera, const ViewOptions& view) {
  const glm::vec3 key = glm::normalize(view.light);
  const glm::vec3 fill = glm::normalize(glm::vec3(-key.x, -0.3f * key.y, std::max(key.z, 0.4f)));
  return Lights{glm::normalize(camera.to_world(key)), glm::normalize(camera.to_world(fill))};
}

glm::vec3 shade(const glm::vec3& normal, const glm::vec3& to_eye, const Lights& lights) {
  const glm::vec3 albedo(0.80f, 0.78f, 0.74f);
  const float diffuse = std::max(glm::dot(normal, lights.key), 0.0f);
  const float fill = std::max(glm::dot(normal, lights.fill), 0.0f);
  float specular = 0.0f;
  if (diffuse > 0.0f) {
    const glm::vec3 half = glm::normalize(lights.key + to_eye);
    specular = std::pow(std::max(glm::dot(normal, half), 0.0f), 40.0f);
  }
  const glm::vec3 linear = albedo * (0.04f + 0.82f * diffuse + 0.2f * fill) + glm::vec3(0.3f * specular);
  glm::vec3 display;
  for (int c = 0; c < 3; ++c) display[c] = std::pow(std::clamp(linear[c], 0.0f, 1.0f), 1.0f / 2.2f);
  return display;
}

glm::vec3 high_normal(const Mesh& high, std::int32_t tri, glm::vec2 b, const glm::vec3& otherwise,
                      bool& fallback) {
  const std::uint32_t* h = &high.indices[3 * static_cast<std::size_t>(tri)];
  const glm::vec3 n =
      high.normals[h[0]] * (1.0f - b.x - b.y) + high.normals[h[1]] * b.x + high.normals[h[2]] * b.y;
  const float l = glm::length(n);
  if (l > 1e-12f && std::isfinite(l)) return n / l;
  fallback = true;
  const glm::vec3 f =
      glm::cross(high.positions[h[1]] - high.positions[h[0]], high.positions[h[2]] - high.positions[h[0]]);
  const float lf = glm::length(f);
  return lf > 1e-12f && std::isfinite(lf) ? f / lf : otherwise;
}

// --- Embree ------------------------------------------------------------------

namespace {

std::mutex g_error_mutex;
std::string g_last_error;

void on_embree_error(void*, RTCError code, const char* message) {
  std::lock_guard<std::mutex> lock(g_error_mutex);
  g_last_error = "Embree error " + std::to_string(static_cast<int>(code)) + ": " + (message ? message : "");
}

}  // namespace

struct RayScene::Impl {
  RTCDevice device = nullptr;
  RTCScene scene = nullptr;
  ~Impl() {
    if (scene) rtcReleaseScene(scene);
    if (device) rtcReleaseDevice(device);
  }
};

RayScene::RayScene() = default;
RayScene::~RayScene() = default;

Status LowSoup::build(const LowSurface& surface) {
  positions.reserve(surface.position.size() + 1);  // Embree's spare element
  positions.assign(surface.position.begin(), surface.position.end());
  indices.resize(surface.position.size());
  std::iota(indices.begin(), indices.end(), 0u);
  return scene.build(positions, indices);
}

Status RayScene::build(const std::vector<glm::vec3>& positions, const std::vector<std::uint32_t>& indices) {
  NMBAKE_CHECK(positions.capacity() > positions.size(), "one spare position for Embree");
  auto impl = std::make_unique<Impl>();
  impl->device = rtcNewDevice(nullptr);
  if (!impl->device) return Status::internal("cannot create an Embree device");
  rtcSetDeviceErrorFunction(impl->device, on_embree_error, nullptr);
  impl->scene = rtcNewScene(impl->device);
  rtcSetSceneFlags(impl->scene, RTC_SCENE_FLAG_ROBUST);  // no pixels lost along shared edges
  RTCGeometry geometry = rtcNewGeometry(impl->device, RTC_GEOMETRY_TYPE_TRIANGLE);
  rtcSetSharedGeometryBuffer(geometry, RTC_BUFFER_TYPE_VERTEX, 0, RTC_FORMAT_FLOAT3, positions.data(), 0,
                             sizeof(glm::vec3), positions.size());
  rtcSetSharedGeometryBuffer(geometry, RTC_BUFFER_TYPE_INDEX, 0, RTC_FORMAT_UINT3, indices.data(), 0,
                             3 * sizeof(std::uint32_t), indices.size() / 3);
  rtcCommitGeometry(geometry);
  rtcAttachGeometry(impl->scene, geometry);
  rtcReleaseGeometry(geometry);
  rtcCommitScene(impl->scene);
  if (rtcGetDeviceError(impl->device) != RTC_ERROR_NONE) {
    std::lock_guard<std::mutex> lock(g_error_mutex);
    return Status::internal("building the preview scene failed: " + g_last_error);
  }
  impl_ = std::move(impl);
  return Status::ok();
}

RayHit RayScene::intersect(const glm::vec3& origin, const glm::vec3& direction) const {
  RTCIntersectContext context;
  rtcInitIntersectContext(&context);
  RTCRayHit rh;
  rh.ray.org_x = origin.x;
  rh.ray.org_y = origin.y;
  rh.ray.org_z = origin.z;
  rh.ray.tnear = 0.0f;
  rh.ray.dir_x = direction.x;
  rh.ray.dir_y = direction.y;
  rh.ray.dir_z = direction.z;
  rh.ray.time = 0.0f;
  rh.ray.tfar = std::numeric_limits<float>::infinity();
  rh.ray.mask = 0xffffffffu;
  rh.ray.id = 0;
  rh.ray.flags = 0;
  rh.hit.geomID = RTC_INVALID_GEOMETRY_ID;
  rh.hit.primID = RTC_INVALID_GEOMETRY_ID;
  rtcIntersect1(impl_->scene, &context, &rh);
  RayHit hit;
  if (rh.hit.geomID == RTC_INVALID_GEOMETRY_ID) return hit;
  hit.triangle = static_cast<std::int32_t>(rh.hit.primID);
  hit.bary = glm::vec2(rh.hit.u, rh.hit.v);
  hit.t = rh.ray.tfar;
  return hit;
}

glm::vec2 sample_position(std::size_t sample, int size, int supersample) {
  const std::size_t width = static_cast<std::size_t>(size) * supersample;
  const float k = static_cast<float>(supersample);
  return glm::vec2((static_cast<float>(sample % width) + 0.5f) / k,
                   (static_cast<float>(sample / width) + 0.5f) / k);
}

void trace_primary(const RayScene& scene, const Camera& camera, int supersample, std::vector<RayHit>& hits) {
  const int width = camera.size * supersample;
  hits.assign(static_cast<std::size_t>(width) * width, RayHit{});
  tbb::parallel_for(0, width, [&](int row) {
    for (int col = 0; col < width; ++col) {
      const std::size_t s = static_cast<std::size_t>(row) * width + col;
      const glm::vec2 p = sample_position(s, camera.size, supersample);
      hits[s] = scene.intersect(camera.eye, camera.direction(p.x, p.y));
    }
  });
}

// --- Font --------------------------------------------------------------------

namespace {

struct Glyph {
  char c;
  const char* rows[8];
};

// Own 5x7 glyphs: '#' is ink.
constexpr Glyph kGlyphs[] = {
    {'0', {".###.", "#...#", "#..##", "#.#.#", "##..#", "#...#", ".###.", "....."}},
    {'1', {"..#..", ".##..", "..#..", "..#..", "..#..", "..#..", ".###.", "....."}},
    {'2', {".###.", "#...#", "....#", "...#.", "..#..", ".#...", "#####", "....."}},
    {'3', {"#####", "...#.", "..#..", "...#.", "....#", "#...#", ".###.", "....."}},
    {'4', {"...#.", "..##.", ".#.#.", "#..#.", "#####", "...#.", "...#.", "....."}},
    {'5', {"#####", "#....", "####.", "....#", "....#", "#...#", ".###.", "....."}},
    {'6', {"..##.", ".#...", "#....", "####.", "#...#", "#...#", ".###.", "....."}},
    {'7', {"#####", "....#", "...#.", "..#..", ".#...", ".#...", ".#...", "....."}},
    {'8', {".###.", "#...#", "#...#", ".###.", "#...#", "#...#", ".###.", "....."}},
    {'9', {".###.", "#...#", "#...#", ".####", "....#", "...#.", ".##..", "....."}},
    {'.', {".....", ".....", ".....", ".....", ".....", ".##..", ".##..", "....."}},
    {'%', {"##...", "##..#", "...#.", "..#..", ".#...", "#..##", "...##", "....."}},
    {'+', {".....", "..#..", "..#..", "#####", "..#..", "..#..", ".....", "....."}},
    {'-', {".....", ".....", ".....", "#####", ".....", ".....", ".....", "....."}},
    {':', {".....", ".##..", ".##..", ".....", ".##..", ".##..", ".....", "....."}},
    {' ', {".....", ".....", ".....", ".....", ".....", ".....", ".....", "....."}},
    {'a', {".....", ".....", ".###.", "....#", ".####", "#...#", ".####", "....."}},
    {'d', {"....#", "....#", ".##.#", "#..##", "#...#", "#...#", ".####", "....."}},
    {'e', {".....", ".....", ".###.", "#...#", "#####", "#....", ".###.", "....."}},
    {'g', {".....", ".....", ".####", "#...#", "#...#", ".####", "....#", ".###."}},
    {'h', {"#....", "#....", "#.##.", "##..#", "#...#", "#...#", "#...#", "....."}},
    {'i', {"..#..", ".....", ".##..", "..#..", "..#..", "..#..", ".###.", "....."}},
    {'l', {".##..", "..#..", "..#..", "..#..", "..#..", "..#..", ".###.", "....."}},
    {'m', {".....", ".....", "##.#.", "#.#.#", "#.#.#", "#...#", "#...#", "....."}},
    {'n', {".....", ".....", "#.##.", "##..#", "#...#", "#...#", "#...#", "....."}},
    {'o', {".....", ".....", ".###.", "#...#", "#...#", "#...#", ".###.", "....."}},
    {'p', {".....", ".....", "####.", "#...#", "#...#", "####.", "#....", "#...."}},
    {'r', {".....", ".....", "#.##.", "##..#", "#....", "#....", "#....", "....."}},
    {'s', {".....", ".....", ".####", "#....", ".###.", "....#", "####.", "....."}},
    {'w', {".....", ".....", "#...#", "#...#", "#.#.#", "#.#.#", ".#.#.", "....."}},
    {'x', {".....", ".....", "#...#", ".#.#.", "..#..", ".#.#.", "#...#", "....."}},
    {'y', {".....", ".....", "#...#", "#...#", "#...#", ".####", "....#", ".###."}},
};
constexpr Glyph kUnknown{'?', {"#####", "#...#", "#...#", "#...#", "#...#", "#...#", "#####", "....."}};

const Glyph& glyph_of(char c) {
  for (const Glyph& g : kGlyphs) {
    if (g.c == c) return g;
  }
  return kUnknown;
}

void put(Image& image, int x, int y, const glm::vec3& colour) {
  if (x < 0 || y < 0 || x >= image.width || y >= image.height) return;
  float* p = image.at(x, y);
  for (int c = 0; c < 3; ++c) p[c] = colour[c];
}

void draw_glyphs(Image& image, int x, int y, const std::string& text, int scale, const glm::vec3& colour) {
  for (std::size_t i = 0; i < text.size(); ++i) {
    const Glyph& g = glyph_of(text[i]);
    const int gx = x + static_cast<int>(i) * 6 * scale;
    for (int row = 0; row < 8; ++row) {
      for (int col = 0; col < 5; ++col) {
        if (g.rows[row][col] != '#') continue;
        fill_rect(image, gx + col * scale, y + row * scale, gx + (col + 1) * scale, y + (row + 1) * scale,
                  colour);
      }
    }
  }
}

}  // namespace

int text_width(const std::string& text, int scale) {
  return static_cast<int>(text.size()) * 6 * scale - scale;
}

void draw_text(Image& image, int x, int y, const std::string& text, int scale, const glm::vec3& colour) {
  draw_glyphs(image, x + 1, y + 1, text, scale, glm::vec3(0.02f));
  draw_glyphs(image, x, y, text, scale, colour);
}

void fill_rect(Image& image, int x0, int y0, int x1, int y1, const glm::vec3& colour) {
  for (int y = std::max(y0, 0); y < std::min(y1, image.height); ++y) {
    for (int x = std::max(x0, 0); x < std::min(x1, image.width); ++x) put(image, x, y, colour);
  }
}

glm::vec3 heat_colour(float fraction) {
  static const glm::vec3 stops[] = {{0.04f, 0.06f, 0.32f},
                                    {0.10f, 0.42f, 0.95f},
                                    {0.15f, 0.80f, 0.35f},
                                    {0.95f, 0.85f, 0.10f},
                                    {0.88f, 0.10f, 0.05f}};
  const float f = std::isfinite(fraction) ? std::clamp(fraction, 0.0f, 1.0f) * 4.0f : 4.0f;
  const int i = std::min(3, static_cast<int>(f));
  const float w = f - static_cast<float>(i);
  return stops[i] * (1.0f - w) + stops[i + 1] * w;
}

std::string format_number(double value, int decimals) {
  char buffer[64];
  std::snprintf(buffer, sizeof buffer, "%.*f", decimals, std::isfinite(value) ? value : 0.0);
  return buffer;
}

}  // namespace nmbake::preview_detail
