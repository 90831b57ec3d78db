// Stage "load": picks the parser by extension, streams the file through one
// reusable buffer, then drops unreferenced vertices and validates the mesh.
#include "nmbake/load.hpp"

#include <fcntl.h>
#include <sys/stat.h>
#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>
#include <tbb/parallel_reduce.h>
#include <unistd.h>

#include <algorithm>
#include <atomic>
#include <cctype>
#include <cerrno>
#include <charconv>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <functional>
#include <limits>

#include "load/parsers.hpp"

namespace nmbake {
namespace load_detail {

namespace {
// Large enough that read(2) calls are rare, small enough to stay in L2/L3-ish
// territory and fault in once.
constexpr std::size_t kBufferBytes = std::size_t{4} << 20;
constexpr std::uint64_t kMinBufferBytes = 4096;
// Room before read_ahead()'s bytes for the unread tail of the buffer (the
// last, incomplete line of a block), so joining them copies only that.
constexpr std::size_t kAheadRoom = std::size_t{64} << 10;
}  // namespace

FileReader::~FileReader() {
  if (fd_ >= 0) ::close(fd_);
}

Status FileReader::open(const std::string& path) {
  path_ = path;
  // open(2) would see the path cut at the NUL: another file.
  if (path.find('\0') != std::string::npos)
    return Status::bad_input(path + ": cannot open: the path holds a NUL byte");
  fd_ = ::open(path.c_str(), O_RDONLY | O_CLOEXEC);
  if (fd_ < 0) return Status::bad_input(path + ": cannot open: " + std::strerror(errno));
  struct stat info {};
  if (::fstat(fd_, &info) != 0) return Status::bad_input(path + ": cannot open: " + std::strerror(errno));
  if (S_ISDIR(info.st_mode)) return Status::bad_input(path + ": cannot open: " + std::strerror(EISDIR));
  file_size_ = static_cast<std::uint64_t>(info.st_size);
#ifdef POSIX_FADV_SEQUENTIAL
  (void)::posix_fadvise(fd_, 0, 0, POSIX_FADV_SEQUENTIAL);
#endif
  // A small file gets a small buffer: most tests and low meshes are tiny.
  capacity_ =
      static_cast<std::size_t>(std::clamp<std::uint64_t>(file_size_ + 1, kMinBufferBytes, kBufferBytes));
  buffer_ = std::make_unique_for_overwrite<char[]>(capacity_);
  buffer_bytes_ = capacity_;
  data_ = buffer_.get();
  return Status::ok();
}

void FileReader::read_ahead(std::size_t count) {
  // Only when the buffer holds little more than the block being decoded (a
  // refill would follow): else the join would copy the unread rest.
  if (eof_ || ahead_pending_ || end_ - pos_ > count + kAheadRoom) return;
  const std::uint64_t read_so_far = buffer_offset_ + end_;
  count = static_cast<std::size_t>(
      std::min<std::uint64_t>(count, file_size_ - std::min(file_size_, read_so_far)));
  if (count == 0) return;
  if (ahead_bytes_ < kAheadRoom + count) {
    ahead_bytes_ = kAheadRoom + count;
    ahead_ = std::make_unique_for_overwrite<char[]>(ahead_bytes_);
  }
  char* into = ahead_.get() + kAheadRoom;
  const std::size_t room = ahead_bytes_ - kAheadRoom;
  ahead_end_ = 0;
  ahead_eof_ = false;
  while (ahead_end_ < count) {
    const ssize_t got = ::read(fd_, into + ahead_end_, room - ahead_end_);
    if (got < 0) {
      if (errno == EINTR) continue;
      ahead_status_ = Status::io(path_ + ": read failed: " + std::strerror(errno));
      ahead_eof_ = true;
      break;
    }
    if (got == 0) {
      ahead_eof_ = true;
      break;
    }
    ahead_end_ += static_cast<std::size_t>(got);
  }
  ahead_pending_ = true;
}

void FileReader::join_ahead() {
  ahead_pending_ = false;
  const std::size_t tail = end_ - pos_;
  if (tail <= kAheadRoom) {
    // The buffers change places: the tail goes just before the new bytes.
    std::memcpy(ahead_.get() + kAheadRoom - tail, data_ + pos_, tail);
    buffer_offset_ += pos_;
    std::swap(buffer_, ahead_);
    std::swap(buffer_bytes_, ahead_bytes_);
    data_ = buffer_.get() + (kAheadRoom - tail);
    capacity_ = buffer_bytes_ - (kAheadRoom - tail);
    pos_ = 0;
    end_ = tail + ahead_end_;
  } else {
    // A long unread tail (a line longer than the room): the new bytes are
    // copied behind it.
    std::memmove(buffer_.get(), data_ + pos_, tail);
    buffer_offset_ += pos_;
    data_ = buffer_.get();
    capacity_ = buffer_bytes_;
    pos_ = 0;
    end_ = tail;
    if (end_ + ahead_end_ > capacity_) {
      auto bigger = std::make_unique_for_overwrite<char[]>(end_ + ahead_end_);
      std::memcpy(bigger.get(), data_, end_);
      buffer_ = std::move(bigger);
      buffer_bytes_ = capacity_ = end_ + ahead_end_;
      data_ = buffer_.get();
    }
    std::memcpy(data_ + end_, ahead_.get() + kAheadRoom, ahead_end_);
    end_ += ahead_end_;
  }
  ahead_end_ = 0;
  if (ahead_eof_) eof_ = true;
  if (!ahead_status_.is_ok()) read_status_ = ahead_status_;
}

bool FileReader::fill(std::size_t count) {
  if (ahead_pending_) join_ahead();
  if (eof_) return false;
  // Keep the unread tail, move it to the front, and read behind it.
  const std::size_t kept = end_ - pos_;
  if (pos_ > 0) {
    std::memmove(data_, data_ + pos_, kept);
    buffer_offset_ += pos_;
    pos_ = 0;
    end_ = kept;
  }
  if (count > capacity_) {
    const std::size_t grown = std::max(count, capacity_ * 2);
    auto bigger = std::make_unique_for_overwrite<char[]>(grown);
    std::memcpy(bigger.get(), data_, end_);
    buffer_ = std::move(bigger);
    buffer_bytes_ = capacity_ = grown;
    data_ = buffer_.get();
  }
  while (end_ < capacity_) {
    const ssize_t got = ::read(fd_, data_ + end_, capacity_ - end_);
    if (got < 0) {
      if (errno == EINTR) continue;
      read_status_ = Status::io(path_ + ": read failed: " + std::strerror(errno));
      eof_ = true;
      break;
    }
    if (got == 0) {
      eof_ = true;
      break;
    }
    end_ += static_cast<std::size_t>(got);
    if (end_ >= count) break;  // enough for the caller; do not block on more
  }
  return end_ - pos_ >= count;
}

bool FileReader::skip(std::uint64_t count) {
  while (count > 0) {
    if (end_ == pos_ && !fill(1)) return false;
    const std::uint64_t step = std::min<std::uint64_t>(count, end_ - pos_);
    pos_ += static_cast<std::size_t>(step);
    count -= step;
  }
  return true;
}

bool FileReader::next_line_slow(std::string_view& line) {
  // No newline in the buffered bytes: read more until one appears or the file
  // ends; a line longer than the buffer grows it, up to kMaxLineBytes: an
  // endless stream with no newline (a link to /dev/zero) must not grow it
  // until memory runs out.
  for (;;) {
    const std::size_t scanned = end_ - pos_;
    if (eof_) break;
    if (scanned > kMaxLineBytes) {
      read_status_ =
          Status::bad_input(path_ + ":" + std::to_string(line_number_ + 1) + ": line longer than " +
                            std::to_string(kMaxLineBytes >> 20) + " MiB (no line end): not a mesh file");
      eof_ = true;
      pos_ = end_;
      return false;
    }
    fill(scanned + 1);
    const char* newline =
        static_cast<const char*>(std::memchr(data_ + pos_ + scanned, '\n', end_ - pos_ - scanned));
    if (newline != nullptr) return next_line(line);
  }
  if (pos_ == end_) return false;
  // The last line has no newline.
  line = std::string_view(data_ + pos_, end_ - pos_);
  pos_ = end_;
  ++line_number_;
  if (!line.empty() && line.back() == '\r') line.remove_suffix(1);
  return true;
}

NumberError parse_int(const char* first, const char* last, std::int64_t& value) {
  first = skip_plus(first, last);
  const auto [end, error] = std::from_chars(first, last, value);
  if (error == std::errc::result_out_of_range) return NumberError::overflow;
  if (error != std::errc{} || end != last) return NumberError::syntax;
  return NumberError::none;
}

std::string token_text(std::string_view token) {
  std::string text = printable_text(token.substr(0, 64));
  if (token.size() > 64) text += "...";
  return text;
}

std::string number_error_text(NumberError error, std::string_view token) {
  // Appended piecewise: GCC 12 warns falsely (-Wrestrict) on "'" + string.
  std::string quoted(1, '\'');
  quoted.append(token_text(token));
  quoted.push_back('\'');
  switch (error) {
    case NumberError::none:
      break;
    case NumberError::syntax:
      return token.empty() ? std::string("missing number") : "bad number " + quoted;
    case NumberError::overflow:
      return "number out of range " + quoted;
    case NumberError::non_finite:
      return "non-finite number " + quoted + " (NaN or Inf)";
  }
  return "bad number " + quoted;
}

Status text_error(const std::string& path, std::uint64_t line, const std::string& reason) {
  return Status::bad_input(path + ":" + std::to_string(line) + ": " + reason);
}

Status binary_error(const std::string& path, std::uint64_t offset, const std::string& reason) {
  return Status::bad_input(path + ": byte " + std::to_string(offset) + ": " + reason);
}

std::string lower_extension(const std::string& path) {
  const std::size_t slash = path.find_last_of('/');
  const std::size_t dot = path.find_last_of('.');
  if (dot == std::string::npos || (slash != std::string::npos && dot < slash)) return {};
  std::string extension = path.substr(dot);
  for (char& c : extension) c = static_cast<char>(std::tolower(static_cast<unsigned char>(c)));
  return extension;
}

std::size_t block_bytes(const LoadOptions& options) {
  // Many tasks for every core, yet small enough to stay in cache between
  // read(2) and the decoders; a larger block was slower (measured: 32 MiB
  // buffers cost a page fault per 4 KiB on every load).
  constexpr std::size_t kDefaultBlockBytes = std::size_t{4} << 20;
  return options.block_bytes > 0 ? options.block_bytes : kDefaultBlockBytes;
}

void drop_unreferenced_vertices(Mesh& mesh) {
  const std::size_t vertex_count = mesh.positions.size();
  // Marked and counted on all cores: a loaded mesh nearly always uses every
  // vertex, and then this is all there is to do. Racing stores all write 1.
  std::vector<std::uint8_t> used(vertex_count, 0);
  tbb::parallel_for(
      tbb::blocked_range<std::size_t>(0, mesh.indices.size(), 65536),
      [&](const tbb::blocked_range<std::size_t>& range) {
        for (std::size_t i = range.begin(); i != range.end(); ++i) {
          std::atomic_ref<std::uint8_t>(used[mesh.indices[i]]).store(1, std::memory_order_relaxed);
        }
      });
  const std::size_t used_count = tbb::parallel_reduce(
      tbb::blocked_range<std::size_t>(0, vertex_count, 65536), std::size_t{0},
      [&](const tbb::blocked_range<std::size_t>& range, std::size_t sum) {
        for (std::size_t v = range.begin(); v != range.end(); ++v) sum += used[v];
        return sum;
      },
      std::plus<>());
  if (used_count == vertex_count) return;
  constexpr std::uint32_t kUnused = 0xffffffffu;
  std::vector<std::uint32_t> remap(vertex_count, kUnused);
  std::uint32_t kept_count = 0;
  for (std::size_t v = 0; v < vertex_count; ++v) {
    if (used[v] != 0) remap[v] = kept_count++;
  }
  // Compact in place: a kept vertex only ever moves to a lower slot.
  for (std::size_t old_index = 0; old_index < vertex_count; ++old_index) {
    const std::uint32_t new_index = remap[old_index];
    if (new_index == kUnused) continue;
    mesh.positions[new_index] = mesh.positions[old_index];
    if (mesh.has_normals()) mesh.normals[new_index] = mesh.normals[old_index];
    if (mesh.has_uvs()) mesh.uvs[new_index] = mesh.uvs[old_index];
    if (mesh.has_tangents()) mesh.tangents[new_index] = mesh.tangents[old_index];
    if (mesh.has_colors()) mesh.colors[new_index] = mesh.colors[old_index];
  }
  mesh.positions.resize(kept_count);
  if (mesh.has_normals()) mesh.normals.resize(kept_count);
  if (mesh.has_uvs()) mesh.uvs.resize(kept_count);
  if (mesh.has_tangents()) mesh.tangents.resize(kept_count);
  if (mesh.has_colors()) mesh.colors.resize(kept_count);
  for (std::uint32_t& index : mesh.indices) index = remap[index];
}

void append_range(std::vector<MeshPart>& ranges, const std::string& name, std::uint32_t first,
                  std::uint32_t count) {
  if (count == 0) return;
  if (!ranges.empty() && ranges.back().name == name &&
      ranges.back().first_triangle + ranges.back().triangle_count == first) {
    ranges.back().triangle_count += count;
    return;
  }
  ranges.push_back(MeshPart{name, first, count});
}

}  // namespace load_detail

bool mesh_extension_supported(const std::string& path) {
  const std::string extension = load_detail::lower_extension(path);
  return extension == ".obj" || extension == ".ply" || extension == ".gltf" || extension == ".glb" ||
         load_detail::is_assimp_extension(extension);
}

const char* supported_mesh_extensions() { return ".obj, .ply, .gltf, .glb, .fbx, .dae, .3ds or .stl"; }

Status load_mesh(const std::string& path, const LoadOptions& options, Mesh& out, LoadStats& stats) {
  const auto begin = std::chrono::steady_clock::now();
  out = Mesh{};
  stats = LoadStats{};
  const std::string extension = load_detail::lower_extension(path);
  const bool gltf = extension == ".gltf" || extension == ".glb";
  const bool assimp = load_detail::is_assimp_extension(extension);
  if (!mesh_extension_supported(path)) {
    return Status::bad_input(path + ": unknown mesh format '" + extension + "' (expected " +
                             supported_mesh_extensions() + ")");
  }
  if (!gltf && !assimp && options.uv_set != 0) {
    return Status::bad_input(path + ": UV set " + std::to_string(options.uv_set) + " asked for, but " +
                             (extension == ".obj" ? "an OBJ" : "a PLY") + " file has one UV set (0)");
  }
  if (options.corner_uvs && !gltf && !assimp && extension != ".obj") {
    return Status::bad_input(path +
                             ": textures and materials of the high mesh are read from OBJ (+ MTL), glTF, "
                             "FBX and Collada files, not from '" +
                             extension + "' files");
  }
  Status status;
  if (gltf) {
    status = load_detail::load_gltf(path, options, out, stats);
  } else if (assimp) {
    status = load_detail::load_assimp(path, options, out, stats);
  } else {
    load_detail::FileReader reader;
    NMBAKE_TRY(reader.open(path));
    stats.bytes = reader.file_size();
    status = extension == ".obj" ? load_detail::load_obj(path, reader, options, out, stats)
                                 : load_detail::load_ply(path, reader, options, out, stats);
    if (!reader.read_status().is_ok()) status = reader.read_status();
  }
  if (!status.is_ok()) {
    out = Mesh{};
    return status;
  }
  load_detail::drop_unreferenced_vertices(out);
  // Materials none of which has a name are no materials (mesh.hpp).
  if (!out.has_named_materials()) out.materials.clear();
  stats.triangles = out.triangle_count();
  status = validate_mesh(out, path);
  if (!status.is_ok()) out = Mesh{};
  stats.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - begin).count();
  return status;
}

