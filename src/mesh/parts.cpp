// Parts into bake groups (parts.hpp): explicit groups, or names matched by
// suffix as Substance's "match by mesh name" does.
#include "nmbake/parts.hpp"

#include <algorithm>
#include <cctype>
#include <map>
#include <string_view>

namespace nmbake {

namespace {

bool ends_with_nocase(std::string_view name, std::string_view suffix) {
  if (suffix.empty() || name.size() <= suffix.size()) return false;  // the base must not be empty
  const std::string_view tail = name.substr(name.size() - suffix.size());
  for (std::size_t i = 0; i < suffix.size(); ++i) {
    if (std::tolower(static_cast<unsigned char>(tail[i])) !=
        std::tolower(static_cast<unsigned char>(suffix[i]))) {
      return false;
    }
  }
  return true;
}

// "X_high" -> "X"; "X_high_2", "X_high.001" -> "X"; false when the name is
// none of these.
bool high_base(std::string_view name, std::string_view suffix, std::string& base) {
  if (ends_with_nocase(name, suffix)) {
    base = std::string(name.substr(0, name.size() - suffix.size()));
    return true;
  }
  std::size_t end = name.size();
  while (end > 0 && std::isdigit(static_cast<unsigned char>(name[end - 1]))) --end;
  if (end == name.size() || end == 0 || (name[end - 1] != '_' && name[end - 1] != '.')) return false;
  const std::string_view stem = name.substr(0, end - 1);
  if (!ends_with_nocase(stem, suffix)) return false;
  base = std::string(stem.substr(0, stem.size() - suffix.size()));
  return true;
}

// The parts of a mesh, or one unnamed part covering it.
std::vector<MeshPart> parts_of(const Mesh& mesh) {
  if (!mesh.parts.empty()) return mesh.parts;
  return {MeshPart{"", 0, static_cast<std::uint32_t>(mesh.triangle_count())}};
}

// Distinct names in file order.
std::vector<std::string> distinct_names(const std::vector<MeshPart>& parts) {
  std::vector<std::string> names;
  for (const MeshPart& p : parts) {
    if (std::find(names.begin(), names.end(), p.name) == names.end()) names.push_back(p.name);
  }
  return names;
}

std::string quoted_list(const std::vector<std::string>& names) {
  std::string text;
  for (std::size_t i = 0; i < names.size(); ++i) {
    if (i > 0) text += ", ";
    text += "'" + names[i] + "'";
  }
  return text;
}

constexpr std::uint32_t kNoGroup = 0xffffffffu;

}  // namespace

Status check_low_parts(const Mesh& low, const MatchOptions& options, const std::string& low_path) {
  const std::vector<std::string> low_names = distinct_names(parts_of(low));
  if (!options.groups.empty()) {
    std::map<std::string, std::size_t> low_to_group;  // low part -> the group that lists it
    for (std::size_t g = 0; g < options.groups.size(); ++g) {
      const GroupSpec& spec = options.groups[g];
      const std::string group = spec.name.empty() ? "group " + std::to_string(g + 1) : spec.name;
      for (const std::string& name : spec.low) {
        if (std::find(low_names.begin(), low_names.end(), name) == low_names.end()) {
          return Status::bad_input(low_path + ": group '" + group + "' names low part '" + name +
                                   "', which the file does not have (parts: " + quoted_list(low_names) + ")");
        }
        const auto [it, added] = low_to_group.emplace(name, g);
        if (!added) {
          if (it->second == g) {
            return Status::bad_input(low_path + ": group '" + group + "' lists low part '" + name +
                                     "' twice");
          }
          const GroupSpec& first = options.groups[it->second];
          const std::string first_name =
              first.name.empty() ? "group " + std::to_string(it->second + 1) : first.name;
          return Status::bad_input(low_path + ": low part '" + name + "' is in two groups ('" + first_name +
                                   "' and '" + group + "')");
        }
      }
    }
    return Status::ok();
  }
  if (options.mode == MatchMode::name &&
      std::none_of(low_names.begin(), low_names.end(),
                   [&](const std::string& name) { return ends_with_nocase(name, options.low_suffix); })) {
    return Status::bad_input(low_path + ": --match name: no low part ends in '" + options.low_suffix +
                             "' (parts: " + quoted_list(low_names) + ")");
  }
  return Status::ok();
}

Status match_parts(const Mesh& low, const Mesh& high, const MatchOptions& options,
                   const std::string& low_path, const std::string& high_path, BakeGroups& out) {
  out = BakeGroups{};
  NMBAKE_TRY(check_low_parts(low, options, low_path));
  const std::vector<MeshPart> low_parts = parts_of(low);
  const std::vector<MeshPart> high_parts = parts_of(high);
  const std::vector<std::string> low_names = distinct_names(low_parts);
  const std::vector<std::string> high_names = distinct_names(high_parts);

  // Group membership by distinct name: low name -> group, high name -> groups.
  std::vector<BakeGroup> groups;
  std::map<std::string, std::uint32_t> low_to_group;
  std::map<std::string, std::vector<std::uint32_t>> high_to_groups;

  if (!options.groups.empty()) {
    for (const GroupSpec& spec : options.groups) {
      const auto g = static_cast<std::uint32_t>(groups.size());
      BakeGroup group;
      group.name = spec.name.empty() ? "group " + std::to_string(g + 1) : spec.name;
      for (const std::string& name : spec.low) {  // each a low part, in one group (check_low_parts)
        low_to_group[name] = g;
        group.low_parts.push_back(name);
      }
      for (const std::string& name : spec.high) {
        if (std::find(high_names.begin(), high_names.end(), name) == high_names.end()) {
          return Status::bad_input(high_path + ": group '" + group.name + "' names high part '" + name +
                                   "', which the file does not have (parts: " + quoted_list(high_names) +
                                   ")");
        }
        // A high part may serve several groups, but once each.
        std::vector<std::uint32_t>& in = high_to_groups[name];
        if (std::find(in.begin(), in.end(), g) != in.end()) {
          return Status::bad_input(high_path + ": group '" + group.name + "' lists high part '" + name +
                                   "' twice");
        }
        in.push_back(g);
        group.high_parts.push_back(name);
      }
      groups.push_back(std::move(group));
    }
  } else {
    bool any_suffixed = false;
    for (const std::string& name : low_names) any_suffixed |= ends_with_nocase(name, options.low_suffix);
    if (options.mode == MatchMode::off || !any_suffixed) return Status::ok();  // one group of everything
    // Groups in the order their low parts first appear.
    std::map<std::string, std::uint32_t> base_to_group;
    for (const std::string& name : low_names) {
      if (!ends_with_nocase(name, options.low_suffix)) continue;
      const std::string base = name.substr(0, name.size() - options.low_suffix.size());
      auto [it, added] = base_to_group.emplace(base, static_cast<std::uint32_t>(groups.size()));
      if (added) groups.push_back(BakeGroup{base, {}, {}, 0, 0});
      groups[it->second].low_parts.push_back(name);
      low_to_group[name] = it->second;
    }
    for (const std::string& name : high_names) {
      std::string base;
      if (!high_base(name, options.high_suffix, base)) continue;
      const auto it = base_to_group.find(base);
      if (it == base_to_group.end()) continue;
      high_to_groups[name].push_back(it->second);
      groups[it->second].high_parts.push_back(name);
    }
    // A suffixed low part whose base has no high part is unmatched too.
    std::vector<BakeGroup> kept;
    std::vector<std::uint32_t> renumber(groups.size(), kNoGroup);
    for (std::uint32_t g = 0; g < groups.size(); ++g) {
      if (groups[g].high_parts.empty()) continue;
      renumber[g] = static_cast<std::uint32_t>(kept.size());
      kept.push_back(std::move(groups[g]));
    }
    groups = std::move(kept);
    for (auto it = low_to_group.begin(); it != low_to_group.end();) {
      if (renumber[it->second] == kNoGroup) {
        it = low_to_group.erase(it);
      } else {
        it->second = renumber[it->second];
        ++it;
      }
    }
    for (auto& [name, in] : high_to_groups) {
      for (std::uint32_t& g : in) g = renumber[g];
    }
  }

  std::vector<std::string> unmatched;
  for (const std::string& name : low_names) {
    if (low_to_group.find(name) == low_to_group.end()) unmatched.push_back(name.empty() ? "(unnamed)" : name);
  }
  std::vector<std::string> unused_high;
  for (const std::string& name : high_names) {
    if (high_to_groups.find(name) == high_to_groups.end()) unused_high.push_back(name);
  }
  if (!unmatched.empty()) {
    if (options.unmatched == Unmatched::error) {
      return Status::bad_input(
          low_path + ": low parts with no high part to bake from: " + quoted_list(unmatched) +
          " (high parts: " + quoted_list(high_names) + "; name them X" + options.low_suffix + " / X" +
          options.high_suffix + ", list them in a group, or pass --unmatched all)");
    }
    if (unused_high.empty()) {
      return Status::bad_input(high_path +
                               ": --unmatched all: every high part is in a group, none is left for " +
                               quoted_list(unmatched));
    }
    const auto g = static_cast<std::uint32_t>(groups.size());
    BakeGroup rest{"(unmatched)", {}, unused_high, 0, 0};
    for (const std::string& name : low_names) {
      if (low_to_group.find(name) != low_to_group.end()) continue;
      low_to_group[name] = g;
      rest.low_parts.push_back(name);
    }
    for (const std::string& name : unused_high) high_to_groups[name].push_back(g);
    unused_high.clear();
    groups.push_back(std::move(rest));
  }

  out.low_group.assign(low.triangle_count(), kNoGroup);
  for (const MeshPart& part : low_parts) {
    const std::uint32_t g = low_to_group.at(part.name);
    std::fill_n(out.low_group.begin() + part.first_triangle, part.triangle_count, g);
    groups[g].low_triangles += part.triangle_count;
  }
  out.high_triangles.assign(groups.size(), {});
  for (const MeshPart& part : high_parts) {
    const auto it = high_to_groups.find(part.name);
    if (it == high_to_groups.end()) continue;
    for (const std::uint32_t g : it->second) {
      for (std::uint32_t t = 0; t < part.triangle_count; ++t)
        out.high_triangles[g].push_back(part.first_triangle + t);
      groups[g].high_triangles += part.triangle_count;
    }
  }
  for (std::size_t g = 0; g < groups.size(); ++g) {
    if (groups[g].low_triangles == 0) {
      return Status::bad_input(low_path + ": group '" + groups[g].name + "' has no low part");
    }
    if (groups[g].high_triangles == 0) {
      return Status::bad_input(high_path + ": group '" + groups[g].name + "' has no high part");
    }
  }
  out.groups = std::move(groups);
  out.unused_high_parts = std::move(unused_high);
  // One group of every low and every high triangle is no grouping at all.
  if (out.groups.size() == 1 && out.groups[0].high_triangles == high.triangle_count() &&
      out.unused_high_parts.empty()) {
    out = BakeGroups{};
  }
  return Status::ok();
}

Status order_cage_by_parts(const Mesh& low, const MatchOptions& options, const std::string& cage_path,
                           Mesh& cage) {
  const bool named =
      std::any_of(cage.parts.begin(), cage.parts.end(), [](const MeshPart& p) { return !p.name.empty(); });
  if (low.parts.empty() || !named) return Status::ok();
  // Unused ranges of each cage name, in file order.
  std::map<std::string, std::vector<const MeshPart*>> ranges;
  for (const MeshPart& part : cage.parts) ranges[part.name].push_back(&part);
  std::map<std::string, std::size_t> taken;
  std::vector<std::uint32_t> indices;
  indices.reserve(cage.indices.size());
  for (const MeshPart& part : low.parts) {
    std::string wanted = part.name;
    if (ranges.find(wanted) == ranges.end() && ends_with_nocase(part.name, options.low_suffix)) {
      const std::string base = part.name.substr(0, part.name.size() - options.low_suffix.size());
      for (const auto& [name, list] : ranges) {
        if (ends_with_nocase(name, options.cage_suffix) &&
            name.compare(0, name.size() - options.cage_suffix.size(), base) == 0 &&
            name.size() - options.cage_suffix.size() == base.size()) {
          wanted = name;
          break;
        }
      }
    }
    const auto it = ranges.find(wanted);
    std::size_t& k = taken[wanted];
    if (it == ranges.end() || k >= it->second.size()) {
      return Status::bad_input(
          cage_path + ": no cage part for low part '" + part.name + "' (expected '" +
          (ends_with_nocase(part.name, options.low_suffix)
               ? part.name.substr(0, part.name.size() - options.low_suffix.size()) + options.cage_suffix
               : part.name) +
          "')");
    }
    const MeshPart& cage_part = *it->second[k++];
    if (cage_part.triangle_count != part.triangle_count) {
      return Status::bad_input(cage_path + ": cage part '" + cage_part.name + "' has " +
                               std::to_string(cage_part.triangle_count) + " triangles, low part '" +
                               part.name + "' has " + std::to_string(part.triangle_count));
    }
    indices.insert(indices.end(),
                   cage.indices.begin() + 3 * static_cast<std::ptrdiff_t>(cage_part.first_triangle),
                   cage.indices.begin() +
                       3 * static_cast<std::ptrdiff_t>(cage_part.first_triangle + cage_part.triangle_count));
  }
  for (const auto& [name, list] : ranges) {
    if (taken[name] < list.size()) {
      return Status::bad_input(cage_path + ": cage part '" + name + "' belongs to no low part");
    }
  }
  cage.indices = std::move(indices);
  // Reordered: the ranges no longer match (and the cage needs none).
  cage.parts.clear();
  cage.materials.clear();
  return Status::ok();
}

std::vector<std::uint32_t> group_high_indices(const Mesh& high, const BakeGroups& groups,
                                              std::vector<std::uint32_t>& first) {
  std::vector<std::uint32_t> indices;
  std::size_t total = 0;
  for (const auto& triangles : groups.high_triangles) total += triangles.size();
  indices.reserve(3 * total);
  first.assign(1, 0);
  for (const auto& triangles : groups.high_triangles) {
    for (const std::uint32_t t : triangles) {
      indices.insert(indices.end(), high.indices.begin() + 3 * static_cast<std::ptrdiff_t>(t),
                     high.indices.begin() + 3 * static_cast<std::ptrdiff_t>(t) + 3);
    }
    first.push_back(static_cast<std::uint32_t>(indices.size() / 3));
  }
  return indices;
}

}  // namespace nmbake
