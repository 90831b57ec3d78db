// Private to the load stage: the chunked file reader shared by the OBJ and PLY
// parsers, the error-message helpers, and the per-format entry points.
//
// The reader keeps one fixed buffer (grown only for a line longer than it) and
// refills it with read(2): a multi-gigabyte high mesh is streamed, not mapped
// or slurped, so memory stays at the size of the mesh arrays and the buffer's
// pages fault in once.
#pragma once

#include <fast_float/fast_float.h>

#include <algorithm>
#include <cmath>
#include <cstddef>
#include <cstdint>
#include <cstring>
#include <memory>
#include <string>
#include <string_view>
#include <type_traits>
#include <vector>

#include "nmbake/common.hpp"
#include "nmbake/load.hpp"
#include "nmbake/mesh.hpp"

namespace nmbake::load_detail {

// The longest text line a mesh file may have (README, "Limits"); no real
// OBJ or PLY header line comes near it.
constexpr std::size_t kMaxLineBytes = std::size_t{64} << 20;

class FileReader {
 public:
  FileReader() = default;
  ~FileReader();
  FileReader(const FileReader&) = delete;
  FileReader& operator=(const FileReader&) = delete;

  // bad_input "PATH: cannot open: REASON" when the file cannot be opened.
  Status open(const std::string& path);
  std::uint64_t file_size() const { return file_size_; }

  // Text: the next line without its "\n" or "\r\n"; false at the end of the
  // file (or after a read error, see read_status()). line_number() is the
  // 1-based number of the line last returned.
  bool next_line(std::string_view& line) {
    const char* newline = static_cast<const char*>(std::memchr(data_ + pos_, '\n', end_ - pos_));
    if (newline == nullptr) return next_line_slow(line);
    const std::size_t length = static_cast<std::size_t>(newline - (data_ + pos_));
    line = std::string_view(data_ + pos_, length);
    pos_ += length + 1;
    ++line_number_;
    if (!line.empty() && line.back() == '\r') line.remove_suffix(1);
    return true;
  }
  std::uint64_t line_number() const { return line_number_; }

  // Binary: a pointer to the next `count` bytes (valid until the next call),
  // consumed; nullptr when the file ends first (or on a read error).
  const char* take(std::size_t count) {
    if (end_ - pos_ < count && !fill(count)) return nullptr;
    const char* bytes = data_ + pos_;
    pos_ += count;
    return bytes;
  }
  // Binary: consumes `count` bytes without keeping them; false when the file
  // ends first.
  bool skip(std::uint64_t count);
  // Blocks for the parallel decoders: up to `count` bytes at the read
  // position, not consumed; returns how many (0 only at the end of the file
  // or after a read error). Refills only when fewer than half are buffered,
  // so a decoder that stops early and resumes does not move the buffer each
  // time. The request is capped at what the file still holds, so a small
  // file keeps a small buffer.
  std::size_t peek(std::size_t count, const char*& bytes) {
    if (ahead_pending_) join_ahead();
    const std::uint64_t unread = file_size_ - std::min(file_size_, offset());
    count = static_cast<std::size_t>(std::min<std::uint64_t>(count, std::max<std::uint64_t>(unread, 1)));
    if (end_ - pos_ < (count + 1) / 2) fill(count);
    bytes = data_ + pos_;
    return std::min(count, end_ - pos_);
  }
  // Consumes `count` bytes of what peek() returned.
  void consume(std::size_t count) { pos_ += count; }
  // Blocks: reads up to `count` bytes after the buffered ones into a second
  // buffer, which the next peek() (or any refill) joins behind the unread
  // bytes. Meant to run on another thread while the caller decodes what
  // peek() returned: it touches only that second buffer and the file
  // position, so nothing else of the reader may be used until it returns.
  void read_ahead(std::size_t count);
  // Text blocks: counts the lines the caller consumed through peek().
  void add_lines(std::uint64_t count) { line_number_ += count; }

  // Absolute file offset of the next unread byte.
  std::uint64_t offset() const { return buffer_offset_ + pos_; }

  // ok, or io "PATH: read failed: REASON" if read(2) failed, or bad_input
  // "PATH:LINE: line longer than 64 MiB" (kMaxLineBytes).
  const Status& read_status() const { return read_status_; }

 private:
  bool next_line_slow(std::string_view& line);
  // Makes at least `count` bytes available after pos_; false at end of file.
  bool fill(std::size_t count);
  // Puts the read_ahead() bytes behind the unread ones.
  void join_ahead();