namespace {

std::string file_stem(const std::string& path) { return std::filesystem::path(path).stem().string(); }

// Appends `next` (loaded from `path`) to `out`, by load_meshes()'s rules.
Status append_mesh(const std::string& path, Mesh next, Mesh& out) {
  const std::size_t base = out.positions.size();
  if (base + next.positions.size() > std::numeric_limits<std::uint32_t>::max()) {
    return Status::bad_input(path + ": the high files hold more than 2^32 vertices together");
  }
  if (out.has_uvs() != next.has_uvs() || out.has_tangents() != next.has_tangents()) {
    return Status::bad_input(path + ": " + (out.has_uvs() != next.has_uvs() ? "UVs" : "tangents") +
                             " are in some of the files and not in others");
  }
  const std::size_t out_vertices = out.positions.size(), next_vertices = next.positions.size();
  if (out.has_normals() != next.has_normals()) {
    (out.has_normals() ? next.normals : out.normals)
        .resize(out.has_normals() ? next_vertices : out_vertices, glm::vec3(0.0f));
  }
  if (out.has_colors() != next.has_colors()) {
    (out.has_colors() ? next.colors : out.colors)
        .resize(out.has_colors() ? next_vertices : out_vertices, glm::vec4(1.0f));
  }
  const auto base_triangle = static_cast<std::uint32_t>(out.triangle_count());
  const std::size_t next_triangles = next.triangle_count();
  // Material ranges: "" where a file has none; a name an earlier file
  // defines differently gets the file's stem.
  if (!out.materials.empty() || !next.materials.empty()) {
    if (out.materials.empty() && base_triangle > 0) out.materials.push_back({"", 0, base_triangle});
    if (next.materials.empty()) next.materials.push_back({"", 0, static_cast<std::uint32_t>(next_triangles)});
  }
  // Embedded images follow the earlier files' (TextureRef::embedded).
  const auto image_base = static_cast<int>(out.embedded_images.size());
  for (Material& m : next.material_defs) {
    for (TextureRef* t : {&m.base_color_texture, &m.roughness_texture, &m.metallic_texture,
                          &m.emissive_texture, &m.opacity_texture, &m.normal_texture}) {
      if (t->embedded >= 0) t->embedded += image_base;
    }
  }
  for (EmbeddedImage& image : next.embedded_images) out.embedded_images.push_back(std::move(image));
  for (Material& m : next.material_defs) {
    const Material* earlier = out.material_def(m.name);
    if (earlier == nullptr || *earlier == m) continue;
    const std::string renamed = file_stem(path) + "/" + m.name;
    for (MeshPart& range : next.materials) {
      if (range.name == m.name) range.name = renamed;
    }
    m.name = renamed;
  }
  for (Material& m : next.material_defs) {
    if (out.material_def(m.name) == nullptr) out.material_defs.push_back(std::move(m));
  }
  for (MeshPart range : next.materials) {
    range.first_triangle += base_triangle;
    out.materials.push_back(std::move(range));
  }
  for (MeshPart part : next.parts) {
    part.first_triangle += base_triangle;
    out.parts.push_back(std::move(part));
  }
  auto append = [](auto& to, auto& from) { to.insert(to.end(), from.begin(), from.end()); };
  append(out.positions, next.positions);
  append(out.normals, next.normals);
  append(out.uvs, next.uvs);
  append(out.tangents, next.tangents);
  append(out.colors, next.colors);
  append(out.corner_uvs, next.corner_uvs);
  out.indices.reserve(out.indices.size() + next.indices.size());
  for (const std::uint32_t i : next.indices) out.indices.push_back(i + static_cast<std::uint32_t>(base));
  return Status::ok();
}

}  // namespace

