// Tests of the glTF and Assimp (FBX, Collada, 3DS, STL) loaders: tiny glTF
// files written here with exact expectations (node hierarchies, embedded
// buffers, every rejection), files no one here wrote (Debian's
// assimp-testmodels), FBX files made with Assimp's exporter, the glTF writer
// round trip, and bakes of the same asset as OBJ and as glTF.
#include <assimp/scene.h>
#include <gtest/gtest.h>
#include <sys/stat.h>

#include <algorithm>
#include <assimp/Exporter.hpp>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <functional>
#include <glm/geometric.hpp>
#include <iterator>
#include <limits>
#include <nlohmann/json.hpp>
#include <numbers>
#include <set>
#include <string>
#include <vector>

#include "fbx_write.hpp"
#include "nmbake/job.hpp"
#include "nmbake/load.hpp"
#include "nmbake/mesh.hpp"
#include "nmbake/tangents.hpp"
#include "test_util.hpp"

namespace nmbake {
namespace {

namespace fs = std::filesystem;
using test::TempDir;
using test::write_text;
using json = nlohmann::json;

struct Loaded {
  Status status;
  Mesh mesh;
  LoadStats stats;
};

Loaded load(const std::string& path, LoadOptions options = {}) {
  Loaded result;
  result.status = load_mesh(path, options, result.mesh, result.stats);
  return result;
}

bool contains(const std::string& text, const std::string& part) {
  return text.find(part) != std::string::npos;
}

void expect_near(const glm::vec3& actual, const glm::vec3& expected, float tolerance = 1e-6f) {
  EXPECT_NEAR(actual.x, expected.x, tolerance);
  EXPECT_NEAR(actual.y, expected.y, tolerance);
  EXPECT_NEAR(actual.z, expected.z, tolerance);
}

std::string base64(const std::string& bytes) {
  static const char* const kAlphabet = "ABCDEFGHIJKLMNOPQRSTUVWXYZabcdefghijklmnopqrstuvwxyz0123456789+/";
  std::string out;
  std::size_t i = 0;
  for (; i + 2 < bytes.size(); i += 3) {
    const unsigned v = (static_cast<unsigned char>(bytes[i]) << 16) |
                       (static_cast<unsigned char>(bytes[i + 1]) << 8) |
                       static_cast<unsigned char>(bytes[i + 2]);
    for (int s = 18; s >= 0; s -= 6) out.push_back(kAlphabet[(v >> s) & 63]);
  }
  if (i < bytes.size()) {
    unsigned v = static_cast<unsigned char>(bytes[i]) << 16;
    if (i + 1 < bytes.size()) v |= static_cast<unsigned char>(bytes[i + 1]) << 8;
    out.push_back(kAlphabet[(v >> 18) & 63]);
    out.push_back(kAlphabet[(v >> 12) & 63]);
    out.push_back(i + 1 < bytes.size() ? kAlphabet[(v >> 6) & 63] : '=');
    out.push_back('=');
  }
  return out;
}

// A glTF document written by hand: a binary buffer of accessors and the JSON
// that describes it, so each test states exactly what the file holds.
class GltfFile {
 public:
  GltfFile() {
    doc_["asset"] = {{"version", "2.0"}};
    doc_["buffers"] = json::array();
    doc_["bufferViews"] = json::array();
    doc_["accessors"] = json::array();
    doc_["meshes"] = json::array();
    doc_["nodes"] = json::array();
  }
  // Float accessor of `components` per element (VEC2, VEC3, VEC4, SCALAR).
  int floats(const std::vector<float>& values, int components) {
    static const char* const kTypes[] = {"", "SCALAR", "VEC2", "VEC3", "VEC4"};
    const int view = add_view(values.data(), values.size() * sizeof(float));
    return add_accessor(view, 5126, kTypes[components], values.size() / static_cast<std::size_t>(components));
  }
  int indices(const std::vector<std::uint32_t>& values) {
    const int view = add_view(values.data(), values.size() * sizeof(std::uint32_t));
    return add_accessor(view, 5125, "SCALAR", values.size());
  }
  int unsigned_shorts(const std::vector<std::uint16_t>& values, int components, bool normalized) {
    static const char* const kTypes[] = {"", "SCALAR", "VEC2", "VEC3", "VEC4"};
    const int view = add_view(values.data(), values.size() * sizeof(std::uint16_t));
    const int a =
        add_accessor(view, 5123, kTypes[components], values.size() / static_cast<std::size_t>(components));
    doc_["accessors"][static_cast<std::size_t>(a)]["normalized"] = normalized;
    return a;
  }
  // A mesh of one primitive; attributes maps names to accessors.
  int mesh(const json& attributes, int index_accessor, const std::string& name = "", int mode = 4) {
    json primitive = {{"attributes", attributes}, {"mode", mode}};
    if (index_accessor >= 0) primitive["indices"] = index_accessor;
    json m = {{"primitives", json::array({primitive})}};
    if (!name.empty()) m["name"] = name;
    doc_["meshes"].push_back(m);
    return static_cast<int>(doc_["meshes"].size()) - 1;
  }
  int node(const json& fields) {
    doc_["nodes"].push_back(fields);
    return static_cast<int>(doc_["nodes"].size()) - 1;
  }
  void scene(const std::vector<int>& roots) {
    doc_["scenes"] = json::array({{{"nodes", roots}}});
    doc_["scene"] = 0;
  }
  json& doc() { return doc_; }

  // .gltf with the buffer beside it (bin_name), or embedded when empty.
  void write_gltf(const TempDir& dir, const std::string& name, const std::string& bin_name = "") {
    json doc = doc_;
    if (bin_name.empty()) {
      doc["buffers"] = json::array({{{"byteLength", bytes_.size()},
                                     {"uri", "data:application/octet-stream;base64," + base64(bytes_)}}});
    } else {
      doc["buffers"] = json::array({{{"byteLength", bytes_.size()}, {"uri", bin_name}}});
      std::ofstream(dir.file(bin_name), std::ios::binary)
          .write(bytes_.data(), static_cast<std::streamsize>(bytes_.size()));
    }
    write_text(dir.file(name), doc.dump());
  }

 private:
  int add_view(const void* data, std::size_t size) {
    while (bytes_.size() % 4 != 0) bytes_.push_back('\0');
    doc_["bufferViews"].push_back({{"buffer", 0}, {"byteOffset", bytes_.size()}, {"byteLength", size}});
    bytes_.append(static_cast<const char*>(data), size);
    return static_cast<int>(doc_["bufferViews"].size()) - 1;
  }
  int add_accessor(int view, int component_type, const char* type, std::size_t count) {
    doc_["accessors"].push_back(
        {{"bufferView", view}, {"componentType", component_type}, {"type", type}, {"count", count}});
    return static_cast<int>(doc_["accessors"].size()) - 1;
  }

