// Wavefront OBJ reader: the geometry statements of the Wavefront Advanced
// Visualizer manual, appendix B1 "Object Files (.obj)" (v, vt, vn, f with
// absolute and relative indices), enough to bake from any modeller's export.
//
// Vertices of the output are the distinct (v, vt, vn) index combinations the
// faces use, restricted to the attributes LoadOptions keeps. Two paths:
//   * identity: while every corner uses the same number for v and its kept
//     vt/vn (or has none), vertex i is simply file vertex i; nothing but the
//     index arrays is built. Sculpting tools write high meshes like this.
//   * split: at the first corner that breaks this, the indices so far are
//     converted and every further corner is looked up in a per-position chain
//     of the combinations already seen (no hash map: positions are the
//     natural bucket and chains are short), new combinations appended in order
//     of first use. Deterministic, no per-vertex allocation.
// Indices must refer to data defined earlier in the file (the manual's rule),
// which lets every error name its line. Vertices no face uses are dropped by
// load_mesh.
//
// Names: `o` and `g` make parts, `usemtl` materials (the manual's appendix
// B1 "Grouping" and "Display/render attributes" statements), both as ranges
// of the triangles that follow (finish_ranges()). Vertex colours, with
// LoadOptions::keep_colors: the "v x y z r g b" extension that MeshLab,
// Open3D and other tools write (not in the manual; read_vertex_color()).
//
// Parallel path: the file is read in blocks (LoadOptions::block_bytes), each
// cut at line boundaries into a few slices per core. The slices are parsed on
// all cores into raw records (reals, and face corners as the written, possibly
// negative, numbers with the slice-local counts of v/vt/vn before the face);
// then the slices are applied in file order by the same code as the serial
// path, so relative indices, vertex splitting and numbering are unchanged.
// Whatever the slice parser does not accept (a syntax error, an index out of
// range, a layout change) sends the rest of that slice through the serial
// line parser from the state just before that line, so messages and line
// numbers are the serial ones.
#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>
#include <tbb/task_arena.h>

#include <algorithm>
#include <cmath>
#include <cstring>
#include <glm/vec2.hpp>
#include <glm/vec3.hpp>
#include <glm/vec4.hpp>
#include <string>
#include <string_view>
#include <type_traits>
#include <vector>

#include "base/huge_pages.hpp"
#include "load/parsers.hpp"

namespace nmbake::load_detail {
namespace {

constexpr std::uint32_t kNone = 0xffffffffu;
constexpr std::size_t kNoColor = ~std::size_t{0};

struct Corner {
  std::uint32_t v = kNone;
  std::uint32_t vt = kNone;  // kNone when absent or not kept
  std::uint32_t vn = kNone;  // kNone when absent or not kept
  std::uint32_t uv = kNone;  // the vt for Mesh::corner_uvs (LoadOptions::corner_uvs); kNone when absent
  std::uint32_t vertex = kNone;
};

// A face corner as written; 0 (never valid) when the part is absent or its
// attribute is not kept.
struct RawCorner {
  std::int64_t v = 0;
  std::int64_t vt = 0;
  std::int64_t vn = 0;
};

// An `o`, `g` or `usemtl` statement: where a named part or material begins
// (mesh.hpp MeshPart).
// `mtllib` is recorded the same way (its files are read after the mesh).
enum class NameKind : std::uint8_t { object, group, material, library };
struct NameStatement {
  NameKind kind = NameKind::object;
  std::string name;                // the rest of the line, blanks trimmed
  std::uint64_t faces_before = 0;  // slice records: faces of the slice before it
};

// The name of an `o`/`g`/`usemtl` statement: all its arguments ("g a b"
// names "a b").
std::string statement_name(const char* p, const char* end) {
  p = skip_blanks(p, end);
  while (end > p && is_blank(end[-1])) --end;
  return std::string(p, end);
}

// The statements that name ranges of triangles; false for any other keyword.
bool name_kind(std::string_view keyword, NameKind& kind) {
  if (keyword == "o") {
    kind = NameKind::object;
  } else if (keyword == "g") {
    kind = NameKind::group;
  } else if (keyword == "usemtl") {
    kind = NameKind::material;
  } else if (keyword == "mtllib") {
    kind = NameKind::library;
  } else {
    return false;
  }
  return true;
}

// A vertex colour after the position: "v x y z r g b" (further numbers
// ignored). Only when the 4th to 6th arguments are three finite reals; "v x
// y z w" (a rational weight, 4 numbers) or anything else has none, and is
// read as it is without keep_colors (extra arguments are ignored). The
// values are kept as written: like a PLY's, they are display (sRGB-encoded)
// values in [0, 1]. Shared by the serial and the slice parser.
bool read_vertex_color(const char* p, const char* end, glm::vec4& color) {
  for (int i = 0; i < 3; ++i) p = skip_token(skip_blanks(p, end), end);
  color = glm::vec4(1.0f);
  glm::vec3 rgb(1.0f);
  for (int i = 0; i < 3; ++i) {
    p = skip_blanks(p, end);
    if (p == end) return false;
    const char* token_end = skip_token(p, end);
    if (parse_float(p, token_end, rgb[i]) != NumberError::none) return false;
    p = token_end;
  }
  color = glm::vec4(rgb, 1.0f);
  return true;
}

struct RawFace {
  std::uint32_t first_corner = 0;
  std::uint32_t corner_count = 0;
  // v / vt / vn statements of the slice before this face.
  std::uint64_t v_before = 0;
  std::uint64_t vt_before = 0;
  std::uint64_t vn_before = 0;
  std::uint64_t line = 0;  // 0-based within the slice
  const char* line_begin = nullptr;
};

// Complete lines [begin, end) of a block and what the slice parser made of
// them. Reused from block to block, so the vectors keep their capacity.
struct ObjSlice {
  const char* begin = nullptr;
  const char* end = nullptr;
  std::vector<glm::vec3> positions;
  std::vector<glm::vec4> colors;       // one per position, only with keep_colors (white: none)
  std::size_t first_color = kNoColor;  // index in positions of the first with a colour
  std::vector<glm::vec2> texcoords;    // only when kept
  std::vector<glm::vec3> normals;      // only when kept
  std::uint64_t texcoord_count = 0;    // vt statements, kept or not
  std::uint64_t normal_count = 0;      // vn statements, kept or not
  std::vector<RawFace> faces;
  std::vector<RawCorner> corners;
  std::vector<NameStatement> names;
  std::uint64_t line_count = 0;
  const char* stop = nullptr;  // first line the slice parser did not take, or nullptr
  std::uint64_t stop_line = 0;

