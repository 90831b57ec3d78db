// `nmbake bake`: one bake from flags, or every bake of a job file.
#include <charconv>
#include <cmath>
#include <cstdio>
#include <fstream>
#include <string>
#include <vector>

#include "commands.hpp"
#include "nmbake/bake.hpp"
#include "nmbake/job.hpp"
#include "progress.hpp"

namespace nmbake::cli {

namespace {

struct BakeFlags {
  std::string job_file;
  std::string low, high, cage;
  std::vector<std::string> outputs;
  std::string size = "2048";
  int samples = 4;
  std::string space = "tangent", green = "up", front = "auto", back = "auto", hit = "first";
  std::string cage_mode = "averaged", high_normals = "smooth", build_quality = "low", encode = "inverse", bvh = "auto";
  std::string format;
  std::string tangent_basis = "mikktspace";
  std::string tangents = "mikktspace";
  int uv_set = 0;
  bool ignore_backfaces = false;
  int padding = 16;
  std::string report;
  std::string debug_dump;
  double max_miss_rate = -1.0;  // < 0: no gate
};

int fail(const Status& status) {
  std::fprintf(stderr, "nmbake: error: %s\n", status.message().c_str());
  return status.code() == StatusCode::internal ? kInternal : kBadInput;
}

int usage_error(const std::string& message) {
  std::fprintf(stderr, "nmbake: error: %s\n", message.c_str());
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
  o.samples = f.samples;
  if (!parse_normal_space(f.space, o.space)) return Status::bad_input("--space " + f.space + ": expected tangent or object");
  if (!parse_green_channel(f.green, o.green)) return Status::bad_input("--green " + f.green + ": expected up or down");
  if (!parse_hit_rule(f.hit, o.hit)) return Status::bad_input("--hit " + f.hit + ": expected first or nearest");
  if (!parse_cage_mode(f.cage_mode, o.cage_mode)) return Status::bad_input("--cage-mode " + f.cage_mode + ": expected averaged or interpolated");
  if (!parse_high_normals(f.high_normals, o.high_normals)) return Status::bad_input("--high-normals " + f.high_normals + ": expected smooth or face");
  if (!parse_bvh_memory(f.bvh, o.bvh_memory)) return Status::bad_input("--bvh " + f.bvh + ": expected auto, fast or compact");
  if (!parse_build_quality(f.build_quality, o.build_quality)) return Status::bad_input("--build-quality " + f.build_quality + ": expected low, medium or high");
  if (!parse_tangent_encode(f.encode, o.tangent_encode)) return Status::bad_input("--encode " + f.encode + ": expected inverse or transpose");
  if (!parse_tangent_basis(f.tangent_basis, o.tangent_basis)) return Status::bad_input("--tangent-basis " + f.tangent_basis + ": expected mikktspace, lengyel, face or file");
  if (f.tangents != "mikktspace" && f.tangents != "file") return Status::bad_input("--tangents " + f.tangents + ": expected mikktspace or file");
  if (f.tangents == "file") o.tangent_basis = TangentBasis::file;
  o.uv_set = f.uv_set;
  if (!parse_distance(f.front, o.front)) return Status::bad_input("--front " + f.front + ": expected a distance, N% or auto");
  if (!parse_distance(f.back, o.back)) return Status::bad_input("--back " + f.back + ": expected a distance, N% or auto");
  o.ignore_backfaces = f.ignore_backfaces;
  o.padding = f.padding;
  o.debug_dump_prefix = f.debug_dump;
  for (const std::string& path : f.outputs) {
    OutputSpec out;
    out.path = path;
    if (!f.format.empty()) {
      if (!parse_pixel_format(f.format, out.format)) {
        return Status::bad_input("--format " + f.format + ": expected png8, png16, tiff16, exr-half, exr-float or exr-float-piz");
      }
    } else if (!pixel_format_from_path(path, out.format)) {
      return Status::bad_input(path + ": unknown image extension (use .png, .tif, .tiff or .exr)");
    }
    o.outputs.push_back(out);
  }
  return Status::ok();
}

Status write_report(const std::string& path, const BakeReport& report) {
  const std::string tmp = path + ".tmp";
  {
    std::ofstream out(tmp, std::ios::binary | std::ios::trunc);
    if (!out) return Status::io(path + ": cannot write the report");
    out << report.to_json();
    if (!out.flush()) return Status::io(path + ": cannot write the report");
  }
  if (std::rename(tmp.c_str(), path.c_str()) != 0) {
    std::remove(tmp.c_str());
    return Status::io(path + ": cannot write the report");
  }
  return Status::ok();
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
  // Check every job before the first one runs: a typo in the last bake of a
  // job file must not be found after an hour of baking.
  for (const BakeJob& job : jobs) {
    const Status s = validate_options(job.options);
    // An environment failure (the image module missing) stays internal.
    if (!s) {
      return fail(s.code() == StatusCode::internal ? s : Status::bad_input(job.name + ": " + s.message()));
    }
  }

  int exit_code = kSuccess;
  for (const BakeJob& job : jobs) {
    const bool show_progress = !global.quiet && stderr_is_terminal();
    ProgressBar bar(show_progress);
    BakeReport report;
    // No listener at all when nothing is drawn: the stages then skip the
    // pauses they make to report progress.
    ProgressFn listener;
    if (show_progress) listener = [&](const char* stage, double f) { bar.update(stage, f); };
    const Status s = bake(job.options, report, listener);
    bar.finish();
    if (!s) return fail(s);
    if (!job.report_path.empty()) {
      const Status rs = write_report(job.report_path, report);
      if (!rs) return fail(rs);
    }
    if (!global.quiet) {
      std::printf("%s: %s\n", job.name.c_str(), report.summary_line().c_str());
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
                   job.name.c_str(), report.front, report.back);
    } else if (report.miss_rate() > 0.01) {
      std::fprintf(stderr, "nmbake: warning: %s: %.2f%% of the rays missed the high mesh (kept the low normal)\n",
                   job.name.c_str(), 100.0 * report.miss_rate());
    }
    if (flags.max_miss_rate >= 0.0 && report.miss_rate() > flags.max_miss_rate) {
      std::fprintf(stderr, "nmbake: gate failed: %s: miss rate %.4f is above --max-miss-rate %.4f\n",
                   job.name.c_str(), report.miss_rate(), flags.max_miss_rate);
      exit_code = kGateFailed;
    }
  }
  return exit_code;
}

}  // namespace

