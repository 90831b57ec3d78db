// The bake cache (cache.hpp).
#include "nmbake/cache.hpp"

#include <fcntl.h>
#include <sys/stat.h>
#include <unistd.h>
#include <xxhash.h>

#include <algorithm>
#include <atomic>
#include <cerrno>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <limits>
#include <map>
#include <memory>
#include <nlohmann/json.hpp>
#include <set>
#include <string_view>

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

// A manifest and a report are a few KB; these only keep a hostile one from
// being read whole into memory.
constexpr std::uint64_t kMaxManifestBytes = std::uint64_t{16} << 20;
constexpr std::uint64_t kMaxReportBytes = std::uint64_t{16} << 20;
constexpr int kFirstUdimTile = 1001, kLastUdimTile = 2000;  // udim.hpp: u 0..9, v 0..99
constexpr std::size_t kMaxNameBytes = 255;
constexpr std::size_t kChunkBytes = std::size_t{1} << 20;

// A name no other process uses at the same time.
std::string unique_suffix() {
  static std::atomic<unsigned> counter{0};
  return std::to_string(::getpid()) + "-" + std::to_string(++counter);
}

class FileDescriptor {
 public:
  explicit FileDescriptor(int fd = -1) : fd_(fd) {}
  ~FileDescriptor() {
    if (fd_ >= 0) ::close(fd_);
  }
  FileDescriptor(const FileDescriptor&) = delete;
  FileDescriptor& operator=(const FileDescriptor&) = delete;
  int get() const { return fd_; }
  void reset(int fd) {
    if (fd_ >= 0) ::close(fd_);
    fd_ = fd;
  }
  int release() {
    const int fd = fd_;
    fd_ = -1;
    return fd;
  }
  // Closes now; the error of close(2) (a write-back failure) or 0.
  int close() {
    const int result = fd_ >= 0 ? ::close(fd_) : 0;
    fd_ = -1;
    return result != 0 ? errno : 0;
  }

 private:
  int fd_;
};

std::string hex64(std::uint64_t value) {
  char text[17];
  std::snprintf(text, sizeof text, "%016llx", static_cast<unsigned long long>(value));
  return text;
}

// A file name directly inside the entry: openat() relative to the entry's
// folder then cannot leave it (no `/`, no `..`).
bool plain_name(const std::string& name) {
  return !name.empty() && name.size() <= kMaxNameBytes && name != "." && name != ".." &&
         name.find('/') == std::string::npos && name.find('\0') == std::string::npos;
}

// The largest map file a bake of `options` can write, a tile of a UDIM map
// included: 4 float channels a texel stored uncompressed, twice over for
// any format's own framing, plus 1 MiB of headers.
std::uint64_t max_map_bytes(const BakeOptions& options) {
  return std::uint64_t{2} * 16 * static_cast<std::uint64_t>(std::max(options.width, 1)) *
             static_cast<std::uint64_t>(std::max(options.height, 1)) +
         (std::uint64_t{1} << 20);
}

// Opens `name` in the entry folder `entry_fd` for reading: a regular file
// (O_NOFOLLOW: a symlink is refused, wherever it points; O_NONBLOCK: a FIFO
// does not block the open) of at most `max_bytes`. "" or why not.
std::string open_in_entry(int entry_fd, const std::string& name, std::uint64_t max_bytes, FileDescriptor& fd,
                          std::uint64_t& size) {
  if (!plain_name(name)) return "a file name that is not a plain name in the entry ('" + name + "')";
  FileDescriptor opened(::openat(entry_fd, name.c_str(), O_RDONLY | O_NOFOLLOW | O_NONBLOCK | O_CLOEXEC));
  if (opened.get() < 0) {
    return name + ": " +
           (errno == ELOOP ? std::string("a symlink, not a file of the entry") : std::strerror(errno));
  }
  struct stat info {};
  if (::fstat(opened.get(), &info) != 0) return name + ": " + std::strerror(errno);
  if (!S_ISREG(info.st_mode)) return name + ": not a regular file";
  size = static_cast<std::uint64_t>(info.st_size);
  if (size > max_bytes) {
    return name + ": " + std::to_string(size) + " bytes, more than the " + std::to_string(max_bytes) +
           " it may hold";
  }
  // Reads block again (a regular file never blocks; this only keeps the
  // flag from mattering).
  (void)::fcntl(opened.get(), F_SETFL, ::fcntl(opened.get(), F_GETFL) & ~O_NONBLOCK);
  fd.reset(opened.release());
  return "";
}

