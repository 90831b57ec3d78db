// Engine presets: how each engine or tool decodes a tangent-space normal map,
// so a bake can store the exact inverse of that decode (encode.hpp,
// NormalDecode). The README ("Outputs as engines want them") has the table
// with the documentation each row comes from, and what no document says.
#pragma once

#include <string>
#include <vector>

#include "nmbake/encode.hpp"

namespace nmbake {

struct EnginePreset {
  const char* name;
  GreenChannel green;
  NormalDecode decode;
};

// unity, unreal, godot, blender, gltf, maya, 3dsmax, substance (in that order).
const std::vector<EnginePreset>& engine_presets();
// False for a name not in the table.
bool find_engine_preset(const std::string& name, EnginePreset& out);
// "unity, unreal, ...": for messages and --help.
std::string engine_preset_names();

// Which of the preset's settings were given explicitly (a flag, a job key):
// those keep their value, whatever order they were given in.
struct PresetOverrides {
  bool green = false, bitangent = false, tbn = false, blue = false;
};
void apply_engine_preset(const EnginePreset& preset, const PresetOverrides& given, GreenChannel& green,
                         NormalDecode& decode);

}  // namespace nmbake
