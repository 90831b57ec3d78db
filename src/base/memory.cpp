// The machine's memory (memory.hpp), read from the kernel's own accounting.
#include "nmbake/memory.hpp"

#include <sys/resource.h>

#include <algorithm>
#include <cctype>
#include <charconv>
#include <cmath>
#include <cstdio>
#include <fstream>
#include <limits>
#include <sstream>
#include <string>

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
    if (line.compare(0, key.size(), key) != 0 || line.size() <= key.size() || line[key.size()] != ':')
      continue;
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
  if (read_kb_field("/proc/meminfo", "MemAvailable", bytes))
    consider(limit, bytes, "MemAvailable in /proc/meminfo");
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

std::uint64_t resident_memory() {
  std::uint64_t resident = 0;
  (void)read_kb_field("/proc/self/status", "VmRSS", resident);
  return resident;
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

Status check_image_memory(const std::string& path, std::uint64_t width, std::uint64_t height,
                          std::uint64_t channels) {
  // The float pixels (4 bytes a value) and one image of the same size that
  // the command makes from them (a normal map, a heat map, a difference).
  const double needed =
      2.0 * 4.0 * static_cast<double>(width) * static_cast<double>(height) * static_cast<double>(channels);
  const MemoryLimit limit = available_memory();
  if (limit.bytes == 0 || needed <= static_cast<double>(limit.bytes)) return Status::ok();
  const std::uint64_t shown =
      needed >= 1.8e19 ? std::numeric_limits<std::uint64_t>::max() : static_cast<std::uint64_t>(needed);
  return Status::bad_input("cannot read '" + path + "': its header says " + std::to_string(width) + "x" +
                           std::to_string(height) + " with " + std::to_string(channels) +
                           " channels, which needs about " + memory_text(shown) + "; " +
                           memory_text(limit.bytes) + " are available (" + limit.source + ")");
}

}  // namespace nmbake
