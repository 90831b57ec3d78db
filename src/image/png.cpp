// PNG encoder for the write stage (ISO/IEC 15948 / W3C PNG, 2nd edition):
// IHDR, IDAT, IEND and nothing else (no gAMA, sRGB or time chunks: a normal
// map's bytes are data, and the same map gives the same file).
//
// Why our own and not OpenImageIO's: its writer runs libpng's adaptive filters
// and one zlib stream on one core, about a quarter of a 2048^2 bake's wall
// time. Here rows are quantised, filtered and deflated in fixed groups of
// about 256 KB in parallel, the way pigz splits gzip: each group is a raw
// deflate stream ended by an empty stored block (so it ends on a byte
// boundary, what zlib's sync flush does), the last ended by a final block;
// their concatenation is one valid deflate stream, and the Adler-32 of the
// whole is combined from the groups' (zlib's adler32_combine). Groups never
// depend on the thread count.
//
// Filter: Paeth on every row (filter type 4). Normal maps are smooth in both
// directions, and Paeth's prediction from left, up and up-left gave the
// smallest files of the five filters on baked maps, with none of the cost of
// libpng's per-row trial of all five.
//
// Deflate: Huffman codes only, no string matching. Paeth residuals of a
// normal map are small numbers with few repeats, so LZ77 finds little: on the
// demo map (2048^2, 16-bit) zlib's Huffman-only mode wrote 11.5 MB in 0.18 s
// where level 1 wrote 13.2 MB in 0.24 s. The Huffman coding is our own
// (deflate_huffman.cpp): zlib's per-byte block bookkeeping was three
// quarters of the write, and ours codes a byte in about a nanosecond.
//
// Checksums: libdeflate's Adler-32 and CRC-32 (SIMD; zlib's were 10% of
// the write; BENCHMARKS.md, "The map set"); zlib's adler32_combine joins the
// groups' Adler-32s (libdeflate has none).
#include "image/png.hpp"

#include <libdeflate.h>
#include <zlib.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <memory>

#include "base/simd4.hpp"
#include "image/deflate_huffman.hpp"
#include "image/quantise.hpp"
#include "image/stream_file.hpp"