// Reads the open file to its end, passing each chunk to `sink` (which
// returns "" or why it failed) and hashing it: exactly `size` bytes are
// expected (a file that grows or shrinks while read is refused, and no
// more than size + 1 bytes are ever read). "" or why not.
template <typename Sink>
std::string read_exactly(int fd, const std::string& name, std::uint64_t size, std::uint64_t& hash,
                         Sink&& sink) {
  std::unique_ptr<XXH3_state_t, decltype(&XXH3_freeState)> state(XXH3_createState(), &XXH3_freeState);
  if (!state) throw std::bad_alloc();
  XXH3_64bits_reset(state.get());
  const auto buffer = std::make_unique_for_overwrite<char[]>(kChunkBytes);
  std::uint64_t total = 0;
  for (;;) {
    const std::uint64_t want = std::min<std::uint64_t>(kChunkBytes, size + 1 - total);
    const ssize_t got = ::read(fd, buffer.get(), static_cast<std::size_t>(want));
    if (got < 0 && errno == EINTR) continue;
    if (got < 0) return name + ": " + std::strerror(errno);
    if (got == 0) break;
    total += static_cast<std::uint64_t>(got);
    if (total > size) return name + ": longer than the " + std::to_string(size) + " bytes recorded";
    XXH3_64bits_update(state.get(), buffer.get(), static_cast<std::size_t>(got));
    if (std::string why = sink(std::string_view(buffer.get(), static_cast<std::size_t>(got))); !why.empty()) {
      return why;
    }
  }
  if (total != size)
    return name + ": " + std::to_string(total) + " bytes where " + std::to_string(size) + " were recorded";
  hash = XXH3_64bits_digest(state.get());
  return "";
}

// Reads a small file of the entry whole. "" or why not.
std::string read_small(int entry_fd, const std::string& name, std::uint64_t max_bytes, std::string& text,
                       std::uint64_t& hash) {
  FileDescriptor fd;
  std::uint64_t size = 0;
  if (std::string why = open_in_entry(entry_fd, name, max_bytes, fd, size); !why.empty()) return why;
  text.clear();
  text.reserve(static_cast<std::size_t>(size));
  return read_exactly(fd.get(), name, size, hash, [&](std::string_view chunk) {
    text.append(chunk);
    return std::string();
  });
}

// One file the manifest lists.
struct EntryFile {
  std::string name;
  std::uint64_t size = 0, hash = 0;
  std::size_t output = 0;  // index into map_outputs(options)
  int tile = kFirstUdimTile;
};

// A size and an XXH3-64 as the manifest records them: {"size": N,
// "xxh3": "16 hex digits"}. False when `j` is not of that shape.
bool parse_sum(const nlohmann::json& j, std::uint64_t max_bytes, std::uint64_t& size, std::uint64_t& hash) {
  if (!j.is_object()) return false;
  const auto s = j.find("size");
  const auto h = j.find("xxh3");
  if (s == j.end() || h == j.end() || !s->is_number_unsigned() || !h->is_string()) return false;
  size = s->get<std::uint64_t>();
  const std::string& text = h->get_ref<const std::string&>();
  if (size > max_bytes || text.size() != 16 || !std::all_of(text.begin(), text.end(), [](char c) {
        return (c >= '0' && c <= '9') || (c >= 'a' && c <= 'f');
      })) {
    return false;
  }
  hash = std::stoull(text, nullptr, 16);
  return true;
}

