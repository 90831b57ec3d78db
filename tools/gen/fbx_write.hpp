// A minimal binary FBX writer (FBX 7.4, 32-bit record offsets) for tests and
// the loading benchmarks: one Model with one Geometry (positions, per-vertex
// normals and UVs, polygons of any size), its local translation, rotation
// and scaling, and the document's UnitScaleFactor. Assimp 5.2.5's own binary
// FBX exporter writes files that its importer refuses (nested node lists
// without their closing null record), so the binary FBX files of the tests
// and benchmarks come from here. It writes what Assimp's importer reads; it
// is not a general FBX exporter (one material, no definitions or footer).
#pragma once

#include <cstdint>
#include <glm/vec3.hpp>
#include <string>
#include <vector>

#include "nmbake/common.hpp"
#include "nmbake/mesh.hpp"

namespace nmbake::gen {

struct FbxModel {
  std::string name = "mesh";
  glm::dvec3 translation{0.0};
  glm::dvec3 rotation_degrees{0.0};  // Euler XYZ (FBX's default order: x applied first)
  glm::dvec3 scaling{1.0};
  double unit_scale_factor = 1.0;  // centimetres per file unit (FBX: 1 = cm, 100 = m)
  // A material on every polygon (none when `material` is empty): its
  // DiffuseColor, and a diffuse texture when `texture` names a file; with
  // `embedded` bytes that file is embedded (a Video's Content).
  std::string material;
  glm::dvec3 diffuse{0.8};
  std::string texture;
  std::string embedded;
};

// `polygon_sizes` empty: every polygon is a triangle of mesh.indices;
// otherwise mesh.indices holds the polygons' corners one after the other.
Status write_fbx_binary(const std::string& path, const Mesh& mesh, const FbxModel& model,
                        const std::vector<std::uint32_t>& polygon_sizes = {});

}  // namespace nmbake::gen
