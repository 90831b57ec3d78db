// Parts, bake groups and UDIM tiles: OBJ o/g parts, name matching, explicit
// groups, and end-to-end bakes where parts must not bleed into each other and
// tiles must equal the tile baked alone.
#include "nmbake/parts.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <fstream>
#include <functional>
#include <iterator>
#include <nlohmann/json.hpp>
#include <sstream>

#include "nmbake/bake.hpp"
#include "nmbake/diff.hpp"
#include "nmbake/job.hpp"
#include "nmbake/load.hpp"
#include "nmbake/udim.hpp"
#include "test_util.hpp"

namespace nmbake {
namespace {

std::string read_bytes(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  return std::string(std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>());
}

// A named grid of n x n quads over [x0, x1] x [y0, y1] at height z + h(x, y),
// with UVs over [u0, u1] x [v0, v1] (none when u0 == u1).
struct Plate {
  std::string name;
  int n = 8;
  float x0 = 0, x1 = 1, y0 = 0, y1 = 1, z = 0;
  float u0 = 0, u1 = 0, v0 = 0, v1 = 0;
  std::function<float(float, float)> h;
  glm::vec2 uv_shift{0.0f};  // subtracted from each UV after it is computed
};

// OBJ text of several plates, each an `o` object (vertices numbered across
// the file as OBJ does).
// `materials`: a `usemtl` line for each plate (none when empty).
std::string plates_obj(const std::vector<Plate>& plates, const std::vector<std::string>& materials = {}) {
  std::ostringstream out;
  out.precision(9);
  std::size_t base = 0;
  for (std::size_t plate = 0; plate < plates.size(); ++plate) {
    const Plate& p = plates[plate];
    out << "o " << p.name << "\n";
    if (plate < materials.size()) out << "usemtl " << materials[plate] << "\n";
    const bool uv = p.u1 != p.u0;
    for (int j = 0; j <= p.n; ++j) {
      for (int i = 0; i <= p.n; ++i) {
        const float s = static_cast<float>(i) / p.n, t = static_cast<float>(j) / p.n;
        const float x = p.x0 + s * (p.x1 - p.x0), y = p.y0 + t * (p.y1 - p.y0);
        out << "v " << x << " " << y << " " << p.z + (p.h ? p.h(x, y) : 0.0f) << "\n";
        if (uv) {
          const float u = p.u0 + s * (p.u1 - p.u0), v = p.v0 + t * (p.v1 - p.v0);
          out << "vt " << u - p.uv_shift.x << " " << v - p.uv_shift.y << "\n";
        }
      }
    }
    for (int j = 0; j < p.n; ++j) {
      for (int i = 0; i < p.n; ++i) {
        const std::size_t a = base + static_cast<std::size_t>(j * (p.n + 1) + i) + 1;
        const std::size_t b = a + 1, c = a + static_cast<std::size_t>(p.n + 1) + 1, d = c - 1;
        if (uv) {
          out << "f " << a << "/" << a << " " << b << "/" << b << " " << c << "/" << c << "\n";
          out << "f " << a << "/" << a << " " << c << "/" << c << " " << d << "/" << d << "\n";
        } else {
          out << "f " << a << " " << b << " " << c << "\nf " << a << " " << c << " " << d << "\n";
        }
      }
    }
    base += static_cast<std::size_t>((p.n + 1) * (p.n + 1));
  }
  return out.str();
}

Mesh load(const std::string& path, bool uvs = true) {
  Mesh mesh;
  LoadStats stats;
  const Status s = load_mesh(path, LoadOptions{uvs, true}, mesh, stats);
  EXPECT_TRUE(s.is_ok()) << s.message();
  return mesh;
}

// -------------------------------------------------------------- OBJ parts

TEST(LoadParts, ObjObjectsNameParts) {
  test::TempDir dir;
  // Triangles before the first name are an unnamed part; `g` inside objects
  // does not split them; an object named again later joins consecutive runs
  // only.
  test::write_text(dir.file("m.obj"),
                   "v 0 0 0\nv 1 0 0\nv 0 1 0\n"
                   "f 1 2 3\n"
                   "o body_low\ng material_a\nf 1 2 3\nf 1 2 3\ng material_b\nf 1 2 3\n"
                   "o empty\n"
                   "o mag_low\nf 1 2 3\n"
                   "o body_low\nf 1 2 3\n");
  for (const bool serial : {true, false}) {
    Mesh mesh;
    LoadStats stats;
    LoadOptions options;
    options.serial = serial;
    options.block_bytes = 16;  // many blocks: names across block boundaries
    ASSERT_TRUE(load_mesh(dir.file("m.obj"), options, mesh, stats).is_ok());
    ASSERT_EQ(mesh.parts.size(), 4u) << serial;
    EXPECT_EQ(mesh.parts[0].name, "");
    EXPECT_EQ(mesh.parts[0].triangle_count, 1u);
    EXPECT_EQ(mesh.parts[1].name, "body_low");
    EXPECT_EQ(mesh.parts[1].first_triangle, 1u);
    EXPECT_EQ(mesh.parts[1].triangle_count, 3u);
    EXPECT_EQ(mesh.parts[2].name, "mag_low");
    EXPECT_EQ(mesh.parts[2].triangle_count, 1u);
    EXPECT_EQ(mesh.parts[3].name, "body_low");
    EXPECT_EQ(mesh.parts[3].first_triangle, 5u);
  }
}

TEST(LoadParts, ObjGroupsNamePartsWhenThereAreNoObjects) {
  test::TempDir dir;
  test::write_text(dir.file("g.obj"),
                   "v 0 0 0\nv 1 0 0\nv 0 1 0\ng  a_low \nf 1 2 3\ng b low\nf 1 2 3\nf 1 2 3\n");
  const Mesh mesh = load(dir.file("g.obj"));
  ASSERT_EQ(mesh.parts.size(), 2u);
  EXPECT_EQ(mesh.parts[0].name, "a_low");  // blanks trimmed
  EXPECT_EQ(mesh.parts[1].name, "b low");  // "g b low": the whole rest of the line
  EXPECT_EQ(mesh.parts[1].triangle_count, 2u);
  test::write_text(dir.file("n.obj"), "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n");
  EXPECT_TRUE(load(dir.file("n.obj")).parts.empty());
}

TEST(LoadParts, ValidateRejectsPartsThatDoNotTile) {
  Mesh mesh;
  mesh.positions = {{0, 0, 0}, {1, 0, 0}, {0, 1, 0}};
  mesh.indices = {0, 1, 2, 0, 1, 2};
  mesh.parts = {{"a", 0, 1}};
  EXPECT_FALSE(validate_mesh(mesh, "m").is_ok());
  mesh.parts = {{"a", 0, 1}, {"b", 2, 1}};
  EXPECT_FALSE(validate_mesh(mesh, "m").is_ok());
  mesh.parts = {{"a", 0, 1}, {"b", 1, 1}};
  EXPECT_TRUE(validate_mesh(mesh, "m").is_ok());
}

// -------------------------------------------------------------- materials

// `usemtl` names materials by the rules of parts: triangles before the first
// are the unnamed material, a material holds across `o` and `g` until the
// next `usemtl`, consecutive runs of one name are one range, a name that
// names no triangle makes none, and a name may come back later. The serial
// and the slice parser read the same.
TEST(LoadMaterials, ObjUsemtlNamesMaterialRanges) {
  test::TempDir dir;
  test::write_text(dir.file("m.obj"),
                   "mtllib m.mtl\nv 0 0 0\nv 1 0 0\nv 0 1 0\n"
                   "f 1 2 3\n"
                   "usemtl steel\nf 1 2 3\no bolt\ng thread\nf 1 2 3\n"
                   "usemtl unused\n"
                   "usemtl  steel  \nf 1 2 3\n"
                   "usemtl rubber grip\nf 1 2 3\nf 1 2 3\n"
                   "o nut\nusemtl steel\nf 1 2 3\n");
  for (const bool serial : {true, false}) {
    SCOPED_TRACE(serial ? "serial" : "slices");
    Mesh mesh;
    LoadStats stats;
    LoadOptions options;
    options.serial = serial;
    options.block_bytes = 16;  // many blocks: statements across block boundaries
    ASSERT_TRUE(load_mesh(dir.file("m.obj"), options, mesh, stats).is_ok());
    const std::vector<MeshPart> expected{{"", 0, 1}, {"steel", 1, 3}, {"rubber grip", 4, 2}, {"steel", 6, 1}};
    EXPECT_EQ(mesh.materials, expected);
    EXPECT_TRUE(mesh.has_named_materials());
    // Parts are the objects, whatever the materials do.
    const std::vector<MeshPart> parts{{"", 0, 2}, {"bolt", 2, 4}, {"nut", 6, 1}};
    EXPECT_EQ(mesh.parts, parts);
  }
  // usemtl before the first face: every triangle has a name.
  test::write_text(dir.file("first.obj"),
                   "usemtl a\nv 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\nusemtl b\nf 1 2 3\n");
  const std::vector<MeshPart> first{{"a", 0, 1}, {"b", 1, 1}};
  EXPECT_EQ(load(dir.file("first.obj")).materials, first);
  // No usemtl, or only a bare one (the unnamed material): no materials.
  test::write_text(dir.file("none.obj"), "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n");
  EXPECT_TRUE(load(dir.file("none.obj")).materials.empty());
  test::write_text(dir.file("bare.obj"), "v 0 0 0\nv 1 0 0\nv 0 1 0\nusemtl\nf 1 2 3\n");
  EXPECT_TRUE(load(dir.file("bare.obj")).materials.empty());
}

TEST(LoadMaterials, ValidateRejectsMaterialsThatDoNotTile) {
  Mesh mesh;
  mesh.positions = {{0, 0, 0}, {1, 0, 0}, {0, 1, 0}};
  mesh.indices = {0, 1, 2, 0, 1, 2};
  mesh.materials = {{"a", 0, 1}};
  const Status short_of = validate_mesh(mesh, "m");
  EXPECT_EQ(short_of.message(), "m: the materials cover 1 of 2 triangles");
  mesh.materials = {{"a", 0, 1}, {"b", 1, 0}, {"c", 1, 1}};
  const Status empty = validate_mesh(mesh, "m");
  EXPECT_NE(empty.message().find("material 'b' (triangles 1 + 0) does not follow the material before it"),
            std::string::npos)
      << empty.message();
  mesh.materials = {{"a", 0, 1}, {"a", 1, 1}};  // two ranges of one name may follow each other
  EXPECT_TRUE(validate_mesh(mesh, "m").is_ok());
}

// save_mesh writes materials back (OBJ usemtl, glTF one primitive per
// material range within each part's node) and they load back as they were,
// with the parts, also where a material range crosses a part boundary and
// where the unnamed material follows a named one.
TEST(LoadMaterials, SavedMaterialsLoadBack) {
  test::TempDir dir;
  Mesh mesh;
  mesh.positions = {{0, 0, 0}, {1, 0, 0}, {0, 1, 0}};
  for (int t = 0; t < 7; ++t) mesh.indices.insert(mesh.indices.end(), {0, 1, 2});
  mesh.parts = {{"body", 0, 3}, {"lid", 3, 4}};
  mesh.materials = {{"paint", 0, 2}, {"chrome", 2, 3}, {"", 5, 1}, {"paint", 6, 1}};
  for (const char* name : {"m.obj", "m.glb", "m.gltf"}) {
    SCOPED_TRACE(name);
    ASSERT_TRUE(save_mesh(dir.file(name), mesh).is_ok());
    const Mesh back = load(dir.file(name), false);
    EXPECT_EQ(back.parts, mesh.parts);
    EXPECT_EQ(back.materials, mesh.materials);
  }
  // The OBJ text: usemtl where each range begins, a bare one for "".
  std::ifstream in(dir.file("m.obj"));
  const std::string text((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
  EXPECT_NE(text.find("o body\nusemtl paint\nf 1 2 3\nf 1 2 3\nusemtl chrome\n"), std::string::npos) << text;
  EXPECT_NE(text.find("usemtl\nf 1 2 3\nusemtl paint\n"), std::string::npos) << text;
}

// -------------------------------------------------------------- matching

Mesh with_parts(const std::vector<std::pair<std::string, std::uint32_t>>& parts) {
  Mesh mesh;
  mesh.positions = {{0, 0, 0}, {1, 0, 0}, {0, 1, 0}};
  std::uint32_t first = 0;
  for (const auto& [name, count] : parts) {
    mesh.parts.push_back({name, first, count});
    for (std::uint32_t t = 0; t < count; ++t) mesh.indices.insert(mesh.indices.end(), {0, 1, 2});
    first += count;
  }
  return mesh;
}

TEST(MatchParts, SuffixesNumberedDuplicatesAndCase) {
  const Mesh low = with_parts({{"body_low", 2}, {"Mag_LOW", 1}, {"body_low", 1}});
  const Mesh high = with_parts({{"Mag_High", 1},
                                {"body_high", 3},
                                {"body_high.001", 2},
                                {"body_high_2", 1},
                                {"bodyx_high", 1},
                                {"mag_high", 1},
                                {"stray", 1}});
  BakeGroups g;
  ASSERT_TRUE(match_parts(low, high, MatchOptions{}, "low.obj", "high.obj", g).is_ok());
  ASSERT_EQ(g.groups.size(), 2u);
  EXPECT_EQ(g.groups[0].name, "body");
  EXPECT_EQ(g.groups[0].low_parts, (std::vector<std::string>{"body_low"}));
  EXPECT_EQ(g.groups[0].high_parts, (std::vector<std::string>{"body_high", "body_high.001", "body_high_2"}));
  EXPECT_EQ(g.groups[0].low_triangles, 3u);
  EXPECT_EQ(g.groups[0].high_triangles, 6u);
  // The suffix ignores case, the base name does not: Mag_LOW takes Mag_High only.
  EXPECT_EQ(g.groups[1].name, "Mag");
  EXPECT_EQ(g.groups[1].high_parts, (std::vector<std::string>{"Mag_High"}));
  EXPECT_EQ(g.low_group, (std::vector<std::uint32_t>{0, 0, 1, 0}));
  EXPECT_EQ(g.high_triangles[1], (std::vector<std::uint32_t>{0}));
  EXPECT_EQ(g.high_triangles[0], (std::vector<std::uint32_t>{1, 2, 3, 4, 5, 6}));
  EXPECT_EQ(g.unused_high_parts, (std::vector<std::string>{"bodyx_high", "mag_high", "stray"}));

  std::vector<std::uint32_t> first;
  const std::vector<std::uint32_t> indices = group_high_indices(high, g, first);
  EXPECT_EQ(first, (std::vector<std::uint32_t>{0, 6, 7}));
  EXPECT_EQ(indices.size(), 21u);
}

TEST(MatchParts, UnmatchedLowPartsAreListedOrBakedAgainstTheRest) {
  const Mesh low = with_parts({{"body_low", 1}, {"scope_low", 1}, {"bolt", 1}});
  const Mesh high = with_parts({{"body_high", 1}, {"scope_hi", 1}, {"bolts", 2}});
  BakeGroups g;
  const Status s = match_parts(low, high, MatchOptions{}, "low.obj", "high.obj", g);
  ASSERT_FALSE(s.is_ok());
  EXPECT_EQ(s.code(), StatusCode::bad_input);
  EXPECT_NE(s.message().find("low.obj"), std::string::npos) << s.message();
  EXPECT_NE(s.message().find("'scope_low', 'bolt'"), std::string::npos) << s.message();
  EXPECT_NE(s.message().find("--unmatched all"), std::string::npos) << s.message();

  MatchOptions all;
  all.unmatched = Unmatched::all;
  ASSERT_TRUE(match_parts(low, high, all, "low.obj", "high.obj", g).is_ok());
  ASSERT_EQ(g.groups.size(), 2u);
  EXPECT_EQ(g.groups[1].name, "(unmatched)");
  EXPECT_EQ(g.groups[1].low_parts, (std::vector<std::string>{"scope_low", "bolt"}));
  EXPECT_EQ(g.groups[1].high_parts, (std::vector<std::string>{"scope_hi", "bolts"}));
  EXPECT_EQ(g.low_group, (std::vector<std::uint32_t>{0, 1, 1}));
  EXPECT_TRUE(g.unused_high_parts.empty());
}

TEST(MatchParts, NoSuffixOrMatchOffIsOneGroupOfEverything) {
  const Mesh low = with_parts({{"body", 1}, {"mag", 1}});
  const Mesh high = with_parts({{"body_high", 1}, {"mag_high", 1}});
  BakeGroups g;
  ASSERT_TRUE(match_parts(low, high, MatchOptions{}, "l", "h", g).is_ok());
  EXPECT_FALSE(g.grouped());
  MatchOptions name;
  name.mode = MatchMode::name;
  EXPECT_FALSE(match_parts(low, high, name, "l", "h", g).is_ok());

  const Mesh suffixed = with_parts({{"body_low", 1}, {"mag_low", 1}});
  MatchOptions off;
  off.mode = MatchMode::off;
  ASSERT_TRUE(match_parts(suffixed, high, off, "l", "h", g).is_ok());
  EXPECT_FALSE(g.grouped());
  // One group that holds every high triangle is no grouping either.
  ASSERT_TRUE(match_parts(with_parts({{"x_low", 2}}), with_parts({{"x_high", 1}, {"x_high.002", 1}}),
                          MatchOptions{}, "l", "h", g)
                  .is_ok());
  EXPECT_FALSE(g.grouped());
  // Custom suffixes.
  MatchOptions custom;
  custom.low_suffix = "_lp";
  custom.high_suffix = "_hp";
  ASSERT_TRUE(match_parts(with_parts({{"a_lp", 1}, {"b_lp", 1}}), with_parts({{"a_hp", 1}, {"b_hp", 1}}),
                          custom, "l", "h", g)
                  .is_ok());
  EXPECT_EQ(g.groups.size(), 2u);
}

TEST(MatchParts, ExplicitGroups) {
  const Mesh low = with_parts({{"body", 1}, {"mag", 1}});
  const Mesh high = with_parts({{"body_hi", 1}, {"bolts", 1}, {"mag_hi", 1}});
  MatchOptions options;
  options.groups = {{"main", {"body"}, {"body_hi", "bolts"}}, {"", {"mag"}, {"mag_hi", "bolts"}}};
  BakeGroups g;
  ASSERT_TRUE(match_parts(low, high, options, "l", "h", g).is_ok());
  ASSERT_EQ(g.groups.size(), 2u);
  EXPECT_EQ(g.groups[0].name, "main");
  EXPECT_EQ(g.groups[1].name, "group 2");
  EXPECT_EQ(g.high_triangles[0], (std::vector<std::uint32_t>{0, 1}));
  EXPECT_EQ(g.high_triangles[1], (std::vector<std::uint32_t>{1, 2}));  // bolts in both

  MatchOptions unknown;
  unknown.groups = {{"g", {"body"}, {"nope"}}};
  const Status s = match_parts(low, high, unknown, "l.obj", "h.obj", g);
  ASSERT_FALSE(s.is_ok());
  EXPECT_NE(s.message().find("h.obj: group 'g' names high part 'nope'"), std::string::npos) << s.message();
  MatchOptions twice;
  twice.groups = {{"a", {"body"}, {"body_hi"}}, {"b", {"body", "mag"}, {"mag_hi"}}};
  EXPECT_FALSE(match_parts(low, high, twice, "l", "h", g).is_ok());
  MatchOptions missing;  // mag in no group: unmatched
  missing.groups = {{"a", {"body"}, {"body_hi"}}};
  EXPECT_FALSE(match_parts(low, high, missing, "l", "h", g).is_ok());
}

// A part listed twice in one group: the low part was looked up in the
// groups made so far, which did not hold its own group yet (SIGSEGV).
TEST(MatchParts, PartListedTwiceInOneGroupIsRefused) {
  const Mesh low = with_parts({{"body", 1}, {"mag", 1}});
  const Mesh high = with_parts({{"body_hi", 1}, {"mag_hi", 1}});
  BakeGroups g;
  MatchOptions low_twice;
  low_twice.groups = {{"main", {"body", "body"}, {"body_hi"}}, {"", {"mag"}, {"mag_hi"}}};
  Status s = match_parts(low, high, low_twice, "l.obj", "h.obj", g);
  ASSERT_FALSE(s.is_ok());
  EXPECT_EQ(s.code(), StatusCode::bad_input);
  EXPECT_NE(s.message().find("l.obj: group 'main' lists low part 'body' twice"), std::string::npos)
      << s.message();
  MatchOptions high_twice;
  high_twice.groups = {{"main", {"body"}, {"body_hi", "body_hi"}}, {"", {"mag"}, {"mag_hi"}}};
  s = match_parts(low, high, high_twice, "l.obj", "h.obj", g);
  ASSERT_FALSE(s.is_ok());
  EXPECT_NE(s.message().find("h.obj: group 'main' lists high part 'body_hi' twice"), std::string::npos)
      << s.message();
}

// The job file says the same, with its line, before any mesh is read.
TEST(JobGroups, PartListedTwiceOrLowPartInTwoGroupsNamesJobGroupAndPart) {
  test::TempDir dir;
  const std::string head = "[[bake]]\nlow = \"l.obj\"\nhigh = \"h.obj\"\noutputs = [\"m.png\"]\n";
  const std::pair<std::string, std::string> cases[] = {
      {"[[bake.group]]\nname = \"main\"\nlow = [\"body_low\", \"body_low\"]\nhigh = [\"body_high\"]\n",
       "group 'main': low part 'body_low' is listed twice"},
      {"[[bake.group]]\nlow = [\"body_low\"]\nhigh = [\"body_high\", \"bolt\", \"body_high\"]\n",
       "group 'group 1': high part 'body_high' is listed twice"},
      {"[[bake.group]]\nname = \"a\"\nlow = [\"body_low\"]\nhigh = [\"body_high\"]\n"
       "[[bake.group]]\nname = \"b\"\nlow = [\"mag_low\", \"body_low\"]\nhigh = [\"mag_high\"]\n",
       "low part 'body_low' is in two groups ('a' and 'b')"},
  };
  for (const auto& [groups, message] : cases) {
    test::write_text(dir.file("job.toml"), head + groups);
    std::vector<BakeJob> jobs;
    const Status s = load_job_file(dir.file("job.toml"), jobs);
    ASSERT_FALSE(s.is_ok()) << groups;
    EXPECT_EQ(s.code(), StatusCode::bad_input);
    EXPECT_NE(s.message().find(dir.file("job.toml")), std::string::npos) << s.message();
    EXPECT_NE(s.message().find(message), std::string::npos) << s.message();
  }
  // A high part in two groups is allowed (bolts baked onto both).
  test::write_text(dir.file("job.toml"), head +
                                             "[[bake.group]]\nlow = [\"a\"]\nhigh = [\"a_hi\", \"bolts\"]\n"
                                             "[[bake.group]]\nlow = [\"b\"]\nhigh = [\"b_hi\", \"bolts\"]\n");
  std::vector<BakeJob> jobs;
  const Status ok = load_job_file(dir.file("job.toml"), jobs);
  EXPECT_TRUE(ok.is_ok()) << ok.message();
}

TEST(JobGroups, ParsesGroupTablesAndMatchKeys) {
  test::TempDir dir;
  test::write_text(
      dir.file("job.toml"),
      "[defaults]\nlow_suffix = \"_lp\"\nunmatched = \"all\"\n"
      "[[bake]]\nlow = \"l.obj\"\nhigh = \"h.obj\"\noutputs = [\"m.png\"]\nmatch = \"name\"\n"
      "[[bake.group]]\nname = \"body\"\nlow = [\"body_lp\"]\nhigh = [\"body_hp\", \"bolts_hp\"]\n"
      "[[bake.group]]\nlow = [\"mag_lp\"]\nhigh = [\"mag_hp\"]\n");
  std::vector<BakeJob> jobs;
  const Status s = load_job_file(dir.file("job.toml"), jobs);
  ASSERT_TRUE(s.is_ok()) << s.message();
  ASSERT_EQ(jobs.size(), 1u);
  const MatchOptions& m = jobs[0].options.match;
  EXPECT_EQ(m.low_suffix, "_lp");
  EXPECT_EQ(m.unmatched, Unmatched::all);
  EXPECT_EQ(m.mode, MatchMode::name);
  ASSERT_EQ(m.groups.size(), 2u);
  EXPECT_EQ(m.groups[0].name, "body");
  EXPECT_EQ(m.groups[0].high, (std::vector<std::string>{"body_hp", "bolts_hp"}));
  EXPECT_EQ(m.groups[1].low, (std::vector<std::string>{"mag_lp"}));

  test::write_text(dir.file("bad.toml"),
                   "[[bake]]\nlow = \"l.obj\"\nhigh = \"h.obj\"\noutputs = [\"m.png\"]\n"
                   "[[bake.group]]\nlow = [\"a\"]\nhihg = [\"b\"]\n");
  const Status bad = load_job_file(dir.file("bad.toml"), jobs);
  ASSERT_FALSE(bad.is_ok());
  EXPECT_NE(bad.message().find("hihg"), std::string::npos) << bad.message();
}

// -------------------------------------------------------------- bleeding

// Two parts stacked 1 mm apart (plates 10 cm wide): part b sits right above
// part a, so a's cage rays cross b's high mesh before they reach a's. Side
// by side in UV: a in the left half of the map, b in the right.
struct BleedScene {
  test::TempDir dir;
  Plate a_low{"a_low", 8, 0, 0.1f, 0, 0.1f, 0, 0.02f, 0.48f, 0.02f, 0.98f, {}};
  Plate b_low{"b_low", 8, 0, 0.1f, 0, 0.1f, 0.001f, 0.52f, 0.98f, 0.02f, 0.98f, {}};
  Plate a_high{
      "a_high", 96, 0,
      0.1f,     0,  0.1f,
      0,        0,  0,
      0,        0,  [](float x, float y) { return 0.0003f * std::sin(120.0f * x) * std::cos(90.0f * y); }};
  Plate b_high{"b_high", 96, 0, 0.1f, 0, 0.1f,
               0.001f,   0,  0, 0,    0, [](float x, float) { return 0.0002f * std::sin(200.0f * x); }};

  BleedScene() {
    test::write_text(dir.file("low.obj"), plates_obj({a_low, b_low}));
    test::write_text(dir.file("high.obj"), plates_obj({a_high, b_high}));
    test::write_text(dir.file("a_low.obj"), plates_obj({a_low}));
    test::write_text(dir.file("a_high.obj"), plates_obj({a_high}));
    test::write_text(dir.file("b_low.obj"), plates_obj({b_low}));
    test::write_text(dir.file("b_high.obj"), plates_obj({b_high}));
  }
  // Distances: auto, or a cage 1.5 mm out, past b's high mesh (as an
  // artist's cage often is), and 0.5 mm in.
  BakeOptions options(const std::string& low, const std::string& high, const std::string& out,
                      bool auto_distances = false) const {
    BakeOptions o;
    if (!auto_distances) {
      o.rays.front = {Distance::Kind::absolute, 0.0015f};
      o.rays.back = {Distance::Kind::absolute, 0.0005f};
    }
    o.low_path = dir.file(low);
    o.high_paths = {dir.file(high)};
    o.outputs = {{dir.file(out), PixelFormat::png16}};
    o.width = o.height = 128;
    o.padding = 0;  // the halves of the map stay apart
    return o;
  }
};

Image read(const std::string& path) {
  Image image;
  EXPECT_TRUE(read_image(path, image).is_ok()) << path;
  return image;
}

// Angular difference over one half of the map.
DiffStats diff_half(const std::string& a, const std::string& b, bool left) {
  const Image ia = read(a), ib = read(b);
  Image mask;
  mask.width = ia.width;
  mask.height = ia.height;
  mask.channels = 1;
  mask.pixels.assign(static_cast<std::size_t>(ia.width) * ia.height, 0.0f);
  for (int y = 0; y < ia.height; ++y) {
    for (int x = 0; x < ia.width; ++x) {
      if ((x < ia.width / 2) == left) mask.pixels[static_cast<std::size_t>(y) * ia.width + x] = 1.0f;
    }
  }
  DiffStats stats;
  DiffOptions options;
  options.quantisation = Quantisation::uint16;
  EXPECT_TRUE(diff_images(ia, ib, &mask, options, stats, nullptr).is_ok());
  return stats;
}

TEST(BakeGroupsEndToEnd, MatchedPartsDoNotBleedAndUnmatchedDo) {
  BleedScene scene;
  BakeReport report;
  for (const auto& [low, high, out] :
       {std::tuple{"a_low.obj", "a_high.obj", "a.png"}, std::tuple{"b_low.obj", "b_high.obj", "b.png"},
        std::tuple{"low.obj", "high.obj", "matched.png"}}) {
    const Status s = bake(scene.options(low, high, out), report);
    ASSERT_TRUE(s.is_ok()) << s.message();
  }
  ASSERT_EQ(report.groups.size(), 2u);
  EXPECT_EQ(report.groups[0].parts.name, "a");
  EXPECT_EQ(report.groups[1].parts.high_parts, (std::vector<std::string>{"b_high"}));
  EXPECT_EQ(report.scenes, 1);  // two groups share a BVH through ray masks
  EXPECT_EQ(report.high_triangles_used, report.high_triangles);
  BakeOptions unmatched = scene.options("low.obj", "high.obj", "unmatched.png");
  unmatched.match.mode = MatchMode::off;
  ASSERT_TRUE(bake(unmatched, report).is_ok());
  EXPECT_TRUE(report.groups.empty());

  const DiffStats a_matched = diff_half(scene.dir.file("matched.png"), scene.dir.file("a.png"), true);
  const DiffStats b_matched = diff_half(scene.dir.file("matched.png"), scene.dir.file("b.png"), false);
  const DiffStats a_bleed = diff_half(scene.dir.file("unmatched.png"), scene.dir.file("a.png"), true);
  std::printf("bleed: matched vs alone a: %s\n", a_matched.summary_line().c_str());
  std::printf("bleed: matched vs alone b: %s\n", b_matched.summary_line().c_str());
  std::printf("bleed: unmatched vs alone a: %s\n", a_bleed.summary_line().c_str());
  // Matched: each part's map is the part baked alone; with the same
  // distances the rays are the same, so the halves are identical.
  EXPECT_EQ(a_matched.changed_texels, 0u);
  EXPECT_EQ(b_matched.changed_texels, 0u);
  // Unmatched: a's rays pick up b's high mesh.
  EXPECT_GT(a_bleed.mean, 0.5);
  EXPECT_GT(a_bleed.share_changed(), 0.5);
}

// The same parts as glTF nodes (save_mesh writes one node per part): matched
// the same way, the same map.
TEST(BakeGroupsEndToEnd, GltfPartsMatchLikeObjParts) {
  BleedScene scene;
  BakeReport report;
  ASSERT_TRUE(bake(scene.options("low.obj", "high.obj", "obj.png"), report).is_ok());
  for (const char* name : {"low", "high"}) {
    Mesh mesh = load(scene.dir.file(std::string(name) + ".obj"), std::string(name) == "low");
    ASSERT_EQ(mesh.parts.size(), 2u);
    const Status s = save_mesh(scene.dir.file(std::string(name) + ".glb"), mesh);
    ASSERT_TRUE(s.is_ok()) << s.message();
  }
  const Status s = bake(scene.options("low.glb", "high.glb", "gltf.png"), report);
  ASSERT_TRUE(s.is_ok()) << s.message();
  ASSERT_EQ(report.groups.size(), 2u);
  EXPECT_EQ(report.groups[1].parts.low_parts, (std::vector<std::string>{"b_low"}));
  // glTF stores v flipped (1 - v, and back on load), which moves some UVs by
  // a float step: a few chart-border texels take another border sample
  // (under a degree); nothing like the bleed's 1.6 degrees on 90% of texels.
  for (const bool left : {true, false}) {
    const DiffStats d = diff_half(scene.dir.file("obj.png"), scene.dir.file("gltf.png"), left);
    std::printf("glTF vs OBJ parts, %s half: %s\n", left ? "left" : "right", d.summary_line().c_str());
    EXPECT_LT(d.mean, 0.01);
    EXPECT_LT(d.max, 1.0);
    EXPECT_LT(d.share_changed(), 0.01);
  }
}

// Auto distances are estimated per group: a's probes never see b's mesh.
// Probes are placed by the whole low mesh's area, so a group's probes are
// not exactly those of the part baked alone: equal to the 16-bit floor.
TEST(BakeGroupsEndToEnd, AutoDistancesPerGroupMatchThePartBakedAlone) {
  BleedScene scene;
  BakeReport report;
  ASSERT_TRUE(bake(scene.options("a_low.obj", "a_high.obj", "a.png", true), report).is_ok());
  const float alone_front = report.front;
  ASSERT_TRUE(bake(scene.options("low.obj", "high.obj", "matched.png", true), report).is_ok());
  ASSERT_EQ(report.groups.size(), 2u);
  std::printf("auto distances: a alone front %.6f, in the group %.6f back %.6f; b front %.6f back %.6f\n",
              alone_front, report.groups[0].front, report.groups[0].back, report.groups[1].front,
              report.groups[1].back);
  EXPECT_NEAR(report.groups[0].front, alone_front, 0.1f * alone_front);
  EXPECT_LT(report.groups[0].front, 0.001f);  // below b: the cage does not reach b's mesh
  const DiffStats a = diff_half(scene.dir.file("matched.png"), scene.dir.file("a.png"), true);
  std::printf("auto distances: matched vs alone a: %s\n", a.summary_line().c_str());
  EXPECT_LT(a.max, 0.01);
}

// One low part matched to one of two high parts: a grouped bake of a single
// group, whose scene is traced like an ungrouped one. With auto distances
// the estimate had no entry for the group and the bake read past it
// (SIGSEGV); with explicit --front/--back it never looked.
TEST(BakeGroupsEndToEnd, OneMatchedGroupWithAutoDistances) {
  BleedScene scene;
  BakeReport report;
  ASSERT_TRUE(bake(scene.options("a_low.obj", "a_high.obj", "alone.png", true), report).is_ok());
  const float alone_front = report.front;
  const Status s = bake(scene.options("a_low.obj", "high.obj", "one_group.png", true), report);
  ASSERT_TRUE(s.is_ok()) << s.message();
  ASSERT_EQ(report.groups.size(), 1u);
  EXPECT_EQ(report.groups[0].parts.high_parts, (std::vector<std::string>{"a_high"}));
  EXPECT_EQ(report.unused_high_parts, (std::vector<std::string>{"b_high"}));
  // The group's distances are its own probes' (all of them), as alone.
  EXPECT_EQ(report.groups[0].front, report.front);
  EXPECT_EQ(report.groups[0].back, report.back);
  EXPECT_EQ(report.front, alone_front);
  EXPECT_EQ(read_bytes(scene.dir.file("one_group.png")), read_bytes(scene.dir.file("alone.png")));
}

TEST(BakeGroupsEndToEnd, MasksAndScenePerGroupGiveTheSameBytes) {
  BleedScene scene;
  BakeReport report;
  BakeOptions masks = scene.options("low.obj", "high.obj", "masks.png");
  masks.samples = 4;
  masks.groups_per_scene = 32;
  ASSERT_TRUE(bake(masks, report).is_ok());
  EXPECT_EQ(report.scenes, 1);
  BakeOptions scenes = scene.options("low.obj", "high.obj", "scenes.png");
  scenes.samples = 4;
  scenes.groups_per_scene = 1;
  ASSERT_TRUE(bake(scenes, report).is_ok());
  EXPECT_EQ(report.scenes, 2);
  EXPECT_EQ(read_bytes(scene.dir.file("masks.png")), read_bytes(scene.dir.file("scenes.png")));
  // `nearest` and --ignore-backfaces take the same grouped path.
  masks.rays.hit = scenes.rays.hit = HitRule::nearest;
  masks.rays.ignore_backfaces = scenes.rays.ignore_backfaces = true;
  ASSERT_TRUE(bake(masks, report).is_ok());
  ASSERT_TRUE(bake(scenes, report).is_ok());
  EXPECT_EQ(read_bytes(scene.dir.file("masks.png")), read_bytes(scene.dir.file("scenes.png")));
}

TEST(BakeGroupsEndToEnd, CliListsUnmatchedPartsAndWritesNothing) {
  BleedScene scene;
  test::write_text(scene.dir.file("high2.obj"), plates_obj({scene.a_high}));
  const test::CommandResult r = test::run_command(
      test::cli_path() + " bake --low " + scene.dir.file("low.obj") + " --high " +
      scene.dir.file("high2.obj") + " --size 64 -o " + scene.dir.file("x.png") + " -q 2>&1");
  EXPECT_EQ(r.exit_code, 2) << r.output;
  EXPECT_NE(r.output.find("'b_low'"), std::string::npos) << r.output;
  EXPECT_FALSE(std::filesystem::exists(scene.dir.file("x.png")));
  const test::CommandResult all =
      test::run_command(test::cli_path() + " bake --low " + scene.dir.file("low.obj") + " --high " +
                        scene.dir.file("high.obj") + " --size 64 --unmatched all --low-suffix _LOW -o " +
                        scene.dir.file("x.png") + " --report " + scene.dir.file("r.json") + " -q 2>&1");
  EXPECT_EQ(all.exit_code, 0) << all.output;
  const std::string report = read_bytes(scene.dir.file("r.json"));
  EXPECT_NE(report.find("\"low_parts\""), std::string::npos);
}

// A cage file whose parts come in another order than the low file's is
// put in the low order by name; the bake equals the bake with a cage in the
// low order.
TEST(BakeGroupsEndToEnd, CagePartsAreMatchedByName) {
  BleedScene scene;
  Plate a_cage = scene.a_low, b_cage = scene.b_low;
  a_cage.name = "a_cage";
  b_cage.name = "b_cage";
  a_cage.z += 0.0012f;
  b_cage.z += 0.0012f;
  test::write_text(scene.dir.file("cage_in_order.obj"), plates_obj({a_cage, b_cage}));
  test::write_text(scene.dir.file("cage_swapped.obj"), plates_obj({b_cage, a_cage}));
  BakeReport report;
  BakeOptions in_order = scene.options("low.obj", "high.obj", "in_order.png", true);
  in_order.cage_path = scene.dir.file("cage_in_order.obj");
  Status s = bake(in_order, report);
  ASSERT_TRUE(s.is_ok()) << s.message();
  BakeOptions swapped = scene.options("low.obj", "high.obj", "swapped.png", true);
  swapped.cage_path = scene.dir.file("cage_swapped.obj");
  s = bake(swapped, report);
  ASSERT_TRUE(s.is_ok()) << s.message();
  EXPECT_EQ(read_bytes(scene.dir.file("in_order.png")), read_bytes(scene.dir.file("swapped.png")));
  Plate c_cage = a_cage;
  c_cage.name = "c_cage";
  test::write_text(scene.dir.file("cage_wrong.obj"), plates_obj({b_cage, c_cage}));
  swapped.cage_path = scene.dir.file("cage_wrong.obj");
  s = bake(swapped, report);
  ASSERT_FALSE(s.is_ok());
  EXPECT_NE(s.message().find("no cage part for low part 'a_low' (expected 'a_cage')"), std::string::npos)
      << s.message();
}

// ------------------------------------------------- several high files

// The high split across files (one subtool a file) bakes the same bytes as
// one file holding the same parts in the same order: matched by name, with
// every part against everything (--match off), and the id map of parts.
TEST(SeveralHighFiles, BakeTheSameBytesAsOneFileHoldingTheParts) {
  BleedScene scene;
  BakeReport report;
  for (const bool matched : {true, false}) {
    SCOPED_TRACE(matched);
    BakeOptions one = scene.options("low.obj", "high.obj", "one_<MAP>.png");
    one.maps = {MapKind::normal, MapKind::id};
    one.id_source = IdSource::part;
    if (!matched) one.match.mode = MatchMode::off;
    BakeOptions two = one;
    two.outputs = {{scene.dir.file("two_<MAP>.png"), PixelFormat::png16}};
    two.high_paths = {scene.dir.file("a_high.obj"), scene.dir.file("b_high.obj")};
    Status s = bake(one, report);
    ASSERT_TRUE(s.is_ok()) << s.message();
    s = bake(two, report);
    ASSERT_TRUE(s.is_ok()) << s.message();
    EXPECT_EQ(report.high_paths, two.high_paths);
    for (const char* map : {"normal", "id"}) {
      EXPECT_EQ(read_bytes(scene.dir.file(std::string("one_") + map + ".png")),
                read_bytes(scene.dir.file(std::string("two_") + map + ".png")))
          << map;
    }
  }
  // The command line (--high twice) and a job file (high = [...]) the same.
  const test::CommandResult cli =
      test::run_command(test::cli_path() + " bake --low " + scene.dir.file("low.obj") + " --high " +
                        scene.dir.file("a_high.obj") + " --high " + scene.dir.file("b_high.obj") +
                        " --size 128 --padding 0 --front 0.0015 --back 0.0005 -o " +
                        scene.dir.file("cli.png") + " --report " + scene.dir.file("cli.json") + " -q 2>&1");
  ASSERT_EQ(cli.exit_code, 0) << cli.output;
  ASSERT_TRUE(bake(scene.options("low.obj", "high.obj", "one.png"), report).is_ok());
  EXPECT_EQ(read_bytes(scene.dir.file("cli.png")), read_bytes(scene.dir.file("one.png")));
  const nlohmann::json json = nlohmann::json::parse(read_bytes(scene.dir.file("cli.json")));
  EXPECT_EQ(json["high"], nlohmann::json({scene.dir.file("a_high.obj"), scene.dir.file("b_high.obj")}));
  test::write_text(scene.dir.file("job.toml"),
                   "[[bake]]\nlow = \"low.obj\"\nhigh = [\"a_high.obj\", \"b_high.obj\"]\nsize = 128\n"
                   "padding = 0\nfront = 0.0015\nback = 0.0005\noutputs = [\"job.png\"]\n");
  const test::CommandResult job =
      test::run_command(test::cli_path() + " bake " + scene.dir.file("job.toml") + " -q 2>&1");
  ASSERT_EQ(job.exit_code, 0) << job.output;
  EXPECT_EQ(read_bytes(scene.dir.file("job.png")), read_bytes(scene.dir.file("one.png")));
}

// A file without part names is one part named after its stem (ZBrush
// exports a subtool a file, named after the subtool), so the low's parts
// match it by name.
TEST(SeveralHighFiles, AFileWithoutPartNamesIsAPartNamedAfterTheFile) {
  BleedScene scene;
  const auto unnamed = [&](const std::string& name) {
    std::string text = read_bytes(scene.dir.file(name));
    text.erase(0, text.find('\n') + 1);  // the one "o NAME" line
    ASSERT_EQ(text.find("o "), std::string::npos);
    std::filesystem::create_directories(scene.dir.file("unnamed"));
    test::write_text(scene.dir.file("unnamed/" + name), text);
  };
  unnamed("a_high.obj");
  unnamed("b_high.obj");
  Mesh mesh;
  LoadStats stats;
  ASSERT_TRUE(load_meshes({scene.dir.file("unnamed/a_high.obj"), scene.dir.file("unnamed/b_high.obj")},
                          LoadOptions{}, mesh, stats)
                  .is_ok());
  ASSERT_EQ(mesh.parts.size(), 2u);
  EXPECT_EQ(mesh.parts[0].name, "a_high");
  EXPECT_EQ(mesh.parts[1].name, "b_high");
  BakeReport report;
  BakeOptions named = scene.options("low.obj", "high.obj", "named.png");
  BakeOptions stems = scene.options("low.obj", "high.obj", "stems.png");
  stems.high_paths = {scene.dir.file("unnamed/a_high.obj"), scene.dir.file("unnamed/b_high.obj")};
  ASSERT_TRUE(bake(named, report).is_ok());
  const Status s = bake(stems, report);
  ASSERT_TRUE(s.is_ok()) << s.message();
  EXPECT_EQ(read_bytes(scene.dir.file("named.png")), read_bytes(scene.dir.file("stems.png")));
}

// A missing or broken second file is exit 2 naming it, before anything is
// written; so is a group naming a part no file has.
TEST(SeveralHighFiles, AMistakeInAnyFileNamesThatFileAndWritesNothing) {
  BleedScene scene;
  test::write_text(scene.dir.file("broken.obj"), "v 0 0 0\nf 1 2 3\n");
  for (const std::string& second : {std::string("missing.obj"), std::string("broken.obj")}) {
    SCOPED_TRACE(second);
    const test::CommandResult r =
        test::run_command(test::cli_path() + " bake --low " + scene.dir.file("low.obj") + " --high " +
                          scene.dir.file("a_high.obj") + " --high " + scene.dir.file(second) +
                          " --size 64 -o " + scene.dir.file("x.png") + " -q 2>&1");
    EXPECT_EQ(r.exit_code, 2) << r.output;
    EXPECT_NE(r.output.find(scene.dir.file(second)), std::string::npos) << r.output;
    EXPECT_FALSE(std::filesystem::exists(scene.dir.file("x.png")));
  }
  // b_low has no b_high among these files: the message names both files.
  const test::CommandResult r =
      test::run_command(test::cli_path() + " bake --low " + scene.dir.file("low.obj") + " --high " +
                        scene.dir.file("a_high.obj") + " --high " + scene.dir.file("a_high.obj") +
                        " --size 64 -o " + scene.dir.file("x.png") + " -q 2>&1");
  EXPECT_EQ(r.exit_code, 2) << r.output;
  EXPECT_NE(r.output.find("'b_low'"), std::string::npos) << r.output;
  EXPECT_FALSE(std::filesystem::exists(scene.dir.file("x.png")));
}

// ------------------------------------------------------- texture sets

// A low of three plates in two materials ("metal" twice, "rubber/1"), UVs
// on a grid of 1/64 (exact in float, also shifted by a whole tile), over a
// bumpy high.
struct SetScene {
  test::TempDir dir;
  std::vector<Plate> low{{"a", 8, 0.0f, 0.1f, 0.0f, 0.1f, 0.0f, 0.0625f, 0.4375f, 0.0625f, 0.4375f, {}, {}},
                         {"b", 8, 0.2f, 0.3f, 0.0f, 0.1f, 0.0f, 0.5625f, 0.9375f, 0.0625f, 0.4375f, {}, {}},
                         {"c", 8, 0.4f, 0.5f, 0.0f, 0.1f, 0.0f, 0.0625f, 0.4375f, 0.5625f, 0.9375f, {}, {}}};
  std::vector<std::string> materials{"metal", "rubber/1", "metal"};
  SetScene() {
    Plate high{
        "high", 150,    -0.05f,
        0.55f,  -0.05f, 0.15f,
        0.0f,   0,      0,
        0,      0,      [](float x, float y) { return 0.002f * std::sin(90.0f * x) * std::cos(70.0f * y); },
        {}};
    test::write_text(dir.file("high.obj"), plates_obj({high}));
    test::write_text(dir.file("hero_low.obj"), plates_obj(low, materials));
  }
  BakeOptions options(const std::string& low_file, const std::string& out) const {
    BakeOptions o;
    o.low_path = dir.file(low_file);
    o.high_paths = {dir.file("high.obj")};
    o.outputs = {{dir.file(out), PixelFormat::png16}};
    o.maps = {MapKind::normal, MapKind::ao};
    o.ao_rays = 8;
    o.width = o.height = 96;
    o.rays.front = o.rays.back = {Distance::Kind::absolute, 0.01f};
    return o;
  }
};

// Each set's maps equal the maps of the same low with the other set's
// triangles moved to another UV tile (the <UDIM> bake of that file), and
// each set gets its packs.
TEST(TextureSets, EachSetEqualsTheBakeWithTheOtherSetInAnotherTile) {
  SetScene scene;
  BakeReport report;
  BakeOptions sets = scene.options("hero_low.obj", "s_<SET>_<MAP>.png");
  PackSpec pack;
  ASSERT_TRUE(parse_pack(scene.dir.file("p_<SET>.png") + "=r:ao,g:ao,b:ao", pack).is_ok());
  sets.packs = {pack};
  Status s = bake(sets, report);
  ASSERT_TRUE(s.is_ok()) << s.message();
  ASSERT_EQ(report.tiles.size(), 2u);
  EXPECT_EQ(report.tiles[0].set, "metal");
  EXPECT_EQ(report.tiles[1].set, "rubber/1");
  EXPECT_TRUE(std::filesystem::exists(scene.dir.file("p_metal.png")));
  EXPECT_TRUE(std::filesystem::exists(scene.dir.file("p_rubber_1.png")));
  // metal in tile 1001, rubber in 1002.
  std::vector<Plate> tiled = scene.low;
  tiled[1].uv_shift = {-1.0f, 0.0f};
  test::write_text(scene.dir.file("tiled_low.obj"), plates_obj(tiled, scene.materials));
  s = bake(scene.options("tiled_low.obj", "t_<UDIM>_<MAP>.png"), report);
  ASSERT_TRUE(s.is_ok()) << s.message();
  for (const char* map : {"normal", "ao"}) {
    SCOPED_TRACE(map);
    const std::string metal = read_bytes(scene.dir.file(std::string("s_metal_") + map + ".png"));
    const std::string rubber = read_bytes(scene.dir.file(std::string("s_rubber_1_") + map + ".png"));
    EXPECT_NE(metal, rubber);
    EXPECT_EQ(metal, read_bytes(scene.dir.file(std::string("t_1001_") + map + ".png")));
    EXPECT_EQ(rubber, read_bytes(scene.dir.file(std::string("t_1002_") + map + ".png")));
  }
  // <LOW> and <SET> from the command line: the low file's stem.
  const test::CommandResult cli =
      test::run_command(test::cli_path() + " bake --low " + scene.dir.file("hero_low.obj") + " --high " +
                        scene.dir.file("high.obj") + " --size 96 --front 0.01 --back 0.01 --map normal -o '" +
                        scene.dir.file("<LOW>_<SET>.png") + "' -q 2>&1");
  ASSERT_EQ(cli.exit_code, 0) << cli.output;
  EXPECT_TRUE(std::filesystem::exists(scene.dir.file("hero_low_metal.png")));
  EXPECT_TRUE(std::filesystem::exists(scene.dir.file("hero_low_rubber_1.png")));
}

TEST(TextureSets, MistakesAreExit2AndWriteNothing) {
  SetScene scene;
  std::vector<std::string> clash = scene.materials;
  clash[2] = "rubber_1";
  test::write_text(scene.dir.file("plain_low.obj"), plates_obj(scene.low));
  test::write_text(scene.dir.file("clash_low.obj"), plates_obj(scene.low, clash));
  const auto run = [&](const std::string& low, const std::string& outputs) {
    return test::run_command(test::cli_path() + " bake --low " + scene.dir.file(low) + " --high " +
                             scene.dir.file("high.obj") + " --size 32 --front 0.01 --back 0.01 " + outputs +
                             " -q 2>&1");
  };
  const std::string x = scene.dir.file("x_<SET>.png");
  struct Case {
    std::string low, outputs, expected;
  };
  for (const Case& c :
       {Case{"plain_low.obj", "-o '" + x + "'", "has no named materials"},
        Case{"clash_low.obj", "-o '" + x + "'", "'rubber/1' and 'rubber_1'"},
        Case{"hero_low.obj", "-o '" + x + "' -o " + scene.dir.file("y.png"), "would be written once"},
        Case{"hero_low.obj", "-o '" + x + "' --tile 1/2 --tile-file " + scene.dir.file("t.nmt"),
             "cannot be baked in tiles"}}) {
    SCOPED_TRACE(c.low + " " + c.outputs);
    const test::CommandResult r = run(c.low, c.outputs);
    EXPECT_EQ(r.exit_code, 2) << r.output;
    EXPECT_NE(r.output.find(c.expected), std::string::npos) << r.output;
    for (const auto& entry : std::filesystem::directory_iterator(scene.dir.path())) {
      EXPECT_NE(entry.path().extension(), ".png") << entry.path();
      EXPECT_NE(entry.path().extension(), ".nmt") << entry.path();
    }
  }
}

// -------------------------------------------------------------- UDIM

TEST(Udim, TilePathsAndOffsets) {
  EXPECT_TRUE(has_udim_token("a/n.<UDIM>.png"));
  EXPECT_EQ(udim_path("a/n.<UDIM>.png", 1012), "a/n.1012.png");
  EXPECT_EQ(udim_offset(1001), glm::vec2(0, 0));
  EXPECT_EQ(udim_offset(1012), glm::vec2(1, 1));
  EXPECT_EQ(udim_offset(1010), glm::vec2(9, 0));
}

// Three plates side by side in space, their UVs in tiles 1001, 1002 and
// 1011. Each tile's map equals that plate baked alone with its UVs moved
// into [0, 1]^2, byte for byte (fixed distances: auto ones would be
// estimated from other probes).
TEST(Udim, EachTileEqualsTheTileBakedAlone) {
  test::TempDir dir;
  const auto bumps = [](float x, float y) { return 0.02f * std::sin(9.0f * x) * std::sin(7.0f * y); };
  std::vector<Plate> low, high;
  const int tiles[3] = {1001, 1002, 1011};
  for (int k = 0; k < 3; ++k) {
    const glm::vec2 o = udim_offset(tiles[k]);
    const float x0 = 1.2f * static_cast<float>(k);
    low.push_back({"p" + std::to_string(k),
                   6,
                   x0,
                   x0 + 1,
                   0,
                   1,
                   0,
                   o.x + 0.05f,
                   o.x + 0.95f,
                   o.y + 0.05f,
                   o.y + 0.95f,
                   {}});
    high.push_back({"h" + std::to_string(k), 64, x0, x0 + 1, 0, 1, 0, 0, 0, 0, 0, bumps});
  }
  test::write_text(dir.file("low.obj"), plates_obj(low));
  test::write_text(dir.file("high.obj"), plates_obj(high));
  BakeOptions o;
  o.low_path = dir.file("low.obj");
  o.high_paths = {dir.file("high.obj")};
  o.width = o.height = 96;
  o.rays.front = {Distance::Kind::absolute, 0.05f};
  o.rays.back = {Distance::Kind::absolute, 0.05f};
  o.outputs = {{dir.file("n.<UDIM>.png"), PixelFormat::png16},
               {dir.file("n_<UDIM>.exr"), PixelFormat::exr_half}};
  BakeReport report;
  Status s = bake(o, report);
  ASSERT_TRUE(s.is_ok()) << s.message();
  ASSERT_EQ(report.tiles.size(), 3u);
  EXPECT_EQ(report.outputs.size(), 6u);
  for (int k = 0; k < 3; ++k) EXPECT_EQ(report.tiles[k].tile, tiles[k]);
  for (int k = 0; k < 3; ++k) {
    Plate alone = low[k];
    alone.uv_shift = udim_offset(tiles[k]);  // the baker's own shift, in floats
    test::write_text(dir.file("alone.obj"), plates_obj({alone}));
    BakeOptions a = o;
    a.low_path = dir.file("alone.obj");
    a.outputs = {{dir.file("alone.png"), PixelFormat::png16}};
    s = bake(a, report);
    ASSERT_TRUE(s.is_ok()) << s.message();
    const std::string tile_map = dir.file("n." + std::to_string(tiles[k]) + ".png");
    const std::string tile_exr = dir.file("n_" + std::to_string(tiles[k]) + ".exr");
    EXPECT_TRUE(std::filesystem::exists(tile_exr));
    const std::string tile_bytes = read_bytes(tile_map);
    EXPECT_FALSE(tile_bytes.empty()) << tile_map;
    if (tile_bytes != read_bytes(dir.file("alone.png"))) {
      const DiffStats d = diff_half(tile_map, dir.file("alone.png"), true);
      ADD_FAILURE() << "tile " << tiles[k] << " differs from the tile baked alone: " << d.summary_line();
    }
  }
}

TEST(Udim, UvsOutsideTheUnitSquareNeedTheToken) {
  test::TempDir dir;
  test::write_text(dir.file("low.obj"), plates_obj({{"a", 2, 0, 1, 0, 1, 0, 1.1f, 1.9f, 0.1f, 0.9f, {}}}));
  test::write_text(dir.file("high.obj"), plates_obj({{"b", 4, 0, 1, 0, 1, 0, 0, 0, 0, 0, {}}}));
  BakeOptions o;
  o.low_path = dir.file("low.obj");
  o.high_paths = {dir.file("high.obj")};
  o.width = o.height = 32;
  o.outputs = {{dir.file("n.png"), PixelFormat::png16}};
  BakeReport report;
  Status s = bake(o, report);
  ASSERT_FALSE(s.is_ok());
  EXPECT_EQ(s.code(), StatusCode::bad_input);
  EXPECT_NE(s.message().find("tiles 1002"), std::string::npos) << s.message();
  EXPECT_NE(s.message().find("<UDIM>"), std::string::npos) << s.message();
  EXPECT_FALSE(std::filesystem::exists(dir.file("n.png")));
  // Negative UVs are in no tile at all.
  test::write_text(dir.file("neg.obj"), plates_obj({{"a", 2, 0, 1, 0, 1, 0, -0.9f, -0.1f, 0.1f, 0.9f, {}}}));
  o.low_path = dir.file("neg.obj");
  o.outputs = {{dir.file("n.<UDIM>.png"), PixelFormat::png16}};
  s = bake(o, report);
  ASSERT_FALSE(s.is_ok());
  EXPECT_NE(s.message().find("outside every UDIM tile"), std::string::npos) << s.message();
}

}  // namespace
}  // namespace nmbake
