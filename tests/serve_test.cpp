// `nmbake serve` (README, "Live sessions") through the real binary: a
// session fed and read through pipes, each bake's maps against a cold
// `nmbake bake` of the same keys (a job file), the cache's reuse, bad
// requests, cancel and quit; and `nmbake bake --progress json`.
#include <gtest/gtest.h>
#include <sys/types.h>
#include <sys/wait.h>
#include <unistd.h>

#include <csignal>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <nlohmann/json.hpp>
#include <sstream>
#include <string>
#include <utility>
#include <vector>

#include "test_util.hpp"

namespace nmbake {
namespace {

using nlohmann::json;

std::string file_bytes(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  std::ostringstream s;
  s << in.rdbuf();
  return s.str();
}

// A `nmbake serve` child with its stdin and stdout on pipes.
class ServeProcess {
 public:
  explicit ServeProcess(const std::string& folder, bool hold = false, const char* budget = "8G") {
    int in[2], out[2];
    EXPECT_EQ(::pipe(in), 0);
    EXPECT_EQ(::pipe(out), 0);
    pid_ = ::fork();
    if (pid_ == 0) {
      ::dup2(in[0], 0);
      ::dup2(out[1], 1);
      ::close(in[0]);
      ::close(in[1]);
      ::close(out[0]);
      ::close(out[1]);
      if (::chdir(folder.c_str()) != 0) ::_exit(99);
      if (hold) ::setenv("NMBAKE_SERVE_TEST_HOLD", "1", 1);
      const std::string cli = test::cli_path();
      ::execl(cli.c_str(), cli.c_str(), "--threads", "2", "serve", "--memory-budget", budget,
              static_cast<char*>(nullptr));
      ::_exit(98);
    }
    ::close(in[0]);
    ::close(out[1]);
    to_ = ::fdopen(in[1], "w");
    from_ = ::fdopen(out[0], "r");
  }
  ~ServeProcess() {
    close_input();
    if (from_ != nullptr) std::fclose(from_);
    if (pid_ > 0) wait();
  }
  void send(const std::string& line) {
    std::fputs((line + "\n").c_str(), to_);
    std::fflush(to_);
  }
  void send(const json& request) { send(request.dump()); }
  // The next answer; a null json at the end of the output.
  json next() {
    std::string line;
    int c = 0;
    while ((c = std::fgetc(from_)) != EOF && c != '\n') line += static_cast<char>(c);
    if (line.empty() && c == EOF) return json();
    return json::parse(line);
  }
  // The next answer that is not a progress answer.
  json next_answer() {
    for (;;) {
      json a = next();
      if (a.is_null() || a["type"] != "progress") return a;
    }
  }
  void close_output() {
    std::fclose(from_);
    from_ = nullptr;
  }
  void close_input() {
    if (to_ != nullptr) std::fclose(to_);
    to_ = nullptr;
  }
  int wait() {
    int status = 0;
    ::waitpid(pid_, &status, 0);
    pid_ = -1;
    return WIFEXITED(status) ? WEXITSTATUS(status) : -1;
  }

