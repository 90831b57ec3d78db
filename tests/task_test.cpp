// Tasks, keys and tiles: bake keys, tiles that merge to the whole bake's
// bytes, the cache, and plans run through Ninja.
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <sstream>
#include <thread>

#include <gtest/gtest.h>

#include "nmbake/bake.hpp"
#include "nmbake/cache.hpp"
#include "nmbake/plan.hpp"
#include "nmbake/task.hpp"
#include "scenes.hpp"
#include "test_util.hpp"

namespace nmbake {
namespace {

namespace fs = std::filesystem;

std::string read_bytes(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  return std::string(std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>());
}

// A displaced sphere pair in `dir`, and the options of a small bake of it.
BakeOptions sphere_bake(const test::TempDir& dir, int width, int height) {
  scenes::SphereParams params;
  params.high_cells = 48;
  params.low_cells = 3;
  const scenes::ScenePair pair = scenes::make_displaced_sphere(params);
  EXPECT_TRUE(save_mesh(dir.file("low.obj"), pair.low).is_ok());
  EXPECT_TRUE(save_mesh(dir.file("high.ply"), pair.high).is_ok());
  BakeOptions o;
  o.low_path = dir.file("low.obj");
  o.high_path = dir.file("high.ply");
  o.width = width;
  o.height = height;
  o.samples = 4;
  return o;
}

TEST(TaskTiles, RowsAreWholeRasterTilesCoveringTheMapOnce) {
  for (const int height : {1, 31, 32, 33, 150, 1000}) {
    for (const int count : {1, 2, 3, 7, 16}) {
      int next = 0;
      for (int i = 0; i < count; ++i) {
        int b = 0, e = 0;
        tile_rows(height, i, count, b, e);
        EXPECT_EQ(b, next) << height << " " << count << " " << i;
        EXPECT_LE(b, e);
        EXPECT_TRUE(b % kRasterTileSize == 0 || b == height);
        next = e;
      }
      EXPECT_EQ(next, height);
    }
  }
  int index = 0, count = 0;
  EXPECT_TRUE(parse_tile_spec("3/7", index, count));
  EXPECT_EQ(index, 2);
  EXPECT_EQ(count, 7);
  for (const char* bad : {"0/3", "4/3", "3", "/3", "3/", "a/3", "1/0", "-1/3", "1/99999"}) {
    EXPECT_FALSE(parse_tile_spec(bad, index, count)) << bad;
  }
}

// N = 1, 2, 3, 7, 16 tiles of a 200 x 150 map (neither side a multiple of
// 32 or of N) with padding wider than a tile (40 > 32 rows): the merged PNG
// and EXR are the whole bake's bytes.
TEST(TaskTiles, MergedTilesGiveTheWholeBakesBytes) {
  test::TempDir dir;
  BakeOptions whole = sphere_bake(dir, 200, 150);
  whole.padding = 40;
  whole.outputs = {{dir.file("whole.png"), PixelFormat::png16}, {dir.file("whole.exr"), PixelFormat::exr_float}};
  BakeReport report;
  ASSERT_TRUE(bake(whole, report).is_ok());
  const std::string png = read_bytes(dir.file("whole.png"));
  const std::string exr = read_bytes(dir.file("whole.exr"));
  ASSERT_FALSE(png.empty());
  for (const int count : {1, 2, 3, 7, 16}) {
    std::vector<std::string> tiles;
    for (int i = count - 1; i >= 0; --i) {  // any order
      BakeOptions tile = whole;
      tile.tile_index = i;
      tile.tile_count = count;
      tile.tile_path = dir.file(std::to_string(i) + ".tile");
      const Status s = bake(tile, report);
      ASSERT_TRUE(s.is_ok()) << s.message();
      EXPECT_FALSE(fs::exists(dir.file("whole.png.tmp")));
      tiles.push_back(tile.tile_path);
    }
    MergeReport merged;
    const Status s = merge_tiles(
        tiles, {{dir.file("m.png"), PixelFormat::png16}, {dir.file("m.exr"), PixelFormat::exr_float}}, merged);
    ASSERT_TRUE(s.is_ok()) << s.message();
    EXPECT_EQ(read_bytes(dir.file("m.png")), png) << count << " tiles";
    EXPECT_EQ(read_bytes(dir.file("m.exr")), exr) << count << " tiles";
    // Without -o: the maps the bake named.
    fs::remove(dir.file("whole.png"));
    ASSERT_TRUE(merge_tiles(tiles, {}, merged).is_ok());
    EXPECT_EQ(read_bytes(dir.file("whole.png")), png);
  }
}

TEST(TaskTiles, MergeRefusesMixedMissingRepeatedAndDamagedTiles) {
  test::TempDir dir;
  BakeOptions o = sphere_bake(dir, 64, 96);
  o.outputs = {{dir.file("m.png"), PixelFormat::png16}};
  BakeReport report;
  const auto tile = [&](const BakeOptions& base, int i, int n, const std::string& name) {
    BakeOptions t = base;
    t.tile_index = i;
    t.tile_count = n;
    t.tile_path = dir.file(name);
    EXPECT_TRUE(bake(t, report).is_ok());
    return t.tile_path;
  };
  const std::string a0 = tile(o, 0, 2, "a0"), a1 = tile(o, 1, 2, "a1");
  BakeOptions other = o;
  other.samples = 1;  // another bake: another key
  const std::string b1 = tile(other, 1, 2, "b1");
  MergeReport merged;
  Status s = merge_tiles({a0, b1}, {}, merged);
  ASSERT_FALSE(s.is_ok());
  EXPECT_NE(s.message().find("a tile of another bake"), std::string::npos) << s.message();
  s = merge_tiles({a0}, {}, merged);
  ASSERT_FALSE(s.is_ok());
  EXPECT_NE(s.message().find("2 tiles"), std::string::npos) << s.message();
  s = merge_tiles({a0, a0}, {}, merged);
  ASSERT_FALSE(s.is_ok());
  EXPECT_NE(s.message().find("given twice"), std::string::npos) << s.message();
  // A torn file and a flipped byte.
  std::string bytes = read_bytes(a1);
  test::write_text(dir.file("torn"), bytes.substr(0, bytes.size() / 2));
  s = merge_tiles({a0, dir.file("torn")}, {}, merged);
  ASSERT_FALSE(s.is_ok());
  EXPECT_NE(s.message().find("torn: not a complete nmbake tile file"), std::string::npos) << s.message();
  bytes[bytes.size() / 2] ^= 0x40;
  test::write_text(dir.file("flipped"), bytes);
  s = merge_tiles({a0, dir.file("flipped")}, {}, merged);
  ASSERT_FALSE(s.is_ok());
  EXPECT_NE(s.message().find("checksum"), std::string::npos) << s.message();
  EXPECT_FALSE(fs::exists(dir.file("m.png")));
  ASSERT_TRUE(merge_tiles({a1, a0}, {}, merged).is_ok());
  EXPECT_TRUE(fs::exists(dir.file("m.png")));
}

TEST(TaskKey, CoversBytesAndOptionsNotPathsOrThreads) {
  test::TempDir dir;
  BakeOptions o = sphere_bake(dir, 64, 64);
  o.outputs = {{dir.file("m.png"), PixelFormat::png16}};
  BakeKey base, k;
  ASSERT_TRUE(bake_key(o, base).is_ok());
  EXPECT_EQ(base.hex().size(), 32u);
  // Same bytes elsewhere, other output path, other threads and bands: same key.
  fs::copy_file(dir.file("high.ply"), dir.file("copy.ply"));
  BakeOptions same = o;
  same.high_path = dir.file("copy.ply");
  same.outputs[0].path = dir.file("elsewhere.png");
  same.band_samples = 4096;
  ASSERT_TRUE(bake_key(same, k).is_ok());
  EXPECT_EQ(k, base);
  // One byte of a mesh, or any option: another key.
  std::string bytes = read_bytes(dir.file("copy.ply"));
  bytes[bytes.size() - 5] ^= 1;
  test::write_text(dir.file("copy.ply"), bytes);
  ASSERT_TRUE(bake_key(same, k).is_ok());
  EXPECT_FALSE(k == base);
  const std::vector<std::function<void(BakeOptions&)>> changes = {
      [](BakeOptions& x) { x.samples = 16; },
      [](BakeOptions& x) { x.width = 65; },
      [](BakeOptions& x) { x.green = GreenChannel::down; },
      [](BakeOptions& x) { x.front = {Distance::Kind::percent, 1.0f}; },
      [](BakeOptions& x) { x.padding = 3; },
      [](BakeOptions& x) { x.outputs[0].format = PixelFormat::png8; },
      [](BakeOptions& x) { x.match.groups.push_back({"g", {"a"}, {"b"}}); },
  };
  for (const auto& change : changes) {
    BakeOptions c = o;
    change(c);
    ASSERT_TRUE(bake_key(c, k).is_ok());
    EXPECT_FALSE(k == base) << bake_key_text(c);
  }
  BakeOptions missing = o;
  missing.low_path = dir.file("nope.obj");
  const Status s = bake_key(missing, k);
  ASSERT_FALSE(s.is_ok());
  EXPECT_NE(s.message().find("nope.obj"), std::string::npos);
}

// Through the CLI: the second bake of a key is copied from the cache, with
// the same bytes; two processes storing one key leave one whole entry.
TEST(TaskCache, SecondBakeIsCachedAndConcurrentStoresStayWhole) {
  test::TempDir dir;
  BakeOptions o = sphere_bake(dir, 96, 96);
  const std::string base = test::cli_path() + " bake --low " + o.low_path + " --high " + o.high_path +
                           " --size 96 --cache " + dir.file("cache");
  test::CommandResult r = test::run_command(base + " -o " + dir.file("a.png") + " --report " + dir.file("a.json"));
  ASSERT_EQ(r.exit_code, 0) << r.output;
  EXPECT_EQ(r.output.find("cached"), std::string::npos) << r.output;
  r = test::run_command(base + " -o " + dir.file("b.png") + " --report " + dir.file("b.json"));
  ASSERT_EQ(r.exit_code, 0) << r.output;
  EXPECT_NE(r.output.find("cached (key "), std::string::npos) << r.output;
  EXPECT_EQ(read_bytes(dir.file("a.png")), read_bytes(dir.file("b.png")));
  EXPECT_NE(read_bytes(dir.file("b.json")).find("\"cached\": true"), std::string::npos);
  // Another option: baked, not fetched.
  r = test::run_command(base + " --samples 1 -o " + dir.file("c.png"));
  EXPECT_EQ(r.output.find("cached"), std::string::npos) << r.output;

  // Four processes at once on a fresh cache folder.
  const std::string racing = test::cli_path() + " bake --low " + o.low_path + " --high " + o.high_path +
                             " --size 128 -q --cache " + dir.file("race");
  r = test::run_command("for i in 1 2 3 4; do " + racing + " -o " + dir.file("r$i.png") + " & done; wait");
  EXPECT_EQ(r.exit_code, 0) << r.output;
  int entries = 0;
  for (const auto& e : fs::directory_iterator(dir.file("race"))) {
    ++entries;
    EXPECT_EQ(e.path().filename().string().rfind(".tmp", 0), std::string::npos) << "a temporary entry was left";
    EXPECT_TRUE(fs::exists(e.path() / "manifest.json"));
    EXPECT_EQ(read_bytes((e.path() / "o0_1001.png").string()), read_bytes(dir.file("r1.png")));
  }
  EXPECT_EQ(entries, 1);
  for (const char* name : {"r2.png", "r3.png", "r4.png"}) EXPECT_EQ(read_bytes(dir.file(name)), read_bytes(dir.file("r1.png")));
}

// A plan of three bakes (one in tiles) run by Ninja: every map equals the
// one-machine bake; touching one mesh makes `ninja -n` list exactly the
// tasks that read it.
TEST(TaskPlan, NinjaRebakesOnlyWhatChanged) {
  if (test::run_command("command -v ninja >/dev/null 2>&1").exit_code != 0) {
    GTEST_SKIP() << "ninja is not installed (tools/setup installs ninja-build)";
  }
  test::TempDir dir;
  const BakeOptions a = sphere_bake(dir, 64, 64);
  test::TempDir other;
  scenes::HeightfieldParams hp;
  hp.high_cells = 64;
  const scenes::ScenePair field = scenes::make_heightfield(hp);
  ASSERT_TRUE(save_mesh(dir.file("field_low.obj"), field.low).is_ok());
  ASSERT_TRUE(save_mesh(dir.file("field_high.ply"), field.high).is_ok());
  test::write_text(dir.file("job.toml"),
                   "[defaults]\nsize = 64\n"
                   "[[bake]]\nname = \"sphere\"\nlow = \"low.obj\"\nhigh = \"high.ply\"\noutputs = [\"sphere.png\"]\n"
                   "[[bake]]\nname = \"field\"\nlow = \"field_low.obj\"\nhigh = \"field_high.ply\"\noutputs = [\"field.png\"]\n"
                   "report = \"field.json\"\n"
                   "[[bake]]\nname = \"big\"\nlow = \"low.obj\"\nhigh = \"high.ply\"\nsize = 100\npadding = 40\n"
                   "outputs = [\"big.png\", \"big.exr\"]\n");
  const std::string ninja = dir.file("plan.ninja");
  test::CommandResult r = test::run_command(test::cli_path() + " plan " + dir.file("job.toml") + " --tiles 3 --tiles-min-size 100 --ninja " +
                                            ninja + " --json " + dir.file("plan.json") + " 2>&1");
  ASSERT_EQ(r.exit_code, 0) << r.output;
  EXPECT_NE(r.output.find("6 tasks (2 bakes, 3 tiles, 1 merges)"), std::string::npos) << r.output;
  r = test::run_command("ninja -f " + ninja + " 2>&1");
  ASSERT_EQ(r.exit_code, 0) << r.output;
  r = test::run_command("ninja -f " + ninja + " -n 2>&1");
  EXPECT_NE(r.output.find("no work to do"), std::string::npos) << r.output;

  // The plan's maps are the one-machine bakes' bytes.
  r = test::run_command(test::cli_path() + " bake " + dir.file("job.toml") + " --only big -q 2>&1 && mv " +
                        dir.file("big.png") + " " + dir.file("big_whole.png") + " && mv " + dir.file("big.exr") + " " +
                        dir.file("big_whole.exr"));
  ASSERT_EQ(r.exit_code, 0) << r.output;
  r = test::run_command("ninja -f " + ninja + " 2>&1");  // the merge runs again: its outputs were moved away
  ASSERT_EQ(r.exit_code, 0) << r.output;
  EXPECT_EQ(read_bytes(dir.file("big.png")), read_bytes(dir.file("big_whole.png")));
  EXPECT_EQ(read_bytes(dir.file("big.exr")), read_bytes(dir.file("big_whole.exr")));

  // Touch the heightfield's high mesh: only the field bake is out of date.
  std::this_thread::sleep_for(std::chrono::milliseconds(20));
  r = test::run_command("touch " + dir.file("field_high.ply") + " && ninja -f " + ninja + " -n 2>&1");
  EXPECT_NE(r.output.find("bake field"), std::string::npos) << r.output;
  EXPECT_EQ(r.output.find("sphere"), std::string::npos) << r.output;
  EXPECT_EQ(r.output.find("big"), std::string::npos) << r.output;
  EXPECT_NE(r.output.find("[1/1]"), std::string::npos) << r.output;
  // Touch the sphere's low mesh: the sphere bake, the three tiles and the merge.
  r = test::run_command("ninja -f " + ninja + " >/dev/null && touch " + dir.file("low.obj") + " && ninja -f " + ninja +
                        " -n 2>&1");
  EXPECT_NE(r.output.find("[5/5]"), std::string::npos) << r.output;
  EXPECT_EQ(r.output.find("field"), std::string::npos) << r.output;
  EXPECT_NE(r.output.find("merge big"), std::string::npos) << r.output;

  const std::string json = read_bytes(dir.file("plan.json"));
  EXPECT_NE(json.find("\"dependencies\": [\n        \"tile:big:1\""), std::string::npos) << json.substr(0, 400);
  EXPECT_NE(json.find("\"key\""), std::string::npos);
}

TEST(TaskPlan, DuplicateNamesAreRefused) {
  test::TempDir dir;
  sphere_bake(dir, 32, 32);
  test::write_text(dir.file("job.toml"),
                   "[[bake]]\nname = \"x\"\nlow = \"low.obj\"\nhigh = \"high.ply\"\noutputs = [\"a.png\"]\n"
                   "[[bake]]\nname = \"x\"\nlow = \"low.obj\"\nhigh = \"high.ply\"\noutputs = [\"b.png\"]\n");
  const test::CommandResult r =
      test::run_command(test::cli_path() + " plan " + dir.file("job.toml") + " --json " + dir.file("p.json") + " 2>&1");
  EXPECT_EQ(r.exit_code, 2) << r.output;
  EXPECT_NE(r.output.find("two bakes are named 'x'"), std::string::npos) << r.output;
  EXPECT_FALSE(fs::exists(dir.file("p.json")));
}

TEST(TaskPlan, ShellCommandsQuoteWhatTheyMust) {
  EXPECT_EQ(shell_command({"/bin/nmbake", "bake", "a b.toml", "--only", "it's"}),
            "/bin/nmbake bake 'a b.toml' --only 'it'\\''s'");
}

}  // namespace
}  // namespace nmbake
