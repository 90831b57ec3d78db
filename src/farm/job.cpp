// Job files (TOML, through toml++): their keys are the option table's
// (options.hpp), and a job's own (name, outputs, report, cache, groups).
#include "nmbake/job.hpp"

#include <toml++/toml.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <set>
#include <sstream>

#include "nmbake/options.hpp"

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

// A TOML value as the option table takes it (options.hpp).
bool option_value(const toml::node& node, const std::filesystem::path& folder, OptionValue& out) {
  out = OptionValue{};
  out.folder = folder.string();
  if (auto s = node.value_exact<std::string>()) {
    out.text = *s;
  } else if (auto i = node.value_exact<std::int64_t>()) {
    out.kind = OptionValue::Kind::integer;
    out.integer = *i;
  } else if (auto d = node.value_exact<double>()) {
    out.kind = OptionValue::Kind::number;
    out.number = *d;
  } else if (auto b = node.value_exact<bool>()) {
    out.kind = OptionValue::Kind::boolean;
    out.boolean = *b;
  } else if (const toml::array* list = node.as_array()) {
    out.kind = OptionValue::Kind::list;
    for (const toml::node& item : *list) {
      const auto word = item.value_exact<std::string>();
      if (!word) return false;
      out.list.push_back(*word);
    }
  } else {
    return false;
  }
  return true;
}

// [[bake.pack]] tables (file = "orm.png", r = "ao", g = "roughness", b =
// "metallic", a = 1) as the pack option's text ("orm.png=r:ao,g:roughness,
// b:metallic,a:1"), which the option table parses, as it does
// pack = ["..."]. False with `why` for a table of another shape.
bool pack_tables(const toml::array& tables, std::vector<std::string>& texts, std::string& why) {
  for (const toml::node& item : tables) {
    const toml::table* t = item.as_table();
    if (t == nullptr) return false;
    std::string file;
    std::string channel[4];  // r, g, b, a (TOML tables have no order)
    for (const auto& [k, v] : *t) {
      const std::string key(k.str());
      std::string value;
      if (auto s = v.value_exact<std::string>()) {
        value = *s;
      } else if (auto number = v.value<double>()) {
        char digits[32];
        std::snprintf(digits, sizeof digits, "%.17g", *number);
        value = digits;
      } else {
        why = "pack: " + key + ": expected a map name or a number";
        return false;
      }
      if (key == "file") {
        file = value;
      } else if (key == "r" || key == "g" || key == "b" || key == "a") {
        channel[key == "r" ? 0 : key == "g" ? 1 : key == "b" ? 2 : 3] = key + ":" + value;
      } else {
        why = "pack: unknown key \"" + key + "\" (file, r, g, b, a)";
        return false;
      }
    }
    if (file.empty()) {
      why = "pack: a [[bake.pack]] table needs file = \"...\"";
      return false;
    }
    std::string channels;
    for (const std::string& c : channel) {
      if (!c.empty()) channels += (channels.empty() ? "" : ",") + c;
    }
    texts.push_back(file + "=" + channels);
  }
  return true;
}

