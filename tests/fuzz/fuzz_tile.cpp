// Tile files through read_tile() and merge_tiles(), as `nmbake merge` reads
// them. The fuzzer's bytes are the file without its trailer: the harness
// appends their XXH3-64, so a mutation reaches the field checks instead of
// stopping at the checksum. A tile that reads and is a whole bake (1/1) is
// merged into a scratch folder: every map finished and written as PNG at
// the map's own depth and as float EXR.
//
// LLVMFuzzerCustomMutator mutates by structure half of the time: it walks
// the header as read_tile() does, picks one field (a size, a row, a count, a
// format, a path length, a map kind, a range, a ray count, a counter) and
// gives it a value from the edges of its type or its check, then resizes
// the texel arrays to what the new header asks for, so that the file still
// reaches the checks after the header (and the checksum, appended by the
// harness, still matches).
#include <tbb/global_control.h>

#include <cmath>
#include <cstdio>
#include <cstring>
#include <limits>
#include <random>
#include <string>
#include <vector>

#define XXH_INLINE_ALL  // the library keeps libxxhash to itself
#include <xxhash.h>

#include "fuzz_util.hpp"
#include "nmbake/maps.hpp"
#include "nmbake/task.hpp"

extern "C" std::size_t LLVMFuzzerMutate(std::uint8_t* data, std::size_t size, std::size_t max_size);

namespace {

enum class FieldKind { i32, u32, u8, f32, u64, f64 };

struct Field {
  std::size_t offset;
  FieldKind kind;
};

template <typename T>
T load(const std::uint8_t* data, std::size_t offset) {
  T v;
  std::memcpy(&v, data + offset, sizeof v);
  return v;
}

// The header's fields in file order (task.cpp's format 3), as far as the
// bytes go; `texels_at` is where the texel arrays start (0 when the header
// is cut short) and `channels` the map set's channel count.
std::vector<Field> header_fields(const std::uint8_t* data, std::size_t size, std::size_t& texels_at,
                                 int& channels) {
  std::vector<Field> fields;
  texels_at = 0;
  channels = 0;
  std::size_t at = 24;  // magic, key
  const auto add = [&](FieldKind kind, std::size_t bytes) {
    if (at + bytes > size) return false;
    fields.push_back({at, kind});
    at += bytes;
    return true;
  };
  for (int i = 0; i < 10; ++i) {
    if (!add(FieldKind::i32, 4)) return fields;
  }
  const auto outputs = load<std::int32_t>(data, 24 + 8 * 4), maps = load<std::int32_t>(data, 24 + 9 * 4);
  if (outputs < 0 || outputs > 64 || maps < 1 || maps > 16) return fields;
  for (std::int32_t i = 0; i < outputs; ++i) {
    if (!add(FieldKind::u8, 1) || !add(FieldKind::u8, 1) || !add(FieldKind::u32, 4)) return fields;
    const auto length = load<std::uint32_t>(data, at - 4);
    if (length > size - at) return fields;
    at += length;
  }
  for (std::int32_t i = 0; i < maps; ++i) {
    if (!add(FieldKind::u8, 1)) return fields;
    const auto kind = static_cast<nmbake::MapKind>(data[at - 1]);
    if (data[at - 1] <= static_cast<std::uint8_t>(std::size(nmbake::kMapKindWords) - 1))
      channels += nmbake::map_traits(kind).channels;
  }
  for (const FieldKind k :
       {FieldKind::f32, FieldKind::f32, FieldKind::i32, FieldKind::f32, FieldKind::i32, FieldKind::f32,
        FieldKind::f32, FieldKind::f32, FieldKind::f32, FieldKind::f32, FieldKind::f32, FieldKind::f32}) {
    if (!add(k, 4)) return fields;
  }
  for (int i = 0; i < 13; ++i) {
    if (!add(FieldKind::u64, 8)) return fields;
  }
  for (std::int32_t m = 0; m < maps; ++m) {
    if (!add(FieldKind::u32, 4)) return fields;
    const auto count = load<std::uint32_t>(data, at - 4);
    if (count > 64) return fields;
    for (std::uint32_t i = 0; i < count; ++i) {
      if (!add(FieldKind::u8, 1)) return fields;
      at += data[at - 1];
      if (at > size || !add(FieldKind::f64, 8)) return fields;
    }
  }
  texels_at = at;
  return fields;
}

template <typename T>
void store(std::uint8_t* data, std::size_t offset, T v) {
  std::memcpy(data + offset, &v, sizeof v);
}

void mutate_field(std::uint8_t* data, const Field& f, std::minstd_rand& rng) {
  const auto pick = [&](auto... values) {
    const std::int64_t table[] = {static_cast<std::int64_t>(values)...};
    return table[rng() % sizeof...(values)];
  };
  switch (f.kind) {
    case FieldKind::i32: {
      const auto old = load<std::int32_t>(data, f.offset);
      const std::int64_t v = pick(0, 1, -1, 2, 32, 4096, 4097, 65536, 65537, INT32_MAX, INT32_MIN,
                                  std::int64_t{old} + 1, std::int64_t{old} - 1);
      store(data, f.offset, static_cast<std::int32_t>(v));
      break;
    }
    case FieldKind::u32: {
      const auto old = load<std::uint32_t>(data, f.offset);
      store(data, f.offset,
            static_cast<std::uint32_t>(pick(0, 1, 64, 65, 65536, 65537, UINT32_MAX, old + 1, old - 1)));
      break;
    }
    case FieldKind::u8:
      data[f.offset] =
          static_cast<std::uint8_t>(pick(0, 1, 2, 5, 10, 11, 12, 64, 65, 255, data[f.offset] + 1));
      break;
    case FieldKind::f32: {
      const float values[] = {0.0f,
                              -0.0f,
                              1.0f,
                              -1.0f,
                              1e-39f,
                              1.5e-39f,
                              1e30f,
                              3.4e38f,
                              std::numeric_limits<float>::infinity(),
                              std::numeric_limits<float>::quiet_NaN(),
                              std::numeric_limits<float>::denorm_min(),
                              1e12f};
      store(data, f.offset, values[rng() % std::size(values)]);
      break;
    }
    case FieldKind::u64:
      store(data, f.offset, static_cast<std::uint64_t>(pick(0, 1, INT64_MAX, -1, 1ll << 53)));
      break;
    case FieldKind::f64: {
      const double values[] = {0.0,
                               1.0,
                               -1.0,
                               0.5,
                               0x1p53,
                               0x1p53 + 2,
                               1e300,
                               std::numeric_limits<double>::infinity(),
                               std::numeric_limits<double>::quiet_NaN()};
      store(data, f.offset, values[rng() % std::size(values)]);
      break;
    }
  }
}

}  // namespace

