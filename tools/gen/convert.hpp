// nmbake-gen convert IN OUT (OBJ, PLY, glTF, FBX... in; .obj, .ply, .glb,
// .gltf + .bin, or binary .fbx (fbx_write.hpp) out) and
// nmbake-gen load FILE [--low] (load only, prints counts and time).
#pragma once

#include <string>

#include "nmbake/common.hpp"

namespace nmbake::gen {

Status convert_mesh(const std::string& in, const std::string& out);
// Loads as the bake loads a high mesh (no UVs), or a low one with `low`.
Status load_only(const std::string& path, bool low);

}  // namespace nmbake::gen
