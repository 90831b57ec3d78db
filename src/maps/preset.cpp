// The engine preset table (preset.hpp). Each row is what the engine's own
// documentation (or, where it is silent, its shader source) says its decode
// does; README "Outputs as engines want them" cites them row by row.
#include "nmbake/preset.hpp"

namespace nmbake {

const std::vector<EnginePreset>& engine_presets() {
  using B = Bitangent;
  // name, green, {bitangent, unit_frame, rebuild_blue}
  static const std::vector<EnginePreset> table = {
      // Built-in pipeline: B per vertex (Substance: "per fragment disabled:
      // Unity 5.3 or newer"), DXT5nm/BC5 normal maps, z rebuilt.
      {"unity", GreenChannel::up, {B::vertex, false, true}},
      // B per pixel from unnormalised T, N; BC5 (TC_Normalmap), z rebuilt.
      {"unreal", GreenChannel::down, {B::pixel, false, true}},
      // Binormal per vertex; T, B, N normalised per pixel; z always rebuilt.
      {"godot", GreenChannel::up, {B::vertex, true, true}},
      // Cycles/EEVEE Normal Map node: MikkTSpace per pixel, RGB.
      {"blender", GreenChannel::up, {B::pixel, false, false}},
      // bitangent = cross(normal, tangent) * w per vertex, the TBN
      // normalised per pixel (Khronos glTF Sample Viewer), RGB.
      {"gltf", GreenChannel::up, {B::vertex, true, false}},
      // Green per Autodesk/Substance; the bitangent rule is not documented:
      // MikkTSpace's per-pixel default.
      {"maya", GreenChannel::up, {B::pixel, false, false}},
      {"3dsmax", GreenChannel::down, {B::pixel, false, false}},
      // Painter's "Compute tangent space per fragment" on; OpenGL format.
      {"substance", GreenChannel::up, {B::pixel, false, false}},
  };
  return table;
}

bool find_engine_preset(const std::string& name, EnginePreset& out) {
  for (const EnginePreset& p : engine_presets()) {
    if (name == p.name) {
      out = p;
      return true;
    }
  }
  return false;
}

std::string engine_preset_names() {
  std::string names;
  for (const EnginePreset& p : engine_presets()) names += (names.empty() ? "" : ", ") + std::string(p.name);
  return names;
}

void apply_engine_preset(const EnginePreset& preset, const PresetOverrides& given, GreenChannel& green,
                         NormalDecode& decode) {
  if (!given.green) green = preset.green;
  if (!given.bitangent) decode.bitangent = preset.decode.bitangent;
  if (!given.tbn) decode.unit_frame = preset.decode.unit_frame;
  if (!given.blue) decode.rebuild_blue = preset.decode.rebuild_blue;
}

}  // namespace nmbake
