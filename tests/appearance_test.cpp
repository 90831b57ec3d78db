// The appearance evaluator (appearance.hpp): what a renderer shows, judged
// against the high mesh from 14 cameras, with its two references.
#include "nmbake/appearance.hpp"

#include <gtest/gtest.h>
#include <tbb/global_control.h>

#include <cstdio>

#include "lab_scenes.hpp"
#include "nmbake/bake.hpp"
#include "nmbake/load.hpp"
#include "nmbake/preview.hpp"
#include "scenes.hpp"
#include "test_util.hpp"

namespace nmbake {
namespace {

Image flat_map(int size) {
  Image map{size, size, 3, {}};
  map.pixels.resize(static_cast<std::size_t>(size) * size * 3);
  for (std::size_t i = 0; i < map.pixels.size(); ++i) map.pixels[i] = i % 3 == 2 ? 1.0f : 0.5f;
  return map;
}

LowSurface surface_of(const Mesh& low) {
  SurfaceStats stats;
  return build_low_surface(low, nullptr, stats);
}

AppearanceOptions small_views() {
  AppearanceOptions o;
  o.size = 96;
  o.supersample = 2;
  return o;
}

// The low mesh rendered as its own high mesh: a map holding (0, 0, 1)
// decodes to exactly the interpolated normal the high mesh shows.
TEST(Appearance, LowEqualsHighScoresZero) {
  scenes::SphereParams p;
  p.low_cells = 4;
  Mesh mesh = scenes::make_displaced_sphere(p).low;
  const LowSurface surface = surface_of(mesh);
  pad_for_embree(mesh);
  AppearanceSamples samples;
  ASSERT_TRUE(render_appearance(surface, mesh, 64, 64, small_views(), samples).is_ok());
  EXPECT_GT(samples.sample_count(), 20000u);
  EXPECT_EQ(samples.high_missed, 0u);
  EXPECT_EQ(samples.depth_rejected, 0u);
  const AppearanceError flat =
      appearance_error(samples, surface, flat_map(64), NormalSpace::tangent, GreenChannel::up);
  const AppearanceError bare = appearance_without_map(samples, surface);
  const AppearanceError floor = appearance_floor(samples);
  std::printf("low = high: flat map %s\n             no map %s\n             floor %s\n",
              flat.to_text().c_str(), bare.to_text().c_str(), floor.to_text().c_str());
  EXPECT_EQ(flat.decode_fallbacks, 0u);
  EXPECT_LT(flat.mean, 1e-3);
  EXPECT_LT(flat.max, 0.01);
  EXPECT_LT(bare.max, 0.01);
  // The smooth normals turn within a texel: one value per texel cannot follow.
  EXPECT_GT(floor.mean, 0.01);
}

struct BoxBake {
  test::TempDir dir;
  Mesh low, high;
  LowSurface surface;
  Image map;
};

// The bevelled box baked with the defaults (auto distances) at 128^2.
void bake_box(BoxBake& b) {
  scenes::BoxParams p;
  p.low_cells = 2;
  p.high_cells = 48;
  const scenes::ScenePair pair = scenes::make_box(p);
  ASSERT_TRUE(save_mesh(b.dir.file("low.obj"), pair.low).is_ok());
  ASSERT_TRUE(save_mesh(b.dir.file("high.ply"), pair.high).is_ok());
  BakeOptions o;
  o.low_path = b.dir.file("low.obj");
  o.high_paths = {b.dir.file("high.ply")};
  o.outputs = {{b.dir.file("map.exr"), PixelFormat::exr_float}};
  o.width = o.height = 128;
  o.padding = 4;
  BakeReport report;
  ASSERT_TRUE(bake(o, report).is_ok());
  ASSERT_TRUE(read_image(b.dir.file("map.exr"), b.map).is_ok());
  ASSERT_TRUE(load_preview_meshes(o.low_path, o.high_paths[0], b.low, b.surface, b.high).is_ok());
}

TEST(Appearance, FlippedGreenIsMuchWorseThanTheRightMap) {
  BoxBake b;
  bake_box(b);
  AppearanceSamples samples;
  ASSERT_TRUE(
      render_appearance(b.surface, b.high, b.map.width, b.map.height, small_views(), samples).is_ok());
  const AppearanceError right =
      appearance_error(samples, b.surface, b.map, NormalSpace::tangent, GreenChannel::up);
  const AppearanceError flipped =
      appearance_error(samples, b.surface, b.map, NormalSpace::tangent, GreenChannel::down);
  const AppearanceError bare = appearance_without_map(samples, b.surface);
  const AppearanceError floor = appearance_floor(samples);
  std::printf("box: right %s\n     green flipped %s\n     no map %s\n     floor %s\n",
              right.to_text().c_str(), flipped.to_text().c_str(), bare.to_text().c_str(),
              floor.to_text().c_str());
  EXPECT_GT(flipped.mean, 5.0 * right.mean);
  EXPECT_GT(bare.mean, 3.0 * right.mean);
  EXPECT_LT(right.mean, 1.3 * floor.mean);
}

TEST(Appearance, SameFiguresForAnyThreadCount) {
  BoxBake b;
  bake_box(b);
  AppearanceError e[2];
  for (int threads : {1, 2}) {
    tbb::global_control limit(tbb::global_control::max_allowed_parallelism,
                              static_cast<std::size_t>(threads));
    AppearanceSamples samples;
    ASSERT_TRUE(render_appearance(b.surface, b.high, 128, 128, small_views(), samples).is_ok());
    e[threads - 1] = appearance_error(samples, b.surface, b.map, NormalSpace::tangent, GreenChannel::up);
  }
  EXPECT_EQ(e[0].samples, e[1].samples);
  EXPECT_EQ(e[0].mean, e[1].mean);
  EXPECT_EQ(e[0].p99, e[1].p99);
}

TEST(Appearance, RejectsBadOptions) {
  scenes::SphereParams p;
  p.low_cells = 2;
  Mesh mesh = scenes::make_displaced_sphere(p).low;
  const LowSurface surface = surface_of(mesh);
  pad_for_embree(mesh);
  AppearanceSamples samples;
  AppearanceOptions o = small_views();
  o.depth_tolerance = 0.0f;
  EXPECT_EQ(render_appearance(surface, mesh, 16, 16, o, samples).code(), StatusCode::bad_input);
  o = small_views();
  o.size = 8;
  EXPECT_EQ(render_appearance(surface, mesh, 16, 16, o, samples).code(), StatusCode::bad_input);
  EXPECT_EQ(render_appearance(surface, mesh, 0, 16, small_views(), samples).code(), StatusCode::bad_input);
}

}  // namespace
}  // namespace nmbake
