// `nmbake diff`: statistics on constructed maps with known angles, formats of
// different precision, masks, the green flip, the heat map and the exit codes.
#include "nmbake/diff.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <fstream>
#include <glm/geometric.hpp>
#include <glm/trigonometric.hpp>
#include <iterator>

#include "nmbake/bake.hpp"
#include "scenes.hpp"
#include "test_util.hpp"

namespace nmbake {
namespace {

constexpr int kSize = 64;

std::string read_bytes(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  return std::string(std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>());
}

glm::vec3 base_normal(int x, int y) {
  return glm::normalize(glm::vec3(0.5f * std::sin(0.11f * x), 0.4f * std::cos(0.13f * y + 0.3f), 1.0f));
}

// `n` turned by `degrees` about an axis perpendicular to it.
glm::vec3 rotated(const glm::vec3& n, float degrees) {
  const glm::vec3 k = glm::normalize(glm::cross(n, glm::vec3(0.6f, 0.8f, 0.0f)));
  const float a = glm::radians(degrees);
  return n * std::cos(a) + glm::cross(k, n) * std::sin(a);
}

// A map of base normals; texels where `turn(x, y)` turned by `degrees`.
template <class Turn>
Image make_map(float degrees, Turn turn, bool flip_green = false) {
  Image image;
  image.width = image.height = kSize;
  image.pixels.resize(static_cast<std::size_t>(kSize) * kSize * 3);
  for (int y = 0; y < kSize; ++y) {
    for (int x = 0; x < kSize; ++x) {
      glm::vec3 n = base_normal(x, y);
      if (turn(x, y)) n = rotated(n, degrees);
      if (flip_green) n.y = -n.y;
      float* p = image.at(x, y);
      for (int c = 0; c < 3; ++c) p[c] = 0.5f * n[c] + 0.5f;
    }
  }
  return image;
}

Image make_map(float degrees) {
  return make_map(degrees, [](int, int) { return true; });
}

TEST(Diff, QuantisationHelpers) {
  EXPECT_EQ(coarser(Quantisation::uint16, Quantisation::uint8), Quantisation::uint8);
  EXPECT_EQ(coarser(Quantisation::none, Quantisation::half), Quantisation::half);
  EXPECT_EQ(coarser(Quantisation::uint16, Quantisation::half), Quantisation::half);
  EXPECT_EQ(coarser(Quantisation::none, Quantisation::uint16), Quantisation::uint16);
  EXPECT_EQ(quantisation_of_data_type("uint8"), Quantisation::uint8);
  EXPECT_EQ(quantisation_of_data_type("half"), Quantisation::half);
  EXPECT_EQ(quantisation_of_data_type("float"), Quantisation::none);
  EXPECT_FLOAT_EQ(quantise(0.5f + 0.4f / 255.0f, Quantisation::uint8), 128.0f / 255.0f);
  // Half keeps 11 significant bits: steps of 2^-11 in [0.5, 1).
  EXPECT_FLOAT_EQ(quantise(0.75f + 0x1p-13f, Quantisation::half), 0.75f);
  EXPECT_FLOAT_EQ(quantise(0.75f + 0x1p-11f, Quantisation::half), 0.75f + 0x1p-11f);
}

TEST(Diff, ConstantRotationGivesItsAngle) {
  test::TempDir dir;
  const Image a = make_map(0.0f), b = make_map(2.0f);
  DiffStats exact;
  ASSERT_TRUE(diff_images(a, b, nullptr, DiffOptions{}, exact, nullptr).is_ok());
  EXPECT_NEAR(exact.mean, 2.0, 1e-4);
  EXPECT_NEAR(exact.max, 2.0, 1e-3);
  EXPECT_EQ(exact.compared_texels, static_cast<std::uint64_t>(kSize * kSize));
  EXPECT_EQ(exact.over_one_degree, exact.compared_texels);
  EXPECT_EQ(exact.changed_texels, exact.compared_texels);

  // Through 16- and 8-bit files: the angle survives within the quantisation.
  ASSERT_TRUE(write_image(a, dir.file("a16.png"), PixelFormat::png16).is_ok());
  ASSERT_TRUE(write_image(b, dir.file("b16.png"), PixelFormat::png16).is_ok());
  ASSERT_TRUE(write_image(b, dir.file("b8.png"), PixelFormat::png8).is_ok());
  DiffStats s16, s8;
  ASSERT_TRUE(diff_files(dir.file("a16.png"), dir.file("b16.png"), "", DiffOptions{}, s16, nullptr).is_ok());
  std::printf("2 deg, png16: %s\n", s16.summary_line().c_str());
  EXPECT_NEAR(s16.mean, 2.0, 0.002);
  EXPECT_NEAR(s16.p99, 2.0, 0.005);
  EXPECT_NEAR(s16.max, 2.0, 0.01);
  EXPECT_EQ(s16.quantisation, Quantisation::uint16);
  ASSERT_TRUE(diff_files(dir.file("a16.png"), dir.file("b8.png"), "", DiffOptions{}, s8, nullptr).is_ok());
  std::printf("2 deg, png16 vs png8: %s\n", s8.summary_line().c_str());
  EXPECT_EQ(s8.quantisation, Quantisation::uint8);
  EXPECT_NEAR(s8.mean, 2.0, 0.05);
  EXPECT_NEAR(s8.max, 2.0, 0.5);
}

TEST(Diff, IdenticalMapsAreUnchanged) {
  const Image a = make_map(0.0f);
  DiffStats s;
  ASSERT_TRUE(diff_images(a, a, nullptr, DiffOptions{}, s, nullptr).is_ok());
  EXPECT_EQ(s.max, 0.0);
  EXPECT_EQ(s.changed_texels, 0u);
  EXPECT_EQ(s.over_one_degree, 0u);
}

TEST(Diff, PngAndExrOfOneBakeAgree) {
  test::TempDir dir;
  scenes::HeightfieldParams params;
  params.high_cells = 96;
  const scenes::ScenePair scene = scenes::make_heightfield(params);
  ASSERT_TRUE(save_mesh(dir.file("low.obj"), scene.low).is_ok());
  ASSERT_TRUE(save_mesh(dir.file("high.ply"), scene.high).is_ok());
  BakeOptions o;
  o.low_path = dir.file("low.obj");
  o.high_paths = {dir.file("high.ply")};
  o.outputs = {{dir.file("map.png"), PixelFormat::png16},
               {dir.file("map.exr"), PixelFormat::exr_float},
               {dir.file("map_half.exr"), PixelFormat::exr_half},
               {dir.file("map8.png"), PixelFormat::png8}};
  o.width = o.height = 64;
  o.samples = 1;
  o.dither = false;  // the 8-bit map rounded, so "changed" counts only rounding boundaries
  BakeReport report;
  ASSERT_TRUE(bake(o, report).is_ok());

  DiffStats s;
  ASSERT_TRUE(diff_files(dir.file("map.exr"), dir.file("map.png"), "", DiffOptions{}, s, nullptr).is_ok());
  std::printf("exr vs png16: %s\n", s.summary_line().c_str());
  EXPECT_LT(s.max, 0.01);
  EXPECT_EQ(s.changed_texels, 0u);  // the float map rounded to 16 bits is the PNG
  ASSERT_TRUE(
      diff_files(dir.file("map.png"), dir.file("map_half.exr"), "", DiffOptions{}, s, nullptr).is_ok());
  std::printf("png16 vs exr-half: %s\n", s.summary_line().c_str());
  EXPECT_LT(s.max, 0.1);
  EXPECT_EQ(s.quantisation, Quantisation::half);
  ASSERT_TRUE(diff_files(dir.file("map.png"), dir.file("map8.png"), "", DiffOptions{}, s, nullptr).is_ok());
  std::printf("png16 vs png8: %s\n", s.summary_line().c_str());
  EXPECT_LT(s.max, 0.6);
  EXPECT_EQ(s.quantisation, Quantisation::uint8);
  EXPECT_LT(s.share_changed(), 0.01);  // only texels near an 8-bit rounding boundary
}

TEST(Diff, MaskSelectsTexels) {
  const Image a = make_map(0.0f);
  const Image b = make_map(3.0f, [](int x, int) { return x < kSize / 2; });
  Image mask;
  mask.width = mask.height = kSize;
  mask.channels = 1;
  mask.pixels.resize(static_cast<std::size_t>(kSize) * kSize);
  for (int y = 0; y < kSize; ++y) {
    for (int x = 0; x < kSize; ++x) mask.at(x, y)[0] = x >= kSize / 2 ? 1.0f : 0.0f;
  }
  DiffStats all, right, left;
  ASSERT_TRUE(diff_images(a, b, nullptr, DiffOptions{}, all, nullptr).is_ok());
  EXPECT_NEAR(all.mean, 1.5, 1e-3);
  EXPECT_NEAR(all.median, 0.0, 1e-6);  // nearest rank: half the texels are 0
  EXPECT_NEAR(all.p95, 3.0, 1e-3);
  ASSERT_TRUE(diff_images(a, b, &mask, DiffOptions{}, right, nullptr).is_ok());
  EXPECT_EQ(right.compared_texels, static_cast<std::uint64_t>(kSize * kSize / 2));
  EXPECT_EQ(right.max, 0.0);
  for (float& v : mask.pixels) v = 1.0f - v;
  ASSERT_TRUE(diff_images(a, b, &mask, DiffOptions{}, left, nullptr).is_ok());
  EXPECT_NEAR(left.mean, 3.0, 1e-3);
  EXPECT_NEAR(left.median, 3.0, 1e-3);
  mask.width = kSize / 2;
  EXPECT_EQ(diff_images(a, b, &mask, DiffOptions{}, left, nullptr).code(), StatusCode::bad_input);
}

TEST(Diff, GreenFlipOfTheSecondMap) {
  const Image a = make_map(0.0f);
  const Image b = make_map(
      0.0f, [](int, int) { return false; }, true);
  DiffStats s;
  ASSERT_TRUE(diff_images(a, b, nullptr, DiffOptions{}, s, nullptr).is_ok());
  EXPECT_GT(s.mean, 10.0);
  DiffOptions flip;
  flip.green_b = GreenChannel::down;
  ASSERT_TRUE(diff_images(a, b, nullptr, flip, s, nullptr).is_ok());
  EXPECT_LT(s.max, 1e-3);
  // In 16-bit files 1 - g is exact, so nothing changed at all.
  test::TempDir dir;
  ASSERT_TRUE(write_image(a, dir.file("gl.png"), PixelFormat::png16).is_ok());
  Image dx;
  ASSERT_TRUE(read_image(dir.file("gl.png"), dx).is_ok());
  for (std::size_t i = 1; i < dx.pixels.size(); i += 3) dx.pixels[i] = 1.0f - dx.pixels[i];
  ASSERT_TRUE(write_image(dx, dir.file("dx.png"), PixelFormat::png16).is_ok());
  ASSERT_TRUE(diff_files(dir.file("gl.png"), dir.file("dx.png"), "", flip, s, nullptr).is_ok());
  EXPECT_LT(s.max, 0.01);
  EXPECT_EQ(s.changed_texels, 0u);
}

TEST(Diff, DegenerateTexelsHaveDefinedAngles) {
  Image a = make_map(0.0f), b = a;
  for (int c = 0; c < 3; ++c) a.at(0, 0)[c] = b.at(0, 0)[c] = 0.5f;  // both without direction: 0
  for (int c = 0; c < 3; ++c) b.at(1, 0)[c] = 0.5f;                  // one lost: 90
  DiffStats s;
  ASSERT_TRUE(diff_images(a, b, nullptr, DiffOptions{}, s, nullptr).is_ok());
  EXPECT_EQ(s.degenerate_texels, 2u);
  EXPECT_DOUBLE_EQ(s.max, 90.0);
  EXPECT_TRUE(std::isfinite(s.mean));
}

TEST(Diff, HeatMapRamp) {
  const Image a = make_map(0.0f);
  const Image b = make_map(10.0f, [](int x, int) { return x >= kSize / 2; });
  DiffOptions options;
  options.heatmap_max_degrees = 5.0f;
  DiffStats s;
  Image heat;
  ASSERT_TRUE(diff_images(a, b, nullptr, options, s, &heat).is_ok());
  ASSERT_EQ(heat.width, kSize);
  ASSERT_EQ(heat.channels, 3);
  EXPECT_FLOAT_EQ(heat.at(0, 0)[0], 0.0f);  // 0 deg: black
  EXPECT_FLOAT_EQ(heat.at(0, 0)[2], 0.0f);
  EXPECT_FLOAT_EQ(heat.at(kSize - 1, 0)[0], 1.0f);  // over the top: red
  EXPECT_FLOAT_EQ(heat.at(kSize - 1, 0)[1], 0.0f);
  EXPECT_FLOAT_EQ(heat.at(kSize - 1, 0)[2], 0.0f);
}

// The CLI: one-line summary, JSON, heat map bytes, exit codes 0 / 1 / 2.
TEST(Diff, CommandExitCodes) {
  test::TempDir dir;
  ASSERT_TRUE(write_image(make_map(0.0f), dir.file("a.png"), PixelFormat::png16).is_ok());
  ASSERT_TRUE(write_image(make_map(2.0f), dir.file("b.exr"), PixelFormat::exr_float).is_ok());
  Image small = make_map(0.0f);
  small.width = small.height = kSize / 2;
  small.pixels.resize(static_cast<std::size_t>(kSize / 2) * (kSize / 2) * 3);
  ASSERT_TRUE(write_image(small, dir.file("small.png"), PixelFormat::png16).is_ok());
  const std::string cli = test::cli_path() + " diff " + dir.file("a.png") + " " + dir.file("b.exr");

  test::CommandResult r = test::run_command(cli + " --max-mean 2.1 --max-p99 2.1 --json " +
                                            dir.file("d.json") + " --heatmap " + dir.file("heat.png"));
  EXPECT_EQ(r.exit_code, 0) << r.output;
  EXPECT_NE(r.output.find("mean 2.00"), std::string::npos) << r.output;
  EXPECT_NE(read_bytes(dir.file("d.json")).find("\"mean_deg\""), std::string::npos);
  const std::string heat_bytes = read_bytes(dir.file("heat.png"));
  ASSERT_FALSE(heat_bytes.empty());
  r = test::run_command(cli + " --heatmap " + dir.file("heat.png"));
  EXPECT_EQ(r.exit_code, 0) << r.output;
  EXPECT_EQ(read_bytes(dir.file("heat.png")), heat_bytes);

  r = test::run_command(cli + " --max-mean 1.9");
  EXPECT_EQ(r.exit_code, 1) << r.output;
  EXPECT_NE(r.output.find("mean"), std::string::npos) << r.output;
  r = test::run_command(cli + " --max-p99 1.5");
  EXPECT_EQ(r.exit_code, 1) << r.output;
  EXPECT_NE(r.output.find("--max-p99"), std::string::npos) << r.output;
  r = test::run_command(cli + " --max-max 2.5 --max-mean 3");
  EXPECT_EQ(r.exit_code, 0) << r.output;

  r = test::run_command(test::cli_path() + " diff " + dir.file("a.png") + " " + dir.file("small.png"));
  EXPECT_EQ(r.exit_code, 2) << r.output;
  EXPECT_NE(r.output.find("sizes differ"), std::string::npos) << r.output;
  r = test::run_command(test::cli_path() + " diff " + dir.file("a.png") + " " + dir.file("missing.png"));
  EXPECT_EQ(r.exit_code, 2) << r.output;
  EXPECT_NE(r.output.find("missing.png"), std::string::npos) << r.output;
  r = test::run_command(cli + " --mask " + dir.file("small.png"));
  EXPECT_EQ(r.exit_code, 2) << r.output;
  EXPECT_NE(r.output.find("mask"), std::string::npos) << r.output;
}

}  // namespace
}  // namespace nmbake
