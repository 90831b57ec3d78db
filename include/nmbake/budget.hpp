// Memory budgets: what a bake will need, estimated before
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
#include "nmbake/memory.hpp"

namespace nmbake {

struct BakeOptions;

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

}  // namespace nmbake