  json doc_;
  std::string bytes_;
};

// One triangle in the xy plane, counter-clockwise seen from +z, with UVs.
struct Triangle {
  int positions, normals, uvs, tangents, indices;
};
Triangle add_triangle(GltfFile& file) {
  Triangle t{};
  t.positions = file.floats({0, 0, 0, 1, 0, 0, 0, 1, 0}, 3);
  t.normals = file.floats({0, 0, 1, 0, 0, 1, 0, 0, 1}, 3);
  t.uvs = file.floats({0.0f, 0.0f, 1.0f, 0.0f, 0.0f, 0.25f}, 2);
  t.tangents = file.floats({1, 0, 0, 1, 1, 0, 0, 1, 1, 0, 0, 1}, 4);
  t.indices = file.indices({0, 1, 2});
  return t;
}

glm::vec3 face_normal(const Mesh& mesh, std::size_t triangle) {
  const glm::vec3 a = mesh.positions[mesh.indices[3 * triangle]];
  const glm::vec3 b = mesh.positions[mesh.indices[3 * triangle + 1]];
  const glm::vec3 c = mesh.positions[mesh.indices[3 * triangle + 2]];
  return glm::normalize(glm::cross(b - a, c - a));
}

TEST(LoadGltf, NodeHierarchyWithRotationAndScaleGivesWorldSpace) {
  TempDir dir;
  GltfFile file;
  const Triangle t = add_triangle(file);
  const int mesh =
      file.mesh({{"POSITION", t.positions}, {"NORMAL", t.normals}, {"TEXCOORD_0", t.uvs}}, t.indices, "tri");
  // Parent: a quarter turn about +z (quaternion x, y, z, w) and scale 2;
  // child: moved by (1, 0, 0) in the parent's frame, non-uniform scale.
  const int child =
      file.node({{"name", "blade"}, {"mesh", mesh}, {"translation", {1, 0, 0}}, {"scale", {1, 3, 1}}});
  const int parent = file.node({{"name", "handle"},
                                {"children", {child}},
                                {"rotation", {0, 0, std::sqrt(0.5), std::sqrt(0.5)}},
                                {"scale", {2, 2, 2}}});
  file.scene({parent});
  file.write_gltf(dir, "tree.gltf", "tree.bin");
  const Loaded r = load(dir.file("tree.gltf"));
  ASSERT_TRUE(r.status.is_ok()) << r.status.message();
  ASSERT_EQ(r.mesh.vertex_count(), 3u);
  ASSERT_EQ(r.mesh.triangle_count(), 1u);
  // world = R(90) * S(2) * T(1,0,0) * S(1,3,1): local (x, y) -> (-6y, 2 + 2x).
  expect_near(r.mesh.positions[0], {0, 2, 0});
  expect_near(r.mesh.positions[1], {0, 4, 0});
  expect_near(r.mesh.positions[2], {-6, 2, 0});
  // Normals by the inverse transpose, left unnormalised (the caller does
  // that): z stays z, scaled by 1/2.
  expect_near(r.mesh.normals[0], {0, 0, 0.5f});
  // glTF's v points down the image: v' = 1 - v.
  EXPECT_FLOAT_EQ(r.mesh.uvs[2].y, 0.75f);
  EXPECT_FLOAT_EQ(r.mesh.uvs[0].y, 1.0f);
  ASSERT_EQ(r.mesh.parts.size(), 1u);
  EXPECT_EQ(r.mesh.parts[0].name, "blade");
  EXPECT_EQ(r.stats.unit_meters, 1.0);
  // The external buffer counts into the bytes read.
  EXPECT_EQ(r.stats.bytes, fs::file_size(dir.file("tree.gltf")) + fs::file_size(dir.file("tree.bin")));
}

TEST(LoadGltf, MatrixNodesMirrorFlipsWindingAndTangentSign) {
  TempDir dir;
  GltfFile file;
  const Triangle t = add_triangle(file);
  const int mesh = file.mesh(
      {{"POSITION", t.positions}, {"NORMAL", t.normals}, {"TEXCOORD_0", t.uvs}, {"TANGENT", t.tangents}},
      t.indices);
  // Column-major: x -> -x (a mirror), then translated by (0, 0, 5).
  file.node({{"name", "plain"}, {"mesh", mesh}});
  file.node(
      {{"name", "mirrored"}, {"mesh", mesh}, {"matrix", {-1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1, 0, 0, 0, 5, 1}}});
  file.scene({0, 1});
  file.write_gltf(dir, "mirror.gltf");
  LoadOptions options;
  options.keep_tangents = true;
  const Loaded r = load(dir.file("mirror.gltf"), options);
  ASSERT_TRUE(r.status.is_ok()) << r.status.message();
  ASSERT_EQ(r.mesh.triangle_count(), 2u);
  ASSERT_EQ(r.mesh.parts.size(), 2u);
  EXPECT_EQ(r.mesh.parts[1].name, "mirrored");
  EXPECT_EQ(r.mesh.parts[1].first_triangle, 1u);
  // Both triangles still face +z: the mirror's winding was flipped back.
  expect_near(face_normal(r.mesh, 0), {0, 0, 1});
  expect_near(face_normal(r.mesh, 1), {0, 0, 1});
  expect_near(r.mesh.positions[4], {-1, 0, 5});
  ASSERT_EQ(r.mesh.tangents.size(), 6u);
  EXPECT_EQ(r.mesh.tangents[0], glm::vec4(1, 0, 0, 1));
  // The tangent follows the mirror (x -> -x) and its sign flips.
  EXPECT_EQ(r.mesh.tangents[3], glm::vec4(-1, 0, 0, -1));
}

TEST(LoadGltf, EmbeddedAndBinaryBuffersLoadTheSameMesh) {
  TempDir dir;
  GltfFile file;
  const Triangle t = add_triangle(file);
  const int mesh = file.mesh({{"POSITION", t.positions}, {"TEXCOORD_0", t.uvs}}, t.indices, "only");
  file.node({{"mesh", mesh}});
  file.scene({0});
  file.write_gltf(dir, "embedded.gltf");
  const Loaded embedded = load(dir.file("embedded.gltf"));
  ASSERT_TRUE(embedded.status.is_ok()) << embedded.status.message();
  EXPECT_EQ(embedded.stats.bytes, fs::file_size(dir.file("embedded.gltf")));
  // The mesh's name names an unnamed node's part.
  ASSERT_EQ(embedded.mesh.parts.size(), 1u);
  EXPECT_EQ(embedded.mesh.parts[0].name, "only");
  EXPECT_FALSE(embedded.mesh.has_normals());
  // Our writer's .glb of it reads back the same.
  ASSERT_TRUE(save_mesh(dir.file("again.glb"), embedded.mesh).is_ok());
  const Loaded glb = load(dir.file("again.glb"));
  ASSERT_TRUE(glb.status.is_ok()) << glb.status.message();
  EXPECT_EQ(glb.mesh.positions, embedded.mesh.positions);
  EXPECT_EQ(glb.mesh.uvs, embedded.mesh.uvs);
  EXPECT_EQ(glb.mesh.indices, embedded.mesh.indices);
  ASSERT_EQ(glb.mesh.parts.size(), 1u);
  EXPECT_EQ(glb.mesh.parts[0].name, "only");
}

// COLOR_0 (the vertex-color map): float RGBA and normalised unsigned-short
// RGB, linear in the file, come back sRGB-encoded; a primitive without it is
// white; a file without any has no colours; a 2-component COLOR_0 is an error.
TEST(LoadGltf, VertexColoursAreReadAndEncoded) {
  TempDir dir;
  GltfFile file;
  const int indices = file.indices({0, 1, 2});
  const int positions_a = file.floats({0, 0, 0, 1, 0, 0, 0, 1, 0}, 3);
  const int positions_b = file.floats({5, 0, 0, 6, 0, 0, 5, 1, 0}, 3);
  const int positions_c = file.floats({9, 0, 0, 10, 0, 0, 9, 1, 0}, 3);
  const int rgba =
      file.floats({0.0f, 0.5f, 1.0f, 0.25f, 1.0f, 1.0f, 1.0f, 1.0f, 0.002f, 0.0f, 0.0f, 1.0f}, 4);
  const int rgb16 = file.unsigned_shorts({65535, 32768, 0, 0, 0, 0, 65535, 65535, 65535}, 3, true);
  const int mesh_a = file.mesh({{"POSITION", positions_a}, {"COLOR_0", rgba}}, indices, "a");
  const int mesh_b = file.mesh({{"POSITION", positions_b}}, indices, "b");
  const int mesh_c = file.mesh({{"POSITION", positions_c}, {"COLOR_0", rgb16}}, indices, "c");
  file.node({{"mesh", mesh_a}});
  file.node({{"mesh", mesh_b}});
  file.node({{"mesh", mesh_c}});
  file.scene({0, 1, 2});
  file.write_gltf(dir, "colours.gltf");
  LoadOptions options;
  options.keep_colors = true;
  const Loaded loaded = load(dir.file("colours.gltf"), options);
  ASSERT_TRUE(loaded.status.is_ok()) << loaded.status.message();
  ASSERT_EQ(loaded.mesh.colors.size(), loaded.mesh.positions.size());
  const float half = 1.055f * std::pow(0.5f, 1.0f / 2.4f) - 0.055f;  // 0.7354
  const float half16 = 1.055f * std::pow(32768.0f / 65535.0f, 1.0f / 2.4f) - 0.055f;
  const auto colour_at = [&](glm::vec3 p) {
    for (std::size_t v = 0; v < loaded.mesh.positions.size(); ++v) {
      if (loaded.mesh.positions[v] == p) return loaded.mesh.colors[v];
    }
    ADD_FAILURE() << "no vertex at " << p.x << " " << p.y;
    return glm::vec4(-1.0f);
  };
  const auto expect_colour = [](glm::vec4 actual, glm::vec4 expected) {
    for (int c = 0; c < 4; ++c) EXPECT_NEAR(actual[c], expected[c], 1e-5f) << "channel " << c;
  };
  expect_colour(colour_at({0, 0, 0}), {0.0f, half, 1.0f, 0.25f});
  expect_colour(colour_at({1, 0, 0}), {1.0f, 1.0f, 1.0f, 1.0f});
  expect_colour(colour_at({0, 1, 0}), {12.92f * 0.002f, 0.0f, 0.0f, 1.0f});  // the curve's linear toe
  expect_colour(colour_at({5, 0, 0}), {1.0f, 1.0f, 1.0f, 1.0f});             // no COLOR_0: white
  expect_colour(colour_at({9, 0, 0}), {1.0f, half16, 0.0f, 1.0f});
  expect_colour(colour_at({9, 1, 0}), {1.0f, 1.0f, 1.0f, 1.0f});
  // Not asked for: none read.
  const Loaded plain = load(dir.file("colours.gltf"));
  ASSERT_TRUE(plain.status.is_ok());
  EXPECT_FALSE(plain.mesh.has_colors());

  GltfFile none;
  const Triangle t = add_triangle(none);
  none.node({{"mesh", none.mesh({{"POSITION", t.positions}}, t.indices)}});
  none.scene({0});
  none.write_gltf(dir, "none.gltf");
  const Loaded without = load(dir.file("none.gltf"), options);
  ASSERT_TRUE(without.status.is_ok());
  EXPECT_FALSE(without.mesh.has_colors());

  GltfFile broken;
  const Triangle u = add_triangle(broken);
  const int two = broken.floats({0, 0, 1, 1, 0, 1}, 2);
  broken.node({{"mesh", broken.mesh({{"POSITION", u.positions}, {"COLOR_0", two}}, u.indices)}});
  broken.scene({0});
  broken.write_gltf(dir, "broken.gltf");
  const Loaded bad = load(dir.file("broken.gltf"), options);
  EXPECT_EQ(bad.status.code(), StatusCode::bad_input);
  EXPECT_TRUE(contains(bad.status.message(), "COLOR_0 has 2 components per element")) << bad.status.message();
  EXPECT_TRUE(contains(bad.status.message(), dir.file("broken.gltf"))) << bad.status.message();
}

TEST(LoadGltf, StripsFansNormalizedUvsAndSparseAccessors) {
  TempDir dir;
  GltfFile file;
  // Four vertices of a unit square, counter-clockwise.
  const int positions = file.floats({0, 0, 0, 1, 0, 0, 1, 1, 0, 0, 1, 0}, 3);
  const int uvs = file.unsigned_shorts({0, 65535, 65535, 65535, 65535, 0, 0, 0}, 2, true);
  const int strip_order = file.indices({0, 1, 3, 2});
  const int fan_order = file.indices({0, 1, 2, 3});
  const int strip = file.mesh({{"POSITION", positions}, {"TEXCOORD_0", uvs}}, strip_order, "strip", 5);
  const int fan = file.mesh({{"POSITION", positions}, {"TEXCOORD_0", uvs}}, fan_order, "fan", 6);
  const int points = file.mesh({{"POSITION", positions}}, -1, "points", 0);
  file.node({{"mesh", strip}});
  file.node({{"mesh", fan}});
  file.node({{"mesh", points}});
  file.scene({0, 1, 2});
  // Sparse: the fan's positions moved by substitution of vertex 2.
  json sparse_positions = file.doc()["accessors"][static_cast<std::size_t>(positions)];
  const int values_view = file.floats({2, 2, 0}, 3);
  const int index_view = file.indices({2});
  sparse_positions["sparse"] = {
      {"count", 1},
      {"indices",
       {{"bufferView", file.doc()["accessors"][static_cast<std::size_t>(index_view)]["bufferView"]},
        {"componentType", 5125}}},
      {"values",
       {{"bufferView", file.doc()["accessors"][static_cast<std::size_t>(values_view)]["bufferView"]}}}};
  file.doc()["accessors"].push_back(sparse_positions);
  file.doc()["meshes"][static_cast<std::size_t>(fan)]["primitives"][0]["attributes"]["POSITION"] =
      file.doc()["accessors"].size() - 1;
  file.write_gltf(dir, "modes.gltf", "modes.bin");
  const Loaded r = load(dir.file("modes.gltf"));
  ASSERT_TRUE(r.status.is_ok()) << r.status.message();
  ASSERT_EQ(r.mesh.triangle_count(), 4u);
  // Strip 0 1 3 2: triangles (0 1 3) and, odd ones reversed as the
  // specification orders them, (1 2 3); both counter-clockwise.
  const std::vector<std::uint32_t> strip_expected{0, 1, 3, 1, 2, 3};
  EXPECT_TRUE(std::equal(strip_expected.begin(), strip_expected.end(), r.mesh.indices.begin()));
  // Fan 0 1 2 3: (0 1 2) (0 2 3), the OBJ loader's diagonal; vertex 2 sparse.
  const std::vector<std::uint32_t> fan_expected{4, 5, 6, 4, 6, 7};
  EXPECT_TRUE(std::equal(fan_expected.begin(), fan_expected.end(), r.mesh.indices.begin() + 6));
  expect_near(r.mesh.positions[6], {2, 2, 0});
  // Normalized unsigned shorts: 65535 is 1, then v' = 1 - v.
  EXPECT_EQ(r.mesh.uvs[1], glm::vec2(1.0f, 0.0f));
  EXPECT_EQ(r.mesh.uvs[2], glm::vec2(1.0f, 1.0f));
  // The points primitive adds no triangles; its four points are counted.
  EXPECT_EQ(r.stats.degenerate_faces, 4u);
  ASSERT_EQ(r.mesh.parts.size(), 2u);
  EXPECT_EQ(r.mesh.parts[0].name, "strip");
  EXPECT_EQ(r.mesh.parts[1].name, "fan");
}

// A valid one-triangle file, then one edit that breaks it.
Loaded load_broken(const TempDir& dir, const std::function<void(GltfFile&, const Triangle&)>& edit,
                   LoadOptions options = {}, bool external = false) {
  GltfFile file;
  const Triangle t = add_triangle(file);
  file.mesh({{"POSITION", t.positions}, {"NORMAL", t.normals}, {"TEXCOORD_0", t.uvs}}, t.indices, "tri");
  file.node({{"name", "body"}, {"mesh", 0}});
  file.scene({0});
  edit(file, t);
  file.write_gltf(dir, "broken.gltf", external ? "broken.bin" : "");
  return load(dir.file("broken.gltf"), options);
}

void expect_bad_input(const Loaded& r, const std::string& path, const std::vector<std::string>& parts) {
  ASSERT_FALSE(r.status.is_ok());
  EXPECT_EQ(r.status.code(), StatusCode::bad_input) << r.status.message();
  EXPECT_TRUE(contains(r.status.message(), path)) << r.status.message();
  for (const std::string& part : parts) EXPECT_TRUE(contains(r.status.message(), part)) << r.status.message();
  EXPECT_EQ(r.mesh.triangle_count(), 0u);
}

TEST(LoadGltf, RejectsBrokenFilesNamingFilePartAndReason) {
  TempDir dir;
  const std::string path = dir.file("broken.gltf");
  // Sanity: unbroken, it loads.
  ASSERT_TRUE(load_broken(dir, [](GltfFile&, const Triangle&) {}).status.is_ok());
  expect_bad_input(
      load_broken(dir, [](GltfFile& f, const Triangle&) { f.doc()["accessors"][4]["count"] = 4; }), path,
      {"part 'body'", "do not fit"});
  // A hostile count is refused before anything is sized from it.
  expect_bad_input(
      load_broken(dir,
                  [](GltfFile& f, const Triangle&) { f.doc()["accessors"][0]["count"] = 1000000000000; }),
      path, {"POSITION", "do not fit"});
  expect_bad_input(load_broken(dir,
                               [](GltfFile& f, const Triangle&) {
                                 f.doc()["accessors"][0].erase("bufferView");
                                 f.doc()["accessors"][0]["count"] = 1000000000000;
                                 f.doc()["accessors"][0]["sparse"] = {
                                     {"count", 1},
                                     {"indices", {{"bufferView", 4}, {"componentType", 5125}}},
                                     {"values", {{"bufferView", 0}}}};
                               }),
                   path, {"POSITION without a buffer view"});
  {
    GltfFile file;
    const Triangle t = add_triangle(file);
    const int bad = file.indices({0, 1, 7});
    (void)t;
    file.mesh({{"POSITION", 0}}, bad, "tri");
    file.node({{"name", "body"}, {"mesh", 0}});
    file.scene({0});
    file.write_gltf(dir, "broken.gltf");
    expect_bad_input(load(path), path, {"part 'body'", "7, out of range (3 vertices)"});
  }
  expect_bad_input(load_broken(dir,
                               [](GltfFile& f, const Triangle&) {
                                 f.doc()["meshes"][0]["primitives"][0]["extensions"] = {
                                     {"KHR_draco_mesh_compression",
                                      {{"bufferView", 0}, {"attributes", {{"POSITION", 0}}}}}};
                               }),
                   path, {"part 'body'", "Draco-compressed meshes are not supported"});
  expect_bad_input(load_broken(dir,
                               [](GltfFile& f, const Triangle&) {
                                 f.doc()["extensionsUsed"] = {"KHR_draco_mesh_compression"};
                                 f.doc()["extensionsRequired"] = {"KHR_draco_mesh_compression"};
                               }),
                   path, {"Draco-compressed meshes are not supported"});
  LoadOptions second_set;
  second_set.uv_set = 1;
  expect_bad_input(load_broken(
                       dir, [](GltfFile&, const Triangle&) {}, second_set),
                   path, {"part 'body'", "TEXCOORD_1", "has: TEXCOORD_0"});
  expect_bad_input(load_broken(dir,
                               [](GltfFile& f, const Triangle& t) {
                                 f.node({{"name", "body"}, {"mesh", 0}}), f.scene({0, 1}), (void)t;
                               }),
                   path, {"two parts are named 'body'"});
  expect_bad_input(
      load_broken(dir, [](GltfFile& f, const Triangle&) { f.doc()["nodes"][0]["children"] = {0}; }), path,
      {"reached twice"});
  expect_bad_input(
      load_broken(dir, [](GltfFile& f, const Triangle&) { f.doc()["accessors"][0]["componentType"] = 5123; }),
      path, {"POSITION", "unsigned short"});
  expect_bad_input(
      load_broken(dir,
                  [](GltfFile& f, const Triangle&) { f.doc()["meshes"][0]["primitives"][0]["mode"] = 1; }),
      path, {"no triangles"});
  // A missing external buffer: named by tinygltf's message with its file.
  {
    GltfFile file;
    const Triangle t = add_triangle(file);
    file.mesh({{"POSITION", t.positions}}, t.indices, "tri");
    file.node({{"mesh", 0}});
    file.write_gltf(dir, "broken.gltf", "gone.bin");
    fs::remove(dir.file("gone.bin"));
    expect_bad_input(load(path), path, {"gone.bin"});
  }
  // NaN positions: validate_mesh after the loader.
  {
    GltfFile file;
    const int positions = file.floats({0, 0, 0, 1, 0, 0, 0, std::nanf(""), 0}, 3);
    const int indices = file.indices({0, 1, 2});
    file.mesh({{"POSITION", positions}}, indices, "tri");
    file.node({{"mesh", 0}});
    file.write_gltf(dir, "broken.gltf");
    const Loaded r = load(path);
    expect_bad_input(r, path, {});
  }
  // OBJ and PLY have one UV set.
  write_text(dir.file("one.obj"), "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n");
  expect_bad_input(load(dir.file("one.obj"), second_set), dir.file("one.obj"), {"one UV set"});
}

// tinygltf casts every index to int: a mesh index of 2^40 became mesh 0,
// 2^31 and any negative one "no mesh", and a child of 2^32 + 1 node 1. Each
// is refused by name, as are transforms that place no mesh and glTF 1.0.
TEST(LoadGltf, HostileIndicesTransformsAndVersionsAreRefusedByName) {
  TempDir dir;
  const std::string path = dir.file("broken.gltf");
  for (const json& mesh :
       {json(-1), json(std::numeric_limits<std::int32_t>::min()), json(std::uint64_t{1} << 31),
        json(std::uint64_t{1} << 40), json(0.5), json("0")}) {
    expect_bad_input(
        load_broken(dir, [&](GltfFile& f, const Triangle&) { f.doc()["nodes"][0]["mesh"] = mesh; }), path,
        {"node 0: mesh is ", "not an index"});
  }
  // Another node's bad index is refused though the first node loads.
  expect_bad_input(load_broken(dir,
                               [](GltfFile& f, const Triangle&) {
                                 f.node({{"name", "other"}, {"mesh", -1}});
                                 f.scene({0, 1});
                               }),
                   path, {"node 1: mesh is -1"});
  expect_bad_input(
      load_broken(dir,
                  [](GltfFile& f, const Triangle&) { f.doc()["nodes"][0]["children"] = {(1ull << 32) + 1}; }),
      path, {"node 0: children[0] is 4294967297"});
  expect_bad_input(load_broken(dir,
                               [](GltfFile& f, const Triangle&) {
                                 f.doc()["meshes"][0]["primitives"][0]["attributes"]["POSITION"] = 1ull << 40;
                               }),
                   path, {"mesh 0: primitives[0].attributes.POSITION is 1099511627776"});
  // Indices inside extras are the application's, not glTF's.
  ASSERT_TRUE(load_broken(dir, [](GltfFile& f, const Triangle&) {
                f.doc()["nodes"][0]["extras"] = {{"mesh", -1}, {"children", {-5}}};
              }).status.is_ok());

  const json zero = json::array({0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0});
  const json projective = json::array({1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1, 0.5, 0, 0, 0, 1});
  expect_bad_input(
      load_broken(dir, [&](GltfFile& f, const Triangle&) { f.doc()["nodes"][0]["matrix"] = zero; }), path,
      {"node 0 ('body')", "last row 0 0 0 0", "not affine"});
  expect_bad_input(
      load_broken(dir, [&](GltfFile& f, const Triangle&) { f.doc()["nodes"][0]["matrix"] = projective; }),
      path, {"node 0 ('body')", "last row 0 0 0.5 1"});
  expect_bad_input(load_broken(dir,
                               [](GltfFile& f, const Triangle&) {
                                 f.doc()["nodes"][0]["matrix"] = {1, 0, 0, 0, 1};
                               }),
                   path, {"node 0 ('body')", "matrix has 5 numbers"});
  expect_bad_input(load_broken(dir,
                               [](GltfFile& f, const Triangle&) {
                                 f.doc()["nodes"][0]["rotation"] = {0, 0, 0, 0};
                               }),
                   path, {"node 0 ('body')", "zero quaternion"});
  // A translation-only matrix and a zero scale (a flattened part) still load.
  ASSERT_TRUE(load_broken(dir, [](GltfFile& f, const Triangle&) {
                f.doc()["nodes"][0]["matrix"] = {1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1, 0, 5, 6, 7, 1};
              }).status.is_ok());

  expect_bad_input(
      load_broken(dir, [](GltfFile& f, const Triangle&) { f.doc()["asset"]["version"] = "1.0"; }), path,
      {"asset version '1.0'", "only glTF 2.0"});
  // A GLB whose header says version 1 (glTF 1.0's binary container).
  {
    GltfFile file;
    const Triangle t = add_triangle(file);
    file.mesh({{"POSITION", t.positions}}, t.indices, "tri");
    file.node({{"name", "body"}, {"mesh", 0}});
    file.scene({0});
    file.write_gltf(dir, "one.gltf");
    const Loaded gltf = load(dir.file("one.gltf"));
    ASSERT_TRUE(gltf.status.is_ok()) << gltf.status.message();
    ASSERT_TRUE(save_mesh(dir.file("one.glb"), gltf.mesh).is_ok());
    ASSERT_TRUE(load(dir.file("one.glb")).status.is_ok());
    std::fstream glb(dir.file("one.glb"), std::ios::in | std::ios::out | std::ios::binary);
    glb.seekp(4);
    glb.put('\1');
    glb.close();
    expect_bad_input(load(dir.file("one.glb")), dir.file("one.glb"), {"GLB version 1", "only version 2"});
  }
}

// A GLB whose buffer has a byteLength of 0 made tinygltf throw
// std::out_of_range (vector::at(0) of the empty buffer): exit 3, found by
// fuzz_gltf. Now bad input naming the file.
TEST(LoadGltf, ExceptionsInsideTinygltfAreBadInput) {
  TempDir dir;
  std::string json_chunk = R"({"asset":{"version":"2.0"},"buffers":[{"byteLength":0}]})";
  while (json_chunk.size() % 4 != 0) json_chunk += ' ';
  const auto u32 = [](std::uint32_t v) { return std::string(reinterpret_cast<const char*>(&v), 4); };
  const std::string bin(4, '\0');
  const std::string glb = "glTF" + u32(2) +
                          u32(static_cast<std::uint32_t>(28 + json_chunk.size() + bin.size())) +
                          u32(static_cast<std::uint32_t>(json_chunk.size())) + "JSON" + json_chunk +
                          u32(static_cast<std::uint32_t>(bin.size())) + std::string("BIN\0", 4) + bin;
  write_text(dir.file("zero.glb"), glb);
  expect_bad_input(load(dir.file("zero.glb")), dir.file("zero.glb"),
                   {"glTF: the file is broken (tinygltf: "});
}

// A buffer's uri is read only from a regular file under the glTF's folder:
// "." and "/" were opened as files (std::bad_alloc), "../../etc/passwd" was
// read, a FIFO blocked, and a name missing from the folder was looked up in
// the working folder.
TEST(LoadGltf, BufferUrisStayUnderTheGltfsFolder) {
  TempDir dir;
  const std::string path = dir.file("broken.gltf");
  fs::create_directories(dir.file("sub/deeper"));
  fs::create_directories(dir.file("elsewhere"));
  // broken.gltf and broken.bin beside it; then the uri changed to `uri`.
  ASSERT_TRUE(load_broken(
                  dir, [](GltfFile&, const Triangle&) {}, {}, true)
                  .status.is_ok());
  const std::string document = [&] {
    std::ifstream in(path);
    return std::string(std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>());
  }();
  const auto load_uri = [&](const std::string& uri) {
    json doc = json::parse(document);
    doc["buffers"][0]["uri"] = uri;
    write_text(path, doc.dump());
    return load(path);
  };
  // The same bytes under other names.
  fs::copy_file(dir.file("broken.bin"), dir.file("sub/buffer.bin"));
  fs::copy_file(dir.file("broken.bin"), dir.file("elsewhere/buffer.bin"));
  ASSERT_EQ(::mkfifo(dir.file("sub/pipe.bin").c_str(), 0600), 0);
  for (const std::string uri :
       {"sub/buffer.bin", "sub/deeper/../buffer.bin", "./sub/buffer.bin", "sub%2Fbuffer.bin"}) {
    const Loaded r = load_uri(uri);
    EXPECT_TRUE(r.status.is_ok()) << uri << ": " << r.status.message();
  }
  const std::pair<std::string, std::string> refused[] = {
      {".", "names a folder"},
      {"sub", "names a folder"},
      {"..", "leaves the glTF's folder"},
      {"/", "absolute path"},
      {"/etc/passwd", "absolute path"},
      {"../../etc/passwd", "leaves the glTF's folder"},
      {"sub/../../elsewhere/buffer.bin", "leaves the glTF's folder"},
      {"%2e%2e/elsewhere/buffer.bin", "leaves the glTF's folder"},
      {"sub/pipe.bin", "no regular file"},
      {"missing.bin", "cannot open it"},
  };
  for (const auto& [uri, reason] : refused) {
    expect_bad_input(load_uri(uri), path, {"buffer 0 (uri '" + uri + "')", reason});
  }
  // Not in the glTF's folder but in the working folder: tinygltf's second
  // place to look, not ours.
  const fs::path cwd = fs::current_path();
  fs::current_path(dir.file("elsewhere"));
  const Loaded in_cwd = load_uri("buffer.bin");
  fs::current_path(cwd);
  expect_bad_input(in_cwd, path, {"buffer 0 (uri 'buffer.bin')", "cannot open it"});
}

// Each primitive's material names its triangles: the material's name,
// "material N" when it has none, "" for a primitive without a material;
// consecutive primitives of one material are one range, also across nodes.
// A material index out of range is an error naming the file and part.
TEST(LoadGltf, PrimitiveMaterialsNameMaterialRanges) {
  TempDir dir;
  GltfFile file;
  const Triangle t = add_triangle(file);
  const int mesh = file.mesh({{"POSITION", t.positions}}, t.indices, "body");
  json& primitives = file.doc()["meshes"][static_cast<std::size_t>(mesh)]["primitives"];
  const json primitive = primitives[0];
  for (const int material : {0, 1, -1, 1, 1}) {
    json p = primitive;
    if (material >= 0) p["material"] = material;
    primitives.push_back(p);
  }
  primitives.erase(0);
  file.doc()["materials"] = json::array({{{"name", "brushed steel"}}, json::object()});
  const int other = file.mesh({{"POSITION", t.positions}}, t.indices, "lid");
  file.doc()["meshes"][static_cast<std::size_t>(other)]["primitives"][0]["material"] = 1;
  file.node({{"name", "body"}, {"mesh", mesh}});
  file.node({{"name", "lid"}, {"mesh", other}});
  file.scene({0, 1});
  file.write_gltf(dir, "materials.gltf");
  const Loaded r = load(dir.file("materials.gltf"));
  ASSERT_TRUE(r.status.is_ok()) << r.status.message();
  const std::vector<MeshPart> expected{
      {"brushed steel", 0, 1}, {"material 1", 1, 1}, {"", 2, 1}, {"material 1", 3, 3}};
  EXPECT_EQ(r.mesh.materials, expected);
  const std::vector<MeshPart> parts{{"body", 0, 5}, {"lid", 5, 1}};
  EXPECT_EQ(r.mesh.parts, parts);
  // save_mesh writes them as materials of primitives: the same ranges back.
  ASSERT_TRUE(save_mesh(dir.file("again.glb"), r.mesh).is_ok());
  EXPECT_EQ(load(dir.file("again.glb")).mesh.materials, expected);

  file.doc()["meshes"][static_cast<std::size_t>(other)]["primitives"][0]["material"] = 7;
  file.write_gltf(dir, "bad.gltf");
  expect_bad_input(load(dir.file("bad.gltf")), dir.file("bad.gltf"),
                   {"part 'lid'", "primitive 0: material 7 does not exist"});
}

// ---- files no one here wrote: Debian's assimp-testmodels ----

fs::path test_models() {
  for (const char* dir : {"/usr/share/assimp/models", "/usr/share/assimp-testmodels/models"}) {
    if (fs::is_directory(dir)) return dir;
  }
  return {};
}

#define REQUIRE_TEST_MODELS()            \
  const fs::path models = test_models(); \
  if (models.empty()) GTEST_SKIP() << "the assimp-testmodels package is not installed (tools/setup)"

TEST(LoadFormatsModels, BoxTexturedInEveryGltfFlavour) {
  REQUIRE_TEST_MODELS();
  for (const char* file :
       {"glTF2/BoxTextured-glTF/BoxTextured.gltf", "glTF2/BoxTextured-glTF-Binary/BoxTextured.glb",
        "glTF2/BoxTextured-glTF-Embedded/BoxTextured.gltf"}) {
    SCOPED_TRACE(file);
    const Loaded r = load((models / file).string());
    ASSERT_TRUE(r.status.is_ok()) << r.status.message();
    // 6 faces of 4 split vertices, 2 triangles each; a unit cube.
    EXPECT_EQ(r.mesh.vertex_count(), 24u);
    EXPECT_EQ(r.mesh.triangle_count(), 12u);
    EXPECT_TRUE(r.mesh.has_uvs());
    EXPECT_TRUE(r.mesh.has_normals());
    const Bounds b = compute_bounds(r.mesh);
    expect_near(b.min, {-0.5f, -0.5f, -0.5f}, 1e-5f);
    expect_near(b.max, {0.5f, 0.5f, 0.5f}, 1e-5f);
  }
}

TEST(LoadFormatsModels, AssetGeneratorPrimitiveModes) {
  REQUIRE_TEST_MODELS();
  // The glTF Asset Generator draws the same unit square facing +z in every
  // primitive mode, indexed (07-15) or not (00-06): triangle list, strip and
  // fan must all give two front-facing triangles of total area 1; points
  // and lines have nothing to bake.
  const fs::path folder = models / "glTF2/glTF-Asset-Generator/Mesh_PrimitiveMode";
  for (int n = 0; n <= 15; ++n) {
    const std::string path =
        (folder / ("Mesh_PrimitiveMode_" + std::string(n < 10 ? "0" : "") + std::to_string(n) + ".gltf"))
            .string();
    SCOPED_TRACE(path);
    const Loaded r = load(path);
    const bool points_or_lines = (n >= 0 && n <= 3) || (n >= 7 && n <= 10);
    if (points_or_lines) {
      expect_bad_input(r, path, {"no triangles"});
      continue;
    }
    ASSERT_TRUE(r.status.is_ok()) << r.status.message();
    ASSERT_EQ(r.mesh.triangle_count(), 2u);
    float area = 0.0f;
    for (std::size_t t = 0; t < 2; ++t) {
      expect_near(face_normal(r.mesh, t), {0, 0, 1}, 1e-6f);
      const glm::vec3 a = r.mesh.positions[r.mesh.indices[3 * t]];
      area += 0.5f * glm::length(glm::cross(r.mesh.positions[r.mesh.indices[3 * t + 1]] - a,
                                            r.mesh.positions[r.mesh.indices[3 * t + 2]] - a));
    }
    EXPECT_NEAR(area, 1.0f, 1e-6f);
    const Bounds b = compute_bounds(r.mesh);
    expect_near(b.min, {-0.5f, -0.5f, 0.0f});
    expect_near(b.max, {0.5f, 0.5f, 0.0f});
  }
}

TEST(LoadFormatsModels, FbxCubesFromMayaAnd3dsMax) {
  REQUIRE_TEST_MODELS();
  struct Case {
    const char* file;
    const char* part;
    glm::vec3 min, max;
    double unit_meters;
  };
  // Maya's unit cube in centimetres (binary), 3ds Max's 1.2 box standing on
  // its base in metres (ASCII, UnitScaleFactor 100, originally inches),
  // each a cube of 6 faces of 4 split vertices.
  for (const Case& c :
       {Case{"FBX/phong_cube.fbx", "pCube1", {-0.5f, -0.5f, -0.5f}, {0.5f, 0.5f, 0.5f}, 0.01},
        Case{"FBX/embedded_ascii/box.FBX", "Box001", {-0.6f, -0.6f, 0.0f}, {0.6f, 0.6f, 1.2f}, 1.0}}) {
    SCOPED_TRACE(c.file);
    const Loaded r = load((models / c.file).string());
    ASSERT_TRUE(r.status.is_ok()) << r.status.message();
    EXPECT_EQ(r.mesh.vertex_count(), 24u);
    EXPECT_EQ(r.mesh.triangle_count(), 12u);
    ASSERT_EQ(r.mesh.parts.size(), 1u);
    EXPECT_EQ(r.mesh.parts[0].name, c.part);
    const Bounds b = compute_bounds(r.mesh);
    expect_near(b.min, c.min, 1e-4f);
    expect_near(b.max, c.max, 1e-4f);
    EXPECT_NEAR(r.stats.unit_meters, c.unit_meters, 1e-9);
  }
  // UnitScaleFactor 500: a file unit of 5 m.
  const Loaded settings = load((models / "FBX/global_settings.fbx").string());
  ASSERT_TRUE(settings.status.is_ok()) << settings.status.message();
  EXPECT_NEAR(settings.stats.unit_meters, 5.0, 1e-6);
  // Two models named alike: refused, naming the name.
  const std::string twins = (models / "FBX/cubes_with_names.fbx").string();
  expect_bad_input(load(twins), twins, {"two parts are named"});
}

TEST(LoadFormatsModels, FbxFileTangentsAreMikkTSpacesWithTheSameSign) {
  REQUIRE_TEST_MODELS();
  // Exporters that write MikkTSpace tangents (3ds Max, Blender): read back
  // through --tangents file they must give MikkTSpace's frame, which checks
  // the sign taken from the file's (T, B, N) handedness.
  for (const char* file :
       {"FBX/embedded_ascii/box.FBX", "FBX/box_orphant_embedded_texture.fbx", "FBX/huesitos.fbx"}) {
    SCOPED_TRACE(file);
    LoadOptions options;
    options.keep_tangents = true;
    Loaded r = load((models / file).string(), options);
    ASSERT_TRUE(r.status.is_ok()) << r.status.message();
    ASSERT_TRUE(r.mesh.has_tangents());
    MeshStats mesh_stats;
    prepare_low_normals(r.mesh, mesh_stats);
    std::vector<glm::vec4> mikk;
    std::vector<glm::vec4> from_file;
    TangentStats stats;
    compute_tangents(r.mesh, mikk, stats);
    compute_tangents(r.mesh, TangentBasis::file, from_file, stats);
    EXPECT_EQ(stats.fallback_tangents, 0u);
    ASSERT_EQ(mikk.size(), from_file.size());
    for (std::size_t c = 0; c < mikk.size(); ++c) {
      EXPECT_EQ(mikk[c].w, from_file[c].w) << "corner " << c;
      EXPECT_GT(glm::dot(glm::vec3(mikk[c]), glm::vec3(from_file[c])), std::cos(0.1 * std::numbers::pi / 180))
          << "corner " << c;
    }
  }
}

TEST(LoadFormatsModels, BrokenGltfModelsAreBadInput) {
  REQUIRE_TEST_MODELS();
  for (const char* file :
       {"glTF2/IndexOutOfRange/IndexOutOfRange.gltf", "glTF2/IndexOutOfRange/AllIndicesOutOfRange.gltf",
        "glTF2/MissingBin/BoxTextured.gltf", "glTF2/BoxWithInfinites-glTF-Binary/BoxWithInfinites.glb",
        "glTF2/RecursiveNodes/RecursiveNodes.gltf", "glTF2/draco/2CylinderEngine.gltf"}) {
    SCOPED_TRACE(file);
    const std::string path = (models / file).string();
    const Loaded r = load(path);
    expect_bad_input(r, path, {});
    std::printf("  %s\n", r.status.message().c_str());
  }
}

void load_every_file(const fs::path& folder, const std::vector<std::string>& extensions) {
  std::size_t loaded = 0;
  std::size_t rejected = 0;
  for (const fs::directory_entry& entry : fs::recursive_directory_iterator(folder)) {
    std::string extension = entry.path().extension().string();
    std::transform(extension.begin(), extension.end(), extension.begin(),
                   [](unsigned char c) { return std::tolower(c); });
    if (!entry.is_regular_file() ||
        std::find(extensions.begin(), extensions.end(), extension) == extensions.end()) {
      continue;
    }
    SCOPED_TRACE(entry.path().string());
    for (const bool low : {true, false}) {
      LoadOptions options;
      options.keep_uvs = low;
      options.keep_tangents = low;
      const Loaded r = load(entry.path().string(), options);
      if (r.status.is_ok()) {
        ++loaded;
        EXPECT_GT(r.mesh.triangle_count(), 0u);
        EXPECT_TRUE(validate_mesh(r.mesh, "reloaded").is_ok());
      } else {
        ++rejected;
        EXPECT_EQ(r.status.code(), StatusCode::bad_input) << r.status.message();
        EXPECT_TRUE(contains(r.status.message(), entry.path().string())) << r.status.message();
      }
    }
  }
  std::printf("%s: %zu loads, %zu rejections\n", folder.string().c_str(), loaded, rejected);
  EXPECT_GT(loaded, 0u);
}

TEST(LoadFormatsModels, EveryGltf2ModelLoadsOrIsBadInput) {
  REQUIRE_TEST_MODELS();
  load_every_file(models / "glTF2", {".gltf", ".glb"});
}

TEST(LoadFormatsModels, EveryFbxModelLoadsOrIsBadInput) {
  REQUIRE_TEST_MODELS();
  load_every_file(models / "FBX", {".fbx"});
}

TEST(LoadFormatsModels, EveryColladaStlAnd3dsModelLoadsOrIsBadInput) {
  REQUIRE_TEST_MODELS();
  load_every_file(models / "Collada", {".dae"});
  load_every_file(models / "STL", {".stl"});
  load_every_file(models / "3DS", {".3ds"});
}

}  // namespace
}  // namespace nmbake

