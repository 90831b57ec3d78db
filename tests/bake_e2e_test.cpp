// End-to-end bakes of analytic scenes, scored against the true normal, plus
// determinism and the bad-input contract of the CLI.
#include <gtest/gtest.h>
#include <tbb/global_control.h>

#include <algorithm>
#include <cmath>
#include <fstream>
#include <glm/geometric.hpp>
#include <iterator>

#include "lab_scenes.hpp"
#include "nmbake/bake.hpp"
#include "scenes.hpp"
#include "score.hpp"
#include "test_util.hpp"

namespace nmbake {
namespace {

std::size_t count_non_finite(const Image& image) {
  return static_cast<std::size_t>(
      std::count_if(image.pixels.begin(), image.pixels.end(), [](float v) { return !std::isfinite(v); }));
}

std::string read_bytes(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  return std::string(std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>());
}

// Writes the scene's meshes to `dir` (low.obj, high.ply) and returns the
// options of a size x size, 4-sample bake of them, outputs still to set.
BakeOptions save_scene(const test::TempDir& dir, const scenes::ScenePair& scene, int size) {
  EXPECT_TRUE(save_mesh(dir.file("low.obj"), scene.low).is_ok());
  EXPECT_TRUE(save_mesh(dir.file("high.ply"), scene.high).is_ok());
  BakeOptions o;
  o.low_path = dir.file("low.obj");
  o.high_paths = {dir.file("high.ply")};
  o.width = o.height = size;
  o.samples = 4;
  return o;
}

// Heightfield over a plane: flat low grid, so the tangent frame is the
// identity and the map must hold normalize(-dh/dx, -dh/dy, 1) directly.
TEST(EndToEnd, HeightfieldMatchesAnalyticNormals) {
  test::TempDir dir;
  scenes::HeightfieldParams params;
  params.high_cells = 384;
  BakeOptions o = save_scene(dir, scenes::make_heightfield(params), 256);
  o.outputs = {{dir.file("map.exr"), PixelFormat::exr_float}};
  BakeReport report;
  const Status s = bake(o, report);
  ASSERT_TRUE(s.is_ok()) << s.message();
  EXPECT_EQ(report.trace.misses, 0u);
  EXPECT_DOUBLE_EQ(report.coverage(), 1.0);

  Image map;
  ASSERT_TRUE(read_image(dir.file("map.exr"), map).is_ok());
  const scenes::AngularError e = scenes::score_heightfield(params, map, o.samples);
  std::printf("heightfield 256^2 x4: %s\n", e.to_text().c_str());
  EXPECT_EQ(e.texels, 256u * 256u);
  EXPECT_EQ(e.non_finite, 0u);
  EXPECT_LT(e.mean, 0.1);
  EXPECT_LT(e.p99, 1.0);
}

// Displaced sphere: a curved low mesh, so this checks the MikkTSpace frame,
// the exact-inverse encode and the averaged cage together. The truth: the
// analytic surface intersected along the bake's own ray, its analytic normal
// expressed through the same frame.
TEST(EndToEnd, DisplacedSphereMatchesAnalyticNormals) {
  test::TempDir dir;
  scenes::SphereParams params;
  params.high_cells = 192;
  BakeOptions o = save_scene(dir, scenes::make_displaced_sphere(params), 256);
  o.outputs = {{dir.file("map.exr"), PixelFormat::exr_float}};
  o.padding = 0;
  BakeReport report;
  const Status s = bake(o, report);
  ASSERT_TRUE(s.is_ok()) << s.message();
  EXPECT_EQ(report.trace.misses, 0u);

  Mesh low;
  LoadStats load_stats;
  ASSERT_TRUE(load_mesh(dir.file("low.obj"), LoadOptions{}, low, load_stats).is_ok());
  MeshStats mesh_stats;
  prepare_low_normals(low, mesh_stats);
  Image map;
  ASSERT_TRUE(read_image(dir.file("map.exr"), map).is_ok());
  const scenes::AngularError e = scenes::score_sphere(params, low, map, o.samples, report.front, report.back);
  std::printf("displaced sphere 256^2 x4: %s\n", e.to_text().c_str());
  EXPECT_GT(e.texels, 256u * 256u / 2u);
  EXPECT_EQ(e.non_finite, 0u);
  EXPECT_LT(e.mean, 0.1);
  EXPECT_LT(e.p99, 1.0);
}

// Bands of rows bound the memory; they must not show in the result.
TEST(EndToEnd, BandsDoNotChangeTheMap) {
  test::TempDir dir;
  scenes::SphereParams params;
  params.high_cells = 48;
  BakeOptions o =
      save_scene(dir, scenes::make_displaced_sphere(params), 200);  // not a multiple of the band height
  o.outputs = {{dir.file("one.exr"), PixelFormat::exr_float}};
  BakeReport one, many;
  ASSERT_TRUE(bake(o, one).is_ok());
  o.band_samples = 200 * 4 * 32;  // bands of 32 rows
  o.outputs = {{dir.file("many.exr"), PixelFormat::exr_float}};
  ASSERT_TRUE(bake(o, many).is_ok());
  EXPECT_EQ(read_bytes(dir.file("one.exr")), read_bytes(dir.file("many.exr")));
  EXPECT_EQ(one.trace.rays, many.trace.rays);
  EXPECT_EQ(one.raster.covered_texels, many.raster.covered_texels);
  EXPECT_EQ(one.raster.border_samples, many.raster.border_samples);
}

// The banded cage and the retry of misses are as deterministic as the rest:
// a hard-edged box with automatic distances (its corners miss, and are
// retried) bakes the same bytes with 1 and 2 threads and in bands of 32 rows.
TEST(EndToEnd, BandedCageAndRetriesGiveTheSameBytesForAnyThreadCountAndBand) {
  test::TempDir dir;
  scenes::BoxParams params;
  params.low_cells = 2;
  params.high_cells = 48;
  BakeOptions o = save_scene(dir, scenes::make_box(params), 160);
  BakeReport report[3];
  for (int run = 0; run < 3; ++run) {
    tbb::global_control limit(tbb::global_control::max_allowed_parallelism, run == 0 ? 1 : 2);
    o.band_samples = run == 2 ? 160 * 4 * 32 : 0;
    o.outputs = {{dir.file("map" + std::to_string(run) + ".exr"), PixelFormat::exr_float}};
    ASSERT_TRUE(bake(o, report[run]).is_ok());
  }
  EXPECT_EQ(report[0].cage_mode, "banded");
  EXPECT_GT(report[0].trace.retried, 0u);
  EXPECT_EQ(report[0].trace.misses, 0u);
  EXPECT_EQ(read_bytes(dir.file("map0.exr")), read_bytes(dir.file("map1.exr")));
  EXPECT_EQ(read_bytes(dir.file("map0.exr")), read_bytes(dir.file("map2.exr")));
  EXPECT_EQ(report[0].trace.retried, report[2].trace.retried);
}

// The compact BVH (indices only) finds the same surface as the fast one. Not
// bit for bit: Embree's two leaf layouts compute triangle edges in a different
// order, so a few texels differ in the last float bits.
TEST(EndToEnd, CompactBvhGivesTheSameMap) {
  test::TempDir dir;
  scenes::SphereParams params;
  params.high_cells = 48;
  BakeOptions o = save_scene(dir, scenes::make_displaced_sphere(params), 128);
  BakeReport fast, compact, automatic;
  o.bvh_memory = BvhMemory::fast;
  o.outputs = {{dir.file("fast.exr"), PixelFormat::exr_float}};
  ASSERT_TRUE(bake(o, fast).is_ok());
  o.bvh_memory = BvhMemory::compact;
  o.outputs = {{dir.file("compact.exr"), PixelFormat::exr_float}};
  ASSERT_TRUE(bake(o, compact).is_ok());
  o.bvh_memory = BvhMemory::automatic;
  o.outputs = {{dir.file("auto.exr"), PixelFormat::exr_float}};
  ASSERT_TRUE(bake(o, automatic).is_ok());
  EXPECT_FALSE(fast.compact_bvh);
  EXPECT_TRUE(compact.compact_bvh);
  EXPECT_FALSE(automatic.compact_bvh);  // far below kCompactBvhAbove
  Image a, c;
  ASSERT_TRUE(read_image(dir.file("fast.exr"), a).is_ok());
  ASSERT_TRUE(read_image(dir.file("compact.exr"), c).is_ok());
  ASSERT_EQ(a.pixels.size(), c.pixels.size());
  float worst = 0.0f;
  for (std::size_t i = 0; i < a.pixels.size(); ++i)
    worst = std::max(worst, std::fabs(a.pixels[i] - c.pixels[i]));
  EXPECT_LT(worst, 1e-4f);
  EXPECT_NEAR(static_cast<double>(fast.trace.hits), static_cast<double>(compact.trace.hits),
              1e-4 * static_cast<double>(fast.trace.rays));
}

class CliBake : public ::testing::Test {
 protected:
  void SetUp() override {
    scenes::HeightfieldParams params;
    params.high_cells = 64;
    const scenes::ScenePair scene = scenes::make_heightfield(params);
    ASSERT_TRUE(save_mesh(dir.file("low.obj"), scene.low).is_ok());
    ASSERT_TRUE(save_mesh(dir.file("high.obj"), scene.high).is_ok());
  }
  test::CommandResult bake(const std::string& args) {
    return test::run_command(test::cli_path() + " bake " + args);
  }
  std::string low() const { return dir.file("low.obj"); }
  std::string high() const { return dir.file("high.obj"); }
  test::TempDir dir;
};

TEST_F(CliBake, SameBytesWithOneAndTwoThreads) {
  const std::string common = " --low " + low() + " --high " + high() + " --size 128 --samples 4 -q";
  const auto a = bake(common + " --threads 1 -o " + dir.file("a.png") + " -o " + dir.file("a.exr"));
  const auto b = bake(common + " --threads 2 -o " + dir.file("b.png") + " -o " + dir.file("b.exr"));
  ASSERT_EQ(a.exit_code, 0) << a.output;
  ASSERT_EQ(b.exit_code, 0) << b.output;
  EXPECT_EQ(read_bytes(dir.file("a.png")), read_bytes(dir.file("b.png")));
  EXPECT_EQ(read_bytes(dir.file("a.exr")), read_bytes(dir.file("b.exr")));
  EXPECT_GT(read_bytes(dir.file("a.png")).size(), 1000u);
}

// OpenImageIO is a module loaded only for TIFF, PIZ EXR and reading: PNG
// and (ZIP) EXR bakes run without it, and a bake asking for TIFF or PIZ EXR
// without it fails before baking, naming the module and where it was looked for.
TEST_F(CliBake, PngAndExrNeedNoImageModuleAndTiffWithoutItFailsUpFront) {
  const std::string empty = dir.file("no_modules");
  std::filesystem::create_directory(empty);
  const std::string env = "NMBAKE_MODULE_DIR=" + empty + " ";
  const std::string common = " bake --low " + low() + " --high " + high() + " --size 32 --samples 1 -q -o ";
  for (const char* name : {"m.png", "m.exr"}) {
    const auto r = test::run_command(env + test::cli_path() + common + dir.file(name));
    EXPECT_EQ(r.exit_code, 0) << name << ": " << r.output;
    EXPECT_TRUE(std::filesystem::exists(dir.file(name))) << name;
  }
  const std::string tif = dir.file("m.tif"), piz = dir.file("piz.exr");
  for (const std::string& target : {tif, piz}) {
    const std::string output_args = target == piz ? piz + " --format exr-float-piz" : tif;
    const auto missing = test::run_command(env + test::cli_path() + common + output_args);
    EXPECT_EQ(missing.exit_code, 3) << missing.output;
    EXPECT_NE(missing.output.find("libnmbake_oiio.so"), std::string::npos) << missing.output;
    EXPECT_NE(missing.output.find(empty), std::string::npos) << missing.output;
    EXPECT_EQ(missing.output.find("baked"), std::string::npos) << missing.output;
    EXPECT_FALSE(std::filesystem::exists(target));
    // Found beside the executable when the variable is not set.
    const auto found = test::run_command(test::cli_path() + common + output_args);
    EXPECT_EQ(found.exit_code, 0) << found.output;
    EXPECT_TRUE(std::filesystem::exists(target));
  }
  ImageFileInfo info;
  ASSERT_TRUE(read_image_info(dir.file("piz.exr"), info).is_ok());
  EXPECT_EQ(info.compression, "piz");
  EXPECT_EQ(info.data_type, "float");
}

TEST_F(CliBake, PngAndExrAgreeTo16Bits) {
  const auto r = bake("--low " + low() + " --high " + high() + " --size 64 -q -o " + dir.file("m.png") +
                      " -o " + dir.file("m.exr") + " --report " + dir.file("r.json"));
  ASSERT_EQ(r.exit_code, 0) << r.output;
  Image png, exr;
  ASSERT_TRUE(read_image(dir.file("m.png"), png).is_ok());
  ASSERT_TRUE(read_image(dir.file("m.exr"), exr).is_ok());
  ASSERT_EQ(png.pixels.size(), exr.pixels.size());
  float worst = 0.0f;
  for (std::size_t i = 0; i < png.pixels.size(); ++i)
    worst = std::max(worst, std::fabs(png.pixels[i] - exr.pixels[i]));
  EXPECT_LE(worst, 0.5f / 65535.0f + 1e-7f);
  EXPECT_EQ(count_non_finite(exr), 0u);
  const std::string json = read_bytes(dir.file("r.json"));
  for (const char* key :
       {"\"misses\"", "\"rays\"", "\"seconds\"", "\"peak_rss_bytes\"", "\"tangent_fallbacks\""}) {
    EXPECT_NE(json.find(key), std::string::npos) << key;
  }
}

TEST_F(CliBake, JobFileBakesEveryEntry) {
  test::write_text(dir.file("job.toml"),
                   "[defaults]\nsize = 32\nsamples = 1\n"
                   "[[bake]]\nlow = \"low.obj\"\nhigh = \"high.obj\"\noutputs = [\"j1.png\"]\n"
                   "[[bake]]\nlow = \"low.obj\"\nhigh = \"high.obj\"\noutputs = [\"j2.exr\"]\n"
                   "space = \"object\"\nreport = \"j2.json\"\n");
  const auto r = bake(dir.file("job.toml"));
  ASSERT_EQ(r.exit_code, 0) << r.output;
  EXPECT_TRUE(std::filesystem::exists(dir.file("j1.png")));
  EXPECT_TRUE(std::filesystem::exists(dir.file("j2.exr")));
  EXPECT_TRUE(std::filesystem::exists(dir.file("j2.json")));
}

TEST_F(CliBake, EverythingMissedWarnsAndGateFails) {
  Mesh far;
  LoadStats ls;
  ASSERT_TRUE(load_mesh(high(), LoadOptions{}, far, ls).is_ok());
  for (glm::vec3& p : far.positions) p.z += 10.0f;
  ASSERT_TRUE(save_mesh(dir.file("far.obj"), far).is_ok());
  const auto r = bake("--low " + low() + " --high " + dir.file("far.obj") +
                      " --size 32 --front 0.1 --back 0.1 --max-miss-rate 0.5 -o " + dir.file("m.png"));
  EXPECT_EQ(r.exit_code, 1) << r.output;
  EXPECT_NE(r.output.find("every ray missed"), std::string::npos) << r.output;
  Image map;
  ASSERT_TRUE(read_image(dir.file("m.png"), map).is_ok());  // a flat map: every texel (0, 0, 1)
  EXPECT_NEAR(map.at(10, 10)[2], 1.0f, 1e-4f);
}

// Bad input: exit code 2, a message naming the file and the reason, no map.
TEST_F(CliBake, BadInputsExitTwoAndWriteNothing) {
  test::write_text(dir.file("truncated.obj"), "v 0 0 0\nv 1 0 0\nv 1 1 0\nvt 0 0\nf 1/1 2/");
  test::write_text(dir.file("range.obj"), "v 0 0 0\nv 1 0 0\nv 1 1 0\nvt 0 0\nf 1/1 2/1 7/1\n");
  test::write_text(dir.file("nan.obj"), "v 0 0 0\nv nan 0 0\nv 1 1 0\nvt 0 0\nf 1/1 2/1 3/1\n");
  test::write_text(dir.file("nouv.obj"), "v 0 0 0\nv 1 0 0\nv 1 1 0\nf 1 2 3\n");
  struct Case {
    std::string args, must_mention;
  };
  const std::string out = " -o " + dir.file("out.png");
  const std::vector<Case> cases = {
      {"--low " + dir.file("missing.obj") + " --high " + high() + out, "missing.obj"},
      {"--low " + dir.file("truncated.obj") + " --high " + high() + out, "truncated.obj"},
      {"--low " + dir.file("range.obj") + " --high " + high() + out, "range.obj"},
      {"--low " + dir.file("nan.obj") + " --high " + high() + out, "nan.obj"},
      {"--low " + low() + " --high " + dir.file("nan.obj") + out, "nan.obj"},
      {"--low " + low() + " --high " + high() + " --size 0" + out, "size"},
      {"--low " + low() + " --high " + high() + " --samples 3" + out, "samples"},
      {"--low " + low() + " --high " + high() + " --front -1" + out, "front"},
      {"--low " + low() + " --high " + high() + " -o " + dir.file("no/such/folder/m.png"), "folder"},
      {"--low " + low() + " --high " + high() + " -o " + dir.file("m.bmp"), "extension"},
      {"--low " + low() + " --high " + high() + " --cage " + dir.file("truncated.obj") + out,
       "truncated.obj"},
  };
  for (const Case& c : cases) {
    const auto r = bake(c.args);
    EXPECT_EQ(r.exit_code, 2) << c.args << "\n" << r.output;
    EXPECT_NE(r.output.find(c.must_mention), std::string::npos) << c.args << "\n" << r.output;
    EXPECT_FALSE(std::filesystem::exists(dir.file("out.png"))) << c.args;
  }
  for (const auto& entry : std::filesystem::directory_iterator(dir.path())) {
    EXPECT_EQ(entry.path().filename().string().find("tmp"), std::string::npos) << entry.path();
  }
  // A low mesh without UVs is no longer an error: it is unwrapped, and the
  // unwrapped mesh is written beside the map.
  const auto r = bake("--low " + dir.file("nouv.obj") + " --high " + high() + " --size 64 -o " +
                      dir.file("nouv_map.png"));
  EXPECT_EQ(r.exit_code, 0) << r.output;
  EXPECT_TRUE(std::filesystem::exists(dir.file("nouv_map.png")));
  Mesh unwrapped;
  LoadStats load_stats;
  ASSERT_TRUE(load_mesh(dir.file("nouv_map_low_uv.obj"), LoadOptions{}, unwrapped, load_stats).is_ok())
      << r.output;
  EXPECT_EQ(unwrapped.triangle_count(), 1u);
  EXPECT_TRUE(unwrapped.has_uvs());
}

TEST_F(CliBake, CageMeshWithOtherTopologyIsRejected) {
  test::write_text(dir.file("cage.obj"), "v 0 0 0\nv 1 0 0\nv 1 1 0\nf 1 2 3\n");
  const auto r = bake("--low " + low() + " --high " + high() + " --cage " + dir.file("cage.obj") + " -o " +
                      dir.file("m.png"));
  EXPECT_EQ(r.exit_code, 2) << r.output;
  EXPECT_NE(r.output.find("topology"), std::string::npos) << r.output;
}

}  // namespace
}  // namespace nmbake