 private:
  pid_t pid_ = -1;
  std::FILE* to_ = nullptr;
  std::FILE* from_ = nullptr;
};

// The small sphere scene (nmbake-gen) in `dir`: sphere_low.obj,
// sphere_high.ply, sphere_cage.obj; and a second low mesh and high mesh.
void make_scenes(const test::TempDir& dir) {
  const std::string gen = test::gen_path();
  for (const std::string& args : {" sphere --high-cells 32 --low-cells 4 --out-dir " + dir.file(""),
                                  " sphere --high-cells 24 --low-cells 3 --out-dir " + dir.file("other")}) {
    const auto r = test::run_command(gen + args);
    ASSERT_EQ(r.exit_code, 0) << r.output;
  }
}

// The keys as a job file's [[bake]] (JSON strings, numbers and lists of
// strings are TOML too).
std::string job_toml(const json& bake) {
  std::string toml = "[[bake]]\n";
  for (const auto& [key, value] : bake.items()) toml += key + " = " + value.dump() + "\n";
  return toml;
}

// A cold bake of the same keys with the CLI, its outputs renamed "cold_*".
json cold_bake(const test::TempDir& dir, json bake) {
  json outputs = json::array();
  for (const auto& out : bake["outputs"]) outputs.push_back("cold_" + out.get<std::string>());
  bake["outputs"] = outputs;
  test::write_text(dir.file("cold.toml"), job_toml(bake));
  const auto r = test::run_command(test::cli_path() + " -q bake " + dir.file("cold.toml"));
  EXPECT_EQ(r.exit_code, 0) << r.output;
  return outputs;
}

json bake_request(const std::string& id, const json& bake) {
  return {{"id", id}, {"type", "bake"}, {"bake", bake}};
}

// Each result's maps equal a cold bake's; reuse as the cache allows.
TEST(Serve, SessionBakesTheBytesOfColdBakesAndReusesTheHigh) {
  test::TempDir dir;
  make_scenes(dir);
  ServeProcess serve(dir.path().string());
  const json ready = serve.next();
  EXPECT_EQ(ready["type"], "ready");
  EXPECT_EQ(ready["protocol"], 1);

  const json base = {{"low", "sphere_low.obj"}, {"high", "sphere_high.ply"}, {"size", 64}, {"samples", 1}};
  struct Step {
    std::string id;
    json changes;
    std::vector<std::string> maps;  // files written
    bool high_mesh, high_scene;     // reuse expected
  };
  const std::vector<Step> steps = {
      {"first", {}, {"first.png"}, false, false},
      {"low", {{"low", "other/sphere_low.obj"}}, {"low.png"}, true, true},
      {"cage", {{"cage", "sphere_cage.obj"}}, {"cage.png"}, true, true},
      {"distances", {{"front", "3%"}, {"back", 0.02}}, {"distances.png"}, true, true},
      // The map set shapes the scene's data of the high: the mesh is reused, the scene built again.
      {"maps", {{"maps", {"normal", "height"}}}, {"maps_normal.png", "maps_height.png"}, true, false},
      {"high", {}, {"high.png"}, false, false},
  };
  for (const Step& step : steps) {
    if (step.id == "high") {
      // Other bytes under the same name, of the same size and date: a
      // vertex's x moved by its last bit (a binary little-endian PLY).
      const std::string path = dir.file("sphere_high.ply");
      const auto date = std::filesystem::last_write_time(path);
      std::string bytes = file_bytes(path);
      const std::size_t data = bytes.find("end_header\n") + 11;
      bytes[data] = static_cast<char>(bytes[data] ^ 1);
      test::write_text(path, bytes);
      std::filesystem::last_write_time(path, date);
    }
    json bake = base;
    for (const auto& [k, v] : step.changes.items()) bake[k] = v;
    bake["outputs"] = step.maps.size() == 1 ? json{step.id + ".png"} : json{step.id + "_<MAP>.png"};
    serve.send(bake_request(step.id, bake));
    const json answer = serve.next_answer();
    ASSERT_EQ(answer["type"], "result") << step.id << ": " << answer.dump();
    EXPECT_EQ(answer["id"], step.id);
    EXPECT_EQ(answer["reused"]["high_mesh"], step.high_mesh) << step.id;
    EXPECT_EQ(answer["reused"]["high_scene"], step.high_scene) << step.id;
    EXPECT_EQ(answer["report"]["session"]["reused_high_scene"], step.high_scene) << step.id;
    EXPECT_TRUE(answer["report"].contains("coverage")) << step.id;
    cold_bake(dir, bake);
    for (const std::string& map : step.maps) {
      const std::string served = file_bytes(dir.file(map));
      ASSERT_FALSE(served.empty()) << map;
      EXPECT_EQ(served, file_bytes(dir.file("cold_" + map))) << step.id << ": " << map;
    }
  }

  serve.send(json{{"id", "st"}, {"type", "status"}});
  const json status = serve.next_answer();
  EXPECT_EQ(status["type"], "status");
  EXPECT_EQ(status["busy"], false);
  EXPECT_EQ(status["queued"], 0);
  EXPECT_GE(status["cache"]["entries"].get<int>(), 2);
  EXPECT_GT(status["cache"]["bytes"].get<std::uint64_t>(), 0u);

  serve.send(json{{"type", "quit"}});
  EXPECT_EQ(serve.next_answer()["type"], "bye");
  EXPECT_TRUE(serve.next().is_null());
  EXPECT_EQ(serve.wait(), 0);
}

// Over the budget the least recently used entry goes: with room for one
// entry, the built scene pushes the loaded mesh out, and the next bake's
// load pushes the scene out.
TEST(Serve, MemoryBudgetEvictsLeastRecentlyUsed) {
  test::TempDir dir;
  make_scenes(dir);
  ServeProcess serve(dir.path().string(), false, "4K");
  EXPECT_EQ(serve.next()["type"], "ready");
  const json bake = {{"low", "sphere_low.obj"},
                     {"high", "sphere_high.ply"},
                     {"outputs", {"m.png"}},
                     {"size", 32},
                     {"samples", 1}};
  serve.send(bake_request("1", bake));
  json a = serve.next_answer();
  ASSERT_EQ(a["type"], "result") << a.dump();
  EXPECT_EQ(a["report"]["session"]["cache"]["evictions"], 1);
  serve.send(bake_request("2", bake));
  a = serve.next_answer();
  EXPECT_EQ(a["reused"]["high_mesh"], false);
  EXPECT_EQ(a["reused"]["high_scene"], false);
  EXPECT_EQ(a["report"]["session"]["cache"]["evictions"], 3);
  serve.send(json{{"id", "s"}, {"type", "status"}});
  a = serve.next_answer();
  EXPECT_EQ(a["cache"]["entries"], 1);
  EXPECT_EQ(a["cache"]["budget"], 4096);
  EXPECT_EQ(a["cache"]["evictions"], 3);
  serve.send(json{{"type", "quit"}});
  EXPECT_EQ(serve.next_answer()["type"], "bye");
  EXPECT_EQ(serve.wait(), 0);
}

// A bad request is answered with an error naming what is wrong, and the
// session goes on.
TEST(Serve, BadRequestsAreAnsweredAndTheSessionGoesOn) {
  test::TempDir dir;
  make_scenes(dir);
  ServeProcess serve(dir.path().string());
  EXPECT_EQ(serve.next()["type"], "ready");
  const json good = {{"low", "sphere_low.obj"},
                     {"high", "sphere_high.ply"},
                     {"outputs", {"good.png"}},
                     {"size", 32},
                     {"samples", 1}};
  serve.send(std::string("this is not json"));
  json a = serve.next_answer();
  EXPECT_EQ(a["type"], "error");
  EXPECT_TRUE(a["id"].is_null());
  EXPECT_EQ(a["code"], 2);

  json typo = good;
  typo["smaples"] = 4;
  serve.send(bake_request("typo", typo));
  a = serve.next_answer();
  EXPECT_EQ(a["id"], "typo");
  EXPECT_EQ(a["code"], 2);
  EXPECT_NE(a["message"].get<std::string>().find("smaples"), std::string::npos) << a.dump();

  json bad_value = good;
  bad_value["space"] = "tangnet";
  serve.send(bake_request("value", bad_value));
  a = serve.next_answer();
  EXPECT_EQ(a["code"], 2);
  EXPECT_NE(a["message"].get<std::string>().find("bake.space"), std::string::npos) << a.dump();

  json missing = good;
  missing["high"] = "nowhere.ply";
  serve.send(bake_request("missing", missing));
  a = serve.next_answer();
  EXPECT_EQ(a["id"], "missing");
  EXPECT_EQ(a["code"], 2);
  EXPECT_NE(a["message"].get<std::string>().find("nowhere.ply"), std::string::npos) << a.dump();

  serve.send(json{{"id", 7}, {"type", "unknown"}});
  a = serve.next_answer();
  EXPECT_EQ(a["id"], 7);
  EXPECT_NE(a["message"].get<std::string>().find("type"), std::string::npos);
  serve.send(json{{"type", "status"}});
  a = serve.next_answer();
  EXPECT_NE(a["message"].get<std::string>().find("id"), std::string::npos);

  serve.send(bake_request("good", good));
  a = serve.next_answer();
  EXPECT_EQ(a["type"], "result") << a.dump();
  EXPECT_EQ(a["id"], "good");
  EXPECT_TRUE(std::filesystem::exists(dir.file("good.png")));
  // EOF is quit.
  serve.close_input();
  EXPECT_EQ(serve.next_answer()["type"], "bye");
  EXPECT_EQ(serve.wait(), 0);
}

// Cancel: a queued bake is dropped, a running one stops with 130 and writes
// nothing. The test hold (NMBAKE_SERVE_TEST_HOLD) keeps each bake at its
// first progress call until it is cancelled or the input ends: no timing.
TEST(Serve, CancelStopsARunningBakeAndDropsAQueuedOne) {
  test::TempDir dir;
  make_scenes(dir);
  ServeProcess serve(dir.path().string(), true);
  EXPECT_EQ(serve.next()["type"], "ready");
  auto bake = [](const std::string& out) {
    return json{{"low", "sphere_low.obj"}, {"high", "sphere_high.ply"}, {"outputs", {out}}, {"size", 32}};
  };
  serve.send(bake_request("a", bake("a.png")));
  json a = serve.next();
  EXPECT_EQ(a["type"], "progress");  // running, held
  EXPECT_EQ(a["id"], "a");
  serve.send(bake_request("b", bake("b.png")));
  serve.send(bake_request("c", bake("c.png")));
  serve.send(json{{"id", "s"}, {"type", "status"}});
  a = serve.next_answer();
  EXPECT_EQ(a["busy"], true);
  EXPECT_EQ(a["queued"], 2);
  serve.send(json{{"id", "x"}, {"type", "cancel"}, {"target", "b"}});
  a = serve.next_answer();
  EXPECT_EQ(a["id"], "b");
  EXPECT_EQ(a["code"], 130);
  serve.send(json{{"id", "y"}, {"type", "cancel"}, {"target", "nope"}});
  a = serve.next_answer();
  EXPECT_EQ(a["id"], "y");
  EXPECT_EQ(a["code"], 2);
  serve.send(json{{"id", "z"}, {"type", "cancel"}, {"target", "a"}});
  a = serve.next_answer();
  EXPECT_EQ(a["id"], "a");
  EXPECT_EQ(a["code"], 130);
  // c runs (held until the input ends), then bye.
  EXPECT_EQ(serve.next()["id"], "c");
  serve.send(json{{"type", "quit"}});
  a = serve.next_answer();
  EXPECT_EQ(a["id"], "c");
  EXPECT_EQ(a["type"], "result") << a.dump();
  EXPECT_EQ(serve.next_answer()["type"], "bye");
  EXPECT_EQ(serve.wait(), 0);
  EXPECT_FALSE(std::filesystem::exists(dir.file("a.png")));
  EXPECT_FALSE(std::filesystem::exists(dir.file("b.png")));
  EXPECT_TRUE(std::filesystem::exists(dir.file("c.png")));
  for (const auto& entry : std::filesystem::directory_iterator(dir.path()))
    EXPECT_EQ(entry.path().string().find(".tmp"), std::string::npos) << entry.path();
}

// A closed stdout ends the session cleanly (exit 0) at its next answer.
TEST(Serve, ClosedOutputEndsTheSession) {
  test::TempDir dir;
  std::signal(SIGPIPE, SIG_IGN);  // our own writes to a session that is gone
  ServeProcess serve(dir.path().string());
  EXPECT_EQ(serve.next()["type"], "ready");
  serve.close_output();
  serve.send(json{{"id", 1}, {"type", "status"}});
  EXPECT_EQ(serve.wait(), 0);
}

// --progress json: one JSON object a line on stderr.
TEST(Serve, BakeProgressJsonLines) {
  test::TempDir dir;
  make_scenes(dir);
  const auto r = test::run_command("(cd " + dir.path().string() + " && " + test::cli_path() +
                                   " -q bake --low sphere_low.obj --high sphere_high.ply -o p.png --size 32 "
                                   "--samples 1 --progress json 2>progress.txt)");
  ASSERT_EQ(r.exit_code, 0) << r.output;
  std::istringstream lines(file_bytes(dir.file("progress.txt")));
  std::string line;
  int count = 0;
  bool write_done = false;
  while (std::getline(lines, line)) {
    const json j = json::parse(line);
    ASSERT_TRUE(j.contains("stage") && j.contains("fraction") && j.contains("elapsed_seconds") &&
                j.contains("eta_seconds"))
        << line;
    EXPECT_GE(j["fraction"].get<double>(), 0.0);
    EXPECT_LE(j["fraction"].get<double>(), 1.0);
    if (j["stage"] == "write" && j["fraction"] == 1.0) write_done = true;
    ++count;
  }
  EXPECT_GT(count, 3);
  EXPECT_TRUE(write_done);
}

}  // namespace
}  // namespace nmbake
