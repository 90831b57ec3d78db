// PLY reader after Greg Turk, "The PLY Polygon File Format" (1994), with the
// sized type aliases (int8 … float64) later writers use: ascii,
// binary_little_endian and binary_big_endian bodies; element "vertex"
// (x y z, optional nx ny nz and a UV pair) and element "face" (list
// vertex_indices or vertex_index, fan-triangulated); everything else skipped
// by its declared layout.
//
// PLY attributes are per vertex, so no vertex is ever split. Fast paths for
// binary bodies: a vertex element of fixed-size scalars is decoded block by
// block with a fixed stride on all cores, and so are the triangles of a face
// element holding only a one-byte-counted list of 32-bit indices (13-byte
// records); the first record these cannot take (a polygon, a bad value, the
// end of the file) goes through the record-by-record reader, which also
// names the byte of any error.
#include <tbb/blocked_range.h>
#include <tbb/parallel_reduce.h>

#include <algorithm>
#include <bit>
#include <cmath>
#include <cstring>
#include <glm/vec2.hpp>
#include <glm/vec3.hpp>
#include <string>
#include <string_view>
#include <vector>

#include "base/huge_pages.hpp"
#include "load/parsers.hpp"

namespace nmbake::load_detail {
namespace {

// Records per task of the parallel decoders: enough work to hide the task
// overhead, small enough to balance two cores on a block.
constexpr std::size_t kRecordGrain = 16384;

std::uint32_t byteswap32(std::uint32_t value) {
  return (value >> 24) | ((value >> 8) & 0xff00u) | ((value << 8) & 0xff0000u) | (value << 24);
}

enum class PlyType : std::uint8_t { int8, uint8, int16, uint16, int32, uint32, float32, float64 };

// The largest value of an integer type (colour channels are fractions of it).
double type_max(PlyType type) {
  switch (type) {
    case PlyType::int8:
      return 127.0;
    case PlyType::uint8:
      return 255.0;
    case PlyType::int16:
      return 32767.0;
    case PlyType::uint16:
      return 65535.0;
    case PlyType::int32:
      return 2147483647.0;
    case PlyType::uint32:
      return 4294967295.0;
    default:
      return 1.0;
  }
}

bool parse_type(std::string_view name, PlyType& type) {
  struct Entry {
    std::string_view name;
    PlyType type;
  };
  static constexpr Entry kTypes[] = {
      {"char", PlyType::int8},       {"int8", PlyType::int8},       {"uchar", PlyType::uint8},
      {"uint8", PlyType::uint8},     {"short", PlyType::int16},     {"int16", PlyType::int16},
      {"ushort", PlyType::uint16},   {"uint16", PlyType::uint16},   {"int", PlyType::int32},
      {"int32", PlyType::int32},     {"uint", PlyType::uint32},     {"uint32", PlyType::uint32},
      {"float", PlyType::float32},   {"float32", PlyType::float32}, {"double", PlyType::float64},
      {"float64", PlyType::float64},
  };
  for (const Entry& entry : kTypes) {
    if (entry.name == name) {
      type = entry.type;
      return true;
    }
  }
  return false;
}

std::size_t type_size(PlyType type) {
  switch (type) {
    case PlyType::int8:
    case PlyType::uint8:
      return 1;
    case PlyType::int16:
    case PlyType::uint16:
      return 2;
    case PlyType::int32:
    case PlyType::uint32:
    case PlyType::float32:
      return 4;
    case PlyType::float64:
      return 8;
  }
  return 0;
}

bool is_integer(PlyType type) { return type != PlyType::float32 && type != PlyType::float64; }

template <typename T>
T load_raw(const char* bytes, bool swap) {
  unsigned char raw[sizeof(T)];
  std::memcpy(raw, bytes, sizeof(T));
  if (swap) {
    for (std::size_t i = 0; i < sizeof(T) / 2; ++i) std::swap(raw[i], raw[sizeof(T) - 1 - i]);
  }
  T value;
  std::memcpy(&value, raw, sizeof(T));
  return value;
}

double load_as_double(const char* bytes, PlyType type, bool swap) {
  switch (type) {
    case PlyType::int8:
      return load_raw<std::int8_t>(bytes, swap);
    case PlyType::uint8:
      return load_raw<std::uint8_t>(bytes, swap);
    case PlyType::int16:
      return load_raw<std::int16_t>(bytes, swap);
    case PlyType::uint16:
      return load_raw<std::uint16_t>(bytes, swap);
    case PlyType::int32:
      return load_raw<std::int32_t>(bytes, swap);
    case PlyType::uint32:
      return load_raw<std::uint32_t>(bytes, swap);
    case PlyType::float32:
      return load_raw<float>(bytes, swap);
    case PlyType::float64:
      return load_raw<double>(bytes, swap);
  }
  return 0.0;
}

// Only for integer types.
std::int64_t load_as_int(const char* bytes, PlyType type, bool swap) {
  switch (type) {
    case PlyType::int8:
      return load_raw<std::int8_t>(bytes, swap);
    case PlyType::uint8:
      return load_raw<std::uint8_t>(bytes, swap);
    case PlyType::int16:
      return load_raw<std::int16_t>(bytes, swap);
    case PlyType::uint16:
      return load_raw<std::uint16_t>(bytes, swap);
    case PlyType::int32:
      return load_raw<std::int32_t>(bytes, swap);
    case PlyType::uint32:
      return load_raw<std::uint32_t>(bytes, swap);
    case PlyType::float32:
    case PlyType::float64:
      break;
  }
  return 0;
}

struct PlyProperty {
  std::string name;
  bool is_list = false;
  PlyType count_type = PlyType::uint8;  // lists only
  PlyType type = PlyType::float32;      // the scalar, or the list item
};

struct PlyElement {
  std::string name;
  std::uint64_t count = 0;
  std::uint64_t line = 0;  // header line, for messages
  std::vector<PlyProperty> properties;

