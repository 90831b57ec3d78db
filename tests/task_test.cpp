// Tasks, keys and tiles: bake keys, tiles that merge to the whole bake's
// bytes, the cache, and plans run through Ninja.
#include <gtest/gtest.h>
#include <sys/stat.h>
#include <tbb/global_control.h>

#include <cmath>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <functional>
#include <iterator>
#include <sstream>
#include <thread>
// The tests write tile files with a hand-made checksum.
#define XXH_INLINE_ALL
#include <xxhash.h>

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
  o.high_paths = {dir.file("high.ply")};
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
  whole.outputs = {{dir.file("whole.png"), PixelFormat::png16},
                   {dir.file("whole.exr"), PixelFormat::exr_float}};
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
        tiles, {{dir.file("m.png"), PixelFormat::png16}, {dir.file("m.exr"), PixelFormat::exr_float}},
        merged);
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

// The maps of a map set that cost little to trace (every map but
// vertex-color, which needs a coloured mesh), with few AO and thickness rays.
BakeOptions map_set_bake(const test::TempDir& dir, int width, int height) {
  BakeOptions o = sphere_bake(dir, width, height);
  o.maps = {MapKind::normal,    MapKind::height,   MapKind::ao,   MapKind::bent_normal,   MapKind::curvature,
            MapKind::thickness, MapKind::position, MapKind::miss, MapKind::object_normal, MapKind::id};
  o.ao_rays = 8;
  o.thickness_rays = 4;
  return o;
}

// Every file of a map set in every format: each map's own .png depth, PNG 8
// (dithered) and 16 given, TIFF 16 and float EXR.
std::vector<OutputSpec> map_set_outputs(const test::TempDir& dir, const std::string& prefix) {
  return {{dir.file(prefix + "_<MAP>.png"), PixelFormat::png16, false},
          {dir.file(prefix + "8_<MAP>.png"), PixelFormat::png8, true},
          {dir.file(prefix + "16_<MAP>.png"), PixelFormat::png16, true},
          {dir.file(prefix + "_<MAP>.tif"), PixelFormat::tiff16, true},
          {dir.file(prefix + "_<MAP>.exr"), PixelFormat::exr_float, false}};
}

// A map set in 3 tiles of rows (a 200 x 150 map, padding wider than a tile)
// merged: every map's file in every format has the whole bake's bytes (auto
// height and curvature ranges from the whole map, not a tile's), and the
// merge reports each map's figures as the whole bake does. Tiles baked with
// one thread, merged with one and with two.
TEST(TaskTiles, MapSetMergedTilesGiveTheWholeBakesBytes) {
  test::TempDir dir;
  BakeOptions whole = map_set_bake(dir, 200, 150);
  whole.padding = 40;
  whole.outputs = map_set_outputs(dir, "w");
  BakeReport report;
  const Status baked = bake(whole, report);
  ASSERT_TRUE(baked.is_ok()) << baked.message();
  const std::vector<MapReport> whole_maps = report.map_reports;
  ASSERT_EQ(whole_maps.size(), whole.maps.size());
  std::vector<std::string> tiles;
  {
    const tbb::global_control one(tbb::global_control::max_allowed_parallelism, 1);
    for (const int i : {2, 0, 1}) {
      BakeOptions tile = whole;
      tile.tile_index = i;
      tile.tile_count = 3;
      tile.tile_path = dir.file(std::to_string(i) + ".tile");
      const Status s = bake(tile, report);
      ASSERT_TRUE(s.is_ok()) << s.message();
      tiles.push_back(tile.tile_path);
    }
  }
  const std::vector<MapOutput> whole_files = map_outputs(whole);
  std::vector<std::string> whole_bytes;
  for (const MapOutput& out : whole_files) whole_bytes.push_back(read_bytes(out.path));
  for (const int threads : {1, 2}) {
    const tbb::global_control limit(tbb::global_control::max_allowed_parallelism, threads);
    const std::string prefix = std::string("m").append(std::to_string(threads));
    MergeReport merged;
    const Status s = merge_tiles(tiles, map_set_outputs(dir, prefix), merged);
    ASSERT_TRUE(s.is_ok()) << s.message();
    ASSERT_EQ(merged.outputs.size(), whole_files.size());
    for (std::size_t i = 0; i < whole_files.size(); ++i) {
      ASSERT_FALSE(whole_bytes[i].empty()) << whole_files[i].path;
      EXPECT_NE(merged.outputs[i], whole_files[i].path);
      EXPECT_TRUE(read_bytes(merged.outputs[i]) == whole_bytes[i])
          << merged.outputs[i] << " (" << threads << " threads)";
    }
    ASSERT_EQ(merged.maps.size(), whole_maps.size());
    for (std::size_t m = 0; m < whole_maps.size(); ++m) {
      EXPECT_EQ(merged.maps[m].map, whole_maps[m].map);
      // The id map's name count and source come from the bake's mesh, which
      // tiles do not carry (README: a merge reports no id names); every
      // counter is the whole bake's.
      auto whole_figures = whole_maps[m].figures;
      if (whole_maps[m].map == MapKind::id) {
        ASSERT_EQ(whole_maps[m].figure("ids"), 1.0);
        std::erase_if(whole_figures,
                      [](const auto& f) { return f.first == "ids" || f.first == "from_materials"; });
      }
      EXPECT_EQ(merged.maps[m].figures, whole_figures) << to_string(whole_maps[m].map);
    }
  }
  // The ranges came from the whole map, and the AO rays of every tile add up.
  EXPECT_GT(whole_maps[1].figure("range"), 0.0);
  EXPECT_GT(whole_maps[2].figure("rays"), 0.0);
  // Without -o: the files the bake named, <MAP> replaced.
  for (const MapOutput& out : whole_files) fs::remove(out.path);
  MergeReport merged;
  ASSERT_TRUE(merge_tiles(tiles, {}, merged).is_ok());
  for (std::size_t i = 0; i < whole_files.size(); ++i) {
    EXPECT_TRUE(read_bytes(whole_files[i].path) == whole_bytes[i]) << whole_files[i].path;
  }
  // Several maps need <MAP> in a path given to the merge.
  const Status s = merge_tiles(tiles, {{dir.file("one.png"), PixelFormat::png16}}, merged);
  ASSERT_FALSE(s.is_ok());
  EXPECT_NE(s.message().find("needs the <MAP> token"), std::string::npos) << s.message();
  EXPECT_FALSE(fs::exists(dir.file("one.png")));
}

