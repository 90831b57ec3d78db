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
#include <cstring>
#include <string>
#include <string_view>
#include <vector>

#include <glm/vec2.hpp>
#include <glm/vec3.hpp>

#include "load/parsers.hpp"

namespace nmbake::load_detail {
namespace {

constexpr std::uint32_t kNone = 0xffffffffu;

struct Corner {
  std::uint32_t v = kNone;
  std::uint32_t vt = kNone;  // kNone when absent or not kept
  std::uint32_t vn = kNone;  // kNone when absent or not kept
  std::uint32_t vertex = kNone;
};

class ObjParser {
 public:
  ObjParser(const std::string& path, FileReader& reader, const LoadOptions& options, Mesh& out,
            LoadStats& stats)
      : path_(path), reader_(reader), options_(options), out_(out), stats_(stats) {}

  Status run() {
    // Untouched reserved pages cost no memory; a rough guess from typical
    // line lengths saves most of the regrowth copies of a big mesh.
    const std::uint64_t bytes = reader_.file_size();
    positions_.reserve(static_cast<std::size_t>(bytes / 80));
    out_.indices.reserve(static_cast<std::size_t>(bytes / 14));

    std::string_view line;
    while (reader_.next_line(line)) {
      const char* p = skip_blanks(line.data(), line.data() + line.size());
      const char* end = line.data() + line.size();
      if (p == end || *p == '#') continue;
      const char* keyword_end = skip_token(p, end);
      const std::string_view keyword(p, static_cast<std::size_t>(keyword_end - p));
      // A comment may follow a statement.
      if (const void* hash = std::memchr(keyword_end, '#', static_cast<std::size_t>(end - keyword_end))) {
        end = static_cast<const char*>(hash);
      }
      if (keyword == "v") {
        NMBAKE_TRY(parse_position(keyword_end, end));
      } else if (keyword == "vt") {
        NMBAKE_TRY(parse_texcoord(keyword_end, end));
      } else if (keyword == "vn") {
        NMBAKE_TRY(parse_normal(keyword_end, end));
      } else if (keyword == "f") {
        NMBAKE_TRY(parse_face(keyword_end, end));
      }
      // Everything else (o, g, s, usemtl, mtllib, l, p, vp, curves) carries
      // nothing a bake uses.
    }
    if (!reader_.read_status().is_ok()) return reader_.read_status();
    if (out_.indices.empty()) {
      return Status::bad_input(path_ + ": no triangles (" + std::to_string(stats_.degenerate_faces) +
                               " faces with fewer than 3 corners skipped)");
    }
    finish();
    return Status::ok();
  }

 private:
  Status error(const std::string& reason) const { return text_error(path_, reader_.line_number(), reason); }

  // Reads `count` reals (at least `required`), the rest left at their value.
  Status parse_reals(const char* p, const char* end, float* values, int required, int count) {
    for (int i = 0; i < count; ++i) {
      p = skip_blanks(p, end);
      if (p == end) {
        if (i < required) return error("expected " + std::to_string(required) + " numbers, found " + std::to_string(i));
        return Status::ok();
      }
      const char* token_end = skip_token(p, end);
      const NumberError number_error = parse_float(p, token_end, values[i]);
      if (number_error != NumberError::none) {
        return error(number_error_text(number_error, std::string_view(p, static_cast<std::size_t>(token_end - p))));
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
    if (split_) first_vertex_.push_back(kNone);
    return Status::ok();
  }

  Status parse_texcoord(const char* p, const char* end) {
    ++texcoord_count_;
    if (!options_.keep_uvs) return Status::ok();  // counted for relative indices only
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
      return error(std::string("bad ") + what + " index '" + std::string(first, last) + "'");
    }
    if (value == 0) return error(std::string(what) + " index 0 (OBJ indices start at 1)");
    const std::int64_t resolved = value > 0 ? value - 1 : static_cast<std::int64_t>(count) + value;
    if (resolved < 0 || static_cast<std::uint64_t>(resolved) >= count) {
      return error(std::string(what) + " index " + std::to_string(value) + " out of range (" + std::to_string(count) +
                   " defined so far)");
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
        if (options_.keep_uvs) {
          NMBAKE_TRY(resolve_index(vt_first, vt_last, texcoord_count_, "texture coordinate", corner.vt));
        }
      }
      if (vt_last < token_end) {
        if (vt_last + 1 == token_end) return error("missing normal index in corner '" + std::string(token) + "'");
        has_vn = true;
        if (options_.keep_normals) {
          NMBAKE_TRY(resolve_index(vt_last + 1, token_end, normal_count_, "normal", corner.vn));
        }
      } else if (vt_last == vt_first) {
        return error("missing texture coordinate index in corner '" + std::string(token) + "'");
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
      return error("corner '" + std::string(token) + (kept_vt ? "' has" : "' has no") +
                   " texture coordinate index but earlier corners " + (kept_vt ? "do not" : "do"));
    } else if (kept_vn != has_vn_) {
      return error("corner '" + std::string(token) + (kept_vn ? "' has" : "' has no") + " normal index but earlier corners " +
                   (kept_vn ? "do not" : "do"));
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
    }
    return Status::ok();
  }

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
  }

  const std::string& path_;
  FileReader& reader_;
  const LoadOptions& options_;
  Mesh& out_;
  LoadStats& stats_;

  std::vector<glm::vec3> positions_;
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

  std::vector<Corner> corners_;  // scratch of the current face
};

}  // namespace

Status load_obj(const std::string& path, FileReader& reader, const LoadOptions& options, Mesh& out,
                LoadStats& stats) {
  ObjParser parser(path, reader, options, out, stats);
  return parser.run();
}

}  // namespace nmbake::load_detail