  int find(std::string_view property_name) const {
    for (std::size_t i = 0; i < properties.size(); ++i) {
      if (properties[i].name == property_name) return static_cast<int>(i);
    }
    return -1;
  }
  bool fixed_size() const {
    for (const PlyProperty& property : properties) {
      if (property.is_list) return false;
    }
    return true;
  }
  // Bytes of one entry when every list is empty: a lower bound for binary.
  std::uint64_t min_bytes() const {
    std::uint64_t bytes = 0;
    for (const PlyProperty& property : properties) {
      bytes += type_size(property.is_list ? property.count_type : property.type);
    }
    return bytes;
  }
};

enum class PlyFormat : std::uint8_t { ascii, binary_little_endian, binary_big_endian };

// Vertex attributes gathered into these slots, in this order.
enum Slot : int { kX, kY, kZ, kNx, kNy, kNz, kU, kV, kR, kG, kB, kA, kSlotCount };

class PlyParser {
 public:
  PlyParser(const std::string& path, FileReader& reader, const LoadOptions& options, Mesh& out,
            LoadStats& stats)
      : path_(path), reader_(reader), options_(options), out_(out), stats_(stats) {}

  Status run() {
    NMBAKE_TRY(parse_header());
    NMBAKE_TRY(plan_vertex_layout());
    NMBAKE_TRY(plan_face_layout());
    swap_ = format_ != PlyFormat::ascii &&
            ((format_ == PlyFormat::binary_big_endian) != (std::endian::native == std::endian::big));
    // Sized from the header, so faces may be checked even when they come
    // before the vertices.
    begin_vertices(elements_[static_cast<std::size_t>(vertex_element_)]);
    for (std::size_t e = 0; e < elements_.size(); ++e) {
      const PlyElement& element = elements_[e];
      if (static_cast<int>(e) == vertex_element_) {
        NMBAKE_TRY(format_ == PlyFormat::ascii ? read_vertices_ascii(element)
                                               : read_vertices_binary(element));
      } else if (static_cast<int>(e) == face_element_) {
        NMBAKE_TRY(format_ == PlyFormat::ascii ? read_faces_ascii(element) : read_faces_binary(element));
      } else {
        NMBAKE_TRY(format_ == PlyFormat::ascii ? skip_element_ascii(element) : skip_element_binary(element));
      }
    }
    if (!reader_.read_status().is_ok()) return reader_.read_status();
    if (out_.indices.empty()) {
      return Status::bad_input(path_ + ": no triangles (" + std::to_string(stats_.degenerate_faces) +
                               " faces with fewer than 3 corners skipped)");
    }
    return Status::ok();
  }

 private:
  Status header_error(const std::string& reason) const {
    return text_error(path_, reader_.line_number(), reason);
  }
  Status line_error(const std::string& reason) const {
    return text_error(path_, reader_.line_number(), reason);
  }
  Status byte_error(std::uint64_t offset, const std::string& reason) const {
    return binary_error(path_, offset, reason);
  }

  // ---------------------------------------------------------------- header