// Tiles of two map sets are two bakes (the key holds the maps and their
// options); a tile whose map settings were altered under the same key is
// refused too; a tile file of the format before map sets says so.
TEST(TaskTiles, TilesOfAnotherMapSetOrFormatAreRefused) {
  test::TempDir dir;
  BakeOptions o = sphere_bake(dir, 64, 96);
  o.maps = {MapKind::normal, MapKind::height};
  o.outputs = {{dir.file("m_<MAP>.png"), PixelFormat::png16}};
  BakeReport report;
  const auto tile = [&](const BakeOptions& base, int i, const std::string& name) {
    BakeOptions t = base;
    t.tile_index = i;
    t.tile_count = 2;
    t.tile_path = dir.file(name);
    const Status s = bake(t, report);
    EXPECT_TRUE(s.is_ok()) << s.message();
    return t.tile_path;
  };
  const std::string a0 = tile(o, 0, "a0"), a1 = tile(o, 1, "a1");
  BakeOptions ao = o;
  ao.maps = {MapKind::normal, MapKind::ao};
  BakeOptions range = o;
  range.height_range = 0.5f;
  BakeOptions normal = o;
  normal.maps = {MapKind::normal};
  MergeReport merged;
  for (const BakeOptions* other : {&ao, &range, &normal}) {
    const Status s = merge_tiles({a0, tile(*other, 1, "b1")}, {}, merged);
    ASSERT_FALSE(s.is_ok());
    EXPECT_NE(s.message().find("b1: a tile of another bake (key"), std::string::npos) << s.message();
  }
  // The same key, other settings: refused by the settings themselves.
  TileData altered;
  ASSERT_TRUE(read_tile(a1, altered).is_ok());
  altered.maps.height_range = 2.0f;
  ASSERT_TRUE(write_tile(dir.file("altered"), altered).is_ok());
  Status s = merge_tiles({a0, dir.file("altered")}, {}, merged);
  ASSERT_FALSE(s.is_ok());
  EXPECT_NE(s.message().find(
                "altered: a tile of another bake (size, tile count, padding, dithering or maps differ)"),
            std::string::npos)
      << s.message();
  // Format 2 (before map sets) and an unknown one.
  std::string bytes = read_bytes(a1);
  bytes[7] = '2';
  test::write_text(dir.file("old"), bytes);
  s = merge_tiles({a0, dir.file("old")}, {}, merged);
  ASSERT_FALSE(s.is_ok());
  EXPECT_NE(s.message().find(
                "old: a tile file of format 2, written by an older nmbake; this nmbake reads format 3"),
            std::string::npos)
      << s.message();
  bytes[7] = '\x7f';
  test::write_text(dir.file("odd"), bytes);
  s = read_tile(dir.file("odd"), altered);
  ASSERT_FALSE(s.is_ok());
  EXPECT_NE(s.message().find("odd: a tile file of format \\x7f, written by another nmbake"),
            std::string::npos)
      << s.message();
  EXPECT_FALSE(fs::exists(dir.file("m_normal.png")));
  ASSERT_TRUE(merge_tiles({a1, a0}, {}, merged).is_ok());
  EXPECT_TRUE(fs::exists(dir.file("m_height.png")));
}

