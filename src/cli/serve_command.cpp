// `nmbake serve`: a live bake session (docs/guide/live.md). Requests
// are JSON lines on stdin, answers JSON lines on stdout (protocol 1). A
// reader thread reads stdin all the time, so that status and cancel are
// answered while a bake runs; the bakes run one at a time, in request
// order, on the main thread, sharing a HighCache (session.hpp) that keeps
// the high mesh and its BVH between requests.
#include <atomic>
#include <chrono>
#include <condition_variable>
#include <csignal>
#include <cstdio>
#include <cstdlib>
#include <deque>
#include <exception>
#include <filesystem>
#include <iostream>
#include <memory>
#include <mutex>
#include <nlohmann/json.hpp>
#include <string>
#include <thread>

#include "commands.hpp"
#include "nmbake/bake.hpp"
#include "nmbake/cleanup.hpp"
#include "nmbake/memory.hpp"
#include "nmbake/session.hpp"
#include "nmbake/task.hpp"

namespace nmbake::cli {

namespace {

// Answers keep their keys in the order written ("id" and "type" first; the
// report as --report writes it).
using json = nlohmann::ordered_json;

constexpr int kProtocol = 1;
constexpr int kCancelled = 130;  // as a shell reports a bake stopped by Ctrl-C

struct ServeFlags {
  std::string memory_budget;  // "" : half of the memory available at start
};

// Thrown from a bake's progress listener to stop it (bake.hpp: ProgressFn).
struct BakeCancelled {};

struct Request {
  json id;
  BakeJob job;
};

// What the reader thread and the bakes share. Held by a shared_ptr: the
// reader may still sit in a read of stdin when the session ends.
struct Session {
  std::mutex mutex;
  std::condition_variable wake;
  std::deque<Request> queue;
  bool busy = false;
  json running_id;
  std::atomic<bool> cancel_running{false};
  bool quit = false;                // quit or EOF: the queue is baked, then bye
  std::atomic<bool> broken{false};  // stdout is gone: stop at once
  std::mutex out_mutex;             // one answer a line, whole
  std::mutex cache_mutex;           // the HighCache: the bake's calls, status
  std::unique_ptr<HighCache> cache;
  // Tests only (NMBAKE_SERVE_TEST_HOLD=1): each bake waits at its first
  // progress call until it is cancelled or the input ends, so that a test
  // can see it running, queue others behind it and cancel either without
  // depending on timing.
  bool test_hold = false;

  void send(const json& answer) {
    const std::string line = answer.dump(-1, ' ', false, json::error_handler_t::replace) + "\n";
    const std::lock_guard<std::mutex> lock(out_mutex);
    if (broken) return;
    if (std::fwrite(line.data(), 1, line.size(), stdout) != line.size() || std::fflush(stdout) != 0) {
      broken = true;
      cancel_running = true;
      const std::lock_guard<std::mutex> state(mutex);
      wake.notify_all();
    }
  }
  void error(const json& id, int code, const std::string& message) {
    send({{"id", id}, {"type", "error"}, {"code", code}, {"message", printable_text(message)}});
  }
  HighCacheStats cache_stats() {
    const std::lock_guard<std::mutex> lock(cache_mutex);
    return cache->stats();
  }
};

json cache_json(const HighCacheStats& s) {
  return {{"entries", s.entries}, {"bytes", s.bytes}, {"budget", s.budget}, {"evictions", s.evictions}};
}

// The session's cache, each call under the session's lock (status reads it
// from the reader thread).
class LockedStore final : public HighStore {
 public:
  explicit LockedStore(Session& session) : s_(session) {}
  std::shared_ptr<const LoadedHigh> find_loaded(const std::string& key) override {
    const std::lock_guard<std::mutex> lock(s_.cache_mutex);
    return s_.cache->find_loaded(key);
  }
  void keep_loaded(const std::string& key, std::shared_ptr<const LoadedHigh> high) override {
    const std::lock_guard<std::mutex> lock(s_.cache_mutex);
    s_.cache->keep_loaded(key, std::move(high));
  }
  std::shared_ptr<const BuiltHigh> find_built(const std::string& key) override {
    const std::lock_guard<std::mutex> lock(s_.cache_mutex);
    return s_.cache->find_built(key);
  }
  void keep_built(const std::string& key, std::shared_ptr<const BuiltHigh> high) override {
    const std::lock_guard<std::mutex> lock(s_.cache_mutex);
    s_.cache->keep_built(key, std::move(high));
  }

