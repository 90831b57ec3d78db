// nmbake-gen convert / load: mesh format conversion for the loading
// benchmarks (BENCHMARKS.md, "Loading glTF and FBX") and a load-only run to
// time under /usr/bin/time.
#include "convert.hpp"

#include <chrono>
#include <cstdio>
#include <memory>
#include <string>

#include "fbx_write.hpp"
#include "nmbake/load.hpp"

namespace nmbake::gen {

namespace {

std::string lower_extension(const std::string& path) {
  const std::size_t dot = path.find_last_of('.');
  std::string extension = dot == std::string::npos ? std::string() : path.substr(dot);
  for (char& c : extension) c = static_cast<char>(std::tolower(static_cast<unsigned char>(c)));
  return extension;
}

}  // namespace

Status convert_mesh(const std::string& in, const std::string& out) {
  Mesh mesh;
  LoadStats stats;
  NMBAKE_TRY(load_mesh(in, LoadOptions{}, mesh, stats));
  const std::string extension = lower_extension(out);
  if (extension == ".fbx") return write_fbx_binary(out, mesh, FbxModel{});
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