// Every field of the map set's part of a tile file is checked, with the
// checksum made right so that the field itself is what is refused: counts
// beyond the file, unknown or repeated maps, settings out of range, counters
// that are not whole numbers. Nothing is allocated for a count the file
// cannot hold.
TEST(TaskTiles, HostileMapSetFieldsAreRefused) {
  test::TempDir dir;
  TileData t;
  t.key = {1, 2};
  t.width = 4;
  t.height = 32;
  t.row_end = 32;
  t.outputs = {{dir.file("o_<MAP>.exr"), PixelFormat::exr_float, true}};
  t.maps.maps = {MapKind::normal, MapKind::height, MapKind::object_normal};
  t.maps.occlusion.rays = 8;
  t.maps.thickness.rays = 4;
  t.counts.maps = {{}, {}, {{"zero_results", 2.0}}};
  t.counts.occlusion.rays = 5;
  for (const int channels : {3, 1, 3})
    t.texels.emplace_back(static_cast<std::size_t>(4 * 32 * channels), 0.5f);
  t.coverage.assign(4 * 32, 1);
  ASSERT_TRUE(write_tile(dir.file("good"), t).is_ok());
  const std::string good = read_bytes(dir.file("good"));
  MergeReport merged;
  ASSERT_TRUE(merge_tiles({dir.file("good")}, {}, merged).is_ok());
  ASSERT_EQ(merged.maps.size(), 3u);
  EXPECT_EQ(merged.maps[2].figure("zero_results"), 2.0);
  EXPECT_TRUE(fs::exists(dir.file("o_object-normal.exr")));

  // Offsets of the fields (task.cpp, the tile file).
  const std::size_t map_count = 8 + 16 + 9 * 4;
  const std::size_t output = map_count + 4, path_length = output + 2;
  const std::size_t maps = path_length + 4 + t.outputs[0].path.size();
  const std::size_t settings = maps + 3;
  const std::size_t counters = settings + 48 + 13 * 8;
  const std::size_t third_counter = counters + 4 + 4 + 4 + 1 + std::string("zero_results").size();
  const auto patched = [&](std::size_t at, const void* value, std::size_t size, std::size_t cut = 0) {
    std::string bytes = good;
    std::memcpy(bytes.data() + at, value, size);
    bytes.resize(bytes.size() - 8 - cut);
    const std::uint64_t check = XXH3_64bits(bytes.data(), bytes.size());
    bytes.append(reinterpret_cast<const char*>(&check), sizeof check);
    test::write_text(dir.file("bad"), bytes);
    TileData read;
    const Status s = read_tile(dir.file("bad"), read);
    EXPECT_TRUE(s.code() == StatusCode::bad_input && s.message().rfind(dir.file("bad") + ": ", 0) == 0)
        << s.message();
    return s.message();
  };
  const auto i32 = [&](std::size_t at, std::int32_t v) { return patched(at, &v, sizeof v); };
  const auto u32 = [&](std::size_t at, std::uint32_t v) { return patched(at, &v, sizeof v); };
  const auto u8 = [&](std::size_t at, std::uint8_t v) { return patched(at, &v, sizeof v); };
  const auto f32 = [&](std::size_t at, float v) { return patched(at, &v, sizeof v); };
  const auto says = [](const std::string& message, const char* what) {
    return message.find(what) != std::string::npos;
  };
  EXPECT_TRUE(says(i32(map_count, 0), "header values out of range"));
  EXPECT_TRUE(says(i32(map_count, 200), "header values out of range"));
  EXPECT_TRUE(says(i32(map_count, 11), "bad map list"));  // reads the settings' bytes as maps
  EXPECT_TRUE(says(u8(output, 250), "bad output entry"));
  EXPECT_TRUE(says(u32(path_length, 0x7fffffff), "bad output entry"));
  EXPECT_TRUE(says(u32(path_length, 60000), "too short"));
  EXPECT_TRUE(says(u8(maps, 42), "bad map list"));
  EXPECT_TRUE(says(u8(maps + 1, 0), "bad map list"));  // normal twice
  EXPECT_TRUE(says(f32(settings, std::nanf("")), "map settings out of range"));
  EXPECT_TRUE(says(f32(settings + 4, -1.0f), "map settings out of range"));
  EXPECT_TRUE(says(i32(settings + 8, 0), "map settings out of range"));
  EXPECT_TRUE(says(f32(settings + 20, INFINITY), "map settings out of range"));
  EXPECT_TRUE(says(f32(settings + 24, INFINITY), "map settings out of range"));
  EXPECT_TRUE(says(u32(counters, 0xffffffffu), "too many counters"));
  EXPECT_TRUE(says(u32(counters, 40), "bad counter"));  // reads the next map's count as an empty name
  EXPECT_TRUE(says(u8(third_counter - 12, 'Z'), "bad counter"));
  const double half = 0.5, negative = -1.0;
  EXPECT_TRUE(says(patched(third_counter, &half, sizeof half), "bad counter"));
  EXPECT_TRUE(says(patched(third_counter, &negative, sizeof negative), "bad counter"));
  const std::uint8_t nothing = 0;
  EXPECT_TRUE(says(patched(0, &nothing, 0, 4), "bytes where the header says"));  // 4 bytes short
  // Texels a bake never writes: NaN, or too large for the normal map's dilation.
  const std::size_t texels = good.size() - 8 - 4 * 32 * (1 + 4 * 7);
  EXPECT_TRUE(says(f32(texels + 4 * 5, std::nanf("")), "texels of the normal map out of range"));
  EXPECT_TRUE(says(f32(texels + 4 * 5, 1e20f), "texels of the normal map out of range"));
  EXPECT_TRUE(says(f32(texels + 4 * 4 * 32 * 3, INFINITY), "texels of the height map out of range"));
  // The file itself is fine: its checksum is what a flipped field breaks.
  std::string flipped = good;
  flipped[settings] ^= 1;
  test::write_text(dir.file("flipped"), flipped);
  TileData read;
  EXPECT_TRUE(says(read_tile(dir.file("flipped"), read).message(), "checksum does not match"));
}

