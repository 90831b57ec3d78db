// Tests of the load stage: tiny hand-written OBJ and PLY files with exact
// expectations, every rejection with its file and place, and save/load round
// trips.
#include "nmbake/load.hpp"

#include <gtest/gtest.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <glm/geometric.hpp>
#include <limits>
#include <string>
#include <vector>

#include "test_util.hpp"

namespace nmbake {
namespace {

using test::TempDir;
using test::write_text;

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

Loaded load_text(const TempDir& dir, const std::string& name, const std::string& text,
                 LoadOptions options = {}) {
  const std::string path = dir.file(name);
  write_text(path, text);
  return load(path, options);
}

// Bytes of a binary PLY body with an explicit byte order.
class Bytes {
 public:
  explicit Bytes(bool big_endian) : big_endian_(big_endian) {}
  template <typename T>
  Bytes& put(T value) {
    unsigned char raw[sizeof(T)];
    std::memcpy(raw, &value, sizeof(T));
    // The test machine is little endian (checked below); reverse for BE.
    if (big_endian_) {
      for (std::size_t i = 0; i < sizeof(T) / 2; ++i) std::swap(raw[i], raw[sizeof(T) - 1 - i]);
    }
    data_.append(reinterpret_cast<const char*>(raw), sizeof(T));
    return *this;
  }
  Bytes& text(const std::string& s) {
    data_ += s;
    return *this;
  }
  const std::string& data() const { return data_; }
  std::size_t size() const { return data_.size(); }

