// MTL (the material library of an OBJ) and the texture paths it names: the
// fuzzer's bytes as `input.mtl`, every material it defines read
// (read_mtl_library), then every texture of every attribute loaded as a bake
// of the transfer maps would (load_material_textures: missing files, folders,
// devices, <UDIM> patterns, paths from other machines).
#include <cstring>
#include <string>
#include <vector>

#include "fuzz_util.hpp"
#include "load/parsers.hpp"
#include "nmbake/textures.hpp"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  using namespace nmbake;
  const fuzz::InputFile file(data, size, "input.mtl");
  // The names the file defines, so that each is "used".
  std::vector<std::string> used;
  const std::string text(reinterpret_cast<const char*>(data), size);
  for (std::size_t at = text.find("newmtl"); at != std::string::npos; at = text.find("newmtl", at + 6)) {
    std::size_t begin = at + 6, end = text.find_first_of("\r\n#", begin);
    if (end == std::string::npos) end = text.size();
    while (begin < end && (text[begin] == ' ' || text[begin] == '\t')) ++begin;
    while (end > begin &&
           (text[end - 1] == ' ' || text[end - 1] == '\t' || text[end - 1] == '\f' || text[end - 1] == '\v'))
      --end;
    used.push_back(text.substr(begin, end - begin));
  }
  Mesh mesh;
  const std::string obj = (fuzz::scratch_folder() / "input.obj").string();
  std::vector<std::string> files;
  if (!load_detail::read_mtl_library(obj, "input.mtl", used, mesh.material_defs, files).is_ok()) return 0;
  TextureNeeds all;
  all.base_color = all.roughness = all.metallic = all.emissive = all.opacity = true;
  TextureSet textures;
  (void)load_material_textures(mesh, obj, all, textures);
  return 0;
}
