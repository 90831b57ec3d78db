// Stage "load": a mesh file into the indexed Mesh of mesh.hpp.
//
// Formats (chosen by extension, case-insensitive):
//   * OBJ: v, vt, vn; f with v, v/vt, v//vn, v/vt/vn; negative (relative)
//     indices; polygons fan-triangulated; all objects and groups are one
//     mesh, `o` (else `g`) naming its parts and `usemtl` its materials
//     (ranges of the triangles that follow; triangles before the first
//     `usemtl` have the unnamed material ""). With keep_colors, "v x y z r
//     g b" colours (see keep_colors). Other statements (s, mtllib, l, p,
//     curves) are ignored.
//   * PLY: ascii, binary_little_endian, binary_big_endian; element vertex with
//     x y z, optional nx ny nz and u v | s t | texture_u texture_v |
//     texture_s texture_t (any scalar type); element face with a list property
//     vertex_indices or vertex_index (polygons fan-triangulated); other
//     elements and properties skipped.
//   * glTF 2.0 (.gltf with external or data: URI buffers, .glb; gltf.cpp,
//     tinygltf): every node with a mesh in the default scene (else scene 0,
//     else every root node), with its world matrix (the full node
//     hierarchy) applied to positions, the inverse transpose to normals,
//     the linear part to TANGENT xyz; a mirroring matrix (determinant < 0)
//     swaps two corners of each triangle, so counter-clockwise stays the
//     front, and flips TANGENT w. Primitives TRIANGLES, TRIANGLE_STRIP
//     (triangles with a repeated vertex skipped, counted in
//     degenerate_faces) and TRIANGLE_FAN (a fan from vertex 0, like OBJ
//     polygons), indexed or not; points and lines skipped, each point or
//     segment counted in degenerate_faces. POSITION, NORMAL, TANGENT float;
//     TEXCOORD_<uv_set> float or normalized unsigned byte/short; sparse
//     accessors are applied. glTF's UV origin is the top-left of the image:
//     v' = 1 - v gives nmbake's bottom-left. Vertices are the file's (split
//     as the file splits them, also for a high mesh). One MeshPart per node:
//     the node's name, else its mesh's name when no other node uses that
//     mesh, else "node<N>". A material range per primitive: its material's
//     name, "material <N>" when unnamed, "" without a material (an index
//     out of range is an error). unit_meters = 1. Draco (KHR_draco_mesh_compression)
//     and meshopt-compressed files are refused with a message that says so.
//   * FBX (binary, ASCII), Collada .dae, .3ds, .stl (assimp.cpp, Assimp 5.2):
//     the node tree with every node's matrix applied as for glTF; polygons
//     fan-triangulated from corner 0 exactly like OBJ (not by Assimp, whose
//     triangulation starts concave quads at the reflex corner and
//     ear-clips n-gons); vertices welded where every kept attribute is
//     bitwise equal (FBX stores them per polygon corner). UV channel uv_set; tangents from the file's
//     tangents and bitangents (w = sign of dot(cross(N, T), B)). One
//     MeshPart per node with meshes, named by the node ("node<N>" if
//     unnamed); a material range per Assimp mesh, named by its material
//     (AI_MATKEY_NAME; Assimp's invented "DefaultMaterial" and "%%%DEFAULT"
//     are ""); vertex colours from colour set 0. unit_meters = 0.01 * the FBX UnitScaleFactor; positions
//     stay in file units. Collada: Assimp applies the file's up axis and
//     unit to the root node.
//   * glTF and Assimp files: two parts with the same name are an error; a
//     low mesh (keep_uvs) must have UV set uv_set on every primitive, or no
//     UVs at all with uv_set 0 (then it is unwrapped like an OBJ without vt);
//     with keep_tangents, tangents on every primitive or on none. OBJ and
//     PLY have one UV set: uv_set != 0 is an error.
//
// Every problem is a Status::bad_input naming the file, the line (text) or
// byte offset (binary) and the reason: "PATH:LINE: reason",
// "PATH: byte OFFSET: reason", or "PATH: reason" for the whole file (cannot
// open, unknown extension, no triangles). A read(2) failure is Status::io.
// After loading, validate_mesh() has passed: no NaN/Inf, every index in
// range, at least one triangle. On failure `out` is left empty.
//
// What the loaded mesh holds:
//   * Vertices no triangle references are dropped; the others keep file
//     order (OBJ with split vertices: order of first use by the faces).
//   * OBJ vertices are the distinct (v, vt, vn) combinations the faces use,
//     counting only the attributes kept by LoadOptions (so the high mesh is
//     not split at UV seams). All corners must agree on whether they carry a
//     kept vt / vn (else bad_input naming the line); an attribute that is not
//     kept is neither range-checked nor required to be consistent. Indices
//     must refer to data defined earlier in the file, as the OBJ spec says.
//   * Materials (Mesh::materials) are empty when no triangle has a named
//     material; consecutive ranges of one name are merged.
//   * Normals are returned as stored in the file: not normalised, zero-length
//     ones kept. The caller runs normalize_normals() or, when the file had
//     none, compute_vertex_normals() (mesh.hpp), which count their fallbacks.
//   * Faces with fewer than 3 corners (points, lines) are skipped and counted
//     in LoadStats::degenerate_faces; LoadStats::polygons counts the others.
//   * Reals out of float range or NaN/Inf are errors; underflow reads as 0.
//
// Speed: the file is read in blocks (LoadOptions::block_bytes, so memory
// stays near the size of the mesh arrays), and each block is decoded on all
// cores: fixed-stride binary PLY records (vertices; faces that are triangles
// with a one-byte count) and OBJ text split at line boundaries. Anything else
// (ascii PLY, other face layouts) is read by the one-thread parsers. The
// result does not depend on the thread count or the block size.
#pragma once