  // What apply_slice needs to take the faces whole (the identity layout of
  // high meshes): while `simple`, every corner's indices are positive and
  // its kept vt and vn equal its v, every corner has one layout, and
  // `triangles` holds the fan triangulation as file vertex numbers (v - 1).
  // The reaches are the largest index minus the elements of the slice
  // before its face: every index is in range when each reach is at most the
  // count of elements before the slice.
  bool simple = true;
  bool layout_set = false;
  bool layout_vt = false;
  bool layout_vn = false;
  std::int64_t reach_v = 0;
  std::int64_t reach_vt = 0;
  std::int64_t reach_vn = 0;
  std::vector<std::uint32_t> triangles;
  std::uint64_t polygons = 0;
  std::uint64_t degenerate_faces = 0;

  void clear() {
    positions.clear();
    colors.clear();
    first_color = kNoColor;
    texcoords.clear();
    normals.clear();
    texcoord_count = 0;
    normal_count = 0;
    faces.clear();
    corners.clear();
    names.clear();
    line_count = 0;
    stop = nullptr;
    stop_line = 0;
    simple = true;
    layout_set = false;
    layout_vt = false;
    layout_vn = false;
    reach_v = 0;
    reach_vt = 0;
    reach_vn = 0;
    triangles.clear();
    polygons = 0;
    degenerate_faces = 0;
  }
};

// Lines end at '\n'; a "\r\n" ending loses its '\r' as FileReader does.
const char* line_content_end(const char* line_begin, const char* newline) {
  return newline > line_begin && newline[-1] == '\r' ? newline - 1 : newline;
}

// A statement's keyword and the end of its arguments (a trailing comment
// cut off); false for a blank line or a comment. Shared by the serial and the
// slice parsers, so both read the same statements.
bool split_statement(const char* p, const char* end, std::string_view& keyword, const char*& args_end) {
  p = skip_blanks(p, end);
  if (p == end || *p == '#') return false;
  const char* keyword_end = skip_token(p, end);
  keyword = std::string_view(p, static_cast<std::size_t>(keyword_end - p));
  const void* hash = std::memchr(keyword_end, '#', static_cast<std::size_t>(end - keyword_end));
  args_end = hash != nullptr ? static_cast<const char*>(hash) : end;
  return true;
}

// The serial parse_reals without messages: false on any error.
bool read_reals(const char* p, const char* end, float* values, int required, int count) {
  for (int i = 0; i < count; ++i) {
    p = skip_blanks(p, end);
    if (p == end) return i >= required;
    const char* token_end = skip_token(p, end);
    if (parse_float(p, token_end, values[i]) != NumberError::none) return false;
    p = token_end;
  }
  return true;
}

// One index as written; false when it is not a number or is 0. Plain
// "-?digits" (what exporters write) is read here, 18 digits at most so it
// cannot overflow; anything else goes to parse_int, the serial parser's reader.
bool read_index(const char* first, const char* last, std::int64_t& value) {
  const char* p = first;
  const bool negative = p < last && *p == '-';
  if (negative) ++p;
  if (p < last && last - p <= 18) {
    std::int64_t magnitude = 0;
    for (; p < last; ++p) {
      const auto digit = static_cast<unsigned>(*p - '0');
      if (digit > 9) break;
      magnitude = magnitude * 10 + static_cast<std::int64_t>(digit);
    }
    if (p == last) {
      value = negative ? -magnitude : magnitude;
      return value != 0;
    }
  }
  return parse_int(first, last, value) == NumberError::none && value != 0;
}

class ObjParser {
 public:
  ObjParser(const std::string& path, FileReader& reader, const LoadOptions& options, Mesh& out,
            LoadStats& stats)
      : path_(path), reader_(reader), options_(options), out_(out), stats_(stats) {}

  Status run() {
    // Untouched reserved pages cost no memory; a rough guess from typical
    // line lengths saves most of the regrowth copies of a big mesh.
    const std::uint64_t bytes = reader_.file_size();
    // Advised for 2 MB pages before the first touch, as the PLY loader's.
    detail::reserve_huge_pages(positions_, static_cast<std::size_t>(bytes / 80));
    detail::reserve_huge_pages(out_.indices, static_cast<std::size_t>(bytes / 14));
    if (options_.keep_normals) detail::reserve_huge_pages(normals_, static_cast<std::size_t>(bytes / 80));
    if (read_vt()) detail::reserve_huge_pages(texcoords_, static_cast<std::size_t>(bytes / 80));

    if (options_.serial) {
      std::string_view line;
      while (reader_.next_line(line)) {
        line_number_ = reader_.line_number();
        NMBAKE_TRY(parse_line(line));
      }
    } else {
      NMBAKE_TRY(parse_blocks());
    }
    if (!reader_.read_status().is_ok()) return reader_.read_status();
    if (out_.indices.empty()) {
      return Status::bad_input(path_ + ": no triangles (" + std::to_string(stats_.degenerate_faces) +
                               " faces with fewer than 3 corners skipped)");
    }
    finish();
    finish_names();
    if (options_.material_defs) NMBAKE_TRY(read_material_libraries());
    return Status::ok();
  }

 private:
  Status error(const std::string& reason) const { return text_error(path_, line_number_, reason); }

  // vt statements are read for the low mesh's vertices or for corner UVs.
  bool read_vt() const { return options_.keep_uvs || options_.corner_uvs; }

