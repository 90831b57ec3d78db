// The parallel block decoders of the load stage against the one-thread
// reference parsers (LoadOptions::serial): meshes spanning many small blocks,
// loaded with one and two threads, must give the same arrays, counters and
// error messages as the reference.
#include <gtest/gtest.h>
#include <tbb/global_control.h>

#include <cmath>
#include <cstdint>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <limits>
#include <random>
#include <string>
#include <vector>

#include "nmbake/load.hpp"
#include "test_util.hpp"

namespace nmbake {
namespace {

using test::TempDir;
using test::write_text;

// A binary PLY body in either byte order.
class PlyBytes {
 public:
  explicit PlyBytes(bool big_endian) : big_endian_(big_endian) {}
  template <typename T>
  void put(T value) {
    unsigned char raw[sizeof(T)];
    std::memcpy(raw, &value, sizeof(T));
    if (big_endian_ == host_is_little_endian()) {
      for (std::size_t i = 0; i < sizeof(T) / 2; ++i) std::swap(raw[i], raw[sizeof(T) - 1 - i]);
    }
    data_.append(reinterpret_cast<const char*>(raw), sizeof(T));
  }
  void text(const std::string& s) { data_ += s; }
  const std::string& data() const { return data_; }
  std::size_t size() const { return data_.size(); }

 private:
  static bool host_is_little_endian() {
    const std::uint16_t one = 1;
    unsigned char first = 0;
    std::memcpy(&first, &one, 1);
    return first == 1;
  }
  bool big_endian_;
  std::string data_;
};

// A grid of side x side vertices with irregular coordinates, two triangles
// per cell; `quad_cells` lists cells written as one quad instead.
struct GridPly {
  int side = 60;
  bool big_endian = false;
  bool doubles = false;  // vertex values as float64 (the generic stride decode)
  bool with_uvs = true;
  std::vector<int> quad_cells;
  int nan_vertex = -1;      // this vertex's y is NaN
  int bad_index_face = -1;  // this face's last index is out of range

