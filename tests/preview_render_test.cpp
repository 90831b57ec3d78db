// The 3D preview sheet and the tangent-frame views: golden images with a
// tolerance, determinism across thread counts, the heat map of a perfect and
// of a deliberately wrong bake, and the CLI contract.
//
// Goldens live in tests/golden/. After an intended change of the rendering,
// regenerate them with NMBAKE_UPDATE_GOLDEN=1 ./build/tests/nmbake_tests
// --gtest_filter='PreviewRender*:TangentsView*' and look at them before
// committing.
#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <fstream>
#include <iterator>

#include "nmbake/bake.hpp"
#include "nmbake/load.hpp"
#include "nmbake/preview.hpp"
#include "scenes.hpp"
#include "test_util.hpp"

namespace nmbake {
namespace {

std::string read_bytes(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  return std::string(std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>());
}

// Mean absolute difference of the RGB values against tests/golden/NAME, or
// writes the golden when NMBAKE_UPDATE_GOLDEN is set.
void expect_matches_golden(const Image& image, const std::string& name, double tolerance) {
  const std::string path = test::source_dir() + "/tests/golden/" + name;
  if (std::getenv("NMBAKE_UPDATE_GOLDEN") != nullptr) {
    ASSERT_TRUE(write_image(image, path, PixelFormat::png8).is_ok());
    std::printf("golden written: %s\n", path.c_str());
    return;
  }
  Image golden;
  const Status s = read_image(path, golden);
  ASSERT_TRUE(s.is_ok()) << s.message() << " (regenerate with NMBAKE_UPDATE_GOLDEN=1)";
  ASSERT_EQ(golden.width, image.width);
  ASSERT_EQ(golden.height, image.height);
  ASSERT_GE(golden.channels, 3);
  double sum = 0.0;
  for (int y = 0; y < image.height; ++y) {
    for (int x = 0; x < image.width; ++x) {
      for (int c = 0; c < 3; ++c) sum += std::fabs(golden.at(x, y)[c] - image.at(x, y)[c]);
    }
  }
  const double mean = sum / (3.0 * image.width * image.height);
  std::printf("%s: mean absolute difference %.5f\n", name.c_str(), mean);
  EXPECT_LT(mean, tolerance) << name;
}

// A small heightfield baked once for the whole suite (about 0.2 s).
class PreviewRender : public ::testing::Test {
 protected:
  static void SetUpTestSuite() {
    dir_ = new test::TempDir();
    scenes::HeightfieldParams params;
    params.high_cells = 96;
    const scenes::ScenePair scene = scenes::make_heightfield(params);
    ASSERT_TRUE(save_mesh(dir_->file("low.obj"), scene.low).is_ok());
    ASSERT_TRUE(save_mesh(dir_->file("high.ply"), scene.high).is_ok());
    for (const NormalSpace space : {NormalSpace::tangent, NormalSpace::object}) {
      BakeOptions o;
      o.low_path = dir_->file("low.obj");
      o.high_paths = {dir_->file("high.ply")};
      o.outputs = {
          {dir_->file(space == NormalSpace::tangent ? "map.png" : "map_os.png"), PixelFormat::png16}};
      o.width = o.height = 128;
      o.encode.space = space;
      BakeReport report;
      const Status s = bake(o, report);
      ASSERT_TRUE(s.is_ok()) << s.message();
    }
  }
  static void TearDownTestSuite() {
    delete dir_;
    dir_ = nullptr;
  }

  static PreviewOptions options(int size) {
    PreviewOptions o;
    o.view.size = size;
    o.view.up = UpAxis::z;
    o.view.yaw_degrees = 20.0f;
    o.view.pitch_degrees = 40.0f;
    return o;
  }

  static void render(const std::string& map_name, const PreviewOptions& o, Image& sheet,
                     PreviewStats& stats) {
    Mesh low, high;
    LowSurface surface;
    ASSERT_TRUE(
        load_preview_meshes(dir_->file("low.obj"), dir_->file("high.ply"), low, surface, high).is_ok());
    Image map;
    ASSERT_TRUE(read_image(dir_->file(map_name), map).is_ok());
    const Status s = render_preview(surface, high, map, o, sheet, stats);
    ASSERT_TRUE(s.is_ok()) << s.message();
  }