  // The `mtllib` files, in order, each definition of a material a `usemtl`
  // names (the first definition of a name wins, as in Blender's importer).
  Status read_material_libraries() {
    std::vector<std::string> used;
    for (const MeshPart& m : out_.materials) {
      if (!m.name.empty() && std::find(used.begin(), used.end(), m.name) == used.end())
        used.push_back(m.name);
    }
    for (const NameStatement& n : names_) {
      if (n.kind != NameKind::library || n.name.empty()) continue;
      if (!options_.material_libraries_optional) {
        NMBAKE_TRY(read_mtl_library(path_, n.name, used, out_.material_defs, stats_.files));
        continue;
      }
      // Optional: what the library gave before it failed is dropped with it.
      std::vector<Material> defs = out_.material_defs;
      if (read_mtl_library(path_, n.name, used, defs, stats_.files).is_ok()) {
        out_.material_defs = std::move(defs);
      } else {
        ++stats_.unread_material_libraries;
      }
    }
    return Status::ok();
  }

  Status parse_line(std::string_view line) {
    std::string_view keyword;
    const char* end = nullptr;
    if (!split_statement(line.data(), line.data() + line.size(), keyword, end)) return Status::ok();
    const char* keyword_end = keyword.data() + keyword.size();
    if (keyword == "v") return parse_position(keyword_end, end);
    if (keyword == "vt") return parse_texcoord(keyword_end, end);
    if (keyword == "vn") return parse_normal(keyword_end, end);
    if (keyword == "f") return parse_face(keyword_end, end);
    if (NameKind kind; name_kind(keyword, kind)) {
      add_name(NameStatement{kind, statement_name(keyword_end, end), 0});
      return Status::ok();
    }
    // Everything else (s, mtllib, l, p, vp, curves) carries nothing a bake
    // uses.
    return Status::ok();
  }

  // A part name starts at the next triangle.
  void add_name(NameStatement statement) {
    statement.faces_before = out_.indices.size() / 3;  // now: triangles before it
    names_.push_back(std::move(statement));
  }

  // Parts from the `o`/`g` statements: by `o` when the file has any (Blender,
  // Maya and 3ds Max name objects with `o` and use `g` for materials or
  // smoothing groups), else by `g`. Materials from `usemtl`, which holds
  // across `o` and `g` until the next `usemtl`.
  void finish_names() {
    const bool by_object = std::any_of(names_.begin(), names_.end(),
                                       [](const NameStatement& n) { return n.kind == NameKind::object; });
    finish_ranges(by_object ? NameKind::object : NameKind::group, out_.parts);
    finish_ranges(NameKind::material, out_.materials);
  }

  // Ranges from the statements of one kind: triangles before the first name
  // are an unnamed range; a name that names no triangle makes no range;
  // consecutive ranges of one name are one range. No such statement: none.
  void finish_ranges(NameKind kind, std::vector<MeshPart>& ranges) const {
    const auto triangle_count = static_cast<std::uint32_t>(out_.indices.size() / 3);
    std::string current;
    std::uint32_t begin = 0;
    bool any = false;
    const auto close = [&](std::uint32_t end) {
      append_range(ranges, current, begin, end - begin);
      begin = end;
    };
    for (const NameStatement& n : names_) {
      if (n.kind != kind) continue;
      any = true;
      close(static_cast<std::uint32_t>(n.faces_before));
      current = n.name;
    }
    if (!any) return;
    close(triangle_count);
  }

  // Reads `count` reals (at least `required`), the rest left at their value.
  Status parse_reals(const char* p, const char* end, float* values, int required, int count) {
    for (int i = 0; i < count; ++i) {
      p = skip_blanks(p, end);
      if (p == end) {
        if (i < required)
          return error("expected " + std::to_string(required) + " numbers, found " + std::to_string(i));
        return Status::ok();
      }
      const char* token_end = skip_token(p, end);
      const NumberError number_error = parse_float(p, token_end, values[i]);
      if (number_error != NumberError::none) {
        return error(
            number_error_text(number_error, std::string_view(p, static_cast<std::size_t>(token_end - p))));
      }
      p = token_end;
    }
    // Further numbers (w, vertex colours) are allowed and ignored.
    return Status::ok();
  }

  Status parse_position(const char* p, const char* end) {
    glm::vec3 position{0.0f};
    NMBAKE_TRY(parse_reals(p, end, &position.x, 3, 3));
    if (positions_.size() >= kNone - 1) return error("too many vertices");
    positions_.push_back(position);
    if (options_.keep_colors) {
      glm::vec4 color;
      any_color_ = read_vertex_color(p, end, color) || any_color_;
      colors_.push_back(color);
    }
    if (split_) first_vertex_.push_back(kNone);
    return Status::ok();
  }

  Status parse_texcoord(const char* p, const char* end) {
    ++texcoord_count_;
    if (!read_vt()) return Status::ok();  // counted for relative indices only
    glm::vec2 uv{0.0f};
    NMBAKE_TRY(parse_reals(p, end, &uv.x, 1, 2));
    texcoords_.push_back(uv);
    return Status::ok();
  }

  Status parse_normal(const char* p, const char* end) {
    ++normal_count_;
    if (!options_.keep_normals) return Status::ok();
    glm::vec3 normal{0.0f};
    NMBAKE_TRY(parse_reals(p, end, &normal.x, 3, 3));
    normals_.push_back(normal);
    return Status::ok();
  }

  // One index of a corner: 1-based, or negative relative to the `count`
  // elements defined so far. `what` names the element kind for messages.
  Status resolve_index(const char* first, const char* last, std::uint64_t count, const char* what,
                       std::uint32_t& index) {
    std::int64_t value = 0;
    const NumberError number_error = parse_int(first, last, value);
    if (number_error != NumberError::none) {
      return error(std::string("bad ") + what + " index '" +
                   token_text(std::string_view(first, static_cast<std::size_t>(last - first))) + "'");
    }
    if (value == 0) return error(std::string(what) + " index 0 (OBJ indices start at 1)");
    const std::int64_t resolved = value > 0 ? value - 1 : static_cast<std::int64_t>(count) + value;
    if (resolved < 0 || static_cast<std::uint64_t>(resolved) >= count) {
      return error(std::string(what) + " index " + std::to_string(value) + " out of range (" +
                   std::to_string(count) + " defined so far)");
    }
    index = static_cast<std::uint32_t>(resolved);
    return Status::ok();
  }

