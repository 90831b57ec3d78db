// Mesh writer: Wavefront OBJ (v with colours as "v x y z r g b", vt, vn, o
// for parts, usemtl for materials, f) and PLY binary_little_endian (Turk
// 1994; no parts or materials). Reals are written so that they read back bit for bit: OBJ uses
// the shortest decimal form that round-trips (std::to_chars), PLY raw float32.
// The file appears atomically: written to a temporary file in the same folder,
// then renamed over the target.
#include <fcntl.h>
#include <unistd.h>

#include <atomic>
#include <bit>
#include <cerrno>
#include <charconv>
#include <cstring>
#include <filesystem>
#include <string>

#include "load/parsers.hpp"
#include "nmbake/cleanup.hpp"
#include "nmbake/load.hpp"

namespace nmbake {
namespace {

// Buffered writer over a file descriptor; remembers the first error.
class Writer {
 public:
  explicit Writer(int fd) : fd_(fd) { buffer_.reserve(kFlushBytes + 256); }

  void text(std::string_view s) {
    buffer_.append(s);
    maybe_flush();
  }
  void real(float value) {
    char digits[32];
    const auto result = std::to_chars(digits, digits + sizeof(digits), value);
    buffer_.append(digits, result.ptr);
  }
  void integer(std::uint64_t value) {
    char digits[24];
    const auto result = std::to_chars(digits, digits + sizeof(digits), value);
    buffer_.append(digits, result.ptr);
  }
  template <typename T>
  void little_endian(T value) {
    unsigned char raw[sizeof(T)];
    std::memcpy(raw, &value, sizeof(T));
    if constexpr (std::endian::native == std::endian::big) {
      for (std::size_t i = 0; i < sizeof(T) / 2; ++i) std::swap(raw[i], raw[sizeof(T) - 1 - i]);
    }
    buffer_.append(reinterpret_cast<const char*>(raw), sizeof(T));
  }
  void maybe_flush() {
    if (buffer_.size() >= kFlushBytes) flush();
  }
  void flush() {
    std::size_t done = 0;
    while (done < buffer_.size() && error_ == 0) {
      const ssize_t written = ::write(fd_, buffer_.data() + done, buffer_.size() - done);
      if (written < 0) {
        if (errno != EINTR) error_ = errno;
        continue;
      }
      done += static_cast<std::size_t>(written);
    }
    buffer_.clear();
  }
  int error() const { return error_; }