extern "C" std::size_t LLVMFuzzerCustomMutator(std::uint8_t* data, std::size_t size, std::size_t max_size,
                                               unsigned int seed) {
  std::minstd_rand rng(seed);
  std::size_t texels_at = 0;
  int channels = 0;
  const std::vector<Field> fields = header_fields(data, size, texels_at, channels);
  if (fields.empty() || rng() % 2 == 0) return LLVMFuzzerMutate(data, size, max_size);
  mutate_field(data, fields[rng() % fields.size()], rng);
  // Texels and coverage as the (new) header asks, when it still parses and
  // they fit: a mutation of the size then reaches the texel checks.
  std::size_t at = 0;
  int new_channels = 0;
  header_fields(data, size, at, new_channels);
  if (at == 0) return size;
  const auto width = load<std::int32_t>(data, 24), begin = load<std::int32_t>(data, 32),
             end = load<std::int32_t>(data, 36);
  if (width <= 0 || end < begin || begin < 0) return size;
  const auto texels = static_cast<std::uint64_t>(end - begin) * static_cast<std::uint64_t>(width);
  const std::uint64_t want = at + texels * (static_cast<std::uint64_t>(new_channels) * 4 + 1);
  if (want > max_size) return size;
  if (want > size) std::memset(data + size, 0, static_cast<std::size_t>(want - size));
  return static_cast<std::size_t>(want);
}

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  // One thread: two cores are shared, and the fuzzer wants executions.
  static const tbb::global_control one_thread(tbb::global_control::max_allowed_parallelism, 1);
  std::vector<std::uint8_t> bytes(data, data + size);
  const std::uint64_t check = XXH3_64bits(data, size);
  const auto* trailer = reinterpret_cast<const std::uint8_t*>(&check);
  bytes.insert(bytes.end(), trailer, trailer + sizeof check);
  const nmbake::fuzz::InputFile file(bytes.data(), bytes.size(), "input.nmt");
  nmbake::TileData tile;
  if (!nmbake::read_tile(file.path(), tile).is_ok() || tile.count != 1) return 0;
  // The merge holds the whole map set in memory: a header may rightly ask
  // for 16384^2 x 3 floats (3 GB), over libFuzzer's malloc limit. Merges of
  // maps up to 4096^2 are fuzzed; the larger ones run the same code.
  if (static_cast<std::uint64_t>(tile.width) * static_cast<std::uint64_t>(tile.height) > 4096u * 4096u)
    return 0;
  const std::string folder = nmbake::fuzz::scratch_folder().string();
  const std::vector<nmbake::OutputSpec> outputs{
      {folder + "/m_<MAP>.png", nmbake::PixelFormat::png16, false},
      {folder + "/m_<MAP>.exr", nmbake::PixelFormat::exr_float, true}};
  nmbake::MergeReport report;
  if (nmbake::merge_tiles({file.path()}, outputs, report).is_ok()) {
    for (const std::string& path : report.outputs) std::remove(path.c_str());
  }
  return 0;
}
