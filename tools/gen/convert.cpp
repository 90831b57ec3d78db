// nmbake-gen convert / load: mesh format conversion for the loading
// benchmarks (BENCHMARKS.md, "Loading glTF and FBX") and a load-only run to
// time under /usr/bin/time.
#include "convert.hpp"

#include <chrono>
#include <cstdio>
#include <memory>
#include <string>

#include <assimp/Exporter.hpp>
#include <assimp/scene.h>

#include "nmbake/load.hpp"

namespace nmbake::gen {

namespace {

std::string lower_extension(const std::string& path) {
  const std::size_t dot = path.find_last_of('.');
  std::string extension = dot == std::string::npos ? std::string() : path.substr(dot);
  for (char& c : extension) c = static_cast<char>(std::tolower(static_cast<unsigned char>(c)));
  return extension;
}

// One node, one mesh: Assimp's exporter wants a material too.
Status export_fbx(const Mesh& mesh, const std::string& path, bool ascii) {
  aiScene scene;
  auto* out = new aiMesh();
  out->mName = "mesh";
  out->mPrimitiveTypes = aiPrimitiveType_TRIANGLE;
  out->mNumVertices = static_cast<unsigned>(mesh.vertex_count());
  out->mVertices = new aiVector3D[mesh.vertex_count()];
  for (std::size_t v = 0; v < mesh.vertex_count(); ++v) {
    out->mVertices[v] = aiVector3D(mesh.positions[v].x, mesh.positions[v].y, mesh.positions[v].z);
  }
  if (mesh.has_normals()) {
    out->mNormals = new aiVector3D[mesh.vertex_count()];
    for (std::size_t v = 0; v < mesh.vertex_count(); ++v) {
      out->mNormals[v] = aiVector3D(mesh.normals[v].x, mesh.normals[v].y, mesh.normals[v].z);
    }
  }
  if (mesh.has_uvs()) {
    out->mTextureCoords[0] = new aiVector3D[mesh.vertex_count()];
    out->mNumUVComponents[0] = 2;
    for (std::size_t v = 0; v < mesh.vertex_count(); ++v) out->mTextureCoords[0][v] = aiVector3D(mesh.uvs[v].x, mesh.uvs[v].y, 0);
  }
  out->mNumFaces = static_cast<unsigned>(mesh.triangle_count());
  out->mFaces = new aiFace[mesh.triangle_count()];
  for (std::size_t t = 0; t < mesh.triangle_count(); ++t) {
    out->mFaces[t].mNumIndices = 3;
    out->mFaces[t].mIndices = new unsigned[3]{mesh.indices[3 * t], mesh.indices[3 * t + 1], mesh.indices[3 * t + 2]};
  }
  scene.mNumMeshes = 1;
  scene.mMeshes = new aiMesh*[1]{out};
  scene.mNumMaterials = 1;
  scene.mMaterials = new aiMaterial*[1]{new aiMaterial()};
  scene.mRootNode = new aiNode("root");
  auto* node = new aiNode("mesh");
  node->mNumMeshes = 1;
  node->mMeshes = new unsigned[1]{0};
  aiNode* children[] = {node};
  scene.mRootNode->addChildren(1, children);
  Assimp::Exporter exporter;
  if (exporter.Export(&scene, ascii ? "fbxa" : "fbx", path) != AI_SUCCESS) {
    return Status::io(path + ": Assimp export: " + exporter.GetErrorString());
  }
  return Status::ok();
}

}  // namespace

Status convert_mesh(const std::string& in, const std::string& out) {
  Mesh mesh;
  LoadStats stats;
  NMBAKE_TRY(load_mesh(in, LoadOptions{}, mesh, stats));
  const std::string extension = lower_extension(out);
  if (extension == ".fbx") return export_fbx(mesh, out, false);
  return save_mesh(out, mesh);
}

Status load_only(const std::string& path, bool low) {
  Mesh mesh;
  LoadStats stats;
  LoadOptions options;
  options.keep_uvs = low;
  NMBAKE_TRY(load_mesh(path, options, mesh, stats));
  std::printf("load %s: %zu vertices, %zu triangles, %.3f s, %.1f MB/s\n", path.c_str(), mesh.vertex_count(),
              mesh.triangle_count(), stats.seconds, stats.mb_per_second());
  return Status::ok();
}

}  // namespace nmbake::gen