  Status parse_header() {
    std::string_view line;
    std::vector<std::string_view> words;
    bool format_seen = false;
    bool first = true;
    for (;;) {
      if (!reader_.next_line(line)) {
        if (first) return Status::bad_input(path_ + ": not a PLY file (it is empty)");
        return header_error("file ends inside the header (no end_header)");
      }
      split_words(line, words);
      if (first) {
        if (words.size() != 1 || words[0] != "ply")
          return header_error("not a PLY file (first line is not 'ply')");
        first = false;
        continue;
      }
      if (words.empty() || words[0] == "comment" || words[0] == "obj_info") continue;
      if (words[0] == "end_header") break;
      if (words[0] == "format") {
        if (words.size() < 2) return header_error("format line without a format");
        if (words[1] == "ascii") {
          format_ = PlyFormat::ascii;
        } else if (words[1] == "binary_little_endian") {
          format_ = PlyFormat::binary_little_endian;
        } else if (words[1] == "binary_big_endian") {
          format_ = PlyFormat::binary_big_endian;
        } else {
          return header_error("unknown format '" + token_text(words[1]) + "'");
        }
        format_seen = true;
      } else if (words[0] == "element") {
        if (words.size() != 3) return header_error("expected 'element NAME COUNT'");
        PlyElement element;
        element.name = std::string(words[1]);
        element.line = reader_.line_number();
        std::int64_t count = 0;
        if (parse_int(words[2].data(), words[2].data() + words[2].size(), count) != NumberError::none ||
            count < 0) {
          return header_error("bad element count '" + token_text(words[2]) + "'");
        }
        element.count = static_cast<std::uint64_t>(count);
        elements_.push_back(std::move(element));
      } else if (words[0] == "property") {
        if (elements_.empty()) return header_error("property before any element");
        PlyProperty property;
        if (words.size() == 5 && words[1] == "list") {
          property.is_list = true;
          if (!parse_type(words[2], property.count_type)) {
            return header_error("unknown property type '" + token_text(words[2]) + "'");
          }
          if (!is_integer(property.count_type))
            return header_error("list count type must be an integer type");
          if (!parse_type(words[3], property.type)) {
            return header_error("unknown property type '" + token_text(words[3]) + "'");
          }
          property.name = std::string(words[4]);
        } else if (words.size() == 3 && words[1] != "list") {
          if (!parse_type(words[1], property.type)) {
            return header_error("unknown property type '" + token_text(words[1]) + "'");
          }
          property.name = std::string(words[2]);
        } else {
          return header_error("expected 'property TYPE NAME' or 'property list COUNT_TYPE TYPE NAME'");
        }
        elements_.back().properties.push_back(std::move(property));
      } else {
        return header_error("unknown header line '" + token_text(line) + "'");
      }
    }
    if (!format_seen) return header_error("no format line in the header");
    // A header must not promise more than the file can hold: this catches
    // truncated files early and keeps a corrupt count from allocating
    // gigabytes.
    const std::uint64_t body_bytes = reader_.file_size() - std::min(reader_.file_size(), reader_.offset());
    std::uint64_t needed = 0;
    for (const PlyElement& element : elements_) {
      const std::uint64_t per_entry =
          format_ == PlyFormat::ascii ? element.properties.size() : element.min_bytes();
      if (per_entry == 0) continue;
      if (element.count > body_bytes / per_entry || needed + element.count * per_entry > body_bytes) {
        return text_error(path_, element.line,
                          "element '" + token_text(element.name) + "' has " + std::to_string(element.count) +
                              " entries, more than the " + std::to_string(body_bytes) +
                              " bytes after the header can hold (truncated file?)");
      }
      needed += element.count * per_entry;
    }
    return Status::ok();
  }

  static void split_words(std::string_view line, std::vector<std::string_view>& words) {
    words.clear();
    const char* p = line.data();
    const char* end = line.data() + line.size();
    for (;;) {
      p = skip_blanks(p, end);
      if (p == end) return;
      const char* word_end = skip_token(p, end);
      words.emplace_back(p, static_cast<std::size_t>(word_end - p));
      p = word_end;
    }
  }

