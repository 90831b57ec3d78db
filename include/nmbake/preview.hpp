// Looking at a bake.
//
// * render_lit_map: the normal map itself lit per pixel with Blinn-Phong in
//   tangent space (as in the classic normal-mapping articles): a flat surface
//   seen head-on, a raking key light and a fill, so craters, bevels and seams
//   stand out.
// * render_preview: the 3D preview sheet. From one camera and one set of
//   lights: the high mesh shaded with its own normals, the low mesh shaded
//   with the map decoded exactly as an engine does, and a heat map of the
//   angle between the two (see PreviewOptions for how that angle is defined).
// * render_tangent_frames / render_uv_layout: the low mesh's MikkTSpace
//   frames drawn over the shaded mesh, and the UV layout coloured by tangent
//   with mirrored triangles hatched.
//
// Rendering is Embree primary rays (no OpenGL, headless), a fixed k x k grid
// of samples per pixel, tiles in parallel: the same bytes for any thread
// count. Embree types stay in the .cpp files.
#pragma once

#include <cstdint>
#include <glm/vec3.hpp>
#include <string>
#include <vector>

#include "nmbake/encode.hpp"
#include "nmbake/image.hpp"
#include "nmbake/mesh.hpp"
#include "nmbake/surface.hpp"
#include "nmbake/trace.hpp"

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

// --- 3D views ----------------------------------------------------------------

enum class UpAxis : std::uint8_t { y, z };

// The camera and the lights of every 3D view. The camera is a perspective
// camera (30 degrees vertical field of view) looking at the centre of the
// bounding box from far enough that the bounding sphere fits the square
// image. yaw turns it around the up axis, pitch raises it (degrees, pitch in
// [-89, 89]); yaw 0, pitch 0 looks from +z at y-up scenes and from -y at
// z-up scenes (Blender's front view).
struct ViewOptions {
  int size = 384;  // pixels per side of a square panel
  float yaw_degrees = 30.0f;
  float pitch_degrees = 20.0f;
  UpAxis up = UpAxis::y;
  // Key light direction in camera space (x right, y up, z towards the
  // viewer), towards the light; normalised inside. A weaker fill light comes
  // from the mirrored side, so the lighting follows the camera in a turntable.
  glm::vec3 light{-0.55f, 0.6f, 0.6f};
  int supersample = 3;  // k: k x k samples per pixel at cell centres (fixed pattern)
};
Status validate_view_options(const ViewOptions& view);

struct PreviewOptions {
  ViewOptions view;
  int turntable = 1;  // views in the sheet, yaw + 360 k / turntable (k = 0 .. turntable - 1)
  NormalSpace space = NormalSpace::tangent;
  GreenChannel green = GreenChannel::up;
  // How the map's engine decodes it (encode.hpp, preset.hpp): the map is
  // decoded the same way, so a map baked with --preset X is previewed with
  // --preset X.
  NormalDecode decode;
  // The bake's rays, used to find the high normal the baker should have
  // stored at each low point: resolved as the bake resolves them
  // (resolve_rays(): auto distances estimated, misses retried by the same rule).
  RaySettings rays;
  float heat_max_degrees = 5.0f;  // the top of the colour ramp
};

struct PreviewViewStats {
  float yaw_degrees = 0.0f;
  std::uint64_t low_samples = 0;  // samples whose primary ray hit the low mesh
  std::uint64_t bake_misses =
      0;                      // of those, bake ray found no high surface (shown magenta, not in the stats)
  double mean_degrees = 0.0;  // over the remaining samples
  double p99_degrees = 0.0;
  double max_degrees = 0.0;
};

struct PreviewStats {
  std::vector<PreviewViewStats> views;
  PreviewViewStats all;                     // every view together (yaw_degrees unused)
  float front = 0.0f, back = 0.0f;          // resolved ray distances, scene units
  std::uint64_t decode_fallbacks = 0;       // decoded map normal of length ~0: low normal used
  std::uint64_t high_normal_fallbacks = 0;  // interpolated high normal of length ~0: face normal used
};

