// `nmbake plan`: a job file as a graph of tasks for an existing engine
// (DESIGN.md: nmbake plans, bakes a task and merges; it does not schedule).
//
// A task is one bake (`nmbake bake JOB --only NAME`), or one tile of a big
// bake (`… --tile I/N --tile-file T`) followed by a merge task (`nmbake merge
// T1 … TN`) that depends on all of them. Every command is a complete argv
// with absolute paths, so it runs from any folder of any machine that sees
// the same files. Writers:
//   * Ninja: one build statement per task (inputs: the meshes, the job file
//     and the nmbake binary; outputs: maps, tile files and report), `restat`,
//     so `ninja` re-bakes only what changed;
//   * Slurm: DIR/tasks.txt and DIR/merges.txt (one command a line),
//     DIR/bake.sbatch (a job array, one array task a line of tasks.txt),
//     DIR/merge.sbatch (an array over merges.txt), and DIR/submit.sh, which
//     submits both, the merges with --dependency=afterok on the bake array;
//   * JSON: {"tasks": [{"id", "kind", "name", "command", "inputs", "outputs",
//     "dependencies", "key"}]} for any other farm manager.
#pragma once

#include <string>
#include <vector>

#include "nmbake/common.hpp"
#include "nmbake/job.hpp"

namespace nmbake {

struct PlanOptions {
  std::string nmbake;    // absolute path of the nmbake program the tasks run
  std::string job_file;  // absolute path
  int tiles = 0;         // > 1: bakes of at least tiles_min_size (larger side) are split into this many tiles
  int tiles_min_size = 4096;
  std::string cache_dir;  // non-empty: every bake task gets --cache DIR
};

struct PlanTask {
  std::string id;    // "bake:NAME", "tile:NAME:I", "merge:NAME"
  std::string kind;  // bake | tile | merge
  std::string name;  // the job's name
  std::vector<std::string> command;
  std::vector<std::string> inputs, outputs;
  std::vector<std::string> dependencies;  // task ids
  std::string key;                        // the bake key (task.hpp)
};

// The tasks of `jobs` (from load_job_file(options.job_file)), bakes before
// merges. bad_input, naming the job file, when two bakes share a name
// (--only needs names), an input cannot be hashed, a name or path holds a NUL
// byte (no argv carries one), two tasks write one file (the maps of one
// would be the other's; Ninja refuses it), or a task writes a file that a
// bake reads (a cycle).
Status plan_jobs(const std::vector<BakeJob>& jobs, const PlanOptions& options, std::vector<PlanTask>& tasks);

// Whether every name, path and command word of `tasks` can be written in
// that format (RELIABILITY.md, "Plans: what quoting guarantees"); bad_input
// naming `job_file`, the bake, the text and the byte otherwise. A writer
// refuses what its check refuses before it writes anything; a caller writing
// several formats checks them all first, so that a refusal writes nothing.
//   * Ninja: no line feed or carriage return anywhere (its lexer ends a path
//     or a value there; `$` + newline continues a line, it adds no newline);
//   * Slurm: no line feed or carriage return in a command word (the task
//     lists hold one command a line; a second line would be a second command
//     for the next array task), nor in `folder`, which also may not hold a
//     backslash (sbatch drops it from --output and turns off its patterns);
//   * JSON: valid UTF-8 (a JSON string cannot hold other bytes).
Status check_ninja_plan(const std::vector<PlanTask>& tasks, const std::string& job_file);
Status check_slurm_plan(const std::vector<PlanTask>& tasks, const std::string& job_file,
                        const std::string& folder);
Status check_json_plan(const std::vector<PlanTask>& tasks, const std::string& job_file);

// `job_file` only names the plan's source in refusals.
Status write_ninja_plan(const std::vector<PlanTask>& tasks, const std::string& job_file,
                        const std::string& path);
Status write_slurm_plan(const std::vector<PlanTask>& tasks, const std::string& job_file,
                        const std::string& folder);
Status write_json_plan(const std::vector<PlanTask>& tasks, const std::string& job_file,
                       const std::string& path);

// A command line for a POSIX shell: each word single-quoted when it needs it.
std::string shell_command(const std::vector<std::string>& argv);

}  // namespace nmbake