  Status plan_vertex_layout() {
    for (std::size_t e = 0; e < elements_.size(); ++e) {
      if (elements_[e].name == "vertex") vertex_element_ = static_cast<int>(e);
      if (elements_[e].name == "face") face_element_ = static_cast<int>(e);
    }
    if (vertex_element_ < 0) return Status::bad_input(path_ + ": no element 'vertex' in the header");
    const PlyElement& vertex = elements_[static_cast<std::size_t>(vertex_element_)];
    if (vertex.count >= 0xffffffffu) {
      return text_error(path_, vertex.line, "too many vertices (" + std::to_string(vertex.count) + ")");
    }
    slot_of_property_.assign(vertex.properties.size(), -1);
    auto assign = [&](std::string_view name, int slot) {
      const int property = vertex.find(name);
      if (property >= 0) slot_of_property_[static_cast<std::size_t>(property)] = slot;
      return property >= 0;
    };
    if (!assign("x", kX) || !assign("y", kY) || !assign("z", kZ)) {
      return text_error(path_, vertex.line, "element 'vertex' lacks one of the properties x, y, z");
    }
    if (options_.keep_normals) {
      const int present_count =
          int(vertex.find("nx") >= 0) + int(vertex.find("ny") >= 0) + int(vertex.find("nz") >= 0);
      if (present_count == 3) {
        assign("nx", kNx);
        assign("ny", kNy);
        assign("nz", kNz);
        has_normals_ = true;
      } else if (present_count != 0) {
        return text_error(path_, vertex.line, "element 'vertex' has some but not all of nx, ny, nz");
      }
    }
    if (options_.keep_uvs) {
      static constexpr std::string_view kUvNames[][2] = {
          {"u", "v"}, {"s", "t"}, {"texture_u", "texture_v"}, {"texture_s", "texture_t"}};
      for (const auto& pair : kUvNames) {
        const bool has_first = vertex.find(pair[0]) >= 0;
        const bool has_second = vertex.find(pair[1]) >= 0;
        if (has_first != has_second) {
          return text_error(path_, vertex.line,
                            "element 'vertex' has property '" + token_text(has_first ? pair[0] : pair[1]) +
                                "' but not '" + token_text(has_first ? pair[1] : pair[0]) + "'");
        }
        if (has_first && !has_uvs_) {
          assign(pair[0], kU);
          assign(pair[1], kV);
          has_uvs_ = true;
        }
      }
    }
    if (options_.keep_colors) {
      // red/green/blue (MeshLab, Blender, ZBrush) or r/g/b; alpha optional.
      static constexpr std::string_view kColorNames[][4] = {
          {"red", "green", "blue", "alpha"},
          {"r", "g", "b", "a"},
          {"diffuse_red", "diffuse_green", "diffuse_blue", "diffuse_alpha"}};
      for (const auto& names : kColorNames) {
        if (has_colors_ || vertex.find(names[0]) < 0 || vertex.find(names[1]) < 0 ||
            vertex.find(names[2]) < 0)
          continue;
        for (int c = 0; c < 4; ++c) {
          const int property = vertex.find(names[c]);
          if (property < 0) continue;  // no alpha: 1
          assign(names[c], kR + c);
          // Integer channels are fractions of their type's largest value.
          const PlyType type = vertex.properties[static_cast<std::size_t>(property)].type;
          color_divisor_[c] = type == PlyType::float32 || type == PlyType::float64
                                  ? 1.0f
                                  : static_cast<float>(type_max(type));
          has_alpha_ = has_alpha_ || c == 3;
        }
        has_colors_ = true;
      }
    }
    for (std::size_t i = 0; i < vertex.properties.size(); ++i) {
      if (slot_of_property_[i] >= 0 && vertex.properties[i].is_list) {
        return text_error(path_, vertex.line,
                          "vertex property '" + token_text(vertex.properties[i].name) + "' is a list");
      }
    }
    return Status::ok();
  }

  Status plan_face_layout() {
    if (face_element_ < 0)
      return Status::bad_input(path_ + ": no triangles (no element 'face' in the header)");
    const PlyElement& face = elements_[static_cast<std::size_t>(face_element_)];
    index_property_ = face.find("vertex_indices");
    if (index_property_ < 0) index_property_ = face.find("vertex_index");
    if (index_property_ < 0) {
      return text_error(path_, face.line, "element 'face' has no property vertex_indices or vertex_index");
    }
    const PlyProperty& property = face.properties[static_cast<std::size_t>(index_property_)];
    if (!property.is_list || !is_integer(property.type)) {
      return text_error(path_, face.line,
                        "face property '" + token_text(property.name) + "' must be a list of integers");
    }
    return Status::ok();
  }

  // ---------------------------------------------------------------- shared

  void begin_vertices(const PlyElement& element) {
    const auto count = static_cast<std::size_t>(element.count);
    // One spare position: Embree reads 16 bytes at the last vertex
    // (pad_for_embree), and growing later would copy the whole array.
    // Advised before the first touch (huge_pages.hpp): 2 MB pages are faulted
    // in 512 times less often than 4 KB ones (BENCHMARKS.md, "Loading"), and
    // the bake's scattered reads of the hits' corners miss the TLB less.
    detail::reserve_huge_pages(out_.positions, count + 1);
    out_.positions.resize(count);
    if (has_normals_) {
      detail::reserve_huge_pages(out_.normals, count);
      out_.normals.resize(count);
    }
    if (has_uvs_) out_.uvs.resize(count);
    if (has_colors_) out_.colors.resize(count);
  }

  void store_vertex(std::size_t index, const float* values) {
    out_.positions[index] = glm::vec3(values[kX], values[kY], values[kZ]);
    if (has_normals_) out_.normals[index] = glm::vec3(values[kNx], values[kNy], values[kNz]);
    if (has_uvs_) out_.uvs[index] = glm::vec2(values[kU], values[kV]);
    if (has_colors_) {
      out_.colors[index] =
          glm::vec4(values[kR] / color_divisor_[0], values[kG] / color_divisor_[1],
                    values[kB] / color_divisor_[2], has_alpha_ ? values[kA] / color_divisor_[3] : 1.0f);
    }
  }

  // Fan-triangulates corners_ (already range-checked).
  void emit_face() {
    if (corners_.size() < 3) {
      ++stats_.degenerate_faces;
      return;
    }
    ++stats_.polygons;
    for (std::size_t i = 1; i + 1 < corners_.size(); ++i) {
      out_.indices.push_back(corners_[0]);
      out_.indices.push_back(corners_[i]);
      out_.indices.push_back(corners_[i + 1]);
    }
  }