  Status parse_corner(const char* p, const char* token_end, Corner& corner) {
    const std::string_view token(p, static_cast<std::size_t>(token_end - p));
    const char* slash = p;
    while (slash < token_end && *slash != '/') ++slash;
    NMBAKE_TRY(resolve_index(p, slash, positions_.size(), "vertex", corner.v));
    bool has_vt = false;
    bool has_vn = false;
    if (slash < token_end) {
      const char* vt_first = slash + 1;
      const char* vt_last = vt_first;
      while (vt_last < token_end && *vt_last != '/') ++vt_last;
      if (vt_last > vt_first) {
        has_vt = true;
        if (read_vt()) {
          NMBAKE_TRY(resolve_index(vt_first, vt_last, texcoord_count_, "texture coordinate", corner.uv));
          if (options_.keep_uvs) corner.vt = corner.uv;
        }
      }
      if (vt_last < token_end) {
        if (vt_last + 1 == token_end)
          return error("missing normal index in corner '" + token_text(token) + "'");
        has_vn = true;
        if (options_.keep_normals) {
          NMBAKE_TRY(resolve_index(vt_last + 1, token_end, normal_count_, "normal", corner.vn));
        }
      } else if (vt_last == vt_first) {
        return error("missing texture coordinate index in corner '" + token_text(token) + "'");
      }
    }
    // Every corner must carry the same kept attributes; attributes that are
    // not kept may come and go (a high mesh with partial UVs still bakes).
    const bool kept_vt = has_vt && options_.keep_uvs;
    const bool kept_vn = has_vn && options_.keep_normals;
    if (!layout_known_) {
      layout_known_ = true;
      has_vt_ = kept_vt;
      has_vn_ = kept_vn;
    } else if (kept_vt != has_vt_) {
      return error("corner '" + token_text(token) + (kept_vt ? "' has" : "' has no") +
                   " texture coordinate index but earlier corners " + (kept_vt ? "do not" : "do"));
    } else if (kept_vn != has_vn_) {
      return error("corner '" + token_text(token) + (kept_vn ? "' has" : "' has no") +
                   " normal index but earlier corners " + (kept_vn ? "do not" : "do"));
    }
    return Status::ok();
  }

  Status parse_face(const char* p, const char* end) {
    corners_.clear();
    for (;;) {
      p = skip_blanks(p, end);
      if (p == end) break;
      const char* token_end = skip_token(p, end);
      Corner corner;
      NMBAKE_TRY(parse_corner(p, token_end, corner));
      corners_.push_back(corner);
      p = token_end;
    }
    return add_face();
  }

  // Counts, splits and fan-triangulates the resolved corners_.
  Status add_face() {
    if (corners_.size() < 3) {
      ++stats_.degenerate_faces;  // a point or a line, not a surface
      return Status::ok();
    }
    ++stats_.polygons;
    if (!split_) {
      for (const Corner& corner : corners_) {
        if ((corner.vt != kNone && corner.vt != corner.v) || (corner.vn != kNone && corner.vn != corner.v)) {
          enter_split_mode();
          break;
        }
      }
    }
    if (vertex_v_.size() + corners_.size() >= kNone) return error("too many vertices");
    for (Corner& corner : corners_) corner.vertex = split_ ? find_or_add_vertex(corner) : corner.v;
    // Fan triangulation around the first corner (exact for convex polygons,
    // which is what exporters write).
    for (std::size_t i = 1; i + 1 < corners_.size(); ++i) {
      out_.indices.push_back(corners_[0].vertex);
      out_.indices.push_back(corners_[i].vertex);
      out_.indices.push_back(corners_[i + 1].vertex);
      if (options_.corner_uvs) {
        for (const std::size_t c : {std::size_t{0}, i, i + 1}) {
          const std::uint32_t uv = corners_[c].uv;
          if (uv == kNone) ++stats_.corners_without_uvs;
          out_.corner_uvs.push_back(uv == kNone ? glm::vec2(0.0f) : texcoords_[uv]);
        }
      }
    }
    return Status::ok();
  }

  // ---------------------------------------------------------------- blocks

  Status parse_blocks() {
    const std::size_t group_bytes = block_bytes(options_);
    // A few slices per core balance lines of uneven cost (faces against
    // vertices); their count does not change the result.
    const auto slice_count =
        static_cast<std::size_t>(2 * std::max(1, tbb::this_task_arena::max_concurrency()));
    slices_.resize(slice_count);
    for (;;) {
      const char* bytes = nullptr;
      const std::size_t size = reader_.peek(group_bytes, bytes);
      if (size == 0) break;
      const auto* last_newline = static_cast<const char*>(::memrchr(bytes, '\n', size));
      if (last_newline == nullptr) {
        // The last line without a newline, or a line longer than a block.
        std::string_view line;
        if (!reader_.next_line(line)) break;
        line_number_ = reader_.line_number();
        NMBAKE_TRY(parse_line(line));
        continue;
      }
      const char* end = last_newline + 1;
      // Cut at the first line end after each even share of the block.
      const char* begin = bytes;
      for (std::size_t s = 0; s < slice_count; ++s) {
        ObjSlice& slice = slices_[s];
        slice.begin = begin;
        if (s + 1 == slice_count) {
          slice.end = end;
        } else {
          const char* target = bytes + (static_cast<std::size_t>(end - bytes) * (s + 1)) / slice_count;
          if (target < begin) target = begin;
          const auto* newline =
              static_cast<const char*>(std::memchr(target, '\n', static_cast<std::size_t>(end - target)));
          slice.end = newline == nullptr ? end : newline + 1;
        }
        begin = slice.end;
      }
      // Two more tasks beside the slices: reading the next block
      // (FileReader::read_ahead(): the copy out of the page cache is ~8% of
      // the work) and faulting in the output pages this block will likely
      // append to (prefault()).
      tbb::parallel_for(tbb::blocked_range<std::size_t>(0, slice_count + 2, 1),
                        [&](const tbb::blocked_range<std::size_t>& range) {
                          for (std::size_t s = range.begin(); s != range.end(); ++s) {
                            if (s < slice_count) {
                              parse_slice(slices_[s]);
                            } else if (s == slice_count) {
                              reader_.read_ahead(group_bytes);
                            } else {
                              prefault();
                            }
                          }
                        });
      std::uint64_t line = reader_.line_number() + 1;
      for (ObjSlice& slice : slices_) {
        NMBAKE_TRY(apply_slice(slice, line));
        line += slice.line_count;
      }
      reader_.consume(static_cast<std::size_t>(end - bytes));
      reader_.add_lines(line - 1 - reader_.line_number());
    }
    return Status::ok();
  }

