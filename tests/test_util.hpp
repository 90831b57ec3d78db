// Helpers shared by the tests: temporary folders, running the CLI, small meshes.
#pragma once

#include <filesystem>
#include <string>

#include "nmbake/bake_options.hpp"
#include "nmbake/mesh.hpp"
#include "nmbake/surface.hpp"

namespace nmbake::test {

// A fresh, empty folder under the system temp dir, removed by the destructor.
class TempDir {
 public:
  TempDir();
  ~TempDir();
  TempDir(const TempDir&) = delete;
  TempDir& operator=(const TempDir&) = delete;
  const std::filesystem::path& path() const { return path_; }
  std::string file(const std::string& name) const { return (path_ / name).string(); }

 private:
  std::filesystem::path path_;
};

// Writes `text` to `path` (overwriting).
void write_text(const std::string& path, const std::string& text);

struct CommandResult {
  int exit_code = -1;
  std::string output;  // stdout and stderr together
};
// Runs a shell command line, capturing its output.
CommandResult run_command(const std::string& command_line);

// A low quad [0,1]^2 at z = 0 (two triangles, normal +z, UV = xy, tangent
// +x) as a LowSurface.
LowSurface low_quad();

// The mesh as a Collada 1.4.1 document written by hand, for the Assimp
// loader (Y up, metres, one node "mesh"): positions, normals and RGBA vertex
// colours (COLOR) when it has them, and one <triangles> element per material
// range bound to a material of that name (a range named "" has none, and
// Assimp then gives it the first bound material; no materials: one
// element). Parts are not written. Reals in the shortest
// form that reads back exactly.
std::string collada_text(const Mesh& mesh);

// Bakes `options` as `count` tiles of rows (the last first: the order must
// not matter), each to `folder`/I.tile, and merges them to `outputs`.
Status bake_tiles_and_merge(const BakeOptions& options, int count, const std::filesystem::path& folder,
                            const std::vector<OutputSpec>& outputs);

// Paths of the built programs and of the source tree.
std::string cli_path();
std::string gen_path();
std::string source_dir();

}  // namespace nmbake::test
