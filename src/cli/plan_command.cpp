// `nmbake plan jobs.toml [--tiles N] [--ninja FILE] [--slurm DIR] [--json FILE]`:
// the bakes of a job file as tasks for Ninja, Slurm or any farm manager
// (plan.hpp).
#include <unistd.h>

#include <cstdio>
#include <filesystem>

#include "commands.hpp"
#include "nmbake/cache.hpp"
#include "nmbake/plan.hpp"

namespace nmbake::cli {

namespace {

struct PlanFlags {
  std::string job_file, ninja, slurm, json, cache;
  int tiles = 0, tiles_min_size = 4096;
};

// This program's own path, for the tasks' commands.
std::string self_path() {
  std::error_code ec;
  const std::filesystem::path self = std::filesystem::read_symlink("/proc/self/exe", ec);
  return ec ? std::string("nmbake") : self.string();
}

int run_plan(const PlanFlags& f, const GlobalOptions& global) {
  if (f.ninja.empty() && f.slurm.empty() && f.json.empty()) {
    std::fprintf(stderr, "nmbake: error: plan: give --ninja FILE, --slurm DIR and/or --json FILE\n");
    return kBadInput;
  }
  const auto fail = [](const Status& s) {
    std::fprintf(stderr, "nmbake: error: %s\n", s.message().c_str());
    return s.code() == StatusCode::internal ? kInternal : kBadInput;
  };
  std::vector<BakeJob> jobs;
  if (const Status s = load_job_file(f.job_file, jobs); !s) return fail(s);
  PlanOptions options;
  options.nmbake = self_path();
  options.job_file = std::filesystem::absolute(f.job_file).lexically_normal().string();
  options.tiles = f.tiles;
  options.tiles_min_size = f.tiles_min_size;
  const std::string cache = resolve_cache_dir(f.cache);
  if (!cache.empty()) options.cache_dir = std::filesystem::absolute(cache).lexically_normal().string();
  std::vector<PlanTask> tasks;
  if (const Status s = plan_jobs(jobs, options, tasks); !s) return fail(s);
  // Every format asked for is checked before the first is written: a refusal
  // leaves nothing behind.
  const std::string& job = options.job_file;
  if (!f.ninja.empty()) {
    if (const Status s = check_ninja_plan(tasks, job); !s) return fail(s);
  }
  if (!f.slurm.empty()) {
    if (const Status s = check_slurm_plan(tasks, job, f.slurm); !s) return fail(s);
  }
  if (!f.json.empty()) {
    if (const Status s = check_json_plan(tasks, job); !s) return fail(s);
  }
  if (!f.ninja.empty()) {
    if (const Status s = write_ninja_plan(tasks, job, f.ninja); !s) return fail(s);
  }
  if (!f.slurm.empty()) {
    if (const Status s = write_slurm_plan(tasks, job, f.slurm); !s) return fail(s);
  }
  if (!f.json.empty()) {
    if (const Status s = write_json_plan(tasks, job, f.json); !s) return fail(s);
  }
  if (!global.quiet) {
    int tiles = 0, merges = 0;
    for (const PlanTask& t : tasks) {
      tiles += t.kind == "tile" ? 1 : 0;
      merges += t.kind == "merge" ? 1 : 0;
    }
    std::printf("plan: %zu tasks (%zu bakes, %d tiles, %d merges)%s%s%s%s%s%s\n", tasks.size(),
                tasks.size() - static_cast<std::size_t>(tiles + merges), tiles, merges,
                f.ninja.empty() ? "" : ", ninja ", f.ninja.c_str(), f.slurm.empty() ? "" : ", slurm ",
                f.slurm.c_str(), f.json.empty() ? "" : ", json ", f.json.c_str());
  }
  return kSuccess;
}

}  // namespace

Runner add_plan_command(CLI::App& app, const GlobalOptions& global) {
  auto flags = std::make_shared<PlanFlags>();
  CLI::App* cmd = app.add_subcommand("plan", "turn a job file into tasks for Ninja, Slurm or a farm manager");
  cmd->add_option("job", flags->job_file, "job file (TOML)")->required()->check(CLI::ExistingFile);
  cmd->add_option("--ninja", flags->ninja, "write a Ninja build file (ninja -f FILE re-bakes what changed)");
  cmd->add_option("--slurm", flags->slurm, "write DIR/submit.sh and the sbatch job arrays");
  cmd->add_option("--json", flags->json, "write the task graph as JSON");
  cmd->add_option("--tiles", flags->tiles,
                  "split each bake of at least --tiles-min-size into N tiles and a merge")
      ->default_val(0)
      ->check(CLI::Range(0, 4096));
  cmd->add_option("--tiles-min-size", flags->tiles_min_size, "larger map side from which --tiles applies")
      ->default_val(4096);
  cmd->add_option("--cache", flags->cache, "every bake task uses this cache folder (also NMBAKE_CACHE)");
  return [flags, &global]() { return run_plan(*flags, global); };
}

}  // namespace nmbake::cli