  // The appends of the slices (apply_slice) run on one thread, and the first
  // touch of a 2 MB page costs up to ~4 ms on these machines (huge_pages.hpp):
  // while the slices of a block are parsed, another task faults in the
  // reserved (untouched) pages the block will likely fill, as much as the
  // previous block appended to each array. Raw storage beyond size(), as
  // detail::size_output() touches it; the contents are unchanged.
  struct Prefaulted {
    const void* data = nullptr;  // the allocation `bytes` refers to
    std::size_t bytes = 0;       // faulted in from data
    std::size_t last_size = 0;   // the array's size at the previous block
  };
  template <typename T>
  static void prefault_array(std::vector<T>& v, Prefaulted& mark) {
    static_assert(std::is_trivially_copyable_v<T>, "raw storage is written before the elements exist");
    if (mark.data != v.data()) {
      mark.data = v.data();
      mark.bytes = 0;
    }
    const std::size_t grown = v.size() - std::min(v.size(), mark.last_size);
    mark.last_size = v.size();
    const std::size_t from = std::max(mark.bytes, v.size() * sizeof(T));
    const std::size_t to = std::min(v.capacity(), v.size() + grown + grown / 4) * sizeof(T);
    if (to <= from) return;
    auto* bytes = reinterpret_cast<unsigned char*>(v.data());
    constexpr std::size_t page = 4096;
    for (std::size_t i = (from + page - 1) / page * page; i < to; i += page) bytes[i] = 0;
    mark.bytes = to;
  }
  void prefault() {
    prefault_array(positions_, prefaulted_[0]);
    prefault_array(out_.indices, prefaulted_[1]);
    prefault_array(normals_, prefaulted_[2]);
    prefault_array(texcoords_, prefaulted_[3]);
  }

  // Runs on any thread: reads only the slice and the options.
  void parse_slice(ObjSlice& slice) const {
    slice.clear();
    const char* p = slice.begin;
    std::uint64_t line = 0;
    while (p < slice.end) {
      const char* next = read_common_line(p, line, slice);
      if (next == nullptr) {
        const auto* newline =
            static_cast<const char*>(std::memchr(p, '\n', static_cast<std::size_t>(slice.end - p)));
        if (!parse_line_records(p, line_content_end(p, newline), line, slice)) {
          slice.stop = p;
          slice.stop_line = line;
          line += static_cast<std::uint64_t>(std::count(p, slice.end, '\n'));
          break;
        }
        next = newline + 1;
      }
      p = next;
      ++line;
    }
    slice.line_count = line;
  }

  // ------------------------------------------------------- common lines
  //
  // The lines big files are made of, read in one pass without first cutting
  // the line into tokens: "v x y z", "vn x y z", "vt u [v]", "f" with
  // corners a, a/b, a//c, a/b/c, and comments. They give the records
  // parse_line_records gives (the same number reader on the same tokens,
  // the same arguments ignored); anything else or unusual (a leading blank,
  // a '+', a '#' after a statement, too few numbers, a vertex colour to
  // keep) returns nullptr with nothing recorded, and parse_line_records
  // takes the line. Lines of a slice end with '\n', so every read stops
  // before the slice's end.

  static bool ends_token(char c) { return c == ' ' || c == '\t' || c == '\r' || c == '\n'; }
  static const char* skip_spaces(const char* p) {
    while (*p == ' ' || *p == '\t' || *p == '\r') ++p;
    return p;
  }
  // Past the line's '\n'.
  static const char* next_line(const char* p, const char* end) {
    if (*p == '\n') return p + 1;
    return static_cast<const char*>(std::memchr(p, '\n', static_cast<std::size_t>(end - p))) + 1;
  }

  // `count` reals (at least `required`), the rest of the line ignored as
  // read_reals ignores it; nullptr where read_reals might say otherwise.
  static const char* read_line_reals(const char* p, const char* end, float* values, int required, int count) {
    for (int i = 0; i < count; ++i) {
      p = skip_spaces(p);
      if (*p == '\n') return i >= required ? p + 1 : nullptr;
      float value = 0.0f;
      const char* token_end = read_real_prefix(p, end, value);
      if (token_end == nullptr || !ends_token(*token_end) || !std::isfinite(value)) return nullptr;
      values[i] = value;
      p = token_end;
    }
    return next_line(p, end);
  }

  // A plain index "-?digits" (18 digits at most, not 0), as read_index reads it.
  static const char* read_line_index(const char* p, std::int64_t& value) {
    const bool negative = *p == '-';
    if (negative) ++p;
    const char* first = p;
    std::uint64_t magnitude = 0;  // exact up to 18 digits; longer ones are refused
    for (auto digit = static_cast<unsigned>(*p - '0'); digit <= 9; digit = static_cast<unsigned>(*p - '0')) {
      magnitude = magnitude * 10 + digit;
      ++p;
    }
    if (p == first || p - first > 18 || magnitude == 0) return nullptr;
    value = negative ? -static_cast<std::int64_t>(magnitude) : static_cast<std::int64_t>(magnitude);
    return p;
  }

