// A live session's cache of the high side, and live requests' bakes: their
// keys go through the option table (options.hpp) as a job file's do.
#include "nmbake/session.hpp"

#include <filesystem>
#include <nlohmann/json.hpp>
#include <utility>
#include <vector>

#include "nmbake/options.hpp"
#include "nmbake/parts.hpp"

namespace nmbake {

namespace {

template <class T>
std::uint64_t array_bytes(const std::vector<T>& v) {
  return static_cast<std::uint64_t>(v.capacity()) * sizeof(T);
}

std::uint64_t mesh_bytes(const Mesh& m) {
  return array_bytes(m.positions) + array_bytes(m.normals) + array_bytes(m.uvs) + array_bytes(m.tangents) +
         array_bytes(m.colors) + array_bytes(m.indices) + array_bytes(m.corner_uvs) + array_bytes(m.parts) +
         array_bytes(m.materials);
}

constexpr std::uint64_t kBvhBytesPerTriangle = 64;

}  // namespace

std::uint64_t entry_bytes(const LoadedHigh& high) { return mesh_bytes(high.mesh); }

std::uint64_t entry_bytes(const BuiltHigh& high) {
  const MapMeshData& d = high.map_mesh;
  return mesh_bytes(high.mesh) + kBvhBytesPerTriangle * high.mesh.triangle_count() +
         array_bytes(d.vertex_curvature) + array_bytes(d.triangle_id) + array_bytes(d.id_colors) +
         array_bytes(d.transfer.triangle_material) + array_bytes(d.transfer.corner_uv) +
         array_bytes(d.transfer.uv_density) + array_bytes(d.transfer.corner_tangent);
}

std::list<HighCache::Entry>::iterator HighCache::find(const std::string& key) {
  for (auto it = entries_.begin(); it != entries_.end(); ++it) {
    if (it->key == key) {
      entries_.splice(entries_.begin(), entries_, it);  // most recently used
      return entries_.begin();
    }
  }
  return entries_.end();
}

std::shared_ptr<const LoadedHigh> HighCache::find_loaded(const std::string& key) {
  const auto it = find("loaded:" + key);
  return it == entries_.end() ? nullptr : it->loaded;
}

std::shared_ptr<const BuiltHigh> HighCache::find_built(const std::string& key) {
  const auto it = find("built:" + key);
  return it == entries_.end() ? nullptr : it->built;
}

void HighCache::keep_loaded(const std::string& key, std::shared_ptr<const LoadedHigh> high) {
  const std::uint64_t bytes = entry_bytes(*high);
  keep(Entry{"loaded:" + key, std::move(high), nullptr, bytes});
}

void HighCache::keep_built(const std::string& key, std::shared_ptr<const BuiltHigh> high) {
  const std::uint64_t bytes = entry_bytes(*high);
  keep(Entry{"built:" + key, nullptr, std::move(high), bytes});
}

void HighCache::keep(Entry entry) {
  if (auto old = find(entry.key); old != entries_.end()) {
    stats_.bytes -= old->bytes;
    entries_.erase(old);
  }
  stats_.bytes += entry.bytes;
  entries_.push_front(std::move(entry));
  // Least recently used out first; the newest entry stays even alone over
  // the budget (the bake holding it needs it anyway; the next one evicts it).
  while (stats_.bytes > stats_.budget && entries_.size() > 1) {
    stats_.bytes -= entries_.back().bytes;
    entries_.pop_back();
    ++stats_.evictions;
  }
  stats_.entries = entries_.size();
}

namespace {

std::string resolve_path(const std::string& folder, const std::string& p) {
  const std::filesystem::path path(p);
  if (path.is_absolute() || folder.empty()) return p;
  return (std::filesystem::path(folder) / path).lexically_normal().string();
}

// A JSON value as the option table takes it (options.hpp), as job files'
// TOML values are: strings, integers, numbers, booleans, lists of strings.
bool option_value(const nlohmann::json& v, const std::string& folder, OptionValue& out) {
  out = OptionValue{};
  out.folder = folder;
  if (v.is_string()) {
    out.text = v.get<std::string>();
  } else if (v.is_number_integer()) {
    out.kind = OptionValue::Kind::integer;
    out.integer = v.get<std::int64_t>();
    out.number = static_cast<double>(out.integer);
  } else if (v.is_number()) {
    out.kind = OptionValue::Kind::number;
    out.number = v.get<double>();
  } else if (v.is_boolean()) {
    out.kind = OptionValue::Kind::boolean;
    out.boolean = v.get<bool>();
  } else if (v.is_array()) {
    out.kind = OptionValue::Kind::list;
    for (const nlohmann::json& item : v) {
      if (!item.is_string()) return false;
      out.list.push_back(item.get<std::string>());
    }
  } else {
    return false;
  }
  return true;
}

Status parse_outputs(const nlohmann::json& value, const std::string& folder, BakeOptions& o) {
  const auto bad = [](const std::string& why) { return Status::bad_input("bake.outputs: " + why); };
  if (!value.is_array() || value.empty())
    return bad("expected a list of paths or {\"path\": .., \"format\": ..} objects");
  for (const nlohmann::json& item : value) {
    std::string path, format;
    if (item.is_string()) {
      path = item.get<std::string>();
    } else if (item.is_object()) {
      for (const auto& [k, v] : item.items()) {
        if ((k != "path" && k != "format") || !v.is_string())
          return bad("an output object takes \"path\" and \"format\" (strings)");
        (k == "path" ? path : format) = v.get<std::string>();
      }
    }
    if (path.empty()) return bad("each output needs a path");
    OutputSpec out;
    out.path = resolve_path(folder, path);
    const bool ok =
        format.empty() ? pixel_format_from_path(out.path, out.format) : parse_word(format, out.format);
    out.format_given = !format.empty();
    if (!ok) {
      return bad(format.empty()
                     ? "unknown image extension of " + path + " (use .png, .tif, .tiff, .exr, .tga)"
                     : "unknown format \"" + format + "\" (" + word_list<PixelFormat>(", ") + ")");
    }
    o.outputs.push_back(out);
  }
  return Status::ok();
}

Status parse_groups(const nlohmann::json& value, BakeOptions& o) {
  const auto bad = [](const std::string& why) { return Status::bad_input("bake.group: " + why); };
  if (!value.is_array()) return bad("expected a list of {\"name\", \"low\": [..], \"high\": [..]} objects");
  for (const nlohmann::json& item : value) {
    if (!item.is_object()) return bad("expected an object with low = [..] and high = [..]");
    GroupSpec group;
    for (const auto& [k, v] : item.items()) {
      if (k == "name" && v.is_string()) {
        group.name = v.get<std::string>();
      } else if ((k == "low" || k == "high") && v.is_array() && !v.empty()) {
        for (const nlohmann::json& n : v) {
          if (!n.is_string()) return bad(k + ": expected part names (strings)");
          (k == "low" ? group.low : group.high).push_back(n.get<std::string>());
        }
      } else {
        return bad("unexpected key \"" + printable_text(k) + "\" (name: a string; low, high: part names)");
      }
    }
    if (group.low.empty() || group.high.empty()) return bad("a group needs low and high part names");
    o.match.groups.push_back(std::move(group));
  }
  return Status::ok();
}

}  // namespace

Status request_bake_job(const nlohmann::json& bake, const std::string& folder, BakeJob& job) {
  job = BakeJob{};
  job.name = "bake";
  if (!bake.is_object()) return Status::bad_input("bake: expected an object of a job's [[bake]] keys");
  std::vector<GivenOption> given;
  for (const auto& [key, value] : bake.items()) {
    const std::string where = "bake." + printable_text(key);
    if (const OptionSpec* spec = find_option(key)) {
      GivenOption g{spec, {}, where, false};
      if (!option_value(value, folder, g.value)) {
        const std::string words = spec->words();
        return Status::bad_input(where + ": expected " +
                                 (words.empty() ? std::string(spec->value) : "one of: " + words));
      }
      given.push_back(std::move(g));
    } else if (key == "outputs") {
      NMBAKE_TRY(parse_outputs(value, folder, job.options));
    } else if (key == "name") {
      if (!value.is_string()) return Status::bad_input(where + ": expected a string");
      job.name = value.get<std::string>();
    } else if (key == "report") {
      if (!value.is_string() || value.get<std::string>().empty())
        return Status::bad_input(where + ": expected a path");
      job.report_path = resolve_path(folder, value.get<std::string>());
    } else if (key == "group") {
      NMBAKE_TRY(parse_groups(value, job.options));
    } else {
      return Status::bad_input("bake: unknown key \"" + printable_text(key) + "\"");
    }
  }
  NMBAKE_TRY(apply_options(given, job.options));
  resolve_low_token(job.options);
  NMBAKE_TRY(validate_option_values(job.options));
  if (job.options.low_path.empty()) return Status::bad_input("bake.low: missing (the low mesh)");
  if (job.options.high_paths.empty()) return Status::bad_input("bake.high: missing (the high mesh)");
  if (job.options.outputs.empty()) return Status::bad_input("bake.outputs: missing (the maps to write)");
  return Status::ok();
}

}  // namespace nmbake