 private:
  static constexpr std::size_t kFlushBytes = std::size_t{1} << 20;
  int fd_;
  std::string buffer_;
  int error_ = 0;
};

void write_obj(Writer& out, const Mesh& mesh) {
  out.text("# nmbake mesh: ");
  out.integer(mesh.vertex_count());
  out.text(" vertices, ");
  out.integer(mesh.triangle_count());
  out.text(" triangles\n");
  for (std::size_t v = 0; v < mesh.vertex_count(); ++v) {
    const glm::vec3& p = mesh.positions[v];
    out.text("v ");
    out.real(p.x);
    out.text(" ");
    out.real(p.y);
    out.text(" ");
    out.real(p.z);
    if (mesh.has_colors()) {
      // The "v x y z r g b" extension the loader reads; alpha is lost.
      for (int c = 0; c < 3; ++c) {
        out.text(" ");
        out.real(mesh.colors[v][c]);
      }
    }
    out.text("\n");
  }
  for (const glm::vec2& uv : mesh.uvs) {
    out.text("vt ");
    out.real(uv.x);
    out.text(" ");
    out.real(uv.y);
    out.text("\n");
  }
  for (const glm::vec3& n : mesh.normals) {
    out.text("vn ");
    out.real(n.x);
    out.text(" ");
    out.real(n.y);
    out.text(" ");
    out.real(n.z);
    out.text("\n");
  }
  // Every attribute is per vertex, so a corner uses the same number thrice.
  const std::string_view normal_separator = mesh.has_uvs() ? "/" : "//";
  std::size_t next_part = 0;
  std::size_t next_material = 0;
  for (std::size_t t = 0; t < mesh.triangle_count(); ++t) {
    // Parts as `o` objects, so they load back as the same parts.
    if (next_part < mesh.parts.size() && mesh.parts[next_part].first_triangle == t) {
      out.text("o ");
      out.text(mesh.parts[next_part].name);
      out.text("\n");
      ++next_part;
    }
    // Materials as `usemtl` (no mtllib: nmbake reads only the names). The
    // unnamed material needs no statement at the start; later it is a bare
    // `usemtl`, which the loader reads as "" (other readers may not).
    if (next_material < mesh.materials.size() && mesh.materials[next_material].first_triangle == t) {
      if (t > 0 || !mesh.materials[next_material].name.empty()) {
        out.text("usemtl");
        if (!mesh.materials[next_material].name.empty()) {
          out.text(" ");
          out.text(mesh.materials[next_material].name);
        }
        out.text("\n");
      }
      ++next_material;
    }
    out.text("f");
    for (int c = 0; c < 3; ++c) {
      const std::uint64_t index = std::uint64_t{mesh.indices[3 * t + c]} + 1;
      out.text(" ");
      out.integer(index);
      if (mesh.has_uvs()) {
        out.text("/");
        out.integer(index);
      }
      if (mesh.has_normals()) {
        out.text(normal_separator);
        out.integer(index);
      }
    }
    out.text("\n");
  }
}

void write_ply(Writer& out, const Mesh& mesh) {
  out.text("ply\nformat binary_little_endian 1.0\ncomment written by nmbake\nelement vertex ");
  out.integer(mesh.vertex_count());
  out.text("\nproperty float x\nproperty float y\nproperty float z\n");
  if (mesh.has_normals()) out.text("property float nx\nproperty float ny\nproperty float nz\n");
  if (mesh.has_uvs()) out.text("property float u\nproperty float v\n");
  if (mesh.has_colors())
    out.text("property float red\nproperty float green\nproperty float blue\nproperty float alpha\n");
  out.text("element face ");
  out.integer(mesh.triangle_count());
  out.text("\nproperty list uchar uint vertex_indices\nend_header\n");
  for (std::size_t v = 0; v < mesh.vertex_count(); ++v) {
    out.little_endian(mesh.positions[v].x);
    out.little_endian(mesh.positions[v].y);
    out.little_endian(mesh.positions[v].z);
    if (mesh.has_normals()) {
      out.little_endian(mesh.normals[v].x);
      out.little_endian(mesh.normals[v].y);
      out.little_endian(mesh.normals[v].z);
    }
    if (mesh.has_uvs()) {
      out.little_endian(mesh.uvs[v].x);
      out.little_endian(mesh.uvs[v].y);
    }
    if (mesh.has_colors()) {
      for (int c = 0; c < 4; ++c) out.little_endian(mesh.colors[v][c]);
    }
    out.maybe_flush();
  }
  for (std::size_t t = 0; t < mesh.triangle_count(); ++t) {
    out.little_endian(std::uint8_t{3});
    for (int c = 0; c < 3; ++c) out.little_endian(mesh.indices[3 * t + c]);
    out.maybe_flush();
  }
}

// Writes what `body` puts into the writer to a temporary file in the same
// folder (so the rename cannot cross file systems; O_EXCL and a
// process-unique name keep concurrent writers apart), then renames it.
template <typename Body>
Status write_atomically(const std::string& path, Body&& body) {
  static std::atomic<unsigned> counter{0};
  const std::string temp_path = path + ".tmp" + std::to_string(::getpid()) + "_" + std::to_string(counter++);
  const TempFileGuard guard(temp_path);  // removed if a signal ends the process meanwhile
  const int fd = ::open(temp_path.c_str(), O_WRONLY | O_CREAT | O_EXCL | O_CLOEXEC, 0666);
  if (fd < 0) return Status::io(path + ": cannot write: " + std::strerror(errno));
  Writer writer(fd);
  body(writer);
  writer.flush();
  int error = writer.error();
  if (::close(fd) != 0 && error == 0) error = errno;
  if (error == 0 && ::rename(temp_path.c_str(), path.c_str()) != 0) error = errno;
  if (error != 0) {
    ::unlink(temp_path.c_str());
    return Status::io(path + ": cannot write: " + std::strerror(error));
  }
  return Status::ok();
}

}  // namespace

Status save_mesh(const std::string& path, const Mesh& mesh) {
  const std::string extension = load_detail::lower_extension(path);
  const bool gltf = extension == ".gltf" || extension == ".glb";
  if (extension != ".obj" && extension != ".ply" && !gltf) {
    return Status::bad_input(path + ": unknown mesh format '" + extension +
                             "' (expected .obj, .ply, .gltf or .glb)");
  }
  NMBAKE_TRY(validate_mesh(mesh, path));
  NMBAKE_TRY(check_output_target(path));
  if (extension == ".glb") {
    std::string bytes;
    std::string unused;
    NMBAKE_TRY(load_detail::encode_gltf(mesh, "", bytes, unused));
    return write_atomically(path, [&](Writer& w) { w.text(bytes); });
  }
  if (extension == ".gltf") {
    // The buffer beside the .gltf, as DCC tools write it; written first, so
    // that a .gltf never names a .bin that is not there yet.
    const std::filesystem::path bin = std::filesystem::path(path).replace_extension(".bin");
    std::string json_text;
    std::string bin_bytes;
    NMBAKE_TRY(load_detail::encode_gltf(mesh, bin.filename().string(), json_text, bin_bytes));
    NMBAKE_TRY(write_atomically(bin.string(), [&](Writer& w) { w.text(bin_bytes); }));
    return write_atomically(path, [&](Writer& w) { w.text(json_text); });
  }
  return write_atomically(path, [&](Writer& w) {
    if (extension == ".obj") {
      write_obj(w, mesh);
    } else {
      write_ply(w, mesh);
    }
  });
}

}  // namespace nmbake