  static test::TempDir* dir_;
};
test::TempDir* PreviewRender::dir_ = nullptr;

TEST_F(PreviewRender, PerfectBakeShowsLowError) {
  Image sheet;
  PreviewStats stats;
  render("map.png", options(64), sheet, stats);
  std::printf("perfect bake: mean %.4f p99 %.4f max %.3f deg over %llu samples, %llu misses\n",
              stats.all.mean_degrees, stats.all.p99_degrees, stats.all.max_degrees,
              static_cast<unsigned long long>(stats.all.low_samples),
              static_cast<unsigned long long>(stats.all.bake_misses));
  EXPECT_GT(stats.all.low_samples, 64u * 64u);  // the plane fills a good part of the view
  EXPECT_EQ(stats.all.bake_misses, 0u);
  EXPECT_LT(stats.all.mean_degrees, 0.5);
  EXPECT_LT(stats.all.p99_degrees, 2.0);
  EXPECT_EQ(stats.decode_fallbacks, 0u);
  EXPECT_EQ(sheet.width, 3 * 64 + 2 * 2);
  EXPECT_EQ(sheet.height, 64);
}

TEST_F(PreviewRender, FlippedGreenShowsLargeError) {
  PreviewOptions o = options(64);
  Image perfect_sheet, sheet;
  PreviewStats perfect, flipped;
  render("map.png", o, perfect_sheet, perfect);
  o.green = GreenChannel::down;  // the map was baked green up
  render("map.png", o, sheet, flipped);
  std::printf("flipped green: mean %.3f p99 %.3f deg (perfect %.4f)\n", flipped.all.mean_degrees,
              flipped.all.p99_degrees, perfect.all.mean_degrees);
  EXPECT_GT(flipped.all.mean_degrees, 2.0);
  EXPECT_GT(flipped.all.mean_degrees, 10.0 * perfect.all.mean_degrees);
  // The shaded low panel changes too, the high panel does not.
  double low_diff = 0.0, high_diff = 0.0;
  for (int y = 0; y < 64; ++y) {
    for (int x = 0; x < 64; ++x) {
      for (int c = 0; c < 3; ++c) {
        high_diff += std::fabs(sheet.at(x, y)[c] - perfect_sheet.at(x, y)[c]);
        low_diff += std::fabs(sheet.at(x + 66, y)[c] - perfect_sheet.at(x + 66, y)[c]);
      }
    }
  }
  EXPECT_EQ(high_diff, 0.0);
  EXPECT_GT(low_diff, 1.0);
}

// On the curved sphere the object-space and tangent-space readings differ,
// so --space matters (on the flat heightfield the frame is the identity).
TEST(PreviewRenderSphere, ObjectSpaceMapDecodesDirectly) {
  test::TempDir dir;
  scenes::SphereParams params;
  params.low_cells = 4;
  params.high_cells = 48;
  const scenes::ScenePair scene = scenes::make_displaced_sphere(params);
  ASSERT_TRUE(save_mesh(dir.file("low.obj"), scene.low).is_ok());
  ASSERT_TRUE(save_mesh(dir.file("high.ply"), scene.high).is_ok());
  BakeOptions b;
  b.low_path = dir.file("low.obj");
  b.high_paths = {dir.file("high.ply")};
  b.outputs = {{dir.file("map_os.png"), PixelFormat::png16}};
  b.width = b.height = 128;
  b.encode.space = NormalSpace::object;
  BakeReport report;
  ASSERT_TRUE(bake(b, report).is_ok());

  Mesh low, high;
  LowSurface surface;
  ASSERT_TRUE(load_preview_meshes(dir.file("low.obj"), dir.file("high.ply"), low, surface, high).is_ok());
  Image map, sheet;
  ASSERT_TRUE(read_image(dir.file("map_os.png"), map).is_ok());
  PreviewOptions o;
  o.view.size = 48;
  o.space = NormalSpace::object;
  PreviewStats right, wrong;
  ASSERT_TRUE(render_preview(surface, high, map, o, sheet, right).is_ok());
  o.space = NormalSpace::tangent;
  ASSERT_TRUE(render_preview(surface, high, map, o, sheet, wrong).is_ok());
  std::printf("object-space map: read as object %.4f deg, as tangent %.2f deg\n", right.all.mean_degrees,
              wrong.all.mean_degrees);
  EXPECT_LT(right.all.mean_degrees, 0.5);
  EXPECT_GT(wrong.all.mean_degrees, 10.0);
}

TEST_F(PreviewRender, GoldenSheet) {
  PreviewOptions o = options(96);
  o.turntable = 2;
  o.green = GreenChannel::down;  // a visible error pattern makes a better golden
  Image sheet;
  PreviewStats stats;
  render("map.png", o, sheet, stats);
  ASSERT_EQ(stats.views.size(), 2u);
  EXPECT_EQ(sheet.height, 2 * 96 + 2);
  expect_matches_golden(sheet, "preview_heightfield.png", 0.01);
}

TEST_F(PreviewRender, RejectsBadOptions) {
  Mesh low, high;
  LowSurface surface;
  ASSERT_TRUE(load_preview_meshes(dir_->file("low.obj"), dir_->file("high.ply"), low, surface, high).is_ok());
  Image map;
  ASSERT_TRUE(read_image(dir_->file("map.png"), map).is_ok());
  Image sheet;
  PreviewStats stats;
  PreviewOptions o = options(32);
  o.view.pitch_degrees = 90.0f;
  EXPECT_EQ(render_preview(surface, high, map, o, sheet, stats).code(), StatusCode::bad_input);
  o = options(32);
  o.view.light = glm::vec3(0.0f);
  EXPECT_EQ(render_preview(surface, high, map, o, sheet, stats).code(), StatusCode::bad_input);
  o = options(32);
  o.turntable = 0;
  EXPECT_EQ(render_preview(surface, high, map, o, sheet, stats).code(), StatusCode::bad_input);
  o = options(8);
  EXPECT_EQ(render_preview(surface, high, map, o, sheet, stats).code(), StatusCode::bad_input);
}

TEST_F(PreviewRender, CliSameBytesWithOneAndTwoThreads) {
  const std::string common = test::cli_path() + " preview -q --low " + dir_->file("low.obj") + " --high " +
                             dir_->file("high.ply") + " --map " + dir_->file("map.png") +
                             " --size 48 --up z --turntable 2 --light=-0.3,0.8,0.5";
  const auto a = test::run_command(common + " --threads 1 -o " + dir_->file("a.png"));
  const auto b = test::run_command(common + " --threads 2 -o " + dir_->file("b.png"));
  ASSERT_EQ(a.exit_code, 0) << a.output;
  ASSERT_EQ(b.exit_code, 0) << b.output;
  const std::string bytes = read_bytes(dir_->file("a.png"));
  EXPECT_GT(bytes.size(), 1000u);
  EXPECT_EQ(bytes, read_bytes(dir_->file("b.png")));
}

TEST_F(PreviewRender, CliModesAndBadInput) {
  const std::string cli = test::cli_path() + " preview --map " + dir_->file("map.png");
  // Without --low/--high: the lit map, as before.
  const auto lit = test::run_command(cli + " -o " + dir_->file("lit.png"));
  EXPECT_EQ(lit.exit_code, 0) << lit.output;
  Image image;
  ASSERT_TRUE(read_image(dir_->file("lit.png"), image).is_ok());
  EXPECT_EQ(image.width, 128);
  // The 3D sheet prints its statistics.
  const auto sheet = test::run_command(cli + " --low " + dir_->file("low.obj") + " --high " +
                                       dir_->file("high.ply") + " --size 32 -o " + dir_->file("sheet.png"));
  EXPECT_EQ(sheet.exit_code, 0) << sheet.output;
  EXPECT_NE(sheet.output.find("error mean"), std::string::npos) << sheet.output;
  // Usage errors exit 2 and write nothing.
  const auto half = test::run_command(cli + " --low " + dir_->file("low.obj") + " -o " + dir_->file("x.png"));
  EXPECT_EQ(half.exit_code, 2) << half.output;
  const auto light = test::run_command(cli + " --low " + dir_->file("low.obj") + " --high " +
                                       dir_->file("high.ply") + " --light 1,2 -o " + dir_->file("x.png"));
  EXPECT_EQ(light.exit_code, 2) << light.output;
  EXPECT_NE(light.output.find("--light"), std::string::npos);
  const auto missing = test::run_command(cli + " --low " + dir_->file("nope.obj") + " --high " +
                                         dir_->file("high.ply") + " -o " + dir_->file("x.png"));
  EXPECT_EQ(missing.exit_code, 2) << missing.output;
  EXPECT_FALSE(std::filesystem::exists(dir_->file("x.png")));
}

// A map baked for Godot (per-vertex bitangent, normalised frame, z
// rebuilt) and previewed with that decode: the error panel's mean is at the
// level of a default bake previewed the default way; read with the default
// decode it is not. A coarse low sphere (frames far from orthonormal).
TEST(PreviewRenderSphere, DecodesAsThePresetSays) {
  scenes::SphereParams params;
  params.low_cells = 2;
  params.high_cells = 32;
  params.amplitude = 0.05f;
  scenes::ScenePair scene = scenes::make_displaced_sphere(params);
  MeshStats mesh_stats;
  prepare_low_normals(scene.low, mesh_stats);
  normalize_normals(scene.high, mesh_stats);
  pad_for_embree(scene.high);
  SurfaceStats surface_stats;
  const LowSurface surface = build_low_surface(scene.low, nullptr, surface_stats);
  HighScene high_scene;
  ASSERT_TRUE(HighScene::build(scene.high, BuildQuality::medium, false, high_scene).is_ok());
  TexelSamples samples;
  RasterStats raster_stats;
  rasterize(surface, 256, 256, 1, samples, raster_stats);
  RayOptions rays;
  rays.front = rays.back = 0.2f;
  Hits hits;
  TraceStats trace_stats;
  trace(high_scene, surface, samples, rays, hits, trace_stats);
  EncodeOptions encode_options;
  encode_options.decode = {Bitangent::vertex, true, true};
  Image map;
  EncodeStats encode_stats;
  encode(surface, samples, scene.high, hits, encode_options, map, encode_stats);
  DilateStats dilate_stats;
  dilate(map, samples.coverage, 8, dilate_stats);

  PreviewOptions options;
  options.view.size = 64;
  options.view.supersample = 1;
  options.rays.front = options.rays.back = {Distance::Kind::absolute, 0.2f};
  Image sheet;
  PreviewStats right, wrong;
  options.decode = encode_options.decode;
  ASSERT_TRUE(render_preview(surface, scene.high, map, options, sheet, right).is_ok());
  options.decode = NormalDecode{};
  ASSERT_TRUE(render_preview(surface, scene.high, map, options, sheet, wrong).is_ok());
  std::printf("godot map: godot decode mean %.4f deg, default decode mean %.4f deg\n", right.all.mean_degrees,
              wrong.all.mean_degrees);
  EXPECT_LT(right.all.mean_degrees, 0.6 * wrong.all.mean_degrees);
}

// --- Tangent-frame views -----------------------------------------------------

LowSurface sphere_surface(scenes::ScenePair& scene) {
  scenes::SphereParams params;
  params.low_cells = 3;
  params.high_cells = 3;
  scene = scenes::make_displaced_sphere(params);
  SurfaceStats stats;
  return build_low_surface(scene.low, nullptr, stats);
}

TEST(TangentsView, GoldenFramesAndUvLayout) {
  scenes::ScenePair scene;
  const LowSurface surface = sphere_surface(scene);
  TangentViewOptions o;
  o.view.size = 96;
  Image frames, uv;
  TangentViewStats stats;
  ASSERT_TRUE(render_tangent_frames(surface, o, frames, stats).is_ok());
  EXPECT_GT(stats.frames, 0u);
  EXPECT_EQ(stats.mirrored_triangles, 0u);
  ASSERT_TRUE(render_uv_layout(surface, 96, uv, stats).is_ok());
  expect_matches_golden(frames, "tangents_frames_sphere.png", 0.01);
  expect_matches_golden(uv, "tangents_uv_sphere.png", 0.01);
}

// Mirroring the UVs (u -> 1 - u) flips every tangent sign: counted, hatched
// in the UV view, and the bitangent lines turn around.
TEST(TangentsView, MirroredChartIsMarked) {
  scenes::HeightfieldParams params;
  params.high_cells = 2;
  scenes::ScenePair scene = scenes::make_heightfield(params);
  SurfaceStats surface_stats;
  const LowSurface plain = build_low_surface(scene.low, nullptr, surface_stats);
  for (glm::vec2& uv : scene.low.uvs) uv.x = 1.0f - uv.x;
  const LowSurface mirrored = build_low_surface(scene.low, nullptr, surface_stats);

  Image plain_uv, mirrored_uv;
  TangentViewStats plain_stats, mirrored_stats;
  ASSERT_TRUE(render_uv_layout(plain, 64, plain_uv, plain_stats).is_ok());
  ASSERT_TRUE(render_uv_layout(mirrored, 64, mirrored_uv, mirrored_stats).is_ok());
  EXPECT_EQ(plain_stats.mirrored_triangles, 0u);
  EXPECT_EQ(mirrored_stats.mirrored_triangles, mirrored.triangle_count());
  // Hatching: many dark pixels inside the chart of the mirrored layout only.
  auto dark_pixels = [](const Image& image) {
    int dark = 0;
    for (int y = 4; y < image.height - 4; ++y) {
      for (int x = 4; x < image.width - 4; ++x) {
        const float* p = image.at(x, y);
        dark += (p[0] + p[1] + p[2] < 0.6f) ? 1 : 0;
      }
    }
    return dark;
  };
  EXPECT_GT(dark_pixels(mirrored_uv), dark_pixels(plain_uv) + 400);

  TangentViewOptions o;
  o.view.size = 64;
  o.view.up = UpAxis::z;
  o.view.pitch_degrees = 60.0f;
  Image plain_frames, mirrored_frames;
  ASSERT_TRUE(render_tangent_frames(plain, o, plain_frames, plain_stats).is_ok());
  ASSERT_TRUE(render_tangent_frames(mirrored, o, mirrored_frames, mirrored_stats).is_ok());
  EXPECT_NE(plain_frames.pixels, mirrored_frames.pixels);
}

// Huge but finite UVs are drawn off the image, never overflow a pixel index.
TEST(TangentsView, AbsurdUvsAreSkipped) {
  scenes::HeightfieldParams params;
  params.high_cells = 2;
  scenes::ScenePair scene = scenes::make_heightfield(params);
  scene.low.uvs[0] = glm::vec2(1e30f, -1e30f);
  SurfaceStats surface_stats;
  const LowSurface surface = build_low_surface(scene.low, nullptr, surface_stats);
  Image uv;
  TangentViewStats stats;
  ASSERT_TRUE(render_uv_layout(surface, 32, uv, stats).is_ok());
  for (float v : uv.pixels) ASSERT_TRUE(std::isfinite(v));
}

TEST(TangentsView, CliSameBytesWithOneAndTwoThreads) {
  test::TempDir dir;
  scenes::ScenePair scene;
  sphere_surface(scene);
  ASSERT_TRUE(save_mesh(dir.file("low.obj"), scene.low).is_ok());
  const std::string common =
      test::cli_path() + " tangents -q " + dir.file("low.obj") + " --size 64 --uv-size 64";
  const auto a = test::run_command(common + " --threads 1 --view " + dir.file("a.png") + " --uv-view " +
                                   dir.file("ua.png"));
  const auto b = test::run_command(common + " --threads 2 --view " + dir.file("b.png") + " --uv-view " +
                                   dir.file("ub.png"));
  ASSERT_EQ(a.exit_code, 0) << a.output;
  ASSERT_EQ(b.exit_code, 0) << b.output;
  EXPECT_EQ(read_bytes(dir.file("a.png")), read_bytes(dir.file("b.png")));
  EXPECT_EQ(read_bytes(dir.file("ua.png")), read_bytes(dir.file("ub.png")));
  const auto nothing = test::run_command(test::cli_path() + " tangents " + dir.file("low.obj"));
  EXPECT_EQ(nothing.exit_code, 2) << nothing.output;
  const auto tif = test::run_command(test::cli_path() + " tangents " + dir.file("low.obj") + " --view " +
                                     dir.file("v.tif"));
  EXPECT_EQ(tif.exit_code, 2) << tif.output;
}

}  // namespace
}  // namespace nmbake
