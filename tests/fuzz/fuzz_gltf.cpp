// glTF 2.0 through load_mesh() (tinygltf and our accessor checks, the same
// entry `nmbake bake --low x.glb` uses). The first byte picks .gltf (JSON,
// data: URIs) or .glb, its next bits ask for vertex colours (COLOR_0) and
// tangents; the rest is the file. Seeds: tests/fuzz/corpus/gltf/
// and, at run time, the small glTF models of assimp-testmodels (tools/fuzz).
#include "fuzz_util.hpp"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  if (size == 0) return 0;
  const nmbake::fuzz::InputFile file(data + 1, size - 1, data[0] % 2 ? "input.glb" : "input.gltf");
  nmbake::Mesh mesh;
  nmbake::LoadStats stats;
  nmbake::LoadOptions options;
  options.keep_colors = (data[0] & 2) != 0;
  options.keep_tangents = (data[0] & 4) != 0;
  const nmbake::Status status = nmbake::load_mesh(file.path(), options, mesh, stats);
  // What the loader returns holds together (one colour and tangent a vertex).
  if (status.is_ok() && !nmbake::validate_mesh(mesh, file.path())) __builtin_trap();
  if (status.is_ok()) (void)nmbake::check_coordinate_range(mesh, file.path());
  return 0;
}
