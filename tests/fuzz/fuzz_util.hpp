// Shared by the harnesses: the fuzzer's bytes as a file with the extension
// the library picks its parser by, in a folder of this process's own (RAM
// backed when /dev/shm exists), removed when the harness returns.
#pragma once

#include <unistd.h>

#include <cstddef>
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <string>

#include "nmbake/load.hpp"

namespace nmbake::fuzz {

inline const std::filesystem::path& scratch_folder() {
  static const std::filesystem::path folder = [] {
    std::error_code ec;
    const std::filesystem::path base = std::filesystem::is_directory("/dev/shm", ec)
                                           ? std::filesystem::path("/dev/shm")
                                           : std::filesystem::temp_directory_path();
    std::filesystem::path f = base / ("nmbake-fuzz-" + std::to_string(::getpid()));
    std::filesystem::create_directories(f, ec);
    return f;
  }();
  return folder;
}

class InputFile {
 public:
  InputFile(const std::uint8_t* data, std::size_t size, const std::string& name)
      : path_((scratch_folder() / name).string()) {
    if (std::FILE* f = std::fopen(path_.c_str(), "wb")) {
      if (size > 0) std::fwrite(data, 1, size, f);
      std::fclose(f);
    }
  }
  ~InputFile() { std::remove(path_.c_str()); }
  InputFile(const InputFile&) = delete;
  InputFile& operator=(const InputFile&) = delete;
  const std::string& path() const { return path_; }

 private:
  std::string path_;
};

// A mesh file through load_mesh(), as `nmbake bake --low` reads it: the
// parallel block parser with small blocks (so lines straddle blocks) and
// the serial reference, which must agree (load.hpp: the same mesh and error
// whatever the tuning), parts, materials and (for inputs of odd length,
// read as for a vertex-color bake) colours included; then the bake's
// coordinate check.
inline int load_mesh_both_ways(const std::uint8_t* data, std::size_t size, const std::string& name) {
  const InputFile file(data, size, name);
  LoadOptions parallel;
  parallel.block_bytes = 64;
  parallel.keep_colors = size % 2 == 1;
  // One input in three as the high of a texture bake: corner UVs and the
  // MTL files it names.
  parallel.corner_uvs = parallel.material_defs = size % 3 == 0;
  LoadOptions serial;
  serial.serial = true;
  serial.keep_colors = parallel.keep_colors;
  serial.corner_uvs = serial.material_defs = parallel.corner_uvs;
  Mesh a, b;
  LoadStats stats;
  const Status sa = load_mesh(file.path(), parallel, a, stats);
  const Status sb = load_mesh(file.path(), serial, b, stats);
  if (sa.is_ok() != sb.is_ok() || sa.message() != sb.message() || a.positions != b.positions ||
      a.indices != b.indices || a.uvs != b.uvs || a.normals != b.normals || a.colors != b.colors ||
      a.parts != b.parts || a.materials != b.materials || a.corner_uvs != b.corner_uvs ||
      a.material_defs != b.material_defs) {
    std::abort();
  }
  if (sa.is_ok()) (void)check_coordinate_range(a, file.path());
  return 0;
}

}  // namespace nmbake::fuzz