// Reads one key of [defaults] or [[bake]]: an option of the table joins
// `given` (applied once the bake's keys are all read), the job's own keys
// (name, report, cache, outputs, groups) go to `job`.
Status apply_key(const std::string& file, const std::filesystem::path& folder, const std::string& key,
                 const toml::node& value, bool in_bake, BakeJob& job, std::vector<GivenOption>& given) {
  BakeOptions& o = job.options;
  auto bad = [&](const std::string& why) {
    return Status::bad_input(where(file, value) + ": " + key + ": " + why);
  };
  auto get_string = [&](std::string& out) -> bool {
    if (auto s = value.value<std::string>()) {
      out = *s;
      return true;
    }
    return false;
  };
  std::string text;
  if (const OptionSpec* spec = find_option(key); spec != nullptr && (in_bake || spec->in_defaults)) {
    GivenOption g{spec, {}, where(file, value) + ": " + key, false};
    const toml::array* tables = value.as_array();
    if (key == "pack" && tables != nullptr && !tables->empty() && tables->front().is_table()) {
      std::string why = "expected [[bake.pack]] tables";
      g.value.kind = OptionValue::Kind::list;
      g.value.folder = folder.string();
      if (!pack_tables(*tables, g.value.list, why)) return Status::bad_input(where(file, value) + ": " + why);
    } else if (!option_value(value, folder, g.value)) {
      // A value of no type the table reads (a table, a date, a list of numbers).
      const std::string words = spec->words();
      return bad("expected " + (words.empty() ? std::string(spec->value) : "one of: " + words));
    }
    given.push_back(std::move(g));
  } else if (in_bake && key == "name") {
    if (!get_string(job.name)) return bad("expected a string");
  } else if (in_bake && key == "report") {
    // "" would resolve to the job file's folder: caught here, by name.
    if (!get_string(text) || text.empty()) return bad("expected a path");
    job.report_path = resolve_path(folder, text);
  } else if (key == "cache") {
    if (!get_string(text) || text.empty()) return bad("expected a folder");
    job.cache_dir = resolve_path(folder, text);
  } else if (in_bake && key == "group") {
    // [[bake.group]] name = "..", low = ["body_low"], high = ["body_high", "bolts_high"]
    const toml::array* list = value.as_array();
    if (!list) return bad("expected [[bake.group]] tables");
    for (const toml::node& item : *list) {
      const toml::table* t = item.as_table();
      if (!t)
        return Status::bad_input(where(file, item) +
                                 ": group: expected a table with low = [..] and high = [..]");
      GroupSpec group;
      // As match_parts() names them: the name, else "group N".
      const auto label = [](const GroupSpec& named, std::size_t number) {
        const std::string name =
            named.name.empty() ? "group " + std::to_string(number) : printable_text(named.name);
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
            return Status::bad_input(where(file, group_value) + ": group: " + k +
                                     ": expected a non-empty list of part names");
          }
          for (const toml::node& n : *names) {
            const auto name = n.value<std::string>();
            if (!name)
              return Status::bad_input(where(file, n) + ": group: " + k + ": expected part names (strings)");
            (k == "low" ? group.low : group.high).push_back(*name);
          }
        } else {
          return Status::bad_input(where(file, group_value) + ": group: unknown key \"" + k +
                                   "\" (name, low, high)");
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
      const bool ok =
          format.empty() ? pixel_format_from_path(out.path, out.format) : parse_word(format, out.format);
      out.format_given = !format.empty();
      if (!ok) {
        return Status::bad_input(
            where(file, item) + ": outputs: " +
            (format.empty() ? "unknown image extension of " + path + " (use .png, .tif, .tiff, .exr, .tga)"
                            : "unknown format \"" + format +
                                  "\" (png8, png16, tiff16, exr-half, exr-float, exr-float-piz, tga)"));
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
  std::vector<GivenOption> defaults_given;
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
    for (const auto& [key, value] : *table) {
      NMBAKE_TRY(apply_key(path, folder, std::string(key.str()), value, false, defaults, defaults_given));
    }
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
    // The options of [defaults], then the bake's own (a preset first, so
    // that green, bitangent, tbn and blue given anywhere override it).
    std::vector<GivenOption> given = defaults_given;
    for (const auto& [key, value] : *table) {
      NMBAKE_TRY(apply_key(path, folder, std::string(key.str()), value, true, job, given));
    }
    NMBAKE_TRY(apply_options(given, job.options));
    resolve_low_token(job.options);
    if (const Status s = validate_option_values(job.options); !s) {
      return Status::bad_input(where(path, node) + ": [[bake]] \"" + printable_text(job.name) +
                               "\": " + s.message());
    }
    if (job.options.low_path.empty() || job.options.high_paths.empty() || job.options.outputs.empty()) {
      return Status::bad_input(where(path, node) + ": [[bake]] \"" + job.name +
                               "\" needs low, high and outputs");
    }
    jobs.push_back(std::move(job));
  }
  return Status::ok();
}

}  // namespace nmbake