namespace nmbake::image_detail {

namespace {

void put_u32(std::vector<std::uint8_t>& out, std::uint32_t v) {
  out.push_back(static_cast<std::uint8_t>(v >> 24));
  out.push_back(static_cast<std::uint8_t>(v >> 16));
  out.push_back(static_cast<std::uint8_t>(v >> 8));
  out.push_back(static_cast<std::uint8_t>(v));
}

// A chunk: length, type, data, CRC-32 of type and data.
void put_chunk(std::vector<std::uint8_t>& out, const char (&type)[5], const std::uint8_t* data,
               std::size_t size) {
  put_u32(out, static_cast<std::uint32_t>(size));
  const std::size_t type_at = out.size();
  out.insert(out.end(), type, type + 4);
  if (size > 0) out.insert(out.end(), data, data + size);
  const std::uint32_t crc = libdeflate_crc32(0, out.data() + type_at, size + 4);
  put_u32(out, static_cast<std::uint32_t>(crc));
}

// Row y quantised to big-endian samples of bits / 8 bytes, each value
// first mapped to v * scale + offset (Mapping); 8-bit rows dithered when
// asked (`channels` values a texel).
struct Mapping {
  float scale = 1.0f, offset = 0.0f;
  bool identity() const { return scale == 1.0f && offset == 0.0f; }
};

template <bool kMapped>
void quantise_row_as(const float* values, std::size_t width, std::size_t channels, int bits,
                     std::uint8_t* out, bool dither, std::size_t y, Mapping m) {
  const std::size_t count = width * channels;
  const auto value = [&](std::size_t i) { return kMapped ? values[i] * m.scale + m.offset : values[i]; };
  if (bits == 8 && dither) {
    // Four texels of a channel at a time, then the rest one by one.
    const auto y32 = static_cast<std::uint32_t>(y);
    std::size_t x = 0;
    for (; x + 4 <= width; x += 4) {
      const auto x32 = static_cast<std::uint32_t>(x);
      if (channels == 1) {
        float v[4];
        for (std::size_t k = 0; k < 4; ++k) v[k] = value(x + k);
        detail::quantise_dithered4_8bit(v, x32, y32, 0, out + x);
        continue;
      }
      for (std::size_t c = 0; c < channels; ++c) {
        float v[4];
        std::uint8_t q[4];
        for (std::size_t k = 0; k < 4; ++k) v[k] = value((x + k) * channels + c);
        detail::quantise_dithered4_8bit(v, x32, y32, static_cast<std::uint32_t>(c), q);
        for (std::size_t k = 0; k < 4; ++k) out[(x + k) * channels + c] = q[k];
      }
    }
    for (std::size_t i = x * channels; x < width; ++x) {
      for (std::size_t c = 0; c < channels; ++c, ++i) {
        out[i] = static_cast<std::uint8_t>(detail::quantise_dithered(
            value(i), 255.0f, static_cast<std::uint32_t>(x), y32, static_cast<std::uint32_t>(c)));
      }
    }
    return;
  }
  const float max_value = bits == 8 ? 255.0f : 65535.0f;
  const auto put = [&](std::size_t i, std::uint32_t q) {
    if (bits == 8) {
      out[i] = static_cast<std::uint8_t>(q);
    } else {
      out[2 * i] = static_cast<std::uint8_t>(q >> 8);
      out[2 * i + 1] = static_cast<std::uint8_t>(q);
    }
  };
  // Four values at a time in SIMD lanes: per lane detail::quantise()'s
  // operations (max and min are its clamp for finite values, the truncating
  // conversion and the fraction's test the same), so the same integers. (GCC
  // keeps the scalar loop's float selects as branches: trapping math.)
  std::size_t i = 0;
  for (; i + 4 <= count; i += 4) {
    detail::f4 v;
    std::memcpy(&v, values + i, sizeof(v));
    if (kMapped) v = v * detail::splat4(m.scale) + detail::splat4(m.offset);
    v = detail::min4(detail::max4(v, detail::splat4(0.0f)), detail::splat4(1.0f));
    const detail::f4 p = v * detail::splat4(max_value);
    const detail::i4 whole = __builtin_convertvector(p, detail::i4);
    const detail::i4 q = whole - ((p - __builtin_convertvector(whole, detail::f4)) >= detail::splat4(0.5f));
#if defined(__SSE2__)
    // Packed in lanes too (q in [0, max]): 16-bit samples big-endian, the
    // unsigned range through the signed pack by an offset of 2^15.
    const __m128i lanes = reinterpret_cast<__m128i>(q);
    if (bits == 8) {
      detail::store_bytes4(lanes, out + i);
    } else {
      const __m128i swapped = _mm_or_si128(_mm_slli_epi32(_mm_and_si128(lanes, _mm_set1_epi32(0xff)), 8),
                                           _mm_srli_epi32(lanes, 8));
      const __m128i offset = _mm_sub_epi32(swapped, _mm_set1_epi32(0x8000));
      const __m128i samples = _mm_xor_si128(_mm_packs_epi32(offset, offset), _mm_set1_epi16(-0x8000));
      _mm_storel_epi64(reinterpret_cast<__m128i*>(out + 2 * i), samples);
    }
#else
    for (int k = 0; k < 4; ++k) put(i + static_cast<std::size_t>(k), static_cast<std::uint32_t>(q[k]));
#endif
  }
  for (; i < count; ++i) put(i, detail::quantise(value(i), max_value));
}

void quantise_row(const float* values, std::size_t width, std::size_t channels, int bits, std::uint8_t* out,
                  bool dither, std::size_t y, Mapping m) {
  if (m.identity()) {
    quantise_row_as<false>(values, width, channels, bits, out, dither, y, m);
  } else {
    quantise_row_as<true>(values, width, channels, bits, out, dither, y, m);
  }
}

// Filter type byte then the Paeth residuals of `row` against `above` (all
// zeros for the first row of the image), `bpp` bytes per pixel. Paeth's
// choice (PNG spec 9.4: the nearest of a, b, c to a + b - c, ties to a then
// b) written without branches, so the loop vectorises: it predicts from the
// unfiltered bytes only, so no byte waits for another.
void filter_row(const std::uint8_t* row, const std::uint8_t* above, std::size_t row_bytes, std::size_t bpp,
                std::uint8_t* out) {
  out[0] = 4;
  // In 16-bit lanes (|a + b - 2c| <= 510): eight bytes a step in SSE2.
  const auto predict = [](std::int16_t a, std::int16_t b, std::int16_t c) {
    const auto abs16 = [](int v) { return static_cast<std::int16_t>(v < 0 ? -v : v); };
    const std::int16_t pa = abs16(b - c), pb = abs16(a - c), pc = abs16(a + b - 2 * c);
    const std::int16_t b_or_c = pb <= pc ? b : c;
    return pa <= pb && pa <= pc ? a : b_or_c;
  };
  const std::size_t head = std::min(bpp, row_bytes);
  for (std::size_t i = 0; i < head; ++i)
    out[1 + i] = static_cast<std::uint8_t>(row[i] - predict(0, above[i], 0));
  for (std::size_t i = head; i < row_bytes; ++i) {
    out[1 + i] = static_cast<std::uint8_t>(row[i] - predict(row[i - bpp], above[i], above[i - bpp]));
  }
}

// Bytes that are written before they are read: not zero-filled first.
struct Bytes {
  std::unique_ptr<std::uint8_t[]> data;
  std::size_t size = 0;
  explicit Bytes(std::size_t capacity) : data(std::make_unique_for_overwrite<std::uint8_t[]>(capacity)) {}
};

struct Group {
  std::size_t index = 0;
  Bytes deflated{0};
  uLong adler = 1;
  std::size_t raw_bytes = 0;
  uLong idat_crc = 0;  // CRC-32 of "IDAT" + deflated, but for the last group (its trailer comes later)
};

uLong idat_crc(const Bytes& data) {
  static constexpr std::uint8_t kType[4] = {'I', 'D', 'A', 'T'};
  return libdeflate_crc32(libdeflate_crc32(0, kType, 4), data.data.get(), data.size);
}

}  // namespace

namespace {

// The PNG file in order, piece by piece, to `put(data, size)`: signature and
// IHDR, then one IDAT per group as the groups come out of a pipeline that
// quantises, filters and deflates them in parallel (a bounded number in
// flight), then IEND. Writing a group overlaps the deflating of the next
// ones, and no copy of the whole file is made.
template <class Put>
void stream_png(const Image& image, int bits, bool dither, Mapping mapping, Put&& put) {
  NMBAKE_CHECK(bits == 8 || bits == 16, "PNG bit depth is 8 or 16");
  NMBAKE_CHECK(image.channels >= 1 && image.channels <= 4, "PNG has 1 to 4 channels");
  const std::size_t width = static_cast<std::size_t>(image.width);
  const std::size_t height = static_cast<std::size_t>(image.height);
  const std::size_t values_per_row = width * static_cast<std::size_t>(image.channels);
  const std::size_t bpp = static_cast<std::size_t>(image.channels) * (bits / 8);
  const std::size_t row_bytes = width * bpp;
  const std::size_t rows_per_group = std::max<std::size_t>(1, kPngGroupBytes / (row_bytes + 1));
  const std::size_t group_count = (height + rows_per_group - 1) / rows_per_group;

  std::vector<std::uint8_t> head = {0x89, 'P', 'N', 'G', '\r', '\n', 0x1a, '\n'};
  static constexpr std::uint8_t kColourType[5] = {0, 0, 4, 2, 6};  // grey, grey+alpha, RGB, RGBA
  std::vector<std::uint8_t> header;
  put_u32(header, static_cast<std::uint32_t>(width));
  put_u32(header, static_cast<std::uint32_t>(height));
  header.push_back(static_cast<std::uint8_t>(bits));
  header.push_back(kColourType[image.channels]);
  header.push_back(0);  // deflate
  header.push_back(0);  // adaptive filtering (one filter byte per row)
  header.push_back(0);  // not interlaced
  put_chunk(head, "IHDR", header.data(), header.size());
  put(head.data(), head.size());

  // One IDAT per group: the zlib header opens the first, the Adler-32 of
  // all filtered rows (combined in order, zlib's adler32_combine) closes the last.
  const auto deflate_group = [&](std::size_t g) {
    auto group = std::make_unique<Group>();
    const std::size_t y0 = g * rows_per_group;
    const std::size_t y1 = std::min(height, y0 + rows_per_group);
    // The row above the group is quantised again here, so groups share nothing.
    std::vector<std::uint8_t> above(row_bytes, 0), row(row_bytes);
    const std::size_t channels = static_cast<std::size_t>(image.channels);
    if (y0 > 0) {
      quantise_row(image.pixels.data() + (y0 - 1) * values_per_row, width, channels, bits, above.data(),
                   dither, y0 - 1, mapping);
    }
    Bytes filtered((y1 - y0) * (row_bytes + 1));
    filtered.size = (y1 - y0) * (row_bytes + 1);
    for (std::size_t y = y0; y < y1; ++y) {
      quantise_row(image.pixels.data() + y * values_per_row, width, channels, bits, row.data(), dither, y,
                   mapping);
      filter_row(row.data(), above.data(), row_bytes, bpp, filtered.data.get() + (y - y0) * (row_bytes + 1));
      std::swap(row, above);
    }
    group->raw_bytes = filtered.size;
    group->adler = libdeflate_adler32(1, filtered.data.get(), filtered.size);
    const bool last = g + 1 == group_count;
    // Room for the zlib header (first group), the stream, and the Adler-32 (last).
    group->deflated = Bytes(2 + deflate_huffman_bound(filtered.size) + 4);
    if (g == 0) {
      group->deflated.data[0] = 0x78;  // zlib header: deflate, 32K window, "fastest"
      group->deflated.data[1] = 0x01;
      group->deflated.size = 2;
    }
    group->deflated.size += deflate_huffman(filtered.data.get(), filtered.size, last,
                                            group->deflated.data.get() + group->deflated.size);
    if (!last) group->idat_crc = idat_crc(group->deflated);
    group->index = g;
    return group;
  };
  uLong adler = 1;
  const auto write_group = [&](std::unique_ptr<Group> group) {
    adler = group->index == 0 ? group->adler
                              : adler32_combine(adler, group->adler, static_cast<z_off_t>(group->raw_bytes));
    if (group->index + 1 == group_count) {
      std::uint8_t* at = group->deflated.data.get() + group->deflated.size;
      for (int k = 0; k < 4; ++k) at[k] = static_cast<std::uint8_t>(adler >> (24 - 8 * k));
      group->deflated.size += 4;
      group->idat_crc = idat_crc(group->deflated);
    }
    // The chunk by hand: its CRC was computed with the group, in parallel.
    std::vector<std::uint8_t> length_and_type;
    put_u32(length_and_type, static_cast<std::uint32_t>(group->deflated.size));
    length_and_type.insert(length_and_type.end(), {'I', 'D', 'A', 'T'});
    put(length_and_type.data(), length_and_type.size());
    put(group->deflated.data.get(), group->deflated.size);
    std::vector<std::uint8_t> crc;
    put_u32(crc, static_cast<std::uint32_t>(group->idat_crc));
    put(crc.data(), crc.size());
  };

  ordered_pieces<Group>(group_count, deflate_group, write_group);

  std::vector<std::uint8_t> tail;
  put_chunk(tail, "IEND", nullptr, 0);
  put(tail.data(), tail.size());
}

}  // namespace

std::vector<std::uint8_t> encode_png(const Image& image, int bits, bool dither, float scale, float offset) {
  std::vector<std::uint8_t> file;
  stream_png(image, bits, dither, Mapping{scale, offset},
             [&](const std::uint8_t* data, std::size_t size) { file.insert(file.end(), data, data + size); });
  return file;
}

Status write_png(const Image& image, int bits, const std::string& path, const std::string& display_path,
                 bool dither, float scale, float offset) {
  if (image.channels < 1 || image.channels > 4) {
    return Status::io("cannot write '" + display_path + "': PNG holds 1 to 4 channels, not " +
                      std::to_string(image.channels));
  }
  StreamFile file(path, display_path);
  if (!file.is_open()) return file.open_status();
  stream_png(image, bits, dither, Mapping{scale, offset},
             [&](const std::uint8_t* data, std::size_t size) { file.put(data, size); });
  return file.close();
}

}  // namespace nmbake::image_detail
