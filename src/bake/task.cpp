// Bake keys, tile files and the merge (task.hpp).
//
// Key: XXH3-128 (xxHash 0.8, Yann Collet) over, in order, the canonical
// option text and, for each of low, high, cage, the file's length and bytes.
//
// Tile file (format 3), little endian:
//   "NMBTILE3" | key (high, low: u64) | i32 width, height, row_begin,
//   row_end, index, count, padding, dither, output count, map count |
//   per output: u8 format, u8 format given, u32 path length, path (<MAP>
//   unreplaced) | per map: u8 MapKind | the map set's settings: f32 height
//   range, f32 curvature range (0: auto), i32 AO rays, f32 AO distance, i32
//   thickness rays, f32 thickness distance, f32 position box min xyz, max
//   xyz | u64 OcclusionStats (7) and ThicknessStats (6) fields | per map:
//   u32 counter count, per counter: u8 name length, name, f64 value |
//   per map: f32 texels[rows * width * channels] | u8 coverage[rows * width]
//   | u64 XXH3-64 of everything before it.
// Every count is checked against what is left of the file before anything
// is allocated, the trailing hash finds a torn or altered file, and texels
// must be finite (and bounded: read_tile). The
// normal-like maps' encode options (space, green, tangent encode) are not
// written: their texels are encoded, and dilating and writing them does not
// read the options (the key holds them).
#include "nmbake/task.hpp"

#include <fcntl.h>
#include <sys/stat.h>
#include <tbb/parallel_for.h>
#include <unistd.h>
#include <xxhash.h>

#include <algorithm>
#include <bit>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <memory>
#include <nlohmann/json.hpp>

#include "bake/map_report_json.hpp"
#include "nmbake/bake.hpp"
#include "nmbake/cleanup.hpp"
#include "nmbake/image.hpp"
#include "nmbake/preset.hpp"
#include "nmbake/udim.hpp"