#include <cstddef>
#include <cstdint>
#include <string>
#include <vector>

#include "nmbake/common.hpp"
#include "nmbake/mesh.hpp"

namespace nmbake {

struct LoadOptions {
  bool keep_uvs = true;        // false for the high mesh: never split vertices at UV seams
  bool keep_normals = true;    // false: file normals are dropped (e.g. --high-normals face)
  int uv_set = 0;              // glTF TEXCOORD_N / FBX UV channel N (OBJ and PLY have one: N must be 0)
  bool keep_tangents = false;  // glTF TANGENT / FBX tangents into Mesh::tangents (--tangents file)
  // Vertex colours into Mesh::colors (the vertex-color map), sRGB-encoded
  // (display values, as a PLY's bytes) in [0, 1] as files store them: PLY
  // red, green, blue, optional alpha (unsigned char or short scaled to
  // [0, 1], float as stored); OBJ "v x y z r g b" (the MeshLab / Open3D
  // extension; a v without three more finite numbers is white; as written,
  // alpha 1); glTF COLOR_0 (float or normalised unsigned byte/short, RGB or
  // RGBA; linear in the file, so RGB goes through the sRGB curve; white on
  // primitives without it); FBX and Collada (Assimp's colour set 0, RGBA as
  // stored: neither importer converts, and modellers store display values;
  // white on meshes without one; vertices are welded only where their
  // colours agree too). A file with no colour at all gives none.
  bool keep_colors = false;
  // Texture transfer (maps.hpp): every triangle corner's UV (uv_set) into
  // Mesh::corner_uvs without splitting vertices, so the high mesh's
  // triangles, vertices and normals are exactly those of a load without it;
  // corners without a UV get (0, 0), counted. OBJ, glTF and the Assimp
  // formats (FBX, Collada, 3DS; STL has no UVs: all counted); PLY:
  // bad_input saying so.
  bool corner_uvs = false;
  // Material definitions into Mesh::material_defs: OBJ `mtllib` files
  // (MTL: Kd, d, Ke, Pr, Pm, map_Kd, map_d, map_Ke, map_Pr, map_Pm,
  // norm / map_Bump / bump with -bm, options -o -s -clamp -imfchan; Tr as
  // 1 - d), glTF materials (pbrMetallicRoughness factors and textures,
  // normalTexture + scale, emissiveTexture + factor, samplers' wrap modes,
  // KHR_texture_transform; images in buffer views and data: URIs into
  // Mesh::embedded_images), FBX and Collada (and 3DS) through Assimp's
  // aiMaterial (assimp.cpp: diffuse / base colour, opacity, emissive,
  // roughness and metallic factors, their textures, wrap modes, embedded
  // textures into Mesh::embedded_images). A library or image path is
  // resolved against the mesh's folder; a missing MTL file is bad_input
  // naming it. PLY, STL: none.
  bool material_defs = false;
  // A material library that cannot be read (missing, unreadable, malformed)
  // is skipped and counted (LoadStats::unread_material_libraries) instead
  // of bad_input: for a bake that only looks whether the high's materials
  // carry something (--high-normal-maps auto).
  bool material_libraries_optional = false;
  // Tuning of the parallel parsers, for tests and benchmarks; the loaded mesh
  // and every error are the same whatever they are set to.
  std::size_t block_bytes = 0;  // bytes read and decoded at a time; 0: 4 MiB
  bool serial = false;          // true: the one-thread reference parsers only
  // FBX, Collada, 3DS and STL (Assimp) are read in a child process, so that
  // a crash or runaway allocation inside Assimp is an error naming the file
  // (src/load/isolated.hpp). false: in this process (the fuzz harness, which
  // checks both ways give the same mesh).
  bool isolate_libraries = true;
};

struct LoadStats {
  std::uint64_t bytes = 0;                      // file size (for glTF: the .gltf plus its external buffers)
  double seconds = 0.0;                         // wall time of load_mesh
  std::uint64_t polygons = 0;                   // faces in the file before triangulation
  std::uint64_t triangles = 0;                  // after triangulation
  std::uint64_t degenerate_faces = 0;           // faces with fewer than 3 corners: skipped
  std::uint64_t corners_without_uvs = 0;        // LoadOptions::corner_uvs: corners the file gave no UV
  std::uint64_t unread_material_libraries = 0;  // LoadOptions::material_libraries_optional: skipped
  // The files the load read (or looked for) besides the mesh file: MTL
  // libraries, a glTF's external buffers. A bake's cache entry records
  // their checksums (cache.hpp), as the bake key holds the mesh file's.
  std::vector<std::string> files;
  // Length of one file unit in metres when the file says (FBX UnitScaleFactor:
  // 0.01 for centimetres; glTF: 1); 0 when the format does not say (OBJ, PLY).
  // Positions are kept in file units; the report shows this note.
  double unit_meters = 0.0;

