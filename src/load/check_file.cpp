// What can be known of a mesh file without loading it (load.hpp,
// check_mesh_file): its path, its kind of file, and its first bytes.
#include <cctype>
#include <cerrno>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <string>
#include <string_view>

#include "nmbake/load.hpp"

namespace nmbake {

Status check_mesh_file(const char* what, const std::string& path) {
  if (path.empty()) return Status::bad_input(std::string("the ") + what + " mesh path is empty");
  if (path.find('\0') != std::string::npos) {
    return Status::bad_input(printable_text(path) + ": the " + what + " mesh path holds a NUL byte");
  }
  std::string extension = std::filesystem::path(path).extension().string();
  for (char& c : extension) c = static_cast<char>(std::tolower(static_cast<unsigned char>(c)));
  if (!mesh_extension_supported(path)) {
    return Status::bad_input(printable_text(path) + ": unknown mesh format '" + printable_text(extension) +
                             "' (expected " + supported_mesh_extensions() + ")");
  }
  std::error_code ec;
  const std::filesystem::file_status status = std::filesystem::status(path, ec);
  if (ec || !std::filesystem::exists(status)) {
    return Status::bad_input(printable_text(path) + ": the " + what + " mesh does not exist");
  }
  // A FIFO would block and a device (a link to /dev/zero) never ends.
  if (!std::filesystem::is_regular_file(status)) {
    return Status::bad_input(printable_text(path) + ": the " + what + " mesh is not a regular file");
  }
  std::FILE* file = std::fopen(path.c_str(), "rb");
  if (!file)
    return Status::bad_input(printable_text(path) + ": cannot open the " + what +
                             " mesh: " + std::strerror(errno));
  char head[4096];
  const std::size_t got = std::fread(head, 1, sizeof head, file);
  std::fclose(file);
  const std::string_view bytes(head, got);
  if (got == 0) return Status::bad_input(printable_text(path) + ": the " + what + " mesh is empty");
  if (extension == ".ply" && bytes.substr(0, 3) != "ply") {
    return Status::bad_input(printable_text(path) + ": not a PLY file (it does not start with \"ply\")");
  }
  if (extension == ".glb" && bytes.substr(0, 4) != "glTF") {
    return Status::bad_input(printable_text(path) +
                             ": not a binary glTF file (it does not start with \"glTF\")");
  }
  if (extension == ".obj" && bytes.find('\0') != std::string_view::npos) {
    return Status::bad_input(printable_text(path) + ": not an OBJ file (a NUL byte in its first " +
                             std::to_string(got) + " bytes: binary data)");
  }
  return Status::ok();
}

}  // namespace nmbake
