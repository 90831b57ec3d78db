#include "load/isolated.hpp"

#include <poll.h>
#include <signal.h>
#include <sys/prctl.h>
#include <sys/resource.h>
#include <sys/stat.h>
#include <sys/wait.h>
#include <unistd.h>

#include <algorithm>
#include <cerrno>
#include <chrono>
#include <cstdint>
#include <cstdio>
#include <cstring>
#include <string>
#include <type_traits>
#include <vector>

#include "nmbake/memory.hpp"

namespace nmbake::load_detail {
namespace {

// The child's answer, in order: a byte 'R' once the library has returned,
// then 'S' and the status, then (when it is ok) the mesh and the stats.
// Written to the pipe as it goes (a mesh is not copied whole), or to a
// string (encode_child_reply, for tests).
class Writer {
 public:
  explicit Writer(int fd) : fd_(fd) {}
  explicit Writer(std::string& out) : out_(&out) {}
  bool bytes(const void* data, std::size_t size) {
    const char* p = static_cast<const char*>(data);
    if (out_ != nullptr) {
      out_->append(p, size);
      return true;
    }
    while (size > 0) {
      const ssize_t n = ::write(fd_, p, size);
      if (n < 0 && errno == EINTR) continue;
      if (n <= 0) return false;
      p += n;
      size -= static_cast<std::size_t>(n);
    }
    return true;
  }
  template <typename T>
  bool value(const T& v) {
    static_assert(std::is_trivially_copyable_v<T>);
    return bytes(&v, sizeof v);
  }
  bool text(const std::string& s) {
    return value(static_cast<std::uint64_t>(s.size())) && bytes(s.data(), s.size());
  }
  template <typename T>
  bool array(const std::vector<T>& v) {
    return value(static_cast<std::uint64_t>(v.size())) && bytes(v.data(), v.size() * sizeof(T));
  }
  bool ranges(const std::vector<MeshPart>& v) {
    if (!value(static_cast<std::uint64_t>(v.size()))) return false;
    for (const MeshPart& range : v) {
      if (!text(range.name) || !value(range.first_triangle) || !value(range.triangle_count)) return false;
    }
    return true;
  }
  bool texture(const TextureRef& t) {
    return text(t.path) && value(t.embedded) && value(t.texcoord) && value(t.channel) && value(t.wrap_u) &&
           value(t.wrap_v) && value(t.offset) && value(t.scale) && value(t.rotation) && text(t.problem);
  }
  bool materials(const std::vector<Material>& v) {
    if (!value(static_cast<std::uint64_t>(v.size()))) return false;
    for (const Material& m : v) {
      if (!(text(m.name) && value(m.base_color) && texture(m.base_color_texture) && value(m.has_color) &&
            value(m.roughness) && texture(m.roughness_texture) && value(m.metallic) &&
            texture(m.metallic_texture) && value(m.emissive) && texture(m.emissive_texture) &&
            texture(m.opacity_texture) && texture(m.normal_texture) && value(m.normal_scale))) {
        return false;
      }
    }
    return true;
  }
  bool images(const std::vector<EmbeddedImage>& v) {
    if (!value(static_cast<std::uint64_t>(v.size()))) return false;
    for (const EmbeddedImage& image : v) {
      if (!text(image.format) || !value(image.width) || !value(image.height) || !array(image.bytes))
        return false;
    }
    return true;
  }