  // Load rate in MB/s (10^6 bytes), 0 before a load.
  double mb_per_second() const { return seconds > 0.0 ? static_cast<double>(bytes) / seconds * 1e-6 : 0.0; }
};

Status load_mesh(const std::string& path, const LoadOptions& options, Mesh& out, LoadStats& stats);

// Several files as one mesh, in the order given (the high mesh split across
// files: one ZBrush subtool a file). One path is load_mesh(). Otherwise each
// file is loaded by load_mesh() and appended, so the mesh equals one file
// holding the same parts in the same order: vertices and triangles follow
// each other, parts and material ranges are kept, and a file without part
// names becomes one part named after the file's stem (body.obj: "body"), so
// groups and matching by name can address it. Attributes some files have and
// others lack: normals are zero on the others (normalize_normals() computes
// them there and counts them, as for any zero-length normal), colours white
// (as glTF primitives without COLOR_0); UVs and tangents (low meshes) must be
// in every file or none. A material whose name an earlier file defined
// differently is renamed "STEM/NAME" in this file (the id map and the
// transfer maps read each file's own). Files whose units differ (FBX
// UnitScaleFactor) are bad_input naming both. `stats` adds the files' figures.
Status load_meshes(const std::vector<std::string>& paths, const LoadOptions& options, Mesh& out,
                   LoadStats& stats);

// Whether load_mesh() reads files with this path's extension (case-insensitive),
// and the list for messages: ".obj, .ply, .gltf, .glb, .fbx, .dae, .3ds or .stl".
bool mesh_extension_supported(const std::string& path);
const char* supported_mesh_extensions();

// What can be known of a mesh file without loading it, so a job finds a bad
// path in its last bake before the first bake runs: `path` is non-empty, has
// no NUL byte and a supported extension, names an existing regular file (a
// FIFO would block, a device never ends) that opens and is not empty, and
// starts as its format must (PLY: "ply"; binary glTF: "glTF"; OBJ: no NUL
// byte in its first 4 KiB). bad_input naming the path (printable_text) and
// the reason; `what` ("low", "high", "cage") names the mesh.
Status check_mesh_file(const char* what, const std::string& path);

// Writes a mesh as OBJ (v [r g b], vt, vn, f, `o NAME` where each part
// begins, `usemtl NAME` where each material range begins (a bare `usemtl`
// for "" after a named one; no .mtl); reals in the shortest form that reads
// back bit for bit; colour alpha is not written), PLY (binary little endian:
// float x y z [nx ny nz] [u v] [red green blue alpha], face list uchar uint;
// no parts or materials), or glTF (.glb, or .gltf with NAME.bin beside it:
// float POSITION, NORMAL, TEXCOORD_0 with v flipped back to glTF's top-left
// origin, TANGENT, COLOR_0 (linear), uint indices; one node per part, one
// primitive per material range within it, materials with only a name), by
// extension. The mesh must pass
// validate_mesh(). The file is written to a temporary file in the same folder
// and renamed, so a failure never leaves a half-written mesh (Status::io).
// Used by the generators and by `nmbake unwrap`.
Status save_mesh(const std::string& path, const Mesh& mesh);

// The textures of one glTF PBR material of a review .glb (`nmbake view`):
// the bytes of PNG files, embedded in the .glb's buffer; empty = no such
// texture. `name` is the material range of Mesh::materials it dresses.
struct GltfMaterialTextures {
  std::string name;
  std::string normal_png;              // normalTexture (tangent space, green up: glTF's convention)
  std::string occlusion_png;           // occlusionTexture (red channel)
  std::string base_color_png;          // pbrMetallicRoughness.baseColorTexture (sRGB)
  std::string metallic_roughness_png;  // pbrMetallicRoughness.metallicRoughnessTexture (G roughness, B metal)
  std::string emissive_png;            // emissiveTexture (sRGB), emissiveFactor 1
};

// `mesh` as one binary glTF (.glb bytes), written as save_mesh() writes a
// .glb (one node per part, one primitive per material range), with each
// material of `materials` a PBR material wearing its textures (embedded
// PNG images, a linear sampler clamped at the borders, as the baker's
// preview samples). A material range whose name is not in `materials` gets
// a material with its name only. The mesh must pass validate_mesh().
Status encode_textured_glb(const Mesh& mesh, const std::vector<GltfMaterialTextures>& materials,
                           std::string& glb);

// The versions of the mesh readers in use: Assimp's shared library ("5.2.5")
// and tinygltf's header compiled into nmbake ("2.7.0", from its change log).
std::string assimp_version();
std::string tinygltf_version();

}  // namespace nmbake