 private:
  bool big_endian_;
  std::string data_;
};

bool host_is_little_endian() {
  const std::uint16_t one = 1;
  unsigned char first = 0;
  std::memcpy(&first, &one, 1);
  return first == 1;
}

void expect_vec3(const glm::vec3& actual, float x, float y, float z) {
  EXPECT_EQ(actual.x, x);
  EXPECT_EQ(actual.y, y);
  EXPECT_EQ(actual.z, z);
}

std::vector<std::uint32_t> indices_of(const Mesh& mesh) { return mesh.indices; }

// Corner attributes of triangle corner `corner`, for tests where the vertex
// numbering is an implementation choice.
glm::vec3 corner_position(const Mesh& mesh, std::size_t corner) {
  return mesh.positions[mesh.indices[corner]];
}

// ------------------------------------------------------------------- OBJ

TEST(LoadObj, PositionsOnlyTriangle) {
  TempDir dir;
  const std::string text = "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n";
  const Loaded r = load_text(dir, "tri.obj", text);
  ASSERT_TRUE(r.status.is_ok()) << r.status.message();
  ASSERT_EQ(r.mesh.vertex_count(), 3u);
  expect_vec3(r.mesh.positions[1], 1, 0, 0);
  EXPECT_EQ(indices_of(r.mesh), (std::vector<std::uint32_t>{0, 1, 2}));
  EXPECT_FALSE(r.mesh.has_normals());
  EXPECT_FALSE(r.mesh.has_uvs());
  EXPECT_EQ(r.stats.bytes, text.size());
  EXPECT_EQ(r.stats.polygons, 1u);
  EXPECT_EQ(r.stats.triangles, 1u);
  EXPECT_EQ(r.stats.degenerate_faces, 0u);
}

TEST(LoadObj, EveryCornerForm) {
  TempDir dir;
  const std::string data =
      "v 0 0 0\nv 1 0 0\nv 0 1 0\nvt 0.25 0.5\nvt 1 0\nvt 0 1\nvn 0 0 1\nvn 0 0 2\nvn 0 0 3\n";
  {
    const Loaded r = load_text(dir, "vt.obj", data + "f 1/1 2/2 3/3\n");
    ASSERT_TRUE(r.status.is_ok()) << r.status.message();
    ASSERT_TRUE(r.mesh.has_uvs());
    EXPECT_FALSE(r.mesh.has_normals());
    EXPECT_EQ(r.mesh.uvs[0], glm::vec2(0.25f, 0.5f));
    EXPECT_EQ(r.mesh.uvs[2], glm::vec2(0.0f, 1.0f));
  }
  {
    const Loaded r = load_text(dir, "vn.obj", data + "f 1//1 2//2 3//3\n");
    ASSERT_TRUE(r.status.is_ok()) << r.status.message();
    EXPECT_FALSE(r.mesh.has_uvs());
    ASSERT_TRUE(r.mesh.has_normals());
    // Returned as in the file: normalisation is the caller's step.
    expect_vec3(r.mesh.normals[1], 0, 0, 2);
  }
  {
    const Loaded r = load_text(dir, "both.obj", data + "f 1/1/1 2/2/2 3/3/3\n");
    ASSERT_TRUE(r.status.is_ok()) << r.status.message();
    ASSERT_EQ(r.mesh.vertex_count(), 3u);
    EXPECT_EQ(r.mesh.uvs[1], glm::vec2(1.0f, 0.0f));
    expect_vec3(r.mesh.normals[2], 0, 0, 3);
  }
  {
    // The same corners with different vt/vn numbers: each vertex gets its own.
    const Loaded r = load_text(dir, "mixed.obj", data + "f 1/3/2 2/1/3 3/2/1\n");
    ASSERT_TRUE(r.status.is_ok()) << r.status.message();
    ASSERT_EQ(r.mesh.vertex_count(), 3u);
    for (std::size_t c = 0; c < 3; ++c) {
      const std::uint32_t v = r.mesh.indices[c];
      const glm::vec3 expected_position[] = {{0, 0, 0}, {1, 0, 0}, {0, 1, 0}};
      const glm::vec2 expected_uv[] = {{0, 1}, {0.25f, 0.5f}, {1, 0}};
      const glm::vec3 expected_normal[] = {{0, 0, 2}, {0, 0, 3}, {0, 0, 1}};
      EXPECT_EQ(r.mesh.positions[v], expected_position[c]);
      EXPECT_EQ(r.mesh.uvs[v], expected_uv[c]);
      EXPECT_EQ(r.mesh.normals[v], expected_normal[c]);
    }
  }
}

TEST(LoadObj, NegativeIndicesAreRelativeToDefinitionsSoFar) {
  TempDir dir;
  const Loaded r = load_text(dir, "neg.obj",
                             "v 0 0 0\nv 1 0 0\nv 1 1 0\nvt 0 0\nvt 1 0\nvt 1 1\n"
                             "f -3/-3 -2/-2 -1/-1\n"
                             "v 0 1 0\nvt 0 1\n"
                             "f -4/-4 -2/-2 -1/-1\n");
  ASSERT_TRUE(r.status.is_ok()) << r.status.message();
  ASSERT_EQ(r.mesh.vertex_count(), 4u);
  EXPECT_EQ(indices_of(r.mesh), (std::vector<std::uint32_t>{0, 1, 2, 0, 2, 3}));
  EXPECT_EQ(r.mesh.uvs[3], glm::vec2(0.0f, 1.0f));
}

TEST(LoadObj, PolygonsAreFanTriangulated) {
  TempDir dir;
  const Loaded r =
      load_text(dir, "poly.obj",
                "v 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\nv 2 0 0\nv 3 0 0\nv 3 1 0\nv 2.5 2 0\nv 2 1 0\n"
                "f 1 2 3 4\nf 5 6 7 8 9\n");
  ASSERT_TRUE(r.status.is_ok()) << r.status.message();
  EXPECT_EQ(indices_of(r.mesh), (std::vector<std::uint32_t>{0, 1, 2, 0, 2, 3, 4, 5, 6, 4, 6, 7, 4, 7, 8}));
  EXPECT_EQ(r.stats.polygons, 2u);
  EXPECT_EQ(r.stats.triangles, 5u);
}

TEST(LoadObj, ObjectsGroupsAndOtherStatementsAreMerged) {
  TempDir dir;
  // CRLF endings, tabs, comments (whole line and trailing), blank lines,
  // statements we ignore, extra numbers on v (w or colours), a vt with no v.
  const std::string text =
      "# exported by a test\r\n"
      "mtllib scene.mtl\r\n"
      "o first\r\n"
      "\r\n"
      "v 0 0 0 1\r\n"
      "v\t1 0 0 0.5 0.5 0.5\r\n"
      "v 0 1 0   # trailing comment\r\n"
      "vt 0.5\r\n"
      "vp 0.1 0.2\r\n"
      "g part_a\r\n"
      "usemtl red\r\n"
      "s 1\r\n"
      "f 1/1 2/1 3/1\r\n"
      "   \r\n"
      "o second\r\n"
      "g part_b part_c\r\n"
      "v 5 5 5\r\n"
      "l 1 4\r\n"
      "s off\r\n"
      "f 2/1 4/1 3/1 # another comment\r\n";
  const Loaded r = load_text(dir, "groups.obj", text);
  ASSERT_TRUE(r.status.is_ok()) << r.status.message();
  EXPECT_EQ(r.mesh.vertex_count(), 4u);
  EXPECT_EQ(r.mesh.triangle_count(), 2u);
  expect_vec3(r.mesh.positions[3], 5, 5, 5);
  EXPECT_EQ(r.mesh.uvs[3], glm::vec2(0.5f, 0.0f));
}

// Vertex colours from "v x y z r g b" (the extension MeshLab and Open3D
// write), kept as written, only with keep_colors; a v without them (3
// numbers, "x y z w", or arguments that are not three finite reals) is
// white; they follow the positions through split vertices, and save_mesh
// writes them back (alpha is lost: 1).
TEST(LoadObj, VertexColoursAfterThePosition) {
  TempDir dir;
  const std::string text =
      "v 0 0 0 1 0 0.25\n"
      "v 1 0 0 0 0.5 1 7\n"    // a 7th number: ignored
      "v 0 1 0 2\n"            // x y z w: no colour
      "v 1 1 0 0.5 nan 0.5\n"  // not three finite reals: no colour
      "v 2 2 0 0.5 0.5\n"      // two numbers: no colour
      "vt 0 0\nvt 1 1\n"
      "f 1/1 2/1 3/1\nf 2/2 4/2 3/2\nf 3/1 4/1 5/1\n";
  LoadOptions options;
  const Loaded plain = load_text(dir, "c.obj", text, options);
  ASSERT_TRUE(plain.status.is_ok()) << plain.status.message();
  EXPECT_FALSE(plain.mesh.has_colors());
  options.keep_colors = true;
  for (const bool serial : {true, false}) {
    options.serial = serial;
    const Loaded r = load_text(dir, "c.obj", text, options);
    ASSERT_TRUE(r.status.is_ok()) << r.status.message();
    ASSERT_EQ(r.mesh.colors.size(), r.mesh.vertex_count());
    EXPECT_GT(r.mesh.vertex_count(), 5u);  // split at the UV seam
    for (std::size_t i = 0; i < r.mesh.vertex_count(); ++i) {
      const glm::vec3 p = r.mesh.positions[i];
      const glm::vec4 expected = p == glm::vec3(0, 0, 0)   ? glm::vec4(1, 0, 0.25f, 1)
                                 : p == glm::vec3(1, 0, 0) ? glm::vec4(0, 0.5f, 1, 1)
                                                           : glm::vec4(1.0f);
      EXPECT_EQ(r.mesh.colors[i], expected) << "vertex " << i << (serial ? " serial" : " slices");
    }
  }
  // No vertex with a colour: none, even when asked.
  const Loaded none = load_text(dir, "n.obj", "v 0 0 0\nv 1 0 0 1\nv 0 1 0\nf 1 2 3\n", options);
  ASSERT_TRUE(none.status.is_ok());
  EXPECT_FALSE(none.mesh.has_colors());
  // Written back and read again: the same RGB, alpha 1.
  Mesh mesh = plain.mesh;
  mesh.uvs.clear();
  mesh.colors.assign(mesh.vertex_count(), glm::vec4(0.1f, 0.2f, 0.3f, 0.5f));
  mesh.colors[0] = glm::vec4(1e-8f, 1.0f / 3.0f, 0.0f, 1.0f);
  ASSERT_TRUE(save_mesh(dir.file("back.obj"), mesh).is_ok());
  const Loaded back = load(dir.file("back.obj"), options);
  ASSERT_TRUE(back.status.is_ok()) << back.status.message();
  ASSERT_EQ(back.mesh.colors.size(), mesh.colors.size());
  for (std::size_t i = 0; i < mesh.colors.size(); ++i) {
    EXPECT_EQ(glm::vec3(back.mesh.colors[i]), glm::vec3(mesh.colors[i]));
    EXPECT_EQ(back.mesh.colors[i].a, 1.0f);
  }
}

TEST(LoadObj, LastLineWithoutNewline) {
  TempDir dir;
  const Loaded r = load_text(dir, "nonl.obj", "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3");
  ASSERT_TRUE(r.status.is_ok()) << r.status.message();
  EXPECT_EQ(r.mesh.triangle_count(), 1u);
}

// A quad whose two triangles use different vt at the shared edge: a UV seam.
const char* kSeamQuad =
    "v 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\n"
    "vt 0 0\nvt 0.5 0\nvt 0.5 0.5\nvt 0 0.5\nvt 0.6 0\nvt 0.6 0.5\n"
    "vn 0 0 1\n"
    "f 1/1/1 2/2/1 3/3/1\n"
    "f 1/5/1 3/6/1 4/4/1\n";

TEST(LoadObj, UvSeamSplitsVerticesWhenUvsAreKept) {
  TempDir dir;
  const Loaded r = load_text(dir, "seam.obj", kSeamQuad);
  ASSERT_TRUE(r.status.is_ok()) << r.status.message();
  // Corners: (1,1,1) (2,2,1) (3,3,1) (1,5,1) (3,6,1) (4,4,1): six combinations.
  ASSERT_EQ(r.mesh.vertex_count(), 6u);
  ASSERT_EQ(r.mesh.triangle_count(), 2u);
  const glm::vec2 expected_uv[] = {{0, 0}, {0.5f, 0}, {0.5f, 0.5f}, {0.6f, 0}, {0.6f, 0.5f}, {0, 0.5f}};
  const glm::vec3 expected_position[] = {{0, 0, 0}, {1, 0, 0}, {1, 1, 0}, {0, 0, 0}, {1, 1, 0}, {0, 1, 0}};
  for (std::size_t c = 0; c < 6; ++c) {
    EXPECT_EQ(r.mesh.uvs[r.mesh.indices[c]], expected_uv[c]) << "corner " << c;
    EXPECT_EQ(corner_position(r.mesh, c), expected_position[c]) << "corner " << c;
    expect_vec3(r.mesh.normals[r.mesh.indices[c]], 0, 0, 1);
  }
}

TEST(LoadObj, HighMeshIsNotSplitAtUvSeams) {
  TempDir dir;
  LoadOptions options;
  options.keep_uvs = false;
  const Loaded r = load_text(dir, "seam.obj", kSeamQuad, options);
  ASSERT_TRUE(r.status.is_ok()) << r.status.message();
  ASSERT_EQ(r.mesh.vertex_count(), 4u);
  EXPECT_FALSE(r.mesh.has_uvs());
  ASSERT_TRUE(r.mesh.has_normals());
  EXPECT_EQ(r.mesh.triangle_count(), 2u);
  // Shared corners share a vertex.
  EXPECT_EQ(r.mesh.indices[0], r.mesh.indices[3]);
  EXPECT_EQ(r.mesh.indices[2], r.mesh.indices[4]);
}

TEST(LoadObj, DroppedNormalsDoNotSplit) {
  TempDir dir;
  // Two triangles meeting at a hard edge: normals differ on the shared edge.
  const std::string text =
      "v 0 0 0\nv 1 0 0\nv 0 1 0\nv 0 0 1\nvn 0 0 1\nvn 1 0 0\n"
      "f 1//1 2//1 3//1\nf 1//2 3//2 4//2\n";
  const Loaded kept = load_text(dir, "hard.obj", text);
  ASSERT_TRUE(kept.status.is_ok()) << kept.status.message();
  EXPECT_EQ(kept.mesh.vertex_count(), 6u);
  LoadOptions options;
  options.keep_normals = false;
  const Loaded dropped = load_text(dir, "hard.obj", text, options);
  ASSERT_TRUE(dropped.status.is_ok()) << dropped.status.message();
  EXPECT_EQ(dropped.mesh.vertex_count(), 4u);
  EXPECT_FALSE(dropped.mesh.has_normals());
  EXPECT_EQ(indices_of(dropped.mesh), (std::vector<std::uint32_t>{0, 1, 2, 0, 2, 3}));
}

TEST(LoadObj, SwitchFromSharedToSplitIndicesMidFile) {
  TempDir dir;
  // The first faces use v == vn; the last does not. The result must be the
  // same as if every corner had been looked up from the start.
  const std::string text =
      "v 0 0 0\nv 1 0 0\nv 0 1 0\nv 1 1 0\nvn 0 0 1\nvn 0 0 2\nvn 0 0 3\nvn 0 0 4\n"
      "f 1//1 2//2 3//3\nf 2//2 4//4 3//3\nf 1//4 2//2 4//1\n";
  const Loaded r = load_text(dir, "switch.obj", text);
  ASSERT_TRUE(r.status.is_ok()) << r.status.message();
  const int expected_v[] = {1, 2, 3, 2, 4, 3, 1, 2, 4};
  const int expected_vn[] = {1, 2, 3, 2, 4, 3, 4, 2, 1};
  const glm::vec3 file_positions[] = {{0, 0, 0}, {1, 0, 0}, {0, 1, 0}, {1, 1, 0}};
  for (std::size_t c = 0; c < 9; ++c) {
    EXPECT_EQ(corner_position(r.mesh, c), file_positions[expected_v[c] - 1]) << "corner " << c;
    expect_vec3(r.mesh.normals[r.mesh.indices[c]], 0, 0, static_cast<float>(expected_vn[c]));
  }
  // (1,1) (2,2) (3,3) (4,4) (1,4) (4,1): six distinct combinations.
  EXPECT_EQ(r.mesh.vertex_count(), 6u);
}

TEST(LoadObj, UnreferencedVerticesAreDropped) {
  TempDir dir;
  const Loaded r = load_text(dir, "unused.obj", "v 9 9 9\nv 0 0 0\nv 8 8 8\nv 1 0 0\nv 0 1 0\nf 2 4 5\n");
  ASSERT_TRUE(r.status.is_ok()) << r.status.message();
  ASSERT_EQ(r.mesh.vertex_count(), 3u);
  expect_vec3(r.mesh.positions[0], 0, 0, 0);
  expect_vec3(r.mesh.positions[1], 1, 0, 0);
  expect_vec3(r.mesh.positions[2], 0, 1, 0);
  EXPECT_EQ(indices_of(r.mesh), (std::vector<std::uint32_t>{0, 1, 2}));
}

TEST(LoadObj, FacesWithFewerThanThreeCornersAreCountedAndSkipped) {
  TempDir dir;
  const Loaded r = load_text(dir, "deg.obj", "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2\nf 3\nf 1 2 3\nf\n");
  ASSERT_TRUE(r.status.is_ok()) << r.status.message();
  EXPECT_EQ(r.stats.degenerate_faces, 3u);
  EXPECT_EQ(r.stats.polygons, 1u);
  EXPECT_EQ(r.mesh.triangle_count(), 1u);
}

TEST(LoadObj, NumberForms) {
  TempDir dir;
  // Exponents, a leading '+', and an underflow (a zero, not an error).
  const Loaded r = load_text(dir, "num.obj", "v 1e2 +2.5 -3E-1\nv 1e-50 0 0\nv 0 1 0\nf 1 2 3\n");
  ASSERT_TRUE(r.status.is_ok()) << r.status.message();
  expect_vec3(r.mesh.positions[0], 100.0f, 2.5f, -0.3f);
  expect_vec3(r.mesh.positions[1], 0, 0, 0);
}

TEST(LoadObj, FileLargerThanTheReadBuffer) {
  TempDir dir;
  // About 7 MB: lines straddle several buffer refills.
  const int quad_count = 100000;
  std::string text;
  text.reserve(8 << 20);
  for (int i = 0; i <= quad_count; ++i) {
    text += "v " + std::to_string(i) + " 0 0.123456789\nv " + std::to_string(i) + " 1 0.987654321\n";
  }
  for (int i = 0; i < quad_count; ++i) {
    const int a = 2 * i + 1;
    text += "f " + std::to_string(a) + " " + std::to_string(a + 2) + " " + std::to_string(a + 3) + " " +
            std::to_string(a + 1) + "\n";
  }
  ASSERT_GT(text.size(), std::size_t{5} << 20);
  const Loaded r = load_text(dir, "big.obj", text);
  ASSERT_TRUE(r.status.is_ok()) << r.status.message();
  EXPECT_EQ(r.mesh.vertex_count(), static_cast<std::size_t>(2 * (quad_count + 1)));
  EXPECT_EQ(r.mesh.triangle_count(), static_cast<std::size_t>(2 * quad_count));
  expect_vec3(r.mesh.positions.back(), static_cast<float>(quad_count), 1.0f, 0.987654321f);
  const std::size_t last = r.mesh.indices.size() - 1;
  EXPECT_EQ(r.mesh.indices[last], static_cast<std::uint32_t>(2 * quad_count - 1));
}

// ------------------------------------------------------------ OBJ errors

// Loads `text` and expects a bad_input whose message starts with
// "PATH:LINE: " and contains `reason`.
void expect_obj_error(const std::string& text, int line, const std::string& reason,
                      LoadOptions options = {}) {
  TempDir dir;
  const std::string path = dir.file("bad.obj");
  write_text(path, text);
  Mesh mesh;
  LoadStats stats;
  const Status status = load_mesh(path, options, mesh, stats);
  ASSERT_FALSE(status.is_ok()) << text;
  EXPECT_EQ(status.code(), StatusCode::bad_input);
  const std::string prefix = path + ":" + std::to_string(line) + ": ";
  EXPECT_EQ(status.message().rfind(prefix, 0), 0u) << status.message() << " does not start with " << prefix;
  EXPECT_NE(status.message().find(reason), std::string::npos) << status.message() << " lacks " << reason;
  EXPECT_EQ(mesh.vertex_count(), 0u);
}

const char* kTriangle = "v 0 0 0\nv 1 0 0\nv 0 1 0\n";

TEST(LoadObjErrors, BadNumbers) {
  expect_obj_error("v 0 0 0\nv 1 abc 0\n", 2, "bad number 'abc'");
  expect_obj_error("v 0 0 0\nv 1 2\n", 2, "expected 3 numbers, found 2");
  expect_obj_error("v 0 0 0\nv 1 2 3x\n", 2, "bad number '3x'");
  expect_obj_error("v 1e39 0 0\n", 1, "out of range");
  expect_obj_error(std::string(kTriangle) + "vn 0 0 1\nvn 1 1\n", 5, "expected 3 numbers");
  expect_obj_error(std::string(kTriangle) + "vt\n", 4, "expected 1 numbers, found 0");
}

TEST(LoadObjErrors, NonFiniteCoordinates) {
  expect_obj_error("v 0 0 0\nv nan 0 0\n", 2, "NaN or Inf");
  expect_obj_error("v 0 inf 0\n", 1, "NaN or Inf");
  expect_obj_error(std::string(kTriangle) + "vn 0 0 -inf\n", 4, "NaN or Inf");
  expect_obj_error(std::string(kTriangle) + "vt NaN 0\n", 4, "NaN or Inf");
}

TEST(LoadObjErrors, BadIndices) {
  const std::string tri = kTriangle;
  expect_obj_error(tri + "f 0 1 2\n", 4, "vertex index 0");
  expect_obj_error(tri + "f 1 2 4\n", 4, "vertex index 4 out of range (3 defined so far)");
  expect_obj_error(tri + "f -4 -2 -1\n", 4, "vertex index -4 out of range");
  expect_obj_error("v 0 0 0\nf 1 2 3\nv 1 0 0\nv 0 1 0\n", 2, "vertex index 2 out of range");
  expect_obj_error(tri + "vt 0 0\nf 1/1 2/2 3/1\n", 5, "texture coordinate index 2 out of range");
  expect_obj_error(tri + "vn 0 0 1\nf 1//1 2//0 3//1\n", 5, "normal index 0");
  expect_obj_error(tri + "f 1 2 x\n", 4, "bad vertex index 'x'");
  expect_obj_error(tri + "f 1/ 2/ 3/\n", 4, "missing texture coordinate index");
  expect_obj_error(tri + "f 1// 2// 3//\n", 4, "missing normal index");
  expect_obj_error(tri + "f /1 2 3\n", 4, "bad vertex index ''");
}

TEST(LoadObjErrors, CornersMustAgreeOnKeptAttributes) {
  const std::string data = std::string(kTriangle) + "vt 0 0\nvn 0 0 1\n";
  expect_obj_error(data + "f 1/1 2/1 3\n", 6,
                   "corner '3' has no texture coordinate index but earlier corners do");
  expect_obj_error(data + "f 1 2 3\nf 1//1 2//1 3//1\n", 7, "has normal index but earlier corners do not");
  // An attribute that is not kept may come and go.
  TempDir dir;
  LoadOptions options;
  options.keep_uvs = false;
  const Loaded r = load_text(dir, "mixed.obj", data + "f 1/1 2/1 3\nf 1 3 2\n", options);
  EXPECT_TRUE(r.status.is_ok()) << r.status.message();
}

TEST(LoadObjErrors, NoTriangles) {
  TempDir dir;
  for (const std::string& text :
       {std::string(), std::string(kTriangle), std::string(kTriangle) + "f 1 2\nl 1 2 3\n"}) {
    const std::string path = dir.file("empty.obj");
    write_text(path, text);
    Mesh mesh;
    LoadStats stats;
    const Status status = load_mesh(path, {}, mesh, stats);
    ASSERT_FALSE(status.is_ok());
    EXPECT_EQ(status.code(), StatusCode::bad_input);
    EXPECT_EQ(status.message().rfind(path + ": no triangles", 0), 0u) << status.message();
  }
}

TEST(LoadErrors, MissingFileAndUnknownExtension) {
  TempDir dir;
  Mesh mesh;
  LoadStats stats;
  const std::string missing = dir.file("missing.obj");
  Status status = load_mesh(missing, {}, mesh, stats);
  EXPECT_EQ(status.code(), StatusCode::bad_input);
  EXPECT_EQ(status.message(), missing + ": cannot open: No such file or directory");

  const std::string xyz = dir.file("mesh.xyz");
  write_text(xyz, "0 0 0\n");
  status = load_mesh(xyz, {}, mesh, stats);
  EXPECT_EQ(status.code(), StatusCode::bad_input);
  EXPECT_EQ(
      status.message(),
      xyz + ": unknown mesh format '.xyz' (expected .obj, .ply, .gltf, .glb, .fbx, .dae, .3ds or .stl)");

  // Extensions are case-insensitive.
  const std::string upper = dir.file("TRI.OBJ");
  write_text(upper, kTriangle + std::string("f 1 2 3\n"));
  EXPECT_TRUE(load_mesh(upper, {}, mesh, stats).is_ok());
}

// ------------------------------------------------------------------- PLY

TEST(LoadPly, AsciiWithNormalsUvsAndQuad) {
  TempDir dir;
  const Loaded r = load_text(dir, "quad.ply",
                             "ply\n"
                             "format ascii 1.0\n"
                             "comment made by hand\n"
                             "obj_info nothing\n"
                             "element vertex 4\n"
                             "property float x\nproperty float y\nproperty float z\n"
                             "property float nx\nproperty float ny\nproperty float nz\n"
                             "property float s\nproperty float t\n"
                             "element face 1\n"
                             "property list uchar int vertex_indices\n"
                             "end_header\n"
                             "0 0 0 0 0 1 0 0\n"
                             "1 0 0 0 0 1 1 0\n"
                             "1 1 0 0 0 1 1 1\n"
                             "0 1 0 0 0 2 0 1\n"
                             "4 0 1 2 3\n");
  ASSERT_TRUE(r.status.is_ok()) << r.status.message();
  ASSERT_EQ(r.mesh.vertex_count(), 4u);
  EXPECT_EQ(indices_of(r.mesh), (std::vector<std::uint32_t>{0, 1, 2, 0, 2, 3}));
  expect_vec3(r.mesh.normals[3], 0, 0, 2);
  EXPECT_EQ(r.mesh.uvs[2], glm::vec2(1.0f, 1.0f));
  EXPECT_EQ(r.stats.polygons, 1u);
  EXPECT_EQ(r.stats.triangles, 2u);
}

TEST(LoadPly, AsciiSkipsUnknownElementsAndProperties) {
  TempDir dir;
  // CRLF header, an element before the vertices, colour properties, a list
  // property in the vertex, a face with extra list and scalar properties, an
  // element after the faces, entries spanning lines, a 2-corner face.
  const Loaded r = load_text(dir, "extra.ply",
                             "ply\r\n"
                             "format ascii 1.0\r\n"
                             "element camera 1\r\n"
                             "property float view_x\r\nproperty list uchar float params\r\n"
                             "element vertex 3\r\n"
                             "property uchar red\r\n"
                             "property double x\r\nproperty double y\r\nproperty double z\r\n"
                             "property list int int tags\r\n"
                             "property float texture_u\r\nproperty float texture_v\r\n"
                             "element face 2\r\n"
                             "property int flags\r\n"
                             "property list uint8 float32 weights\r\n"
                             "property list uint16 uint32 vertex_index\r\n"
                             "property uchar material\r\n"
                             "element edge 1\r\n"
                             "property int vertex1\r\nproperty int vertex2\r\n"
                             "end_header\r\n"
                             "0.5 3 1 2 3\r\n"
                             "255 0 0 0 0 0.25 0.75\r\n"
                             "7 1 0 0 2 10 20 1 0\r\n"
                             "9 0 1 0.5 0\n1 1\r\n"
                             "-1 2 0.5 0.5 3 0 1 2 4\r\n"
                             "-1 0 2 0 1 4\r\n"
                             "0 1\r\n");
  ASSERT_TRUE(r.status.is_ok()) << r.status.message();
  ASSERT_EQ(r.mesh.vertex_count(), 3u);
  expect_vec3(r.mesh.positions[2], 0, 1, 0.5f);
  EXPECT_EQ(r.mesh.uvs[0], glm::vec2(0.25f, 0.75f));
  EXPECT_EQ(r.mesh.uvs[2], glm::vec2(1.0f, 1.0f));
  EXPECT_EQ(indices_of(r.mesh), (std::vector<std::uint32_t>{0, 1, 2}));
  EXPECT_EQ(r.stats.degenerate_faces, 1u);
}

std::string ply_header(const std::string& format, const std::string& body) {
  return "ply\nformat " + format + " 1.0\n" + body + "end_header\n";
}

TEST(LoadPly, BinaryLittleEndianFastPath) {
  ASSERT_TRUE(host_is_little_endian());
  TempDir dir;
  Bytes file(false);
  file.text(ply_header("binary_little_endian",
                       "element vertex 4\n"
                       "property float x\nproperty float y\nproperty float z\n"
                       "property float nx\nproperty float ny\nproperty float nz\n"
                       "element face 2\n"
                       "property list uchar int vertex_indices\n"));
  const float vertices[4][6] = {
      {0, 0, 0, 0, 0, 1}, {1, 0, 0, 0, 0, 1}, {1, 1, 0.1f, 0, 0, 1}, {0, 1, -0.0f, 0, 1, 0}};
  for (const auto& vertex : vertices) {
    for (const float value : vertex) file.put(value);
  }
  file.put<std::uint8_t>(3).put<std::int32_t>(0).put<std::int32_t>(1).put<std::int32_t>(2);
  // A quad inside the fast path's layout.
  file.put<std::uint8_t>(4).put<std::int32_t>(0).put<std::int32_t>(1).put<std::int32_t>(2).put<std::int32_t>(
      3);
  const std::string path = dir.file("fast.ply");
  write_text(path, file.data());
  const Loaded r = load(path);
  ASSERT_TRUE(r.status.is_ok()) << r.status.message();
  ASSERT_EQ(r.mesh.vertex_count(), 4u);
  expect_vec3(r.mesh.positions[2], 1, 1, 0.1f);
  EXPECT_TRUE(std::signbit(r.mesh.positions[3].z));
  expect_vec3(r.mesh.normals[3], 0, 1, 0);
  EXPECT_FALSE(r.mesh.has_uvs());
  EXPECT_EQ(indices_of(r.mesh), (std::vector<std::uint32_t>{0, 1, 2, 0, 1, 2, 0, 2, 3}));
  EXPECT_EQ(r.stats.polygons, 2u);
  EXPECT_EQ(r.stats.bytes, file.size());
}

TEST(LoadPly, BinaryBigEndianDoublesAndSmallTypes) {
  TempDir dir;
  Bytes file(true);
  file.text(ply_header("binary_big_endian",
                       "element vertex 3\n"
                       "property float64 x\nproperty double y\nproperty double z\n"
                       "property uchar red\nproperty uint8 green\n"
                       "property ushort u\nproperty short v\n"
                       "element face 1\n"
                       "property list uint16 int16 vertex_indices\n"));
  const double xyz[3][3] = {{0.5, -1.25, 3.0}, {1e10, 0, 0}, {0, 1, 1.0 / 3.0}};
  for (int i = 0; i < 3; ++i) {
    file.put(xyz[i][0]).put(xyz[i][1]).put(xyz[i][2]);
    file.put<std::uint8_t>(200).put<std::uint8_t>(100);
    file.put<std::uint16_t>(static_cast<std::uint16_t>(1000 + i))
        .put<std::int16_t>(static_cast<std::int16_t>(-i));
  }
  file.put<std::uint16_t>(3).put<std::int16_t>(2).put<std::int16_t>(1).put<std::int16_t>(0);
  const std::string path = dir.file("be.ply");
  write_text(path, file.data());
  const Loaded r = load(path);
  ASSERT_TRUE(r.status.is_ok()) << r.status.message();
  ASSERT_EQ(r.mesh.vertex_count(), 3u);
  expect_vec3(r.mesh.positions[0], 0.5f, -1.25f, 3.0f);
  expect_vec3(r.mesh.positions[1], 1e10f, 0, 0);
  expect_vec3(r.mesh.positions[2], 0, 1, static_cast<float>(1.0 / 3.0));
  EXPECT_EQ(r.mesh.uvs[2], glm::vec2(1002.0f, -2.0f));
  EXPECT_EQ(indices_of(r.mesh), (std::vector<std::uint32_t>{2, 1, 0}));
}

TEST(LoadPly, BinaryGenericPathSkipsListsAndElements) {
  for (const bool big_endian : {false, true}) {
    TempDir dir;
    Bytes file(big_endian);
    file.text(ply_header(big_endian ? "binary_big_endian" : "binary_little_endian",
                         "element face 2\n"  // faces before vertices
                         "property uchar flags\n"
                         "property list uchar uint vertex_index\n"
                         "property list int char extra\n"
                         "element material 2\n"
                         "property list uchar double coefficients\n"
                         "property int id\n"
                         "element vertex 4\n"
                         "property float x\nproperty float y\nproperty float z\n"
                         "property list uchar uchar tags\n"
                         "property float u\nproperty float v\n"
                         "property int8 padding\n"));
    file.put<std::uint8_t>(1)
        .put<std::uint8_t>(3)
        .put<std::uint32_t>(0)
        .put<std::uint32_t>(1)
        .put<std::uint32_t>(2);
    file.put<std::int32_t>(2).put<std::int8_t>(-1).put<std::int8_t>(5);
    file.put<std::uint8_t>(0)
        .put<std::uint8_t>(3)
        .put<std::uint32_t>(2)
        .put<std::uint32_t>(1)
        .put<std::uint32_t>(3);
    file.put<std::int32_t>(0);
    file.put<std::uint8_t>(2).put(1.0).put(2.0).put<std::int32_t>(7);
    file.put<std::uint8_t>(0).put<std::int32_t>(8);
    for (int i = 0; i < 4; ++i) {
      file.put(static_cast<float>(i)).put(0.0f).put(-static_cast<float>(i));
      file.put<std::uint8_t>(static_cast<std::uint8_t>(i));
      for (int t = 0; t < i; ++t) file.put<std::uint8_t>(42);
      file.put(0.125f * static_cast<float>(i)).put(1.0f).put<std::int8_t>(0);
    }
    const std::string path = dir.file("generic.ply");
    write_text(path, file.data());
    const Loaded r = load(path);
    ASSERT_TRUE(r.status.is_ok()) << r.status.message();
    ASSERT_EQ(r.mesh.vertex_count(), 4u);
    expect_vec3(r.mesh.positions[3], 3, 0, -3);
    EXPECT_EQ(r.mesh.uvs[2], glm::vec2(0.25f, 1.0f));
    EXPECT_EQ(indices_of(r.mesh), (std::vector<std::uint32_t>{0, 1, 2, 2, 1, 3}));
  }
}

TEST(LoadPly, OptionsDropNormalsAndUvs) {
  TempDir dir;
  const std::string text =
      ply_header("ascii",
                 "element vertex 3\nproperty float x\nproperty float y\nproperty float z\n"
                 "property float nx\nproperty float ny\nproperty float nz\n"
                 "property float u\nproperty float v\n"
                 "element face 1\nproperty list uchar uint vertex_indices\n") +
      "0 0 0 0 0 1 0 0\n1 0 0 0 0 1 1 0\n0 1 0 0 0 1 0 1\n3 0 1 2\n";
  LoadOptions options;
  options.keep_normals = false;
  options.keep_uvs = false;
  const Loaded r = load_text(dir, "opts.ply", text, options);
  ASSERT_TRUE(r.status.is_ok()) << r.status.message();
  EXPECT_FALSE(r.mesh.has_normals());
  EXPECT_FALSE(r.mesh.has_uvs());
  EXPECT_EQ(r.mesh.vertex_count(), 3u);
}

// ------------------------------------------------------------ PLY errors

Status load_status(const std::string& path) {
  Mesh mesh;
  LoadStats stats;
  return load_mesh(path, {}, mesh, stats);
}

void expect_message(const Status& status, const std::string& prefix, const std::string& reason) {
  ASSERT_FALSE(status.is_ok());
  EXPECT_EQ(status.code(), StatusCode::bad_input);
  EXPECT_EQ(status.message().rfind(prefix, 0), 0u) << status.message() << " does not start with " << prefix;
  EXPECT_NE(status.message().find(reason), std::string::npos) << status.message() << " lacks " << reason;
}

const char* kFastHeader =
    "element vertex 3\nproperty float x\nproperty float y\nproperty float z\n"
    "element face 1\nproperty list uchar int vertex_indices\n";

TEST(LoadPlyErrors, BinaryProblemsNameTheByteOffset) {
  TempDir dir;
  const std::string header = ply_header("binary_little_endian", kFastHeader);
  const std::size_t body = header.size();
  auto vertices = [](Bytes& file, float bad) {
    file.put(0.0f).put(0.0f).put(0.0f).put(1.0f).put(bad).put(0.0f).put(0.0f).put(1.0f).put(0.0f);
  };
  const std::string path = dir.file("bad.ply");
  {
    Bytes file(false);
    file.text(header);
    vertices(file, 0.0f);
    file.put<std::uint8_t>(3).put<std::int32_t>(0).put<std::int32_t>(3).put<std::int32_t>(1);
    write_text(path, file.data());
    expect_message(load_status(path), path + ": byte " + std::to_string(body + 36 + 1 + 4) + ": ",
                   "face 0: vertex index 3 out of range (3 vertices)");
  }
  {
    Bytes file(false);
    file.text(header);
    vertices(file, 0.0f);
    file.put<std::uint8_t>(3).put<std::int32_t>(-1).put<std::int32_t>(1).put<std::int32_t>(2);
    write_text(path, file.data());
    expect_message(load_status(path), path + ": byte " + std::to_string(body + 36 + 1) + ": ",
                   "vertex index -1");
  }
  {
    Bytes file(false);
    file.text(header);
    vertices(file, std::numeric_limits<float>::quiet_NaN());
    file.put<std::uint8_t>(3).put<std::int32_t>(0).put<std::int32_t>(1).put<std::int32_t>(2);
    write_text(path, file.data());
    expect_message(load_status(path), path + ": byte " + std::to_string(body + 16) + ": ",
                   "vertex 1: non-finite");
  }
  {
    // Truncated inside the face list: the header still fits the body.
    Bytes file(false);
    file.text(header);
    vertices(file, 0.0f);
    file.put<std::uint8_t>(3).put<std::int32_t>(0).put<std::int32_t>(1);
    write_text(path, file.data());
    expect_message(load_status(path), path + ": byte " + std::to_string(body + 36) + ": ",
                   "file ends inside face 0 of 1");
  }
  {
    // Truncated so much that the header promises more than the file holds.
    Bytes file(false);
    file.text(header);
    file.put(0.0f);
    write_text(path, file.data());
    expect_message(load_status(path), path + ":3: ", "element 'vertex' has 3 entries");
  }
}

TEST(LoadPlyErrors, HeaderAndAsciiProblemsNameTheLine) {
  TempDir dir;
  const std::string path = dir.file("bad.ply");
  auto expect = [&](const std::string& text, int line, const std::string& reason) {
    write_text(path, text);
    expect_message(load_status(path), path + ":" + std::to_string(line) + ": ", reason);
  };
  expect("PLY\nformat ascii 1.0\n", 1, "not a PLY file");
  expect("ply\nformat binary_middle_endian 1.0\nend_header\n", 2, "unknown format 'binary_middle_endian'");
  expect("ply\nformat ascii 1.0\nelement vertex 3\n", 3, "file ends inside the header");
  expect("ply\nformat ascii 1.0\nproperty float x\nend_header\n", 3, "property before any element");
  expect("ply\nformat ascii 1.0\nelement vertex 1\nproperty float128 x\nend_header\n", 4,
         "unknown property type 'float128'");
  expect("ply\nformat ascii 1.0\nelement vertex 1\nproperty float x\nproperty float y\nend_header\n0 0\n", 3,
         "lacks one of the properties x, y, z");
  expect(
      "ply\nformat ascii 1.0\nelement vertex 1\nproperty float x\nproperty float y\nproperty float z\n"
      "property float u\nend_header\n0 0 0 0\n",
      3, "has property 'u' but not 'v'");
  expect("ply\nformat ascii 1.0\nelement vertex 1\nelement face 1\nend_header\n0 0\n", 3,
         "element 'vertex' lacks");
  const std::string header = ply_header("ascii", kFastHeader);  // 9 lines
  expect(header + "0 0 0\n1 0 0\n0 1 zero\n3 0 1 2\n", 12, "bad number 'zero'");
  expect(header + "0 0 0\n1 0 0\n0 1 0\n3 0 1 3\n", 13, "face 0: vertex index 3 out of range (3 vertices)");
  expect(header + "0 0 0\n1 0 0\n0 1 nan\n3 0 1 2\n", 12, "NaN or Inf");
  expect(header + "0 0 0\n1 0 0\n0 1 0\n3 0 1\n", 13, "file ends inside face 0 of 1");
  write_text(path,
             "ply\nformat ascii 1.0\nelement vertex 3\nproperty float x\nproperty float y\nproperty float z\n"
             "end_header\n0 0 0 1 0 0 0 1 0\n");
  expect_message(load_status(path), path + ": no triangles", "no element 'face'");
  write_text(path, header + "0 0 0\n1 0 0\n0 1 0\n2 0 1\n");
  expect_message(load_status(path), path + ": no triangles", "1 faces with fewer than 3 corners");
}

// ------------------------------------------------------------------ save

Mesh awkward_mesh() {
  Mesh mesh;
  mesh.positions = {{0.1f, -0.0f, 3.4e38f},
                    {1e-30f, 1.17549435e-38f, 1e-40f},
                    {-123456.789f, 0.333333343f, 7.0f},
                    {1.0f, 2.0f, 3.0f}};
  mesh.normals = {{0, 0, 1}, {0.6f, 0.8f, 0}, {-0.267261237f, 0.534522474f, 0.801783681f}, {1, 0, 0}};
  mesh.uvs = {{0.1f, 0.9f}, {1.0f / 3.0f, 2.0f / 3.0f}, {-0.5f, 1.5f}, {0, 0}};
  mesh.indices = {0, 1, 2, 0, 2, 3};
  return mesh;
}

bool bitwise_equal(const void* a, const void* b, std::size_t bytes) {
  return bytes == 0 || std::memcmp(a, b, bytes) == 0;  // empty vectors may hold null
}

TEST(SaveMesh, RoundTripIsBitExact) {
  TempDir dir;
  for (const char* name : {"round.obj", "round.ply"}) {
    for (int layout = 0; layout < 4; ++layout) {
      Mesh mesh = awkward_mesh();
      if (layout & 1) mesh.normals.clear();
      if (layout & 2) mesh.uvs.clear();
      const std::string path = dir.file(name);
      const Status saved = save_mesh(path, mesh);
      ASSERT_TRUE(saved.is_ok()) << saved.message();
      const Loaded r = load(path);
      ASSERT_TRUE(r.status.is_ok()) << r.status.message();
      ASSERT_EQ(r.mesh.vertex_count(), mesh.vertex_count()) << name << " layout " << layout;
      EXPECT_TRUE(bitwise_equal(r.mesh.positions.data(), mesh.positions.data(), 12 * mesh.vertex_count()))
          << name << " layout " << layout;
      ASSERT_EQ(r.mesh.normals.size(), mesh.normals.size());
      EXPECT_TRUE(bitwise_equal(r.mesh.normals.data(), mesh.normals.data(), 12 * mesh.normals.size()));
      ASSERT_EQ(r.mesh.uvs.size(), mesh.uvs.size());
      EXPECT_TRUE(bitwise_equal(r.mesh.uvs.data(), mesh.uvs.data(), 8 * mesh.uvs.size()));
      EXPECT_EQ(r.mesh.indices, mesh.indices);
    }
  }
  // Only the two targets remain: no temporary files are left behind.
  std::vector<std::string> names;
  for (const auto& entry : std::filesystem::directory_iterator(dir.path()))
    names.push_back(entry.path().filename());
  std::sort(names.begin(), names.end());
  EXPECT_EQ(names, (std::vector<std::string>{"round.obj", "round.ply"}));
}

TEST(SaveMesh, LargeRoundTripCrossesBufferRefills) {
  // About 5 MB of PLY and 9 MB of OBJ: records straddle the 4 MB read buffer.
  const int side = 300;
  Mesh mesh;
  for (int y = 0; y <= side; ++y) {
    for (int x = 0; x <= side; ++x) {
      const float fx = static_cast<float>(x) / 7.0f;
      const float fy = static_cast<float>(y) / 3.0f;
      mesh.positions.emplace_back(fx, fy, std::sin(fx) * std::cos(fy));
      mesh.normals.push_back(
          glm::normalize(glm::vec3(-std::cos(fx) * std::cos(fy), std::sin(fx) * std::sin(fy), 1.0f)));
      mesh.uvs.emplace_back(static_cast<float>(x) / side, static_cast<float>(y) / side);
    }
  }
  for (int y = 0; y < side; ++y) {
    for (int x = 0; x < side; ++x) {
      const auto a = static_cast<std::uint32_t>(y * (side + 1) + x);
      mesh.indices.insert(mesh.indices.end(), {a, a + 1, a + side + 2, a, a + side + 2, a + side + 1});
    }
  }
  TempDir dir;
  for (const char* name : {"grid.ply", "grid.obj"}) {
    const std::string path = dir.file(name);
    ASSERT_TRUE(save_mesh(path, mesh).is_ok());
    const Loaded r = load(path);
    ASSERT_TRUE(r.status.is_ok()) << r.status.message();
    EXPECT_GT(r.stats.bytes, std::uint64_t{4} << 20) << name;
    ASSERT_EQ(r.mesh.vertex_count(), mesh.vertex_count());
    EXPECT_TRUE(bitwise_equal(r.mesh.positions.data(), mesh.positions.data(), 12 * mesh.vertex_count()))
        << name;
    EXPECT_TRUE(bitwise_equal(r.mesh.normals.data(), mesh.normals.data(), 12 * mesh.vertex_count())) << name;
    EXPECT_TRUE(bitwise_equal(r.mesh.uvs.data(), mesh.uvs.data(), 8 * mesh.vertex_count())) << name;
    EXPECT_EQ(r.mesh.indices, mesh.indices) << name;
  }
}

TEST(SaveMesh, ObjTextIsWhatAReaderExpects) {
  TempDir dir;
  Mesh mesh;
  mesh.positions = {{0, 0, 0}, {1, 0, 0}, {0, 1, 0}};
  mesh.normals = {{0, 0, 1}, {0, 0, 1}, {0, 0, 1}};
  mesh.indices = {0, 1, 2};
  const std::string path = dir.file("n.obj");
  ASSERT_TRUE(save_mesh(path, mesh).is_ok());
  std::ifstream in(path);
  const std::string text((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
  EXPECT_NE(text.find("\nv 1 0 0\n"), std::string::npos) << text;
  EXPECT_NE(text.find("\nvn 0 0 1\n"), std::string::npos) << text;
  EXPECT_NE(text.find("\nf 1//1 2//2 3//3\n"), std::string::npos) << text;
}

TEST(SaveMesh, Errors) {
  TempDir dir;
  Mesh mesh = awkward_mesh();
  Status status = save_mesh(dir.file("mesh.stl"), mesh);
  EXPECT_EQ(status.code(), StatusCode::bad_input);
  status = save_mesh(dir.file("no_such_folder/mesh.obj"), mesh);
  EXPECT_EQ(status.code(), StatusCode::io);
  EXPECT_NE(status.message().find("no_such_folder/mesh.obj: cannot write: No such file or directory"),
            std::string::npos)
      << status.message();
  mesh.positions[1].y = std::numeric_limits<float>::infinity();
  status = save_mesh(dir.file("inf.obj"), mesh);
  EXPECT_EQ(status.code(), StatusCode::bad_input);
  EXPECT_FALSE(std::filesystem::exists(dir.file("inf.obj")));
}

// ------------------------------------------------------------- benchmark

// Rough load speed on a generated 2M-triangle grid (about 100 MB of OBJ):
// run with --gtest_also_run_disabled_tests --gtest_filter='*LoadSpeed*'.
TEST(LoadBenchmark, DISABLED_LoadSpeed) {
  TempDir dir;
  const int side = 1000;  // (side)^2 quads, 2 * side^2 triangles
  Mesh grid;
  grid.positions.reserve((side + 1) * (side + 1));
  for (int y = 0; y <= side; ++y) {
    for (int x = 0; x <= side; ++x) {
      const float fx = static_cast<float>(x) / side;
      const float fy = static_cast<float>(y) / side;
      grid.positions.emplace_back(fx, fy, 0.05f * std::sin(17.0f * fx) * std::cos(13.0f * fy));
    }
  }
  grid.normals.assign(grid.positions.size(), glm::vec3(0.0f, 0.0f, 1.0f));
  for (int y = 0; y < side; ++y) {
    for (int x = 0; x < side; ++x) {
      const std::uint32_t a = static_cast<std::uint32_t>(y * (side + 1) + x);
      const std::uint32_t b = a + 1;
      const std::uint32_t c = a + side + 2;
      const std::uint32_t d = a + side + 1;
      grid.indices.insert(grid.indices.end(), {a, b, c, a, c, d});
    }
  }
  auto report = [](const char* what, const Loaded& r, double seconds) {
    std::printf("load %-16s %8.1f MB  %6.3f s  %7.1f MB/s  %6.2f Mtri/s\n", what,
                static_cast<double>(r.stats.bytes) / 1e6, seconds,
                static_cast<double>(r.stats.bytes) / 1e6 / seconds,
                static_cast<double>(r.stats.triangles) / 1e6 / seconds);
  };
  {
    // Split path: every corner uses the single normal 1, so v != vn.
    std::string text;
    text.reserve(std::size_t{120} << 20);
    char line[128];
    for (const glm::vec3& p : grid.positions) {
      text.append(line, static_cast<std::size_t>(
                            std::snprintf(line, sizeof(line), "v %.9g %.9g %.9g\n", p.x, p.y, p.z)));
    }
    text += "vn 0 0 1\n";
    for (std::size_t t = 0; t < grid.triangle_count(); ++t) {
      text.append(line, static_cast<std::size_t>(std::snprintf(
                            line, sizeof(line), "f %u//1 %u//1 %u//1\n", grid.indices[3 * t] + 1,
                            grid.indices[3 * t + 1] + 1, grid.indices[3 * t + 2] + 1)));
    }
    const std::string path = dir.file("split.obj");
    write_text(path, text);
    const auto start = std::chrono::steady_clock::now();
    const Loaded r = load(path);
    const double seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
    ASSERT_TRUE(r.status.is_ok()) << r.status.message();
    ASSERT_EQ(r.mesh.triangle_count(), grid.triangle_count());
    ASSERT_EQ(r.mesh.vertex_count(), grid.vertex_count());
    report("obj split", r, seconds);
  }
  for (const char* name : {"grid.obj", "grid.ply"}) {
    for (const bool normals : {false, true}) {
      Mesh mesh = grid;
      if (!normals) mesh.normals.clear();
      const std::string path = dir.file(name);
      ASSERT_TRUE(save_mesh(path, mesh).is_ok());
      const auto start = std::chrono::steady_clock::now();
      const Loaded r = load(path);
      const double seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
      ASSERT_TRUE(r.status.is_ok()) << r.status.message();
      ASSERT_EQ(r.mesh.triangle_count(), grid.triangle_count());
      report((std::string(name) + (normals ? " +normals" : "")).c_str(), r, seconds);
    }
  }
}

}  // namespace
}  // namespace nmbake