// An input file the entry's bake read besides the meshes (an MTL library, a
// glTF buffer, a texture: BakeReport::input_files) and its sum then.
struct InputFile {
  std::string path;
  std::uint64_t size = 0, hash = 0;
};

// The manifest's "inputs" (absent in entries of bakes that read none).
std::string parse_inputs(const nlohmann::json& manifest, std::vector<InputFile>& inputs) {
  const auto list = manifest.find("inputs");
  if (list == manifest.end()) return "";
  if (!list->is_array()) return "manifest.json: inputs is not a list";
  for (const nlohmann::json& f : *list) {
    InputFile input;
    const auto path = f.is_object() ? f.find("path") : f.end();
    if (path == f.end() || !path->is_string() ||
        !parse_sum(f, std::numeric_limits<std::uint64_t>::max(), input.size, input.hash)) {
      return "manifest.json: an input entry of the wrong shape";
    }
    input.path = path->get<std::string>();
    inputs.push_back(std::move(input));
  }
  return "";
}

// Checks the manifest's shape against the bake it is fetched for: the key,
// every output once per tile (tile 1001 only for an output without
// <UDIM>), plain file names, sizes within bounds. "" or why not.
std::string parse_manifest(const std::string& text, const BakeKey& key, const BakeOptions& options,
                           std::vector<EntryFile>& files, EntryFile& report, std::vector<InputFile>& inputs) {
  const nlohmann::json manifest = nlohmann::json::parse(text, nullptr, false);
  if (manifest.is_discarded()) return "manifest.json is not JSON";
  if (!manifest.is_object()) return "manifest.json is not a JSON object";
  const auto k = manifest.find("key");
  if (k == manifest.end() || !k->is_string() || k->get_ref<const std::string&>() != key.hex()) {
    return "manifest.json names another key";
  }
  const auto r = manifest.find("report");
  if (r == manifest.end() || !parse_sum(*r, kMaxReportBytes, report.size, report.hash)) {
    return "manifest.json records no size and checksum of the report (an entry of an older nmbake?)";
  }
  report.name = "report.json";
  if (std::string why = parse_inputs(manifest, inputs); !why.empty()) return why;
  const auto list = manifest.find("files");
  if (list == manifest.end() || !list->is_array() || list->empty()) return "manifest.json lists no files";
  const std::vector<MapOutput> outputs = map_outputs(options);
  const std::uint64_t max_bytes = max_map_bytes(options);
  std::set<std::pair<int, std::size_t>> seen;
  std::map<int, std::size_t> per_tile;
  for (const nlohmann::json& f : *list) {
    if (!f.is_object()) return "manifest.json: a file entry is not an object";
    EntryFile file;
    const auto output = f.find("output");
    const auto tile = f.find("tile");
    const auto name = f.find("file");
    if (output == f.end() || !output->is_number_unsigned() || tile == f.end() || !tile->is_number_integer() ||
        name == f.end() || !name->is_string()) {
      return "manifest.json: a file entry of the wrong shape";
    }
    if (!parse_sum(f, max_bytes, file.size, file.hash)) {
      return "manifest.json: a file without its size and checksum, or larger than a map of this bake can be";
    }
    const auto index = output->get<std::uint64_t>();
    const auto number = tile->get<std::int64_t>();
    if (index >= outputs.size() || number < kFirstUdimTile || number > kLastUdimTile) {
      return "manifest.json: a file of another layout (output " + std::to_string(index) + ", tile " +
             std::to_string(number) + ")";
    }
    file.output = static_cast<std::size_t>(index);
    file.tile = static_cast<int>(number);
    if (file.tile != kFirstUdimTile && !has_udim_token(outputs[file.output].path)) {
      return "manifest.json: a UDIM tile for an output without <UDIM>";
    }
    file.name = name->get<std::string>();
    if (!plain_name(file.name)) return "manifest.json: a file name that is not a plain name in the entry";
    if (!seen.emplace(file.tile, file.output).second) return "manifest.json: a map listed twice";
    ++per_tile[file.tile];
    files.push_back(std::move(file));
  }
  for (const auto& [tile, count] : per_tile) {
    if (count != outputs.size()) return "manifest.json: tile " + std::to_string(tile) + " lacks maps";
  }
  return "";
}