  std::string bytes() const {
    const int vertex_count = side * side;
    const int cell_count = (side - 1) * (side - 1);
    const int face_count = 2 * cell_count - static_cast<int>(quad_cells.size());
    PlyBytes file(big_endian);
    const char* type = doubles ? "double" : "float";
    std::string header = std::string("ply\nformat ") +
                         (big_endian ? "binary_big_endian" : "binary_little_endian") +
                         " 1.0\nelement vertex " + std::to_string(vertex_count) + "\n";
    for (const char* name : {"x", "y", "z", "nx", "ny", "nz"})
      header += std::string("property ") + type + " " + name + "\n";
    if (with_uvs) header += std::string("property ") + type + " u\nproperty " + type + " v\n";
    header += "element face " + std::to_string(face_count) +
              "\nproperty list uchar int vertex_indices\nend_header\n";
    file.text(header);
    for (int v = 0; v < vertex_count; ++v) {
      const float x = static_cast<float>(v % side) + 0.001f * static_cast<float>((v * 7919) % 997);
      const float y =
          v == nan_vertex ? std::numeric_limits<float>::quiet_NaN() : static_cast<float>(v / side);
      const float z = std::sin(static_cast<float>(v) * 0.37f);
      float values[8] = {x, y, z, 0.0f, z, 1.0f, x / static_cast<float>(side), y / static_cast<float>(side)};
      for (int i = 0; i < (with_uvs ? 8 : 6); ++i) {
        if (doubles) {
          file.put(static_cast<double>(values[i]));
        } else {
          file.put(values[i]);
        }
      }
    }
    int face = 0;
    auto put_face = [&](std::initializer_list<int> corners) {
      file.put(static_cast<std::uint8_t>(corners.size()));
      int c = 0;
      for (const int corner : corners) {
        const bool bad = face == bad_index_face && ++c == static_cast<int>(corners.size());
        file.put(static_cast<std::int32_t>(bad ? vertex_count : corner));
      }
      ++face;
    };
    for (int cell = 0; cell < cell_count; ++cell) {
      const int row = cell / (side - 1);
      const int column = cell % (side - 1);
      const int a = row * side + column;
      const int b = a + 1;
      const int c = a + side + 1;
      const int d = a + side;
      bool quad = false;
      for (const int q : quad_cells) quad |= q == cell;
      if (quad) {
        put_face({a, b, c, d});
      } else {
        put_face({a, b, c});
        put_face({a, c, d});
      }
    }
    return file.data();
  }
};

struct Loaded {
  Status status;
  Mesh mesh;
  LoadStats stats;
};

Loaded load(const std::string& path, bool serial, int threads, std::size_t block_bytes = 1000,
            LoadOptions options = {}) {
  tbb::global_control control(tbb::global_control::max_allowed_parallelism,
                              static_cast<std::size_t>(threads));
  options.serial = serial;
  options.block_bytes = block_bytes;
  Loaded result;
  result.status = load_mesh(path, options, result.mesh, result.stats);
  return result;
}

// Bitwise, so -0 and NaN payloads count too.
template <typename T>
bool same_bits(const std::vector<T>& a, const std::vector<T>& b) {
  return a.size() == b.size() && (a.empty() || std::memcmp(a.data(), b.data(), a.size() * sizeof(T)) == 0);
}

void expect_same(const Loaded& reference, const Loaded& other) {
  ASSERT_EQ(reference.status.is_ok(), other.status.is_ok()) << other.status.message();
  EXPECT_EQ(reference.status.message(), other.status.message());
  EXPECT_TRUE(same_bits(reference.mesh.positions, other.mesh.positions));
  EXPECT_TRUE(same_bits(reference.mesh.normals, other.mesh.normals));
  EXPECT_TRUE(same_bits(reference.mesh.uvs, other.mesh.uvs));
  EXPECT_TRUE(same_bits(reference.mesh.indices, other.mesh.indices));
  EXPECT_TRUE(same_bits(reference.mesh.colors, other.mesh.colors));
  EXPECT_EQ(reference.mesh.parts, other.mesh.parts);
  EXPECT_EQ(reference.mesh.materials, other.mesh.materials);
  EXPECT_EQ(reference.stats.polygons, other.stats.polygons);
  EXPECT_EQ(reference.stats.triangles, other.stats.triangles);
  EXPECT_EQ(reference.stats.degenerate_faces, other.stats.degenerate_faces);
}

// The reference, then the block decoders with 1 and 2 threads and a few
// block sizes (1000 bytes: ~30 vertex records, ~75 triangles a block).
Loaded expect_blocks_match_reference(const std::string& path) {
  Loaded reference = load(path, true, 1);
  for (const int threads : {1, 2}) {
    for (const std::size_t block : {std::size_t{1000}, std::size_t{4093}, std::size_t{0}}) {
      SCOPED_TRACE("threads " + std::to_string(threads) + ", block " + std::to_string(block));
      expect_same(reference, load(path, false, threads, block));
    }
  }
  return reference;
}

TEST(LoadParallelPly, BlocksMatchTheReferenceInBothByteOrders) {
  TempDir dir;
  for (const bool big_endian : {false, true}) {
    for (const bool doubles : {false, true}) {
      SCOPED_TRACE(std::string(big_endian ? "big" : "little") + " endian, " +
                   (doubles ? "doubles" : "floats"));
      GridPly grid;
      grid.big_endian = big_endian;
      grid.doubles = doubles;
      const std::string path = dir.file("grid.ply");
      write_text(path, grid.bytes());
      const Loaded reference = expect_blocks_match_reference(path);
      ASSERT_TRUE(reference.status.is_ok()) << reference.status.message();
      EXPECT_EQ(reference.mesh.vertex_count(), 3600u);
      EXPECT_EQ(reference.stats.triangles, 2u * 59u * 59u);
      EXPECT_EQ(reference.mesh.positions[61].y, 1.0f);  // decoded, not left at zero
      EXPECT_EQ(reference.mesh.uvs.size(), 3600u);
    }
  }
}

TEST(LoadParallelPly, PolygonsBetweenTrianglesResumeTheBlocks) {
  // Quads in the first face, in the middle of a block, on a block edge and
  // last: each one leaves the block decoder and comes back.
  TempDir dir;
  GridPly grid;
  grid.with_uvs = false;
  grid.quad_cells = {0, 37, 38, 75, 1000, 59 * 59 - 1};
  const std::string path = dir.file("mixed.ply");
  write_text(path, grid.bytes());
  const Loaded reference = expect_blocks_match_reference(path);
  ASSERT_TRUE(reference.status.is_ok()) << reference.status.message();
  EXPECT_EQ(reference.stats.polygons, 2u * 59u * 59u - 6u);
  EXPECT_EQ(reference.stats.triangles, 2u * 59u * 59u);
}

TEST(LoadParallelPly, ErrorsInLateBlocksNameTheSameByte) {
  TempDir dir;
  const std::string path = dir.file("bad.ply");
  for (const bool big_endian : {false, true}) {
    SCOPED_TRACE(big_endian ? "big endian" : "little endian");
    {
      GridPly grid;
      grid.big_endian = big_endian;
      grid.nan_vertex = 3000;
      write_text(path, grid.bytes());
      const Loaded reference = expect_blocks_match_reference(path);
      EXPECT_NE(reference.status.message().find("vertex 3000: non-finite"), std::string::npos)
          << reference.status.message();
    }
    {
      GridPly grid;
      grid.big_endian = big_endian;
      grid.bad_index_face = 6000;
      write_text(path, grid.bytes());
      const Loaded reference = expect_blocks_match_reference(path);
      EXPECT_NE(reference.status.message().find("face 6000: vertex index 3600 out of range"),
                std::string::npos)
          << reference.status.message();
    }
    {
      // Cut inside the last triangles: the header count still fits.
      GridPly grid;
      grid.big_endian = big_endian;
      std::string bytes = grid.bytes();
      bytes.resize(bytes.size() - 20);
      write_text(path, bytes);
      const Loaded reference = expect_blocks_match_reference(path);
      EXPECT_NE(reference.status.message().find("file ends inside face"), std::string::npos)
          << reference.status.message();
    }
  }
}

// A grid of side x side vertices as OBJ text, each v followed by its vt and
// vn. Rows of faces come right after the vertex row that closes them, odd
// rows with relative indices reaching back two vertex rows (many slices when
// the blocks are small). Every 7th cell is a quad.
// With `materials`, faces before the first `usemtl` (the one of the header
// is left out), then a `usemtl` every 4th row: moss, moss (one range),
// stone, rust, moss again, ...; an `o` every 10th row (parts). With
// `colors`, "v x y z r g b" except on every 13th vertex (white).
struct GridObj {
  int side = 40;
  bool split = true;  // a corner's vn is its face row's first vertex: most vertices split
  bool crlf = false;
  bool final_newline = true;
  bool materials = false;
  bool colors = false;
  std::vector<std::pair<std::size_t, std::string>> replaced;  // line index, new text

