// Memory budgets: what a bake or an image read will need, estimated before
// the big buffers are allocated, against what the process may use. An input
// that would need more is refused with the numbers (bad_input, exit 2)
// instead of dying in std::bad_alloc or taking the machine down.
//
// The estimates are upper-leaning sums of the buffers each stage holds at
// once (README, "Limits"); they need not be exact, only of the right size:
// a 32768^2 map needs ~14 GB whatever the mesh.
#pragma once

#include <cstdint>
#include <string>

#include "nmbake/common.hpp"

namespace nmbake {

struct BakeOptions;

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

// Counts of a loaded mesh the estimate needs (zeros: not loaded yet).
struct MeshSize {
  std::uint64_t vertices = 0;
  std::uint64_t triangles = 0;
};

struct BakeMemory {
  std::uint64_t map = 0;    // float RGB image, coverage, dilation lists, debug images
  std::uint64_t bands = 0;  // per-sample arrays of one band (raster + trace)
  std::uint64_t low = 0;    // low mesh, its OpenMesh copy, per-corner surface arrays
  std::uint64_t high = 0;   // high mesh arrays, normals, BVH and its build
  std::uint64_t fixed = 0;  // libraries, thread stacks, writer buffers
  std::uint64_t total() const { return map + bands + low + high + fixed; }
};
BakeMemory estimate_bake_memory(const BakeOptions& options, const MeshSize& low, const MeshSize& high);

// Ok when the estimate fits the budget: options.max_memory_bytes when set,
// else available_memory(). Else bad_input: "a 32768x32768 map at 4 spp needs
// about N GB (map .., meshes ..); M GB are available (SOURCE)".
Status check_bake_memory(const BakeOptions& options, const MeshSize& low, const MeshSize& high);

// An image of width x height x channels read as float (plus the copy a
// command makes of it) against available_memory(); bad_input naming `path`.
Status check_image_memory(const std::string& path, std::uint64_t width, std::uint64_t height,
                          std::uint64_t channels);

}  // namespace nmbake