// Loads and prepares the meshes as `nmbake bake` does: low with UVs (normals
// from the file normalised, else averaged over coincident positions), its
// MikkTSpace surface; high with normals (computed when missing), padded for
// Embree. `high_path` may be empty (tangent views).
Status load_preview_meshes(const std::string& low_path, const std::string& high_path, Mesh& low,
                           LowSurface& surface, Mesh& high);

// The preview sheet: one row per view, each row three panels of
// view.size x view.size separated by a gap: [high | low + map | error].
//
// * high: Blinn-Phong with the high mesh's interpolated vertex normals.
// * low + map: at the hit, T (xyz + sign), N and uv are interpolated
//   barycentrically from the per-corner arrays; the map is sampled
//   bilinearly at uv (texel centres at u = (x + 0.5) / W, v = 1 - (y + 0.5) / H,
//   clamped at the borders), decoded rgb * 2 - 1 (y negated for green down)
//   and turned into a world normal with tangent_to_world (T, N not
//   normalised, B = sign cross(N, T)); object space maps are used directly.
// * error: for each sample that hits the low mesh, the bake's own ray
//   (make_ray with the rays resolve_rays() gives for options.rays, the
//   bake's retry of misses included) finds the high
//   normal the baker should have stored there; the panel shows the angle
//   between it and the decoded normal (0 .. heat_max_degrees on the ramp,
//   a scale bar, the mean and p99 printed). Bake-ray misses are magenta. This
//   measures the map, not the difference in silhouette between the meshes.
//
// `high` must be padded (pad_for_embree) and carry unit normals; `map` is an
// encoded normal map with >= 3 channels. Deterministic for any thread count.
Status render_preview(const LowSurface& surface, const Mesh& high, const Image& map,
                      const PreviewOptions& options, Image& sheet, PreviewStats& stats);

// The map's normal at a point of the low surface (triangle `tri`,
// barycentrics `b`: weights of corners 1 and 2), decoded exactly as the
// low+map panel of render_preview (and an engine) decodes it: uv, T (with
// its sign) and N interpolated from the corners, the map sampled bilinearly
// at uv (texel centres at u = (x + 0.5) / W, v = 1 - (y + 0.5) / H, clamped
// at the borders), t = 2 rgb - 1 (y negated for green down), then
// tangent_to_world (T, N not normalised) or, in object space, t itself.
// With another engine's `decode` (preset.hpp): z rebuilt from x and y, B per
// vertex, the frame normalised, as it says. Counted fallback: a decoded
// vector of length ~0 gives the unit low normal (or `otherwise` when N has no
// length either) and sets `fallback`.
glm::vec3 decode_map_normal(const LowSurface& surface, const Image& map, std::int32_t tri, glm::vec2 b,
                            NormalSpace space, GreenChannel green, const glm::vec3& otherwise, bool& fallback,
                            const NormalDecode& decode = {});

struct TangentViewOptions {
  ViewOptions view;
  float length = 0.0f;  // of the drawn T, B, N, scene units; 0: 40% of the mean edge length
};

struct TangentViewStats {
  std::uint64_t frames = 0;              // distinct (position, normal, tangent, sign) corner frames drawn
  std::uint64_t mirrored_triangles = 0;  // tangent sign -1
};

// The low mesh shaded with its interpolated normals and, at every distinct
// corner frame, T (red), B = sign cross(N, T) (green) and N (blue) as short
// 1-pixel lines, depth-tested against the rendered surface.
Status render_tangent_frames(const LowSurface& surface, const TangentViewOptions& options, Image& out,
                             TangentViewStats& stats);

// The UV square (v up, `size` x `size`): each triangle filled with its
// interpolated tangent T as colour (0.5 T + 0.5), mirrored triangles (sign
// -1) hatched with dark diagonal stripes, triangle edges drawn dark.
Status render_uv_layout(const LowSurface& surface, int size, Image& out, TangentViewStats& stats);

}  // namespace nmbake