  static std::string material_of_row(int row) {
    static const char* const kNames[] = {"moss", "moss", "stone", "rust"};
    return kNames[(row / 4) % 4];
  }

  std::vector<std::string> lines() const {
    std::vector<std::string> out = {"# nmbake parallel OBJ test",
                                    "mtllib grid.mtl",
                                    "o grid",
                                    "g rows",
                                    materials ? "# no material yet" : "usemtl stone",
                                    "s 1"};
    char text[160];
    int defined = 0;  // v (= vt = vn) statements so far
    for (int row = 0; row < side; ++row) {
      for (int column = 0; column < side; ++column) {
        const int v = row * side + column;
        const double z = std::sin(static_cast<double>(v) * 0.37) * 1e-3;
        char color[64] = "";
        if (colors && v % 13 != 0) {
          std::snprintf(color, sizeof(color), " %.6g %.6g 0.5", column / static_cast<double>(side),
                        row / static_cast<double>(side));
        }
        std::snprintf(text, sizeof(text), "v %.9g %.9g %.9g%s%s", column + 0.001 * ((v * 7919) % 997),
                      row * 1.5, z, color, v % 11 == 0 ? " # trailing comment" : "");
        out.emplace_back(text);
        std::snprintf(text, sizeof(text), "vt %.7g %.7g", column / static_cast<double>(side), row * 0.25);
        out.emplace_back(text);
        std::snprintf(text, sizeof(text), "vn %.6g %.6g 1", z, -z);
        out.emplace_back(text);
        ++defined;
      }
      if (row == 0) continue;
      if (materials && row % 4 == 0) out.push_back("usemtl " + material_of_row(row));
      if (materials && row % 10 == 0) out.push_back("o block" + std::to_string(row / 10));
      if (row % 5 == 0) {
        out.emplace_back("# row " + std::to_string(row));
        out.emplace_back("l 1 2");
        out.emplace_back("f 1/1/1 2/2/2");  // a line: skipped and counted
      }
      const bool relative = row % 2 == 1;
      auto corner = [&](int vertex, int face_row) {  // vertex 0-based
        const int vn = split ? face_row * side : vertex;
        auto number = [&](int index) { return relative ? index - defined : index + 1; };
        return std::to_string(number(vertex)) + "/" + std::to_string(number(vertex)) + "/" +
               std::to_string(number(vn));
      };
      for (int column = 0; column + 1 < side; ++column) {
        const int a = (row - 1) * side + column;
        const int b = a + 1;
        const int c = a + side + 1;
        const int d = a + side;
        const int face_row = row - 1;
        if ((a % 7) == 0) {
          out.push_back("f " + corner(a, face_row) + " " + corner(b, face_row) + " " + corner(c, face_row) +
                        " " + corner(d, face_row));
        } else {
          out.push_back("f " + corner(a, face_row) + " " + corner(b, face_row) + " " + corner(c, face_row));
          out.push_back("f\t" + corner(a, face_row) + "  " + corner(c, face_row) + " " + corner(d, face_row));
        }
      }
    }
    for (const auto& [index, line] : replaced) out.at(index) = line;
    return out;
  }