 private:
  int fd_ = -1;
  std::string* out_ = nullptr;
};

class Reader {
 public:
  explicit Reader(const std::string& data) : data_(data) {}
  bool bytes(void* out, std::size_t size) {
    if (data_.size() - at_ < size) return false;
    if (size == 0) return true;  // an empty vector's data() may be null
    std::memcpy(out, data_.data() + at_, size);
    at_ += size;
    return true;
  }
  template <typename T>
  bool value(T& v) {
    return bytes(&v, sizeof v);
  }
  bool text(std::string& s) {
    std::uint64_t n = 0;
    if (!value(n) || n > data_.size() - at_) return false;
    s.assign(data_, at_, n);
    at_ += n;
    return true;
  }
  template <typename T>
  bool array(std::vector<T>& v) {
    std::uint64_t n = 0;
    if (!value(n) || n > (data_.size() - at_) / sizeof(T)) return false;
    v.resize(n);
    return bytes(v.data(), n * sizeof(T));
  }
  // Parts or materials: a count no larger than the bytes left can hold
  // (each range takes at least 16: name length, first, count) is checked
  // before anything is allocated, so a hostile count is an error, not an
  // allocation.
  bool ranges(std::vector<MeshPart>& v) {
    constexpr std::size_t kRangeBytes = sizeof(std::uint64_t) + 2 * sizeof(std::uint32_t);
    std::uint64_t n = 0;
    if (!value(n) || n > (data_.size() - at_) / kRangeBytes) return false;
    v.resize(n);
    for (MeshPart& range : v) {
      if (!text(range.name) || !value(range.first_triangle) || !value(range.triangle_count)) return false;
    }
    return true;
  }
  // A bool or an enum read as its byte and checked, so a broken reply
  // cannot make a value its type does not have.
  bool flag(bool& b) {
    std::uint8_t byte = 0;
    if (!value(byte) || byte > 1) return false;
    b = byte == 1;
    return true;
  }
  bool wrap(TextureWrap& w) {
    std::uint8_t byte = 0;
    if (!value(byte) || byte > static_cast<std::uint8_t>(TextureWrap::mirror)) return false;
    w = static_cast<TextureWrap>(byte);
    return true;
  }
  bool texture(TextureRef& t) {
    return text(t.path) && value(t.embedded) && value(t.texcoord) && value(t.channel) && wrap(t.wrap_u) &&
           wrap(t.wrap_v) && value(t.offset) && value(t.scale) && value(t.rotation) && text(t.problem);
  }
  // Counts checked as for ranges: a material takes at least its name's and
  // six textures' two string lengths, an image its format's and bytes' lengths.
  bool materials(std::vector<Material>& v) {
    constexpr std::size_t kMaterialBytes = 13 * sizeof(std::uint64_t);
    std::uint64_t n = 0;
    if (!value(n) || n > (data_.size() - at_) / kMaterialBytes) return false;
    v.resize(n);
    for (Material& m : v) {
      if (!(text(m.name) && value(m.base_color) && texture(m.base_color_texture) && flag(m.has_color) &&
            value(m.roughness) && texture(m.roughness_texture) && value(m.metallic) &&
            texture(m.metallic_texture) && value(m.emissive) && texture(m.emissive_texture) &&
            texture(m.opacity_texture) && texture(m.normal_texture) && value(m.normal_scale))) {
        return false;
      }
    }
    return true;
  }
  bool images(std::vector<EmbeddedImage>& v) {
    constexpr std::size_t kImageBytes = 2 * sizeof(std::uint64_t);
    std::uint64_t n = 0;
    if (!value(n) || n > (data_.size() - at_) / kImageBytes) return false;
    v.resize(n);
    for (EmbeddedImage& image : v) {
      if (!text(image.format) || !value(image.width) || !value(image.height) || !array(image.bytes))
        return false;
    }
    return true;
  }

