// Height maps to normal maps.
//
// Flat: the heightfield normal from central differences (the textbook
// n = (-dh/du, -dh/dv, 1) of a surface (u, v, h(u, v))).
// Cube sphere: S. Wittens, "Making Worlds 3: That's no Moon..." (2009): the
// tangents of the displaced sphere are the Jacobian of the cube-to-sphere warp
// k(s, t, h) = h (s, t, 1) / |(s, t, 1)| applied to the flat tangents
// (1, 0, dh/ds) and (0, 1, dh/dt); their cross product is the normal. The
// tangent-space output uses the low mesh's MikkTSpace frame (Mikkelsen 2008)
// through the encode stage's world_to_tangent.
#include "nmbake/height2normal.hpp"

#include <tbb/parallel_for.h>

#include <algorithm>
#include <cmath>
#include <glm/ext/vector_double3.hpp>
#include <glm/geometric.hpp>

namespace nmbake {

namespace {

// Per-row counters, summed in row order afterwards (integers: any order
// would do, but this keeps the pattern of the other stages).
struct RowCounts {
  std::uint64_t one_sided = 0, flat = 0, clamped = 0, degenerate = 0, singular = 0, uncovered = 0;
};

void add_counts(const std::vector<RowCounts>& rows, HeightToNormalStats& stats) {
  for (const RowCounts& r : rows) {
    stats.one_sided_texels += r.one_sided;
    stats.flat_texels += r.flat;
    stats.clamped_radii += r.clamped;
    stats.degenerate_normals += r.degenerate;
    stats.singular_frames += r.singular;
    stats.uncovered_texels += r.uncovered;
  }
}

void store(const glm::vec3& n, float* rgb) {
  rgb[0] = 0.5f * n.x + 0.5f;
  rgb[1] = 0.5f * n.y + 0.5f;
  rgb[2] = 0.5f * n.z + 0.5f;
}

// Neighbour indices along one axis of length `size`; false when there is no
// neighbour on that side (clamped border).
struct Neighbours {
  int minus, plus;
};
Neighbours neighbours(int i, int size, HeightBorder border) {
  if (border == HeightBorder::wrap) return {(i + size - 1) % size, (i + 1) % size};
  return {std::max(i - 1, 0), std::min(i + 1, size - 1)};
}

}  // namespace

Image height_to_normal(const Image& height, const HeightToNormalOptions& options,
                       HeightToNormalStats& stats) {
  NMBAKE_CHECK(height.width > 0 && height.height > 0 && height.channels > 0, "empty height map");
  stats = HeightToNormalStats{};
  Image out;
  out.width = height.width;
  out.height = height.height;
  out.channels = 3;
  out.pixels.assign(static_cast<std::size_t>(out.width) * out.height * 3, 0.0f);
  const double strength = options.strength;
  const double green = options.green == GreenChannel::down ? -1.0 : 1.0;
  std::vector<RowCounts> rows(static_cast<std::size_t>(height.height));
  auto h = [&height](int x, int y) { return static_cast<double>(height.at(x, y)[0]); };

  tbb::parallel_for(0, height.height, [&](int y) {
    RowCounts& counts = rows[static_cast<std::size_t>(y)];
    const Neighbours ny = neighbours(y, height.height, options.border);
    for (int x = 0; x < height.width; ++x) {
      const Neighbours nx = neighbours(x, height.width, options.border);
      // Divide by the texel distance actually spanned: 2 inside (and when
      // wrapping), 1 on a clamped border; no neighbour at all (a map one
      // texel wide, or two when wrapping) gives slope 0 along that axis.
      const bool wrap = options.border == HeightBorder::wrap;
      const int span_x = wrap ? 2 : nx.plus - nx.minus;
      const int span_y = wrap ? 2 : ny.plus - ny.minus;
      if (!wrap && (span_x == 1 || span_y == 1)) ++counts.one_sided;
      if (nx.plus == nx.minus || ny.plus == ny.minus) ++counts.flat;
      double du = 0.0, dv = 0.0;
      if (nx.plus != nx.minus) du = (h(nx.plus, y) - h(nx.minus, y)) / span_x;
      // The texel above (y - 1) is at larger v.
      if (ny.plus != ny.minus) dv = (h(x, ny.minus) - h(x, ny.plus)) / span_y;
      const glm::dvec3 n = glm::normalize(glm::dvec3(-strength * du, -strength * dv, 1.0));
      store(glm::vec3(n.x, green * n.y, n.z), out.at(x, y));
    }
  });
  add_counts(rows, stats);
  return out;
}

// --- Cube sphere ---------------------------------------------------------------

const std::array<CubeFace, 6> kCubeFaces = {{
    {{0, 0, -1}, {0, 1, 0}, {1, 0, 0}},   // +X
    {{0, 0, 1}, {0, 1, 0}, {-1, 0, 0}},   // -X
    {{1, 0, 0}, {0, 0, -1}, {0, 1, 0}},   // +Y
    {{1, 0, 0}, {0, 0, 1}, {0, -1, 0}},   // -Y
    {{1, 0, 0}, {0, 1, 0}, {0, 0, 1}},    // +Z
    {{-1, 0, 0}, {0, 1, 0}, {0, 0, -1}},  // -Z
}};

CubeTexel cube_atlas_point(double u, double v, float uv_gutter) {
  const int cell_x = std::clamp(static_cast<int>(std::floor(u * 3.0)), 0, 2);
  const int cell_y = std::clamp(static_cast<int>(std::floor(v * 2.0)), 0, 1);
  const double gutter = uv_gutter;
  const double u0 = cell_x / 3.0 + gutter, v0 = cell_y / 2.0 + gutter;
  const double chart_width = 1.0 / 3.0 - 2.0 * gutter, chart_height = 0.5 - 2.0 * gutter;
  CubeTexel texel;
  texel.face = cell_y * 3 + cell_x;
  texel.s = 2.0 * (u - u0) / chart_width - 1.0;
  texel.t = 2.0 * (v - v0) / chart_height - 1.0;
  return texel;
}

CubeTexel cube_atlas_texel(int x, int y, int width, int height, float uv_gutter) {
  return cube_atlas_point((x + 0.5) / width, 1.0 - (y + 0.5) / height, uv_gutter);
}

glm::vec3 cube_direction(int face, double s, double t) {
  const CubeFace& f = kCubeFaces[static_cast<std::size_t>(std::clamp(face, 0, 5))];
  const glm::dvec3 p = s * glm::dvec3(f.u) + t * glm::dvec3(f.v) + glm::dvec3(f.n);
  return glm::vec3(p / glm::length(p));
}

Status cube_sphere_height_to_normal(const Image& atlas, const CubeSphereOptions& options,
                                    const LowSurface* low, Image& out, HeightToNormalStats& stats) {
  stats = HeightToNormalStats{};
  if (atlas.width < 3 || atlas.height < 2 || atlas.channels < 1) {
    return Status::bad_input("a cube-sphere atlas needs at least 3 x 2 texels, this one is " +
                             std::to_string(atlas.width) + "x" + std::to_string(atlas.height));
  }
  if (!(options.uv_gutter >= 0.0f && options.uv_gutter < 1.0f / 6.0f)) {
    return Status::bad_input("cube-sphere gutter " + std::to_string(options.uv_gutter) +
                             " is outside [0, 1/6)");
  }
  const bool tangent_space = options.space == NormalSpace::tangent;
  if (tangent_space && low == nullptr) {
    return Status::bad_input("a tangent-space cube-sphere map needs the low mesh (--low)");
  }
  const int width = atlas.width, height = atlas.height;
  const std::size_t texel_count = static_cast<std::size_t>(width) * static_cast<std::size_t>(height);

  TexelSamples samples;
  if (tangent_space) {
    RasterStats raster_stats;
    rasterize(*low, width, height, 1, samples, raster_stats);
  }

  out.width = width;
  out.height = height;
  out.channels = 3;
  out.pixels.assign(texel_count * 3, 0.0f);
  std::vector<std::uint8_t> coverage(texel_count, 1);
  std::vector<RowCounts> rows(static_cast<std::size_t>(height));
  const double strength = options.strength;
  constexpr double kMinRadius = 1e-6;

  tbb::parallel_for(0, height, [&](int y) {
    RowCounts& counts = rows[static_cast<std::size_t>(y)];
    auto radius = [&](int px, int py) {
      return std::max(1.0 + strength * static_cast<double>(atlas.at(px, py)[0]), kMinRadius);
    };
    for (int x = 0; x < width; ++x) {
      const CubeTexel here = cube_atlas_texel(x, y, width, height, options.uv_gutter);
      const int face = here.face;
      auto same_cell = [&](int px, int py) {
        return px >= 0 && py >= 0 && px < width && py < height &&
               cube_atlas_texel(px, py, width, height, options.uv_gutter).face == face;
      };
      // dr/ds and dr/dt over the neighbours that share the cell: central
      // inside, one-sided on the cell border. (s, t) of each texel are
      // recomputed so the spacing is exact whatever the atlas size.
      const int xm = same_cell(x - 1, y) ? x - 1 : x, xp = same_cell(x + 1, y) ? x + 1 : x;
      const int yu = same_cell(x, y - 1) ? y - 1 : y, yd = same_cell(x, y + 1) ? y + 1 : y;
      if (xp - xm == 1 || yd - yu == 1) ++counts.one_sided;
      double r_s = 0.0, r_t = 0.0;
      if (xp != xm) {
        const double ds = cube_atlas_texel(xp, y, width, height, options.uv_gutter).s -
                          cube_atlas_texel(xm, y, width, height, options.uv_gutter).s;
        r_s = (radius(xp, y) - radius(xm, y)) / ds;
      }
      if (yd != yu) {
        const double dt = cube_atlas_texel(x, yu, width, height, options.uv_gutter).t -
                          cube_atlas_texel(x, yd, width, height, options.uv_gutter).t;
        r_t = (radius(x, yu) - radius(x, yd)) / dt;
      }
      if (xp == xm || yd == yu) ++counts.flat;

      // Jacobian of k at (s, t, r), applied to the flat tangents.
      const double s = here.s, t = here.t, r = radius(x, y);
      if (!(1.0 + strength * static_cast<double>(atlas.at(x, y)[0]) > kMinRadius)) ++counts.clamped;
      const double w = std::sqrt(s * s + t * t + 1.0);
      const glm::dvec3 p(s, t, 1.0);
      const glm::dvec3 k_s = r * (glm::dvec3(1.0, 0.0, 0.0) / w - p * (s / (w * w * w)));
      const glm::dvec3 k_t = r * (glm::dvec3(0.0, 1.0, 0.0) / w - p * (t / (w * w * w)));
      const glm::dvec3 k_r = p / w;
      const glm::dvec3 tangent_s = k_s + r_s * k_r;
      const glm::dvec3 tangent_t = k_t + r_t * k_r;
      glm::dvec3 local = glm::cross(tangent_s, tangent_t);
      const double length = glm::length(local);
      if (length > 1e-12 && std::isfinite(length)) {
        local /= length;
      } else {
        local = p / w;
        ++counts.degenerate;
      }
      const CubeFace& frame = kCubeFaces[static_cast<std::size_t>(face)];
      const glm::vec3 n = glm::normalize(glm::vec3(static_cast<float>(local.x) * frame.u +
                                                   static_cast<float>(local.y) * frame.v +
                                                   static_cast<float>(local.z) * frame.n));
      float* rgb = out.at(x, y);
      if (!tangent_space) {
        store(n, rgb);
        continue;
      }
      const std::size_t texel = static_cast<std::size_t>(y) * static_cast<std::size_t>(width) + x;
      const std::int32_t triangle = samples.triangle[texel];
      if (!samples.coverage[texel] || triangle < 0) {
        coverage[texel] = 0;
        ++counts.uncovered;
        store(glm::vec3(0.0f, 0.0f, 1.0f), rgb);
        continue;
      }
      const std::size_t base = 3 * static_cast<std::size_t>(triangle);
      const glm::vec2 b = samples.bary[texel];
      const float b0 = 1.0f - b.x - b.y;
      const glm::vec4 T =
          low->tangent[base] * b0 + low->tangent[base + 1] * b.x + low->tangent[base + 2] * b.y;
      const glm::vec3 N = low->normal[base] * b0 + low->normal[base + 1] * b.x + low->normal[base + 2] * b.y;
      glm::vec3 tangent_value;
      if (!world_to_tangent(n, glm::vec3(T), N, T.w < 0.0f ? -1.0f : 1.0f, TangentEncode::inverse,
                            tangent_value)) {
        ++counts.singular;
      }
      if (options.green == GreenChannel::down) tangent_value.y = -tangent_value.y;
      store(tangent_value, rgb);
    }
  });
  add_counts(rows, stats);
  if (tangent_space && options.padding > 0) dilate(out, coverage, options.padding, stats.dilate);
  return Status::ok();
}

Status assemble_cube_atlas(const std::vector<Image>& faces, Image& atlas) {
  if (faces.size() != 6) {
    return Status::bad_input("a cube sphere needs six face maps (+X, -X, +Y, -Y, +Z, -Z), got " +
                             std::to_string(faces.size()));
  }
  const int n = faces[0].width;
  for (std::size_t f = 0; f < 6; ++f) {
    if (faces[f].width != n || faces[f].height != n || n <= 0 || faces[f].channels < 1) {
      return Status::bad_input("cube face " + std::to_string(f) + " is " + std::to_string(faces[f].width) +
                               "x" + std::to_string(faces[f].height) +
                               ": every face must be square and of one size (" + std::to_string(n) + "x" +
                               std::to_string(n) + ")");
    }
  }
  atlas.width = 3 * n;
  atlas.height = 2 * n;
  atlas.channels = 1;
  atlas.pixels.assign(static_cast<std::size_t>(atlas.width) * atlas.height, 0.0f);
  for (int f = 0; f < 6; ++f) {
    // Cell row 0 (faces 0-2) is the bottom half of the image.
    const int x0 = (f % 3) * n, y0 = (1 - f / 3) * n;
    for (int y = 0; y < n; ++y) {
      for (int x = 0; x < n; ++x)
        atlas.at(x0 + x, y0 + y)[0] = faces[static_cast<std::size_t>(f)].at(x, y)[0];
    }
  }
  return Status::ok();
}

}  // namespace nmbake