 private:
  Session& s_;
};

// One request line: answered at once (status, cancel, a bad request) or
// queued (bake). False on quit.
bool handle_line(Session& s, const std::string& line) {
  nlohmann::json request;
  try {
    request = nlohmann::json::parse(line);
  } catch (const json::exception& e) {
    s.error(nullptr, kBadInput, std::string("not a JSON object: ") + e.what());
    return true;
  }
  if (!request.is_object()) {
    s.error(nullptr, kBadInput, "not a JSON object");
    return true;
  }
  const json id = request.contains("id") ? json(request["id"]) : json(nullptr);
  const auto type_it = request.find("type");
  if (type_it == request.end() || !type_it->is_string()) {
    s.error(id, kBadInput, "type: missing (bake, status, cancel or quit)");
    return true;
  }
  const std::string type = type_it->get<std::string>();
  if (type == "quit") {
    const std::lock_guard<std::mutex> lock(s.mutex);
    s.quit = true;
    s.wake.notify_all();
    return false;
  }
  if (!id.is_string() && !id.is_number()) {
    s.error(nullptr, kBadInput, id.is_null() ? "id: missing" : "id: expected a string or a number");
    return true;
  }
  // Every key a request of this type takes: a typo is an error, not ignored.
  const auto keys_ok = [&](std::initializer_list<const char*> keys) {
    for (const auto& [key, value] : request.items()) {
      bool known = key == "id" || key == "type";
      for (const char* k : keys) known = known || key == k;
      if (!known) {
        s.error(id, kBadInput, "unknown key \"" + key + "\" in a " + type + " request");
        return false;
      }
    }
    return true;
  };
  if (type == "status") {
    if (!keys_ok({})) return true;
    json answer{{"id", id}, {"type", "status"}};
    {
      const std::lock_guard<std::mutex> lock(s.mutex);
      answer["busy"] = s.busy;
      answer["queued"] = s.queue.size();
    }
    answer["cache"] = cache_json(s.cache_stats());
    s.send(answer);
  } else if (type == "cancel") {
    if (!keys_ok({"target"})) return true;
    const auto target = request.find("target");
    if (target == request.end() || (!target->is_string() && !target->is_number())) {
      s.error(id, kBadInput, "target: expected the id of a bake");
      return true;
    }
    std::unique_lock<std::mutex> lock(s.mutex);
    for (auto it = s.queue.begin(); it != s.queue.end(); ++it) {
      if (it->id == json(*target)) {
        const json cancelled = it->id;
        s.queue.erase(it);
        lock.unlock();
        s.error(cancelled, kCancelled, "cancelled before it started");
        return true;
      }
    }
    if (s.busy && s.running_id == json(*target)) {
      s.cancel_running = true;  // the bake answers 130 at its next progress call
      s.wake.notify_all();
      return true;
    }
    lock.unlock();
    s.error(id, kBadInput, "target: no queued or running bake has the id " + target->dump());
  } else if (type == "bake") {
    if (!keys_ok({"bake", "folder"})) return true;
    std::string folder;
    if (const auto f = request.find("folder"); f != request.end()) {
      if (!f->is_string()) {
        s.error(id, kBadInput, "folder: expected a path");
        return true;
      }
      folder = f->get<std::string>();
    }
    const auto bake = request.find("bake");
    if (bake == request.end()) {
      s.error(id, kBadInput, "bake: missing (the keys of a job file's [[bake]])");
      return true;
    }
    Request r{id, {}};
    if (const Status st = request_bake_job(*bake, folder, r.job); !st) {
      s.error(id, st.code() == StatusCode::internal ? kInternal : kBadInput, st.message());
      return true;
    }
    const std::lock_guard<std::mutex> lock(s.mutex);
    s.queue.push_back(std::move(r));
    s.wake.notify_all();
  } else {
    s.error(id, kBadInput, "type: unknown \"" + type + "\" (bake, status, cancel or quit)");
  }
  return true;
}

void read_requests(const std::shared_ptr<Session>& s) {
  std::string line;
  while (!s->broken && std::getline(std::cin, line)) {
    if (line.find_first_not_of(" \t\r") == std::string::npos) continue;
    if (!handle_line(*s, line)) return;
  }
  const std::lock_guard<std::mutex> lock(s->mutex);
  s->quit = true;  // EOF
  s->wake.notify_all();
}

// Runs one bake and answers it: result, or error 2, 3 or 130.
void run_request(Session& s, const Request& request) {
  const json& id = request.id;
  const BakeJob& job = request.job;
  Status st = validate_options(job.options);
  if (st) st = check_bake_inputs(job.options);
  if (!st) {
    s.error(id, st.code() == StatusCode::internal ? kInternal : kBadInput, st.message());
    return;
  }
  // At most ten progress answers a second; a cancel stops the bake at its
  // next progress call (never once it has begun writing: bake.hpp).
  auto last = std::chrono::steady_clock::now() - std::chrono::seconds(1);
  bool held = !s.test_hold;
  const ProgressFn listener = [&](const char* stage, double fraction) {
    if (!held) {
      held = true;
      s.send({{"id", id}, {"type", "progress"}, {"stage", stage}, {"fraction", fraction}});
      std::unique_lock<std::mutex> lock(s.mutex);
      s.wake.wait(lock, [&] { return s.cancel_running || s.quit || s.broken; });
    }
    const bool writing = std::string_view(stage) == "write" && fraction > 0.0;
    if (s.cancel_running && !writing) throw BakeCancelled{};
    const auto now = std::chrono::steady_clock::now();
    if (now - last < std::chrono::milliseconds(100)) return;
    last = now;
    s.send({{"id", id}, {"type", "progress"}, {"stage", stage}, {"fraction", fraction}});
  };
  BakeReport report;
  HighReuse reused;
  LockedStore store(s);
  try {
    st = bake(job.options, report, listener, &store, &reused);
    if (st && !job.report_path.empty()) {
      st = check_output_target(job.report_path);
      if (st) st = write_file_atomically(job.report_path, {report.to_json()}, "the report");
    }
  } catch (const BakeCancelled&) {
    s.error(id, kCancelled, "cancelled");
    return;
  } catch (const std::exception& e) {
    s.error(id, kInternal, std::string("internal error: ") + e.what());
    return;
  }
  if (!st) {
    s.error(id, st.code() == StatusCode::internal ? kInternal : kBadInput, st.message());
    return;
  }
  json report_json = json::parse(report.to_json());
  // The session's figures beside the bake's own (a CLI report has none).
  report_json["session"] = {{"reused_high_mesh", reused.high_mesh},
                            {"reused_high_scene", reused.high_scene},
                            {"cache", cache_json(s.cache_stats())}};
  s.send({{"id", id},
          {"type", "result"},
          {"report", std::move(report_json)},
          {"reused", {{"high_mesh", reused.high_mesh}, {"high_scene", reused.high_scene}}}});
}

int run_serve(const ServeFlags& flags) {
  std::uint64_t budget = 0;
  if (!flags.memory_budget.empty()) {
    if (!parse_memory_size(flags.memory_budget, budget)) {
      print_error("--memory-budget " + flags.memory_budget + ": expected a size such as 8G or 512M");
      return kBadInput;
    }
  } else {
    const MemoryLimit available = available_memory();
    budget = available.bytes > 0 ? available.bytes / 2 : 8ull << 30;
  }
  // A closed stdout is an answer that cannot be written (EPIPE), not a signal.
  std::signal(SIGPIPE, SIG_IGN);
  auto session = std::make_shared<Session>();
  session->cache = std::make_unique<HighCache>(budget);
  const char* hold = std::getenv("NMBAKE_SERVE_TEST_HOLD");
  session->test_hold = hold != nullptr && std::string(hold) == "1";
  session->send({{"type", "ready"}, {"protocol", kProtocol}, {"nmbake", kNmbakeVersion}});
  std::thread(read_requests, session).detach();
  Session& s = *session;
  for (;;) {
    Request request;
    {
      std::unique_lock<std::mutex> lock(s.mutex);
      s.wake.wait(lock, [&] { return s.broken || !s.queue.empty() || s.quit; });
      if (s.broken) return kSuccess;
      if (s.queue.empty()) break;  // quit, and every bake asked for is answered
      request = std::move(s.queue.front());
      s.queue.pop_front();
      s.busy = true;
      s.running_id = request.id;
      s.cancel_running = false;
    }
    run_request(s, request);
    const std::lock_guard<std::mutex> lock(s.mutex);
    s.busy = false;
    s.running_id = nullptr;
  }
  s.send({{"type", "bye"}});
  // The reader may still wait for a line: the process ends without it.
  std::fflush(stdout);
  return kSuccess;
}

}  // namespace

Runner add_serve_command(CLI::App& app, const GlobalOptions& global) {
  (void)global;
  auto flags = std::make_shared<ServeFlags>();
  CLI::App* cmd = app.add_subcommand(
      "serve", "a live bake session: JSON requests on stdin, JSON answers on stdout (docs/guide/live.md)");
  cmd->add_option("--memory-budget", flags->memory_budget,
                  "memory for the high meshes and BVHs kept between requests, e.g. 8G (default: half of "
                  "the memory available at start)");
  return [flags]() { return run_serve(*flags); };
}

}  // namespace nmbake::cli
