// FBX, Collada, 3DS and STL through load_mesh() (Assimp and our checks, the
// same entry `nmbake bake --low x.fbx` uses: Assimp in a child process,
// load/isolated.hpp). The first byte picks the extension; the rest is the
// file. Assimp's own crashes and runaway allocations are errors there; a
// crash in our conversion code is internal, which aborts here. When the
// file loads, it is loaded again in this process (coverage for libFuzzer),
// which must give the same mesh (parts, materials and colours included).
// The first byte's next bit asks for vertex colours, the one after for
// materials, corner UVs and embedded textures (as a texture bake loads the
// high mesh), which must cross from the child whole too. Seeds:
// tests/fuzz/corpus/assimp/ and, at run time, the small models of
// assimp-testmodels (tools/fuzz).
#include "fuzz_util.hpp"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  if (size == 0) return 0;
  static const char* const kNames[] = {"input.fbx", "input.dae", "input.3ds", "input.stl"};
  const nmbake::fuzz::InputFile file(data + 1, size - 1, kNames[data[0] % 4]);
  nmbake::LoadOptions options;
  options.keep_colors = (data[0] / 4) % 2 == 1;
  options.material_defs = options.corner_uvs = (data[0] / 8) % 2 == 1;
  nmbake::Mesh isolated;
  nmbake::LoadStats stats;
  const nmbake::Status status = nmbake::load_mesh(file.path(), options, isolated, stats);
  if (status.code() == nmbake::StatusCode::internal) std::abort();
  if (!status.is_ok()) return 0;
  nmbake::LoadOptions here = options;
  here.isolate_libraries = false;
  nmbake::Mesh mesh;
  const nmbake::Status again = nmbake::load_mesh(file.path(), here, mesh, stats);
  if (!again.is_ok() || mesh.positions != isolated.positions || mesh.indices != isolated.indices ||
      mesh.uvs != isolated.uvs || mesh.normals != isolated.normals || mesh.colors != isolated.colors ||
      mesh.parts != isolated.parts || mesh.materials != isolated.materials ||
      mesh.corner_uvs != isolated.corner_uvs || mesh.material_defs != isolated.material_defs ||
      mesh.embedded_images != isolated.embedded_images) {
    std::abort();
  }
  (void)nmbake::check_coordinate_range(mesh, file.path());
  return 0;
}