  const char* read_common_line(const char* p, std::uint64_t line, ObjSlice& slice) const {
    const char* end = slice.end;
    if (*p == '\n') return p + 1;
    if (*p == '#') return next_line(p, end);
    if (*p == 'v') {
      const char c = p[1];
      if (c == ' ' || c == '\t') {
        if (options_.keep_colors) return nullptr;
        glm::vec3 position{0.0f};
        const char* next = read_line_reals(p + 2, end, &position.x, 3, 3);
        if (next != nullptr) slice.positions.push_back(position);
        return next;
      }
      if ((c != 'n' && c != 't') || (p[2] != ' ' && p[2] != '\t')) return nullptr;
      if (c == 'n') {
        if (!options_.keep_normals) {
          ++slice.normal_count;
          return next_line(p + 2, end);
        }
        glm::vec3 normal{0.0f};
        const char* next = read_line_reals(p + 3, end, &normal.x, 3, 3);
        if (next == nullptr) return nullptr;
        slice.normals.push_back(normal);
        ++slice.normal_count;
        return next;
      }
      if (!read_vt()) {
        ++slice.texcoord_count;
        return next_line(p + 2, end);
      }
      glm::vec2 uv{0.0f};
      const char* next = read_line_reals(p + 3, end, &uv.x, 1, 2);
      if (next == nullptr) return nullptr;
      slice.texcoords.push_back(uv);
      ++slice.texcoord_count;
      return next;
    }
    if (*p != 'f' || (p[1] != ' ' && p[1] != '\t')) return nullptr;
    RawFace face;
    face.first_corner = static_cast<std::uint32_t>(slice.corners.size());
    face.v_before = slice.positions.size();
    face.vt_before = slice.texcoord_count;
    face.vn_before = slice.normal_count;
    face.line = line;
    face.line_begin = p;
    const char* q = p + 2;
    for (;;) {
      q = skip_spaces(q);
      if (*q == '\n') break;
      RawCorner corner;
      q = read_line_index(q, corner.v);
      if (q != nullptr && *q == '/') {
        std::int64_t index = 0;
        if (q[1] != '/') {
          q = read_line_index(q + 1, index);
          if (q != nullptr && read_vt()) corner.vt = index;
        } else {
          ++q;  // "a//c"
          if (q[1] == '/' || ends_token(q[1])) q = nullptr;
        }
        if (q != nullptr && *q == '/') {
          q = read_line_index(q + 1, index);
          if (options_.keep_normals) corner.vn = index;
        }
      }
      if (q == nullptr || !ends_token(*q)) {
        slice.corners.resize(face.first_corner);
        return nullptr;
      }
      slice.corners.push_back(corner);
    }
    face.corner_count = static_cast<std::uint32_t>(slice.corners.size() - face.first_corner);
    slice.faces.push_back(face);
    note_face(slice, face);
    return q + 1;
  }

  // Keeps the slice's `simple` record (ObjSlice) up to date with a new face.
  void note_face(ObjSlice& slice, const RawFace& face) const {
    if (!slice.simple) return;
    const RawCorner* corners = slice.corners.data() + face.first_corner;
    for (std::uint32_t c = 0; c < face.corner_count; ++c) {
      const RawCorner& corner = corners[c];
      const bool has_vt = corner.vt != 0;
      const bool has_vn = corner.vn != 0;
      if (corner.v <= 0 || (has_vt && corner.vt != corner.v) || (has_vn && corner.vn != corner.v) ||
          (slice.layout_set && (has_vt != slice.layout_vt || has_vn != slice.layout_vn))) {
        slice.simple = false;
        return;
      }
      slice.layout_set = true;
      slice.layout_vt = has_vt;
      slice.layout_vn = has_vn;
      slice.reach_v = std::max(slice.reach_v, corner.v - static_cast<std::int64_t>(face.v_before));
      if (has_vt)
        slice.reach_vt = std::max(slice.reach_vt, corner.vt - static_cast<std::int64_t>(face.vt_before));
      if (has_vn)
        slice.reach_vn = std::max(slice.reach_vn, corner.vn - static_cast<std::int64_t>(face.vn_before));
    }
    if (face.corner_count < 3) {
      ++slice.degenerate_faces;
      return;
    }
    ++slice.polygons;
    const auto first = static_cast<std::uint32_t>(corners[0].v - 1);
    for (std::uint32_t c = 1; c + 1 < face.corner_count; ++c) {
      slice.triangles.push_back(first);
      slice.triangles.push_back(static_cast<std::uint32_t>(corners[c].v - 1));
      slice.triangles.push_back(static_cast<std::uint32_t>(corners[c + 1].v - 1));
    }
  }

  // parse_line as records; false where the serial parser might report an
  // error (nothing of the line is recorded then).
  bool parse_line_records(const char* line_begin, const char* line_end, std::uint64_t line,
                          ObjSlice& slice) const {
    std::string_view keyword;
    const char* end = nullptr;
    if (!split_statement(line_begin, line_end, keyword, end)) return true;
    const char* keyword_end = keyword.data() + keyword.size();
    if (keyword == "v") {
      glm::vec3 position{0.0f};
      if (!read_reals(keyword_end, end, &position.x, 3, 3)) return false;
      if (options_.keep_colors) {
        glm::vec4 color;
        if (read_vertex_color(keyword_end, end, color) && slice.first_color == kNoColor) {
          slice.first_color = slice.positions.size();
        }
        slice.colors.push_back(color);
      }
      slice.positions.push_back(position);
    } else if (keyword == "vt") {
      if (read_vt()) {
        glm::vec2 uv{0.0f};
        if (!read_reals(keyword_end, end, &uv.x, 1, 2)) return false;
        slice.texcoords.push_back(uv);
      }
      ++slice.texcoord_count;
    } else if (keyword == "vn") {
      if (options_.keep_normals) {
        glm::vec3 normal{0.0f};
        if (!read_reals(keyword_end, end, &normal.x, 3, 3)) return false;
        slice.normals.push_back(normal);
      }
      ++slice.normal_count;
    } else if (keyword == "f") {
      RawFace face;
      face.first_corner = static_cast<std::uint32_t>(slice.corners.size());
      face.v_before = slice.positions.size();
      face.vt_before = slice.texcoord_count;
      face.vn_before = slice.normal_count;
      face.line = line;
      face.line_begin = line_begin;
      for (const char* p = keyword_end;;) {
        p = skip_blanks(p, end);
        if (p == end) break;
        const char* token_end = skip_token(p, end);
        if (!read_corner(p, token_end, slice.corners.emplace_back())) {
          slice.corners.resize(face.first_corner);
          return false;
        }
        p = token_end;
      }
      face.corner_count = static_cast<std::uint32_t>(slice.corners.size() - face.first_corner);
      slice.faces.push_back(face);
      note_face(slice, face);
    } else if (NameKind kind; name_kind(keyword, kind)) {
      slice.names.push_back(NameStatement{kind, statement_name(keyword_end, end), slice.faces.size()});
    }
    return true;
  }

