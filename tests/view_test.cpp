// `nmbake view` (review.hpp) through the real binary: the .glb of the moon,
// a map set, parts and UDIM tiles through the Khronos glTF validator (npm
// gltf-validator, tests/gltf_validator; 0 errors, 0 warnings), and the page
// in a real browser (headless Chromium, WebGL through SwiftShader): its
// screenshot with the preview's camera against the low+map panel of
// `nmbake preview`. Skipped, with the reason, where node, the validator or
// Chromium is missing.
#include <gtest/gtest.h>
#include <httplib.h>
#include <sys/wait.h>
#include <unistd.h>

#include <algorithm>
#include <cmath>
#include <csignal>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <nlohmann/json.hpp>
#include <sstream>
#include <string>
#include <vector>

#include "nmbake/image.hpp"
#include "nmbake/load.hpp"
#include "nmbake/review.hpp"
#include "test_util.hpp"

namespace nmbake {
namespace {

namespace fs = std::filesystem;

std::string quoted(const std::string& s) { return "'" + s + "'"; }

std::string cli() { return quoted(test::cli_path()); }

// Runs the CLI and fails the test with its output when it does not exit 0.
void run_ok(const std::string& args) {
  const test::CommandResult r = test::run_command(cli() + " " + args);
  ASSERT_EQ(r.exit_code, 0) << args << "\n" << r.output;
}

// A small moon (768 low triangles, 442k high, 400 craters) baked at `size`.
void make_moon(const test::TempDir& dir, int size, const std::string& maps = "normal") {
  const test::CommandResult gen =
      test::run_command(quoted(test::gen_path()) + " moon --out-dir " + quoted(dir.path().string()) +
                        " --high-cells 192 --low-cells 8 --craters 400");
  ASSERT_EQ(gen.exit_code, 0) << gen.output;
  run_ok("bake -q --low " + quoted(dir.file("moon_low.obj")) + " --high " +
         quoted(dir.file("moon_high.ply")) + " --size " + std::to_string(size) + " --map " + maps + " -o " +
         quoted(dir.file("m_<MAP>.png")) + " --report " + quoted(dir.file("report.json")));
}

// The validator's verdict on a .glb: empty when 0 errors and 0 warnings;
// `skip` set when it cannot run here.
std::string validate(const std::string& glb, std::string& skip) {
  const fs::path dir = fs::path(test::source_dir()) / "tests" / "gltf_validator";
  const test::CommandResult node = test::run_command("command -v node");
  if (node.exit_code != 0) {
    skip = "node is not installed (tools/setup)";
    return "";
  }
  if (!fs::exists(dir / "node_modules" / "gltf-validator" / "package.json")) {
    skip = "the npm package gltf-validator is missing from " + (dir / "node_modules").string() +
           " (run tools/setup-npm.sh)";
    return "";
  }
  const test::CommandResult r =
      test::run_command("node " + quoted((dir / "validate.js").string()) + " " + quoted(glb));
  std::printf("%s", r.output.c_str());
  return r.exit_code == 0 ? "" : r.output;
}

nlohmann::json glb_json(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  std::string bytes((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
  if (bytes.size() < 20) return {};
  std::uint32_t length = 0;
  std::memcpy(&length, bytes.data() + 12, 4);
  return nlohmann::json::parse(bytes.substr(20, length));
}

#define VALIDATE(glb)                                 \
  do {                                                \
    std::string skip;                                 \
    const std::string problems = validate(glb, skip); \
    if (!skip.empty()) GTEST_SKIP() << skip;          \
    EXPECT_EQ(problems, "");                          \
  } while (0)

TEST(View, MoonGlbIsValidAndCarriesTheBakesFrame) {
  test::TempDir dir;
  make_moon(dir, 128);
  run_ok("view -q --low " + quoted(dir.file("moon_low.obj")) + " --map " + quoted(dir.file("m_normal.png")) +
         " --report " + quoted(dir.file("report.json")) + " -o " + quoted(dir.file("review.html")));
  ASSERT_TRUE(fs::exists(dir.file("review.glb")));
  ASSERT_TRUE(fs::exists(dir.file("review.html")));
  const nlohmann::json doc = glb_json(dir.file("review.glb"));
  ASSERT_EQ(doc["materials"].size(), 1u);
  EXPECT_EQ(doc["materials"][0]["name"], "tile_1001");
  EXPECT_EQ(doc["materials"][0]["normalTexture"]["index"], 0);
  EXPECT_EQ(doc["images"][0]["mimeType"], "image/png");
  const auto& attributes = doc["meshes"][0]["primitives"][0]["attributes"];
  for (const char* a : {"POSITION", "NORMAL", "TEXCOORD_0", "TANGENT"})
    EXPECT_TRUE(attributes.contains(a)) << a;
  // The tangents are those `nmbake tangents --write` writes: the bake's frame.
  run_ok("tangents -q " + quoted(dir.file("moon_low.obj")) + " --write " + quoted(dir.file("t.glb")));
  Mesh review, written;
  LoadStats stats;
  LoadOptions with_tangents;
  with_tangents.keep_tangents = true;
  ASSERT_TRUE(load_mesh(dir.file("review.glb"), with_tangents, review, stats));
  ASSERT_TRUE(load_mesh(dir.file("t.glb"), with_tangents, written, stats));
  ASSERT_EQ(review.indices.size(), written.indices.size());
  ASSERT_TRUE(review.has_tangents() && written.has_tangents());
  for (std::size_t c = 0; c < review.indices.size(); ++c) {
    ASSERT_EQ(review.tangents[review.indices[c]], written.tangents[written.indices[c]]) << c;
    ASSERT_EQ(review.positions[review.indices[c]], written.positions[written.indices[c]]) << c;
  }
  VALIDATE(dir.file("review.glb"));
}

TEST(View, MapSetGlbIsValid) {
  test::TempDir dir;
  make_moon(dir, 64, "normal,ao,height,curvature,miss");
  std::string maps;
  for (const char* m : {"normal", "ao", "height", "curvature", "miss"})
    maps += " --map " + quoted(dir.file(std::string("m_") + m + ".png"));
  // Transfer maps as glTF packs them (any grey maps will do for the packing):
  // roughness and metallic into metallicRoughnessTexture, emissive.
  maps += " --map roughness=" + quoted(dir.file("m_ao.png")) +
          " --map metallic=" + quoted(dir.file("m_miss.png")) +
          " --map emissive=" + quoted(dir.file("m_normal.png"));
  run_ok("view -q --low " + quoted(dir.file("moon_low.obj")) + maps + " --report " +
         quoted(dir.file("report.json")) + " -o " + quoted(dir.file("set.html")));
  const nlohmann::json doc = glb_json(dir.file("set.glb"));
  EXPECT_TRUE(doc["materials"][0].contains("occlusionTexture"));
  EXPECT_TRUE(doc["materials"][0].contains("emissiveTexture"));
  EXPECT_TRUE(doc["materials"][0]["pbrMetallicRoughness"].contains("metallicRoughnessTexture"));
  // The maps glTF has no slot for are in the page, each kind named.
  std::ifstream in(dir.file("set.html"));
  const std::string html((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
  for (const char* kind : {"\"height\"", "\"curvature\"", "\"miss\""})
    EXPECT_NE(html.find(kind), std::string::npos) << kind;
  VALIDATE(dir.file("set.glb"));
}

TEST(View, PartsGlbHasANodePerPartAndIsValid) {
  test::TempDir dir;
  const test::CommandResult gen =
      test::run_command(quoted(test::gen_path()) + " parts --out-dir " + quoted(dir.path().string()) +
                        " --count 3 --high-triangles 20000");
  ASSERT_EQ(gen.exit_code, 0) << gen.output;
  run_ok("bake -q --low " + quoted(dir.file("parts_low.obj")) + " --high " +
         quoted(dir.file("parts_high.obj")) + " --size 64 -o " + quoted(dir.file("n.png")));
  run_ok("view -q --low " + quoted(dir.file("parts_low.obj")) + " --map " + quoted(dir.file("n.png")) +
         " -o " + quoted(dir.file("parts.html")));
  Mesh low;
  LoadStats stats;
  ASSERT_TRUE(load_mesh(dir.file("parts_low.obj"), LoadOptions{true, true}, low, stats));
  const nlohmann::json doc = glb_json(dir.file("parts.glb"));
  ASSERT_EQ(doc["nodes"].size(), low.parts.size());
  for (std::size_t i = 0; i < low.parts.size(); ++i) EXPECT_EQ(doc["nodes"][i]["name"], low.parts[i].name);
  VALIDATE(dir.file("parts.glb"));
}

TEST(View, UdimGlbHasAMaterialPerTileWithUvsInTheUnitSquare) {
  test::TempDir dir;
  const test::CommandResult gen =
      test::run_command(quoted(test::gen_path()) + " parts --out-dir " + quoted(dir.path().string()) +
                        " --count 2 --high-triangles 20000");
  ASSERT_EQ(gen.exit_code, 0) << gen.output;
  // The second part's UVs moved into tile 1002.
  Mesh low;
  LoadStats stats;
  ASSERT_TRUE(load_mesh(dir.file("parts_low.obj"), LoadOptions{true, true}, low, stats));
  ASSERT_EQ(low.parts.size(), 2u);
  std::vector<char> moved(low.vertex_count(), 0);
  for (std::uint32_t t = low.parts[1].first_triangle;
       t < low.parts[1].first_triangle + low.parts[1].triangle_count; ++t) {
    for (int k = 0; k < 3; ++k) moved[low.indices[3 * t + k]] = 1;
  }
  for (std::size_t v = 0; v < low.vertex_count(); ++v) {
    if (moved[v]) low.uvs[v].x += 1.0f;
  }
  ASSERT_TRUE(save_mesh(dir.file("udim_low.obj"), low));
  run_ok("bake -q --low " + quoted(dir.file("udim_low.obj")) + " --high " +
         quoted(dir.file("parts_high.obj")) + " --size 64 -o " + quoted(dir.file("n.<UDIM>.png")));
  ASSERT_TRUE(fs::exists(dir.file("n.1002.png")));
  run_ok("view -q --low " + quoted(dir.file("udim_low.obj")) + " --map " + quoted(dir.file("n.<UDIM>.png")) +
         " -o " + quoted(dir.file("udim.html")));
  const nlohmann::json doc = glb_json(dir.file("udim.glb"));
  ASSERT_EQ(doc["materials"].size(), 2u);
  EXPECT_EQ(doc["materials"][0]["name"], "tile_1001");
  EXPECT_EQ(doc["materials"][1]["name"], "tile_1002");
  EXPECT_EQ(doc["images"].size(), 2u);
  Mesh review;
  ASSERT_TRUE(load_mesh(dir.file("udim.glb"), LoadOptions{true, true}, review, stats));
  for (const glm::vec2& uv : review.uvs) {
    EXPECT_GE(uv.x, 0.0f);
    EXPECT_LE(uv.x, 1.0f);
  }
  VALIDATE(dir.file("udim.glb"));
}

TEST(View, BadInputIsExit2AndWritesNothing) {
  test::TempDir dir;
  make_moon(dir, 32);
  const std::string base =
      "view --low " + quoted(dir.file("moon_low.obj")) + " -o " + quoted(dir.file("x.html"));
  test::CommandResult r = test::run_command(
      cli() + " " + base + " --map " + quoted(dir.file("m_normal.png")) + " --three-dir /nonexistent/three");
  EXPECT_EQ(r.exit_code, 2) << r.output;
  EXPECT_NE(r.output.find("/nonexistent/three/three.min.js"), std::string::npos) << r.output;
  EXPECT_NE(r.output.find("libjs-three"), std::string::npos) << r.output;
  r = test::run_command(cli() + " " + base + " --map " + quoted(dir.file("missing.png")));
  EXPECT_EQ(r.exit_code, 2) << r.output;
  EXPECT_NE(r.output.find("missing.png"), std::string::npos) << r.output;
  r = test::run_command(cli() + " " + base + " --map " + quoted(dir.file("m_normal.png")) + " --map " +
                        quoted(dir.file("m_normal.png")) + " --map " + quoted(dir.file("report.json")));
  EXPECT_EQ(r.exit_code, 2) << r.output;
  EXPECT_FALSE(fs::exists(dir.file("x.html")));
  EXPECT_FALSE(fs::exists(dir.file("x.glb")));
}

// `nmbake view JOB.toml -o DIR`: a page and a .glb per bake, each wearing
// the maps its bake wrote (a <MAP> output names each).
TEST(View, JobFileGivesAPagePerBake) {
  test::TempDir dir;
  make_moon(dir, 32);
  fs::create_directories(dir.path() / "out");
  test::write_text(
      dir.file("job.toml"),
      "[defaults]\nsize = 64\n"
      "[[bake]]\nname = \"set\"\nlow = \"moon_low.obj\"\nhigh = \"moon_high.ply\"\n"
      "maps = [\"normal\", \"ao\"]\noutputs = [\"out/set_<MAP>.png\"]\nreport = \"out/set.json\"\n"
      "[[bake]]\nname = \"plain\"\nlow = \"moon_low.obj\"\nhigh = \"moon_high.ply\"\n"
      "outputs = [\"out/plain.png\"]\n");
  run_ok("bake -q " + quoted(dir.file("job.toml")));
  run_ok("view -q " + quoted(dir.file("job.toml")) + " -o " + quoted(dir.file("review")));
  for (const char* name : {"set", "plain"}) {
    EXPECT_TRUE(fs::exists(dir.path() / "review" / (std::string(name) + ".html"))) << name;
    ASSERT_TRUE(fs::exists(dir.path() / "review" / (std::string(name) + ".glb"))) << name;
  }
  const nlohmann::json set = glb_json((dir.path() / "review" / "set.glb").string());
  EXPECT_TRUE(set["materials"][0].contains("normalTexture"));
  EXPECT_TRUE(set["materials"][0].contains("occlusionTexture"));
  const nlohmann::json plain = glb_json((dir.path() / "review" / "plain.glb").string());
  EXPECT_TRUE(plain["materials"][0].contains("normalTexture"));
  EXPECT_FALSE(plain["materials"][0].contains("occlusionTexture"));
  VALIDATE((dir.path() / "review" / "set.glb").string());
}

// ------------------------------------------------------------ the browser

std::string chromium() {
  if (const char* env = std::getenv("NMBAKE_CHROMIUM")) return env;
  const test::CommandResult r = test::run_command("command -v chromium");
  std::string path = r.output;
  while (!path.empty() && (path.back() == '\n' || path.back() == '\r')) path.pop_back();
  return r.exit_code == 0 ? path : "";
}

// Headless Chromium with WebGL through SwiftShader, no network; the page's
// timers and image decodes run within the virtual time budget before the
// screenshot or the DOM dump.
test::CommandResult browse(const std::string& exe, const test::TempDir& dir, const std::string& url,
                           const std::string& what) {
  const std::string profile = dir.file("profile");
  return test::run_command(
      quoted(exe) +
      " --headless --no-sandbox --disable-gpu --use-angle=swiftshader --enable-unsafe-swiftshader"
      " --disable-quic --no-first-run --disable-background-networking --disable-component-update"
      " --disable-sync --hide-scrollbars --virtual-time-budget=20000 --user-data-dir=" +
      quoted(profile) + " " + what + " " + quoted(url));
}

struct Difference {
  double mean = 0.0, p99 = 0.0;
};

// Per pixel, the largest difference over R, G, B in 8-bit levels, between
// `shot` and the `size` x `size` square of `sheet` at (ox, 0), outside the
// panel's label (top left, `label` x `label` / 4 pixels).
Difference compare(const Image& shot, const Image& sheet, int ox, int size, int label) {
  std::vector<double> d;
  for (int y = 0; y < size; ++y) {
    for (int x = 0; x < size; ++x) {
      if (x < label && y < label / 4) continue;
      const float* a = shot.at(x, y);
      const float* b = sheet.at(ox + x, y);
      double m = 0.0;
      for (int c = 0; c < 3; ++c) m = std::max(m, std::abs(static_cast<double>(a[c]) - b[c]) * 255.0);
      d.push_back(m);
    }
  }
  Difference r;
  for (double v : d) r.mean += v;
  r.mean /= static_cast<double>(d.size());
  std::sort(d.begin(), d.end());
  r.p99 = d[static_cast<std::size_t>(0.99 * static_cast<double>(d.size()))];
  return r;
}

TEST(View, BrowserMatchesThePreviewAndItsTogglesWork) {
  const std::string exe = chromium();
  if (exe.empty()) GTEST_SKIP() << "chromium is not installed (tools/setup)";
  test::TempDir dir;
  make_moon(dir, 512);
  const int size = 256;
  run_ok("view -q --low " + quoted(dir.file("moon_low.obj")) + " --high " +
         quoted(dir.file("moon_high.ply")) + " --high-budget 20000 --map " +
         quoted(dir.file("m_normal.png")) + " --report " + quoted(dir.file("report.json")) + " -o " +
         quoted(dir.file("review.html")));
  const std::string page = "file://" + fs::absolute(dir.file("review.html")).string();
  const std::string hash =
      "#mode=compare&size=" + std::to_string(size) + "&yaw=30&pitch=20&light=-0.55,0.6,0.6";

  // The page loads without a console error.
  const test::CommandResult dom = browse(exe, dir, page + hash, "--dump-dom");
  ASSERT_EQ(dom.exit_code, 0) << dom.output;
  if (dom.output.find("<title>nmbake view: ready</title>") == std::string::npos) {
    if (dom.output.find("WebGL") != std::string::npos &&
        dom.output.find("nmbake view: error") != std::string::npos &&
        dom.output.find("context") != std::string::npos) {
      GTEST_SKIP() << "Chromium gives no WebGL context here";
    }
    FAIL() << "the page is not ready:\n" << dom.output.substr(0, 4000);
  }

  const std::string window = "--window-size=" + std::to_string(size) + "," + std::to_string(size);
  const auto shot = [&](const std::string& name, const std::string& extra) {
    const std::string path = dir.file(name);
    const test::CommandResult r =
        browse(exe, dir, page + hash + extra, window + " --screenshot=" + quoted(path));
    EXPECT_EQ(r.exit_code, 0) << r.output;
    Image image;
    EXPECT_TRUE(read_image(path, image)) << path;
    EXPECT_EQ(image.width, size);
    return image;
  };
  const Image on = shot("on.png", "&map=on");
  const Image off = shot("off.png", "&map=off");
  const Image wire = shot("wire.png", "&map=on&wire=on");
  const Image shown = shot("shown.png", "&map=on&show=map0");
  ASSERT_EQ(on.width, size);

  // The preview's low+map panel, one sample per pixel (the page draws one).
  run_ok("preview -q --low " + quoted(dir.file("moon_low.obj")) + " --high " +
         quoted(dir.file("moon_high.ply")) + " --map " + quoted(dir.file("m_normal.png")) + " --size " +
         std::to_string(size) + " --aa 1 --yaw 30 --pitch 20 -o " + quoted(dir.file("sheet.png")));
  Image sheet;
  ASSERT_TRUE(read_image(dir.file("sheet.png"), sheet));
  const int gap = std::max(2, size / 48);
  const int label = 64 * std::max(1, size / 192);  // "low+map", drawn by the preview
  const Difference with_map = compare(on, sheet, size + gap, size, label);
  const Difference without_map = compare(off, sheet, size + gap, size, label);
  std::printf("page vs preview, map on: mean %.3f, p99 %.1f levels; map off: mean %.3f, p99 %.1f\n",
              with_map.mean, with_map.p99, without_map.mean, without_map.p99);
  // The bound: mean under 1 level, 99th percentile at most 4 levels (measured:
  // 0.25 and 1; silhouette pixels differ by rasterisation rules).
  constexpr double kMeanBound = 1.0, kP99Bound = 4.0;
  EXPECT_LT(with_map.mean, kMeanBound);
  EXPECT_LE(with_map.p99, kP99Bound);
  // Without the map the page shows the bare low mesh: it must fail the bound,
  // by far (measured: p99 17 levels, mean 1.35).
  EXPECT_GT(without_map.p99, 2.0 * kP99Bound);
  EXPECT_GT(without_map.mean, 3.0 * with_map.mean);

  // The toggles change the picture.
  const Difference wire_vs_on = compare(wire, on, 0, size, 0);
  const Difference shown_vs_on = compare(shown, on, 0, size, 0);
  EXPECT_GT(wire_vs_on.mean, 1.0);
  EXPECT_GT(shown_vs_on.mean, 10.0);
}

// `--serve`: /state counts the map files' changes, /map/I/TILE.png serves
// the file as it is now, and a page that holds an older version (it starts
// at 0) polls, sees the change, fetches the maps again and shows the new
// one: its screenshot is that of a page built from the new map.
TEST(View, ServeReloadsARewrittenMap) {
  test::TempDir dir;
  make_moon(dir, 256);
  // Another map of the same mesh: the same bake read with green down.
  run_ok("bake -q --low " + quoted(dir.file("moon_low.obj")) + " --high " +
         quoted(dir.file("moon_high.ply")) + " --size 256 --green down -o " + quoted(dir.file("down.png")));
  fs::copy_file(dir.file("m_normal.png"), dir.file("live.png"));

  int out[2];
  ASSERT_EQ(::pipe(out), 0);
  const pid_t child = ::fork();
  ASSERT_GE(child, 0);
  if (child == 0) {
    ::dup2(out[1], STDOUT_FILENO);
    ::close(out[0]);
    ::close(out[1]);
    const std::string low = dir.file("moon_low.obj"), map = dir.file("live.png"), exe = test::cli_path();
    ::execl(exe.c_str(), exe.c_str(), "view", "--low", low.c_str(), "--map", map.c_str(), "--serve", "--port",
            "0", static_cast<char*>(nullptr));
    ::_exit(127);
  }
  ::close(out[1]);
  std::string line;
  char c = 0;
  while (::read(out[0], &c, 1) == 1 && c != '\n') line += c;
  const std::size_t at = line.find("http://127.0.0.1:");
  ASSERT_NE(at, std::string::npos) << line;
  const int port = std::stoi(line.substr(at + 17));
  const std::string url = "http://127.0.0.1:" + std::to_string(port) + "/";
  const auto stop = [&]() {
    ::kill(child, SIGINT);
    int status = 0;
    ::waitpid(child, &status, 0);
    ::close(out[0]);
    return status;
  };

  httplib::Client client("127.0.0.1", port);
  auto state = client.Get("/state");
  ASSERT_TRUE(state) << "no answer from " << url;
  EXPECT_EQ(state->body, "{\"version\":0}");
  auto before = client.Get("/map/0/1001.png");
  ASSERT_TRUE(before);
  EXPECT_EQ(before->status, 200);
  EXPECT_EQ(client.Get("/map/1/1001.png")->status, 404);
  // The map rewritten on disk, as a bake writes it (a new file renamed over it).
  fs::copy_file(dir.file("down.png"), dir.file("live.tmp"));
  fs::rename(dir.file("live.tmp"), dir.file("live.png"));
  state = client.Get("/state");
  ASSERT_TRUE(state);
  EXPECT_EQ(state->body, "{\"version\":1}");
  auto after = client.Get("/map/0/1001.png");
  ASSERT_TRUE(after);
  EXPECT_NE(after->body, before->body);
  std::string expected;
  float range[2];
  ASSERT_TRUE(review_map_png("normal", dir.file("down.png"), expected, range));
  EXPECT_EQ(after->body, expected);

  const std::string exe = chromium();
  if (exe.empty()) {
    EXPECT_EQ(stop(), 0);
    GTEST_SKIP() << "chromium is not installed (tools/setup): the page's reload was not checked in a browser";
  }
  const int size = 256;
  const std::string hash = "#mode=compare&size=" + std::to_string(size);
  const test::CommandResult dom = browse(exe, dir, url + hash, "--dump-dom");
  EXPECT_NE(dom.output.find("<title>nmbake view: ready, maps reloaded 1 time</title>"), std::string::npos)
      << dom.output.substr(0, 3000);
  const std::string window = "--window-size=" + std::to_string(size) + "," + std::to_string(size);
  const auto shot = [&](const std::string& page, const std::string& name) {
    const std::string path = dir.file(name);
    const test::CommandResult r = browse(exe, dir, page + hash, window + " --screenshot=" + quoted(path));
    EXPECT_EQ(r.exit_code, 0) << r.output;
    Image image;
    EXPECT_TRUE(read_image(path, image)) << path;
    return image;
  };
  const Image served = shot(url, "served.png");
  EXPECT_EQ(stop(), 0);  // Ctrl-C: a clean exit
  for (const char* name : {"down", "m_normal"}) {
    run_ok("view -q --low " + quoted(dir.file("moon_low.obj")) + " --map " +
           quoted(dir.file(std::string(name) + ".png")) + " -o " +
           quoted(dir.file(std::string(name) + ".html")));
  }
  const Image down = shot("file://" + fs::absolute(dir.file("down.html")).string(), "down_shot.png");
  const Image old = shot("file://" + fs::absolute(dir.file("m_normal.html")).string(), "old_shot.png");
  ASSERT_EQ(served.width, size);
  ASSERT_EQ(down.width, size);
  ASSERT_EQ(old.width, size);
  const Difference to_new = compare(served, down, 0, size, 0);
  const Difference to_old = compare(served, old, 0, size, 0);
  std::printf(
      "served page vs the new map's page: mean %.3f, p99 %.1f; vs the old map's: mean %.3f, p99 %.1f\n",
      to_new.mean, to_new.p99, to_old.mean, to_old.p99);
  EXPECT_LT(to_new.mean, 0.1);
  EXPECT_GT(to_old.p99, 4.0);
}

}  // namespace
}  // namespace nmbake