// Through the CLI: a map set baked in 3 tiles (`--tile I/3 --tile-file`)
// and `nmbake merge`d writes the whole bake's files; the merge report has
// each map's figures.
TEST(TaskTiles, MapSetTilesThroughTheCli) {
  test::TempDir dir;
  const BakeOptions o = sphere_bake(dir, 96, 96);
  const std::string base = test::cli_path() + " bake -q --low " + o.low_path + " --high " + o.high_paths[0] +
                           " --size 96 --map normal,height,ao,curvature --ao-rays 8 -o '" +
                           dir.file("w_<MAP>.png") + "' -o '" + dir.file("w_<MAP>.exr") + "'";
  test::CommandResult r = test::run_command(base + " 2>&1");
  ASSERT_EQ(r.exit_code, 0) << r.output;
  std::string tiles;
  for (int i = 1; i <= 3; ++i) {
    const std::string tile = dir.file(std::string("t").append(std::to_string(i)).append(".nmt"));
    r = test::run_command(base + " --tile " + std::to_string(i) + "/3 --tile-file " + tile + " 2>&1");
    ASSERT_EQ(r.exit_code, 0) << r.output;
    tiles = std::string(" ").append(tile).append(tiles);  // any order
  }
  r = test::run_command(test::cli_path() + " merge" + tiles + " -o '" + dir.file("m_<MAP>.png") + "' -o '" +
                        dir.file("m_<MAP>.exr") + "' --report " + dir.file("merge.json") + " 2>&1");
  ASSERT_EQ(r.exit_code, 0) << r.output;
  EXPECT_NE(r.output.find("m_curvature.exr"), std::string::npos) << r.output;
  for (const char* map : {"normal", "height", "ao", "curvature"}) {
    for (const char* ext : {".png", ".exr"}) {
      const std::string whole = read_bytes(dir.file(std::string("w_") + map + ext));
      EXPECT_FALSE(whole.empty());
      EXPECT_TRUE(whole == read_bytes(dir.file(std::string("m_") + map + ext))) << map << ext;
    }
  }
  const std::string json = read_bytes(dir.file("merge.json"));
  EXPECT_NE(json.find("\"map\": \"ao\""), std::string::npos) << json;
  EXPECT_NE(json.find("\"unoccluded_rays\""), std::string::npos) << json;
  // One path for four maps: exit 2, naming it, nothing written.
  r = test::run_command(test::cli_path() + " merge" + tiles + " -o " + dir.file("x.png") + " 2>&1");
  EXPECT_EQ(r.exit_code, 2) << r.output;
  EXPECT_NE(r.output.find("x.png: 4 maps are baked"), std::string::npos) << r.output;
  EXPECT_FALSE(fs::exists(dir.file("x.png")));
}

