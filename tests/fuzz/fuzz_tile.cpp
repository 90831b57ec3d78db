// Tile files through read_tile() and merge_tiles(), as `nmbake merge` reads
// them. The fuzzer's bytes are the file without its trailer: the harness
// appends their XXH3-64, so a mutation reaches the field checks instead of
// stopping at the checksum. A tile that reads and is a whole bake (1/1) is
// merged into a scratch folder: every map finished and written as PNG at
// the map's own depth and as float EXR.
#include <tbb/global_control.h>

#include <cstdio>
#include <string>
#include <vector>

#define XXH_INLINE_ALL  // the library keeps libxxhash to itself
#include <xxhash.h>

#include "fuzz_util.hpp"
#include "nmbake/task.hpp"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  // One thread: two cores are shared, and the fuzzer wants executions.
  static const tbb::global_control one_thread(tbb::global_control::max_allowed_parallelism, 1);
  std::vector<std::uint8_t> bytes(data, data + size);
  const std::uint64_t check = XXH3_64bits(data, size);
  const auto* trailer = reinterpret_cast<const std::uint8_t*>(&check);
  bytes.insert(bytes.end(), trailer, trailer + sizeof check);
  const nmbake::fuzz::InputFile file(bytes.data(), bytes.size(), "input.nmt");
  nmbake::TileData tile;
  if (!nmbake::read_tile(file.path(), tile).is_ok() || tile.count != 1) return 0;
  const std::string folder = nmbake::fuzz::scratch_folder().string();
  const std::vector<nmbake::OutputSpec> outputs{
      {folder + "/m_<MAP>.png", nmbake::PixelFormat::png16, false},
      {folder + "/m_<MAP>.exr", nmbake::PixelFormat::exr_float, true}};
  nmbake::MergeReport report;
  if (nmbake::merge_tiles({file.path()}, outputs, report).is_ok()) {
    for (const std::string& path : report.outputs) std::remove(path.c_str());
  }
  return 0;
}
