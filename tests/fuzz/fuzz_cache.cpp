// Cache entries through cache_fetch(), as `nmbake bake --cache` reads
// them. The fuzzer's bytes are an entry folder: records separated by a
// line "=====", the first the manifest, the second the report, each other
// one a file of the entry (its first line its name, the rest its bytes; a
// record whose bytes start with "->" is a symlink to what follows). Beside
// the entry lies a secret file, and each input may link to it.
//
// What a fetch must never do: crash; serve a map whose bytes are not those
// of the regular file of the entry the manifest names (so never a symlink's
// target, never the secret); leave a file in the destination folder when
// it does not serve the entry.
#include <tbb/global_control.h>

#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <map>
#include <string>
#include <string_view>
#include <vector>

#include "fuzz_util.hpp"
#include "nmbake/cache.hpp"

namespace {

namespace fs = std::filesystem;

constexpr std::string_view kSeparator = "\n=====\n";

std::string read_bytes(const fs::path& path) {
  std::ifstream in(path, std::ios::binary);
  return std::string(std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>());
}

void write_bytes(const fs::path& path, std::string_view bytes) {
  std::ofstream out(path, std::ios::binary);
  out.write(bytes.data(), static_cast<std::streamsize>(bytes.size()));
}

std::vector<std::string_view> records(std::string_view input) {
  std::vector<std::string_view> out;
  for (;;) {
    const std::size_t at = input.find(kSeparator);
    out.push_back(input.substr(0, at));
    if (at == std::string_view::npos) return out;
    input.remove_prefix(at + kSeparator.size());
  }
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  static const tbb::global_control one_thread(tbb::global_control::max_allowed_parallelism, 1);
  const fs::path root = nmbake::fuzz::scratch_folder() / "cache";
  const nmbake::BakeKey key{0x0123456789abcdefull, 0xfedcba9876543210ull};
  const fs::path cache = root / "c", entry = cache / key.hex(), out = root / "out";
  std::error_code ec;
  fs::remove_all(root, ec);
  fs::create_directories(entry, ec);
  fs::create_directories(out, ec);
  const std::string secret = "root:x:0:0:the secret beside the entry\n";
  write_bytes(root / "secret", secret);

  // The entry: what each regular file of it holds, by name.
  const std::vector<std::string_view> parts =
      records(std::string_view(reinterpret_cast<const char*>(data), size));
  std::map<std::string, std::string> regular;
  write_bytes(entry / "manifest.json", parts[0]);
  if (parts.size() > 1) write_bytes(entry / "report.json", parts[1]);
  for (std::size_t i = 2; i < parts.size(); ++i) {
    const std::size_t eol = parts[i].find('\n');
    const std::string name(parts[i].substr(0, eol));
    const std::string_view bytes =
        eol == std::string_view::npos ? std::string_view() : parts[i].substr(eol + 1);
    if (name.empty() || name.find('/') != std::string::npos || name.find('\0') != std::string::npos ||
        name == "." || name == ".." || name == "manifest.json" || name == "report.json" ||
        name.size() > 200) {
      continue;
    }
    if (bytes.substr(0, 2) == "->") {
      fs::create_symlink(std::string(bytes.substr(2)), entry / name, ec);
    } else {
      write_bytes(entry / name, bytes);
      regular[name] = std::string(bytes);
    }
  }
  regular["manifest.json"] = std::string(parts[0]);
  if (parts.size() > 1) regular["report.json"] = std::string(parts[1]);

  nmbake::BakeOptions options;
  options.width = 16;
  options.height = 16;
  options.outputs = {{(out / "a.png").string(), nmbake::PixelFormat::png16, false},
                     {(out / "b_<UDIM>.exr").string(), nmbake::PixelFormat::exr_float, true}};
  nmbake::CacheLookup lookup;
  std::vector<std::string> written;
  const nmbake::Status s =
      nmbake::cache_fetch(cache.string(), key, options, (out / "r.json").string(), lookup, written);
  if (!s.is_ok()) {
    std::fprintf(stderr, "fetch failed on the destination: %s\n", s.message().c_str());
    std::abort();  // the destination folder is writable: any error is the entry's, which is a miss
  }
  if (!lookup.hit) {
    if (!fs::is_empty(out, ec)) {
      std::fprintf(stderr, "a miss left a file in the destination folder\n");
      std::abort();
    }
    return 0;
  }
  // Served: every map is the bytes of a regular file of the entry, never
  // the secret, and the report was written.
  for (const std::string& path : written) {
    const std::string bytes = read_bytes(path);
    bool found = false;
    for (const auto& [name, content] : regular) found = found || content == bytes;
    if (!found) {
      std::fprintf(stderr, "%s: bytes not of a file of the entry\n", path.c_str());
      std::abort();
    }
  }
  if (!fs::is_regular_file(out / "r.json", ec)) std::abort();
  return 0;
}