Status load_meshes(const std::vector<std::string>& paths, const LoadOptions& options, Mesh& out,
                   LoadStats& stats) {
  if (paths.size() == 1) return load_mesh(paths[0], options, out, stats);
  out = Mesh{};
  stats = LoadStats{};
  std::string unit_path;
  for (const std::string& path : paths) {
    Mesh mesh;
    LoadStats file_stats;
    if (const Status loaded = load_mesh(path, options, mesh, file_stats); !loaded) {
      out = Mesh{};
      return loaded;
    }
    if (file_stats.unit_meters > 0.0) {
      if (stats.unit_meters > 0.0 && stats.unit_meters != file_stats.unit_meters) {
        const auto metres = [](double v) {
          char text[32];
          std::snprintf(text, sizeof text, "%g m", v);
          return std::string(text);
        };
        out = Mesh{};
        return Status::bad_input(path + ": a file unit is " + metres(file_stats.unit_meters) + ", but in " +
                                 unit_path + " it is " + metres(stats.unit_meters) +
                                 " (export the files in one unit)");
      }
      stats.unit_meters = file_stats.unit_meters;
      unit_path = path;
    }
    if (options.corner_uvs && mesh.corner_uvs.empty()) {
      mesh.corner_uvs.assign(mesh.indices.size(), glm::vec2(0.0f));
      file_stats.corners_without_uvs += mesh.indices.size();
    }
    if (mesh.parts.empty()) {
      mesh.parts.push_back({file_stem(path), 0, static_cast<std::uint32_t>(mesh.triangle_count())});
    }
    const Status appended = append_mesh(path, std::move(mesh), out);
    if (!appended) {
      out = Mesh{};
      return appended;
    }
    stats.bytes += file_stats.bytes;
    stats.seconds += file_stats.seconds;
    stats.polygons += file_stats.polygons;
    stats.triangles += file_stats.triangles;
    stats.degenerate_faces += file_stats.degenerate_faces;
    stats.corners_without_uvs += file_stats.corners_without_uvs;
    stats.unread_material_libraries += file_stats.unread_material_libraries;
    stats.files.insert(stats.files.end(), file_stats.files.begin(), file_stats.files.end());
  }
  if (!out.has_named_materials()) out.materials.clear();
  const Status valid = validate_mesh(out, paths.front());
  if (!valid) out = Mesh{};
  return valid;
}

}  // namespace nmbake
