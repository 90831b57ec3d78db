// `nmbake plan` with hostile names and paths: the Ninja file and the Slurm
// task lists are read back by ninja and by the array script's own `bash -c`,
// and must give exactly one task per bake or tile with exactly its argv;
// what a format cannot carry is refused (exit 2) before anything is written.
#include "nmbake/plan.hpp"

#include <gtest/gtest.h>

#include <algorithm>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <sstream>
#include <string>
#include <vector>

#include "nmbake/job.hpp"
#include "test_util.hpp"

namespace nmbake {
namespace {

namespace fs = std::filesystem;

std::string read_bytes(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  return std::string(std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>());
}

std::vector<std::string> split(const std::string& text, char separator) {
  std::vector<std::string> parts;
  std::string part;
  for (const char c : text) {
    if (c == separator) {
      parts.push_back(part);
      part.clear();
    } else {
      part += c;
    }
  }
  if (!part.empty()) parts.push_back(part);
  return parts;
}

std::string toml_string(const std::string& text) { return quoted_string(text); }

// One triangle with UVs: plan hashes the meshes, it does not bake them.
void write_meshes(const test::TempDir& dir) {
  const std::string obj =
      "v 0 0 0\nv 1 0 0\nv 0 1 0\nvt 0 0\nvt 1 0\nvt 0 1\nvn 0 0 1\nf 1/1/1 2/2/1 3/3/1\n";
  test::write_text(dir.file("low.obj"), obj);
  test::write_text(dir.file("high.obj"), obj);
}

// One [[bake]] of the meshes above writing OUTPUT, SIZE a side.
std::string bake_entry(const std::string& name, const std::string& output, int size) {
  return "[[bake]]\nname = " + toml_string(name) +
         "\nlow = \"low.obj\"\nhigh = \"high.obj\"\nsize = " + std::to_string(size) + "\noutputs = [" +
         toml_string(output) + "]\n";
}

// Names a shell, Ninja or sbatch reads specially. The markers are relative:
// the lines run in a folder where any file that appears is a failure.
const std::vector<std::string> kHostileNames = {
    "with space",
    "it's \"quoted\"",
    "$(touch marker1)",
    "`touch marker2`",
    "a: b",
    "a | b",
    "$in $out $$",
    "ünïcødé ✓ #x",
    "semi; touch marker3 & \\ end",
};

// The tasks a plan of kHostileNames must hold, derived from the job, not
// from the planner: the odd bakes are 64 a side and planned in 2 tiles and a
// merge, the even ones 32 (below --tiles-min-size) as one bake task.
struct Expected {
  std::vector<std::vector<std::string>> bakes;   // argv of each bake or tile task, in order
  std::vector<std::vector<std::string>> merges;  // argv of each merge
  std::vector<std::string> outputs;              // every file a task writes
};

struct HostilePlan {
  test::TempDir dir;
  std::string job;
  Expected expected;
};

void make_hostile_plan(HostilePlan& p, const std::string& program) {
  write_meshes(p.dir);
  std::string text;
  for (std::size_t i = 0; i < kHostileNames.size(); ++i) {
    const std::string& name = kHostileNames[i];
    const bool tiled = i % 2 == 1;
    text += bake_entry(name, name + ".png", tiled ? 64 : 32);
    const std::string out = p.dir.file(name + ".png");
    const std::vector<std::string> base{program, "bake", p.dir.file("job.toml"), "--only", name, "-q"};
    if (!tiled) {
      p.expected.bakes.push_back(base);
      p.expected.outputs.push_back(out);
      continue;
    }
    std::vector<std::string> merge{program, "merge", "-q"};
    for (int t = 1; t <= 2; ++t) {
      const std::string tile_file = out + ".tile-" + std::to_string(t) + "-of-2";
      std::vector<std::string> argv = base;
      argv.insert(argv.end(), {"--tile", std::to_string(t) + "/2", "--tile-file", tile_file});
      p.expected.bakes.push_back(argv);
      p.expected.outputs.push_back(tile_file);
      merge.push_back(tile_file);
    }
    merge.insert(merge.end(), {"--expect-output", out});
    p.expected.merges.push_back(merge);
    p.expected.outputs.push_back(out);
  }
  p.job = p.dir.file("job.toml");
  test::write_text(p.job, text);
}

Status plan_of(const HostilePlan& p, const std::string& program, std::vector<PlanTask>& tasks) {
  std::vector<BakeJob> jobs;
  NMBAKE_TRY(load_job_file(p.job, jobs));
  PlanOptions options;
  options.nmbake = program;
  options.job_file = p.job;
  options.tiles = 2;
  options.tiles_min_size = 64;
  return plan_jobs(jobs, options, tasks);
}

TEST(PlanQuoting, HostileNamesGiveOneTaskEachWithTheirExactArgv) {
  HostilePlan p;
  make_hostile_plan(p, "/opt/nm bake/nmbake");
  std::vector<PlanTask> tasks;
  ASSERT_TRUE(plan_of(p, "/opt/nm bake/nmbake", tasks).is_ok());
  std::vector<std::vector<std::string>> bakes, merges;
  for (const PlanTask& t : tasks) (t.kind == "merge" ? merges : bakes).push_back(t.command);
  EXPECT_EQ(bakes, p.expected.bakes);
  EXPECT_EQ(merges, p.expected.merges);
}

// ninja reads the file back: `-t targets all` lists exactly the outputs and
// `-t commands` exactly one command line per task, the planned argv quoted.
TEST(PlanQuoting, NinjaReadsBackEveryOutputAndCommand) {
  if (test::run_command("command -v ninja >/dev/null 2>&1").exit_code != 0) {
    GTEST_SKIP() << "ninja is not installed (tools/setup installs ninja-build)";
  }
  HostilePlan p;
  make_hostile_plan(p, "/opt/nm bake/nmbake");
  std::vector<PlanTask> tasks;
  ASSERT_TRUE(plan_of(p, "/opt/nm bake/nmbake", tasks).is_ok());
  const std::string ninja = p.dir.file("plan.ninja");
  ASSERT_TRUE(write_ninja_plan(tasks, p.job, ninja).is_ok());

  test::CommandResult r = test::run_command("ninja -f " + ninja + " -t targets all 2>&1");
  ASSERT_EQ(r.exit_code, 0) << r.output;
  std::vector<std::string> targets = split(r.output, '\n'), want_targets;
  for (const std::string& o : p.expected.outputs) want_targets.push_back(o + ": nmbake");
  std::sort(targets.begin(), targets.end());
  std::sort(want_targets.begin(), want_targets.end());
  EXPECT_EQ(targets, want_targets);

  r = test::run_command("ninja -f " + ninja + " -t commands 2>&1");
  ASSERT_EQ(r.exit_code, 0) << r.output;
  std::vector<std::string> commands = split(r.output, '\n'), want_commands;
  for (const auto& argv : p.expected.bakes) want_commands.push_back(shell_command(argv));
  for (const auto& argv : p.expected.merges) want_commands.push_back(shell_command(argv));
  std::sort(commands.begin(), commands.end());
  std::sort(want_commands.begin(), want_commands.end());
  EXPECT_EQ(commands, want_commands);
}

// Every byte but the two line breaks, in a path and in a name: ninja reads
// the path back exactly and runs exactly the command.
TEST(PlanQuoting, NinjaCarriesEveryByteButLineBreaks) {
  if (test::run_command("command -v ninja >/dev/null 2>&1").exit_code != 0) {
    GTEST_SKIP() << "ninja is not installed (tools/setup installs ninja-build)";
  }
  test::TempDir dir;
  std::string bytes;
  for (int c = 1; c < 256; ++c) {
    if (c != '\n' && c != '\r' && c != '/') bytes += static_cast<char>(c);
  }
  PlanTask t;
  t.id = "bake:" + bytes;
  t.kind = "bake";
  t.name = bytes;
  t.command = {"/bin/echo", bytes};
  t.inputs = {dir.file("in " + bytes)};
  t.outputs = {dir.file("out " + bytes)};
  const std::string ninja = dir.file("plan.ninja");
  ASSERT_TRUE(write_ninja_plan({t}, dir.file("job.toml"), ninja).is_ok());
  test::CommandResult r = test::run_command("ninja -f " + ninja + " -t targets all 2>&1");
  EXPECT_EQ(r.exit_code, 0);
  EXPECT_TRUE(r.output == t.outputs[0] + ": nmbake\n") << printable_text(r.output);
  r = test::run_command("ninja -f " + ninja + " -t commands 2>&1");
  EXPECT_EQ(r.exit_code, 0);
  EXPECT_TRUE(r.output == shell_command(t.command) + "\n") << printable_text(r.output);
}

// The array scripts run line K + 1 of the list through `bash -c`: run them
// as Slurm would for every K, with a program that records its argv. Each
// task gets exactly its argv, and no marker appears.
TEST(PlanQuoting, SlurmArrayTasksRunExactlyTheirArgv) {
  test::TempDir bin;
  const std::string program = bin.file("record argv");
  test::write_text(program, "#!/bin/sh\nprintf '%s\\0' \"$@\" > \"$RECORD\"\n");
  fs::permissions(program, fs::perms::owner_all);
  HostilePlan p;
  make_hostile_plan(p, program);
  std::vector<PlanTask> tasks;
  ASSERT_TRUE(plan_of(p, program, tasks).is_ok());
  const std::string folder = p.dir.file("slurm");
  ASSERT_TRUE(write_slurm_plan(tasks, p.job, folder).is_ok());
  EXPECT_EQ(split(read_bytes(folder + "/tasks.txt"), '\n').size(), p.expected.bakes.size());
  EXPECT_EQ(split(read_bytes(folder + "/merges.txt"), '\n').size(), p.expected.merges.size());

  test::TempDir work;  // the tasks' working folder: it must stay empty
  const auto run_array = [&](const char* script, const std::vector<std::vector<std::string>>& want) {
    for (std::size_t k = 0; k < want.size(); ++k) {
      const std::string record = bin.file("argv");
      fs::remove(record);
      const test::CommandResult r = test::run_command(
          "cd " + work.path().string() + " && RECORD='" + record + "' SLURM_ARRAY_JOB_ID=1 " +
          "SLURM_ARRAY_TASK_ID=" + std::to_string(k) + " bash " + folder + "/" + script + " 2>&1");
      EXPECT_EQ(r.exit_code, 0) << script << " " << k << ": " << r.output;
      std::vector<std::string> argv{want[k].front()};
      for (const std::string& word : split(read_bytes(record), '\0')) argv.push_back(word);
      EXPECT_EQ(argv, want[k]) << script << " " << k;
    }
  };
  run_array("bake.sbatch", p.expected.bakes);
  run_array("merge.sbatch", p.expected.merges);
  EXPECT_TRUE(fs::is_empty(work.path()));
}

// sbatch reads #SBATCH lines as words with quotes, backslash escapes and
// '#' comments, and --output as a pattern ('%%' is '%'): a folder with
// all of them is quoted; one with a backslash (which turns the pattern's
// %A_%a off) or a line break is refused, and nothing is written.
TEST(PlanQuoting, SlurmOutputLineIsQuotedOrRefused) {
  HostilePlan p;
  make_hostile_plan(p, "/bin/nmbake");
  std::vector<PlanTask> tasks;
  ASSERT_TRUE(plan_of(p, "/bin/nmbake", tasks).is_ok());
  const std::string folder = p.dir.file("a b#c%d\"e'f");
  ASSERT_TRUE(write_slurm_plan(tasks, p.job, folder).is_ok());
  EXPECT_NE(read_bytes(folder + "/bake.sbatch")
                .find("\n#SBATCH --output=\"" + p.dir.file("a b#c%%d\\\"e'f") + "/logs/bake-%A_%a.log\"\n"),
            std::string::npos)
      << read_bytes(folder + "/bake.sbatch");
  for (const char* bad : {"back\\slash", "line\nfeed", "carriage\rreturn"}) {
    const std::string refused = p.dir.file(bad);
    const Status s = write_slurm_plan(tasks, p.job, refused);
    EXPECT_EQ(s.code(), StatusCode::bad_input) << bad;
    EXPECT_NE(s.message().find("a Slurm plan folder cannot hold"), std::string::npos) << s.message();
    EXPECT_FALSE(fs::exists(refused)) << bad;
  }
}

struct Refusal {
  const char* what;
  std::string job;     // the job file's text
  const char* reason;  // in the message, after the job file and the bake
};

// What no format asked for can carry: exit 2 naming the job file, the
// bake(s) and the reason, and no file of any format written.
TEST(PlanQuoting, InexpressibleNamesAndPathsAreRefusedBeforeWriting) {
  const std::vector<Refusal> refusals = {
      {"line feed in a name", bake_entry("a\ntouch marker #", "a.png", 32),
       "bake 'a\\x0atouch marker #': its name holds a line feed"},
      {"carriage return in a name", bake_entry("cr\r", "cr.png", 32),
       "bake 'cr\\x0d': its name holds a carriage return"},
      {"line feed in a tiled output", bake_entry("t", "x\ntouch marker #.png", 64), "bake 't': the output '"},
      {"NUL in a name", bake_entry(std::string("n\0x", 3), "n.png", 32),
       "bake 'n\\x00x': its name holds a NUL byte"},
      {"two bakes, one output", bake_entry("one", "same.png", 32) + bake_entry("two", "same.png", 32),
       "bakes 'one' and 'two' both write "},
      {"a report over another bake's tile file",
       bake_entry("big", "x.png", 64) + bake_entry("small", "s.png", 32) + "report = \"x.png.tile-2-of-2\"\n",
       "bakes 'big' and 'small' both write "},
      {"a report over the low mesh", bake_entry("r", "r.png", 32) + "report = \"low.obj\"\n",
       "bake 'r' writes "},
  };
  for (const Refusal& refusal : refusals) {
    test::TempDir dir;
    write_meshes(dir);
    test::write_text(dir.file("job.toml"), refusal.job);
    const test::CommandResult r = test::run_command(
        "cd " + dir.path().string() + " && " + test::cli_path() + " plan job.toml --tiles 2 " +
        "--tiles-min-size 64 --ninja plan.ninja --slurm slurm --json plan.json 2>&1");
    EXPECT_EQ(r.exit_code, 2) << refusal.what << ": " << r.output;
    EXPECT_NE(r.output.find(dir.file("job.toml") + ": " + refusal.reason), std::string::npos)
        << refusal.what << ": " << r.output;
    for (const char* written : {"plan.ninja", "slurm", "plan.json"}) {
      EXPECT_FALSE(fs::exists(dir.file(written))) << refusal.what << ": " << written;
    }
  }
}

// A name is job file content: its terminal controls are escaped in messages.
TEST(PlanQuoting, NamesInMessagesAreEscaped) {
  test::TempDir dir;
  write_meshes(dir);
  const std::string name = "\x1b]0;title\x07\x1b[31mred";
  test::write_text(dir.file("job.toml"), bake_entry(name, "a.png", 32) + bake_entry(name, "b.png", 32));
  const test::CommandResult r = test::run_command("cd " + dir.path().string() + " && " + test::cli_path() +
                                                  " plan job.toml --json p.json 2>&1");
  EXPECT_EQ(r.exit_code, 2) << r.output;
  EXPECT_NE(r.output.find("two bakes are named '\\x1b]0;title\\x07\\x1b[31mred'"), std::string::npos)
      << r.output;
  EXPECT_EQ(r.output.find('\x1b'), std::string::npos) << printable_text(r.output);
  EXPECT_FALSE(fs::exists(dir.file("p.json")));
}

// Refusals are per format: an untiled bake's output path is not in its
// command, so a line feed in it suits the Slurm lists (the bake reads it
// from the job file) but not a Ninja file.
TEST(PlanQuoting, RefusalsArePerFormat) {
  test::TempDir dir;
  write_meshes(dir);
  test::write_text(dir.file("job.toml"), bake_entry("b", "x\ny.png", 32));
  test::CommandResult r = test::run_command("cd " + dir.path().string() + " && " + test::cli_path() +
                                            " plan job.toml --slurm slurm 2>&1");
  EXPECT_EQ(r.exit_code, 0) << r.output;
  EXPECT_EQ(split(read_bytes(dir.file("slurm/tasks.txt")), '\n').size(), 1u);
  r = test::run_command("cd " + dir.path().string() + " && " + test::cli_path() +
                        " plan job.toml --ninja p.ninja 2>&1");
  EXPECT_EQ(r.exit_code, 2) << r.output;
  EXPECT_NE(r.output.find("bake 'b': the output '" + dir.file("x\\x0ay.png") +
                          "' holds a line feed, which a Ninja file"),
            std::string::npos)
      << r.output;
  EXPECT_FALSE(fs::exists(dir.file("p.ninja")));
}

// A job file's path is any bytes; a JSON string holds UTF-8 only. It was
// an internal error (exit 3) from the JSON writer.
TEST(PlanQuoting, JsonRefusesBytesThatAreNotUtf8) {
  test::TempDir dir;
  write_meshes(dir);
  const std::string job = dir.file("job\xff.toml");
  test::write_text(job, bake_entry("b", "b.png", 32));
  const test::CommandResult r =
      test::run_command("cd " + dir.path().string() + " && " + test::cli_path() +
                        " plan 'job\xff.toml' --json plan.json --ninja plan.ninja 2>&1");
  EXPECT_EQ(r.exit_code, 2) << r.output;
  EXPECT_NE(r.output.find("job\\xff.toml: bake 'b': the input '"), std::string::npos) << r.output;
  EXPECT_NE(r.output.find("is not valid UTF-8, which a JSON string cannot carry"), std::string::npos)
      << r.output;
  EXPECT_FALSE(fs::exists(dir.file("plan.json")));
  EXPECT_FALSE(fs::exists(dir.file("plan.ninja")));
}

// A bake with packed outputs is planned whole (a tile file carries no
// pack), and its task lists the pack among the files it writes.
// The plan of job file `job` in 4 tiles a bake (bakes of 64² and more).
void plan_in_tiles(const std::string& job, std::vector<PlanTask>& tasks) {
  std::vector<BakeJob> jobs;
  ASSERT_TRUE(load_job_file(job, jobs).is_ok());
  PlanOptions options;
  options.nmbake = "nmbake";
  options.job_file = job;
  options.tiles = 4;
  options.tiles_min_size = 64;
  const Status s = plan_jobs(jobs, options, tasks);
  ASSERT_TRUE(s.is_ok()) << s.message();
}

TEST(Plan, BakesWithPacksAreNotTiled) {
  test::TempDir dir;
  write_meshes(dir);
  const std::string job = dir.file("job.toml");
  test::write_text(job, bake_entry("packed", "m_<MAP>.png", 128) +
                            "maps = [\"normal\", \"height\"]\npack = [\"orm.png=r:height,g:0,b:1\"]\n");
  std::vector<PlanTask> tasks;
  plan_in_tiles(job, tasks);
  ASSERT_EQ(tasks.size(), 1u);
  EXPECT_EQ(tasks[0].kind, "bake");
  EXPECT_NE(std::find(tasks[0].outputs.begin(), tasks[0].outputs.end(), dir.file("orm.png")),
            tasks[0].outputs.end());
}

// A bake with texture sets is one task (not tiled) that lists each set's
// maps and packs, and several high files are each an input.
TEST(Plan, TextureSetsAreOneTaskListingEachSetsFiles) {
  test::TempDir dir;
  write_meshes(dir);
  test::write_text(dir.file("low.obj"),
                   "v 0 0 0\nv 1 0 0\nv 0 1 0\nv 1 1 0\nvt 0 0\nvt 1 0\nvt 0 1\nvt 1 1\nvn 0 0 1\n"
                   "usemtl body\nf 1/1/1 2/2/1 3/3/1\nusemtl visor\nf 2/2/1 4/4/1 3/3/1\n");
  test::write_text(dir.file("high2.obj"), "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n");
  const std::string job = dir.file("job.toml");
  test::write_text(job,
                   "[[bake]]\nname = \"sets\"\nlow = \"low.obj\"\nhigh = [\"high.obj\", \"high2.obj\"]\n"
                   "size = 128\noutputs = [\"<LOW>_<SET>_<MAP>.png\"]\nmaps = [\"normal\", \"ao\"]\n"
                   "pack = [\"<SET>_orm.png=r:ao,g:0,b:1\"]\n");
  std::vector<PlanTask> tasks;
  plan_in_tiles(job, tasks);
  ASSERT_EQ(tasks.size(), 1u);
  EXPECT_EQ(tasks[0].kind, "bake");
  for (const char* file : {"low_body_normal.png", "low_body_ao.png", "low_visor_normal.png",
                           "low_visor_ao.png", "body_orm.png", "visor_orm.png"}) {
    EXPECT_NE(std::find(tasks[0].outputs.begin(), tasks[0].outputs.end(), dir.file(file)),
              tasks[0].outputs.end())
        << file;
  }
  for (const char* file : {"high.obj", "high2.obj"}) {
    EXPECT_NE(std::find(tasks[0].inputs.begin(), tasks[0].inputs.end(), dir.file(file)),
              tasks[0].inputs.end())
        << file;
  }
}

}  // namespace
}  // namespace nmbake