// A verified copy of one entry file, written to a temporary file beside
// its destination and renamed by the caller.
struct Staged {
  std::string temp, to;
  std::unique_ptr<TempFileGuard> guard;
};

// Removes every staged temporary file.
void drop(std::vector<Staged>& staged) {
  for (Staged& s : staged) {
    ::unlink(s.temp.c_str());
    s.guard.reset();
  }
  staged.clear();
}

// Copies `file` of the entry to a temporary file beside `to`, checking its
// size and checksum on the bytes copied. `why` gets the entry's fault
// (the Status stays ok); an error Status is the destination's.
Status stage(int entry_fd, const EntryFile& file, const std::string& to, std::vector<Staged>& staged,
             std::string& why) {
  FileDescriptor in;
  std::uint64_t size = 0;
  why = open_in_entry(entry_fd, file.name, file.size, in, size);
  if (!why.empty()) return Status::ok();
  if (size != file.size) {
    why = file.name + ": " + std::to_string(size) + " bytes where " + std::to_string(file.size) +
          " were recorded";
    return Status::ok();
  }
  Staged& s = staged.emplace_back();
  s.to = to;
  s.temp = to + ".tmp" + unique_suffix();
  s.guard = std::make_unique<TempFileGuard>(s.temp);
  FileDescriptor out(::open(s.temp.c_str(), O_WRONLY | O_CREAT | O_EXCL | O_CLOEXEC, 0666));
  if (out.get() < 0) {
    const int error = errno;
    s.guard.reset();
    staged.pop_back();
    return Status::io(to + ": cannot write: " + std::strerror(error));
  }
  int write_error = 0;
  std::uint64_t hash = 0;
  why = read_exactly(in.get(), file.name, file.size, hash, [&](std::string_view chunk) {
    while (!chunk.empty()) {
      const ssize_t n = ::write(out.get(), chunk.data(), chunk.size());
      if (n < 0 && errno == EINTR) continue;
      if (n <= 0) {
        write_error = n < 0 ? errno : ENOSPC;
        return std::string("write");
      }
      chunk.remove_prefix(static_cast<std::size_t>(n));
    }
    return std::string();
  });
  if (write_error == 0) write_error = out.close();
  if (write_error != 0) return Status::io(to + ": cannot write: " + std::strerror(write_error));
  if (why.empty() && hash != file.hash)
    why = file.name + ": its checksum does not match (a damaged or altered file)";
  return Status::ok();
}

// Copies `from` (a map the bake just wrote) into the entry being built,
// returning its size and checksum. "" or why not.
std::string copy_in(const std::string& from, const fs::path& to, std::uint64_t& size, std::uint64_t& hash) {
  FileDescriptor in(::open(from.c_str(), O_RDONLY | O_NONBLOCK | O_CLOEXEC));
  struct stat info {};
  if (in.get() < 0 || ::fstat(in.get(), &info) != 0) return from + ": " + std::strerror(errno);
  if (!S_ISREG(info.st_mode)) return from + ": not a regular file";
  size = static_cast<std::uint64_t>(info.st_size);
  FileDescriptor out(::open(to.c_str(), O_WRONLY | O_CREAT | O_EXCL | O_CLOEXEC, 0666));
  if (out.get() < 0) return to.string() + ": " + std::strerror(errno);
  int write_error = 0;
  std::string why = read_exactly(in.get(), from, size, hash, [&](std::string_view chunk) {
    while (!chunk.empty()) {
      const ssize_t n = ::write(out.get(), chunk.data(), chunk.size());
      if (n < 0 && errno == EINTR) continue;
      if (n <= 0) {
        write_error = n < 0 ? errno : ENOSPC;
        return to.string() + ": " + std::strerror(write_error);
      }
      chunk.remove_prefix(static_cast<std::size_t>(n));
    }
    return std::string();
  });
  if (why.empty() && out.close() != 0) why = to.string() + ": " + std::strerror(errno);
  return why;
}

}  // namespace