namespace nmbake {

static_assert(std::endian::native == std::endian::little,
              "tile files are written in the machine's byte order");

std::string BakeKey::hex() const {
  char text[33];
  std::snprintf(text, sizeof text, "%016llx%016llx", static_cast<unsigned long long>(high),
                static_cast<unsigned long long>(low));
  return text;
}

std::string bake_key_text(const BakeOptions& o) {
  std::string t;
  const auto line = [&](const char* name, const std::string& value) {
    t += name;
    t += ' ';
    t += value;
    t += '\n';
  };
  const auto number = [](double v) {
    char text[32];
    std::snprintf(text, sizeof text, "%.9g", v);
    return std::string(text);
  };
  line("nmbake", kNmbakeVersion);
  line("size", std::to_string(o.width) + "x" + std::to_string(o.height));
  if (o.adaptive) {
    // The thresholds are part of the rule: a change of them changes bytes.
    line("samples", "adaptive " + std::to_string(o.adaptive_options.max_samples) + " " +
                        number(o.adaptive_options.normal_threshold) + " " +
                        number(o.adaptive_options.depth_threshold) + " " +
                        number(o.adaptive_options.border_threshold) + " " +
                        number(o.adaptive_options.spread_threshold));
  } else {
    line("samples", std::to_string(o.samples));
  }
  line("space", o.encode.space == NormalSpace::tangent ? "tangent" : "object");
  line("green", o.encode.green == GreenChannel::up ? "up" : "down");
  for (const auto& [name, d] : {std::pair{"front", o.rays.front}, std::pair{"back", o.rays.back}}) {
    line(name, d.kind == Distance::Kind::automatic ? std::string("auto")
               : d.kind == Distance::Kind::percent ? number(d.value) + "%"
                                                   : number(d.value));
  }
  line("hit", o.rays.hit == HitRule::first ? "first" : "nearest");
  line("cage_mode", to_string(o.rays.cage_mode));
  if (o.rays.cage_mode == CageMode::banded) line("edge_band", number(o.rays.edge_band));
  line("retry_misses", o.rays.retry_misses == RetryMisses::on    ? "on"
                       : o.rays.retry_misses == RetryMisses::off ? "off"
                                                                 : "auto");
  line("cage", o.cage_path.empty() ? "none" : "mesh");
  line("ignore_backfaces", o.rays.ignore_backfaces ? "1" : "0");
  line("high_normals", o.encode.high_normals == HighNormals::smooth ? "smooth" : "face");
  // Not written for the default, so a key made before the option existed
  // stays the key of the same bake (auto reads what the high's files say).
  if (o.high_normal_maps != HighNormalMaps::automatic)
    line("high_normal_maps", to_string(o.high_normal_maps));
  line("tangent_encode", o.encode.tangent_encode == TangentEncode::inverse ? "inverse" : "transpose");
  line("tangent_basis", to_string(o.tangent_basis));
  // Outputs as engines want them: the preset, and what it resolved to after
  // explicit flags (the rules are what change bytes; the name errs on the
  // side of a miss).
  line("preset", o.preset.empty() ? "none" : o.preset);
  line("decode", std::string(to_string(o.encode.decode.bitangent)) + " " +
                     word_of(kFrameRuleWords, o.encode.decode.unit_frame) + " " +
                     word_of(kBlueRuleWords, o.encode.decode.rebuild_blue));
  line("dither", o.dither ? "on" : "off");
  // The BVH's quality and layout do not choose other hits, but a key errs on
  // the side of a miss.
  line("build_quality", std::to_string(static_cast<int>(o.build_quality)));
  line("bvh", std::to_string(static_cast<int>(o.bvh_memory)));
  line("padding", std::to_string(o.padding));
  line("unwrap_gutter", std::to_string(o.unwrap_gutter));
  line("match", to_string(o.match.mode));
  line("suffixes", o.match.low_suffix + " " + o.match.high_suffix + " " + o.match.cage_suffix);
  line("unmatched", to_string(o.match.unmatched));
  for (const GroupSpec& g : o.match.groups) {
    std::string text = g.name + " |";
    for (const std::string& n : g.low) text += " " + n;
    text += " |";
    for (const std::string& n : g.high) text += " " + n;
    line("group", text);
  }
  // The map set, only when it is more than the normal map (the key of a
  // normal bake is the key it had before maps existed): the maps in order,
  // the options of those baked, and whether an output's format was given
  // (a map's own depth for `.png` otherwise).
  const bool map_set = o.maps.size() != 1 || o.maps.front() != MapKind::normal;
  for (const OutputSpec& out : o.outputs) {
    line("output", std::string(to_string(out.format)) + (has_udim_token(out.path) ? " udim" : "") +
                       (map_set && out.format_given ? " given" : ""));
  }
  if (map_set) {
    std::string names;
    for (const MapKind m : o.maps) {
      if (!names.empty()) names += ',';
      names += to_string(m);
    }
    line("maps", names);
    const auto has = [&](MapKind m) { return std::find(o.maps.begin(), o.maps.end(), m) != o.maps.end(); };
    const auto distance = [&](const Distance& d) {
      return d.kind == Distance::Kind::automatic ? std::string("auto")
             : d.kind == Distance::Kind::percent ? number(d.value) + "%"
                                                 : number(d.value);
    };
    if (has(MapKind::height)) line("height_range", o.height_range > 0.0f ? number(o.height_range) : "auto");
    if (has(MapKind::curvature))
      line("curvature_range", o.curvature_range > 0.0f ? number(o.curvature_range) : "auto");
    if (has(MapKind::id)) line("id_source", to_string(o.id_source));
    if (has(MapKind::ao) || has(MapKind::bent_normal)) {
      line("ao_rays", std::to_string(o.ao_rays));
      line("ao_distance", distance(o.ao_distance));
    }
    if (has(MapKind::thickness)) {
      line("thickness_rays", std::to_string(o.thickness_rays));
      line("thickness_distance", distance(o.thickness_distance));
    }
  }
  return t;
}

namespace {

// Why reading a file failed: it is not a regular file (a folder, a FIFO, a
// device: opened without blocking, so a FIFO is refused, not waited on), or
// the system's reason, or it changed size while it was read.
enum class ReadFailure { none, open, not_regular, read, changed };

// Reads the regular file `path` in 1 MiB chunks: `take_size(size)` once its
// size is known, then `take(bytes, count)` for each chunk. `error` is the
// system's reason for an open or read failure.
template <typename TakeSize, typename Take>
ReadFailure read_regular_file(const std::string& path, TakeSize&& take_size, Take&& take,
                              std::string& error) {
  const int fd = ::open(path.c_str(), O_RDONLY | O_NONBLOCK | O_CLOEXEC);
  if (fd < 0) {
    error = std::strerror(errno);
    return ReadFailure::open;
  }
  struct stat info {};
  if (::fstat(fd, &info) != 0 || !S_ISREG(info.st_mode)) {
    ::close(fd);
    return ReadFailure::not_regular;
  }
  const auto size = static_cast<std::uint64_t>(info.st_size);
  take_size(size);
  constexpr std::size_t kChunk = std::size_t{1} << 20;
  const auto buffer = std::make_unique_for_overwrite<char[]>(kChunk);
  std::uint64_t total = 0;
  for (;;) {
    const ssize_t got = ::read(fd, buffer.get(), kChunk);
    if (got < 0 && errno == EINTR) continue;
    if (got < 0) {
      error = std::strerror(errno);
      ::close(fd);
      return ReadFailure::read;
    }
    if (got == 0) break;
    take(buffer.get(), static_cast<std::size_t>(got));
    total += static_cast<std::uint64_t>(got);
  }
  ::close(fd);
  return total == size ? ReadFailure::none : ReadFailure::changed;
}

// Streams a file into the hash; its length first, so that two files cannot
// trade bytes across their border.
Status hash_file(XXH3_state_t* state, const std::string& path, const char* role) {
  if (path.empty()) {
    const std::uint64_t none = ~std::uint64_t{0};
    XXH3_128bits_update(state, &none, sizeof none);
    return Status::ok();
  }
  std::string error;
  const ReadFailure failure = read_regular_file(
      path, [&](std::uint64_t size) { XXH3_128bits_update(state, &size, sizeof size); },
      [&](const char* bytes, std::size_t count) { XXH3_128bits_update(state, bytes, count); }, error);
  const std::string mesh = std::string("the ") + role + " mesh";
  switch (failure) {
    case ReadFailure::none:
      return Status::ok();
    case ReadFailure::not_regular:
      return Status::bad_input(path + ": " + mesh + " is not a regular file");
    case ReadFailure::changed:
      return Status::bad_input(path + ": " + mesh + " changed while it was read");
    case ReadFailure::open:
    case ReadFailure::read:
      break;
  }
  return Status::bad_input(path + ": cannot read " + mesh + ": " + error);
}

}  // namespace

std::string hash_file_contents(const std::string& path, std::uint64_t& size, std::uint64_t& hash) {
  std::unique_ptr<XXH3_state_t, decltype(&XXH3_freeState)> state(XXH3_createState(), &XXH3_freeState);
  NMBAKE_CHECK(state != nullptr, "xxHash state");
  XXH3_64bits_reset(state.get());
  std::string error;
  const ReadFailure failure = read_regular_file(
      path, [&](std::uint64_t file_size) { size = file_size; },
      [&](const char* bytes, std::size_t count) { XXH3_64bits_update(state.get(), bytes, count); }, error);
  switch (failure) {
    case ReadFailure::none:
      hash = XXH3_64bits_digest(state.get());
      return "";
    case ReadFailure::not_regular:
      return path + ": not a regular file";
    case ReadFailure::changed:
      return path + ": changed while it was read";
    case ReadFailure::open:
    case ReadFailure::read:
      break;
  }
  return path + ": " + error;
}

Status bake_key(const BakeOptions& o, BakeKey& key) {
  std::unique_ptr<XXH3_state_t, decltype(&XXH3_freeState)> state(XXH3_createState(), &XXH3_freeState);
  NMBAKE_CHECK(state != nullptr, "xxHash state");
  XXH3_128bits_reset(state.get());
  const std::string text = bake_key_text(o);
  XXH3_128bits_update(state.get(), text.data(), text.size());
  NMBAKE_TRY(hash_file(state.get(), o.low_path, "low"));
  for (const std::string& high : o.high_paths) NMBAKE_TRY(hash_file(state.get(), high, "high"));
  NMBAKE_TRY(hash_file(state.get(), o.cage_path, "cage"));
  // The palette's bytes make the id map's colours (a bake without an id map
  // does not read it).
  if (std::find(o.maps.begin(), o.maps.end(), MapKind::id) != o.maps.end() && !o.id_palette.empty())
    NMBAKE_TRY(hash_file(state.get(), o.id_palette, "id palette"));
  const XXH128_hash_t h = XXH3_128bits_digest(state.get());
  key.high = h.high64;
  key.low = h.low64;
  return Status::ok();
}

void tile_rows(int height, int index, int count, int& begin, int& end) {
  NMBAKE_CHECK(count > 0 && index >= 0 && index < count, "tile index in range");
  const int units = (height + kRasterTileSize - 1) / kRasterTileSize;  // 32-row raster tiles
  const auto split = [&](int i) {
    return static_cast<int>(static_cast<std::int64_t>(units) * i / count) * kRasterTileSize;
  };
  begin = std::min(height, split(index));
  end = std::min(height, split(index + 1));
}

bool parse_tile_spec(const std::string& text, int& index, int& count) {
  const std::size_t slash = text.find('/');
  if (slash == std::string::npos || slash == 0 || slash + 1 == text.size()) return false;
  int i = 0, n = 0;
  for (std::size_t k = 0; k < text.size(); ++k) {
    if (k == slash) continue;
    if (text[k] < '0' || text[k] > '9') return false;
  }
  try {
    if (slash > 6 || text.size() - slash - 1 > 6) return false;
    i = std::stoi(text.substr(0, slash));
    n = std::stoi(text.substr(slash + 1));
  } catch (...) {
    return false;
  }
  if (n < 1 || n > 4096 || i < 1 || i > n) return false;
  index = i - 1;
  count = n;
  return true;
}

namespace {

// The format's number is the magic's last byte. "2": the dither flag joined
// the header; "3": every map of a map set, its settings and counts.
constexpr char kMagic[8] = {'N', 'M', 'B', 'T', 'I', 'L', 'E', '3'};
constexpr std::size_t kMaxTileOutputs = 64, kMaxPathBytes = 65536, kMaxFigures = 64, kMaxFigureName = 64;
constexpr std::size_t kMapKindCount = std::size(kMapKindWords);

template <typename T>
void put(std::string& out, const T& value) {
  out.append(reinterpret_cast<const char*>(&value), sizeof value);
}

std::size_t map_channels(const std::vector<MapKind>& maps) {
  std::size_t channels = 0;
  for (const MapKind m : maps) channels += static_cast<std::size_t>(map_traits(m).channels);
  return channels;
}

// XXH3-64 of the header and the tile's arrays: the trailer of a tile file.
std::uint64_t tile_checksum(const std::string& header, const TileData& tile) {
  std::unique_ptr<XXH3_state_t, decltype(&XXH3_freeState)> state(XXH3_createState(), &XXH3_freeState);
  NMBAKE_CHECK(state != nullptr, "xxHash state");
  XXH3_64bits_reset(state.get());
  XXH3_64bits_update(state.get(), header.data(), header.size());
  for (const std::vector<float>& texels : tile.texels) {
    XXH3_64bits_update(state.get(), texels.data(), texels.size() * sizeof(float));
  }
  XXH3_64bits_update(state.get(), tile.coverage.data(), tile.coverage.size());
  return XXH3_64bits_digest(state.get());
}

struct FdCloser {
  int fd;
  ~FdCloser() { ::close(fd); }
};

// Reads `n` bytes, or false at the end of the file or on an error.
bool read_fully(int fd, void* out, std::uint64_t n) {
  auto* at = static_cast<char*>(out);
  while (n > 0) {
    const ssize_t got =
        ::read(fd, at, static_cast<std::size_t>(std::min<std::uint64_t>(n, std::uint64_t{1} << 30)));
    if (got < 0 && errno == EINTR) continue;
    if (got <= 0) return false;
    at += got;
    n -= static_cast<std::uint64_t>(got);
  }
  return true;
}

// Reads a tile file's header field by field; no read (and so no
// allocation) is larger than what is left of the file. The bytes read are
// kept for the checksum.
class HeaderReader {
 public:
  HeaderReader(int fd, std::uint64_t file_size) : fd_(fd), left_(file_size) {}
  bool bytes(void* out, std::uint64_t n) {
    if (n > left_) return false;
    const std::size_t at = header.size();
    header.resize(at + n);
    if (!read_fully(fd_, header.data() + at, n)) return false;
    std::memcpy(out, header.data() + at, n);
    left_ -= n;
    return true;
  }
  template <typename T>
  bool get(T& value) {
    return bytes(&value, sizeof value);
  }
  bool text(std::string& out, std::uint64_t n) {
    if (n > left_) return false;
    out.resize(n);
    return bytes(out.data(), n);
  }
  std::uint64_t left() const { return left_; }
  std::string header;