// `merge` reads regular files only: a FIFO is refused at once (it blocked
// for ever), naming it.
TEST(TaskTiles, MergeRefusesATileThatIsNotARegularFile) {
  test::TempDir dir;
  const std::string fifo = dir.file("tile.nmt");
  ASSERT_EQ(::mkfifo(fifo.c_str(), 0600), 0);
  // `timeout`: a merge that blocks fails the test instead of hanging it.
  const test::CommandResult r = test::run_command("timeout 60 " + test::cli_path() + " merge " + fifo +
                                                  " -o " + dir.file("m.png") + " 2>&1");
  EXPECT_EQ(r.exit_code, 2) << r.output;
  EXPECT_NE(r.output.find(fifo + ": the tile file is not a regular file"), std::string::npos) << r.output;
  EXPECT_FALSE(fs::exists(dir.file("m.png")));
}

// Without -o, a tile's own output paths are written only inside the
// current folder or the tile file's folder; the paths printed are escaped.
TEST(TaskTiles, MergeWritesTheTilesPathsOnlyInsideItsFolders) {
  test::TempDir dir;
  const BakeOptions o = sphere_bake(dir, 64, 64);
  fs::create_directories(dir.file("work"));
  fs::create_directories(dir.file("tiles"));
  fs::create_directories(dir.file("elsewhere"));
  const auto tile_of = [&](const std::string& output, const std::string& tile) {
    const test::CommandResult r = test::run_command(
        "cd " + dir.file("work") + " && " + test::cli_path() + " bake -q --low " + o.low_path + " --high " +
        o.high_paths[0] + " --size 64 --tile 1/1 --tile-file " + tile + " -o '" + output + "' 2>&1");
    EXPECT_EQ(r.exit_code, 0) << r.output;
  };
  const auto merge = [&](const std::string& tile, const std::string& flags = "") {
    return test::run_command("cd " + dir.file("work") + " && " + test::cli_path() + " merge " + tile + flags +
                             " 2>&1");
  };
  // Refused: an absolute path elsewhere, a `..` escape. Nothing written.
  const std::string far = dir.file("elsewhere/far.png");
  tile_of(far, dir.file("tiles/far.nmt"));
  test::CommandResult r = merge(dir.file("tiles/far.nmt"));
  EXPECT_EQ(r.exit_code, 2) << r.output;
  EXPECT_NE(r.output.find(dir.file("tiles/far.nmt") + ": the tile names the output '" + far),
            std::string::npos)
      << r.output;
  EXPECT_FALSE(fs::exists(far));
  // Fine when -o says where.
  r = merge(dir.file("tiles/far.nmt"), " -o " + dir.file("elsewhere/chosen.png"));
  EXPECT_EQ(r.exit_code, 0) << r.output;
  EXPECT_TRUE(fs::exists(dir.file("elsewhere/chosen.png")));
  tile_of("../up.png", dir.file("tiles/up.nmt"));
  r = merge(dir.file("tiles/up.nmt"));
  EXPECT_EQ(r.exit_code, 2) << r.output;
  EXPECT_NE(r.output.find("which leaves its folder through `..`"), std::string::npos) << r.output;
  EXPECT_FALSE(fs::exists(dir.file("up.png")));
  // Accepted: an absolute path beside the tile (a plan's layout), a
  // relative one under the current folder, printed with escapes.
  tile_of(dir.file("tiles/beside.png"), dir.file("tiles/beside.nmt"));
  r = merge(dir.file("tiles/beside.nmt"));
  EXPECT_EQ(r.exit_code, 0) << r.output;
  EXPECT_TRUE(fs::exists(dir.file("tiles/beside.png")));
  tile_of("sub\x1b[31m.png", dir.file("tiles/esc.nmt"));
  r = merge(dir.file("tiles/esc.nmt"));
  EXPECT_EQ(r.exit_code, 0) << r.output;
  EXPECT_TRUE(fs::exists(dir.file("work/sub\x1b[31m.png")));
  EXPECT_EQ(r.output.find('\x1b'), std::string::npos) << r.output;
  EXPECT_NE(r.output.find("sub\\x1b[31m.png"), std::string::npos) << r.output;
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
  same.high_paths = {dir.file("copy.ply")};
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
      [](BakeOptions& x) { x.encode.green = GreenChannel::down; },
      [](BakeOptions& x) {
        x.rays.front = {Distance::Kind::percent, 1.0f};
      },
      [](BakeOptions& x) { x.padding = 3; },
      [](BakeOptions& x) { x.outputs[0].format = PixelFormat::png8; },
      [](BakeOptions& x) {
        x.match.groups.push_back({"g", {"a"}, {"b"}});
      },
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
  const std::string base = test::cli_path() + " bake --low " + o.low_path + " --high " + o.high_paths[0] +
                           " --size 96 --cache " + dir.file("cache");
  test::CommandResult r =
      test::run_command(base + " -o " + dir.file("a.png") + " --report " + dir.file("a.json"));
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
  const std::string racing = test::cli_path() + " bake --low " + o.low_path + " --high " + o.high_paths[0] +
                             " --size 128 -q --cache " + dir.file("race");
  r = test::run_command("for i in 1 2 3 4; do " + racing + " -o " + dir.file("r$i.png") + " & done; wait");
  EXPECT_EQ(r.exit_code, 0) << r.output;
  int entries = 0;
  for (const auto& e : fs::directory_iterator(dir.file("race"))) {
    ++entries;
    EXPECT_EQ(e.path().filename().string().rfind(".tmp", 0), std::string::npos)
        << "a temporary entry was left";
    EXPECT_TRUE(fs::exists(e.path() / "manifest.json"));
    EXPECT_EQ(read_bytes((e.path() / "o0_1001.png").string()), read_bytes(dir.file("r1.png")));
  }
  EXPECT_EQ(entries, 1);
  for (const char* name : {"r2.png", "r3.png", "r4.png"})
    EXPECT_EQ(read_bytes(dir.file(name)), read_bytes(dir.file("r1.png")));
}