Runner add_bake_command(CLI::App& app, const GlobalOptions& global) {
  auto flags = std::make_shared<BakeFlags>();
  CLI::App* cmd = app.add_subcommand("bake", "bake a normal map (from flags, or every bake of a TOML job file)");
  cmd->add_option("job", flags->job_file, "job file (TOML) describing one or several bakes")->check(CLI::ExistingFile);
  cmd->add_option("--low", flags->low, "low-poly mesh with UVs (OBJ, PLY, glTF/GLB, FBX, DAE, 3DS)");
  cmd->add_option("--high", flags->high, "high-poly mesh (OBJ, PLY, glTF/GLB, FBX, DAE, 3DS, STL)");
  cmd->add_option("--cage", flags->cage, "cage mesh with the low mesh's topology (default: averaged-normal cage)");
  cmd->add_option("-o,--output", flags->outputs, "output map(s): .png (16-bit), .tif, .exr; repeat for several")->allow_extra_args(false);
  cmd->add_option("--size", flags->size, "map size, N or WxH")->default_val("2048");
  cmd->add_option("--samples", flags->samples, "samples per texel: 1, 4, 16, 64")->default_val(4);
  cmd->add_option("--space", flags->space, "tangent | object")->default_val("tangent");
  cmd->add_option("--green", flags->green, "up (OpenGL: Blender, Unity, glTF) | down (DirectX: Unreal)")->default_val("up");
  cmd->add_option("--front", flags->front, "cage distance outside the low surface: units, N% of the bbox diagonal, auto")->default_val("auto");
  cmd->add_option("--back", flags->back, "search distance inside the low surface: units, N%, auto")->default_val("auto");
  cmd->add_option("--hit", flags->hit, "first (from the cage) | nearest (to the low surface)")->default_val("first");
  cmd->add_option("--cage-mode", flags->cage_mode, "averaged | interpolated normals push the default cage")->default_val("averaged");
  cmd->add_flag("--ignore-backfaces", flags->ignore_backfaces, "skip high triangles that face away from the ray");
  cmd->add_option("--high-normals", flags->high_normals, "smooth (interpolated vertex normals) | face")->default_val("smooth");
  cmd->add_option("--padding", flags->padding, "texels of dilation around charts")->default_val(16);
  cmd->add_option("--format", flags->format, "png8 | png16 | tiff16 | exr-half | exr-float | exr-float-piz (default: from the extension)");
  cmd->add_option("--report", flags->report, "write the bake report (JSON) here");
  cmd->add_option("--max-miss-rate", flags->max_miss_rate, "exit 1 when more than this share of rays miss (0..1)")->check(CLI::Range(0.0, 1.0));
  cmd->add_option("--build-quality", flags->build_quality, "BVH build quality: low | medium | high")->default_val("low");
  cmd->add_option("--bvh", flags->bvh,
                  "BVH memory: fast (vertices copied into leaves) | compact (indices only, about a third of the "
                  "memory, slower rays) | auto (compact above 16M high triangles)")
      ->default_val("auto");
  cmd->add_option("--encode", flags->encode, "tangent-space encode: inverse (exact) | transpose (for comparison)")->default_val("inverse");
  cmd->add_option("--tangent-basis", flags->tangent_basis, "basis the map is encoded in: mikktspace | lengyel | face (comparison only)")->default_val("mikktspace");
  cmd->add_option("--tangents", flags->tangents,
                  "tangent frame of the map: mikktspace (computed) | file (the low mesh's glTF TANGENT / FBX tangents)")
      ->default_val("mikktspace");
  cmd->add_option("--uv-set", flags->uv_set, "the low mesh's UV set: glTF TEXCOORD_N, FBX UV channel N")
      ->default_val(0)->check(CLI::Range(0, 7));
  cmd->add_option("--debug-dump", flags->debug_dump, "also write PREFIX_coverage.png, PREFIX_misses.png, PREFIX_distance.exr");
  return [flags, &global, cmd]() { return run_bake(*flags, global, *cmd); };
}

}  // namespace nmbake::cli
