// `nmbake bake`: one bake from flags, or every bake of a job file.
#include <algorithm>
#include <charconv>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <string>
#include <vector>

#include <unistd.h>

#include "commands.hpp"
#include "nmbake/bake.hpp"
#include "nmbake/cache.hpp"
#include "nmbake/budget.hpp"
#include "nmbake/cleanup.hpp"
#include "nmbake/job.hpp"
#include "nmbake/preset.hpp"
#include "nmbake/task.hpp"
#include "progress.hpp"

namespace nmbake::cli {

namespace {

struct BakeFlags {
  std::string job_file;
  std::string low, high, cage;
  std::vector<std::string> outputs;
  std::string size = "2048";
  std::string samples = "4";
  int adaptive_max = 16;
  AdaptiveOptions adaptive;  // thresholds (experts; adaptive.hpp)
  std::string space = "tangent", front = "auto", back = "auto", hit = "first";
  std::string cage_mode = "banded", retry_misses = "auto", high_normals = "smooth", build_quality = "low", encode = "inverse", bvh = "auto";
  std::string format;
  std::string tangent_basis = "mikktspace";
  std::string tangents = "mikktspace";
  int uv_set = 0;
  bool ignore_backfaces = false;
  float edge_band = kDefaultEdgeBand;
  int padding = 16;
  std::string report;
  std::string debug_dump;
  double max_miss_rate = -1.0;  // < 0: no gate
  std::string match = "auto", unmatched = "error", low_suffix = "_low", high_suffix = "_high", cage_suffix = "_cage";
  int groups_per_scene = 0;
  std::string only, tile, tile_file, cache;
  bool keep_going = false;      // a job: run the other bakes after one fails
  std::string job_report;       // a job: write each bake's status here (JSON)
  std::string max_memory;       // empty: the memory available to the process
  // Outputs as engines want them: a preset, then the flags given explicitly
  // ("" = not given), which override it whatever their order.
  std::string preset, green, bitangent, tbn, blue;
  std::string dither = "on";
  // The map set (maps.hpp).
  std::vector<std::string> maps;
  std::string height_range = "auto", curvature_range = "auto", ao_distance = "auto", thickness_distance = "auto";
  std::string id_source = "auto";
  int ao_rays = 64, thickness_rays = 16;
};

// "auto" (0) or a number > 0.
bool parse_range(const std::string& text, float& out) {
  if (text == "auto") {
    out = 0.0f;
    return true;
  }
  const char* end = text.data() + text.size();
  const auto r = std::from_chars(text.data(), end, out);
  return r.ec == std::errc() && r.ptr == end && std::isfinite(out) && out > 0.0f;
}

int fail(const Status& status) {
  print_error(status.message());
  return status.code() == StatusCode::internal ? kInternal : kBadInput;
}

int usage_error(const std::string& message) {
  print_error(message);
  return kBadInput;
}

bool parse_size(const std::string& text, int& width, int& height) {
  auto parse_int = [](const char* begin, const char* end, int& out) {
    const auto r = std::from_chars(begin, end, out);
    return r.ec == std::errc() && r.ptr == end;
  };
  const auto x = text.find('x');
  const char* begin = text.data();
  const char* end = begin + text.size();
  if (x == std::string::npos) {
    if (!parse_int(begin, end, width)) return false;
    height = width;
    return true;
  }
  return parse_int(begin, begin + x, width) && parse_int(begin + x + 1, end, height);
}

// Turns the flags into options; a usage problem is a bad_input Status.
Status options_from_flags(const BakeFlags& f, BakeOptions& o) {
  o.low_path = f.low;
  o.high_path = f.high;
  o.cage_path = f.cage;
  if (!parse_size(f.size, o.width, o.height)) return Status::bad_input("--size " + f.size + ": expected N or WxH");
  if (f.samples == "adaptive") {
    o.adaptive = true;
    o.adaptive_options = f.adaptive;
    o.adaptive_options.max_samples = f.adaptive_max;
  } else {
    const char* end = f.samples.data() + f.samples.size();
    const auto parsed = std::from_chars(f.samples.data(), end, o.samples);
    if (parsed.ec != std::errc() || parsed.ptr != end) {
      return Status::bad_input("--samples " + f.samples + ": expected 1, 4, 16, 64 or adaptive");
    }
  }
  if (!parse_word(f.space, o.encode.space)) return Status::bad_input("--space " + f.space + ": expected tangent or object");
  if (!f.preset.empty()) {
    EnginePreset preset;
    if (!find_engine_preset(f.preset, preset)) {
      return Status::bad_input("--preset " + f.preset + ": expected one of " + engine_preset_names());
    }
    o.preset = f.preset;
    apply_engine_preset(preset, {}, o.encode.green, o.encode.decode);
  }
  if (!f.green.empty() && !parse_word(f.green, o.encode.green)) {
    return Status::bad_input("--green " + f.green + ": expected up or down");
  }
  if (!f.bitangent.empty() && !parse_word(f.bitangent, o.encode.decode.bitangent)) {
    return Status::bad_input("--bitangent " + f.bitangent + ": expected pixel or vertex");
  }
  if (!f.tbn.empty() && !parse_word(kFrameRuleWords, f.tbn, o.encode.decode.unit_frame)) {
    return Status::bad_input("--tbn " + f.tbn + ": expected raw or normalized");
  }
  if (!f.blue.empty() && !parse_word(kBlueRuleWords, f.blue, o.encode.decode.rebuild_blue)) {
    return Status::bad_input("--blue " + f.blue + ": expected stored or rebuilt");
  }
  if (f.dither != "on" && f.dither != "off") return Status::bad_input("--dither " + f.dither + ": expected on or off");
  o.dither = f.dither == "on";
  if (!parse_word(f.hit, o.rays.hit)) return Status::bad_input("--hit " + f.hit + ": expected first or nearest");
  if (!parse_word(f.cage_mode, o.rays.cage_mode)) return Status::bad_input("--cage-mode " + f.cage_mode + ": expected banded, averaged or interpolated");
  o.rays.edge_band = f.edge_band;
  if (!parse_word(f.retry_misses, o.rays.retry_misses)) return Status::bad_input("--retry-misses " + f.retry_misses + ": expected auto, on or off");
  if (!parse_word(f.high_normals, o.encode.high_normals)) return Status::bad_input("--high-normals " + f.high_normals + ": expected smooth or face");
  if (!parse_word(f.bvh, o.bvh_memory)) return Status::bad_input("--bvh " + f.bvh + ": expected auto, fast or compact");
  if (!parse_word(f.build_quality, o.build_quality)) return Status::bad_input("--build-quality " + f.build_quality + ": expected low, medium or high");
  if (!parse_word(f.encode, o.encode.tangent_encode)) return Status::bad_input("--encode " + f.encode + ": expected inverse or transpose");
  if (!parse_word(f.tangent_basis, o.tangent_basis)) return Status::bad_input("--tangent-basis " + f.tangent_basis + ": expected mikktspace, lengyel, face or file");
  if (f.tangents != "mikktspace" && f.tangents != "file") return Status::bad_input("--tangents " + f.tangents + ": expected mikktspace or file");
  if (f.tangents == "file") o.tangent_basis = TangentBasis::file;
  o.uv_set = f.uv_set;
  if (!parse_distance(f.front, o.rays.front)) return Status::bad_input("--front " + f.front + ": expected a distance, N% or auto");
  if (!parse_distance(f.back, o.rays.back)) return Status::bad_input("--back " + f.back + ": expected a distance, N% or auto");
  if (!parse_word(f.match, o.match.mode)) return Status::bad_input("--match " + f.match + ": expected auto, name or off");
  if (!parse_word(f.unmatched, o.match.unmatched)) return Status::bad_input("--unmatched " + f.unmatched + ": expected error or all");
  if (f.low_suffix.empty() || f.high_suffix.empty()) return Status::bad_input("--low-suffix and --high-suffix must not be empty");
  o.groups_per_scene = f.groups_per_scene;
  o.match.low_suffix = f.low_suffix;
  if (f.cage_suffix.empty()) return Status::bad_input("--cage-suffix must not be empty");
  o.match.cage_suffix = f.cage_suffix;
  o.match.high_suffix = f.high_suffix;
  o.rays.ignore_backfaces = f.ignore_backfaces;
  o.padding = f.padding;
  o.debug_dump_prefix = f.debug_dump;
  if (!f.max_memory.empty() && !parse_memory_size(f.max_memory, o.max_memory_bytes)) {
    return Status::bad_input("--max-memory " + f.max_memory + ": expected bytes, or a number with K, M, G or T");
  }
  if (!f.maps.empty()) {
    o.maps.clear();
    for (const std::string& list : f.maps) {
      if (const Status s = parse_map_list(list, o.maps); !s) return Status::bad_input("--map " + list + ": " + s.message());
    }
  }
  if (!parse_range(f.height_range, o.height_range)) return Status::bad_input("--height-range " + f.height_range + ": expected a distance > 0 or auto");
  if (!parse_range(f.curvature_range, o.curvature_range)) return Status::bad_input("--curvature-range " + f.curvature_range + ": expected a curvature > 0 (1/scene units) or auto");
  if (!parse_distance(f.ao_distance, o.ao_distance)) return Status::bad_input("--ao-distance " + f.ao_distance + ": expected a distance, N% or auto");
  if (!parse_distance(f.thickness_distance, o.thickness_distance)) return Status::bad_input("--thickness-distance " + f.thickness_distance + ": expected a distance, N% or auto");
  o.ao_rays = f.ao_rays;
  o.thickness_rays = f.thickness_rays;
  if (!parse_word(f.id_source, o.id_source))
    return Status::bad_input("--id-source " + f.id_source + ": expected auto, part or material");
  for (const std::string& path : f.outputs) {
    OutputSpec out;
    out.path = path;
    if (!f.format.empty()) {
      if (!parse_word(f.format, out.format)) {
        return Status::bad_input("--format " + f.format + ": expected png8, png16, tiff16, exr-half, exr-float, exr-float-piz or tga");
      }
      out.format_given = true;
    } else if (!pixel_format_from_path(path, out.format)) {
      return Status::bad_input(path + ": unknown image extension (use .png, .tif, .tiff, .exr or .tga)");
    }
    o.outputs.push_back(out);
  }
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
Status bake_or_fetch(const BakeJob& job, const std::string& cache_dir, BakeReport& report, const ProgressFn& listener,
                     bool& cached) {
  cached = false;
  if (cache_dir.empty() || job.options.tile_count > 0) return bake(job.options, report, listener);
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

Status write_report(const std::string& path, const BakeReport& report) { return write_text(path, report.to_json()); }

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
    case JobOutcome::State::done: return "done";
    case JobOutcome::State::failed: return "failed";
    case JobOutcome::State::not_run: break;
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

// A JSON string: quotes, backslashes and control bytes escaped (any other
// byte as it is: the names and paths come from the job file).
std::string json_string(const std::string& text) {
  std::string out = "\"";
  for (const char c : text) {
    const auto byte = static_cast<unsigned char>(c);
    if (c == '"' || c == '\\') {
      out += '\\';
      out += c;
    } else if (byte < 0x20 || byte == 0x7f) {
      char escaped[8];
      std::snprintf(escaped, sizeof escaped, "\\u%04x", byte);
      out += escaped;
    } else {
      out += c;
    }
  }
  return out + "\"";
}

std::string outcomes_json(const std::vector<JobOutcome>& outcomes) {
  std::string out = "{\n  \"bakes\": [";
  for (std::size_t i = 0; i < outcomes.size(); ++i) {
    const JobOutcome& o = outcomes[i];
    out += i == 0 ? "\n" : ",\n";
    out += "    {\"name\": " + json_string(o.name) + ", \"status\": \"" + state_name(o.state) + "\"";
    if (o.state == JobOutcome::State::failed) out += ", \"error\": " + json_string(o.message);
    out += ", \"outputs\": [";
    for (std::size_t k = 0; k < o.outputs.size(); ++k) out += (k == 0 ? "" : ", ") + json_string(o.outputs[k]);
    out += "]}";
  }
  return out + "\n  ]\n}\n";
}

int run_bake(const BakeFlags& flags, const GlobalOptions& global, CLI::App& command) {
  std::vector<BakeJob> jobs;
  if (!flags.job_file.empty()) {
    for (const char* flag : {"--low", "--high", "--cage", "--output"}) {
      if (command.count(flag) > 0) {
        return usage_error(std::string(flag) + " cannot be combined with a job file: the job file names the meshes and maps");
      }
    }
    const Status s = load_job_file(flags.job_file, jobs);
    if (!s) return fail(s);
  } else {
    if (flags.low.empty() || flags.high.empty() || flags.outputs.empty()) {
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
    if (kept.empty()) return usage_error("--only " + flags.only + ": no bake of that name (bakes: " + names + ")");
    jobs = std::move(kept);
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
    const bool show_progress = !global.quiet && stderr_is_terminal();
    ProgressBar bar(show_progress);
    BakeReport report;
    // No listener at all when nothing is drawn: the stages then skip the
    // pauses they make to report progress.
    ProgressFn listener;
    if (show_progress) listener = [&](const char* stage, double f) { bar.update(stage, f); };
    bool cached = false;
    Status s = bake_or_fetch(job, !flags.cache.empty() ? flags.cache : resolve_cache_dir(job.cache_dir), report,
                             listener, cached);
    bar.finish();
    if (s && !cached && !job.report_path.empty()) s = write_report(job.report_path, report);
    if (!s) {
      outcome.state = JobOutcome::State::failed;
      outcome.message = s.message();
      const int code = fail(jobs.size() > 1 ? Status::bad_input(job.name + ": " + s.message()) : s);
      failure_code = std::max(failure_code, s.code() == StatusCode::internal ? static_cast<int>(kInternal) : code);
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
        for (const StageTime& st : report.stages) std::printf("  %-10s %8.3f s\n", st.name.c_str(), st.seconds);
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
      const std::uint64_t fallbacks = report.tangents.fallback_tangents + report.encode.singular_frames +
                                      report.trace.ray_fallbacks + report.encode.zero_high_normals;
      if (fallbacks > 0 || report.raster.overlapping_samples > 0) {
        std::printf("  note: %llu overlapping UV samples, %llu numerical fallbacks (see --report)\n",
                    static_cast<unsigned long long>(report.raster.overlapping_samples),
                    static_cast<unsigned long long>(fallbacks));
      }
    }
    if (report.trace.samples > 0 && report.trace.misses == report.trace.samples) {
      std::fprintf(stderr,
                   "nmbake: warning: %s: every ray missed the high mesh: is it within front %.4g / back %.4g of "
                   "the low mesh, in the same place and scale?\n",
                   printable_text(job.name).c_str(), report.front, report.back);
    } else if (report.miss_rate() > 0.01) {
      std::fprintf(stderr, "nmbake: warning: %s: %.2f%% of the rays missed the high mesh (kept the low normal)\n",
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
  CLI::App* cmd = app.add_subcommand("bake", "bake a normal map (from flags, or every bake of a TOML job file)");
  cmd->add_option("job", flags->job_file, "job file (TOML) describing one or several bakes")->check(CLI::ExistingFile);
  cmd->add_option("--low", flags->low, "low-poly mesh with UVs (OBJ, PLY, glTF/GLB, FBX, DAE, 3DS)");
  cmd->add_option("--high", flags->high, "high-poly mesh (OBJ, PLY, glTF/GLB, FBX, DAE, 3DS, STL)");
  cmd->add_option("--cage", flags->cage, "cage mesh with the low mesh's topology (default: averaged-normal cage)");
  cmd->add_option("-o,--output", flags->outputs, "output map(s): .png (16-bit), .tif, .exr, .tga (8-bit); repeat for several")->allow_extra_args(false);
  cmd->add_option("--size", flags->size, "map size, N or WxH")->default_val("2048");
  cmd->add_option(
         "--samples", flags->samples,
         "samples per texel: 1, 4, 16, 64, or adaptive (1, then --adaptive-max where the normal varies)")
      ->default_val("4");
  cmd->add_option("--adaptive-max", flags->adaptive_max,
                  "samples of a refined texel with --samples adaptive: 4, 16, 64")
      ->default_val(16);
  cmd->add_option("--adaptive-normal", flags->adaptive.normal_threshold,
                  "refine where the stored vector's second difference between texels exceeds this")
      ->default_val(AdaptiveOptions{}.normal_threshold);
  cmd->add_option("--adaptive-depth", flags->adaptive.depth_threshold,
                  "refine where the hit distance's second difference exceeds this many texels")
      ->default_val(AdaptiveOptions{}.depth_threshold);
  cmd->add_option(
         "--adaptive-spread", flags->adaptive.spread_threshold,
         "take --adaptive-max samples where a refined texel's 4 samples spread more than this (radians)")
      ->default_val(AdaptiveOptions{}.spread_threshold);
  cmd->add_option("--adaptive-border", flags->adaptive.border_threshold,
                  "at a chart border, refine where the normal's first difference exceeds this")
      ->default_val(AdaptiveOptions{}.border_threshold);
  cmd->add_option("--space", flags->space, "tangent | object")->default_val("tangent");
  cmd->add_option("--front", flags->front, "cage distance outside the low surface: units, N% of the bbox diagonal, auto")->default_val("auto");
  cmd->add_option("--back", flags->back, "search distance inside the low surface: units, N%, auto")->default_val("auto");
  cmd->add_option("--hit", flags->hit, "first (from the cage) | nearest (to the low surface)")->default_val("first");
  cmd->add_option("--cage-mode", flags->cage_mode, "banded (averaged normals near hard edges, shading normals elsewhere) | averaged | interpolated: how the default cage is pushed")->default_val("banded");
  cmd->add_option("--edge-band", flags->edge_band, "banded cage: width of the band around hard edges, in units of front + back")->default_val(kDefaultEdgeBand);
  cmd->add_option("--retry-misses", flags->retry_misses, "trace a ray that missed again, out and in up to a quarter of the diagonal: auto (when no distance or cage is given) | on | off")->default_val("auto");
  cmd->add_flag("--ignore-backfaces", flags->ignore_backfaces, "skip high triangles that face away from the ray");
  cmd->add_option("--high-normals", flags->high_normals, "smooth (interpolated vertex normals) | face")->default_val("smooth");
  cmd->add_option("--padding", flags->padding, "texels of dilation around charts")->default_val(16);
  cmd->add_option("--format", flags->format, "png8 | png16 | tiff16 | exr-half | exr-float | exr-float-piz | tga (default: from the extension)");
  cmd->add_option("--report", flags->report, "write the bake report (JSON) here");
  cmd->add_option("--max-miss-rate", flags->max_miss_rate, "exit 1 when more than this share of rays miss (0..1)")->check(CLI::Range(0.0, 1.0));
  cmd->add_option("--build-quality", flags->build_quality, "BVH build quality: low | medium | high")->default_val("low");
  cmd->add_option("--bvh", flags->bvh,
                  "BVH memory: fast (vertices copied into leaves) | compact (indices only, about a third of the "
                  "memory, slower rays) | auto (compact above 16M high triangles)")
      ->default_val("auto");
  cmd->add_option("--encode", flags->encode, "tangent-space encode: inverse (exact) | transpose (for comparison)")->default_val("inverse");
  cmd->add_option("--tangent-basis", flags->tangent_basis, "basis the map is encoded in: mikktspace | lengyel | face (comparison only)")->default_val("mikktspace");
  cmd->add_option("--match", flags->match, "parts into bake groups: auto (by name when a low part ends in the low suffix) | name | off")->default_val("auto");
  cmd->add_option("--low-suffix", flags->low_suffix, "name suffix of low parts (X_low bakes from X_high, X_high_1, X_high.001)")->default_val("_low");
  cmd->add_option("--high-suffix", flags->high_suffix, "name suffix of high parts")->default_val("_high");
  cmd->add_option("--cage-suffix", flags->cage_suffix, "name suffix of cage parts (X_cage is the cage of X_low)")->default_val("_cage");
  cmd->add_option("--unmatched", flags->unmatched, "low parts with no high match: error | all (bake them against every unused high part)")->default_val("error");
  cmd->add_option("--groups-per-scene", flags->groups_per_scene, "bake groups sharing one BVH through ray masks, 1-32 (0: auto; for benchmarks)")->default_val(0)->check(CLI::Range(0, 32));
  cmd->add_option("--only", flags->only, "of a job file, bake only the bake of this name");
  cmd->add_option("--tile", flags->tile, "bake only tile I of N (bands of rows) into a tile file, for nmbake merge");
  cmd->add_option("--tile-file", flags->tile_file, "where --tile writes (default: FIRST_OUTPUT.tile-I-of-N)");
  cmd->add_option("--cache", flags->cache, "content-addressed cache folder: a bake whose key is there is copied, not baked (also NMBAKE_CACHE)");
  cmd->add_option("--tangents", flags->tangents,
                  "tangent frame of the map: mikktspace (computed) | file (the low mesh's glTF TANGENT / FBX tangents)")
      ->default_val("mikktspace");
  cmd->add_option("--uv-set", flags->uv_set, "the low mesh's UV set: glTF TEXCOORD_N, FBX UV channel N")
      ->default_val(0)->check(CLI::Range(0, 7));
  cmd->add_flag("--keep-going", flags->keep_going, "a job: run the other bakes when one fails (exit 2 at the end)");
  cmd->add_option("--job-report", flags->job_report, "a job: write each bake's status and outputs here (JSON)");
  cmd->add_option("--max-memory", flags->max_memory,
                  "refuse a bake whose estimated memory is above this (e.g. 8G; default: what is available)");
  // Outputs as engines want them (README): one block, so other option
  // blocks merge beside it.
  cmd->add_option("--preset", flags->preset,
                  "engine the map is for: " + engine_preset_names() +
                      " (sets --green, --bitangent, --tbn, --blue; each of those given too overrides it, in any order)");
  cmd->add_option("--green", flags->green, "up (OpenGL: Blender, Unity, glTF, Maya) | down (DirectX: Unreal, 3ds Max)")
      ->default_str("up");
  cmd->add_option("--bitangent", flags->bitangent,
                  "how the engine gets B: pixel (sign cross(N, T) from the interpolated N, T) | vertex (per vertex, "
                  "interpolated)")
      ->default_str("pixel");
  cmd->add_option("--tbn", flags->tbn, "the engine's T, B, N before the decode: raw (interpolated) | normalized")
      ->default_str("raw");
  cmd->add_option("--blue", flags->blue, "the engine's z: stored (read from blue) | rebuilt (sqrt(1 - x^2 - y^2), BC5)")
      ->default_str("stored");
  cmd->add_option("--dither", flags->dither, "8-bit outputs (png8, tga): on (ordered dither) | off (rounded)")
      ->default_val("on");
  cmd->add_option("--debug-dump", flags->debug_dump, "also write PREFIX_coverage.png, PREFIX_misses.png, PREFIX_distance.exr");
  cmd->add_option("--map", flags->maps,
                  "maps to bake, repeat or comma list: normal (default), height, ao, bent-normal, curvature, thickness, "
                  "position, object-normal, miss, vertex-color, id; several need <MAP> in each output path")
      ->allow_extra_args(false);
  cmd->add_option("--height-range", flags->height_range,
                  "height map in integer files: heights in [-R, R] scene units fill 0..1 (auto: the map's largest)")
      ->default_val("auto");
  cmd->add_option("--curvature-range", flags->curvature_range,
                  "curvature map in integer files: mean curvature in [-R, R] (1/scene units) fills 0..1 (auto: 99th "
                  "percentile)")
      ->default_val("auto");
  cmd->add_option("--ao-rays", flags->ao_rays, "AO (and bent normal) rays per sample, 1-4096")->default_val(64);
  cmd->add_option("--ao-distance", flags->ao_distance,
                  "AO: occluders further than this do not count: units, N% of the bbox diagonal, auto (10%)")
      ->default_val("auto");
  cmd->add_option("--thickness-rays", flags->thickness_rays, "thickness rays per sample, 1-4096")->default_val(16);
  cmd->add_option("--thickness-distance", flags->thickness_distance,
                  "thickness: search distance, also white in integer files: units, N%, auto (10%)")
      ->default_val("auto");
  cmd->add_option(
         "--id-source", flags->id_source,
         "id map colours: part | material | auto (materials when the high mesh has named ones, else parts)")
      ->default_val("auto");
  return [flags, &global, cmd]() { return run_bake(*flags, global, *cmd); };
}

}  // namespace nmbake::cli