// An entry is verified, not trusted: each kind of damage is a miss (a
// warning naming the entry and why), a bake with the right bytes (never
// the bytes of a file outside the entry), and a new entry in its place.
TEST(TaskCache, BadEntriesAreRebakedAndReplaced) {
  test::TempDir dir;
  const BakeOptions o = sphere_bake(dir, 64, 64);
  const std::string cache = dir.file("cache");
  // `timeout`: a fetch that blocks on the FIFO fails the test instead of hanging it.
  const std::string bake_cmd = "timeout 120 " + test::cli_path() + " bake --low " + o.low_path + " --high " +
                               o.high_paths[0] + " --size 64 --cache " + cache + " -o " +
                               dir.file("out.png") + " 2>&1";
  test::CommandResult r = test::run_command(bake_cmd);
  ASSERT_EQ(r.exit_code, 0) << r.output;
  const std::string good = read_bytes(dir.file("out.png"));
  ASSERT_FALSE(good.empty());
  std::string key;
  for (const auto& e : fs::directory_iterator(cache)) key = e.path().filename().string();
  const fs::path entry = fs::path(cache) / key;
  fs::copy(entry, dir.file("saved"), fs::copy_options::recursive);
  const std::string secret = "root:x:0:0:a file outside the entry\n";
  test::write_text(dir.file("secret"), secret);
  const std::string map = (entry / "o0_1001.png").string(), manifest = (entry / "manifest.json").string();
  const auto edit_manifest = [&](const std::string& from, const std::string& to) {
    std::string text = read_bytes(manifest);
    const std::size_t at = text.find(from);
    ASSERT_NE(at, std::string::npos) << text;
    test::write_text(manifest, text.replace(at, from.size(), to));
  };
  const std::vector<std::pair<std::string, std::function<void()>>> damages = {
      {"a truncated map", [&] { fs::resize_file(map, 100); }},
      {"a map of the same size, one byte changed",
       [&] {
         std::string bytes = read_bytes(map);
         bytes[bytes.size() / 2] ^= 1;
         test::write_text(map, bytes);
       }},
      {"a map that is a symlink to a file outside",
       [&] {
         fs::remove(map);
         fs::create_symlink(dir.file("secret"), map);
       }},
      {"a map that is a FIFO",
       [&] {
         fs::remove(map);
         ASSERT_EQ(::mkfifo(map.c_str(), 0600), 0);
       }},
      {"a missing map", [&] { fs::remove(map); }},
      {"a manifest naming a file outside", [&] { edit_manifest("\"o0_1001.png\"", "\"../../secret\""); }},
      {"a manifest with a wrong type", [&] { edit_manifest("\"tile\": 1001", "\"tile\": \"x\""); }},
      {"a manifest that is an array", [&] { test::write_text(manifest, "[1, 2]"); }},
      {"a manifest without checksums (an older entry)", [&] { edit_manifest("\"xxh3\"", "\"xxh3_\""); }},
      {"an entry that is a file",
       [&] {
         fs::remove_all(entry);
         test::write_text(entry.string(), "x");
       }},
  };
  for (const auto& [what, damage] : damages) {
    SCOPED_TRACE(what);
    fs::remove_all(entry);
    fs::copy(dir.file("saved"), entry, fs::copy_options::recursive);
    damage();
    fs::remove(dir.file("out.png"));
    r = test::run_command(bake_cmd);
    EXPECT_EQ(r.exit_code, 0) << r.output;
    EXPECT_NE(r.output.find("warning: " + entry.string() + ": a bad cache entry"), std::string::npos)
        << r.output;
    EXPECT_EQ(r.output.find("cached"), std::string::npos) << r.output;
    EXPECT_TRUE(read_bytes(dir.file("out.png")) == good);
    // The bake replaced the entry: the next one is served from it.
    r = test::run_command(bake_cmd);
    EXPECT_EQ(r.exit_code, 0) << r.output;
    EXPECT_NE(r.output.find("cached (key "), std::string::npos) << r.output;
    EXPECT_EQ(r.output.find("warning"), std::string::npos) << r.output;
    EXPECT_TRUE(read_bytes(dir.file("out.png")) == good);
  }
  EXPECT_EQ(read_bytes(dir.file("secret")), secret);
  for (const auto& e : fs::directory_iterator(cache)) {
    EXPECT_EQ(e.path().filename().string(), key) << "a temporary or moved-aside entry was left";
  }
}