  std::string index_error_text(std::uint64_t face, std::int64_t index) const {
    return "face " + std::to_string(face) + ": vertex index " + std::to_string(index) + " out of range (" +
           std::to_string(out_.positions.size()) + " vertices)";
  }

  // ---------------------------------------------------------------- binary

  Status truncated(std::uint64_t offset, const PlyElement& element, std::uint64_t entry) const {
    return byte_error(offset, "file ends inside " + token_text(element.name) + " " + std::to_string(entry) +
                                  " of " + std::to_string(element.count));
  }

  Status non_finite(std::uint64_t offset, std::uint64_t vertex, double value) const {
    return byte_error(offset, "vertex " + std::to_string(vertex) + ": non-finite value " +
                                  std::to_string(value) + " (NaN, Inf or beyond float range)");
  }

  struct WantedValue {
    std::size_t offset;  // in the record
    PlyType type;
    int slot;
  };

  // One wanted value of a fixed-stride record as float; false when it is not
  // finite (NaN, Inf or beyond float range).
  bool decode_value(const char* record, const WantedValue& w, float& value) const {
    if (w.type == PlyType::float32) {
      std::uint32_t bits;
      std::memcpy(&bits, record + w.offset, sizeof(bits));
      if (swap_) bits = byteswap32(bits);
      value = std::bit_cast<float>(bits);
    } else {
      value = static_cast<float>(load_as_double(record + w.offset, w.type, swap_));
    }
    return std::isfinite(value);
  }

  Status read_vertices_binary(const PlyElement& element) {
    float values[kSlotCount] = {};
    if (element.fixed_size()) {
      std::size_t stride = 0;
      std::vector<std::size_t> offsets(element.properties.size());
      for (std::size_t i = 0; i < element.properties.size(); ++i) {
        offsets[i] = stride;
        stride += type_size(element.properties[i].type);
      }
      std::vector<WantedValue> wanted;
      for (std::size_t i = 0; i < element.properties.size(); ++i) {
        if (slot_of_property_[i] >= 0)
          wanted.push_back({offsets[i], element.properties[i].type, slot_of_property_[i]});
      }
      std::uint64_t v = options_.serial ? 0 : read_vertex_blocks(element, stride, wanted);
      // The rest (nothing, or the record with an error, or a truncated end)
      // record by record, which names the byte of the problem.
      for (; v < element.count; ++v) {
        const std::uint64_t record_offset = reader_.offset();
        const char* record = reader_.take(stride);
        if (record == nullptr) return truncated(record_offset, element, v);
        for (const WantedValue& w : wanted) {
          if (!decode_value(record, w, values[w.slot])) {
            return non_finite(record_offset + w.offset, v, load_as_double(record + w.offset, w.type, swap_));
          }
        }
        store_vertex(static_cast<std::size_t>(v), values);
      }
      return Status::ok();
    }
    for (std::uint64_t v = 0; v < element.count; ++v) {
      for (std::size_t i = 0; i < element.properties.size(); ++i) {
        const PlyProperty& property = element.properties[i];
        const std::uint64_t value_offset = reader_.offset();
        if (property.is_list) {
          NMBAKE_TRY(skip_list_binary(property, element, v));
          continue;
        }
        const char* bytes = reader_.take(type_size(property.type));
        if (bytes == nullptr) return truncated(value_offset, element, v);
        if (slot_of_property_[i] < 0) continue;
        const double wide = load_as_double(bytes, property.type, swap_);
        const auto value = static_cast<float>(wide);
        if (!std::isfinite(value)) return non_finite(value_offset, v, wide);
        values[slot_of_property_[i]] = value;
      }
      store_vertex(static_cast<std::size_t>(v), values);
    }
    return Status::ok();
  }

  // Decodes whole blocks of fixed-stride vertex records on all cores, up to
  // the first record with a non-finite value or the end of the file; returns
  // how many records were stored. Each record lands in its own slot, so the
  // result does not depend on the thread count.
  std::uint64_t read_vertex_blocks(const PlyElement& element, std::size_t stride,
                                   const std::vector<WantedValue>& wanted) {
    const std::size_t records_per_block = std::max<std::size_t>(1, block_bytes(options_) / stride);
    std::uint64_t v = 0;
    while (v < element.count) {
      const auto want =
          static_cast<std::size_t>(std::min<std::uint64_t>(records_per_block, element.count - v));
      const char* bytes = nullptr;
      const std::size_t record_count = reader_.peek(want * stride, bytes) / stride;
      if (record_count == 0) break;
      const std::size_t first_bad = tbb::parallel_reduce(
          tbb::blocked_range<std::size_t>(0, record_count, kRecordGrain), record_count,
          [&](const tbb::blocked_range<std::size_t>& range, std::size_t bad) {
            float record_values[kSlotCount] = {};
            for (std::size_t r = range.begin(); r != range.end(); ++r) {
              const char* record = bytes + r * stride;
              bool finite = true;
              for (const WantedValue& w : wanted) finite &= decode_value(record, w, record_values[w.slot]);
              if (!finite) return std::min(bad, r);
              store_vertex(static_cast<std::size_t>(v + r), record_values);
            }
            return bad;
          },
          [](std::size_t a, std::size_t b) { return std::min(a, b); });
      reader_.consume(first_bad * stride);
      v += first_bad;
      if (first_bad < record_count) break;
    }
    return v;
  }

