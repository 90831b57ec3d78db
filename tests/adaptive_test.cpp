// Adaptive sampling (adaptive.hpp): the compact raster, the refinement rule,
// and bakes that must equal fixed ones where the rule says all or nothing,
// whatever the threads, bands and tiles.
#include "nmbake/adaptive.hpp"

#include <gtest/gtest.h>
#include <tbb/global_control.h>

#include <algorithm>
#include <filesystem>
#include <fstream>
#include <iterator>

#include "lab_scenes.hpp"
#include "nmbake/bake.hpp"
#include "nmbake/task.hpp"
#include "scenes.hpp"
#include "test_util.hpp"

namespace nmbake {
namespace {

std::string read_bytes(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  return std::string(std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>());
}

// The displaced sphere (curved low mesh, several charts) and the box (hard
// edges, bevels): the options of a small adaptive bake, outputs to set.
BakeOptions scene_bake(const test::TempDir& dir, const scenes::ScenePair& pair, int width, int height) {
  EXPECT_TRUE(save_mesh(dir.file("low.obj"), pair.low).is_ok());
  EXPECT_TRUE(save_mesh(dir.file("high.ply"), pair.high).is_ok());
  BakeOptions o;
  o.low_path = dir.file("low.obj");
  o.high_paths = {dir.file("high.ply")};
  o.width = width;
  o.height = height;
  o.adaptive = true;
  return o;
}

scenes::ScenePair small_sphere() {
  scenes::SphereParams params;
  params.high_cells = 48;
  params.low_cells = 3;
  return scenes::make_displaced_sphere(params);
}

std::string bake_to(BakeOptions o, const std::string& path, BakeReport& report) {
  o.outputs = {{path, PixelFormat::exr_float}};
  const Status s = bake(o, report);
  EXPECT_TRUE(s.is_ok()) << s.message();
  return read_bytes(path);
}

// A compact raster of some texels gives each exactly what the full raster
// gives it, samples and coverage, and counts only them.
TEST(AdaptiveRaster, SelectedTexelsEqualTheFullRaster) {
  const scenes::ScenePair pair = small_sphere();
  SurfaceStats stats;
  Mesh low = pair.low;
  MeshStats mesh_stats;
  prepare_low_normals(low, mesh_stats);
  const LowSurface surface = build_low_surface(low, nullptr, stats);
  const int width = 77, height = 70;
  for (const int samples : {4, 16, 64}) {
    for (const int band_begin : {0, 32}) {
      const int band_end = std::min(height, band_begin + 38);
      TexelSamples full, compact;
      RasterStats full_stats, compact_stats;
      rasterize(surface, width, height, samples, full, full_stats, band_begin, band_end);
      // Every third texel, and a run at a chart border.
      std::vector<std::uint32_t> texels;
      for (std::uint32_t t = 0; t < static_cast<std::uint32_t>(width * (band_end - band_begin)); ++t) {
        if (t % 3 == 0 || (t > 500 && t < 540)) texels.push_back(t);
      }
      std::vector<std::uint32_t> slot;
      rasterize_selected(surface, width, height, samples, band_begin, band_end, texels.data(), texels.size(),
                         compact, compact_stats, slot);
      ASSERT_EQ(compact.width, static_cast<int>(texels.size()));
      ASSERT_EQ(compact.height, 1);
      ASSERT_EQ(compact.samples, samples);
      std::uint64_t covered = 0;
      for (std::size_t i = 0; i < texels.size(); ++i) {
        const std::size_t t = texels[i];
        ASSERT_EQ(compact.coverage[i], full.coverage[t]) << t;
        covered += full.coverage[t];
        for (int s = 0; s < samples; ++s) {
          const std::size_t a = i * samples + s, b = t * samples + s;
          ASSERT_EQ(compact.triangle[a], full.triangle[b]) << t << " " << s;
          ASSERT_EQ(compact.bary[a], full.bary[b]) << t << " " << s;
        }
      }
      EXPECT_EQ(compact_stats.covered_texels, covered);
      // The scratch is left clean for the next call.
      EXPECT_TRUE(std::all_of(slot.begin(), slot.end(), [](std::uint32_t v) { return v == 0xffffffffu; }));
    }
  }
}

// Thresholds of zero refine every covered texel: the map is the fixed
// max_samples bake's, byte for byte; thresholds out of reach refine none:
// the one-sample bake's.
TEST(AdaptiveBake, AllOrNothingEqualsTheFixedBakes) {
  test::TempDir dir;
  BakeOptions o = scene_bake(dir, small_sphere(), 96, 80);
  BakeReport report;
  for (const int n : {4, 16}) {
    BakeOptions fixed = o;
    fixed.adaptive = false;
    fixed.samples = n;
    const std::string expected = bake_to(fixed, dir.file("fixed.exr"), report);
    BakeOptions all = o;
    all.adaptive_options = {n, 0.0f, 0.0f, 0.0f, 0.0f};
    BakeReport adaptive;
    EXPECT_EQ(bake_to(all, dir.file("all.exr"), adaptive), expected) << n;
    const std::uint64_t covered = adaptive.raster.covered_texels;
    EXPECT_EQ(adaptive.adaptive.refined_texels, covered);
    // Every texel through every level: 4 samples, then 16.
    const std::vector<std::uint64_t> texels =
        n == 4 ? std::vector<std::uint64_t>{covered} : std::vector<std::uint64_t>{covered, covered};
    EXPECT_EQ(adaptive.adaptive.level_texels, texels);
    std::uint64_t rays = adaptive.adaptive.first_pass_rays;
    for (const std::uint64_t r : adaptive.adaptive.level_rays) rays += r;
    EXPECT_EQ(adaptive.trace.rays, rays);
    EXPECT_EQ(adaptive.adaptive.level_rays.back(), covered * static_cast<std::uint64_t>(n));
  }
  BakeOptions one = o;
  one.adaptive = false;
  one.samples = 1;
  const std::string expected = bake_to(one, dir.file("one.exr"), report);
  BakeOptions none = o;
  none.adaptive_options = {16, 1e9f, 1e9f, 1e9f, 1e9f};
  BakeReport adaptive;
  EXPECT_EQ(bake_to(none, dir.file("none.exr"), adaptive), expected);
  EXPECT_EQ(adaptive.adaptive.refined_texels, 0u);
  EXPECT_EQ(adaptive.trace.rays, adaptive.raster.covered_texels);
}

// The default rule refines some texels and not others, and the same ones
// for any thread count, any band size, and in tiles of rows merged.
TEST(AdaptiveBake, SameBytesForThreadsBandsAndTiles) {
  test::TempDir dir;
  BakeOptions o = scene_bake(dir, small_sphere(), 150, 140);
  o.adaptive_options.normal_threshold = 0.001f;  // this coarse sphere refines a few texels at the default
  o.adaptive_options.spread_threshold = 0.005f;
  BakeReport report;
  std::string whole;
  {
    tbb::global_control one(tbb::global_control::max_allowed_parallelism, 1);
    whole = bake_to(o, dir.file("one_thread.exr"), report);
  }
  EXPECT_GT(report.adaptive.refined_texels, 0u);
  EXPECT_LT(report.adaptive.refined_texels, report.raster.covered_texels / 2);
  ASSERT_EQ(report.adaptive.level_texels.size(), 2u);
  EXPECT_GT(report.adaptive.level_texels[1], 0u);
  EXPECT_LT(report.adaptive.level_texels[1], report.adaptive.level_texels[0]);
  const std::uint64_t refined = report.adaptive.refined_texels;
  EXPECT_EQ(bake_to(o, dir.file("all_threads.exr"), report), whole);
  for (const std::size_t band : {std::size_t{150 * 32}, std::size_t{150 * 64}, std::size_t{1}}) {
    BakeOptions banded = o;
    banded.band_samples = band;  // 32, 64 rows; 1: a refine chunk of one texel
    EXPECT_EQ(bake_to(banded, dir.file("banded.exr"), report), whole) << band;
    EXPECT_EQ(report.adaptive.refined_texels, refined);
  }
  // Tiles of rows: each first traces the rows just outside it.
  o.outputs = {{dir.file("whole.exr"), PixelFormat::exr_float}};
  ASSERT_TRUE(bake(o, report).is_ok());
  for (const int count : {2, 3}) {
    std::vector<std::string> tiles;
    for (int i = 0; i < count; ++i) {
      BakeOptions tile = o;
      tile.tile_index = i;
      tile.tile_count = count;
      tile.tile_path = dir.file(std::to_string(i) + ".tile");
      const Status s = bake(tile, report);
      ASSERT_TRUE(s.is_ok()) << s.message();
      if (i > 0) {
        EXPECT_GT(report.adaptive.halo_rays, 0u);
      }
      tiles.push_back(tile.tile_path);
    }
    MergeReport merged;
    ASSERT_TRUE(merge_tiles(tiles, {{dir.file("merged.exr"), PixelFormat::exr_float}}, merged).is_ok());
    EXPECT_EQ(read_bytes(dir.file("merged.exr")), read_bytes(dir.file("whole.exr"))) << count << " tiles";
  }
}

// On the hard-edged box the rule refines the bevels and leaves the flat
// faces alone; the debug dump shows where.
TEST(AdaptiveBake, RefinesTheBevelsOfTheBox) {
  test::TempDir dir;
  scenes::BoxParams box;
  box.high_cells = 64;
  BakeOptions o = scene_bake(dir, scenes::make_box(box), 128, 128);
  o.debug_dump_prefix = dir.file("dump");
  BakeReport report;
  bake_to(o, dir.file("box.exr"), report);
  const double fraction = static_cast<double>(report.adaptive.refined_texels) / report.raster.covered_texels;
  EXPECT_GT(fraction, 0.01);
  EXPECT_LT(fraction, 0.5);
  Image mask;
  ASSERT_TRUE(read_image(dir.file("dump_refined.png"), mask).is_ok());
  // Level 1 grey, level 2 white.
  std::uint64_t marked = 0, white = 0;
  for (std::size_t i = 0; i < mask.pixels.size(); i += static_cast<std::size_t>(mask.channels)) {
    marked += mask.pixels[i] > 0.25f ? 1 : 0;
    white += mask.pixels[i] > 0.75f ? 1 : 0;
  }
  EXPECT_EQ(marked, report.adaptive.level_texels[0]);
  EXPECT_EQ(white, report.adaptive.level_texels[1]);
  EXPECT_NE(report.to_json().find("\"refined_texels\""), std::string::npos);
  EXPECT_NE(report.summary_line().find("adaptive (1-16 spp"), std::string::npos);
}

TEST(AdaptiveCli, FlagsJobFilesAndBadValues) {
  test::TempDir dir;
  ASSERT_TRUE(save_mesh(dir.file("low.obj"), small_sphere().low).is_ok());
  ASSERT_TRUE(save_mesh(dir.file("high.ply"), small_sphere().high).is_ok());
  const std::string base = test::cli_path() + " bake --low " + dir.file("low.obj") + " --high " +
                           dir.file("high.ply") + " --size 64 -o " + dir.file("m.png");
  test::CommandResult r = test::run_command(base + " --samples adaptive --adaptive-max 4");
  EXPECT_EQ(r.exit_code, 0) << r.output;
  EXPECT_NE(r.output.find("adaptive (1-4 spp"), std::string::npos) << r.output;
  r = test::run_command(base + " --samples adaptive --adaptive-max 8");
  EXPECT_EQ(r.exit_code, 2) << r.output;
  EXPECT_NE(r.output.find("--adaptive-max 8 is not supported"), std::string::npos) << r.output;
  // A map set needs a fixed count; nothing is written.
  const std::string set_base = test::cli_path() + " bake --low " + dir.file("low.obj") + " --high " +
                               dir.file("high.ply") + " --size 64 -o '" + dir.file("set_<MAP>.png") + "'";
  r = test::run_command(set_base + " --samples adaptive --map normal,height");
  EXPECT_EQ(r.exit_code, 2) << r.output;
  EXPECT_NE(r.output.find("--samples adaptive bakes the normal map alone"), std::string::npos) << r.output;
  EXPECT_FALSE(std::filesystem::exists(dir.file("set_normal.png")));
  EXPECT_FALSE(std::filesystem::exists(dir.file("set_height.png")));
  r = test::run_command(base + " --samples lots");
  EXPECT_EQ(r.exit_code, 2) << r.output;
  EXPECT_NE(r.output.find("expected 1, 4, 16, 64 or adaptive"), std::string::npos) << r.output;
  test::write_text(dir.file("job.toml"),
                   "[[bake]]\nlow = \"low.obj\"\nhigh = \"high.ply\"\nsize = 64\nsamples = "
                   "\"adaptive\"\nadaptive_max = 64\noutputs = [\"j.png\"]\n");
  r = test::run_command(test::cli_path() + " bake " + dir.file("job.toml"));
  EXPECT_EQ(r.exit_code, 0) << r.output;
  EXPECT_NE(r.output.find("adaptive (1-64 spp"), std::string::npos) << r.output;
}

}  // namespace
}  // namespace nmbake