// A cache folder that cannot take the bake is an exit 2 before the bake,
// naming the folder, with nothing written.
TEST(TaskCache, UnwritableCacheFolderFailsBeforeTheBake) {
  test::TempDir dir;
  const BakeOptions o = sphere_bake(dir, 64, 64);
  test::write_text(dir.file("a_file"), "x");
  for (const std::string& cache : {dir.file("a_file"), dir.file("a_file") + "/cache"}) {
    const test::CommandResult r =
        test::run_command(test::cli_path() + " bake --low " + o.low_path + " --high " + o.high_paths[0] +
                          " --size 64 --cache " + cache + " -o " + dir.file("out.png") + " --report " +
                          dir.file("out.json") + " 2>&1");
    EXPECT_EQ(r.exit_code, 2) << r.output;
    EXPECT_NE(r.output.find(cache + ": the cache folder cannot be written"), std::string::npos) << r.output;
    EXPECT_FALSE(fs::exists(dir.file("out.png")));
    EXPECT_FALSE(fs::exists(dir.file("out.json")));
  }
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
  test::write_text(
      dir.file("job.toml"),
      "[defaults]\nsize = 64\n"
      "[[bake]]\nname = \"sphere\"\nlow = \"low.obj\"\nhigh = \"high.ply\"\noutputs = [\"sphere.png\"]\n"
      "[[bake]]\nname = \"field\"\nlow = \"field_low.obj\"\nhigh = \"field_high.ply\"\noutputs = "
      "[\"field.png\"]\n"
      "report = \"field.json\"\n"
      "[[bake]]\nname = \"big\"\nlow = \"low.obj\"\nhigh = \"high.ply\"\nsize = 100\npadding = 40\n"
      "outputs = [\"big.png\", \"big.exr\"]\n");
  const std::string ninja = dir.file("plan.ninja");
  test::CommandResult r = test::run_command(test::cli_path() + " plan " + dir.file("job.toml") +
                                            " --tiles 3 --tiles-min-size 100 --ninja " + ninja + " --json " +
                                            dir.file("plan.json") + " 2>&1");
  ASSERT_EQ(r.exit_code, 0) << r.output;
  EXPECT_NE(r.output.find("6 tasks (2 bakes, 3 tiles, 1 merges)"), std::string::npos) << r.output;
  r = test::run_command("ninja -f " + ninja + " 2>&1");
  ASSERT_EQ(r.exit_code, 0) << r.output;
  r = test::run_command("ninja -f " + ninja + " -n 2>&1");
  EXPECT_NE(r.output.find("no work to do"), std::string::npos) << r.output;

  // The plan's maps are the one-machine bakes' bytes.
  r = test::run_command(test::cli_path() + " bake " + dir.file("job.toml") + " --only big -q 2>&1 && mv " +
                        dir.file("big.png") + " " + dir.file("big_whole.png") + " && mv " +
                        dir.file("big.exr") + " " + dir.file("big_whole.exr"));
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
  r = test::run_command("ninja -f " + ninja + " >/dev/null && touch " + dir.file("low.obj") +
                        " && ninja -f " + ninja + " -n 2>&1");
  EXPECT_NE(r.output.find("[5/5]"), std::string::npos) << r.output;
  EXPECT_EQ(r.output.find("field"), std::string::npos) << r.output;
  EXPECT_NE(r.output.find("merge big"), std::string::npos) << r.output;

  const std::string json = read_bytes(dir.file("plan.json"));
  EXPECT_NE(json.find("\"dependencies\": [\n        \"tile:big:1\""), std::string::npos)
      << json.substr(0, 400);
  EXPECT_NE(json.find("\"key\""), std::string::npos);
}

