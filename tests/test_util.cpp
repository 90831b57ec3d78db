#include "test_util.hpp"

#include <sys/wait.h>
#include <unistd.h>

#include <algorithm>
#include <array>
#include <atomic>
#include <charconv>
#include <cstdio>
#include <fstream>
#include <random>
#include <stdexcept>

#include "nmbake/bake.hpp"
#include "nmbake/task.hpp"

namespace nmbake::test {

LowSurface low_quad() {
  LowSurface s;
  const glm::vec3 p[4] = {{0, 0, 0}, {1, 0, 0}, {1, 1, 0}, {0, 1, 0}};
  for (int c : {0, 1, 2, 0, 2, 3}) {
    s.position.push_back(p[c]);
    s.uv.push_back({p[c].x, p[c].y});
    s.normal.push_back({0, 0, 1});
    s.cage_normal.push_back({0, 0, 1});
    s.tangent.push_back({1, 0, 0, 1});
  }
  return s;
}

TempDir::TempDir() {
  static std::atomic<int> counter{0};
  const auto base = std::filesystem::temp_directory_path();
  for (int attempt = 0; attempt < 1000; ++attempt) {
    auto candidate = base / ("nmbake_test_" + std::to_string(::getpid()) + "_" + std::to_string(counter++));
    if (std::filesystem::create_directory(candidate)) {
      path_ = candidate;
      return;
    }
  }
  throw std::runtime_error("cannot create a temporary directory");
}

TempDir::~TempDir() {
  std::error_code ignored;
  std::filesystem::remove_all(path_, ignored);
}

void write_text(const std::string& path, const std::string& text) {
  std::ofstream out(path, std::ios::binary | std::ios::trunc);
  out << text;
}

CommandResult run_command(const std::string& command_line) {
  CommandResult result;
  const std::string full = command_line + " 2>&1";
  FILE* pipe = ::popen(full.c_str(), "r");
  if (!pipe) return result;
  std::array<char, 4096> buffer{};
  size_t n = 0;
  while ((n = std::fread(buffer.data(), 1, buffer.size(), pipe)) > 0) result.output.append(buffer.data(), n);
  const int status = ::pclose(pipe);
  result.exit_code = WIFEXITED(status) ? WEXITSTATUS(status) : -1;
  return result;
}

std::string collada_text(const Mesh& mesh) {
  std::string out;
  const auto reals = [&](const float* values, std::size_t count) {
    char digits[32];
    for (std::size_t i = 0; i < count; ++i) {
      const auto end = std::to_chars(digits, digits + sizeof digits, values[i]).ptr;
      if (i > 0) out += ' ';
      out.append(digits, end);
    }
  };
  const auto source = [&](const char* id, const float* values, std::size_t elements, const char* params) {
    const std::size_t stride = std::string(params).size();
    out += std::string("<source id=\"") + id + "\"><float_array id=\"" + id + "-a\" count=\"" +
           std::to_string(elements * stride) + "\">";
    reals(values, elements * stride);
    out += std::string("</float_array><technique_common><accessor source=\"#") + id + "-a\" count=\"" +
           std::to_string(elements) + "\" stride=\"" + std::to_string(stride) + "\">";
    for (const char* p = params; *p != 0; ++p)
      out += std::string("<param name=\"") + *p + "\" type=\"float\"/>";
    out += "</accessor></technique_common></source>\n";
  };
  std::vector<MeshPart> ranges = mesh.materials;
  if (ranges.empty()) ranges.push_back({"", 0, static_cast<std::uint32_t>(mesh.triangle_count())});
  std::vector<std::string> names;
  for (const MeshPart& r : ranges) {
    if (!r.name.empty() && std::find(names.begin(), names.end(), r.name) == names.end())
      names.push_back(r.name);
  }
  const auto index_of = [&](const std::string& name) {
    return std::to_string(std::find(names.begin(), names.end(), name) - names.begin());
  };
  out +=
      "<?xml version=\"1.0\" encoding=\"utf-8\"?>\n"
      "<COLLADA xmlns=\"http://www.collada.org/2005/11/COLLADASchema\" version=\"1.4.1\">\n"
      "<asset><unit name=\"meter\" meter=\"1\"/><up_axis>Y_UP</up_axis></asset>\n"
      "<library_effects><effect id=\"fx\"><profile_COMMON><technique sid=\"t\"><lambert/></technique>"
      "</profile_COMMON></effect></library_effects>\n<library_materials>\n";
  for (const std::string& name : names) {
    out += "<material id=\"m" + index_of(name) + "\" name=\"" + name +
           "\"><instance_effect url=\"#fx\"/></material>\n";
  }
  out += "</library_materials>\n<library_geometries><geometry id=\"g\" name=\"g\"><mesh>\n";
  source("pos", &mesh.positions[0].x, mesh.vertex_count(), "XYZ");
  if (mesh.has_normals()) source("nrm", &mesh.normals[0].x, mesh.vertex_count(), "XYZ");
  if (mesh.has_colors()) source("col", &mesh.colors[0].x, mesh.vertex_count(), "RGBA");
  out += "<vertices id=\"v\"><input semantic=\"POSITION\" source=\"#pos\"/></vertices>\n";
  for (const MeshPart& r : ranges) {
    out += "<triangles count=\"" + std::to_string(r.triangle_count) + "\"";
    if (!r.name.empty()) out += " material=\"s" + index_of(r.name) + "\"";
    out += "><input semantic=\"VERTEX\" source=\"#v\" offset=\"0\"/>";
    if (mesh.has_normals()) out += "<input semantic=\"NORMAL\" source=\"#nrm\" offset=\"0\"/>";
    if (mesh.has_colors()) out += "<input semantic=\"COLOR\" source=\"#col\" offset=\"0\"/>";
    out += "<p>";
    for (std::size_t i = 3 * std::size_t{r.first_triangle};
         i < 3 * std::size_t{r.first_triangle + r.triangle_count}; ++i) {
      out += std::to_string(mesh.indices[i]) + " ";
    }
    out += "</p></triangles>\n";
  }
  out +=
      "</mesh></geometry></library_geometries>\n<library_visual_scenes><visual_scene id=\"s\"><node "
      "id=\"mesh\" "
      "name=\"mesh\"><instance_geometry url=\"#g\"><bind_material><technique_common>";
  for (const std::string& name : names) {
    out += "<instance_material symbol=\"s" + index_of(name) + "\" target=\"#m" + index_of(name) + "\"/>";
  }
  out +=
      "</technique_common></bind_material></instance_geometry></node></visual_scene></"
      "library_visual_scenes>\n"
      "<scene><instance_visual_scene url=\"#s\"/></scene>\n</COLLADA>\n";
  return out;
}

std::string cli_path() { return NMBAKE_CLI_PATH; }
std::string gen_path() { return NMBAKE_GEN_PATH; }
std::string source_dir() { return NMBAKE_SOURCE_DIR; }

Status bake_tiles_and_merge(const BakeOptions& options, int count, const std::filesystem::path& folder,
                            const std::vector<OutputSpec>& outputs) {
  std::vector<std::string> tiles;
  for (int i = count - 1; i >= 0; --i) {
    BakeOptions tile = options;
    tile.tile_index = i;
    tile.tile_count = count;
    tile.tile_path = (folder / (std::to_string(i) + ".tile")).string();
    BakeReport report;
    NMBAKE_TRY(bake(tile, report));
    tiles.push_back(tile.tile_path);
  }
  MergeReport merged;
  return merge_tiles(tiles, outputs, merged);
}

}  // namespace nmbake::test