Status check_cache_dir(const std::string& dir) {
  if (dir.empty()) return Status::ok();
  const auto fail = [&](const std::string& why) {
    return Status::io(printable_text(dir) + ": the cache folder cannot be written: " + why);
  };
  if (dir.find('\0') != std::string::npos) return fail("the path holds a NUL byte");
  std::error_code ec;
  fs::create_directories(dir, ec);
  if (ec) return fail(ec.message());
  if (!fs::is_directory(dir, ec)) return fail("not a folder");
  // access(W_OK) is true for root on any folder but a read-only mount:
  // making a folder is the test a store will face.
  const fs::path probe = fs::path(dir) / (".tmp-probe-" + unique_suffix());
  if (::mkdir(probe.c_str(), 0700) != 0) return fail(std::strerror(errno));
  ::rmdir(probe.c_str());
  return Status::ok();
}

Status cache_fetch(const std::string& dir, const BakeKey& key, const BakeOptions& options,
                   const std::string& report_path, CacheLookup& lookup, std::vector<std::string>& written) {
  lookup = CacheLookup{};
  written.clear();
  const fs::path entry = fs::path(dir) / key.hex();
  const auto bad = [&](const std::string& why) {
    lookup.bad_entry = why;
    return Status::ok();
  };
  FileDescriptor entry_fd(::open(entry.c_str(), O_RDONLY | O_DIRECTORY | O_NOFOLLOW | O_CLOEXEC));
  if (entry_fd.get() < 0) {
    if (errno == ENOENT) return Status::ok();  // not cached
    return bad(errno == ELOOP || errno == ENOTDIR ? "not a folder (a symlink or a file)"
                                                  : std::strerror(errno));
  }
  std::string text;
  std::uint64_t hash = 0;
  if (std::string why = read_small(entry_fd.get(), "manifest.json", kMaxManifestBytes, text, hash);
      !why.empty()) {
    return bad(why);
  }
  std::vector<EntryFile> files;
  EntryFile report_file;
  std::vector<InputFile> inputs;
  if (std::string why = parse_manifest(text, key, options, files, report_file, inputs); !why.empty())
    return bad(why);
  // The key holds the meshes' bytes; what else the bake read must be as it
  // was (a texture painted over since is another bake).
  for (const InputFile& input : inputs) {
    std::uint64_t now_size = 0, now_hash = 0;
    if (std::string why = hash_file_contents(input.path, now_size, now_hash); !why.empty())
      return bad("an input of the entry's bake cannot be read now: " + why);
    if (now_size != input.size || now_hash != input.hash)
      return bad(input.path + ": changed since the entry was stored (a file the bake read)");
  }
  std::string report_text;
  if (std::string why = read_small(entry_fd.get(), report_file.name, report_file.size, report_text, hash);
      !why.empty()) {
    return bad(why);
  }
  if (report_text.size() != report_file.size || hash != report_file.hash) {
    return bad("report.json: its size or checksum does not match (a damaged or altered file)");
  }
  nlohmann::ordered_json report = nlohmann::ordered_json::parse(report_text, nullptr, false);
  if (!report.is_object()) return bad("report.json is not a JSON object");

  const std::vector<MapOutput> outputs = map_outputs(options);
  std::vector<Staged> staged;
  for (const EntryFile& file : files) {
    std::string why;
    const Status s =
        stage(entry_fd.get(), file, udim_path(outputs[file.output].path, file.tile), staged, why);
    if (!s || !why.empty()) {
      drop(staged);
      return s ? bad(why) : s;
    }
  }
  for (std::size_t i = 0; i < staged.size(); ++i) {
    if (::rename(staged[i].temp.c_str(), staged[i].to.c_str()) != 0) {
      // The destination's fault (the maps renamed so far stay, as a bake's do).
      const int error = errno;
      const std::string to = staged[i].to;
      staged.erase(staged.begin(), staged.begin() + static_cast<std::ptrdiff_t>(i));
      drop(staged);
      return Status::io(to + ": cannot write: " + std::strerror(error));
    }
    staged[i].guard.reset();
    written.push_back(staged[i].to);
  }
  if (!report_path.empty()) {
    report["cached"] = true;
    report["key"] = key.hex();
    report["outputs"] = written;
    report["low"] = options.low_path;
    if (options.high_paths.size() == 1) {
      report["high"] = options.high_paths.front();
    } else {
      report["high"] = options.high_paths;
    }
    NMBAKE_TRY(write_file_atomically(report_path, {report.dump(2) + "\n"}, "the report"));
  }
  lookup.hit = true;
  return Status::ok();
}

