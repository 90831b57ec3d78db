// Stage "load": a mesh file into the indexed Mesh of mesh.hpp.
//
// Formats (chosen by extension, case-insensitive):
//   * OBJ: v, vt, vn; f with v, v/vt, v//vn, v/vt/vn; negative (relative)
//     indices; polygons fan-triangulated; every o/g/s/usemtl ignored, so all
//     objects and groups are merged into one mesh. Other statements ignored.
//   * PLY: ascii, binary_little_endian, binary_big_endian; element vertex with
//     x y z, optional nx ny nz and u v | s t | texture_u texture_v |
//     texture_s texture_t (any scalar type); element face with a list property
//     vertex_indices or vertex_index (polygons fan-triangulated); other
//     elements and properties skipped.
//
// Every problem is a Status::bad_input naming the file, the line (text) or
// byte offset (binary) and the reason. After loading, validate_mesh() has
// passed: no NaN/Inf, every index in range.
#pragma once

#include <string>

#include "nmbake/common.hpp"
#include "nmbake/mesh.hpp"

namespace nmbake {

struct LoadOptions {
  bool keep_uvs = true;      // false for the high mesh: never split vertices at UV seams
  bool keep_normals = true;  // false: file normals are dropped (e.g. --high-normals face)
};

struct LoadStats {
  std::uint64_t bytes = 0;           // file size
  std::uint64_t polygons = 0;        // faces in the file before triangulation
  std::uint64_t triangles = 0;       // after triangulation
  std::uint64_t degenerate_faces = 0;  // faces with fewer than 3 corners: skipped
};

Status load_mesh(const std::string& path, const LoadOptions& options, Mesh& out, LoadStats& stats);

// Writes a mesh as OBJ (v, vt, vn, f) or PLY (binary little endian), by
// extension. Used by the generators and by `nmbake unwrap`.
Status save_mesh(const std::string& path, const Mesh& mesh);

}  // namespace nmbake
