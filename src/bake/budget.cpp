// Memory budgets (budget.hpp): the estimate of a bake's buffers and the
// memory the process may use, read from the kernel's own accounting.
#include "nmbake/budget.hpp"
#include "nmbake/task.hpp"

#include <algorithm>
#include <cctype>
#include <charconv>
#include <cmath>
#include <cstdio>
#include <fstream>
#include <limits>
#include <sstream>
#include <string>

#include <sys/resource.h>

#include "nmbake/bake.hpp"

namespace nmbake {

namespace {

// The first number of a file such as memory.max ("max" and missing files: none).
bool read_number(const std::string& path, std::uint64_t& value) {
  std::ifstream in(path);
  std::string word;
  if (!(in >> word)) return false;
  const auto [end, error] = std::from_chars(word.data(), word.data() + word.size(), value);
  return error == std::errc() && end == word.data() + word.size();
}

// A "Key:   N kB" line of /proc/meminfo or /proc/self/status, in bytes.
bool read_kb_field(const std::string& path, const std::string& key, std::uint64_t& bytes) {
  std::ifstream in(path);
  std::string line;
  while (std::getline(in, line)) {
    if (line.compare(0, key.size(), key) != 0 || line.size() <= key.size() || line[key.size()] != ':') continue;
    std::istringstream fields(line.substr(key.size() + 1));
    std::uint64_t kb = 0;
    if (!(fields >> kb)) return false;
    bytes = kb * 1024;
    return true;
  }
  return false;
}

void consider(MemoryLimit& limit, std::uint64_t bytes, const std::string& source) {
  if (limit.bytes == 0 || bytes < limit.bytes) {
    limit.bytes = bytes;
    limit.source = source;
  }
}

// cgroup v2: the limit may be set at any level above the process's group.
void consider_cgroup_v2(MemoryLimit& limit, const std::string& group) {
  std::string path = group;
  for (;;) {
    const std::string folder = "/sys/fs/cgroup" + (path == "/" ? std::string() : path);
    std::uint64_t max = 0, current = 0;
    if (read_number(folder + "/memory.max", max)) {
      (void)read_number(folder + "/memory.current", current);
      consider(limit, max > current ? max - current : 0, "cgroup " + folder + "/memory.max");
    }
    if (path == "/" || path.empty()) break;
    const std::size_t slash = path.find_last_of('/');
    path = slash == 0 || slash == std::string::npos ? "/" : path.substr(0, slash);
  }
}

void consider_cgroup_v1(MemoryLimit& limit, const std::string& group) {
  // "No limit" is a huge page-aligned number; anything above 2^60 is one.
  constexpr std::uint64_t kUnlimited = std::uint64_t{1} << 60;
  for (const std::string& folder : {"/sys/fs/cgroup/memory" + group, std::string("/sys/fs/cgroup/memory")}) {
    std::uint64_t max = 0, usage = 0;
    if (!read_number(folder + "/memory.limit_in_bytes", max)) continue;
    if (max >= kUnlimited) continue;
    (void)read_number(folder + "/memory.usage_in_bytes", usage);
    consider(limit, max > usage ? max - usage : 0, "cgroup " + folder + "/memory.limit_in_bytes");
    return;
  }
}

// The rows a bake holds in memory: a tile bake (task.hpp) only its own.
int baked_rows(const BakeOptions& o) {
  if (o.tile_count <= 0 || o.tile_index < 0 || o.tile_index >= o.tile_count) return o.height;
  int begin = 0, end = 0;
  tile_rows(o.height, o.tile_index, o.tile_count, begin, end);
  return end - begin;
}

std::string map_text(const BakeOptions& o) {
  std::string text = std::to_string(o.width) + "x" + std::to_string(o.height) + " map at " + std::to_string(o.samples) + " spp";
  if (baked_rows(o) != o.height) {
    text = "tile " + std::to_string(o.tile_index + 1) + "/" + std::to_string(o.tile_count) + " (" +
           std::to_string(baked_rows(o)) + " rows) of a " + text;
  }
  return text;
}

// The address space this process has mapped (VmSize), 0 when unknown.
std::uint64_t address_space_in_use() {
  std::uint64_t used = 0;
  (void)read_kb_field("/proc/self/status", "VmSize", used);
  return used;
}

}  // namespace

MemoryLimit available_memory() {
  MemoryLimit limit;
  std::uint64_t bytes = 0;
  if (read_kb_field("/proc/meminfo", "MemAvailable", bytes)) consider(limit, bytes, "MemAvailable in /proc/meminfo");
  std::ifstream groups("/proc/self/cgroup");
  std::string line;
  while (std::getline(groups, line)) {
    // "0::/path" (v2) or "N:memory,...:/path" (v1).
    const std::size_t a = line.find(':'), b = a == std::string::npos ? a : line.find(':', a + 1);
    if (b == std::string::npos) continue;
    const std::string controllers = line.substr(a + 1, b - a - 1), group = line.substr(b + 1);
    if (controllers.empty()) {
      consider_cgroup_v2(limit, group);
    } else if (("," + controllers + ",").find(",memory,") != std::string::npos) {
      consider_cgroup_v1(limit, group);
    }
  }
  rlimit as{};
  if (getrlimit(RLIMIT_AS, &as) == 0 && as.rlim_cur != RLIM_INFINITY) {
    const std::uint64_t used = address_space_in_use();
    const std::uint64_t cap = static_cast<std::uint64_t>(as.rlim_cur);
    consider(limit, cap > used ? cap - used : 0, "RLIMIT_AS (ulimit -v)");
  }
  return limit;
}

void cap_address_space_at_available() {
#ifndef NMBAKE_SANITIZED
  const MemoryLimit limit = available_memory();
  if (limit.bytes == 0) return;
  rlimit current{};
  if (getrlimit(RLIMIT_AS, &current) != 0) return;
  const std::uint64_t cap = address_space_in_use() + limit.bytes;
  if (current.rlim_cur != RLIM_INFINITY && static_cast<std::uint64_t>(current.rlim_cur) <= cap) return;
  rlimit wanted = current;
  wanted.rlim_cur = static_cast<rlim_t>(cap);
  (void)setrlimit(RLIMIT_AS, &wanted);
#endif
}

bool parse_memory_size(const std::string& text, std::uint64_t& bytes) {
  double value = 0.0;
  const char* begin = text.data();
  const char* end = begin + text.size();
  const auto [rest, error] = std::from_chars(begin, end, value);
  if (error != std::errc() || rest == begin || !std::isfinite(value) || !(value > 0.0)) return false;
  std::string unit(rest, end);
  for (char& c : unit) c = static_cast<char>(std::toupper(static_cast<unsigned char>(c)));
  double scale = 1.0;
  if (!unit.empty()) {
    const std::string letters = "KMGT";
    const std::size_t power = letters.find(unit[0]);
    const std::string suffix = unit.substr(1);
    if (power == std::string::npos || !(suffix.empty() || suffix == "B" || suffix == "IB")) {
      if (unit != "B") return false;
    } else {
      scale = std::pow(1024.0, static_cast<double>(power + 1));
    }
  }
  const double total = value * scale;
  if (!(total >= 1.0) || total >= 1.8e19) return false;
  bytes = static_cast<std::uint64_t>(total);
  return true;
}

std::string memory_text(std::uint64_t bytes) {
  char text[32];
  const double b = static_cast<double>(bytes);
  if (b >= 1e9) {
    std::snprintf(text, sizeof text, "%.1f GB", b * 1e-9);
  } else if (b >= 1e6) {
    std::snprintf(text, sizeof text, "%.0f MB", b * 1e-6);
  } else {
    std::snprintf(text, sizeof text, "%.0f kB", b * 1e-3);
  }
  return text;
}

BakeMemory estimate_bake_memory(const BakeOptions& o, const MeshSize& low, const MeshSize& high) {
  BakeMemory m;
  // A tile bake's image and coverage hold its rows only (bake_tile).
  const std::uint64_t texels = static_cast<std::uint64_t>(o.width) * static_cast<std::uint64_t>(baked_rows(o));
  // Per texel: the float RGB image (12), coverage (1), dilation's rings (2:
  // 20 bytes a ring texel, rings about a tenth of the map at most), the
  // debug images (36). Measured: a 8192^2 bake peaks at 0.92 GB, this says
  // 1.14 GB.
  m.map = texels * (12 + 1 + 2) + (o.debug_dump_prefix.empty() ? 0 : texels * 36);
  // One band of samples: raster (triangle 4 + bary 8) and trace (triangle 4,
  // bary 8, distance 4): 28 bytes, plus a coverage byte per texel.
  const int rows = band_rows(o.width, baked_rows(o), o.samples, o.band_samples);
  const std::uint64_t band_texels = static_cast<std::uint64_t>(rows) * static_cast<std::uint64_t>(o.width);
  m.bands = band_texels * static_cast<std::uint64_t>(o.samples) * 28 + band_texels;
  // Low: the indexed mesh, its half-edge copy for tangents (and unwrap), and
  // the per-corner surface arrays (3 x 72 bytes): about 600 bytes a triangle.
  m.low = low.vertices * 64 + low.triangles * 600;
  // High: positions and normals (24 a vertex, padded), indices (12) and the
  // BVH with its build (DESIGN.md's budget: 100 a triangle all told).
  m.high = high.vertices * 24 + high.triangles * 112;
  // The map set beyond the normal map: each map's float image (4 bytes a
  // channel), its coverage copy for dilation (1) and an integer file's
  // mapped copy (4 a channel); per band sample, AO visibility and the bent
  // direction (16) or thickness (4); the curvature per high vertex (4).
  for (const MapKind map : o.maps) {
    if (map == MapKind::normal) continue;
    const MapTraits t = map_traits(map);
    m.map += texels * (8 * static_cast<std::uint64_t>(t.channels) + 1);
    if (t.occlusion_rays) m.bands += band_texels * static_cast<std::uint64_t>(o.samples) * 16;
    if (t.thickness_rays) m.bands += band_texels * static_cast<std::uint64_t>(o.samples) * 4;
    if (map == MapKind::curvature) m.high += high.vertices * 4;
  }
  // Libraries, TBB and Embree threads, the writers' pieces in flight.
  m.fixed = std::uint64_t{96} << 20;
  return m;
}

Status check_bake_memory(const BakeOptions& o, const MeshSize& low, const MeshSize& high) {
  MemoryLimit limit;
  if (o.max_memory_bytes > 0) {
    limit.bytes = o.max_memory_bytes;
    limit.source = "--max-memory";
  } else {
    limit = available_memory();
    if (limit.bytes == 0) return Status::ok();  // nothing known: no budget
    // What the process holds already (the loaded meshes) is part of the
    // estimate, and no longer part of what is available.
    std::uint64_t resident = 0;
    (void)read_kb_field("/proc/self/status", "VmRSS", resident);
    limit.bytes += resident;
  }
  const BakeMemory m = estimate_bake_memory(o, low, high);
  if (m.total() <= limit.bytes) return Status::ok();
  std::string parts = "map " + memory_text(m.map + m.bands);
  if (low.triangles + high.triangles > 0) parts += ", meshes " + memory_text(m.low + m.high);
  return Status::bad_input("a " + map_text(o) + " needs about " + memory_text(m.total()) + " (" + parts + "); " +
                           memory_text(limit.bytes) + " are available (" + limit.source +
                           "): use a smaller --size" + std::string(baked_rows(o) != o.height ? " or more tiles" : "") +
                           ", or set --max-memory if more can be used");
}

Status check_image_memory(const std::string& path, std::uint64_t width, std::uint64_t height,
                          std::uint64_t channels) {
  // The float pixels (4 bytes a value) and one image of the same size that
  // the command makes from them (a normal map, a heat map, a difference).
  const double needed = 2.0 * 4.0 * static_cast<double>(width) * static_cast<double>(height) *
                        static_cast<double>(channels);
  const MemoryLimit limit = available_memory();
  if (limit.bytes == 0 || needed <= static_cast<double>(limit.bytes)) return Status::ok();
  const std::uint64_t shown = needed >= 1.8e19 ? std::numeric_limits<std::uint64_t>::max()
                                               : static_cast<std::uint64_t>(needed);
  return Status::bad_input("cannot read '" + path + "': its header says " + std::to_string(width) + "x" +
                           std::to_string(height) + " with " + std::to_string(channels) +
                           " channels, which needs about " + memory_text(shown) + "; " + memory_text(limit.bytes) +
                           " are available (" + limit.source + ")");
}

}  // namespace nmbake