 private:
  int fd_;
  std::uint64_t left_;
};

// Where `nmbake merge` without -o may write the maps a tile file names: a
// tile file is data from another machine (or made to look like one), so
// the path it carries must not pick any file of this one. A relative path
// without a `..` component (it is relative to the current folder, as the
// bake's was to its own), or an absolute one inside the current folder or
// the tile file's folder (a plan's tiles lie beside their maps); either
// with an image extension. Anything else needs -o.
Status check_tile_output(const std::string& path, const std::string& tile_path) {
  namespace fs = std::filesystem;
  const auto refuse = [&](const char* why) {
    return Status::bad_input(printable_text(tile_path) + ": the tile names the output '" +
                             printable_text(path) + "', " + why + ": give -o to write the maps elsewhere");
  };
  PixelFormat format{};
  if (path.empty() || !pixel_format_from_path(path, format)) return refuse("not an image file name");
  const fs::path p(path);
  for (const fs::path& part : p) {
    if (part == "..") return refuse("which leaves its folder through `..`");
  }
  if (p.is_relative()) return Status::ok();
  std::error_code ec;
  const fs::path normal = p.lexically_normal();
  const auto inside = [&](const fs::path& folder) {
    const fs::path relative = normal.lexically_relative(folder.lexically_normal());
    return !relative.empty() && *relative.begin() != "..";
  };
  const fs::path here = fs::current_path(ec);
  if (!ec && inside(here)) return Status::ok();
  const fs::path tile_folder = fs::absolute(tile_path, ec).parent_path();
  if (!ec && inside(tile_folder)) return Status::ok();
  return refuse("an absolute path outside the current folder and the tile file's folder");
}

bool finite_at_least_zero(float v) { return std::isfinite(v) && v >= 0.0f; }

// Whether two tiles' map sets finish and write alike (what a tile file holds
// of MapSettings).
bool same_map_set(const MapSettings& a, const MapSettings& b) {
  return a.maps == b.maps && a.height_range == b.height_range && a.curvature_range == b.curvature_range &&
         a.occlusion.rays == b.occlusion.rays && a.occlusion.distance == b.occlusion.distance &&
         a.thickness.rays == b.thickness.rays && a.thickness.distance == b.thickness.distance &&
         a.position_bounds.min == b.position_bounds.min && a.position_bounds.max == b.position_bounds.max;
}

}  // namespace

Status write_tile(const std::string& path, const TileData& tile) {
  const std::size_t texels = static_cast<std::size_t>(tile.row_end - tile.row_begin) * tile.width;
  const MapSettings& m = tile.maps;
  NMBAKE_CHECK(tile.texels.size() == m.maps.size() && tile.counts.maps.size() == m.maps.size() &&
                   tile.coverage.size() == texels,
               "a tile's arrays: one per map, of its rows");
  for (std::size_t i = 0; i < m.maps.size(); ++i) {
    NMBAKE_CHECK(tile.texels[i].size() == texels * static_cast<std::size_t>(map_traits(m.maps[i]).channels),
                 "a map's texels of the tile's rows");
  }
  std::string header(kMagic, sizeof kMagic);
  put(header, tile.key.high);
  put(header, tile.key.low);
  for (const int v :
       {tile.width, tile.height, tile.row_begin, tile.row_end, tile.index, tile.count, tile.padding,
        tile.dither ? 1 : 0, static_cast<int>(tile.outputs.size()), static_cast<int>(m.maps.size())}) {
    put(header, static_cast<std::int32_t>(v));
  }
  for (const OutputSpec& out : tile.outputs) {
    put(header, static_cast<std::uint8_t>(out.format));
    put(header, static_cast<std::uint8_t>(out.format_given ? 1 : 0));
    put(header, static_cast<std::uint32_t>(out.path.size()));
    header += out.path;
  }
  for (const MapKind map : m.maps) put(header, static_cast<std::uint8_t>(map));
  put(header, m.height_range);
  put(header, m.curvature_range);
  put(header, static_cast<std::int32_t>(m.occlusion.rays));
  put(header, m.occlusion.distance);
  put(header, static_cast<std::int32_t>(m.thickness.rays));
  put(header, m.thickness.distance);
  for (int a = 0; a < 3; ++a) put(header, m.position_bounds.min[a]);
  for (int a = 0; a < 3; ++a) put(header, m.position_bounds.max[a]);
  MapCounts counts = tile.counts;
  for (const std::uint64_t* v : counters(counts.occlusion)) put(header, *v);
  for (const std::uint64_t* v : counters(counts.thickness)) put(header, *v);
  for (const auto& figures : counts.maps) {
    NMBAKE_CHECK(figures.size() <= kMaxFigures, "a map's counters fit a tile file");
    put(header, static_cast<std::uint32_t>(figures.size()));
    for (const auto& [name, value] : figures) {
      NMBAKE_CHECK(!name.empty() && name.size() <= kMaxFigureName, "a counter's name fits a tile file");
      put(header, static_cast<std::uint8_t>(name.size()));
      header += name;
      put(header, value);
    }
  }
  const std::uint64_t check = tile_checksum(header, tile);

  std::vector<std::string_view> pieces{header};
  for (const std::vector<float>& t : tile.texels) {
    pieces.emplace_back(reinterpret_cast<const char*>(t.data()), t.size() * sizeof(float));
  }
  pieces.emplace_back(reinterpret_cast<const char*>(tile.coverage.data()), tile.coverage.size());
  pieces.emplace_back(reinterpret_cast<const char*>(&check), sizeof check);
  return write_file_atomically(path, pieces, "the tile file");
}

Status read_tile(const std::string& path, TileData& tile) {
  tile = TileData{};
  if (path.find('\0') != std::string::npos)
    return Status::bad_input(path + ": cannot open the tile file: the path holds a NUL byte");
  // A regular file only, as the mesh loaders take: O_NONBLOCK keeps the
  // open of a FIFO from waiting for a writer, and fstat refuses it (and a
  // device, which never ends) before a byte is read.
  const int fd = ::open(path.c_str(), O_RDONLY | O_NONBLOCK | O_CLOEXEC);
  if (fd < 0) return Status::bad_input(path + ": cannot open the tile file: " + std::strerror(errno));
  const FdCloser closer{fd};
  struct stat info {};
  if (::fstat(fd, &info) != 0)
    return Status::bad_input(path + ": cannot open the tile file: " + std::strerror(errno));
  if (!S_ISREG(info.st_mode)) {
    return Status::bad_input(path + ": the tile file is not a regular file (a folder, FIFO or device)");
  }
  (void)::fcntl(fd, F_SETFL, ::fcntl(fd, F_GETFL) & ~O_NONBLOCK);
  const auto file_size = static_cast<std::uint64_t>(info.st_size);
  const auto bad = [&](const std::string& why) {
    return Status::bad_input(path + ": not a complete nmbake tile file: " + why);
  };
  HeaderReader r(fd, file_size);
  char magic[sizeof kMagic];
  if (!r.bytes(magic, sizeof magic)) return bad("too short");
  if (std::memcmp(magic, kMagic, sizeof kMagic - 1) != 0) return bad("wrong magic bytes");
  if (magic[7] != kMagic[7]) {
    const std::string version = printable_text(std::string(1, magic[7]));
    return Status::bad_input(path + ": a tile file of format " + version + ", written by " +
                             (magic[7] >= '0' && magic[7] < kMagic[7] ? "an older" : "another") +
                             " nmbake; this nmbake reads format " + kMagic[7] +
                             " (it carries every map of a map set): bake the tiles again with it");
  }
  std::int32_t v[10];
  if (!r.get(tile.key.high) || !r.get(tile.key.low) || !r.get(v)) return bad("too short");
  tile.width = v[0];
  tile.height = v[1];
  tile.row_begin = v[2];
  tile.row_end = v[3];
  tile.index = v[4];
  tile.count = v[5];
  tile.padding = v[6];
  const std::int32_t dither = v[7];
  tile.dither = dither == 1;
  const std::int32_t output_count = v[8], map_count = v[9];
  if (tile.width <= 0 || tile.height <= 0 || tile.width > 65536 || tile.height > 65536 ||
      tile.row_begin < 0 || tile.row_end < tile.row_begin || tile.row_end > tile.height || tile.count < 1 ||
      tile.count > 4096 || tile.index < 0 || tile.index >= tile.count || tile.padding < 0 ||
      tile.padding > 4096 || (dither != 0 && dither != 1) || output_count < 0 ||
      output_count > static_cast<std::int32_t>(kMaxTileOutputs) || map_count < 1 ||
      map_count > static_cast<std::int32_t>(kMapKindCount)) {
    return bad("header values out of range");
  }
  for (std::int32_t i = 0; i < output_count; ++i) {
    std::uint8_t format = 0, given = 0;
    std::uint32_t length = 0;
    if (!r.get(format) || !r.get(given) || !r.get(length)) return bad("too short");
    if (format > static_cast<std::uint8_t>(PixelFormat::tga8) || given > 1 || length > kMaxPathBytes) {
      return bad("bad output entry");
    }
    OutputSpec out;
    out.format = static_cast<PixelFormat>(format);
    out.format_given = given == 1;
    if (!r.text(out.path, length)) return bad("too short");
    if (out.path.find('\0') != std::string::npos) return bad("an output path holds a NUL byte");
    tile.outputs.push_back(std::move(out));
  }
  MapSettings& m = tile.maps;
  m.maps.clear();
  for (std::int32_t i = 0; i < map_count; ++i) {
    std::uint8_t kind = 0;
    if (!r.get(kind)) return bad("too short");
    const auto map = static_cast<MapKind>(kind);
    if (kind >= kMapKindCount || !map_traits(map).implemented || m.has(map)) return bad("bad map list");
    m.maps.push_back(map);
  }
  std::int32_t ao_rays = 0, thickness_rays = 0;
  if (!r.get(m.height_range) || !r.get(m.curvature_range) || !r.get(ao_rays) ||
      !r.get(m.occlusion.distance) || !r.get(thickness_rays) || !r.get(m.thickness.distance)) {
    return bad("too short");
  }
  for (int a = 0; a < 3; ++a) {
    if (!r.get(m.position_bounds.min[a])) return bad("too short");
  }
  for (int a = 0; a < 3; ++a) {
    if (!r.get(m.position_bounds.max[a])) return bad("too short");
  }
  m.occlusion.rays = ao_rays;
  m.occlusion.bent = m.has(MapKind::bent_normal);
  m.thickness.rays = thickness_rays;
  bool finite_box = true;
  for (int a = 0; a < 3; ++a) {
    finite_box =
        finite_box && std::isfinite(m.position_bounds.min[a]) && std::isfinite(m.position_bounds.max[a]);
  }
  if (!finite_at_least_zero(m.height_range) || !finite_at_least_zero(m.curvature_range) ||
      !finite_at_least_zero(m.occlusion.distance) || !finite_at_least_zero(m.thickness.distance) ||
      ao_rays < 1 || ao_rays > kMaxOcclusionRays || thickness_rays < 1 ||
      thickness_rays > kMaxOcclusionRays || !finite_box) {
    return bad("map settings out of range");
  }
  for (std::uint64_t* f : counters(tile.counts.occlusion)) {
    if (!r.get(*f)) return bad("too short");
  }
  for (std::uint64_t* f : counters(tile.counts.thickness)) {
    if (!r.get(*f)) return bad("too short");
  }
  tile.counts.maps.resize(m.maps.size());
  for (auto& figures : tile.counts.maps) {
    std::uint32_t count = 0;
    if (!r.get(count)) return bad("too short");
    if (count > kMaxFigures) return bad("too many counters of a map");
    for (std::uint32_t i = 0; i < count; ++i) {
      std::uint8_t length = 0;
      std::string name;
      double value = 0.0;
      if (!r.get(length) || !r.text(name, length) || !r.get(value)) return bad("too short");
      const bool word =
          !name.empty() && name.size() <= kMaxFigureName && std::all_of(name.begin(), name.end(), [](char c) {
            return (c >= 'a' && c <= 'z') || (c >= '0' && c <= '9') || c == '_';
          });
      // Counts: whole numbers a double holds exactly, so sums do not depend on the order.
      if (!word || !(value >= 0.0 && value <= 0x1p53) || value != std::floor(value))
        return bad("bad counter");
      figures.emplace_back(std::move(name), value);
    }
  }
  const std::uint64_t texels = static_cast<std::uint64_t>(tile.row_end - tile.row_begin) * tile.width;
  const std::uint64_t expected = texels * (map_channels(m.maps) * sizeof(float) + 1) + 8;
  if (expected != r.left()) {
    return bad(std::to_string(file_size) + " bytes where the header says " +
               std::to_string(file_size - r.left() + expected));
  }
  for (const MapKind map : m.maps) {
    std::vector<float>& t =
        tile.texels.emplace_back(texels * static_cast<std::uint64_t>(map_traits(map).channels));
    if (!read_fully(fd, t.data(), t.size() * sizeof(float))) return bad("too short");
  }
  tile.coverage.resize(texels);
  std::uint64_t check = 0;
  if (!read_fully(fd, tile.coverage.data(), texels) || !read_fully(fd, &check, sizeof check))
    return bad("too short");
  if (tile_checksum(r.header, tile) != check)
    return bad("its checksum does not match (a torn or altered file)");
  for (const std::uint8_t c : tile.coverage) {
    if (c > 1) return bad("coverage values other than 0 and 1");
  }
  // A bake writes finite texels; these bounds keep the finishing finite
  // (a NaN would reach the integer conversion of the writers): a dilated
  // texel sums 8 neighbours, and the normal-like maps' dilation squares
  // them. Far beyond any bake's (heights and thicknesses are at most 1e12).
  for (std::size_t i = 0; i < m.maps.size(); ++i) {
    const float limit = map_traits(m.maps[i]).dilate == DilateMode::unit_vector ? 1e15f : 1e30f;
    for (const float x : tile.texels[i]) {
      if (!(std::fabs(x) <= limit)) {
        return bad(std::string("texels of the ") + to_string(m.maps[i]) + " map out of range");
      }
    }
  }
  return Status::ok();
}

std::string MergeReport::to_json() const {
  nlohmann::ordered_json j;
  j["key"] = key.hex();
  j["width"] = width;
  j["height"] = height;
  j["tiles"] = tiles;
  j["outputs"] = outputs;
  j["maps"] = detail::map_reports_json(maps);
  j["dilate_filled_texels"] = dilate.filled_texels;
  j["dilate_fallback_texels"] = dilate.fallback_texels;
  j["seconds"] = {{"read", read_seconds}, {"dilate", dilate_seconds}, {"write", write_seconds}};
  return j.dump(2) + "\n";
}

Status merge_tiles(const std::vector<std::string>& tile_paths, const std::vector<OutputSpec>& outputs,
                   MergeReport& report, const std::vector<std::string>& expected) {
  using Clock = std::chrono::steady_clock;
  report = MergeReport{};
  if (tile_paths.empty()) return Status::bad_input("merge: no tile files given");
  auto begin = Clock::now();
  TileData first;
  NMBAKE_TRY(read_tile(tile_paths.front(), first));
  const int width = first.width, height = first.height, count = first.count;
  if (static_cast<int>(tile_paths.size()) != count) {
    return Status::bad_input(tile_paths.front() + ": the bake has " + std::to_string(count) + " tiles, " +
                             std::to_string(tile_paths.size()) + " tile files were given");
  }
  const int padding = first.padding;
  const bool dither = first.dither;
  const MapSettings settings = first.maps;
  const std::vector<OutputSpec> named = first.outputs;
  const std::vector<OutputSpec>& targets = outputs.empty() ? named : outputs;
  if (targets.empty()) return Status::bad_input("merge: no output map given (-o) and the tiles name none");
  if (outputs.empty()) {
    const auto normal = [](const std::string& path) {
      std::error_code ec;
      return std::filesystem::absolute(path, ec).lexically_normal().string();
    };
    std::vector<std::string> names, wanted;
    for (const OutputSpec& out : named) names.push_back(normal(out.path));
    for (const std::string& path : expected) wanted.push_back(normal(path));
    if (!expected.empty() && names != wanted) {
      return Status::bad_input(printable_text(tile_paths.front()) +
                               ": the tile names other outputs than the plan expects: bake the tiles again");
    }
    if (expected.empty()) {
      for (const OutputSpec& out : named) NMBAKE_TRY(check_tile_output(out.path, tile_paths.front()));
    }
  }
  if (const Status tokens = check_map_tokens(targets, settings.maps); !tokens) {
    return Status::bad_input("merge: " + tokens.message());
  }
  const std::vector<MapOutput> files = map_outputs(targets, settings.maps);
  for (const MapOutput& out : files) {
    if (const Status writer = check_image_writer(out.format); !writer)
      return Status::internal(out.path + ": " + writer.message());
  }
  // The whole map's set: the tiles' texels go into its images.
  MapSet maps(settings, width, 0, height);
  std::vector<std::uint8_t> coverage(static_cast<std::size_t>(width) * height, 0);
  std::vector<std::string> seen(static_cast<std::size_t>(count));
  report.key = first.key;
  for (std::size_t i = 0; i < tile_paths.size(); ++i) {
    TileData tile;
    if (i == 0) {
      tile = std::move(first);
    } else {
      NMBAKE_TRY(read_tile(tile_paths[i], tile));
    }
    const std::string& path = tile_paths[i];
    if (!(tile.key == report.key)) {
      return Status::bad_input(path + ": a tile of another bake (key " + tile.key.hex() + ", not " +
                               report.key.hex() + ")");
    }
    if (tile.width != width || tile.height != height || tile.count != count || tile.padding != padding ||
        tile.dither != dither || !same_map_set(tile.maps, settings)) {
      return Status::bad_input(
          path + ": a tile of another bake (size, tile count, padding, dithering or maps differ)");
    }
    if (!seen[tile.index].empty()) {
      return Status::bad_input(path + ": tile " + std::to_string(tile.index + 1) + "/" +
                               std::to_string(count) + " is given twice (also " + seen[tile.index] + ")");
    }
    seen[tile.index] = path;
    int b = 0, e = 0;
    tile_rows(height, tile.index, count, b, e);
    if (tile.row_begin != b || tile.row_end != e)
      return Status::bad_input(path + ": its rows are not those of its tile");
    for (std::size_t m = 0; m < settings.maps.size(); ++m) {
      Image& image = maps.image(settings.maps[m]);
      std::copy(tile.texels[m].begin(), tile.texels[m].end(),
                image.pixels.begin() + static_cast<std::ptrdiff_t>(b) * width * image.channels);
    }
    std::copy(tile.coverage.begin(), tile.coverage.end(),
              coverage.begin() + static_cast<std::ptrdiff_t>(b) * width);
    maps.add_counts(tile.counts);
  }
  report.read_seconds = std::chrono::duration<double>(Clock::now() - begin).count();
  report.width = width;
  report.height = height;
  report.tiles = count;
  begin = Clock::now();
  maps.finish(coverage, padding, report.dilate);
  report.dilate_seconds = std::chrono::duration<double>(Clock::now() - begin).count();
  begin = Clock::now();
  NMBAKE_TRY(write_map_files(maps, files, dither));
  report.write_seconds = std::chrono::duration<double>(Clock::now() - begin).count();
  for (const MapOutput& out : files) report.outputs.push_back(out.path);
  report.maps = map_file_reports(maps, files, 1001);
  return Status::ok();
}

}  // namespace nmbake