  // Reads a list count, checking it against what the file can still hold.
  Status read_list_count_binary(const PlyProperty& property, const PlyElement& element, std::uint64_t entry,
                                std::uint64_t& count) {
    const std::uint64_t offset = reader_.offset();
    const char* bytes = reader_.take(type_size(property.count_type));
    if (bytes == nullptr) return truncated(offset, element, entry);
    const std::int64_t value = load_as_int(bytes, property.count_type, swap_);
    if (value < 0)
      return byte_error(offset,
                        token_text(element.name) + " " + std::to_string(entry) + ": negative list count");
    count = static_cast<std::uint64_t>(value);
    const std::uint64_t remaining = reader_.file_size() - std::min(reader_.file_size(), reader_.offset());
    if (count * type_size(property.type) > remaining) return truncated(offset, element, entry);
    return Status::ok();
  }

  Status skip_list_binary(const PlyProperty& property, const PlyElement& element, std::uint64_t entry) {
    std::uint64_t count = 0;
    const std::uint64_t offset = reader_.offset();
    NMBAKE_TRY(read_list_count_binary(property, element, entry, count));
    if (!reader_.skip(count * type_size(property.type))) return truncated(offset, element, entry);
    return Status::ok();
  }

  Status read_faces_binary(const PlyElement& element) {
    const PlyProperty& index_property = element.properties[static_cast<std::size_t>(index_property_)];
    // The layout of nearly every binary PLY: a one-byte count and 32-bit
    // indices, nothing else. Its triangles are 13-byte records.
    const bool one_list = element.properties.size() == 1 && type_size(index_property.count_type) == 1 &&
                          type_size(index_property.type) == 4;
    std::uint64_t f = 0;
    while (f < element.count) {
      if (one_list && !options_.serial) {
        f += read_triangle_blocks(element, f);
        if (f == element.count) break;
      }
      // One face the blocks could not take (a polygon, an error, the end of
      // the file), or every face when the layout is another.
      NMBAKE_TRY(read_face_binary(element, f));
      ++f;
    }
    return Status::ok();
  }

  // Decodes 13-byte triangle records from face `first` on, on all cores, up
  // to the first record that is not a triangle with indices in range (or the
  // end of the file); returns how many were stored.
  std::uint64_t read_triangle_blocks(const PlyElement& element, std::uint64_t first) {
    constexpr std::size_t kStride = 13;
    const std::size_t records_per_block = std::max<std::size_t>(1, block_bytes(options_) / kStride);
    const auto vertex_count = static_cast<std::uint32_t>(out_.positions.size());
    const bool swap = swap_;
    if (out_.indices.capacity() == 0) {
      detail::reserve_huge_pages(out_.indices, static_cast<std::size_t>(element.count) * 3);
    }
    std::uint64_t f = first;
    while (f < element.count) {
      const auto want =
          static_cast<std::size_t>(std::min<std::uint64_t>(records_per_block, element.count - f));
      const char* bytes = nullptr;
      const std::size_t record_count = reader_.peek(want * kStride, bytes) / kStride;
      if (record_count == 0) break;
      const std::size_t base = out_.indices.size();
      out_.indices.resize(base + record_count * 3);
      std::uint32_t* indices = out_.indices.data() + base;
      const std::size_t first_bad = tbb::parallel_reduce(
          tbb::blocked_range<std::size_t>(0, record_count, kRecordGrain), record_count,
          [&](const tbb::blocked_range<std::size_t>& range, std::size_t bad) {
            for (std::size_t r = range.begin(); r != range.end(); ++r) {
              const char* record = bytes + r * kStride;
              std::uint32_t triangle[3];
              std::memcpy(triangle, record + 1, sizeof(triangle));
              if (swap) {
                for (std::uint32_t& index : triangle) index = byteswap32(index);
              }
              // A negative int32 index is a huge uint32: out of range too.
              if (record[0] != 3 || triangle[0] >= vertex_count || triangle[1] >= vertex_count ||
                  triangle[2] >= vertex_count) {
                return std::min(bad, r);
              }
              std::memcpy(indices + 3 * r, triangle, sizeof(triangle));
            }
            return bad;
          },
          [](std::size_t a, std::size_t b) { return std::min(a, b); });
      out_.indices.resize(base + first_bad * 3);
      stats_.polygons += first_bad;
      reader_.consume(first_bad * kStride);
      f += first_bad;
      if (first_bad < record_count) break;
    }
    return f - first;
  }