  std::string path_;
  int fd_ = -1;
  std::uint64_t file_size_ = 0;
  std::unique_ptr<char[]> buffer_;  // not zero-filled: pages fault in only when read into
  std::size_t buffer_bytes_ = 0;    // its size
  std::size_t capacity_ = 0;        // bytes from data_ to the end of buffer_
  char* data_ = nullptr;            // in buffer_ (after the room for an unread tail, see join_ahead())
  std::size_t pos_ = 0;
  std::size_t end_ = 0;
  std::uint64_t buffer_offset_ = 0;  // file offset of buffer_[0]
  std::uint64_t line_number_ = 0;
  bool eof_ = false;
  Status read_status_;
  // read_ahead(): its bytes at ahead_[kAheadRoom, kAheadRoom + ahead_end_).
  std::unique_ptr<char[]> ahead_;
  std::size_t ahead_bytes_ = 0;
  std::size_t ahead_end_ = 0;
  bool ahead_pending_ = false;
  bool ahead_eof_ = false;
  Status ahead_status_;
};

// ---- token helpers shared by the text parsers ----

inline bool is_blank(char c) { return c == ' ' || c == '\t' || c == '\r' || c == '\v' || c == '\f'; }
inline const char* skip_blanks(const char* p, const char* end) {
  while (p < end && is_blank(*p)) ++p;
  return p;
}
inline const char* skip_token(const char* p, const char* end) {
  while (p < end && !is_blank(*p)) ++p;
  return p;
}

enum class NumberError : std::uint8_t { none, syntax, overflow, non_finite };

// std::from_chars and fast_float reject a leading '+', which some exporters
// write: skipped here (but not in "+-1" or "++1").
inline const char* skip_plus(const char* first, const char* last) {
  if (last - first > 1 && *first == '+' && first[1] != '-' && first[1] != '+') return first + 1;
  return first;
}

// Parses all of [first, last) as a number (a leading '+' is accepted; for
// reals an underflow becomes a signed zero, an overflow or "inf"/"nan" an
// error, so no NaN/Inf enters a mesh).
//
// Reals through fast_float (libfast-float-dev, header-only), inline so the
// OBJ parser's loops keep them: every result is the correctly rounded one,
// what strtof/strtod give (tests/load_test.cpp, "ParseReal"). fast_float
// gives +-Inf for a finite number too large and a signed zero or a
// subnormal for one too small, as strtod does; "inf"/"nan" as from_chars.
//
// The plain form most files are written in, "-?digits[.digits]" of at most
// 19 digits with no exponent, first takes a shortcut (read_plain_decimal):
// the digits m and the count e after the point are exact in a double, so
// m / 10^e is the correctly rounded double (one IEEE division, Clinger's
// fast path); a float rounded from that double is the correctly rounded
// float unless the double falls exactly halfway between two floats (then
// the shortcut is not taken) or below the normal floats (not taken either).
inline constexpr double kExactPowersOfTen[] = {1e0,  1e1,  1e2,  1e3,  1e4,  1e5,  1e6,  1e7,
                                               1e8,  1e9,  1e10, 1e11, 1e12, 1e13, 1e14, 1e15,
                                               1e16, 1e17, 1e18, 1e19, 1e20, 1e21, 1e22};

// The end of the plain decimal at p (before `last`) and its value, or
// nullptr when p does not start one the shortcut takes.
template <typename Real>
inline const char* read_plain_decimal(const char* p, const char* last, Real& value) {
  const bool negative = p < last && *p == '-';
  if (negative) ++p;
  std::uint64_t mantissa = 0;
  int digits = 0;
  int fraction_digits = 0;
  bool point = false;
  for (; p < last; ++p) {
    const auto digit = static_cast<unsigned>(*p - '0');
    if (digit <= 9) {
      mantissa = mantissa * 10 + digit;
      ++digits;
      fraction_digits += point ? 1 : 0;
    } else if (*p == '.' && !point) {
      point = true;
    } else {
      break;
    }
  }
  if (digits == 0 || digits > 19 || mantissa > (std::uint64_t{1} << 53)) return nullptr;
  if (p < last && (*p == 'e' || *p == 'E')) return nullptr;
  const double exact = static_cast<double>(mantissa) / kExactPowersOfTen[fraction_digits];
  if constexpr (std::is_same_v<Real, float>) {
    if (exact != 0.0) {
      if (exact < 0x1p-126) return nullptr;
      std::uint64_t bits = 0;
      std::memcpy(&bits, &exact, sizeof bits);
      // The 29 bits a float drops: exactly half of its last place.
      if ((bits & ((std::uint64_t{1} << 29) - 1)) == (std::uint64_t{1} << 28)) return nullptr;
    }
  }
  const auto rounded = static_cast<Real>(exact);
  value = negative ? -rounded : rounded;
  return p;
}

// A real at the start of [first, last) (no '+'): its end and value, or
// nullptr for no number (from_chars' rules).
template <typename Real>
inline const char* read_real_prefix(const char* first, const char* last, Real& value) {
  if (const char* end = read_plain_decimal(first, last, value)) return end;
  const auto [end, error] = fast_float::from_chars(first, last, value);
  return error == std::errc{} ? end : nullptr;
}

template <typename Real>
NumberError parse_real(const char* first, const char* last, Real& value) {
  first = skip_plus(first, last);
  Real parsed = 0;
  if (read_real_prefix(first, last, parsed) != last) return NumberError::syntax;
  if (!std::isfinite(parsed)) {
    // Digits that overflow, or a spelled-out "inf"/"nan".
    const char* digits = first < last && *first == '-' ? first + 1 : first;
    const bool numeral = digits < last && (*digits == '.' || (*digits >= '0' && *digits <= '9'));
    return numeral ? NumberError::overflow : NumberError::non_finite;
  }
  value = parsed;
  return NumberError::none;
}
inline NumberError parse_float(const char* first, const char* last, float& value) {
  return parse_real(first, last, value);
}
inline NumberError parse_double(const char* first, const char* last, double& value) {
  return parse_real(first, last, value);
}
NumberError parse_int(const char* first, const char* last, std::int64_t& value);
// "bad number 'TOKEN'" and friends, for error messages.
// A token of file content for a message: at most 64 bytes, then "...", and
// printable_text() so a broken file cannot send terminal escape codes.
std::string token_text(std::string_view token);
std::string number_error_text(NumberError error, std::string_view token);

// "PATH:LINE: reason"
Status text_error(const std::string& path, std::uint64_t line, const std::string& reason);
// "PATH: byte OFFSET: reason"
Status binary_error(const std::string& path, std::uint64_t offset, const std::string& reason);

// ".obj", ".ply", ...: the file name's extension in lower case, "" if none.
std::string lower_extension(const std::string& path);

// LoadOptions::block_bytes, or its default.
std::size_t block_bytes(const LoadOptions& options);

// Removes vertices that no triangle references, keeping the order of the
// others and remapping the indices. Indices must already be in range.
void drop_unreferenced_vertices(Mesh& mesh);

// Appends the range [first, first + count) named `name` to `ranges` (parts
// or materials, mesh.hpp), merged into the last range when that has the
// same name and ends at `first`; nothing when count is 0.
void append_range(std::vector<MeshPart>& ranges, const std::string& name, std::uint32_t first,
                  std::uint32_t count);

// Fill `out` from the opened file; stats.bytes is set by the caller. They do
// not call validate_mesh() or drop_unreferenced_vertices(): load_mesh does.
Status load_obj(const std::string& path, FileReader& reader, const LoadOptions& options, Mesh& out,
                LoadStats& stats);
// The materials of an OBJ's `mtllib` statement (its arguments as written)
// that `used` names, appended to `defs` (a name already there is kept):
// mtl.cpp. bad_input naming the OBJ and the library when it cannot be read,
// or the MTL's line.
// Every library file it reads or looks for is appended to `files`.
Status read_mtl_library(const std::string& obj_path, const std::string& statement,
                        const std::vector<std::string>& used, std::vector<Material>& defs,
                        std::vector<std::string>& files);
Status load_ply(const std::string& path, FileReader& reader, const LoadOptions& options, Mesh& out,
                LoadStats& stats);

// glTF 2.0 (.gltf, .glb) through tinygltf (gltf.cpp); opens the file itself
// and sets stats.bytes (the .gltf plus its external buffers).
Status load_gltf(const std::string& path, const LoadOptions& options, Mesh& out, LoadStats& stats);
// The mesh as glTF (gltf_save.cpp): with bin_uri empty a .glb in `bytes`;
// else the .gltf JSON in `bytes`, naming its buffer bin_uri, and the
// buffer's contents in `bin_bytes`.
// `textures` (may be null): the PBR materials of encode_textured_glb(), binary only.
Status encode_gltf(const Mesh& mesh, const std::string& bin_uri, std::string& bytes, std::string& bin_bytes,
                   const std::vector<GltfMaterialTextures>* textures = nullptr);

// FBX, Collada, 3DS and STL through Assimp (assimp.cpp, in the module
// libnmbake_assimp.so when it is built as one); opens the file itself.
bool is_assimp_extension(const std::string& extension);
Status load_assimp(const std::string& path, const LoadOptions& options, Mesh& out, LoadStats& stats);

}  // namespace nmbake::load_detail
