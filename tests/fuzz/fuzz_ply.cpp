// PLY (ascii, binary little and big endian) through load_mesh() (fuzz_util.hpp: both parsers, which must
// agree).
#include "fuzz_util.hpp"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  return nmbake::fuzz::load_mesh_both_ways(data, size, "input.ply");
}
