// `nmbake view --low L --map normal.png [--map ao.png ...] [--high H]
// [--report R.json] -o review.html`: the review .glb (beside the page, same
// stem) and the self-contained page (review.hpp).
#include <chrono>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <nlohmann/json.hpp>

#include "commands.hpp"
#include "nmbake/cleanup.hpp"
#include "nmbake/review.hpp"

namespace nmbake::cli {

namespace {

struct ViewCommandFlags {
  std::string low, high, report, output;
  std::vector<std::string> maps;
  std::uint64_t high_budget = 200000;
  std::string three_dir = "/usr/share/javascript/three";
  ViewFlags camera;
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

int run_view(const ViewCommandFlags& f, const GlobalOptions& global) {
  const auto start = std::chrono::steady_clock::now();
  std::string extension = std::filesystem::path(f.output).extension().string();
  if (extension != ".html" && extension != ".htm") {
    std::fprintf(stderr, "nmbake: error: %s: the review page is written as .html\n", f.output.c_str());
    return kBadInput;
  }
  ReviewOptions options;
  options.low = f.low;
  options.high = f.high;
  options.report = f.report;
  options.high_budget = f.high_budget;
  options.three_dir = f.three_dir;
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
  return kSuccess;
}

}  // namespace

Runner add_view_command(CLI::App& app, const GlobalOptions& global) {
  auto flags = std::make_shared<ViewCommandFlags>();
  CLI::App* cmd = app.add_subcommand(
      "view", "review a bake in 3D: the low mesh wearing its maps as .glb, and a self-contained web page");
  cmd->add_option("--low", flags->low, "the low mesh the maps were baked for (with UVs)")->required();
  cmd->add_option("--map", flags->maps,
                  "a baked map, FILE or KIND=FILE (repeat; FILE may carry <UDIM>); the kind from the report, "
                  "else the file name, else normal for the first")
      ->required();
  cmd->add_option("--high", flags->high,
                  "the high mesh, shown beside the low (and framed as the preview frames it)");
  cmd->add_option("--report", flags->report, "the bake report (JSON): its figures and encoding in the page");
  cmd->add_option("-o,--output", flags->output, "the page (.html); the .glb is written beside it, same stem")
      ->required();
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