  // Face `f`, property by property (fan-triangulated, range-checked).
  Status read_face_binary(const PlyElement& element, std::uint64_t f) {
    const PlyProperty& index_property = element.properties[static_cast<std::size_t>(index_property_)];
    const std::size_t index_size = type_size(index_property.type);
    if (element.properties.size() == 1 && type_size(index_property.count_type) == 1 && index_size == 4 &&
        !swap_) {
      // As the record-by-record reader always did for this layout: a
      // truncated triangle is reported at its start, a truncated polygon at
      // its first missing index.
      const std::uint64_t face_offset = reader_.offset();
      const char* count_byte = reader_.take(1);
      if (count_byte == nullptr) return truncated(face_offset, element, f);
      if (*count_byte == 3 && reader_.offset() + 12 > reader_.file_size()) {
        return truncated(face_offset, element, f);
      }
      const std::int64_t count = load_as_int(count_byte, index_property.count_type, swap_);
      if (count < 0) return byte_error(face_offset, "face " + std::to_string(f) + ": negative list count");
      NMBAKE_TRY(
          read_indices_binary(static_cast<std::uint64_t>(count), index_property, index_size, element, f));
      emit_face();
      return Status::ok();
    }
    for (std::size_t i = 0; i < element.properties.size(); ++i) {
      const PlyProperty& property = element.properties[i];
      const std::uint64_t value_offset = reader_.offset();
      if (static_cast<int>(i) == index_property_) {
        std::uint64_t count = 0;
        NMBAKE_TRY(read_list_count_binary(property, element, f, count));
        NMBAKE_TRY(read_indices_binary(count, property, index_size, element, f));
      } else if (property.is_list) {
        NMBAKE_TRY(skip_list_binary(property, element, f));
      } else if (reader_.take(type_size(property.type)) == nullptr) {
        return truncated(value_offset, element, f);
      }
    }
    emit_face();
    return Status::ok();
  }

  Status read_indices_binary(std::uint64_t count, const PlyProperty& property, std::size_t index_size,
                             const PlyElement& element, std::uint64_t face) {
    corners_.clear();
    for (std::uint64_t c = 0; c < count; ++c) {
      const std::uint64_t offset = reader_.offset();
      const char* bytes = reader_.take(index_size);
      if (bytes == nullptr) return truncated(offset, element, face);
      const std::int64_t index = load_as_int(bytes, property.type, swap_);
      if (index < 0 || static_cast<std::uint64_t>(index) >= out_.positions.size()) {
        return byte_error(offset, index_error_text(face, index));
      }
      corners_.push_back(static_cast<std::uint32_t>(index));
    }
    return Status::ok();
  }

  Status skip_element_binary(const PlyElement& element) {
    if (element.fixed_size()) {
      const std::uint64_t offset = reader_.offset();
      const std::uint64_t stride = element.min_bytes();
      if (!reader_.skip(stride * element.count)) {
        const std::uint64_t end = reader_.offset();
        return truncated(end, element, stride == 0 ? 0 : (end - offset) / stride);
      }
      return Status::ok();
    }
    for (std::uint64_t entry = 0; entry < element.count; ++entry) {
      for (const PlyProperty& property : element.properties) {
        const std::uint64_t offset = reader_.offset();
        if (property.is_list) {
          NMBAKE_TRY(skip_list_binary(property, element, entry));
        } else if (reader_.take(type_size(property.type)) == nullptr) {
          return truncated(offset, element, entry);
        }
      }
    }
    return Status::ok();
  }

  // ---------------------------------------------------------------- ascii

  // Next whitespace-separated token of the body; entries may span lines.
  bool next_token(std::string_view& token) {
    for (;;) {
      cursor_ = skip_blanks(cursor_, line_end_);
      if (cursor_ < line_end_) {
        const char* token_end = skip_token(cursor_, line_end_);
        token = std::string_view(cursor_, static_cast<std::size_t>(token_end - cursor_));
        cursor_ = token_end;
        return true;
      }
      std::string_view line;
      if (!reader_.next_line(line)) return false;
      cursor_ = line.data();
      line_end_ = line.data() + line.size();
    }
  }

  Status ascii_truncated(const PlyElement& element, std::uint64_t entry) const {
    return line_error("file ends inside " + token_text(element.name) + " " + std::to_string(entry) + " of " +
                      std::to_string(element.count));
  }

