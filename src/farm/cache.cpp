// The bake cache (cache.hpp).
#include "nmbake/cache.hpp"

#include <cerrno>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <iterator>

#include <unistd.h>

#include <nlohmann/json.hpp>

#include "base/strings.hpp"

#include "nmbake/cleanup.hpp"
#include "nmbake/udim.hpp"

namespace nmbake {

namespace fs = std::filesystem;

using detail::concat;

std::string resolve_cache_dir(const std::string& flag) {
  if (!flag.empty()) return flag;
  const char* env = std::getenv("NMBAKE_CACHE");
  return env != nullptr ? std::string(env) : std::string();
}

namespace {

// A name no other process uses at the same time.
std::string unique_suffix() {
  static int counter = 0;
  return std::to_string(::getpid()) + "-" + std::to_string(++counter);
}

// Copies `from` to `to` through a temporary file in to's folder.
Status copy_atomically(const std::string& from, const std::string& to) {
  const std::string temp = to + ".tmp" + unique_suffix();
  std::error_code ec;
  fs::copy_file(from, temp, fs::copy_options::overwrite_existing, ec);
  if (ec) {
    fs::remove(temp, ec);
    return Status::io(to + ": cannot copy from the cache: " + ec.message());
  }
  fs::rename(temp, to, ec);
  if (ec) {
    fs::remove(temp, ec);
    return Status::io(to + ": cannot write: " + ec.message());
  }
  return Status::ok();
}

std::string read_text(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  return std::string(std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>());
}

}  // namespace

Status cache_fetch(const std::string& dir, const BakeKey& key, const BakeOptions& options,
                   const std::string& report_path, bool& hit, std::vector<std::string>& written) {
  hit = false;
  written.clear();
  const fs::path entry = fs::path(dir) / key.hex();
  const std::string manifest_text = read_text((entry / "manifest.json").string());
  if (manifest_text.empty()) return Status::ok();  // not cached (or not readable: bake again)
  const nlohmann::json manifest = nlohmann::json::parse(manifest_text, nullptr, false);
  if (manifest.is_discarded() || !manifest.contains("files") || manifest.value("key", "") != key.hex()) {
    return Status::ok();
  }
  for (const auto& file : manifest["files"]) {
    const std::size_t output = file.value("output", std::size_t{0});
    const int tile = file.value("tile", 1001);
    // `output` counts the files of a UDIM tile: each output once per map.
    const std::vector<MapOutput> files = map_outputs(options);
    if (output >= files.size()) return Status::ok();  // another layout: bake again
    const std::string to = udim_path(files[output].path, tile);
    NMBAKE_TRY(copy_atomically((entry / file.value("file", "")).string(), to));
    written.push_back(to);
  }
  if (!report_path.empty()) {
    nlohmann::ordered_json report = nlohmann::ordered_json::parse(read_text((entry / "report.json").string()), nullptr, false);
    if (report.is_discarded()) report = nlohmann::ordered_json::object();
    report["cached"] = true;
    report["key"] = key.hex();
    report["outputs"] = written;
    report["low"] = options.low_path;
    report["high"] = options.high_path;
    NMBAKE_TRY(write_file_atomically(report_path, {report.dump(2) + "\n"}, "the report"));
  }
  hit = true;
  return Status::ok();
}

Status cache_store(const std::string& dir, const BakeKey& key, const BakeOptions& options, const BakeReport& report,
                   const std::string& report_json) {
  std::error_code ec;
  fs::create_directories(dir, ec);
  if (ec) return Status::io(dir + ": cannot create the cache folder: " + ec.message());
  const fs::path entry = fs::path(dir) / key.hex();
  if (fs::exists(entry / "manifest.json", ec)) return Status::ok();
  const fs::path temp = fs::path(dir) / concat(".tmp-", key.hex(), "-", unique_suffix());
  fs::create_directory(temp, ec);
  if (ec) return Status::io(temp.string() + ": cannot create: " + ec.message());
  nlohmann::ordered_json manifest;
  manifest["key"] = key.hex();
  manifest["files"] = nlohmann::ordered_json::array();
  const auto fail = [&](const std::string& why) {
    fs::remove_all(temp, ec);
    return Status::io(dir + ": cannot store the bake in the cache: " + why);
  };
  for (const BakeReport::Tile& tile : report.tiles) {
    if (tile.outputs.size() != map_outputs(options).size()) return fail("outputs and tiles do not agree");
    for (std::size_t i = 0; i < tile.outputs.size(); ++i) {
      const std::string name =
          concat("o", std::to_string(i), "_", std::to_string(tile.tile), fs::path(tile.outputs[i]).extension().string());
      fs::copy_file(tile.outputs[i], temp / name, ec);
      if (ec) return fail(tile.outputs[i] + ": " + ec.message());
      manifest["files"].push_back({{"output", i}, {"tile", tile.tile}, {"file", name}});
    }
  }
  {
    std::ofstream out(temp / "report.json", std::ios::binary);
    out << report_json;
    std::ofstream m(temp / "manifest.json", std::ios::binary);
    m << manifest.dump(2) << "\n";
    if (!out.flush() || !m.flush()) return fail("cannot write the manifest (disk full?)");
  }
  fs::rename(temp, entry, ec);
  if (ec) {
    // Another process stored the same key first: its entry is as good.
    fs::remove_all(temp, ec);
  }
  return Status::ok();
}

}  // namespace nmbake
