// `nmbake view --low L --map normal.png [--map ao.png ...] [--high H]
// [--report R.json] -o review.html`: the review .glb (beside the page, same
// stem) and the self-contained page (review.hpp).
// `--serve [--port N]`: the page served on 127.0.0.1 only (cpp-httplib,
// libcpp-httplib-dev); it polls /state, which changes when a map file's
// size or modification time does, and then fetches /map/I/TILE.png again,
// so a re-bake shows without a click. Ctrl-C stops it (exit 0).
#include <httplib.h>
#include <pthread.h>
#include <sys/stat.h>

#include <atomic>
#include <cctype>
#include <chrono>
#include <csignal>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <mutex>
#include <nlohmann/json.hpp>
#include <thread>

#include "commands.hpp"
#include "nmbake/cleanup.hpp"
#include "nmbake/job.hpp"
#include "nmbake/maps.hpp"
#include "nmbake/review.hpp"
#include "nmbake/udim.hpp"

namespace nmbake::cli {

namespace {

struct ViewCommandFlags {
  std::string job;  // `nmbake view JOB.toml -o DIR`: every bake of the job
  std::string low, high, report, output;
  std::vector<std::string> maps;
  std::uint64_t high_budget = 200000;
  std::string three_dir = "/usr/share/javascript/three";
  ViewFlags camera;
  bool serve = false;
  int port = 8790;
};

int fail(const Status& s) {
  print_error(s.message());
  return s.code() == StatusCode::internal ? kInternal : kBadInput;
}

// The kind of a map given without KIND=: the report's own list of outputs
// first, else a map word in the file name (the longest that fits), else
// normal for the first map.
Status map_kind(const std::string& path, const nlohmann::json& report, bool first, std::string& kind) {
  const std::string name = std::filesystem::path(path).filename().string();
  if (report.is_object() && report.contains("maps") && report["maps"].is_array()) {
    for (const auto& m : report["maps"]) {
      if (!m.is_object() || !m.contains("outputs") || !m["outputs"].is_array() || !m.contains("map"))
        continue;
      for (const auto& out : m["outputs"]) {
        if (out.is_string() && (out.get<std::string>() == path ||
                                std::filesystem::path(out.get<std::string>()).filename().string() == name)) {
          kind = m["map"].get<std::string>();
          return Status::ok();
        }
      }
    }
  }
  static const char* const kWords[] = {"bent-normal", "object-normal", "vertex-color", "base-color",
                                       "normal",      "height",        "ao",           "curvature",
                                       "thickness",   "position",      "miss",         "roughness",
                                       "metallic",    "emissive",      "opacity",      "id"};
  for (const char* word : kWords) {
    // As a whole word of the name: "moon_normal.png", "rock.ao.png".
    const std::string w = word;
    for (std::size_t at = name.find(w); at != std::string::npos; at = name.find(w, at + 1)) {
      const bool start = at == 0 || !std::isalnum(static_cast<unsigned char>(name[at - 1]));
      const std::size_t end = at + w.size();
      const bool stop = end >= name.size() || !std::isalnum(static_cast<unsigned char>(name[end]));
      if (start && stop) {
        kind = w;
        return Status::ok();
      }
    }
  }
  if (first) {
    kind = "normal";
    return Status::ok();
  }
  return Status::bad_input(path + ": cannot tell which map this is: write KIND=" + path +
                           " (KIND: " + review_map_kinds() + ")");
}

Status write_file(const std::string& path, const std::string& bytes) {
  const std::string temp = path + ".tmp";
  {
    std::ofstream out(temp, std::ios::binary);
    out.write(bytes.data(), static_cast<std::streamsize>(bytes.size()));
    out.close();
    if (!out) {
      std::error_code ec;
      std::filesystem::remove(temp, ec);
      return Status::io(path + ": cannot write");
    }
  }
  std::error_code ec;
  std::filesystem::rename(temp, path, ec);
  if (ec) return Status::io(path + ": cannot write: " + ec.message());
  return Status::ok();
}

// Size and modification time of every map file, one line each: what /state
// compares.
std::string map_signature(const std::vector<ReviewMap>& maps, const std::vector<int>& tiles) {
  std::string out;
  for (const ReviewMap& m : maps) {
    for (const int tile : tiles) {
      const std::string path = udim_path(m.path, tile);
      struct stat st {};
      if (::stat(path.c_str(), &st) != 0) {
        out += path + " missing\n";
        continue;
      }
      out += path + " " + std::to_string(st.st_size) + " " + std::to_string(st.st_mtim.tv_sec) + "." +
             std::to_string(st.st_mtim.tv_nsec) + "\n";
    }
  }
  return out;
}

sigset_t stop_signals() {
  sigset_t signals;
  sigemptyset(&signals);
  sigaddset(&signals, SIGINT);
  sigaddset(&signals, SIGTERM);
  return signals;
}

int serve_review(const ViewCommandFlags& f, const GlobalOptions& global, const ReviewOptions& options,
                 const std::string& html, const std::vector<int>& tiles) {
  httplib::Server server;
  std::mutex mutex;
  std::string signature = map_signature(options.maps, tiles);
  std::uint64_t version = 0;
  server.Get("/", [&](const httplib::Request&, httplib::Response& res) {
    res.set_content(html, "text/html; charset=utf-8");
  });
  // The maps' version: one more each time their files change on disk.
  server.Get("/state", [&](const httplib::Request&, httplib::Response& res) {
    std::lock_guard<std::mutex> lock(mutex);
    const std::string now = map_signature(options.maps, tiles);
    if (now != signature) {
      signature = now;
      ++version;
    }
    res.set_header("Cache-Control", "no-store");
    res.set_content("{\"version\":" + std::to_string(version) + "}", "application/json");
  });
  server.Get(R"(/map/(\d+)/(\d+)\.png)", [&](const httplib::Request& req, httplib::Response& res) {
    const std::size_t index = std::stoul(req.matches[1].str());
    const int tile = std::stoi(req.matches[2].str());
    if (index >= options.maps.size() || std::find(tiles.begin(), tiles.end(), tile) == tiles.end()) {
      res.status = 404;
      return;
    }
    std::string png;
    float range[2];
    const ReviewMap& m = options.maps[index];
    if (const Status s = review_map_png(m.kind, udim_path(m.path, tile), png, range); !s) {
      // A map being rewritten: the page keeps the one it has and asks again.
      res.status = 503;
      res.set_content(s.message(), "text/plain");
      return;
    }
    res.set_header("Cache-Control", "no-store");
    res.set_content(png, "image/png");
  });

  // 127.0.0.1 only: the page is for this machine.
  int port = f.port;
  if (port == 0) {
    port = server.bind_to_any_port("127.0.0.1");
  } else if (!server.bind_to_port("127.0.0.1", port)) {
    port = -1;
  }
  if (port <= 0) {
    print_error("cannot listen on 127.0.0.1:" + std::to_string(f.port) +
                " (in use? --port 0 picks a free one)");
    return kBadInput;
  }
  // Ctrl-C and SIGTERM end the server cleanly: run_view() blocked them
  // before any thread started, and one thread waits for them here.
  sigset_t signals = stop_signals();
  std::atomic<bool> stopping{false};
  std::thread waiter([&]() {
    int signal = 0;
    sigwait(&signals, &signal);
    stopping = true;
    server.stop();
  });
  std::printf("view: serving http://127.0.0.1:%d/ (Ctrl-C to stop)\n", port);
  std::fflush(stdout);
  const bool listened = server.listen_after_bind();
  if (!stopping) {
    // The server ended on its own: wake the waiter.
    pthread_kill(waiter.native_handle(), SIGTERM);
  }
  waiter.join();
  if (!global.quiet) std::printf("view: stopped\n");
  return listened || stopping ? kSuccess : kInternal;
}

int run_view(const ViewCommandFlags& f, const GlobalOptions& global);

// The maps a bake of a job wrote, as `--map KIND=FILE`: per map its first
// output (a <MAP> path names each map; a path without it is the normal map,
// or the only map).
std::vector<std::string> job_maps(const BakeJob& job) {
  std::vector<std::string> out;
  for (const MapKind kind : job.options.maps) {
    for (const OutputSpec& o : job.options.outputs) {
      const bool named = has_map_token(o.path);
      if (!named && !(kind == MapKind::normal || job.options.maps.size() == 1)) continue;
      out.push_back(std::string(to_string(kind)) + "=" + (named ? map_path(o.path, kind) : o.path));
      break;
    }
  }
  return out;
}

// `nmbake view JOB.toml -o DIR`: DIR/NAME.html and NAME.glb for every bake.
int run_view_job(const ViewCommandFlags& f, const GlobalOptions& global) {
  if (f.serve) {
    print_error("--serve reviews one bake: give --low and --map, not a job file");
    return kBadInput;
  }
  if (f.output.empty()) {
    print_error(f.job + ": give -o DIR, the folder of the pages");
    return kBadInput;
  }
  std::vector<BakeJob> jobs;
  if (const Status s = load_job_file(f.job, jobs); !s) return fail(s);
  std::error_code ec;
  std::filesystem::create_directories(f.output, ec);
  if (ec) return fail(Status::io(f.output + ": cannot create the folder: " + ec.message()));
  for (std::size_t i = 0; i < jobs.size(); ++i) {
    const BakeJob& job = jobs[i];
    ViewCommandFlags one = f;
    one.job.clear();
    one.low = job.options.low_path;
    // The page shows one high mesh: a bake of several shows its first.
    one.high = job.options.high_paths.empty() ? "" : job.options.high_paths.front();
    one.report = job.report_path;
    if (!one.report.empty() && !std::filesystem::exists(one.report)) one.report.clear();
    one.maps = job_maps(job);
    const std::string name = job.name.empty() ? "bake" + std::to_string(i + 1) : job.name;
    one.output = (std::filesystem::path(f.output) / (name + ".html")).string();
    if (const int code = run_view(one, global); code != kSuccess) return code;
  }
  return kSuccess;
}

int run_view(const ViewCommandFlags& f, const GlobalOptions& global) {
  if (!f.job.empty()) return run_view_job(f, global);
  if (f.low.empty() || f.maps.empty()) {
    print_error("give --low and --map (or a job file)");
    return kBadInput;
  }
  const auto start = std::chrono::steady_clock::now();
  if (f.serve) {
    // Blocked before any thread starts (TBB's workers inherit the mask), so
    // that only serve_review()'s waiter receives them.
    const sigset_t signals = stop_signals();
    pthread_sigmask(SIG_BLOCK, &signals, nullptr);
  }
  std::string extension = std::filesystem::path(f.output).extension().string();
  if (f.output.empty() && !f.serve) {
    print_error("give -o review.html, or --serve");
    return kBadInput;
  }
  if (!f.output.empty() && extension != ".html" && extension != ".htm") {
    print_error(f.output + ": the review page is written as .html");
    return kBadInput;
  }
  ReviewOptions options;
  options.low = f.low;
  options.high = f.high;
  options.report = f.report;
  options.high_budget = f.high_budget;
  options.three_dir = f.three_dir;
  options.served = f.serve;
  if (const Status s = parse_view_flags(f.camera, options.view); !s) return fail(s);
  nlohmann::json report;
  if (!f.report.empty()) {
    std::ifstream in(f.report);
    if (!in) return fail(Status::bad_input(f.report + ": cannot open the report"));
    report = nlohmann::json::parse(in, nullptr, /*allow_exceptions=*/false);
    if (report.is_discarded() || !report.is_object())
      return fail(Status::bad_input(f.report + ": not a JSON object (expected a bake report)"));
  }
  for (std::size_t i = 0; i < f.maps.size(); ++i) {
    ReviewMap m;
    const std::string& text = f.maps[i];
    const std::size_t eq = text.find('=');
    if (eq != std::string::npos && review_map_kind_known(text.substr(0, eq))) {
      m.kind = text.substr(0, eq);
      m.path = text.substr(eq + 1);
    } else {
      m.path = text;
      if (const Status s = map_kind(text, report, i == 0, m.kind); !s) return fail(s);
    }
    options.maps.push_back(m);
  }
  std::string glb, html;
  ReviewStats stats;
  if (const Status s = build_review(options, glb, html, stats); !s) return fail(s);
  if (f.serve && f.output.empty()) return serve_review(f, global, options, html, stats.tiles);
  const std::string glb_path = std::filesystem::path(f.output).replace_extension(".glb").string();
  if (const Status s = write_file(glb_path, glb); !s) return fail(s);
  if (const Status s = write_file(f.output, html); !s) return fail(s);
  if (!global.quiet) {
    const double seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
    std::printf(
        "view: %s (%.1f MiB) and %s (%.1f MiB): %llu low triangles, %llu vertices, %zu tile%s, %zu map%s",
        f.output.c_str(), static_cast<double>(stats.html_bytes) / 1048576.0, glb_path.c_str(),
        static_cast<double>(stats.glb_bytes) / 1048576.0,
        static_cast<unsigned long long>(stats.low_triangles),
        static_cast<unsigned long long>(stats.low_vertices), stats.tiles.size(),
        stats.tiles.size() == 1 ? "" : "s", options.maps.size(), options.maps.size() == 1 ? "" : "s");
    if (!f.high.empty()) {
      std::printf(", high %llu of %llu triangles shown",
                  static_cast<unsigned long long>(stats.high_triangles_shown),
                  static_cast<unsigned long long>(stats.high_triangles));
    }
    std::printf(", %.2f s\n", seconds);
  }
  if (f.serve) return serve_review(f, global, options, html, stats.tiles);
  return kSuccess;
}

}  // namespace

Runner add_view_command(CLI::App& app, const GlobalOptions& global) {
  auto flags = std::make_shared<ViewCommandFlags>();
  CLI::App* cmd = app.add_subcommand(
      "view", "review a bake in 3D: the low mesh wearing its maps as .glb, and a self-contained web page");
  cmd->add_option("job", flags->job, "a job file (TOML): a page per bake, in the folder -o DIR");
  cmd->add_option("--low", flags->low, "the low mesh the maps were baked for (with UVs)");
  cmd->add_option("--map", flags->maps,
                  "a baked map, FILE or KIND=FILE (repeat; FILE may carry <UDIM>); the kind from the report, "
                  "else the file name, else normal for the first");
  cmd->add_option("--high", flags->high,
                  "the high mesh, shown beside the low (and framed as the preview frames it)");
  cmd->add_option("--report", flags->report, "the bake report (JSON): its figures and encoding in the page");
  cmd->add_option("-o,--output", flags->output, "the page (.html); the .glb is written beside it, same stem");
  cmd->add_flag("--serve", flags->serve,
                "serve the page on 127.0.0.1, reloading the maps when their files change (Ctrl-C stops)");
  cmd->add_option("--port", flags->port, "--serve: the port (0: a free one, printed)")
      ->default_val(8790)
      ->check(CLI::Range(0, 65535));
  cmd->add_option("--high-budget", flags->high_budget,
                  "triangles of the high mesh in the page at most (vertex clustering above)")
      ->default_val(200000)
      ->check(CLI::Range(std::uint64_t{1}, std::uint64_t{100000000}));
  cmd->add_option("--three-dir", flags->three_dir, "where libjs-three is (three.min.js, examples/js/)")
      ->default_val("/usr/share/javascript/three");
  add_view_flags(cmd, flags->camera, 384);
  return [flags, &global]() { return run_view(*flags, global); };
}

}  // namespace nmbake::cli