// A map set in a plan's tiles (`maps` in the job file): tile tasks and a
// merge whose outputs are every map's file; run by Ninja they are the
// one-machine bake's bytes.
TEST(TaskPlan, MapSetInTilesThroughNinja) {
  if (test::run_command("command -v ninja >/dev/null 2>&1").exit_code != 0) {
    GTEST_SKIP() << "ninja is not installed (tools/setup installs ninja-build)";
  }
  test::TempDir dir;
  sphere_bake(dir, 96, 96);
  test::write_text(dir.file("job.toml"),
                   "[[bake]]\nname = \"set\"\nlow = \"low.obj\"\nhigh = \"high.ply\"\nsize = 96\n"
                   "maps = [\"normal\", \"height\", \"ao\"]\nao_rays = 8\n"
                   "outputs = [\"set_<MAP>.png\", \"set_<MAP>.exr\"]\n");
  const std::string ninja = dir.file("plan.ninja");
  test::CommandResult r = test::run_command(test::cli_path() + " plan " + dir.file("job.toml") +
                                            " --tiles 3 --tiles-min-size 96 --ninja " + ninja + " 2>&1");
  ASSERT_EQ(r.exit_code, 0) << r.output;
  EXPECT_NE(r.output.find("4 tasks (0 bakes, 3 tiles, 1 merges)"), std::string::npos) << r.output;
  r = test::run_command("ninja -f " + ninja + " 2>&1");
  ASSERT_EQ(r.exit_code, 0) << r.output;
  std::vector<std::string> merged;
  for (const char* name :
       {"set_normal.png", "set_height.png", "set_ao.png", "set_normal.exr", "set_height.exr", "set_ao.exr"}) {
    merged.push_back(read_bytes(dir.file(name)));
    fs::remove(dir.file(name));
  }
  r = test::run_command(test::cli_path() + " bake " + dir.file("job.toml") + " -q 2>&1");
  ASSERT_EQ(r.exit_code, 0) << r.output;
  int i = 0;
  for (const char* name :
       {"set_normal.png", "set_height.png", "set_ao.png", "set_normal.exr", "set_height.exr", "set_ao.exr"}) {
    const std::string whole = read_bytes(dir.file(name));
    EXPECT_FALSE(whole.empty()) << name;
    EXPECT_TRUE(whole == merged[i++]) << name;
  }
}

TEST(TaskPlan, DuplicateNamesAreRefused) {
  test::TempDir dir;
  sphere_bake(dir, 32, 32);
  test::write_text(dir.file("job.toml"),
                   "[[bake]]\nname = \"x\"\nlow = \"low.obj\"\nhigh = \"high.ply\"\noutputs = [\"a.png\"]\n"
                   "[[bake]]\nname = \"x\"\nlow = \"low.obj\"\nhigh = \"high.ply\"\noutputs = [\"b.png\"]\n");
  const test::CommandResult r = test::run_command(test::cli_path() + " plan " + dir.file("job.toml") +
                                                  " --json " + dir.file("p.json") + " 2>&1");
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
