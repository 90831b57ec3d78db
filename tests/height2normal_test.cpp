// height2normal: flat maps against an analytic height function (wrap and
// clamp), the cube-sphere atlas layout against nmbake-gen's cube sphere, the
// cube-sphere normals against the analytic displaced sphere, and a
// tangent-space cube-sphere map against a real bake of the same sphere.
#include "nmbake/height2normal.hpp"

#include <gtest/gtest.h>

#include <chrono>
#include <cmath>
#include <fstream>
#include <glm/geometric.hpp>
#include <glm/trigonometric.hpp>
#include <iterator>
#include <numbers>

#include "nmbake/bake.hpp"
#include "nmbake/diff.hpp"
#include "scenes.hpp"
#include "test_util.hpp"

namespace nmbake {
namespace {

std::string read_bytes(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  return std::string(std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>());
}

glm::dvec3 decode(const float* rgb) {
  return glm::normalize(glm::dvec3(2.0 * rgb[0] - 1.0, 2.0 * rgb[1] - 1.0, 2.0 * rgb[2] - 1.0));
}

double angle_degrees(const glm::dvec3& a, const glm::dvec3& b) {
  return glm::degrees(std::atan2(glm::length(glm::cross(a, b)), glm::dot(a, b)));
}

// h at texel centres, with its derivatives in texel units along x (columns)
// and along v (up: the row index decreasing).
struct Analytic {
  double amplitude, fx, fy, phase;
  int width, height;
  double h(int x, int y) const {
    const double a = 2.0 * std::numbers::pi * fx * (x + 0.5) / width + phase,
                 b = 2.0 * std::numbers::pi * fy * (y + 0.5) / height;
    return amplitude * std::sin(a) * std::cos(b);
  }
  glm::dvec3 normal(int x, int y, double strength) const {
    const double a = 2.0 * std::numbers::pi * fx * (x + 0.5) / width + phase,
                 b = 2.0 * std::numbers::pi * fy * (y + 0.5) / height;
    const double dh_dx = amplitude * std::cos(a) * std::cos(b) * 2.0 * std::numbers::pi * fx / width;
    const double dh_drow = -amplitude * std::sin(a) * std::sin(b) * 2.0 * std::numbers::pi * fy / height;
    return glm::normalize(glm::dvec3(-strength * dh_dx, -strength * -dh_drow, 1.0));
  }
  Image image() const {
    Image out;
    out.width = width;
    out.height = height;
    out.channels = 1;
    out.pixels.resize(static_cast<std::size_t>(width) * height);
    for (int y = 0; y < height; ++y) {
      for (int x = 0; x < width; ++x) out.at(x, y)[0] = static_cast<float>(h(x, y));
    }
    return out;
  }
};

// Largest error (degrees) over the texels at least `margin` from the border.
double max_error(const Image& map, const Analytic& f, double strength, int margin, bool flip_green = false) {
  double worst = 0.0;
  for (int y = margin; y < map.height - margin; ++y) {
    for (int x = margin; x < map.width - margin; ++x) {
      glm::dvec3 expected = f.normal(x, y, strength);
      if (flip_green) expected.y = -expected.y;
      worst = std::max(worst, angle_degrees(decode(map.at(x, y)), expected));
    }
  }
  return worst;
}

TEST(Height2Normal, WrapMatchesAnalyticEverywhere) {
  // Periodic in both directions: wrapping makes every texel central.
  const Analytic f{8.0, 1.0, 1.0, 0.3, 128, 96};
  HeightToNormalOptions options;
  options.border = HeightBorder::wrap;
  options.strength = 1.5f;
  HeightToNormalStats stats;
  const Image map = height_to_normal(f.image(), options, stats);
  const double error = max_error(map, f, 1.5, 0);
  std::printf("wrap: max error %.4f deg\n", error);
  EXPECT_LT(error, 0.1);
  EXPECT_EQ(stats.one_sided_texels, 0u);
  // The slopes are large enough that a sign error could not pass.
  EXPECT_GT(max_error(map, Analytic{-8.0, 1.0, 1.0, 0.3, 128, 96}, 1.5, 0), 20.0);

  options.green = GreenChannel::down;
  const Image down = height_to_normal(f.image(), options, stats);
  EXPECT_LT(max_error(down, f, 1.5, 0, true), 0.1);
}

TEST(Height2Normal, ClampMatchesAnalyticAwayFromBorders) {
  // Not periodic: wrapping would be wrong at the edges, clamping is not.
  const Analytic f{6.0, 1.3, 0.7, 0.4, 100, 120};
  HeightToNormalOptions options;
  options.border = HeightBorder::clamp;
  HeightToNormalStats stats;
  const Image map = height_to_normal(f.image(), options, stats);
  const double inner = max_error(map, f, 1.0, 1);
  const double all = max_error(map, f, 1.0, 0);
  std::printf("clamp: max error %.4f deg inside, %.4f deg with the border texels\n", inner, all);
  EXPECT_LT(inner, 0.1);
  EXPECT_LT(all, 3.0);  // one-sided differences: first order, still close
  EXPECT_EQ(stats.one_sided_texels, static_cast<std::uint64_t>(2 * 100 + 2 * 120 - 4));
  options.border = HeightBorder::wrap;
  EXPECT_GT(max_error(height_to_normal(f.image(), options, stats), f, 1.0, 0), 5.0);
}

TEST(Height2Normal, FlatAndTinyMaps) {
  Image flat;
  flat.width = 1;
  flat.height = 3;
  flat.channels = 1;
  flat.pixels = {0.2f, 0.7f, 0.1f};
  HeightToNormalStats stats;
  const Image map = height_to_normal(flat, HeightToNormalOptions{}, stats);
  EXPECT_EQ(stats.flat_texels, 3u);
  for (float v : map.pixels) EXPECT_TRUE(std::isfinite(v));
  EXPECT_FLOAT_EQ(map.at(0, 0)[0], 0.5f);  // no neighbour along x: no slope
}

TEST(Height2Normal, CommandWritesTheSameMapEveryTime) {
  test::TempDir dir;
  const Analytic f{8.0, 1.0, 1.0, 0.3, 128, 96};
  ASSERT_TRUE(write_image(f.image(), dir.file("h.exr"), PixelFormat::exr_float).is_ok());
  const std::string cmd =
      test::cli_path() + " height2normal " + dir.file("h.exr") + " --strength 1.5 --border wrap -o ";
  test::CommandResult r = test::run_command(cmd + dir.file("n1.exr"));
  ASSERT_EQ(r.exit_code, 0) << r.output;
  r = test::run_command(cmd + dir.file("n2.exr") + " --threads 1");
  ASSERT_EQ(r.exit_code, 0) << r.output;
  EXPECT_EQ(read_bytes(dir.file("n1.exr")), read_bytes(dir.file("n2.exr")));
  Image map;
  ASSERT_TRUE(read_image(dir.file("n1.exr"), map).is_ok());
  EXPECT_LT(max_error(map, f, 1.5, 0), 0.1);

  r = test::run_command(test::cli_path() + " height2normal " + dir.file("missing.exr") + " -o " +
                        dir.file("n.png"));
  EXPECT_EQ(r.exit_code, 2) << r.output;
  r = test::run_command(cmd + dir.file("n.png") + " --border mirror");
  EXPECT_EQ(r.exit_code, 2) << r.output;
  r = test::run_command(test::cli_path() + " height2normal " + dir.file("h.exr") +
                        " --cube-sphere --space tangent -o " + dir.file("n.png"));
  EXPECT_EQ(r.exit_code, 2) << r.output;  // tangent space needs --low
}

// The atlas layout is the one of nmbake-gen's cube spheres: every low vertex
// lies in the direction cube_atlas_point gives for its UV.
TEST(Height2Normal, CubeAtlasLayoutMatchesGenerator) {
  const Mesh low = scenes::make_cube_sphere(
      4, [](const glm::vec3&) { return 2.0f; }, true, scenes::sphere_uv_gutter);
  ASSERT_EQ(kCubeAtlasGutter, scenes::sphere_uv_gutter);
  for (std::size_t i = 0; i < low.vertex_count(); ++i) {
    const CubeTexel c = cube_atlas_point(low.uvs[i].x, low.uvs[i].y, kCubeAtlasGutter);
    ASSERT_LE(std::fabs(c.s), 1.0 + 1e-5);
    ASSERT_LE(std::fabs(c.t), 1.0 + 1e-5);
    ASSERT_LT(glm::length(cube_direction(c.face, c.s, c.t) - low.positions[i] / 2.0f), 1e-5f)
        << "vertex " << i;
  }
}

// Heights of the displaced sphere at the point (s, t) of every texel.
Image sphere_atlas(const scenes::SphereParams& p, int width, int height, float gutter) {
  Image atlas;
  atlas.width = width;
  atlas.height = height;
  atlas.channels = 1;
  atlas.pixels.resize(static_cast<std::size_t>(width) * height);
  for (int y = 0; y < height; ++y) {
    for (int x = 0; x < width; ++x) {
      const CubeTexel c = cube_atlas_texel(x, y, width, height, gutter);
      atlas.at(x, y)[0] = scenes::sphere_radius(p, cube_direction(c.face, c.s, c.t)) / p.radius - 1.0f;
    }
  }
  return atlas;
}

TEST(Height2Normal, CubeSphereObjectSpaceMatchesAnalyticSphere) {
  scenes::SphereParams p;
  p.amplitude = 0.05f;
  const int width = 384, height = 256;
  CubeSphereOptions options;
  HeightToNormalStats stats;
  Image map;
  ASSERT_TRUE(cube_sphere_height_to_normal(sphere_atlas(p, width, height, options.uv_gutter), options,
                                           nullptr, map, stats)
                  .is_ok());
  // The same heights with the warp's Jacobian applied to the flat normal
  // instead of to the tangents: the article's warning, measured.
  double worst = 0.0, sum = 0.0, worst_radial = 0.0;
  std::size_t count = 0;
  for (int y = 0; y < height; ++y) {
    for (int x = 0; x < width; ++x) {
      const CubeTexel c = cube_atlas_texel(x, y, width, height, options.uv_gutter);
      if (std::fabs(c.s) > 1.0 || std::fabs(c.t) > 1.0) continue;
      const glm::vec3 d = cube_direction(c.face, c.s, c.t);
      const glm::dvec3 truth(scenes::sphere_normal(p, d));
      const double e = angle_degrees(decode(map.at(x, y)), truth);
      worst = std::max(worst, e);
      worst_radial = std::max(worst_radial, angle_degrees(glm::dvec3(d), truth));
      sum += e;
      ++count;
    }
  }
  std::printf(
      "cube sphere object space vs analytic: mean %.4f deg, max %.4f deg (the relief tilts normals up to "
      "%.2f deg)\n",
      sum / count, worst, worst_radial);
  EXPECT_LT(sum / count, 0.05);
  EXPECT_LT(worst, 0.5);
  EXPECT_GT(worst_radial, 5.0);  // the relief is there to be found
  EXPECT_EQ(stats.degenerate_normals, 0u);

  // Six face files: the same normals through assemble_cube_atlas.
  const int n = 64;
  std::vector<Image> faces(6);
  for (int f = 0; f < 6; ++f) {
    faces[f].width = faces[f].height = n;
    faces[f].channels = 1;
    faces[f].pixels.resize(static_cast<std::size_t>(n) * n);
    for (int y = 0; y < n; ++y) {
      for (int x = 0; x < n; ++x) {
        const double s = 2.0 * (x + 0.5) / n - 1.0, t = 1.0 - 2.0 * (y + 0.5) / n;
        faces[f].at(x, y)[0] = scenes::sphere_radius(p, cube_direction(f, s, t)) / p.radius - 1.0f;
      }
    }
  }
  Image atlas, face_map;
  ASSERT_TRUE(assemble_cube_atlas(faces, atlas).is_ok());
  ASSERT_EQ(atlas.width, 3 * n);
  options.uv_gutter = 0.0f;
  ASSERT_TRUE(cube_sphere_height_to_normal(atlas, options, nullptr, face_map, stats).is_ok());
  worst = 0.0;
  for (int y = 1; y < atlas.height - 1; ++y) {
    for (int x = 1; x < atlas.width - 1; ++x) {
      const CubeTexel c = cube_atlas_texel(x, y, atlas.width, atlas.height, 0.0f);
      if (std::fabs(c.s) > 1.0 - 2.0 / n || std::fabs(c.t) > 1.0 - 2.0 / n) continue;  // one-sided rows
      worst = std::max(worst,
                       angle_degrees(decode(face_map.at(x, y)),
                                     glm::dvec3(scenes::sphere_normal(p, cube_direction(c.face, c.s, c.t)))));
    }
  }
  EXPECT_LT(worst, 0.5);
  faces.pop_back();
  EXPECT_EQ(assemble_cube_atlas(faces, atlas).code(), StatusCode::bad_input);
}

// The bound: a tangent-space height2normal map of the displaced
// sphere against a bake of the same sphere, within 1 degree mean.
TEST(Height2Normal, CubeSphereTangentSpaceMatchesBake) {
  using Clock = std::chrono::steady_clock;
  test::TempDir dir;
  scenes::SphereParams p;
  p.high_cells = 128;
  const scenes::ScenePair scene = scenes::make_displaced_sphere(p);
  ASSERT_TRUE(save_mesh(dir.file("low.obj"), scene.low).is_ok());
  ASSERT_TRUE(save_mesh(dir.file("high.ply"), scene.high).is_ok());
  const int width = 384, height = 256;

  BakeOptions o;
  o.low_path = dir.file("low.obj");
  o.high_paths = {dir.file("high.ply")};
  o.outputs = {{dir.file("bake.exr"), PixelFormat::exr_float}};
  o.width = width;
  o.height = height;
  o.samples = 4;
  BakeReport report;
  auto t0 = Clock::now();
  ASSERT_TRUE(bake(o, report).is_ok());
  const double bake_seconds = std::chrono::duration<double>(Clock::now() - t0).count();
  EXPECT_EQ(report.trace.misses, 0u);

  // The height map: the radius in the direction of the low surface point of
  // each texel inside a chart (what the bake's rays see), of the cube point
  // (s, t) elsewhere (the gutter).
  Mesh low = scene.low;
  MeshStats mesh_stats;
  prepare_low_normals(low, mesh_stats);
  SurfaceStats surface_stats;
  const LowSurface surface = build_low_surface(low, nullptr, surface_stats);
  TexelSamples samples;
  RasterStats raster_stats;
  rasterize(surface, width, height, 1, samples, raster_stats);
  Image atlas = sphere_atlas(p, width, height, kCubeAtlasGutter);
  Image mask;
  mask.width = width;
  mask.height = height;
  mask.channels = 1;
  mask.pixels.assign(static_cast<std::size_t>(width) * height, 0.0f);
  for (int y = 0; y < height; ++y) {
    for (int x = 0; x < width; ++x) {
      const std::size_t texel = static_cast<std::size_t>(y) * width + x;
      if (!samples.coverage[texel]) continue;
      mask.at(x, y)[0] = 1.0f;
      const CubeTexel c = cube_atlas_texel(x, y, width, height, kCubeAtlasGutter);
      if (std::fabs(c.s) > 1.0 || std::fabs(c.t) > 1.0) continue;
      const std::size_t base = 3 * static_cast<std::size_t>(samples.triangle[texel]);
      const glm::vec2 b = samples.bary[texel];
      const glm::vec3 point = surface.position[base] * (1.0f - b.x - b.y) + surface.position[base + 1] * b.x +
                              surface.position[base + 2] * b.y;
      atlas.at(x, y)[0] = scenes::sphere_radius(p, glm::normalize(point)) / p.radius - 1.0f;
    }
  }
  ASSERT_TRUE(write_image(atlas, dir.file("height.exr"), PixelFormat::exr_float).is_ok());
  ASSERT_TRUE(write_image(mask, dir.file("mask.png"), PixelFormat::png8).is_ok());

  const std::string cmd = test::cli_path() + " height2normal " + dir.file("height.exr") +
                          " --cube-sphere --space tangent --low " + dir.file("low.obj") + " -o ";
  t0 = Clock::now();
  test::CommandResult r = test::run_command(cmd + dir.file("h2n.exr"));
  const double h2n_seconds = std::chrono::duration<double>(Clock::now() - t0).count();
  ASSERT_EQ(r.exit_code, 0) << r.output;
  r = test::run_command(cmd + dir.file("h2n_again.exr") + " --threads 1");
  ASSERT_EQ(r.exit_code, 0) << r.output;
  EXPECT_EQ(read_bytes(dir.file("h2n.exr")), read_bytes(dir.file("h2n_again.exr")));

  DiffStats s;
  ASSERT_TRUE(
      diff_files(dir.file("bake.exr"), dir.file("h2n.exr"), dir.file("mask.png"), DiffOptions{}, s, nullptr)
          .is_ok());
  std::printf(
      "cube sphere %dx%d, bake (x4, %llu high triangles, %.2f s) vs height2normal (CLI, %.2f s): %s\n", width,
      height, static_cast<unsigned long long>(report.high_triangles), bake_seconds, h2n_seconds,
      s.summary_line().c_str());
  EXPECT_LT(s.mean, 1.0);
  EXPECT_LT(s.p99, 3.0);
  // The gate through the CLI.
  r = test::run_command(test::cli_path() + " diff " + dir.file("bake.exr") + " " + dir.file("h2n.exr") +
                        " --mask " + dir.file("mask.png") + " --max-mean 1");
  EXPECT_EQ(r.exit_code, 0) << r.output;
}

}  // namespace
}  // namespace nmbake
