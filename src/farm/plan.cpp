// `nmbake plan` (plan.hpp): tasks of a job file, and the files that hand
// them to Ninja, Slurm or any farm manager.
#include "nmbake/plan.hpp"

#include <sys/stat.h>

#include <cstdio>
#include <filesystem>
#include <fstream>
#include <map>
#include <nlohmann/json.hpp>
#include <set>
#include <string_view>

#include "base/strings.hpp"
#include "nmbake/cleanup.hpp"
#include "nmbake/load.hpp"
#include "nmbake/sets.hpp"
#include "nmbake/task.hpp"
#include "nmbake/udim.hpp"

namespace nmbake {

namespace fs = std::filesystem;

using detail::concat;

std::string shell_command(const std::vector<std::string>& argv) {
  std::string line;
  for (const std::string& word : argv) {
    if (!line.empty()) line += ' ';
    const bool plain = !word.empty() && word.find_first_not_of(
                                            "ABCDEFGHIJKLMNOPQRSTUVWXYZabcdefghijklmnopqrstuvwxyz"
                                            "0123456789_-./=:%+,@") == std::string::npos;
    if (plain) {
      line += word;
      continue;
    }
    line += '\'';
    for (const char c : word) {
      if (c == '\'') {
        line += "'\\''";
      } else {
        line += c;
      }
    }
    line += '\'';
  }
  return line;
}

namespace {

std::string absolute(const std::string& path) { return fs::absolute(path).lexically_normal().string(); }

// The maps a bake writes: each output, per UDIM tile and texture set when
// it has the tokens (the low mesh is read to find its tiles and materials),
// and its packs that name no UDIM tile.
Status bake_outputs(const BakeJob& job, std::vector<std::string>& outputs, std::vector<std::string>& packs) {
  std::vector<int> tiles{1001};
  std::vector<std::string> sets{""};
  bool udim = false, by_set = false;
  for (const OutputSpec& out : job.options.outputs) {
    udim |= has_udim_token(out.path);
    by_set |= has_set_token(out.path);
  }
  if (udim || by_set) {
    Mesh low;
    LoadStats stats;
    NMBAKE_TRY(load_mesh(job.options.low_path, LoadOptions{true, false}, low, stats));
    if (udim && low.has_uvs()) NMBAKE_TRY(find_udim_tiles(low, job.options.low_path, true, tiles));
    if (by_set) {
      std::vector<LowSet> low_sets;
      NMBAKE_TRY(find_low_sets(low, job.options.low_path, low_sets));
      sets.clear();
      for (const LowSet& s : low_sets) sets.push_back(s.path_name);
    }
  }
  for (const std::string& set : sets) {
    for (const int tile : tiles) {
      for (const MapOutput& out : map_outputs(job.options))
        outputs.push_back(absolute(udim_path(replace_token(out.path, kSetToken, set), tile)));
    }
    for (const PackSpec& pack : job.options.packs) {
      if (!has_udim_token(pack.path)) packs.push_back(absolute(replace_token(pack.path, kSetToken, set)));
    }
  }
  return Status::ok();
}

// "bake 'NAME'" for messages (the name comes from the job file).
std::string bake_label(const PlanTask& t) { return concat("bake '", printable_text(t.name), "'"); }

// What a byte that a format cannot carry is called in a refusal.
const char* byte_name(char c) {
  switch (c) {
    case '\0':
      return "a NUL byte";
    case '\n':
      return "a line feed";
    case '\r':
      return "a carriage return";
    case '\\':
      return "a backslash";
    default:
      return "a byte";
  }
}

// Every text of a task that reaches a plan file, with what to call it in a
// refusal: its name first, then its files, then the other command words
// (the job file, the nmbake program, the cache folder).
template <typename Visit>
Status for_each_text(const PlanTask& t, Visit visit) {
  NMBAKE_TRY(visit(t.name, "its name"));
  for (const std::string& o : t.outputs) NMBAKE_TRY(visit(o, "the output"));
  for (const std::string& i : t.inputs) NMBAKE_TRY(visit(i, "the input"));
  for (const std::string& w : t.command) NMBAKE_TRY(visit(w, "the command word"));
  return Status::ok();
}

// bad_input when a text of a task holds one of `bytes`, which `format` cannot carry.
Status refuse_bytes(const std::vector<PlanTask>& tasks, const std::string& job_file, std::string_view bytes,
                    const char* format) {
  for (const PlanTask& t : tasks) {
    NMBAKE_TRY(for_each_text(t, [&](const std::string& text, const char* what) {
      const std::size_t at = text.find_first_of(bytes);
      if (at == std::string::npos) return Status::ok();
      const std::string quoted =
          std::string(what) == "its name" ? "" : concat(" '", printable_text(text), "'");
      return Status::bad_input(concat(printable_text(job_file), ": ", bake_label(t), ": ", what, quoted,
                                      " holds ", byte_name(text[at]), ", which ", format, " cannot carry"));
    }));
  }
  return Status::ok();
}

// A plan whose tasks can run at all: no NUL byte (no argv carries one: the
// name after --only would be cut), every file written by one task only (two
// bakes of one output overwrite each other's maps, and Ninja refuses the
// file), and nothing a bake reads written by a task (a cycle; merges read the
// tile files their tiles write, by design).
Status check_plan_files(const std::vector<PlanTask>& tasks, const std::string& job_file) {
  NMBAKE_TRY(refuse_bytes(tasks, job_file, std::string_view("\0", 1), "a command line"));
  std::map<std::string, const PlanTask*> writers;
  for (const PlanTask& t : tasks) {
    for (const std::string& o : t.outputs) {
      const auto [it, fresh] = writers.emplace(o, &t);
      if (fresh) continue;
      const std::string file = printable_text(o);
      if (it->second->name == t.name) {
        return Status::bad_input(
            concat(printable_text(job_file), ": ", bake_label(t), " writes ", file, " twice"));
      }
      return Status::bad_input(concat(printable_text(job_file), ": bakes '", printable_text(it->second->name),
                                      "' and '", printable_text(t.name), "' both write ", file,
                                      ": each output must come from one bake"));
    }
  }
  for (const PlanTask& t : tasks) {
    if (t.kind == "merge") continue;
    for (const std::string& i : t.inputs) {
      const auto it = writers.find(i);
      if (it == writers.end()) continue;
      const std::string reader = it->second->name == t.name ? "it" : bake_label(t);
      return Status::bad_input(concat(printable_text(job_file), ": ", bake_label(*it->second), " writes ",
                                      printable_text(i), ", which ", reader, " reads"));
    }
  }
  return Status::ok();
}

}  // namespace

Status plan_jobs(const std::vector<BakeJob>& jobs, const PlanOptions& options, std::vector<PlanTask>& tasks) {
  tasks.clear();
  std::set<std::string> names;
  std::vector<PlanTask> merges;
  for (const BakeJob& job : jobs) {
    if (!names.insert(job.name).second) {
      return Status::bad_input(concat(printable_text(options.job_file), ": two bakes are named '",
                                      printable_text(job.name),
                                      "': a plan runs each by name (--only), so names must differ"));
    }
    BakeKey key;
    NMBAKE_TRY(bake_key(job.options, key));
    std::vector<std::string> inputs;
    std::vector<const std::string*> paths{&job.options.low_path, &job.options.cage_path};
    for (const std::string& high : job.options.high_paths) paths.insert(paths.end() - 1, &high);
    for (const std::string* p : paths) {
      if (!p->empty()) inputs.push_back(absolute(*p));
    }
    inputs.push_back(options.job_file);
    inputs.push_back(options.nmbake);
    std::vector<std::string> maps, packs;
    NMBAKE_TRY(bake_outputs(job, maps, packs));
    std::vector<std::string> base{options.nmbake, "bake", options.job_file, "--only", job.name, "-q"};
    const bool udim = maps.size() != map_outputs(job.options).size() ||
                      std::any_of(job.options.outputs.begin(), job.options.outputs.end(),
                                  [](const OutputSpec& o) { return has_udim_token(o.path); });
    // A tile file carries every map of a map set; <UDIM> and <SET> outputs
    // are not tiled, nor bakes with packed outputs (written by whole bakes only).
    const bool tiled = options.tiles > 1 && !udim && job.options.packs.empty() &&
                       std::max(job.options.width, job.options.height) >= options.tiles_min_size;
    if (!tiled) {
      PlanTask t;
      t.id = concat("bake:", job.name);
      t.kind = "bake";
      t.name = job.name;
      t.command = base;
      if (!options.cache_dir.empty()) {
        t.command.push_back("--cache");
        t.command.push_back(options.cache_dir);
      }
      t.inputs = inputs;
      t.outputs = maps;
      t.outputs.insert(t.outputs.end(), packs.begin(), packs.end());
      if (!job.report_path.empty()) t.outputs.push_back(absolute(job.report_path));
      t.key = key.hex();
      tasks.push_back(std::move(t));
      continue;
    }
    PlanTask merge;
    merge.id = concat("merge:", job.name);
    merge.kind = "merge";
    merge.name = job.name;
    merge.command = {options.nmbake, "merge", "-q"};
    for (int i = 0; i < options.tiles; ++i) {
      const std::string spec = std::to_string(i + 1) + "/" + std::to_string(options.tiles);
      const std::string tile_file =
          concat(absolute(map_path(job.options.outputs.front().path, MapKind::normal)), ".tile-",
                 std::to_string(i + 1), "-of-", std::to_string(options.tiles));
      PlanTask t;
      t.id = concat("tile:", job.name, ":", std::to_string(i + 1));
      t.kind = "tile";
      t.name = job.name;
      t.command = base;
      t.command.insert(t.command.end(), {"--tile", spec, "--tile-file", tile_file});
      t.inputs = inputs;
      t.outputs = {tile_file};
      t.key = key.hex();
      merge.command.push_back(tile_file);
      merge.inputs.push_back(tile_file);
      merge.dependencies.push_back(t.id);
      tasks.push_back(std::move(t));
    }
    // The outputs the job names, which the tiles must name too: the merge
    // then writes them wherever the job put them (a tile alone may only
    // name paths beside itself or the current folder).
    for (const OutputSpec& out : job.options.outputs) {
      merge.command.push_back("--expect-output");
      merge.command.push_back(absolute(out.path));
    }
    merge.inputs.push_back(options.nmbake);
    merge.outputs = maps;
    if (!job.report_path.empty()) {
      merge.command.push_back("--report");
      merge.command.push_back(absolute(job.report_path));
      merge.outputs.push_back(absolute(job.report_path));
    }
    merge.key = key.hex();
    merges.push_back(std::move(merge));
  }
  for (PlanTask& m : merges) tasks.push_back(std::move(m));
  return check_plan_files(tasks, options.job_file);
}

namespace {

// Ninja's lexer ends a path at ' ', ':', '|', a newline or '$', and has
// escapes for '$ ', '$:' and '$$' only. '|' (which starts implicit outputs or
// order-only inputs even inside a word) is written as a variable, which a path
// may reference and whose value takes any byte but newlines. Newlines cannot
// be written at all ('$' + newline continues the line): check_ninja_plan
// refuses them before this runs.
std::string ninja_path(const std::string& path) {
  std::string out;
  for (const char c : path) {
    NMBAKE_CHECK(c != '\n' && c != '\r', "line breaks are refused by check_ninja_plan");
    if (c == '|') {
      out += "${nmbake_pipe}";
      continue;
    }
    if (c == '$' || c == ' ' || c == ':') out += '$';
    out += c;
  }
  return out;
}

// A variable's value: only '$' is special (and newlines, refused as above).
std::string ninja_value(const std::string& text) {
  std::string out;
  for (const char c : text) {
    NMBAKE_CHECK(c != '\n' && c != '\r', "line breaks are refused by check_ninja_plan");
    if (c == '$') out += '$';
    out += c;
  }
  return out;
}

// sbatch reads an #SBATCH line as words: quotes group, a backslash escapes
// the next byte (and is dropped), an unquoted '#' starts a comment. The
// --output value is a pattern in which '%' starts a replacement ('%%' is
// one '%') and any backslash turns every replacement off (so %A_%a would
// name one log for every array task): check_slurm_plan refuses backslashes.
std::string sbatch_output_value(const std::string& pattern) {
  std::string out = "\"";
  for (const char c : pattern) {
    if (c == '"') out += '\\';
    out += c;
  }
  return out + '"';
}

// '%' in a folder name, escaped for an --output pattern.
std::string sbatch_pattern_text(const std::string& text) {
  std::string out;
  for (const char c : text) {
    if (c == '%') out += '%';
    out += c;
  }
  return out;
}

Status write_file(const std::string& path, const std::string& text, bool executable = false) {
  return write_file_atomically(path, {text}, "the plan", executable ? 0777 : 0666);
}

}  // namespace

Status check_ninja_plan(const std::vector<PlanTask>& tasks, const std::string& job_file) {
  return refuse_bytes(tasks, job_file, "\n\r", "a Ninja file");
}

Status check_slurm_plan(const std::vector<PlanTask>& tasks, const std::string& job_file,
                        const std::string& folder) {
  // A carriage return is a line break to many text tools (and to bash in a
  // file edited on Windows): refused with the line feed, so that one line is
  // always one task whatever reads the list.
  for (const PlanTask& t : tasks) {
    for (const std::string& word : t.command) {
      const std::size_t at = word.find_first_of("\n\r");
      if (at == std::string::npos) continue;
      const std::string what =
          word == t.name ? "its name" : concat("the command word '", printable_text(word), "'");
      return Status::bad_input(concat(printable_text(job_file), ": ", bake_label(t), ": ", what, " holds ",
                                      byte_name(word[at]),
                                      ", which a Slurm task list (one command a line) cannot carry"));
    }
  }
  const std::string dir = absolute(folder);
  if (const std::size_t at = dir.find_first_of("\n\r\\"); at != std::string::npos) {
    return Status::bad_input(
        concat(printable_text(dir), ": a Slurm plan folder cannot hold ", byte_name(dir[at]),
               dir[at] == '\\' ? " (sbatch drops it from #SBATCH --output and turns off the log's %A_%a)"
                               : " (an #SBATCH line ends there)"));
  }
  return Status::ok();
}

Status check_json_plan(const std::vector<PlanTask>& tasks, const std::string& job_file) {
  // The writer's own test: nlohmann's dump() throws on a byte that is not
  // UTF-8 (a job file's path is any bytes; that was an internal error).
  const auto json_string = [](const std::string& text) {
    try {
      (void)nlohmann::json(text).dump();
      return true;
    } catch (const nlohmann::json::type_error&) {
      return false;
    }
  };
  for (const PlanTask& t : tasks) {
    NMBAKE_TRY(for_each_text(t, [&](const std::string& text, const char* what) {
      if (json_string(text)) return Status::ok();
      const std::string quoted =
          std::string(what) == "its name" ? "" : concat(" '", printable_text(text), "'");
      return Status::bad_input(concat(printable_text(job_file), ": ", bake_label(t), ": ", what, quoted,
                                      " is not valid UTF-8, which a JSON string cannot carry"));
    }));
  }
  return Status::ok();
}

Status write_ninja_plan(const std::vector<PlanTask>& tasks, const std::string& job_file,
                        const std::string& path) {
  NMBAKE_TRY(check_ninja_plan(tasks, job_file));
  std::string text =
      "# Written by nmbake plan: one build statement per bake, tile and merge.\n"
      "# `ninja -f FILE` bakes what is out of date; restat: a task whose outputs\n"
      "# do not change does not make its dependents run.\n"
      "ninja_required_version = 1.3\n\n"
      "nmbake_pipe = |\n\n"
      "rule nmbake\n  command = $cmd\n  description = $desc\n  restat = 1\n\n";
  for (const PlanTask& t : tasks) {
    text += "build";
    for (const std::string& o : t.outputs) text.append(" ").append(ninja_path(o));
    text += ": nmbake";
    for (const std::string& i : t.inputs) text.append(" ").append(ninja_path(i));
    text.append("\n  cmd = ").append(ninja_value(shell_command(t.command))).append("\n");
    const std::string tile_number = t.kind == "tile" ? concat(" ", t.id.substr(t.id.rfind(':') + 1)) : "";
    text.append("  desc = ").append(ninja_value(concat(t.kind, " ", t.name, tile_number))).append("\n\n");
  }
  return write_file(path, text);
}

Status write_slurm_plan(const std::vector<PlanTask>& tasks, const std::string& job_file,
                        const std::string& folder) {
  NMBAKE_TRY(check_slurm_plan(tasks, job_file, folder));
  std::error_code ec;
  fs::create_directories(fs::path(folder) / "logs", ec);
  if (ec) return Status::io(folder + ": cannot create the plan folder: " + ec.message());
  const std::string dir = absolute(folder);
  std::string bakes, merges;
  int bake_count = 0, merge_count = 0;
  for (const PlanTask& t : tasks) {
    if (t.kind == "merge") {
      merges += shell_command(t.command) + "\n";
      ++merge_count;
    } else {
      bakes += shell_command(t.command) + "\n";
      ++bake_count;
    }
  }
  NMBAKE_TRY(write_file(dir + "/tasks.txt", bakes));
  NMBAKE_TRY(write_file(dir + "/merges.txt", merges));
  const auto array_script = [&](const char* name, const char* list, int count) {
    return std::string("#!/bin/bash\n") + "# Written by nmbake plan: array task K runs line K + 1 of " +
           list + ".\n" + "#SBATCH --job-name=nmbake-" + name + "\n" + "#SBATCH --array=0-" +
           std::to_string(std::max(0, count - 1)) + "\n" + "#SBATCH --output=" +
           sbatch_output_value(sbatch_pattern_text(dir) + "/logs/" + name + "-%A_%a.log") + "\n" +
           "set -euo pipefail\n" + "line=$(sed -n \"$((SLURM_ARRAY_TASK_ID + 1))p\" " +
           shell_command({dir + "/" + list}) + ")\n" +
           "echo \"nmbake task $SLURM_ARRAY_JOB_ID.$SLURM_ARRAY_TASK_ID: $line\"\n" +
           "exec bash -c \"$line\"\n";
  };
  NMBAKE_TRY(write_file(dir + "/bake.sbatch", array_script("bake", "tasks.txt", bake_count), true));
  NMBAKE_TRY(write_file(dir + "/merge.sbatch", array_script("merge", "merges.txt", merge_count), true));
  std::string submit =
      "#!/bin/bash\n"
      "# Written by nmbake plan. Submits every bake and tile as one job array and\n"
      "# the merges as a second array that starts only when every task of the\n"
      "# first succeeded (afterok; a failed bake cancels its merges). Prints the\n"
      "# job ids. --wait: returns when all is done, with sbatch's exit code.\n"
      "set -euo pipefail\n"
      "cd " +
      shell_command({dir}) +
      "\n"
      "wait=()\n"
      "[ \"${1:-}\" = --wait ] && wait=(--wait)\n";
  if (merge_count == 0) {
    submit += "bake=$(sbatch --parsable \"${wait[@]}\" bake.sbatch)\necho \"bake array: job $bake\"\n";
  } else {
    submit +=
        "bake=$(sbatch --parsable bake.sbatch)\n"
        "echo \"bake array: job $bake (" +
        std::to_string(bake_count) +
        " tasks)\"\n"
        "merge=$(sbatch --parsable \"${wait[@]}\" --kill-on-invalid-dep=yes --dependency=afterok:$bake "
        "merge.sbatch)\n"
        "echo \"merge array: job $merge (" +
        std::to_string(merge_count) + " tasks, after $bake)\"\n";
  }
  return write_file(dir + "/submit.sh", submit, true);
}

Status write_json_plan(const std::vector<PlanTask>& tasks, const std::string& job_file,
                       const std::string& path) {
  NMBAKE_TRY(check_json_plan(tasks, job_file));
  nlohmann::ordered_json j;
  j["format"] = "nmbake-plan";
  j["version"] = 1;
  j["tasks"] = nlohmann::ordered_json::array();
  for (const PlanTask& t : tasks) {
    j["tasks"].push_back({{"id", t.id},
                          {"kind", t.kind},
                          {"name", t.name},
                          {"command", t.command},
                          {"inputs", t.inputs},
                          {"outputs", t.outputs},
                          {"dependencies", t.dependencies},
                          {"key", t.key}});
  }
  return write_file(path, j.dump(2) + "\n");
}

}  // namespace nmbake
