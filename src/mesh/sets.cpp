// Texture sets (sets.hpp): the low mesh's materials as map sets.
#include "nmbake/sets.hpp"

#include <algorithm>

namespace nmbake {

bool has_set_token(const std::string& path) { return path.find(kSetToken) != std::string::npos; }

std::string replace_token(const std::string& path, const std::string& token, const std::string& value) {
  std::string out = path;
  for (std::size_t at = out.find(token); at != std::string::npos; at = out.find(token, at)) {
    out.replace(at, token.size(), value);
    at += value.size();
  }
  return out;
}

namespace {

std::string path_name(const std::string& name) {
  if (name.empty()) return "default";
  std::string out = name;
  for (char& c : out) {
    const bool plain = (c >= 'a' && c <= 'z') || (c >= 'A' && c <= 'Z') || (c >= '0' && c <= '9') ||
                       c == '.' || c == '-' || c == '_';
    if (!plain) c = '_';
  }
  // "." and ".." would name folders.
  if (out.find_first_not_of('.') == std::string::npos) out[0] = '_';
  return out;
}

}  // namespace

Status find_low_sets(const Mesh& low, const std::string& low_path, std::vector<LowSet>& sets) {
  sets.clear();
  if (!low.has_named_materials()) {
    return Status::bad_input(printable_text(low_path) +
                             ": the output path holds <SET> (a map set per low material), but the low mesh "
                             "has no named materials (OBJ usemtl, glTF primitive materials, FBX and Collada "
                             "materials)");
  }
  for (const MeshPart& range : low.materials) {
    auto it = std::find_if(sets.begin(), sets.end(), [&](const LowSet& s) { return s.name == range.name; });
    if (it == sets.end()) {
      LowSet set;
      set.name = range.name;
      set.path_name = path_name(range.name);
      for (const LowSet& other : sets) {
        if (other.path_name == set.path_name) {
          return Status::bad_input(printable_text(low_path) + ": materials '" + printable_text(other.name) +
                                   "' and '" + printable_text(set.name) + "' both name the texture set '" +
                                   set.path_name + "' in a path (<SET>); rename one");
        }
      }
      set.triangles.assign(low.triangle_count(), 0);
      sets.push_back(std::move(set));
      it = sets.end() - 1;
    }
    std::fill_n(it->triangles.begin() + range.first_triangle, range.triangle_count, std::uint8_t{1});
  }
  return Status::ok();
}

}  // namespace nmbake
