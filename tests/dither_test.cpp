// Banding of 8-bit maps, dithered or rounded (README, "8-bit maps:
// dithering"): the sphere scene baked to a float map, written as png8 both
// ways (the bake's write stage: the float texels are the same), and
// measured against the float map. The figures of the README come from this
// test's "[ figures ]" lines.
#include <gtest/gtest.h>
#include <tbb/global_control.h>

#include <algorithm>
#include <cmath>
#include <fstream>
#include <glm/geometric.hpp>
#include <glm/trigonometric.hpp>
#include <iostream>
#include <iterator>

#include "nmbake/bake.hpp"
#include "nmbake/task.hpp"
#include "scenes.hpp"
#include "test_util.hpp"

namespace nmbake {
namespace {

glm::dvec3 decoded(const Image& image, std::size_t texel) {
  const float* p = &image.pixels[3 * texel];
  return glm::dvec3(2.0 * p[0] - 1.0, 2.0 * p[1] - 1.0, 2.0 * p[2] - 1.0);
}

double angle_degrees(const glm::dvec3& a, const glm::dvec3& b) {
  return glm::degrees(std::atan2(glm::length(glm::cross(a, b)), glm::dot(a, b)));
}

struct Banding {
  int longest_run = 0;        // equal 8-bit values along a row in red or green (x, y), inside the charts
  double mean_run = 0.0;      // the length of the run a texel lies in, averaged over texels (and red, green)
  double share_long = 0.0;    // of texels in runs of 16 or more
  double mean_degrees = 0.0;  // per texel, against the float map
  double mean_4x4_degrees = 0.0;  // 4 x 4 blocks averaged (a mip level three down), against the float map's
};

// `inside[t]`: texel t lies in a chart (not background).
Banding measure(const Image& reference, const Image& map, const std::vector<bool>& inside) {
  Banding b;
  const int w = map.width, h = map.height;
  // Not blue: z sits at the top of its range (254-255) wherever the relief
  // is gentle, with or without a pattern (255 cannot be dithered upward).
  double weighted = 0.0, long_texels = 0.0, texels = 0.0;
  const auto close_run = [&](int run) {
    b.longest_run = std::max(b.longest_run, run);
    weighted += static_cast<double>(run) * run;
    texels += run;
    if (run >= 16) long_texels += run;
  };
  for (int c = 0; c < 2; ++c) {
    for (int y = 0; y < h; ++y) {
      int run = 0;
      long last = -1;
      for (int x = 0; x < w; ++x) {
        const std::size_t t = static_cast<std::size_t>(y) * w + x;
        const long q = inside[t] ? std::lround(map.pixels[3 * t + c] * 255.0f) : -1;
        if (q != last && last >= 0) close_run(run);
        run = q >= 0 && q == last ? run + 1 : 1;
        last = q;
      }
      if (last >= 0) close_run(run);
    }
  }
  b.mean_run = weighted / texels;
  b.share_long = long_texels / texels;
  double sum = 0.0;
  std::size_t count = 0;
  for (std::size_t t = 0; t < inside.size(); ++t) {
    if (!inside[t]) continue;
    sum += angle_degrees(decoded(map, t), decoded(reference, t));
    ++count;
  }
  b.mean_degrees = sum / static_cast<double>(count);
  sum = 0.0;
  count = 0;
  for (int by = 0; by + 4 <= h; by += 4) {
    for (int bx = 0; bx + 4 <= w; bx += 4) {
      glm::dvec3 m(0.0), r(0.0);
      bool all_inside = true;
      for (int y = by; y < by + 4; ++y) {
        for (int x = bx; x < bx + 4; ++x) {
          const std::size_t t = static_cast<std::size_t>(y) * w + x;
          all_inside = all_inside && inside[t];
          m += decoded(map, t);
          r += decoded(reference, t);
        }
      }
      if (!all_inside) continue;
      sum += angle_degrees(m, r);
      ++count;
    }
  }
  b.mean_4x4_degrees = sum / static_cast<double>(count);
  return b;
}

TEST(Dither, BreaksTheBandsOfTheSphereAndKeepsTheMean) {
  test::TempDir dir;
  scenes::SphereParams params;  // the sphere scene of the accuracy lab, high mesh at 96 cells a face
  params.high_cells = 96;
  const scenes::ScenePair pair = scenes::make_displaced_sphere(params);
  ASSERT_TRUE(save_mesh(dir.file("low.obj"), pair.low).is_ok());
  ASSERT_TRUE(save_mesh(dir.file("high.ply"), pair.high).is_ok());
  BakeOptions o;
  o.low_path = dir.file("low.obj");
  o.high_paths = {dir.file("high.ply")};
  o.width = o.height = 512;
  o.padding = 0;  // background stays background: runs are counted inside the charts
  o.outputs = {{dir.file("float.exr"), PixelFormat::exr_float},
               {dir.file("dithered.png"), PixelFormat::png8},
               {dir.file("dithered.tga"), PixelFormat::tga8}};
  BakeReport report;
  ASSERT_TRUE(bake(o, report).is_ok());
  Image reference, dithered, dithered_tga;
  ASSERT_TRUE(read_image(dir.file("float.exr"), reference).is_ok());
  ASSERT_TRUE(read_image(dir.file("dithered.png"), dithered).is_ok());
  ASSERT_TRUE(read_image(dir.file("dithered.tga"), dithered_tga).is_ok());
  EXPECT_EQ(dithered.pixels, dithered_tga.pixels);  // one pattern for both 8-bit formats
  // The rounded map: the same float texels through the writer without dither.
  ASSERT_TRUE(write_image(reference, dir.file("rounded.png"), PixelFormat::png8).is_ok());
  Image rounded;
  ASSERT_TRUE(read_image(dir.file("rounded.png"), rounded).is_ok());
  // With --dither off the bake writes exactly that.
  o.dither = false;
  o.outputs = {{dir.file("off.png"), PixelFormat::png8}};
  ASSERT_TRUE(bake(o, report).is_ok());
  Image off;
  ASSERT_TRUE(read_image(dir.file("off.png"), off).is_ok());
  EXPECT_EQ(off.pixels, rounded.pixels);

  std::vector<bool> inside(static_cast<std::size_t>(o.width) * o.height);
  for (std::size_t t = 0; t < inside.size(); ++t) {
    const float* p = &reference.pixels[3 * t];
    inside[t] = !(p[0] == 0.5f && p[1] == 0.5f && p[2] == 1.0f);
  }
  const Banding d = measure(reference, dithered, inside);
  const Banding r = measure(reference, rounded, inside);
  for (const auto& [name, m] : {std::pair{"rounded", r}, std::pair{"dithered", d}}) {
    std::cout << "[ figures ] sphere 512^2 png8, " << name << ": runs (red, green, along rows) longest "
              << m.longest_run << ", mean " << m.mean_run << " texels, " << 100.0 * m.share_long
              << "% of texels in runs >= 16; error " << m.mean_degrees << " deg a texel, "
              << m.mean_4x4_degrees << " deg over 4x4 blocks\n";
  }
  // Bands: rounding leaves long flat runs on the smooth sphere; the pattern
  // changes a value within a few texels wherever the float map is not within
  // 1/128 of a step (there the 8-bit value is exact, and stays).
  EXPECT_LT(d.mean_run, 0.25 * r.mean_run);
  EXPECT_LT(d.share_long, 0.25 * r.share_long);
  EXPECT_LT(d.longest_run, r.longest_run);
  // One texel is off by up to a step instead of half a step, but any 4 x 4
  // block averages back to the float map better than rounding does.
  EXPECT_LT(d.mean_4x4_degrees, 0.5 * r.mean_4x4_degrees);
  EXPECT_LT(d.mean_degrees, 2.0 * r.mean_degrees);
}

std::string read_bytes(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  return {std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>()};
}

// A preset bake with a per-sample decode and dithered 8-bit maps: the same
// bytes with one thread or all, and from two tiles merged (the tile carries
// the dither flag).
TEST(Dither, PresetBakeSameBytesWithOneThreadOrAllAndFromTiles) {
  test::TempDir dir;
  scenes::SphereParams params;
  params.low_cells = 3;
  params.high_cells = 32;
  const scenes::ScenePair pair = scenes::make_displaced_sphere(params);
  ASSERT_TRUE(save_mesh(dir.file("low.obj"), pair.low).is_ok());
  ASSERT_TRUE(save_mesh(dir.file("high.ply"), pair.high).is_ok());
  BakeOptions o;
  o.low_path = dir.file("low.obj");
  o.high_paths = {dir.file("high.ply")};
  o.width = 160;
  o.height = 96;
  o.preset = "godot";
  o.encode.decode = {Bitangent::vertex, true, true};
  o.outputs = {{dir.file("all.png"), PixelFormat::png8}, {dir.file("all.tga"), PixelFormat::tga8}};
  BakeReport report;
  ASSERT_TRUE(bake(o, report).is_ok());
  BakeOptions one = o;
  one.outputs = {{dir.file("one.png"), PixelFormat::png8}, {dir.file("one.tga"), PixelFormat::tga8}};
  {
    tbb::global_control limit(tbb::global_control::max_allowed_parallelism, 1);
    ASSERT_TRUE(bake(one, report).is_ok());
  }
  EXPECT_EQ(read_bytes(dir.file("one.png")), read_bytes(dir.file("all.png")));
  EXPECT_EQ(read_bytes(dir.file("one.tga")), read_bytes(dir.file("all.tga")));
  std::vector<std::string> tiles;
  for (int i = 0; i < 2; ++i) {
    BakeOptions tile = o;
    tile.tile_index = i;
    tile.tile_count = 2;
    tile.tile_path = dir.file(std::to_string(i) + ".tile");
    ASSERT_TRUE(bake(tile, report).is_ok());
    tiles.push_back(tile.tile_path);
  }
  MergeReport merged;
  ASSERT_TRUE(merge_tiles(tiles, {{dir.file("m.png"), PixelFormat::png8}}, merged).is_ok());
  EXPECT_EQ(read_bytes(dir.file("m.png")), read_bytes(dir.file("all.png")));
  // A tile of the same bake without dither is another bake.
  BakeOptions off = o;
  off.dither = false;
  off.tile_index = 1;
  off.tile_count = 2;
  off.tile_path = dir.file("off.tile");
  ASSERT_TRUE(bake(off, report).is_ok());
  const Status mixed =
      merge_tiles({tiles[0], off.tile_path}, {{dir.file("x.png"), PixelFormat::png8}}, merged);
  EXPECT_FALSE(mixed.is_ok());
}

}  // namespace
}  // namespace nmbake
