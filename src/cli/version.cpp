// `nmbake --version`: the version, the commit it was built from and the
// versions of the libraries it runs with (asked of the libraries loaded, not
// of the headers it was compiled against, where a library can say).
#include <tbb/version.h>

#include <string>

#include "commands.hpp"
#include "nmbake/image.hpp"
#include "nmbake/load.hpp"
#include "nmbake/task.hpp"
#include "nmbake/trace.hpp"

namespace nmbake::cli {

extern const char* const kBuildCommit;  // generated: build_info.cpp

std::string version_text() {
  std::string text = "nmbake ";
  text.append(kNmbakeVersion).append(" (commit ").append(kBuildCommit).append(")\n");
  std::string module_file, module_error;
  const std::string oiio = openimageio_version(module_file, module_error);
  text.append("  Embree       ").append(embree_version()).append("\n");
  text.append("  OpenImageIO  ");
  if (oiio.empty()) {
    text.append("not loaded: ").append(module_error).append("\n");
  } else {
    text.append(oiio).append(" (image module ").append(module_file).append(")\n");
  }
  text.append("  Assimp       ").append(assimp_version()).append("\n");
  text.append("  tinygltf     ").append(tinygltf_version()).append(" (compiled in)\n");
  text.append("  oneTBB       ").append(TBB_runtime_version());
  return text;
}

}  // namespace nmbake::cli