  // The syntax checks of parse_corner.
  bool read_corner(const char* p, const char* token_end, RawCorner& corner) const {
    const char* slash = p;
    while (slash < token_end && *slash != '/') ++slash;
    if (!read_index(p, slash, corner.v)) return false;
    if (slash == token_end) return true;
    const char* vt_first = slash + 1;
    const char* vt_last = vt_first;
    while (vt_last < token_end && *vt_last != '/') ++vt_last;
    if (vt_last > vt_first && read_vt() && !read_index(vt_first, vt_last, corner.vt)) return false;
    if (vt_last < token_end) {
      if (vt_last + 1 == token_end) return false;
      if (options_.keep_normals && !read_index(vt_last + 1, token_end, corner.vn)) return false;
    } else if (vt_last == vt_first) {
      return false;
    }
    return true;
  }

  // An index of resolve_index, without the messages.
  static bool resolve_raw(std::int64_t value, std::uint64_t count, std::uint32_t& index) {
    const std::int64_t resolved = value > 0 ? value - 1 : static_cast<std::int64_t>(count) + value;
    if (resolved < 0 || static_cast<std::uint64_t>(resolved) >= count) return false;
    index = static_cast<std::uint32_t>(resolved);
    return true;
  }

  // Applies a parsed slice in file order; `first_line` is the number of its
  // first line.
  Status apply_slice(const ObjSlice& slice, std::uint64_t first_line) {
    const std::uint64_t base_v = positions_.size();
    const std::uint64_t base_vt = texcoord_count_;
    const std::uint64_t base_vn = normal_count_;
    if (base_v + slice.positions.size() >= kNone) {
      // "too many vertices" is named on its line by the serial parser.
      return parse_lines_serially(slice.begin, slice.end, first_line);
    }
    positions_.insert(positions_.end(), slice.positions.begin(), slice.positions.end());
    colors_.insert(colors_.end(), slice.colors.begin(), slice.colors.end());
    const bool any_color = any_color_;
    any_color_ = any_color_ || slice.first_color != kNoColor;
    texcoords_.insert(texcoords_.end(), slice.texcoords.begin(), slice.texcoords.end());
    normals_.insert(normals_.end(), slice.normals.begin(), slice.normals.end());
    texcoord_count_ += slice.texcoord_count;
    normal_count_ += slice.normal_count;
    if (take_whole(slice, base_v, base_vt, base_vn)) return Status::ok();
    if (split_) first_vertex_.resize(positions_.size(), kNone);
    std::size_t next_name = 0;
    // Names recorded before face `f` of the slice.
    const auto add_names_before = [&](std::size_t f) {
      for (; next_name < slice.names.size() && slice.names[next_name].faces_before <= f; ++next_name) {
        add_name(slice.names[next_name]);
      }
    };
    for (std::size_t f = 0; f < slice.faces.size(); ++f) {
      const RawFace& face = slice.faces[f];
      add_names_before(f);
      const std::uint64_t v_count = base_v + face.v_before;
      const std::uint64_t vt_count = base_vt + face.vt_before;
      const std::uint64_t vn_count = base_vn + face.vn_before;
      const bool layout_known = layout_known_;
      const bool has_vt = has_vt_;
      const bool has_vn = has_vn_;
      bool resolved = true;
      corners_.clear();
      for (std::uint32_t c = 0; c < face.corner_count && resolved; ++c) {
        const RawCorner& raw = slice.corners[face.first_corner + c];
        Corner corner;
        resolved = resolve_raw(raw.v, v_count, corner.v) &&
                   (raw.vt == 0 || resolve_raw(raw.vt, vt_count, corner.uv)) &&
                   (raw.vn == 0 || resolve_raw(raw.vn, vn_count, corner.vn));
        const bool kept_vt = raw.vt != 0 && options_.keep_uvs;
        if (kept_vt) corner.vt = corner.uv;
        const bool kept_vn = raw.vn != 0;
        if (!layout_known_) {
          layout_known_ = true;
          has_vt_ = kept_vt;
          has_vn_ = kept_vn;
        } else if (kept_vt != has_vt_ || kept_vn != has_vn_) {
          resolved = false;
        }
        corners_.push_back(corner);
      }
      if (!resolved) {
        // Back to the state before this line; the serial parser names the
        // problem and takes the rest of the slice.
        layout_known_ = layout_known;
        has_vt_ = has_vt;
        has_vn_ = has_vn;
        positions_.resize(v_count);
        if (options_.keep_colors) colors_.resize(v_count);
        any_color_ = any_color || (slice.first_color != kNoColor && slice.first_color < face.v_before);
        texcoord_count_ = vt_count;
        normal_count_ = vn_count;
        if (read_vt()) texcoords_.resize(vt_count);
        if (options_.keep_normals) normals_.resize(vn_count);
        if (split_) first_vertex_.resize(positions_.size());
        return parse_lines_serially(face.line_begin, slice.end, first_line + face.line);
      }
      line_number_ = first_line + face.line;
      NMBAKE_TRY(add_face());
    }
    add_names_before(slice.faces.size());
    if (slice.stop != nullptr)
      return parse_lines_serially(slice.stop, slice.end, first_line + slice.stop_line);
    return Status::ok();
  }