 private:
  const std::string& data_;
  std::size_t at_ = 0;
};

bool send_result(Writer& w, const Status& status, const Mesh& mesh, const LoadStats& stats) {
  if (!w.value('S') || !w.value(static_cast<int>(status.code())) || !w.text(status.message())) return false;
  if (!status.is_ok()) return true;
  return w.array(mesh.positions) && w.array(mesh.normals) && w.array(mesh.uvs) && w.array(mesh.tangents) &&
         w.array(mesh.colors) && w.array(mesh.indices) && w.ranges(mesh.parts) && w.ranges(mesh.materials) &&
         w.array(mesh.corner_uvs) && w.materials(mesh.material_defs) && w.images(mesh.embedded_images) &&
         w.value(stats.bytes) && w.value(stats.polygons) && w.value(stats.triangles) &&
         w.value(stats.degenerate_faces) && w.value(stats.corners_without_uvs) && w.value(stats.unit_meters);
}

}  // namespace

std::string encode_child_reply(const Status& status, const Mesh& mesh, const LoadStats& stats) {
  std::string out;
  Writer w(out);
  (void)w.value('R');
  (void)send_result(w, status, mesh, stats);
  return out;
}

bool decode_child_reply(const std::string& data, Status& status, Mesh& mesh, LoadStats& stats) {
  Reader r(data);
  char tag = 0;
  if (!r.value(tag) || tag != 'R') return false;
  int code = 0;
  std::string message;
  if (!r.value(tag) || tag != 'S' || !r.value(code) || !r.text(message)) return false;
  if (code != static_cast<int>(StatusCode::ok)) {
    status = code == static_cast<int>(StatusCode::bad_input) ? Status::bad_input(message)
             : code == static_cast<int>(StatusCode::io)      ? Status::io(message)
                                                             : Status::internal(message);
    return true;
  }
  if (!(r.array(mesh.positions) && r.array(mesh.normals) && r.array(mesh.uvs) && r.array(mesh.tangents) &&
        r.array(mesh.colors) && r.array(mesh.indices) && r.ranges(mesh.parts) && r.ranges(mesh.materials) &&
        r.array(mesh.corner_uvs) && r.materials(mesh.material_defs) && r.images(mesh.embedded_images) &&
        r.value(stats.bytes) && r.value(stats.polygons) && r.value(stats.triangles) &&
        r.value(stats.degenerate_faces) && r.value(stats.corners_without_uvs) &&
        r.value(stats.unit_meters))) {
    return false;
  }
  status = Status::ok();
  return true;
}

std::uint64_t child_cpu_seconds(std::uint64_t file_bytes) {
  return kChildCpuSeconds + file_bytes / kChildBytesPerCpuSecond;
}

Status load_in_child(const std::string& path, const char* library, const ChildLoad& load, Mesh& out,
                     LoadStats& stats) {
  int fds[2];
  if (::pipe(fds) != 0) return Status::internal(path + ": cannot create a pipe: " + std::strerror(errno));
  struct stat file_status {};
  const std::uint64_t file_bytes =
      ::stat(path.c_str(), &file_status) == 0 ? static_cast<std::uint64_t>(file_status.st_size) : 0;
  const std::uint64_t cpu_seconds = child_cpu_seconds(file_bytes);
  std::fflush(nullptr);
  const pid_t child = ::fork();
  if (child < 0) {
    ::close(fds[0]);
    ::close(fds[1]);
    return Status::internal(path + ": cannot fork to run " + library + ": " + std::strerror(errno));
  }
  if (child == 0) {
    ::close(fds[0]);
    ::signal(SIGPIPE, SIG_IGN);
    ::signal(SIGXCPU, SIG_DFL);
    cap_address_space_at_available();
    // A crash or a CPU limit in the library must end the child at once: no
    // core dump (where core files are enabled, writing one takes longer than
    // the deadline on a slow disk, and would leave a file behind).
    const rlimit no_core{0, 0};
    (void)::setrlimit(RLIMIT_CORE, &no_core);
    (void)::prctl(PR_SET_DUMPABLE, 0, 0, 0, 0);
    // A file that sends the library into a loop ends as SIGXCPU (CPU time
    // does not depend on how busy the machine is; the parent's wall-clock
    // deadline below catches a child that waits instead).
    const rlimit cpu{static_cast<rlim_t>(cpu_seconds), static_cast<rlim_t>(cpu_seconds + 1)};
    (void)::setrlimit(RLIMIT_CPU, &cpu);
    Writer w(fds[1]);
    Mesh mesh;
    LoadStats child_stats = stats;
    bool sent_read = false;
    const Status status = load(mesh, child_stats, [&] {
      sent_read = true;
      (void)w.value('R');
    });
    if (!sent_read) (void)w.value('R');  // failed before the library returned a scene
    const bool ok = send_result(w, status, mesh, child_stats);
    ::_exit(ok ? 0 : 1);
  }
  ::close(fds[1]);
  std::string data;
  char buffer[1 << 16];
  const auto deadline =
      std::chrono::steady_clock::now() + std::chrono::seconds(kChildWallFactor * cpu_seconds);
  bool timed_out = false;
  for (;;) {
    const auto left =
        std::chrono::duration_cast<std::chrono::milliseconds>(deadline - std::chrono::steady_clock::now());
    if (left.count() <= 0) {
      timed_out = true;
      ::kill(child, SIGKILL);
      break;
    }
    pollfd ready{fds[0], POLLIN, 0};
    const int polled = ::poll(&ready, 1, static_cast<int>(std::min<std::int64_t>(left.count(), 1000)));
    if (polled < 0 && errno != EINTR) break;
    if (polled <= 0) continue;
    const ssize_t n = ::read(fds[0], buffer, sizeof buffer);
    if (n < 0 && errno == EINTR) continue;
    if (n <= 0) break;
    data.append(buffer, static_cast<std::size_t>(n));
  }
  ::close(fds[0]);
  int wstatus = 0;
  while (::waitpid(child, &wstatus, 0) < 0 && errno == EINTR) {
  }
  const bool library_returned = !data.empty() && data[0] == 'R';
  if (timed_out || (WIFSIGNALED(wstatus) && WTERMSIG(wstatus) == SIGXCPU)) {
    const std::string limit = timed_out ? std::to_string(kChildWallFactor * cpu_seconds) + " s"
                                        : std::to_string(cpu_seconds) + " s of CPU time";
    if (library_returned) {
      return Status::internal(path + ": nmbake did not finish converting what " + library + " read within " +
                              limit);
    }
    return Status::bad_input(path + ": " + library + " did not finish reading the file within " + limit +
                             " (" + std::to_string(kChildCpuSeconds) + " s + 1 s per " +
                             std::to_string(kChildBytesPerCpuSecond >> 20) + " MiB of file): a broken file");
  }
  Status status;
  Mesh mesh;
  LoadStats child_stats = stats;
  if (WIFEXITED(wstatus) && WEXITSTATUS(wstatus) == 0 &&
      decode_child_reply(data, status, mesh, child_stats)) {
    if (status.is_ok()) {
      out = std::move(mesh);
      stats = child_stats;
    }
    return status;
  }
  const std::string how =
      WIFSIGNALED(wstatus)
          ? "crashed (signal " + std::to_string(WTERMSIG(wstatus)) + ", " + strsignal(WTERMSIG(wstatus)) + ")"
          : "stopped (exit " + std::to_string(WEXITSTATUS(wstatus)) + ")";
  if (!library_returned) {
    return Status::bad_input(path + ": " + library + " " + how +
                             " reading the file: a broken file (the library runs in a process of its own)");
  }
  return Status::internal(path + ": nmbake " + how + " converting what " + library + " read");
}

}  // namespace nmbake::load_detail