Status cache_store(const std::string& dir, const BakeKey& key, const BakeOptions& options,
                   const BakeReport& report, const std::string& report_json, bool replace) {
  std::error_code ec;
  fs::create_directories(dir, ec);
  if (ec) return Status::io(dir + ": cannot create the cache folder: " + ec.message());
  const fs::path entry = fs::path(dir) / key.hex();
  if (!replace && fs::exists(fs::symlink_status(entry, ec))) return Status::ok();
  const fs::path temp = fs::path(dir) / concat(".tmp-", key.hex(), "-", unique_suffix());
  fs::create_directory(temp, ec);
  if (ec) return Status::io(temp.string() + ": cannot create: " + ec.message());
  nlohmann::ordered_json manifest;
  manifest["key"] = key.hex();
  const auto fail = [&](const std::string& why) {
    fs::remove_all(temp, ec);
    return Status::io(dir + ": cannot store the bake in the cache: " + why);
  };
  if (!report.input_files.empty()) {
    manifest["inputs"] = nlohmann::ordered_json::array();
    for (const std::string& path : report.input_files) {
      std::uint64_t size = 0, hash = 0;
      if (std::string why = hash_file_contents(path, size, hash); !why.empty()) return fail(why);
      manifest["inputs"].push_back({{"path", path}, {"size", size}, {"xxh3", hex64(hash)}});
    }
  }
  manifest["files"] = nlohmann::ordered_json::array();
  for (const BakeReport::Tile& tile : report.tiles) {
    if (tile.outputs.size() != map_outputs(options).size()) return fail("outputs and tiles do not agree");
    for (std::size_t i = 0; i < tile.outputs.size(); ++i) {
      const std::string name = concat("o", std::to_string(i), "_", std::to_string(tile.tile),
                                      fs::path(tile.outputs[i]).extension().string());
      std::uint64_t size = 0, hash = 0;
      if (std::string why = copy_in(tile.outputs[i], temp / name, size, hash); !why.empty()) return fail(why);
      manifest["files"].push_back(
          {{"output", i}, {"tile", tile.tile}, {"file", name}, {"size", size}, {"xxh3", hex64(hash)}});
    }
  }
  manifest["report"] = {{"size", report_json.size()},
                        {"xxh3", hex64(XXH3_64bits(report_json.data(), report_json.size()))}};
  {
    std::ofstream out(temp / "report.json", std::ios::binary);
    out << report_json;
    std::ofstream m(temp / "manifest.json", std::ios::binary);
    m << manifest.dump(2) << "\n";
    if (!out.flush() || !m.flush()) return fail("cannot write the manifest (disk full?)");
  }
  // A bad entry is moved aside first (rename(2) does not replace a folder
  // that holds files), then removed: remove_all deletes symlinks, never
  // what they point at.
  const fs::path aside = fs::path(dir) / concat(".tmp-bad-", key.hex(), "-", unique_suffix());
  if (replace) fs::rename(entry, aside, ec);
  fs::rename(temp, entry, ec);
  if (ec) {
    // Another process stored the same key first: its entry is as good.
    fs::remove_all(temp, ec);
  }
  if (replace) fs::remove_all(aside, ec);
  return Status::ok();
}

}  // namespace nmbake
