// `nmbake bake`: one bake from flags, or every bake of a job file.
#include <unistd.h>

#include <algorithm>
#include <charconv>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <map>
#include <string>
#include <vector>

#include "commands.hpp"
#include "nmbake/bake.hpp"
#include "nmbake/budget.hpp"
#include "nmbake/cache.hpp"
#include "nmbake/cleanup.hpp"
#include "nmbake/job.hpp"
#include "nmbake/options.hpp"
#include "nmbake/preset.hpp"
#include "nmbake/sets.hpp"
#include "nmbake/task.hpp"
#include "progress.hpp"

namespace nmbake::cli {

namespace {

// The command's own flags; every option of the bake itself comes from the
// option table (options.hpp), as text, in `table`.
struct BakeFlags {
  std::string job_file;
  std::vector<std::string> outputs;
  std::string format;
  std::string report;
  double max_miss_rate = -1.0;  // < 0: no gate
  std::string only, tile, tile_file, cache;
  bool keep_going = false;        // a job: run the other bakes after one fails
  std::string job_report;         // a job: write each bake's status here (JSON)
  bool print_options = false;     // print each bake's options (JSON lines) and stop
  std::string progress = "auto";  // auto (a bar on a terminal), bar, json, none
  TableFlags table;               // every option of the bake (options.hpp)
};

int fail(const Status& status) {
  print_error(status.message());
  return status.code() == StatusCode::internal ? kInternal : kBadInput;
}

int usage_error(const std::string& message) {
  print_error(message);
  return kBadInput;
}

// Turns the flags into options through the option table; a usage problem
// is a bad_input Status naming the flag.
Status options_from_flags(const BakeFlags& f, BakeOptions& o) {
  NMBAKE_TRY(apply_table_flags(f.table, o));
  for (const std::string& path : f.outputs) {
    OutputSpec out;
    out.path = path;
    if (!f.format.empty()) {
      if (!parse_word(f.format, out.format))
        return Status::bad_input("--format " + f.format + ": " + expected_words<PixelFormat>());
      out.format_given = true;
    } else if (!pixel_format_from_path(path, out.format)) {
      return Status::bad_input(path + ": unknown image extension (use .png, .tif, .tiff, .exr or .tga)");
    }
    o.outputs.push_back(out);
  }
  resolve_low_token(o);
  return Status::ok();
}

Status write_text(const std::string& path, const std::string& text) {
  NMBAKE_TRY(check_output_target(path));
  return write_file_atomically(path, {text}, "the report");
}

// A bake through the cache (cache.hpp): fetched when its key is there,
// else baked and stored. Without a cache folder, or for a tile, just bake().
// An entry that is there but does not verify is a miss: a warning says
// which and why, and the new bake replaces it. A store that fails after the
// bake (the folder was checked before it: check_cache_dir) only warns: the
// maps are written and right, and the next bake bakes again.
Status bake_or_fetch(const BakeJob& job, const std::string& cache_dir, BakeReport& report,
                     const ProgressFn& listener, bool& cached) {
  cached = false;
  // Packed files and texture sets' maps are not stored in cache entries
  // (yet): such a bake is baked.
  const bool sets = std::any_of(job.options.outputs.begin(), job.options.outputs.end(),
                                [](const OutputSpec& out) { return has_set_token(out.path); });
  if (cache_dir.empty() || job.options.tile_count > 0 || !job.options.packs.empty() || sets)
    return bake(job.options, report, listener);
  BakeKey key;
  NMBAKE_TRY(validate_options(job.options));
  NMBAKE_TRY(bake_key(job.options, key));
  std::vector<std::string> written;
  CacheLookup lookup;
  NMBAKE_TRY(cache_fetch(cache_dir, key, job.options, job.report_path, lookup, written));
  if (lookup.hit) {
    cached = true;
    report = BakeReport{};
    report.key = key.hex();
    report.cached = true;
    report.outputs = written;
    return Status::ok();
  }
  if (!lookup.bad_entry.empty()) {
    std::fprintf(stderr, "nmbake: warning: %s: a bad cache entry (%s): baking again\n",
                 printable_text((std::filesystem::path(cache_dir) / key.hex()).string()).c_str(),
                 printable_text(lookup.bad_entry).c_str());
  }
  NMBAKE_TRY(bake(job.options, report, listener));
  report.key = key.hex();
  if (const Status stored =
          cache_store(cache_dir, key, job.options, report, report.to_json(), !lookup.bad_entry.empty());
      !stored) {
    std::fprintf(stderr, "nmbake: warning: %s (the maps are written)\n",
                 printable_text(stored.message()).c_str());
  }
  return Status::ok();
}

Status write_report(const std::string& path, const BakeReport& report) {
  return write_text(path, report.to_json());
}

// What became of each bake of a job.
struct JobOutcome {
  enum class State { not_run, done, failed };
  std::string name;
  State state = State::not_run;
  std::string message;               // failed: why
  std::vector<std::string> outputs;  // done: every file it wrote
};

const char* state_name(JobOutcome::State state) {
  switch (state) {
    case JobOutcome::State::done:
      return "done";
    case JobOutcome::State::failed:
      return "failed";
    case JobOutcome::State::not_run:
      break;
  }
  return "not run";
}

void print_outcomes(const std::vector<JobOutcome>& outcomes) {
  std::fprintf(stderr, "nmbake: job summary:\n");
  for (const JobOutcome& o : outcomes) {
    std::string line = o.name + ": " + state_name(o.state);
    if (o.state == JobOutcome::State::failed) line += ": " + o.message;
    for (std::size_t i = 0; i < o.outputs.size(); ++i) line += (i == 0 ? ", wrote " : ", ") + o.outputs[i];
    std::fprintf(stderr, "  %s\n", printable_text(line).c_str());
  }
}

std::string outcomes_json(const std::vector<JobOutcome>& outcomes) {
  std::string out = "{\n  \"bakes\": [";
  for (std::size_t i = 0; i < outcomes.size(); ++i) {
    const JobOutcome& o = outcomes[i];
    out += i == 0 ? "\n" : ",\n";
    out += "    {\"name\": " + quoted_string(o.name) + ", \"status\": \"" + state_name(o.state) + "\"";
    if (o.state == JobOutcome::State::failed) out += ", \"error\": " + quoted_string(o.message);
    out += ", \"outputs\": [";
    for (std::size_t k = 0; k < o.outputs.size(); ++k)
      out += (k == 0 ? "" : ", ") + quoted_string(o.outputs[k]);
    out += "]}";
  }
  return out + "\n  ]\n}\n";
}

int run_bake(const BakeFlags& flags, const GlobalOptions& global, CLI::App& command) {
  std::vector<BakeJob> jobs;
  if (!flags.job_file.empty()) {
    for (const char* flag : {"--low", "--high", "--cage", "--output"}) {
      if (command.count(flag) > 0) {
        return usage_error(std::string(flag) +
                           " cannot be combined with a job file: the job file names the meshes and maps");
      }
    }
    const Status s = load_job_file(flags.job_file, jobs);
    if (!s) return fail(s);
  } else {
    if (command.count("--low") == 0 || command.count("--high") == 0 || flags.outputs.empty()) {
      return usage_error("bake needs --low, --high and -o (or a job file); see nmbake bake --help");
    }
    BakeJob job;
    job.name = flags.outputs.front();
    const Status s = options_from_flags(flags, job.options);
    if (!s) return fail(s);
    job.report_path = flags.report;
    jobs.push_back(std::move(job));
  }
  // --only NAME: one bake of a job file (what a plan's tasks run).
  if (!flags.only.empty()) {
    std::vector<BakeJob> kept;
    std::string names;
    for (BakeJob& job : jobs) {
      names += (names.empty() ? "" : ", ") + job.name;
      if (job.name == flags.only) kept.push_back(std::move(job));
    }
    if (kept.empty())
      return usage_error("--only " + flags.only + ": no bake of that name (bakes: " + names + ")");
    jobs = std::move(kept);
  }
  // --report with a job file: the report of its one bake (after --only);
  // a job of several bakes names each one's in the file.
  if (!flags.job_file.empty() && !flags.report.empty()) {
    if (jobs.size() != 1) {
      return usage_error("--report names one bake's report, and the job has " + std::to_string(jobs.size()) +
                         ": pick one with --only NAME, or give each [[bake]] its report = \"...\" "
                         "(--job-report writes every bake's outcome)");
    }
    jobs.front().report_path = flags.report;
  }
  // --tile I/N: one band of rows of one bake, written as a tile file.
  if (!flags.tile.empty()) {
    int index = 0, count = 0;
    if (!parse_tile_spec(flags.tile, index, count)) {
      return usage_error("--tile " + flags.tile + ": expected I/N with 1 <= I <= N <= 4096");
    }
    if (jobs.size() != 1) return usage_error("--tile bakes one bake: pick it with --only NAME");
    BakeOptions& o = jobs.front().options;
    o.tile_index = index;
    o.tile_count = count;
    o.tile_path = !flags.tile_file.empty() ? flags.tile_file
                                           : map_path(o.outputs.front().path, MapKind::normal) + ".tile-" +
                                                 std::to_string(index + 1) + "-of-" + std::to_string(count);
  } else if (!flags.tile_file.empty()) {
    return usage_error("--tile-file needs --tile I/N");
  }
  if (flags.print_options) {
    for (const BakeJob& job : jobs) std::printf("%s\n", options_json(job.options).c_str());
    return kSuccess;
  }
  // Check every job before the first one runs: a typo in the last bake of a
  // job file must not be found after an hour of baking.
  for (const BakeJob& job : jobs) {
    Status s = validate_options(job.options);
    if (s) s = check_bake_inputs(job.options);
    // A cache that cannot take the bake is found now, not after it.
    if (s && job.options.tile_count == 0) {
      s = check_cache_dir(!flags.cache.empty() ? flags.cache : resolve_cache_dir(job.cache_dir));
    }
    // With more than one bake, also what the low mesh decides (its UV set,
    // its UDIM tiles, its part names against the groups): else a later
    // bake's mistake is found after the earlier bakes wrote their maps. The
    // low meshes are small; a lone bake finds the same at once by itself.
    if (s && jobs.size() > 1) s = check_bake_low_mesh(job.options);
    // An environment failure (the image module missing) stays internal. A
    // flag bake is named after its first output, which the message names
    // already: no name in front (it printed the path twice).
    if (!s) {
      return fail(s.code() == StatusCode::internal || flags.job_file.empty()
                      ? s
                      : Status::bad_input(job.name + ": " + s.message()));
    }
  }

  // A bake that fails while it runs (a mesh broken halfway) stops the job
  // (or, with --keep-going, only itself); the summary then says which bakes
  // finished and what they wrote.
  std::vector<JobOutcome> outcomes(jobs.size());
  for (std::size_t i = 0; i < jobs.size(); ++i) outcomes[i].name = jobs[i].name;
  int exit_code = kSuccess;
  int failure_code = kSuccess;
  for (std::size_t index = 0; index < jobs.size(); ++index) {
    const BakeJob& job = jobs[index];
    JobOutcome& outcome = outcomes[index];
    const bool show_progress =
        flags.progress == "bar" || (flags.progress == "auto" && !global.quiet && stderr_is_terminal());
    ProgressBar bar(show_progress);
    JsonProgress json_progress;
    BakeReport report;
    // No listener at all when nothing is drawn: the stages then skip the
    // pauses they make to report progress.
    ProgressFn listener;
    if (show_progress) listener = [&](const char* stage, double f) { bar.update(stage, f); };
    if (flags.progress == "json")
      listener = [&](const char* stage, double f) { json_progress.update(stage, f); };
    bool cached = false;
    Status s = bake_or_fetch(job, !flags.cache.empty() ? flags.cache : resolve_cache_dir(job.cache_dir),
                             report, listener, cached);
    bar.finish();
    if (s && !cached && !job.report_path.empty()) s = write_report(job.report_path, report);
    if (!s) {
      outcome.state = JobOutcome::State::failed;
      outcome.message = s.message();
      const int code = fail(jobs.size() > 1 ? Status::bad_input(job.name + ": " + s.message()) : s);
      failure_code =
          std::max(failure_code, s.code() == StatusCode::internal ? static_cast<int>(kInternal) : code);
      if (!flags.keep_going) break;
      continue;
    }
    if (cached) {
      outcome.state = JobOutcome::State::done;
      outcome.outputs = report.outputs;
      if (!job.report_path.empty()) outcome.outputs.push_back(job.report_path);
      if (!global.quiet) {
        std::printf("%s: cached (key %s): %zu maps\n", printable_text(job.name).c_str(), report.key.c_str(),
                    report.outputs.size());
      }
      continue;
    }
    outcome.state = JobOutcome::State::done;
    outcome.outputs = report.outputs;
    if (report.unwrapped) outcome.outputs.push_back(report.unwrapped_low_path);
    if (!job.report_path.empty()) outcome.outputs.push_back(job.report_path);
    if (!global.quiet) {
      std::printf("%s: %s\n", printable_text(job.name).c_str(), report.summary_line().c_str());
      if (global.verbose) {
        for (const StageTime& st : report.stages)
          std::printf("  %-10s %8.3f s\n", st.name.c_str(), st.seconds);
        const auto print_load = [](const char* which, const LoadStats& load) {
          std::printf("  load %-5s %8.3f s  %.1f MB at %.0f MB/s\n", which, load.seconds,
                      static_cast<double>(load.bytes) * 1e-6, load.mb_per_second());
        };
        print_load("low", report.low_load);
        print_load("high", report.high_load);
      }
      const double low_unit = report.low_load.unit_meters, high_unit = report.high_load.unit_meters;
      if (low_unit > 0.0 && high_unit > 0.0 && std::abs(low_unit / high_unit - 1.0) > 1e-6) {
        // Positions are used in file units: a cm FBX against a m glTF is off by 100.
        std::printf("  note: the low mesh's unit is %g m, the high mesh's %g m; positions are not rescaled\n",
                    low_unit, high_unit);
      }
      const std::uint64_t fallbacks =
          report.tangents.fallback_tangents + report.encode.singular_frames + report.trace.ray_fallbacks +
          report.encode.zero_high_normals + report.encode.high_normal_map_no_uv +
          report.encode.high_normal_map_degenerate_tangent + report.encode.high_normal_map_zero_normal +
          report.encode.high_normal_map_tile_missing + report.high_tangents.fallback_tangents;
      if (fallbacks > 0 || report.raster.overlapping_samples > 0) {
        std::printf("  note: %llu overlapping UV samples, %llu numerical fallbacks (see --report)\n",
                    static_cast<unsigned long long>(report.raster.overlapping_samples),
                    static_cast<unsigned long long>(fallbacks));
      }
    }
    if (report.trace.samples > 0 && report.trace.misses == report.trace.samples) {
      std::fprintf(
          stderr,
          "nmbake: warning: %s: every ray missed the high mesh: is it within front %.4g / back %.4g of "
          "the low mesh, in the same place and scale?\n",
          printable_text(job.name).c_str(), report.front, report.back);
    } else if (report.miss_rate() > 0.01) {
      std::fprintf(stderr,
                   "nmbake: warning: %s: %.2f%% of the rays missed the high mesh (kept the low normal)\n",
                   printable_text(job.name).c_str(), 100.0 * report.miss_rate());
    }
    if (flags.max_miss_rate >= 0.0 && report.miss_rate() > flags.max_miss_rate) {
      std::fprintf(stderr, "nmbake: gate failed: %s: miss rate %.4f is above --max-miss-rate %.4f\n",
                   printable_text(job.name).c_str(), report.miss_rate(), flags.max_miss_rate);
      exit_code = kGateFailed;
    }
  }
  if (failure_code != kSuccess && jobs.size() > 1) print_outcomes(outcomes);
  if (!flags.job_report.empty()) {
    if (const Status s = write_text(flags.job_report, outcomes_json(outcomes)); !s) {
      fail(s);
      failure_code = std::max<int>(failure_code, kBadInput);
    }
  }
  return failure_code != kSuccess ? failure_code : exit_code;
}

}  // namespace

Runner add_bake_command(CLI::App& app, const GlobalOptions& global) {
  auto flags = std::make_shared<BakeFlags>();
  CLI::App* cmd =
      app.add_subcommand("bake", "bake a normal map (from flags, or every bake of a TOML job file)");
  cmd->add_option("job", flags->job_file, "job file (TOML) describing one or several bakes")
      ->check(CLI::ExistingFile);
  cmd->add_option(
         "-o,--output", flags->outputs,
         "output map(s): .png (16-bit), .tif, .exr, .tga (8-bit); repeat for several; <MAP> names each map "
         "of a map set, <UDIM> each UV tile")
      ->allow_extra_args(false);
  cmd->add_option(
      "--format", flags->format,
      "every output in this format: " + word_list<PixelFormat>(", ") + " (default: from the extension)");
  // Every option of the bake, from the option table.
  add_table_flags(cmd, flags->table);
  cmd->add_option("--report", flags->report, "write the bake report (JSON) here");
  cmd->add_option("--max-miss-rate", flags->max_miss_rate,
                  "exit 1 when more than this share of rays miss (0..1)")
      ->check(CLI::Range(0.0, 1.0));
  cmd->add_option("--only", flags->only, "of a job file, bake only the bake of this name");
  cmd->add_option("--tile", flags->tile,
                  "bake only tile I of N (bands of rows) into a tile file, for nmbake merge");
  cmd->add_option("--tile-file", flags->tile_file, "where --tile writes (default: FIRST_OUTPUT.tile-I-of-N)");
  cmd->add_option(
      "--cache", flags->cache,
      "content-addressed cache folder: a bake whose key is there is copied, not baked (also NMBAKE_CACHE)");
  cmd->add_flag("--keep-going", flags->keep_going,
                "a job: run the other bakes when one fails (exit 2 at the end)");
  cmd->add_option("--job-report", flags->job_report,
                  "a job: write each bake's status and outputs here (JSON)");
  cmd->add_option("--progress", flags->progress,
                  "progress on stderr: auto (a bar on a terminal), bar, json (a JSON line a update), none")
      ->check(CLI::IsMember({"auto", "bar", "json", "none"}))
      ->default_val("auto");
  cmd->add_flag("--print-options", flags->print_options,
                "print each bake's options as they were read (one JSON line a bake) and bake nothing");
  return [flags, &global, cmd]() { return run_bake(*flags, global, *cmd); };
}

}  // namespace nmbake::cli