namespace nmbake {
namespace {

// ---- FBX written by Assimp's exporter ----

// A scene of one concave quad (corner 2 is reflex) under a node with
// rotation, scale and translation, built in memory for Assimp's exporter.
void make_quad_scene(aiScene& scene) {
  auto* mesh = new aiMesh();
  mesh->mName = "quad_mesh";
  mesh->mPrimitiveTypes = aiPrimitiveType_POLYGON;
  mesh->mNumVertices = 4;
  mesh->mVertices = new aiVector3D[4]{{0, 0, 0}, {2, 0, 0}, {0.5f, 0.5f, 0}, {0, 2, 0}};
  mesh->mNormals = new aiVector3D[4]{{0, 0, 1}, {0, 0, 1}, {0, 0, 1}, {0, 0, 1}};
  mesh->mTextureCoords[0] = new aiVector3D[4]{{0, 0, 0}, {1, 0, 0}, {0.25f, 0.25f, 0}, {0, 1, 0}};
  mesh->mNumUVComponents[0] = 2;
  mesh->mNumFaces = 1;
  mesh->mFaces = new aiFace[1];
  mesh->mFaces[0].mNumIndices = 4;
  mesh->mFaces[0].mIndices = new unsigned[4]{0, 1, 2, 3};
  mesh->mMaterialIndex = 0;
  scene.mNumMeshes = 1;
  scene.mMeshes = new aiMesh* [1] { mesh };
  scene.mNumMaterials = 1;
  scene.mMaterials = new aiMaterial* [1] { new aiMaterial() };
  scene.mRootNode = new aiNode("root");
  auto* node = new aiNode("crate");
  // Scale 2, a quarter turn about +z, moved by (10, 0, 0).
  node->mTransformation =
      aiMatrix4x4(aiVector3D(2, 2, 2), aiQuaternion(aiVector3D(0, 0, 1), std::numbers::pi_v<float> / 2),
                  aiVector3D(10, 0, 0));
  node->mNumMeshes = 1;
  node->mMeshes = new unsigned[1]{0};
  aiNode* children[] = {node};
  scene.mRootNode->addChildren(1, children);
}

TEST(LoadFbx, AssimpExportedFbxKeepsNodeTransformNameAndOurDiagonal) {
  TempDir dir;
  // ASCII only: Assimp 5.2.5's binary FBX exporter leaves out the null
  // records that end nested node lists, and its own importer then rejects
  // the file ("FBX-Tokenize ... block offset is out of range"); binary FBX
  // is tested with the files of assimp-testmodels and our own writer.
  for (const char* format : {"fbxa"}) {
    SCOPED_TRACE(format);
    aiScene scene;
    make_quad_scene(scene);
    const std::string path = dir.file(std::string("quad_") + format + ".fbx");
    Assimp::Exporter exporter;
    ASSERT_EQ(exporter.Export(&scene, format, path), AI_SUCCESS) << exporter.GetErrorString();
    const Loaded r = load(path);
    ASSERT_TRUE(r.status.is_ok()) << r.status.message();
    ASSERT_EQ(r.mesh.vertex_count(), 4u);
    ASSERT_EQ(r.mesh.triangle_count(), 2u);
    EXPECT_EQ(r.stats.polygons, 1u);
    ASSERT_EQ(r.mesh.parts.size(), 1u);
    EXPECT_EQ(r.mesh.parts[0].name, "crate");
    // Assimp's exporter writes UnitScaleFactor 1 (centimetres) and has no
    // setting for another: 1 file unit = 1 cm.
    EXPECT_DOUBLE_EQ(r.stats.unit_meters, 0.01);
    // world = T(10,0,0) R(90 about z) S(2): (x, y) -> (10 - 2y, 2x).
    const std::vector<glm::vec3> expected{{10, 0, 0}, {10, 4, 0}, {9, 1, 0}, {6, 0, 0}};
    for (std::size_t t = 0; t < 2; ++t) {
      // The fan from corner 0, as the OBJ loader: (0 1 2) (0 2 3), found
      // by position since the exporter may reorder vertices.
      const std::size_t corners[2][3] = {{0, 1, 2}, {0, 2, 3}};
      for (std::size_t c = 0; c < 3; ++c) {
        expect_near(r.mesh.positions[r.mesh.indices[3 * t + c]], expected[corners[t][c]], 1e-4f);
      }
    }
    expect_near(glm::normalize(r.mesh.normals[0]), {0, 0, 1}, 1e-5f);
    expect_near(face_normal(r.mesh, 0), {0, 0, 1}, 1e-5f);
  }
}

TEST(LoadFbx, BinaryFbxInCentimetresAndMetresWithNodeTransform) {
  TempDir dir;
  // The concave quad again, as one FBX polygon of four corners.
  Mesh quad;
  quad.positions = {{0, 0, 0}, {2, 0, 0}, {0.5f, 0.5f, 0}, {0, 2, 0}};
  quad.normals = {{0, 0, 1}, {0, 0, 1}, {0, 0, 1}, {0, 0, 1}};
  quad.uvs = {{0, 0}, {1, 0}, {0.25f, 0.25f}, {0, 1}};
  quad.indices = {0, 1, 2, 3};
  gen::FbxModel model;
  model.name = "crate";
  model.translation = {10, 0, 0};
  model.rotation_degrees = {0, 0, 90};
  model.scaling = {2, 2, 2};
  for (const double unit : {1.0, 100.0}) {
    SCOPED_TRACE(unit);
    model.unit_scale_factor = unit;
    const std::string path = dir.file("quad.fbx");
    ASSERT_TRUE(gen::write_fbx_binary(path, quad, model, {4}).is_ok());
    const Loaded r = load(path);
    ASSERT_TRUE(r.status.is_ok()) << r.status.message();
    // Positions stay in file units whatever the unit; the unit is a note.
    EXPECT_DOUBLE_EQ(r.stats.unit_meters, 0.01 * unit);
    ASSERT_EQ(r.mesh.triangle_count(), 2u);
    ASSERT_EQ(r.mesh.parts.size(), 1u);
    EXPECT_EQ(r.mesh.parts[0].name, "crate");
    // No material in the file: Assimp's "DefaultMaterial" is no material.
    EXPECT_TRUE(r.mesh.materials.empty());
    // world = T(10,0,0) R(90 about z) S(2); the fan (0 1 2) (0 2 3).
    const std::vector<glm::vec3> expected{{10, 0, 0}, {10, 4, 0}, {9, 1, 0}, {6, 0, 0}};
    const std::size_t corners[2][3] = {{0, 1, 2}, {0, 2, 3}};
    for (std::size_t t = 0; t < 2; ++t) {
      for (std::size_t c = 0; c < 3; ++c) {
        expect_near(r.mesh.positions[r.mesh.indices[3 * t + c]], expected[corners[t][c]], 1e-4f);
      }
    }
    EXPECT_NEAR(r.mesh.uvs[r.mesh.indices[2]].x, 0.25f, 1e-6f);
    // A high mesh read from the same file has no UVs, a low one with
    // --uv-set 1 names the channels there are.
    LoadOptions high;
    high.keep_uvs = false;
    EXPECT_FALSE(load(path, high).mesh.has_uvs());
    LoadOptions second;
    second.uv_set = 1;
    expect_bad_input(load(path, second), path, {"part 'crate'", "UV channel 1 is missing", "channels: 0"});
  }
}

TEST(LoadFbx, BrokenFbxIsBadInputWithAssimpsReason) {
  TempDir dir;
  const std::string path = dir.file("broken.fbx");
  write_text(path, "Kaydara FBX Binary  \x00\x1a\x00 this is not a real FBX file");
  const Loaded r = load(path);
  expect_bad_input(r, path, {"Assimp: "});
  const std::string missing = dir.file("missing.fbx");
  expect_bad_input(load(missing), missing, {"cannot open"});
  // Nothing of Assimp's reaches the terminal: the CLI prints one line.
  const test::CommandResult run = test::run_command(test::cli_path() + " bake --low " + path + " --high " +
                                                    path + " -o " + dir.file("x.png") + " 2>&1");
  EXPECT_EQ(run.exit_code, 2);
  EXPECT_EQ(std::count(run.output.begin(), run.output.end(), '\n'), 1) << run.output;
  EXPECT_TRUE(contains(run.output, path + ": Assimp: ")) << run.output;
}

// A Collada file written here: per-vertex RGBA colours (COLOR) and two
// materials, one used twice. Each <triangles> element is an Assimp mesh: a
// range named by its material; colours as stored, also through the child
// process; a vertex whose colour differs is not welded with one at the
// same position. A file without materials has none (Assimp's invented
// "DefaultMaterial" is no material).
TEST(LoadCollada, VertexColoursAndTwoMaterials) {
  TempDir dir;
  Mesh mesh;
  mesh.positions = {{0, 0, 0}, {1, 0, 0}, {1, 1, 0}, {0, 1, 0}, {0, 0, 0}};
  mesh.colors = {{1, 0, 0, 1}, {0, 1, 0, 1}, {0, 0, 1, 0.5f}, {0.25f, 0.5f, 0.75f, 1}, {0.1f, 0.2f, 0.3f, 1}};
  mesh.indices = {0, 1, 2, 4, 2, 3, 0, 2, 3, 0, 1, 3};
  mesh.materials = {{"paint red", 0, 2}, {"paint_blue", 2, 1}, {"paint red", 3, 1}};
  const std::string path = dir.file("two.dae");
  write_text(path, test::collada_text(mesh));
  LoadOptions options;
  options.keep_colors = true;
  const Loaded r = load(path, options);
  ASSERT_TRUE(r.status.is_ok()) << r.status.message();
  ASSERT_EQ(r.mesh.triangle_count(), 4u);
  EXPECT_EQ(r.mesh.materials, mesh.materials);
  ASSERT_EQ(r.mesh.parts.size(), 1u);
  EXPECT_EQ(r.mesh.parts[0].name, "mesh");
  ASSERT_TRUE(r.mesh.has_colors());
  for (std::size_t c = 0; c < r.mesh.indices.size(); ++c) {
    const glm::vec4 expected = mesh.colors[mesh.indices[c]];
    const glm::vec4 actual = r.mesh.colors[r.mesh.indices[c]];
    for (int k = 0; k < 4; ++k)
      EXPECT_NEAR(actual[k], expected[k], 1e-7f) << "corner " << c << " channel " << k;
    expect_near(r.mesh.positions[r.mesh.indices[c]], mesh.positions[mesh.indices[c]], 0.0f);
  }
  // The first mesh's two triangles: (0, 0, 0) twice in two colours (5
  // vertices), then 3 and 3 for the others; without colours they weld (4).
  EXPECT_EQ(r.mesh.vertex_count(), 11u);
  LoadOptions here = options;
  here.isolate_libraries = false;
  const Loaded direct = load(path, here);
  ASSERT_TRUE(direct.status.is_ok()) << direct.status.message();
  EXPECT_EQ(direct.mesh.positions, r.mesh.positions);
  EXPECT_EQ(direct.mesh.colors, r.mesh.colors);
  EXPECT_EQ(direct.mesh.indices, r.mesh.indices);
  EXPECT_EQ(direct.mesh.materials, r.mesh.materials);
  EXPECT_EQ(direct.mesh.parts, r.mesh.parts);
  const Loaded plain = load(path);
  ASSERT_TRUE(plain.status.is_ok()) << plain.status.message();
  EXPECT_FALSE(plain.mesh.has_colors());
  EXPECT_EQ(plain.mesh.vertex_count(), 10u);
  EXPECT_EQ(plain.mesh.materials, mesh.materials);
  mesh.materials.clear();
  write_text(path, test::collada_text(mesh));
  const Loaded none = load(path, options);
  ASSERT_TRUE(none.status.is_ok()) << none.status.message();
  EXPECT_TRUE(none.mesh.materials.empty());
  EXPECT_TRUE(none.mesh.has_colors());
}

// Files no one here wrote: Collada and FBX from modellers' exporters
// (kwxport from 3ds Max: three materials and vertex colours; Maya's FBX
// cubes in two materials; an FBX with colours), and formats whose
// importers invent a material name (STL, 3DS): none.
TEST(LoadFormatsModels, MaterialsAndColoursOfExportedFiles) {
  const fs::path models = test_models();
  if (models.empty()) GTEST_SKIP() << "the assimp-testmodels package is not installed (tools/setup)";
  LoadOptions options;
  options.keep_colors = true;
  const Loaded kwx = load((models / "Collada/kwxport_test_vcolors.dae").string(), options);
  ASSERT_TRUE(kwx.status.is_ok()) << kwx.status.message();
  std::vector<std::string> names;
  for (const MeshPart& m : kwx.mesh.materials) names.push_back(m.name);
  EXPECT_EQ(names, (std::vector<std::string>{"bottom", "top", "side"}));
  ASSERT_TRUE(kwx.mesh.has_colors());
  bool red = false;
  for (const glm::vec4& c : kwx.mesh.colors) red = red || c == glm::vec4(1, 0, 0, 1);
  EXPECT_TRUE(red);

  const Loaded cubes = load((models / "FBX/cubes_nonames.fbx").string(), options);
  ASSERT_TRUE(cubes.status.is_ok()) << cubes.status.message();
  std::set<std::string> cube_materials;
  for (const MeshPart& m : cubes.mesh.materials) cube_materials.insert(m.name);
  EXPECT_EQ(cube_materials, (std::set<std::string>{"Mat_Green", "Mat_Red"}));
  EXPECT_FALSE(cubes.mesh.has_colors());  // none in the file

  const Loaded box = load((models / "FBX/box.fbx").string(), options);
  ASSERT_TRUE(box.status.is_ok()) << box.status.message();
  ASSERT_TRUE(box.mesh.has_colors());
  EXPECT_NEAR(box.mesh.colors[0].r, 250.0f / 255.0f, 1e-6f);
  EXPECT_EQ(
      box.mesh.materials,
      (std::vector<MeshPart>{{"Material_50", 0, static_cast<std::uint32_t>(box.mesh.triangle_count())}}));

  for (const char* file : {"STL/Spider_ascii.stl", "3DS/CameraRollAnim.3ds"}) {
    const Loaded r = load((models / file).string());
    ASSERT_TRUE(r.status.is_ok()) << file << ": " << r.status.message();
    EXPECT_TRUE(r.mesh.materials.empty()) << file << ": " << r.mesh.materials.front().name;
  }
}

// ---- bakes: the same asset as OBJ and as glTF; file tangents ----

std::string bake_args(const std::string& low, const std::string& high, const std::string& out) {
  return test::cli_path() + " bake -q --low " + low + " --high " + high + " -o " + out +
         " --size 128 --samples 1";
}

bool same_bytes(const std::string& a, const std::string& b) {
  std::ifstream fa(a, std::ios::binary);
  std::ifstream fb(b, std::ios::binary);
  const std::string da((std::istreambuf_iterator<char>(fa)), std::istreambuf_iterator<char>());
  const std::string db((std::istreambuf_iterator<char>(fb)), std::istreambuf_iterator<char>());
  return !da.empty() && da == db;
}

TEST(LoadFormatsBake, ObjTransformedTwoPartGltfAndFbxBakeTheSameMap) {
  TempDir dir;
  const std::string out = dir.path().string();
  ASSERT_EQ(test::run_command(test::gen_path() + " box --out-dir " + out + " --high-cells 24 --low-cells 2")
                .exit_code,
            0);
  const std::string low_obj = dir.file("box_low.obj");
  const std::string high = dir.file("box_high.ply");
  Loaded low = load(low_obj);
  ASSERT_TRUE(low.status.is_ok()) << low.status.message();
  ASSERT_TRUE(low.mesh.has_uvs() && low.mesh.has_normals());
  // The same mesh under a node matrix M: (x, y, z) -> (-2y, 2x, 2z). The
  // file holds M^-1 p and M^T n (so that M^-T of it is n); both are exact
  // in floats, so the world-space positions equal the OBJ's bit for bit.
  std::vector<float> positions;
  std::vector<float> normals;
  std::vector<float> uvs;
  for (std::size_t v = 0; v < low.mesh.vertex_count(); ++v) {
    const glm::vec3 p = low.mesh.positions[v];
    const glm::vec3 n = low.mesh.normals[v];
    positions.insert(positions.end(), {p.y / 2, -p.x / 2, p.z / 2});
    normals.insert(normals.end(), {2 * n.y, -2 * n.x, 2 * n.z});
    uvs.insert(uvs.end(), {low.mesh.uvs[v].x, 1.0f - low.mesh.uvs[v].y});
  }
  GltfFile file;
  const int position_accessor = file.floats(positions, 3);
  const int normal_accessor = file.floats(normals, 3);
  const int uv_accessor = file.floats(uvs, 2);
  const std::size_t half = low.mesh.triangle_count() / 2 * 3;
  const std::vector<std::uint32_t> first(low.mesh.indices.begin(),
                                         low.mesh.indices.begin() + static_cast<std::ptrdiff_t>(half));
  const std::vector<std::uint32_t> second(low.mesh.indices.begin() + static_cast<std::ptrdiff_t>(half),
                                          low.mesh.indices.end());
  const json attributes = {
      {"POSITION", position_accessor}, {"NORMAL", normal_accessor}, {"TEXCOORD_0", uv_accessor}};
  const int mesh_a = file.mesh(attributes, file.indices(first), "a");
  const int mesh_b = file.mesh(attributes, file.indices(second), "b");
  const json matrix = {0, 2, 0, 0, -2, 0, 0, 0, 0, 0, 2, 0, 0, 0, 0, 1};
  file.node({{"name", "part_a"}, {"mesh", mesh_a}, {"matrix", matrix}});
  file.node({{"name", "part_b"}, {"mesh", mesh_b}, {"matrix", matrix}});
  file.scene({0, 1});
  file.write_gltf(dir, "box_low.gltf", "box_low.bin");
  const Loaded gltf = load(dir.file("box_low.gltf"));
  ASSERT_TRUE(gltf.status.is_ok()) << gltf.status.message();
  ASSERT_EQ(gltf.mesh.parts.size(), 2u);
  EXPECT_EQ(gltf.mesh.positions, low.mesh.positions);
  EXPECT_EQ(gltf.mesh.indices, low.mesh.indices);

  ASSERT_EQ(test::run_command(bake_args(low_obj, high, dir.file("obj.png"))).exit_code, 0);
  const test::CommandResult baked =
      test::run_command(bake_args(dir.file("box_low.gltf"), high, dir.file("gltf.png")));
  ASSERT_EQ(baked.exit_code, 0) << baked.output;
  // UVs went through 1 - (1 - v), which may move them by an ulp: the maps
  // agree within the 16-bit floor rather than byte for byte.
  const test::CommandResult diff =
      test::run_command(test::cli_path() + " diff " + dir.file("obj.png") + " " + dir.file("gltf.png") +
                        " --max-max 0.05 --max-mean 0.001");
  EXPECT_EQ(diff.exit_code, 0) << diff.output;
  std::printf("OBJ vs transformed two-part glTF: %s\n", diff.output.c_str());

  // And as binary FBX in centimetres: the model scaled by 2 and turned a
  // quarter about z (in double, so not bit-exact), holding M^-1 p.
  Mesh local = low.mesh;
  for (std::size_t v = 0; v < local.vertex_count(); ++v) {
    const glm::vec3 p = low.mesh.positions[v];
    const glm::vec3 n = low.mesh.normals[v];
    local.positions[v] = {p.y / 2, -p.x / 2, p.z / 2};
    local.normals[v] = {n.y, -n.x, n.z};
  }
  gen::FbxModel model;
  model.name = "box";
  model.rotation_degrees = {0, 0, 90};
  model.scaling = {2, 2, 2};
  ASSERT_TRUE(gen::write_fbx_binary(dir.file("box_low.fbx"), local, model).is_ok());
  const test::CommandResult fbx = test::run_command(
      bake_args(dir.file("box_low.fbx"), high, dir.file("fbx.png")) + " --report " + dir.file("fbx.json"));
  ASSERT_EQ(fbx.exit_code, 0) << fbx.output;
  // The report carries the units: the FBX says centimetres, the PLY nothing.
  std::ifstream report_file(dir.file("fbx.json"));
  const json report = json::parse(report_file);
  EXPECT_DOUBLE_EQ(report["unit_meters"]["low"].get<double>(), 0.01);
  EXPECT_DOUBLE_EQ(report["unit_meters"]["high"].get<double>(), 0.0);
  // Not bit-exact, the FBX's points give the automatic back distance 0.2%
  // more (0.1407 against 0.1404: another probe lands on the 99.5th
  // percentile), which widens the banded cage's band around the hard edges
  // as much: half of the texels move by a 16-bit step (0.0017 degrees).
  const test::CommandResult fbx_diff =
      test::run_command(test::cli_path() + " diff " + dir.file("obj.png") + " " + dir.file("fbx.png") +
                        " --max-max 0.05 --max-mean 0.002");
  EXPECT_EQ(fbx_diff.exit_code, 0) << fbx_diff.output;
  std::printf("OBJ vs transformed FBX (cm): %s\n", fbx_diff.output.c_str());
}

TEST(LoadFormatsBake, WrittenMikkTSpaceTangentsBakeLikeMikkTSpace) {
  TempDir dir;
  const std::string out = dir.path().string();
  ASSERT_EQ(
      test::run_command(test::gen_path() + " sphere --out-dir " + out + " --high-cells 32 --low-cells 3")
          .exit_code,
      0);
  const std::string low_obj = dir.file("sphere_low.obj");
  const std::string high = dir.file("sphere_high.ply");
  const std::string glb = dir.file("low_tangents.glb");
  const test::CommandResult wrote =
      test::run_command(test::cli_path() + " tangents " + low_obj + " --write " + glb);
  ASSERT_EQ(wrote.exit_code, 0) << wrote.output;
  LoadOptions options;
  options.keep_tangents = true;
  const Loaded reloaded = load(glb, options);
  ASSERT_TRUE(reloaded.status.is_ok()) << reloaded.status.message();
  ASSERT_TRUE(reloaded.mesh.has_tangents());
  const Loaded original = load(low_obj);
  EXPECT_EQ(reloaded.mesh.triangle_count(), original.mesh.triangle_count());
  EXPECT_GE(reloaded.mesh.vertex_count(), original.mesh.vertex_count());
  for (const glm::vec4& t : reloaded.mesh.tangents) {
    EXPECT_NEAR(glm::length(glm::vec3(t)), 1.0f, 1e-5f);
    EXPECT_TRUE(t.w == 1.0f || t.w == -1.0f);
  }
  ASSERT_EQ(
      test::run_command(bake_args(glb, high, dir.file("mikk.png")) + " --tangents mikktspace").exit_code, 0);
  const test::CommandResult file_run =
      test::run_command(bake_args(glb, high, dir.file("file.png")) + " --tangents file");
  ASSERT_EQ(file_run.exit_code, 0) << file_run.output;
  const test::CommandResult diff =
      test::run_command(test::cli_path() + " diff " + dir.file("mikk.png") + " " + dir.file("file.png") +
                        " --max-max 0.05 --max-mean 0.001");
  EXPECT_EQ(diff.exit_code, 0) << diff.output;
  std::printf("--tangents file vs mikktspace: %s%s\n",
              same_bytes(dir.file("mikk.png"), dir.file("file.png")) ? "byte-identical; " : "",
              diff.output.c_str());
  // The file's tangents are really used: with every sign flipped the map
  // differs (so the comparison above can fail).
  Mesh flipped = reloaded.mesh;
  for (glm::vec4& t : flipped.tangents) t.w = -t.w;
  ASSERT_TRUE(save_mesh(dir.file("flipped.glb"), flipped).is_ok());
  ASSERT_EQ(test::run_command(bake_args(dir.file("flipped.glb"), high, dir.file("flipped.png")) +
                              " --tangents file")
                .exit_code,
            0);
  EXPECT_EQ(test::run_command(test::cli_path() + " diff " + dir.file("mikk.png") + " " +
                              dir.file("flipped.png") + " --max-max 0.05 --max-mean 0.001")
                .exit_code,
            1);
  // A mesh without tangents cannot be baked with --tangents file.
  const test::CommandResult no_tangents =
      test::run_command(bake_args(low_obj, high, dir.file("none.png")) + " --tangents file");
  EXPECT_EQ(no_tangents.exit_code, 2);
  EXPECT_TRUE(contains(no_tangents.output, "has no tangents")) << no_tangents.output;
}

TEST(LoadFormatsBake, UvSetPicksTheGltfTexcoordSet) {
  TempDir dir;
  const std::string out = dir.path().string();
  ASSERT_EQ(test::run_command(test::gen_path() + " box --out-dir " + out + " --high-cells 24 --low-cells 2")
                .exit_code,
            0);
  Loaded low = load(dir.file("box_low.obj"));
  ASSERT_TRUE(low.status.is_ok()) << low.status.message();
  // TEXCOORD_0 is garbage (every corner at one point), TEXCOORD_1 the real
  // layout: only --uv-set 1 bakes the OBJ's map.
  std::vector<float> positions, normals, uvs, flat;
  for (std::size_t v = 0; v < low.mesh.vertex_count(); ++v) {
    positions.insert(positions.end(),
                     {low.mesh.positions[v].x, low.mesh.positions[v].y, low.mesh.positions[v].z});
    normals.insert(normals.end(), {low.mesh.normals[v].x, low.mesh.normals[v].y, low.mesh.normals[v].z});
    uvs.insert(uvs.end(), {low.mesh.uvs[v].x, 1.0f - low.mesh.uvs[v].y});
    flat.insert(flat.end(), {0.5f, 0.5f});
  }
  GltfFile file;
  const json attributes = {{"POSITION", file.floats(positions, 3)},
                           {"NORMAL", file.floats(normals, 3)},
                           {"TEXCOORD_0", file.floats(flat, 2)},
                           {"TEXCOORD_1", file.floats(uvs, 2)}};
  file.node({{"name", "box"}, {"mesh", file.mesh(attributes, file.indices(low.mesh.indices))}});
  file.scene({0});
  file.write_gltf(dir, "two_sets.gltf");
  const std::string gltf = dir.file("two_sets.gltf");
  ASSERT_EQ(
      test::run_command(bake_args(dir.file("box_low.obj"), dir.file("box_high.ply"), dir.file("obj.png")))
          .exit_code,
      0);
  const test::CommandResult set1 =
      test::run_command(bake_args(gltf, dir.file("box_high.ply"), dir.file("set1.png")) + " --uv-set 1");
  ASSERT_EQ(set1.exit_code, 0) << set1.output;
  EXPECT_EQ(test::run_command(test::cli_path() + " diff " + dir.file("obj.png") + " " + dir.file("set1.png") +
                              " --max-max 0.05 --max-mean 0.001")
                .exit_code,
            0);
  ASSERT_EQ(test::run_command(bake_args(gltf, dir.file("box_high.ply"), dir.file("set0.png"))).exit_code, 0);
  EXPECT_EQ(test::run_command(test::cli_path() + " diff " + dir.file("obj.png") + " " + dir.file("set0.png") +
                              " --max-max 0.05 --max-mean 0.001")
                .exit_code,
            1);
  const test::CommandResult set2 =
      test::run_command(bake_args(gltf, dir.file("box_high.ply"), dir.file("set2.png")) + " --uv-set 2");
  EXPECT_EQ(set2.exit_code, 2);
  EXPECT_TRUE(contains(set2.output, "TEXCOORD_0, TEXCOORD_1")) << set2.output;
}

TEST(LoadFormatsBake, JobFilesTakeTangentsAndUvSet) {
  TempDir dir;
  const std::string path = dir.file("job.toml");
  write_text(path,
             "[[bake]]\nlow = \"l.glb\"\nhigh = \"h.ply\"\noutputs = [\"a.png\"]\ntangents = "
             "\"file\"\nuv_set = 1\n");
  std::vector<BakeJob> jobs;
  const Status s = load_job_file(path, jobs);
  ASSERT_TRUE(s.is_ok()) << s.message();
  ASSERT_EQ(jobs.size(), 1u);
  EXPECT_EQ(jobs[0].options.tangent_basis, TangentBasis::file);
  EXPECT_EQ(jobs[0].options.uv_set, 1);
  write_text(path,
             "[[bake]]\nlow = \"l.glb\"\nhigh = \"h.ply\"\noutputs = [\"a.png\"]\ntangents = \"lengyel\"\n");
  EXPECT_FALSE(load_job_file(path, jobs).is_ok());
  write_text(path, "[[bake]]\nlow = \"l.glb\"\nhigh = \"h.ply\"\noutputs = [\"a.png\"]\nuv_set = -1\n");
  EXPECT_FALSE(load_job_file(path, jobs).is_ok());
}

// ------------------------------------------------- several files as one mesh

TEST(LoadMeshes, SeveralFilesAppendInOrder) {
  TempDir dir;
  // a.obj: normals and a material; b.obj: neither, a material of the same
  // name defined otherwise; c.obj: that material as a.obj defines it.
  write_text(dir.file("a.mtl"), "newmtl paint\nKd 1 0 0\n");
  write_text(dir.file("b.mtl"), "newmtl paint\nKd 0 0 1\n");
  write_text(dir.file("a.obj"),
             "mtllib a.mtl\no body\nv 0 0 0\nv 1 0 0\nv 0 1 0\nvn 0 0 1\nusemtl paint\nf 1//1 2//1 3//1\n");
  write_text(dir.file("b.obj"), "mtllib b.mtl\nv 0 0 1\nv 1 0 1\nv 0 1 1\nusemtl paint\nf 1 2 3\n");
  write_text(dir.file("c.obj"), "mtllib a.mtl\nv 0 0 2\nv 1 0 2\nv 0 1 2\nusemtl paint\nf 1 2 3\n");
  LoadOptions options;
  options.material_defs = true;
  Mesh mesh;
  LoadStats stats;
  const Status s =
      load_meshes({dir.file("a.obj"), dir.file("b.obj"), dir.file("c.obj")}, options, mesh, stats);
  ASSERT_TRUE(s.is_ok()) << s.message();
  ASSERT_EQ(mesh.triangle_count(), 3u);
  EXPECT_EQ(stats.triangles, 3u);
  EXPECT_EQ(mesh.indices, (std::vector<std::uint32_t>{0, 1, 2, 3, 4, 5, 6, 7, 8}));
  EXPECT_EQ(mesh.positions[4], glm::vec3(1, 0, 1));
  // The files without normals get zero normals (computed and counted when
  // the bake normalises them).
  ASSERT_EQ(mesh.normals.size(), 9u);
  EXPECT_EQ(mesh.normals[0], glm::vec3(0, 0, 1));
  EXPECT_EQ(mesh.normals[3], glm::vec3(0));
  ASSERT_EQ(mesh.parts.size(), 3u);
  EXPECT_EQ(mesh.parts[0].name, "body");
  EXPECT_EQ(mesh.parts[1].name, "b");
  EXPECT_EQ(mesh.parts[2].name, "c");
  EXPECT_EQ(mesh.parts[2].first_triangle, 2u);
  ASSERT_EQ(mesh.materials.size(), 3u);
  EXPECT_EQ(mesh.materials[0].name, "paint");
  EXPECT_EQ(mesh.materials[1].name, "b/paint");
  EXPECT_EQ(mesh.materials[2].name, "paint");
  ASSERT_EQ(mesh.material_defs.size(), 2u);
  EXPECT_EQ(mesh.material_def("b/paint")->base_color, glm::vec4(0, 0, 1, 1));
  EXPECT_EQ(mesh.material_def("paint")->base_color, glm::vec4(1, 0, 0, 1));
  // One path is load_mesh() itself: no part named after the file.
  ASSERT_TRUE(load_meshes({dir.file("b.obj")}, options, mesh, stats).is_ok());
  EXPECT_TRUE(mesh.parts.empty());
}

TEST(LoadMeshes, FilesInDifferentUnitsAreRefusedNamingBoth) {
  TempDir dir;
  Mesh tri;
  tri.positions = {{0, 0, 0}, {1, 0, 0}, {0, 1, 0}};
  tri.indices = {0, 1, 2};
  gen::FbxModel model;
  model.unit_scale_factor = 1.0;  // centimetres
  ASSERT_TRUE(gen::write_fbx_binary(dir.file("cm.fbx"), tri, model).is_ok());
  model.unit_scale_factor = 100.0;  // metres
  ASSERT_TRUE(gen::write_fbx_binary(dir.file("m.fbx"), tri, model).is_ok());
  ASSERT_TRUE(save_mesh(dir.file("any.obj"), tri).is_ok());
  Mesh mesh;
  LoadStats stats;
  // An OBJ does not say its unit: it goes with either.
  ASSERT_TRUE(load_meshes({dir.file("cm.fbx"), dir.file("any.obj")}, LoadOptions{}, mesh, stats).is_ok());
  EXPECT_DOUBLE_EQ(stats.unit_meters, 0.01);
  const Status s =
      load_meshes({dir.file("cm.fbx"), dir.file("any.obj"), dir.file("m.fbx")}, LoadOptions{}, mesh, stats);
  ASSERT_FALSE(s.is_ok());
  EXPECT_TRUE(contains(s.message(), dir.file("m.fbx"))) << s.message();
  EXPECT_TRUE(contains(s.message(), dir.file("cm.fbx"))) << s.message();
  EXPECT_EQ(mesh.triangle_count(), 0u);
}

}  // namespace
}  // namespace nmbake