  Status ascii_value(PlyType type, std::string_view token, float& value) const {
    NumberError number_error = NumberError::none;
    if (type == PlyType::float32) {
      number_error = parse_float(token.data(), token.data() + token.size(), value);
    } else if (type == PlyType::float64) {
      double wide = 0.0;
      number_error = parse_double(token.data(), token.data() + token.size(), wide);
      value = static_cast<float>(wide);
      if (number_error == NumberError::none && !std::isfinite(value)) number_error = NumberError::overflow;
    } else {
      std::int64_t integer = 0;
      number_error = parse_int(token.data(), token.data() + token.size(), integer);
      value = static_cast<float>(integer);
    }
    if (number_error != NumberError::none) return line_error(number_error_text(number_error, token));
    return Status::ok();
  }

  Status ascii_int(std::string_view token, std::int64_t& value) const {
    const NumberError number_error = parse_int(token.data(), token.data() + token.size(), value);
    if (number_error != NumberError::none) return line_error(number_error_text(number_error, token));
    return Status::ok();
  }

  Status ascii_list_count(const PlyElement& element, std::uint64_t entry, std::uint64_t& count) {
    std::string_view token;
    if (!next_token(token)) return ascii_truncated(element, entry);
    std::int64_t value = 0;
    NMBAKE_TRY(ascii_int(token, value));
    if (value < 0)
      return line_error(token_text(element.name) + " " + std::to_string(entry) + ": negative list count");
    count = static_cast<std::uint64_t>(value);
    return Status::ok();
  }

  Status skip_property_ascii(const PlyProperty& property, const PlyElement& element, std::uint64_t entry) {
    std::string_view token;
    std::uint64_t count = 1;
    if (property.is_list) NMBAKE_TRY(ascii_list_count(element, entry, count));
    for (std::uint64_t i = 0; i < count; ++i) {
      if (!next_token(token)) return ascii_truncated(element, entry);
    }
    return Status::ok();
  }

  Status read_vertices_ascii(const PlyElement& element) {
    float values[kSlotCount] = {};
    std::string_view token;
    for (std::uint64_t v = 0; v < element.count; ++v) {
      for (std::size_t i = 0; i < element.properties.size(); ++i) {
        const PlyProperty& property = element.properties[i];
        if (slot_of_property_[i] < 0) {
          NMBAKE_TRY(skip_property_ascii(property, element, v));
          continue;
        }
        if (!next_token(token)) return ascii_truncated(element, v);
        NMBAKE_TRY(ascii_value(property.type, token, values[slot_of_property_[i]]));
      }
      store_vertex(static_cast<std::size_t>(v), values);
    }
    return Status::ok();
  }

  Status read_faces_ascii(const PlyElement& element) {
    std::string_view token;
    for (std::uint64_t f = 0; f < element.count; ++f) {
      for (std::size_t i = 0; i < element.properties.size(); ++i) {
        const PlyProperty& property = element.properties[i];
        if (static_cast<int>(i) != index_property_) {
          NMBAKE_TRY(skip_property_ascii(property, element, f));
          continue;
        }
        std::uint64_t count = 0;
        NMBAKE_TRY(ascii_list_count(element, f, count));
        corners_.clear();
        for (std::uint64_t c = 0; c < count; ++c) {
          if (!next_token(token)) return ascii_truncated(element, f);
          std::int64_t index = 0;
          NMBAKE_TRY(ascii_int(token, index));
          if (index < 0 || static_cast<std::uint64_t>(index) >= out_.positions.size()) {
            return line_error(index_error_text(f, index));
          }
          corners_.push_back(static_cast<std::uint32_t>(index));
        }
      }
      emit_face();
    }
    return Status::ok();
  }

  Status skip_element_ascii(const PlyElement& element) {
    for (std::uint64_t entry = 0; entry < element.count; ++entry) {
      for (const PlyProperty& property : element.properties)
        NMBAKE_TRY(skip_property_ascii(property, element, entry));
    }
    return Status::ok();
  }

  const std::string& path_;
  FileReader& reader_;
  const LoadOptions& options_;
  Mesh& out_;
  LoadStats& stats_;

  PlyFormat format_ = PlyFormat::ascii;
  bool swap_ = false;
  std::vector<PlyElement> elements_;
  int vertex_element_ = -1;
  int face_element_ = -1;
  int index_property_ = -1;            // in the face element
  std::vector<int> slot_of_property_;  // per vertex property: Slot or -1
  bool has_normals_ = false;
  bool has_uvs_ = false;
  bool has_colors_ = false, has_alpha_ = false;
  float color_divisor_[4] = {1.0f, 1.0f, 1.0f, 1.0f};

  std::vector<std::uint32_t> corners_;  // scratch of the current face
  const char* cursor_ = nullptr;        // ascii body: rest of the current line
  const char* line_end_ = nullptr;
};

}  // namespace

Status load_ply(const std::string& path, FileReader& reader, const LoadOptions& options, Mesh& out,
                LoadStats& stats) {
  PlyParser parser(path, reader, options, out, stats);
  return parser.run();
}

}  // namespace nmbake::load_detail
