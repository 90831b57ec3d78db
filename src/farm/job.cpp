// Job files (TOML, through toml++) and the option words shared with the CLI.
#include "nmbake/job.hpp"
#include "nmbake/budget.hpp"
#include "nmbake/preset.hpp"

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <set>
#include <sstream>

#include <toml++/toml.h>

namespace nmbake {

namespace {

std::string where(const std::string& path, const toml::node& node) {
  const toml::source_region& src = node.source();
  return path + ":" + std::to_string(src.begin.line);
}

std::string resolve_path(const std::filesystem::path& folder, const std::string& p) {
  const std::filesystem::path path(p);
  return path.is_absolute() ? p : (folder / path).lexically_normal().string();
}

// Applies one key of [defaults] or [[bake]] to the options.
Status apply_key(const std::string& file, const std::filesystem::path& folder, const std::string& key,
                 const toml::node& value, bool in_bake, BakeJob& job) {
  BakeOptions& o = job.options;
  auto bad = [&](const std::string& why) { return Status::bad_input(where(file, value) + ": " + key + ": " + why); };
  auto get_string = [&](std::string& out) -> bool {
    if (auto s = value.value<std::string>()) {
      out = *s;
      return true;
    }
    return false;
  };
  auto get_int = [&](int& out) -> bool {
    if (auto i = value.value<std::int64_t>(); i && value.is_integer()) {
      if (*i < -2147483647 || *i > 2147483647) return false;
      out = static_cast<int>(*i);
      return true;
    }
    return false;
  };
  std::string text;
  if (key == "size") {
    int size = 0;
    if (!get_int(size)) return bad("expected an integer");
    o.width = o.height = size;
  } else if (key == "width") {
    if (!get_int(o.width)) return bad("expected an integer");
  } else if (key == "height") {
    if (!get_int(o.height)) return bad("expected an integer");
  } else if (key == "samples") {
    if (get_string(text)) {
      if (text != "adaptive") return bad("expected an integer or \"adaptive\"");
      o.adaptive = true;
    } else if (get_int(o.samples)) {
      o.adaptive = false;
    } else {
      return bad("expected an integer or \"adaptive\"");
    }
  } else if (key == "adaptive_max") {
    if (!get_int(o.adaptive_options.max_samples)) return bad("expected an integer");
  } else if (key == "padding") {
    if (!get_int(o.padding)) return bad("expected an integer");
  } else if (key == "space") {
    if (!get_string(text) || !parse_word(text, o.encode.space)) return bad("expected \"tangent\" or \"object\"");
  } else if (key == "green") {
    if (!get_string(text) || !parse_word(text, o.encode.green)) return bad("expected \"up\" or \"down\"");
  } else if (key == "hit") {
    if (!get_string(text) || !parse_word(text, o.rays.hit)) return bad("expected \"first\" or \"nearest\"");
  } else if (key == "high_normals") {
    if (!get_string(text) || !parse_word(text, o.encode.high_normals)) return bad("expected \"smooth\" or \"face\"");
  } else if (key == "cage_mode") {
    if (!get_string(text) || !parse_word(text, o.rays.cage_mode))
      return bad("expected \"banded\", \"averaged\" or \"interpolated\"");
  } else if (key == "edge_band") {
    if (!value.is_number() || !(*value.value<double>() >= 0.0 && *value.value<double>() <= 100.0))
      return bad("expected a number from 0 to 100");
    o.rays.edge_band = static_cast<float>(*value.value<double>());
  } else if (key == "retry_misses") {
    if (!get_string(text) || !parse_word(text, o.rays.retry_misses)) return bad("expected \"auto\", \"on\" or \"off\"");
  } else if (key == "build_quality") {
    if (!get_string(text) || !parse_word(text, o.build_quality)) return bad("expected \"low\", \"medium\" or \"high\"");
  } else if (key == "bvh") {
    if (!get_string(text) || !parse_word(text, o.bvh_memory)) return bad("expected \"auto\", \"fast\" or \"compact\"");
  } else if (key == "tangents") {
    if (!get_string(text) || (text != "mikktspace" && text != "file")) return bad("expected \"mikktspace\" or \"file\"");
    o.tangent_basis = text == "file" ? TangentBasis::file : TangentBasis::mikktspace;
  } else if (key == "uv_set") {
    if (!get_int(o.uv_set) || o.uv_set < 0 || o.uv_set > 7) return bad("expected an integer 0..7");
  } else if (key == "ignore_backfaces") {
    if (auto b = value.value<bool>(); b && value.is_boolean()) o.rays.ignore_backfaces = *b;
    else return bad("expected true or false");
  } else if (key == "front" || key == "back") {
    Distance d;
    if (value.is_number()) {
      const double v = *value.value<double>();
      if (!(v >= 0.0)) return bad("expected a distance >= 0");
      d.kind = Distance::Kind::absolute;
      d.value = static_cast<float>(v);
    } else if (!get_string(text) || !parse_distance(text, d)) {
      return bad("expected a number, \"N%\" or \"auto\"");
    }
    (key == "front" ? o.rays.front : o.rays.back) = d;
  } else if (key == "max_memory") {
    if (auto i = value.value<std::int64_t>(); i && value.is_integer() && *i > 0) {
      o.max_memory_bytes = static_cast<std::uint64_t>(*i);
    } else if (!get_string(text) || !parse_memory_size(text, o.max_memory_bytes)) {
      return bad("expected bytes, or a string such as \"8G\"");
    }
  } else if (key == "preset") {
    // Outputs as engines want them (preset.hpp): the preset is applied once
    // the bake's keys are all read (load_job_file), so green, bitangent, tbn
    // and blue given anywhere override it.
    EnginePreset preset;
    if (!get_string(text) || !find_engine_preset(text, preset)) return bad("expected one of " + engine_preset_names());
    o.preset = text;
  } else if (key == "bitangent") {
    if (!get_string(text) || !parse_word(text, o.encode.decode.bitangent)) return bad("expected \"pixel\" or \"vertex\"");
  } else if (key == "tbn") {
    if (!get_string(text) || !parse_word(kFrameRuleWords, text, o.encode.decode.unit_frame)) return bad("expected \"raw\" or \"normalized\"");
  } else if (key == "blue") {
    if (!get_string(text) || !parse_word(kBlueRuleWords, text, o.encode.decode.rebuild_blue)) return bad("expected \"stored\" or \"rebuilt\"");
  } else if (key == "dither") {
    if (auto b = value.value<bool>(); b && value.is_boolean()) o.dither = *b;
    else if (get_string(text) && (text == "on" || text == "off")) o.dither = text == "on";
    else return bad("expected \"on\", \"off\", true or false");
  } else if (key == "maps") {
    // maps = ["normal", "ao"] or "normal,ao"
    o.maps.clear();
    if (const toml::array* list = value.as_array()) {
      for (const toml::node& item : *list) {
        const auto name = item.value<std::string>();
        if (!name) return Status::bad_input(where(file, item) + ": maps: expected map names (strings)");
        if (const Status s = parse_map_list(*name, o.maps); !s) return Status::bad_input(where(file, item) + ": maps: " + s.message());
      }
      if (o.maps.empty()) return bad("expected at least one map");
    } else if (get_string(text)) {
      if (const Status s = parse_map_list(text, o.maps); !s) return bad(s.message());
    } else {
      return bad("expected a list of map names, e.g. [\"normal\", \"ao\"]");
    }
  } else if (key == "height_range" || key == "curvature_range") {
    float& range = key == "height_range" ? o.height_range : o.curvature_range;
    if (value.is_number() && *value.value<double>() > 0.0 && std::isfinite(*value.value<double>())) {
      range = static_cast<float>(*value.value<double>());
    } else if (get_string(text) && text == "auto") {
      range = 0.0f;
    } else {
      return bad("expected a number > 0 or \"auto\"");
    }
  } else if (key == "id_source") {
    if (!get_string(text) || !parse_word(text, o.id_source))
      return bad("expected \"auto\", \"part\" or \"material\"");
  } else if (key == "ao_rays" || key == "thickness_rays") {
    if (!get_int(key == "ao_rays" ? o.ao_rays : o.thickness_rays)) return bad("expected an integer");
  } else if (key == "ao_distance" || key == "thickness_distance") {
    Distance d;
    if (value.is_number()) {
      const double v = *value.value<double>();
      if (!(v > 0.0)) return bad("expected a distance > 0");
      d.kind = Distance::Kind::absolute;
      d.value = static_cast<float>(v);
    } else if (!get_string(text) || !parse_distance(text, d)) {
      return bad("expected a number, \"N%\" or \"auto\"");
    }
    (key == "ao_distance" ? o.ao_distance : o.thickness_distance) = d;
  } else if (key == "cage") {
    if (!get_string(text) || text.empty()) return bad("expected a path");
    o.cage_path = resolve_path(folder, text);
  } else if (in_bake && key == "name") {
    if (!get_string(job.name)) return bad("expected a string");
  } else if (in_bake && (key == "low" || key == "high" || key == "report" || key == "debug_dump")) {
    // "" would resolve to the job file's folder: caught here, by name.
    if (!get_string(text) || text.empty()) return bad("expected a path");
    const std::string p = resolve_path(folder, text);
    if (key == "low") o.low_path = p;
    else if (key == "high") o.high_path = p;
    else if (key == "report") job.report_path = p;
    else o.debug_dump_prefix = p;
  } else if (key == "cache") {
    if (!get_string(text) || text.empty()) return bad("expected a folder");
    job.cache_dir = resolve_path(folder, text);
  } else if (key == "match") {
    if (!get_string(text) || !parse_word(text, o.match.mode)) return bad("expected \"auto\", \"name\" or \"off\"");
  } else if (key == "unmatched") {
    if (!get_string(text) || !parse_word(text, o.match.unmatched)) return bad("expected \"error\" or \"all\"");
  } else if (key == "low_suffix" || key == "high_suffix" || key == "cage_suffix") {
    if (!get_string(text) || text.empty()) return bad("expected a non-empty string");
    (key == "low_suffix" ? o.match.low_suffix : key == "high_suffix" ? o.match.high_suffix : o.match.cage_suffix) = text;
  } else if (in_bake && key == "group") {
    // [[bake.group]] name = "..", low = ["body_low"], high = ["body_high", "bolts_high"]
    const toml::array* list = value.as_array();
    if (!list) return bad("expected [[bake.group]] tables");
    for (const toml::node& item : *list) {
      const toml::table* t = item.as_table();
      if (!t) return Status::bad_input(where(file, item) + ": group: expected a table with low = [..] and high = [..]");
      GroupSpec group;
      // As match_parts() names them: the name, else "group N".
      const auto label = [](const GroupSpec& spec, std::size_t number) {
        const std::string name =
            spec.name.empty() ? "group " + std::to_string(number) : printable_text(spec.name);
        return std::string("'").append(name).append("'");
      };
      const std::size_t number = o.match.groups.size() + 1;
      for (const auto& [group_key, group_value] : *t) {
        const std::string k(group_key.str());
        if (k == "name") {
          const auto name = group_value.value<std::string>();
          if (!name) return Status::bad_input(where(file, group_value) + ": group: name: expected a string");
          group.name = *name;
        } else if (k == "low" || k == "high") {
          const toml::array* names = group_value.as_array();
          if (!names || names->empty()) {
            return Status::bad_input(where(file, group_value) + ": group: " + k + ": expected a non-empty list of part names");
          }
          for (const toml::node& n : *names) {
            const auto name = n.value<std::string>();
            if (!name) return Status::bad_input(where(file, n) + ": group: " + k + ": expected part names (strings)");
            (k == "low" ? group.low : group.high).push_back(*name);
          }
        } else {
          return Status::bad_input(where(file, group_value) + ": group: unknown key \"" + k + "\" (name, low, high)");
        }
      }
      if (group.low.empty() || group.high.empty()) {
        return Status::bad_input(where(file, item) + ": group needs low = [..] and high = [..]");
      }
      // Checked after the loop, which sees the keys in name order ("name"
      // last), so that the message can name the group.
      for (const auto& [k, parts] : {std::pair{"low", &group.low}, std::pair{"high", &group.high}}) {
        for (auto it = parts->begin(); it != parts->end(); ++it) {
          if (std::find(parts->begin(), it, *it) != it) {
            return Status::bad_input(where(file, item) + ": group " + label(group, number) + ": " + k +
                                     " part '" + printable_text(*it) + "' is listed twice");
          }
        }
      }
      // A low part's rays search one group's high parts: one group a low
      // part (a high part may serve several).
      for (std::size_t e = 0; e < o.match.groups.size(); ++e) {
        const GroupSpec& earlier = o.match.groups[e];
        for (const std::string& name : group.low) {
          if (std::find(earlier.low.begin(), earlier.low.end(), name) != earlier.low.end()) {
            return Status::bad_input(where(file, item) + ": low part '" + printable_text(name) +
                                     "' is in two groups (" + label(earlier, e + 1) + " and " +
                                     label(group, number) + ")");
          }
        }
      }
      o.match.groups.push_back(std::move(group));
    }
  } else if (in_bake && key == "outputs") {
    const toml::array* list = value.as_array();
    if (!list) return bad("expected a list of paths or { path = .., format = .. } tables");
    for (const toml::node& item : *list) {
      OutputSpec out;
      std::string path, format;
      if (auto s = item.value<std::string>()) {
        path = *s;
      } else if (const toml::table* t = item.as_table()) {
        if (auto p = (*t)["path"].value<std::string>()) path = *p;
        if (auto f = (*t)["format"].value<std::string>()) format = *f;
      }
      if (path.empty()) return Status::bad_input(where(file, item) + ": outputs: each output needs a path");
      out.path = resolve_path(folder, path);
      const bool ok = format.empty() ? pixel_format_from_path(out.path, out.format) : parse_word(format, out.format);
      out.format_given = !format.empty();
      if (!ok) {
        return Status::bad_input(where(file, item) + ": outputs: " +
                                 (format.empty() ? "unknown image extension of " + path + " (use .png, .tif, .tiff, .exr, .tga)"
                                                 : "unknown format \"" + format + "\" (png8, png16, tiff16, exr-half, exr-float, exr-float-piz, tga)"));
      }
      o.outputs.push_back(out);
    }
  } else {
    return Status::bad_input(where(file, value) + ": unknown key \"" + printable_text(key) + "\"" +
                             (in_bake ? std::string() : std::string(" in [defaults]")));
  }
  return Status::ok();
}

}  // namespace

Status load_job_file(const std::string& path, std::vector<BakeJob>& jobs) {
  jobs.clear();
  toml::table root;
  try {
    root = toml::parse_file(path);
  } catch (const toml::parse_error& e) {
    const auto& src = e.source();
    // toml++ quotes the offending bytes of the file: escaped before printing.
    const std::string message = printable_text(e.description());
    if (src.begin.line == 0) return Status::bad_input(path + ": cannot read the job file: " + message);
    return Status::bad_input(path + ":" + std::to_string(src.begin.line) + ": " + message);
  }
  const std::filesystem::path folder = std::filesystem::path(path).parent_path();

  BakeJob defaults;
  const toml::table* defaults_table = root["defaults"].as_table();
  for (const auto& [key, value] : root) {
    const std::string k(key.str());
    if (k != "defaults" && k != "bake") {
      return Status::bad_input(where(path, value) + ": unknown top-level key \"" + printable_text(k) +
                               "\" (expected [defaults] and [[bake]])");
    }
  }
  if (const toml::node_view d = root["defaults"]) {
    const toml::table* table = d.as_table();
    if (!table) return Status::bad_input(path + ": [defaults] must be a table");
    for (const auto& [key, value] : *table) NMBAKE_TRY(apply_key(path, folder, std::string(key.str()), value, false, defaults));
  }
  const toml::array* bakes = root["bake"].as_array();
  if (!bakes || bakes->empty()) return Status::bad_input(path + ": no [[bake]] entries");
  int index = 0;
  for (const toml::node& node : *bakes) {
    ++index;
    const toml::table* table = node.as_table();
    if (!table) return Status::bad_input(where(path, node) + ": each [[bake]] must be a table");
    BakeJob job = defaults;
    job.name = "bake " + std::to_string(index);
    for (const auto& [key, value] : *table) NMBAKE_TRY(apply_key(path, folder, std::string(key.str()), value, true, job));
    if (!job.options.preset.empty()) {
      // Keys given in [defaults] or this [[bake]] keep their values.
      const auto given = [&](const char* key) {
        return table->contains(key) || (defaults_table != nullptr && defaults_table->contains(key));
      };
      EnginePreset preset;
      NMBAKE_CHECK(find_engine_preset(job.options.preset, preset), "preset checked when read");
      apply_engine_preset(preset, {given("green"), given("bitangent"), given("tbn"), given("blue")}, job.options.encode.green,
                          job.options.encode.decode);
    }
    if (job.options.low_path.empty() || job.options.high_path.empty() || job.options.outputs.empty()) {
      return Status::bad_input(where(path, node) + ": [[bake]] \"" + job.name + "\" needs low, high and outputs");
    }
    jobs.push_back(std::move(job));
  }
  return Status::ok();
}

}  // namespace nmbake