  // The faces of a `simple` slice at once, when what add_face() would do with
  // them is only to append their triangles: no split, no corner UVs, no
  // names, every index in range and the layout the file's. False (nothing
  // changed) otherwise.
  bool take_whole(const ObjSlice& slice, std::uint64_t base_v, std::uint64_t base_vt, std::uint64_t base_vn) {
    if (!slice.simple || split_ || options_.corner_uvs || !slice.names.empty() || slice.stop != nullptr)
      return false;
    if (slice.reach_v > static_cast<std::int64_t>(base_v) ||
        slice.reach_vt > static_cast<std::int64_t>(base_vt) ||
        slice.reach_vn > static_cast<std::int64_t>(base_vn)) {
      return false;
    }
    if (slice.layout_set) {
      if (layout_known_ && (slice.layout_vt != has_vt_ || slice.layout_vn != has_vn_)) return false;
      layout_known_ = true;
      has_vt_ = slice.layout_vt;
      has_vn_ = slice.layout_vn;
    }
    out_.indices.insert(out_.indices.end(), slice.triangles.begin(), slice.triangles.end());
    stats_.polygons += slice.polygons;
    stats_.degenerate_faces += slice.degenerate_faces;
    return true;
  }

  // Complete lines [p, end) through parse_line, the first numbered `line`.
  Status parse_lines_serially(const char* p, const char* end, std::uint64_t line) {
    while (p < end) {
      const auto* newline = static_cast<const char*>(std::memchr(p, '\n', static_cast<std::size_t>(end - p)));
      line_number_ = line++;
      NMBAKE_TRY(parse_line(std::string_view(p, static_cast<std::size_t>(line_content_end(p, newline) - p))));
      p = newline + 1;
    }
    return Status::ok();
  }

  // ---------------------------------------------------------------- vertices

  void enter_split_mode() {
    split_ = true;
    first_vertex_.assign(positions_.size(), kNone);
    // Until now every corner was the identity combination of its v index.
    for (std::uint32_t& index : out_.indices) {
      Corner corner;
      corner.v = index;
      corner.vt = has_vt_ ? index : kNone;
      corner.vn = has_vn_ ? index : kNone;
      index = find_or_add_vertex(corner);
    }
  }

  std::uint32_t find_or_add_vertex(const Corner& corner) {
    for (std::uint32_t vertex = first_vertex_[corner.v]; vertex != kNone; vertex = next_vertex_[vertex]) {
      if (vertex_vt_[vertex] == corner.vt && vertex_vn_[vertex] == corner.vn) return vertex;
    }
    const auto vertex = static_cast<std::uint32_t>(vertex_v_.size());
    vertex_v_.push_back(corner.v);
    vertex_vt_.push_back(corner.vt);
    vertex_vn_.push_back(corner.vn);
    next_vertex_.push_back(first_vertex_[corner.v]);
    first_vertex_[corner.v] = vertex;
    return vertex;
  }

  void finish() {
    if (!split_) {
      // Vertex i is file vertex i; attributes of vertices no face uses may be
      // missing and are padded here, then dropped with those vertices.
      const std::size_t vertex_count = positions_.size();
      out_.positions = std::move(positions_);
      if (any_color_) out_.colors = std::move(colors_);
      if (has_vt_) {
        texcoords_.resize(vertex_count, glm::vec2(0.0f));
        out_.uvs = std::move(texcoords_);
      }
      if (has_vn_) {
        normals_.resize(vertex_count, glm::vec3(0.0f, 0.0f, 1.0f));
        out_.normals = std::move(normals_);
      }
      return;
    }
    const std::size_t vertex_count = vertex_v_.size();
    out_.positions.resize(vertex_count);
    for (std::size_t i = 0; i < vertex_count; ++i) out_.positions[i] = positions_[vertex_v_[i]];
    if (has_vt_) {
      out_.uvs.resize(vertex_count);
      for (std::size_t i = 0; i < vertex_count; ++i) out_.uvs[i] = texcoords_[vertex_vt_[i]];
    }
    if (has_vn_) {
      out_.normals.resize(vertex_count);
      for (std::size_t i = 0; i < vertex_count; ++i) out_.normals[i] = normals_[vertex_vn_[i]];
    }
    if (any_color_) {
      out_.colors.resize(vertex_count);
      for (std::size_t i = 0; i < vertex_count; ++i) out_.colors[i] = colors_[vertex_v_[i]];
    }
  }

  const std::string& path_;
  FileReader& reader_;
  const LoadOptions& options_;
  Mesh& out_;
  LoadStats& stats_;

  std::vector<glm::vec3> positions_;
  std::vector<glm::vec4> colors_;     // one per position with keep_colors (white: none)
  bool any_color_ = false;            // some position has a colour: the mesh has colours
  std::vector<glm::vec2> texcoords_;  // only when kept
  std::vector<glm::vec3> normals_;    // only when kept
  std::uint64_t texcoord_count_ = 0;  // vt statements, kept or not
  std::uint64_t normal_count_ = 0;    // vn statements, kept or not

  bool layout_known_ = false;  // set by the first face corner
  bool has_vt_ = false;        // corners carry a kept vt index
  bool has_vn_ = false;        // corners carry a kept vn index

  bool split_ = false;
  std::vector<std::uint32_t> first_vertex_;  // per file position: newest vertex using it
  std::vector<std::uint32_t> next_vertex_;   // per vertex: older vertex with the same position
  std::vector<std::uint32_t> vertex_v_;
  std::vector<std::uint32_t> vertex_vt_;
  std::vector<std::uint32_t> vertex_vn_;

  std::vector<NameStatement> names_;  // o / g / usemtl statements, faces_before = triangles before
  std::vector<Corner> corners_;       // scratch of the current face
  std::uint64_t line_number_ = 0;     // of the line being parsed, for messages
  std::vector<ObjSlice> slices_;      // of the parallel path
  Prefaulted prefaulted_[4];          // positions_, out_.indices, normals_, texcoords_
};

}  // namespace

Status load_obj(const std::string& path, FileReader& reader, const LoadOptions& options, Mesh& out,
                LoadStats& stats) {
  ObjParser parser(path, reader, options, out, stats);
  return parser.run();
}

}  // namespace nmbake::load_detail