  std::string text() const {
    std::string out;
    const std::vector<std::string> all = lines();
    for (std::size_t i = 0; i < all.size(); ++i) {
      out += all[i];
      if (i + 1 < all.size() || final_newline) out += crlf ? "\r\n" : "\n";
    }
    return out;
  }
};

// The reference, then the slices with 1 and 2 threads and block sizes from
// below a line (16 bytes) to the default.
Loaded expect_obj_slices_match_reference(const std::string& path, const LoadOptions& options = {}) {
  Loaded reference = load(path, true, 1, 0, options);
  for (const int threads : {1, 2}) {
    for (const std::size_t block : {std::size_t{16}, std::size_t{64}, std::size_t{300}, std::size_t{1000},
                                    std::size_t{4093}, std::size_t{0}}) {
      SCOPED_TRACE("threads " + std::to_string(threads) + ", block " + std::to_string(block));
      expect_same(reference, load(path, false, threads, block, options));
    }
  }
  return reference;
}

TEST(LoadParallelObj, SlicesMatchTheReference) {
  TempDir dir;
  const std::string path = dir.file("grid.obj");
  for (const bool split : {false, true}) {
    for (const bool crlf : {false, true}) {
      for (const bool final_newline : {true, false}) {
        SCOPED_TRACE(std::string(split ? "split" : "identity") + (crlf ? ", CRLF" : ", LF") +
                     (final_newline ? "" : ", no final newline"));
        GridObj grid;
        grid.split = split;
        grid.crlf = crlf;
        grid.final_newline = final_newline;
        write_text(path, grid.text());
        const Loaded reference = expect_obj_slices_match_reference(path);
        ASSERT_TRUE(reference.status.is_ok()) << reference.status.message();
        EXPECT_EQ(reference.stats.degenerate_faces, 7u);
        EXPECT_EQ(reference.stats.triangles, 2u * 39u * 39u);
        if (split) {
          EXPECT_GT(reference.mesh.vertex_count(), 1600u);
        } else {
          EXPECT_EQ(reference.mesh.vertex_count(), 1600u);
        }
        EXPECT_EQ(reference.mesh.positions[41].y, 1.5f);  // parsed, not left at zero
        // Without UVs (a high mesh) and without normals too.
        LoadOptions high;
        high.keep_uvs = false;
        expect_obj_slices_match_reference(path, high);
        high.keep_normals = false;
        expect_obj_slices_match_reference(path, high);
      }
    }
  }
}

// usemtl and vertex colours read by the slices exactly as by the serial
// parser, whatever the block (names and colours across slice and block
// boundaries), split or not.
TEST(LoadParallelObj, MaterialsAndColoursMatchTheReference) {
  TempDir dir;
  const std::string path = dir.file("grid.obj");
  for (const bool split : {false, true}) {
    SCOPED_TRACE(split ? "split" : "identity");
    GridObj grid;
    grid.split = split;
    grid.materials = true;
    grid.colors = true;
    write_text(path, grid.text());
    LoadOptions options;
    options.keep_uvs = false;
    options.keep_colors = true;
    const Loaded reference = expect_obj_slices_match_reference(path, options);
    ASSERT_TRUE(reference.status.is_ok()) << reference.status.message();
    // Rows 1-3 of faces have no material; then moss (rows 4-7), stone,
    // rust, moss (rows 16-23: two statements, one range), stone, rust, moss.
    const std::uint32_t row = 2 * 39;  // triangles of a row of cells
    const std::vector<MeshPart> expected{{"", 0, 3 * row},
                                         {"moss", 3 * row, 4 * row},
                                         {"stone", 7 * row, 4 * row},
                                         {"rust", 11 * row, 4 * row},
                                         {"moss", 15 * row, 8 * row},
                                         {"stone", 23 * row, 4 * row},
                                         {"rust", 27 * row, 4 * row},
                                         {"moss", 31 * row, 8 * row}};
    const std::vector<MeshPart>& materials = reference.mesh.materials;
    EXPECT_EQ(materials, expected);
    EXPECT_EQ(reference.mesh.parts.size(), 4u);  // grid, block1, block2, block3
    // Colours follow the positions; a v without one is white.
    ASSERT_TRUE(reference.mesh.has_colors());
    bool white = false, coloured = false;
    for (std::size_t i = 0; i < reference.mesh.vertex_count(); ++i) {
      const glm::vec4& c = reference.mesh.colors[i];
      if (c == glm::vec4(1.0f)) {
        white = true;
        continue;
      }
      coloured = true;
      EXPECT_FLOAT_EQ(c.g, std::round(reference.mesh.positions[i].y / 1.5f) / 40.0f) << i;
      EXPECT_EQ(c.b, 0.5f);
      EXPECT_EQ(c.a, 1.0f);
    }
    EXPECT_TRUE(white && coloured);
    // Not asked for: none, and the rest of the mesh is the same.
    options.keep_colors = false;
    const Loaded plain = expect_obj_slices_match_reference(path, options);
    EXPECT_FALSE(plain.mesh.has_colors());
    EXPECT_EQ(plain.mesh.materials, materials);
    EXPECT_TRUE(same_bits(plain.mesh.indices, reference.mesh.indices));
  }
}

// A file of several default-sized blocks (4 MiB), each cut into slices on
// two threads: the same mesh, names and colours as the serial parser.
TEST(LoadParallelObj, LargeFileWithMaterialsMatchesTheReference) {
  TempDir dir;
  const std::string path = dir.file("large.obj");
  GridObj grid;
  grid.side = 330;
  grid.materials = true;
  grid.colors = true;
  write_text(path, grid.text());
  ASSERT_GT(std::filesystem::file_size(path), 3u * (std::uint64_t{4} << 20));
  LoadOptions options;
  options.keep_colors = true;
  const Loaded reference = load(path, true, 1, 0, options);
  ASSERT_TRUE(reference.status.is_ok()) << reference.status.message();
  EXPECT_GT(reference.mesh.materials.size(), 50u);
  expect_same(reference, load(path, false, 2, 0, options));
}

// Every corner form (a, a/b, a//c, a/b/c) in a file of its own, with the
// spellings the slices' one-pass line reader leaves to the general one
// mixed in at random (a leading blank, '+', tabs, comments after a
// statement, exponents, mantissas longer than 19 digits, a w or a third vt
// number, relative and zero-padded indices, quads, lines, CRLF), and a
// corner that splits a vertex late in some files: the same mesh as the
// serial reference.
TEST(LoadParallelObj, EveryLineSpellingMatchesTheReference) {
  TempDir dir;
  const std::string path = dir.file("forms.obj");
  std::mt19937 rng(7);
  const auto pick = [&](int n) { return static_cast<int>(rng() % static_cast<unsigned>(n)); };
  const auto real = [&](double x) {
    char text[96];
    switch (pick(8)) {
      case 0:
        std::snprintf(text, sizeof text, "%.3e", x);
        break;
      case 1:
        std::snprintf(text, sizeof text, "%s%.9g", std::signbit(x) ? "" : "+", x);
        break;
      case 2:
        std::snprintf(text, sizeof text, "%.25f", x);
        break;
      case 3:
        std::snprintf(text, sizeof text, "%.17g", x);
        break;
      case 4:
        std::snprintf(text, sizeof text, "%.1f", x);
        break;
      default:
        std::snprintf(text, sizeof text, "%.8g", x);
        break;
    }
    return std::string(text);
  };
  for (const char* form : {"a", "a/b", "a//c", "a/b/c"}) {
    for (const bool split_late : {false, true}) {
      SCOPED_TRACE(std::string(form) + (split_late ? ", split late" : ""));
      const bool with_vt = std::strchr(form, 'b') != nullptr;
      const bool with_vn = std::strchr(form, 'c') != nullptr;
      const int side = 30;
      std::string text = "# forms\n";
      int defined = 0;
      for (int row = 0; row < side; ++row) {
        for (int column = 0; column < side; ++column) {
          const double x = column * 0.37 - 3.1, y = row * 1e-3, z = std::sin(column + row * 0.5);
          const std::string blank = pick(10) == 0 ? "\t" : " ";
          std::string line = (pick(15) == 0 ? " v" : "v") + blank + real(x) + " " + real(y) + blank + real(z);
          if (pick(12) == 0) line += " 1";
          if (pick(12) == 0) line += " # c";
          text += line + (pick(9) == 0 ? "\r\n" : "\n");
          if (with_vt)
            text += "vt " + real(column / 30.0) + (pick(4) == 0 ? "" : " " + real(row / 30.0)) +
                    (pick(8) == 0 ? " 0" : "") + "\n";
          if (with_vn) text += "vn " + real(z) + " " + real(-z) + " 1\n";
          ++defined;
        }
        if (row == 0) continue;
        if (pick(4) == 0) text += "# row\n\n";
        if (pick(6) == 0) {
          const std::string one = with_vt ? (with_vn ? "1/1/1" : "1/1") : (with_vn ? "1//1" : "1");
          text += "f " + one + " " + one + "\n";  // a line: skipped and counted
        }
        for (int column = 0; column + 1 < side; ++column) {
          const int a = (row - 1) * side + column;
          const int quad[4] = {a, a + 1, a + side + 1, a + side};
          const bool late = split_late && row == side - 2 && column == 5;
          const auto corner = [&](int vertex) {
            const bool relative = pick(5) == 0;
            const auto number = [&](int index) {
              std::string n = std::to_string(relative ? index - defined : index + 1);
              return pick(40) == 0 && n[0] != '-' ? "0" + n : n;
            };
            const std::string v = number(vertex);
            const std::string other = late ? number(0) : v;
            if (!with_vt && !with_vn) return v;
            if (!with_vn) return v + "/" + other;
            if (!with_vt) return v + "//" + other;
            return v + "/" + other + "/" + other;
          };
          const std::string gap = pick(10) == 0 ? "  " : " ";
          std::string line = "f" + gap + corner(quad[0]) + " " + corner(quad[1]) + gap + corner(quad[2]);
          if (pick(3) == 0) {
            line += " " + corner(quad[3]);
          } else {
            line += "\nf " + corner(quad[0]) + " " + corner(quad[2]) + " " + corner(quad[3]);
          }
          if (pick(20) == 0) line += " # c";
          text += line + "\n";
        }
      }
      write_text(path, text);
      const Loaded reference = expect_obj_slices_match_reference(path);
      ASSERT_TRUE(reference.status.is_ok()) << reference.status.message();
      EXPECT_EQ(reference.mesh.vertex_count() > 900u, split_late && (with_vt || with_vn));
      LoadOptions high;
      high.keep_uvs = false;
      expect_obj_slices_match_reference(path, high);
      high.keep_normals = false;
      expect_obj_slices_match_reference(path, high);
      LoadOptions corner_uvs = high;
      corner_uvs.corner_uvs = true;
      expect_obj_slices_match_reference(path, corner_uvs);
    }
  }
}

// Lines longer than the room the reader keeps for a block's unread tail
// when it joins the bytes read ahead (64 KiB, FileReader::join_ahead()),
// falling across block ends: the same mesh as the serial reference.
TEST(LoadParallelObj, LongLinesAcrossReadAheadBlocksMatchTheReference) {
  TempDir dir;
  const std::string path = dir.file("long.obj");
  GridObj grid;
  grid.side = 60;
  const std::vector<std::string> lines = grid.lines();
  std::string text;
  for (std::size_t i = 0; i < lines.size(); ++i) {
    if (i % 100 == 50) text += "# " + std::string(100000 + i, 'x') + "\n";
    text += lines[i] + "\n";
  }
  ASSERT_GT(text.size(), std::size_t{8} << 20);  // twice the reader's buffer
  write_text(path, text);
  const Loaded reference = load(path, true, 1, 0);
  ASSERT_TRUE(reference.status.is_ok()) << reference.status.message();
  for (const std::size_t block :
       {std::size_t{70000}, std::size_t{150000}, std::size_t{333333}, std::size_t{0}}) {
    SCOPED_TRACE("block " + std::to_string(block));
    expect_same(reference, load(path, false, 2, block));
  }
}

TEST(LoadParallelObj, ErrorsInLateSlicesNameTheSameLine) {
  TempDir dir;
  const std::string path = dir.file("bad.obj");
  GridObj grid;
  const std::size_t line_count = grid.lines().size();
  // Line indices: a late vertex row, and a face line near the end.
  std::size_t late_vertex = 0;
  std::size_t late_face = 0;
  {
    const std::vector<std::string> lines = grid.lines();
    for (std::size_t i = line_count * 3 / 4; late_vertex == 0; ++i) {
      if (lines[i].rfind("v ", 0) == 0) late_vertex = i;
    }
    for (std::size_t i = line_count - 20; late_face == 0; ++i) {
      if (lines[i].rfind("f ", 0) == 0) late_face = i;
    }
  }
  struct Case {
    std::size_t line;
    std::string text;
    std::string reason;
  };
  const std::vector<Case> cases = {
      {late_vertex, "v 1.0 abc 2.0", "bad number 'abc'"},
      {late_vertex, "v 1.0 2.0", "expected 3 numbers, found 2"},
      {late_vertex + 1, "vt 1e99999 0", "number out of range"},
      {late_face, "f 1/1/1 2/2/2 999999/3/3", "vertex index 999999 out of range"},
      {late_face, "f 1/1/1 2/2/2 -99999/3/3", "vertex index -99999 out of range"},
      {late_face, "f 1/1/1 2/2/2 3/3/99999", "normal index 99999 out of range"},
      {late_face, "f 0/1/1 2/2/2 3/3/3", "vertex index 0"},
      {late_face, "f 1/1/1 2/0/2 3/3/3", "texture coordinate index 0"},
      {late_face, "f 1/1/1 2/2/2 3/3/x", "bad normal index 'x'"},
      {late_face, "f 1/1/1 2/2/2 3/3/", "missing normal index"},
      {late_face, "f 1//1 2//2 3//3", "has no texture coordinate index"},
      // The edges of the slice parser's own digit reader.
      {late_face, "f 1/1/1 2/2/2 -0/3/3", "vertex index 0"},
      {late_face, "f 1/1/1 2/2/2 -/3/3", "bad vertex index '-'"},
      {late_face, "f 1/1/1 2/2/2 --3/3/3", "bad vertex index '--3'"},
      {late_face, "f 1/1/1 2/2/2 123456789012345678/3/3", "vertex index 123456789012345678 out of range"},
      {late_face, "f 1/1/1 2/2/2 99999999999999999999/3/3", "bad vertex index '99999999999999999999'"},
      {late_face, "f 1/1/1 2/2/2 +99999/3/3", "vertex index 99999 out of range"},
      {late_face, "f +1/01/1 2/2/+2 0003/-00000000000000000001/3", ""},  // valid
  };
  for (const Case& c : cases) {
    SCOPED_TRACE(c.text);
    grid.replaced = {{c.line, c.text}};
    write_text(path, grid.text());
    const Loaded reference = expect_obj_slices_match_reference(path);
    if (c.reason.empty()) {
      EXPECT_TRUE(reference.status.is_ok()) << reference.status.message();
      continue;
    }
    // Appended piecewise: GCC 12 warns falsely (-Wrestrict) on ":" + string.
    std::string where(1, ':');
    where += std::to_string(c.line + 1);
    where += ": ";
    EXPECT_NE(reference.status.message().find(where), std::string::npos) << reference.status.message();
    EXPECT_NE(reference.status.message().find(c.reason), std::string::npos) << reference.status.message();
  }
}

TEST(LoadParallelValidate, FirstBadElementIsReportedWithTwoThreads) {
  // Several bad values far apart: the lowest index is the one named.
  Mesh mesh;
  const std::size_t vertex_count = 300000;
  mesh.positions.assign(vertex_count, glm::vec3(1.0f));
  mesh.indices.assign(3 * 200000, 0u);
  for (std::size_t i = 0; i < mesh.indices.size(); ++i)
    mesh.indices[i] = static_cast<std::uint32_t>(i % vertex_count);
  tbb::global_control control(tbb::global_control::max_allowed_parallelism, 2);
  mesh.positions[250000].y = std::numeric_limits<float>::infinity();
  mesh.positions[170001].z = std::numeric_limits<float>::quiet_NaN();
  EXPECT_NE(validate_mesh(mesh, "m").message().find("m: vertex 170001 has a non-finite position"),
            std::string::npos);
  mesh.positions.assign(vertex_count, glm::vec3(1.0f));
  mesh.indices[590000] = 300000;
  mesh.indices[400001] = 300001;
  EXPECT_NE(validate_mesh(mesh, "m").message().find("m: triangle 133333 refers to vertex 300001"),
            std::string::npos)
      << validate_mesh(mesh, "m").message();
}

}  // namespace
}  // namespace nmbake
