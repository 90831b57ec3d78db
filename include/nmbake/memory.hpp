// The machine's memory as this process sees it: what it may still allocate
// (the kernel's own accounting), memory sizes as text, and the check of an
// image read against it. The bake's own estimate is budget.hpp.
#pragma once

#include <cstdint>
#include <string>

#include "nmbake/common.hpp"

namespace nmbake {

// What the process may still allocate: the least of /proc/meminfo
// MemAvailable, the cgroup's memory.max - memory.current (v2, every level up
// to the root) or memory.limit_in_bytes - memory.usage_in_bytes (v1), and
// RLIMIT_AS (ulimit -v) minus the address space already in use. `source`
// says which one bounds it. bytes = 0 when nothing could be read (then no
// budget is enforced).
struct MemoryLimit {
  std::uint64_t bytes = 0;
  std::string source;
};
MemoryLimit available_memory();

// The memory this process holds now (VmRSS), 0 when unknown.
std::uint64_t resident_memory();

// Caps this process's address space (RLIMIT_AS) at what it maps now plus
// available_memory(), so that an allocation the machine cannot hold fails
// (std::bad_alloc) instead of swapping the machine to a halt. Never raises
// a lower limit; does nothing in sanitizer builds (NMBAKE_SANITIZED), whose
// shadow memory needs terabytes of address space. For a child process that
// runs a third-party reader (src/load/isolated.hpp).
void cap_address_space_at_available();

// "4096", "512K", "512M", "8G", "1.5T" (binary multiples; an optional "B" or
// "iB" after the letter). False for junk, zero, or overflow.
bool parse_memory_size(const std::string& text, std::uint64_t& bytes);
// "13.9 GB" style text (10^9 bytes a GB), for messages.
std::string memory_text(std::uint64_t bytes);

// An image of width x height x channels read as float (plus the copy a
// command makes of it) against available_memory(); bad_input naming `path`.
Status check_image_memory(const std::string& path, std::uint64_t width, std::uint64_t height,
                          std::uint64_t channels);

}  // namespace nmbake
