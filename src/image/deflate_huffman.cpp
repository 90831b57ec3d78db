// Huffman-only deflate (RFC 1951, section 3.2.7: dynamic Huffman blocks).
// Each block: the byte counts, a canonical code of at most 15 bits per
// symbol (literals 0-255 and end-of-block 256; one unused distance code),
// the code lengths run-length coded with symbols 16/17/18 and themselves
// Huffman coded (at most 7 bits), then the bytes.
#include "image/deflate_huffman.hpp"

#include <algorithm>
#include <array>
#include <cstring>
#include <numeric>

#include "nmbake/common.hpp"

namespace nmbake::image_detail {

namespace {

constexpr int kEndOfBlock = 256;
constexpr int kLiteralCodes = 257;  // HLIT = 0: literals and end-of-block, no lengths
// The order in which the code-length code's lengths are stored (RFC 1951, 3.2.7).
constexpr std::array<int, 19> kLengthOrder = {16, 17, 18, 0, 8,  7, 9,  6, 10, 5,
                                              11, 4,  12, 3, 13, 2, 14, 1, 15};

// Bits written least significant first into bytes appended to a vector that
// the caller has sized with room to spare (8 bytes past the last one used).
class BitWriter {
 public:
  explicit BitWriter(std::uint8_t* at) : at_(at) {}
  void put(std::uint32_t bits, int count) {
    buffer_ |= static_cast<std::uint64_t>(bits) << filled_;
    filled_ += count;
    if (filled_ >= 32) {
      std::memcpy(at_, &buffer_, 8);  // little-endian: the low 4 bytes are the next 4 of the stream
      at_ += 4;
      buffer_ >>= 32;
      filled_ -= 32;
    }
  }
  // The codes of `size` bytes, table[b] = code | length << 16 (lengths at
  // most 15, the longest `longest`): the same bits as put() for each,
  // several codes per store of the 64-bit buffer (four when 7 + 4 x longest
  // fit in 64, else three), whole bytes moved out without a branch.
  void put_codes(const std::uint8_t* data, std::size_t size, const std::uint32_t* table, int longest) {
    while (filled_ >= 8) {  // fewer than 8 bits pending: 7 + 3 * 15 fit in 64
      *at_++ = static_cast<std::uint8_t>(buffer_);
      buffer_ >>= 8;
      filled_ -= 8;
    }
    std::size_t k = 0;
    if (longest <= 14) put_runs<4>(data, size, table, k);
    put_runs<3>(data, size, table, k);
    for (; k < size; ++k) put(table[data[k]] & 0xffffu, static_cast<int>(table[data[k]] >> 16));
  }
  // Pads with zero bits to a byte boundary and writes what is left.
  std::uint8_t* finish() {
    while (filled_ > 0) {
      *at_++ = static_cast<std::uint8_t>(buffer_);
      buffer_ >>= 8;
      filled_ = std::max(0, filled_ - 8);
    }
    return at_;
  }

 private:
  // put_codes() from byte k on, kCodes codes a store, while kCodes are left.
  template <int kCodes>
  void put_runs(const std::uint8_t* data, std::size_t size, const std::uint32_t* table, std::size_t& k) {
    std::uint64_t buffer = buffer_;
    int filled = filled_;
    std::uint8_t* at = at_;
    for (; k + kCodes <= size; k += kCodes) {
      std::uint32_t t[kCodes];
      for (int c = 0; c < kCodes; ++c) t[c] = table[data[k + c]];
      for (int c = 0; c < kCodes; ++c) {
        buffer |= static_cast<std::uint64_t>(t[c] & 0xffffu) << filled;
        filled += static_cast<int>(t[c] >> 16);
      }
      std::memcpy(at, &buffer, 8);  // little-endian: the stream's next bytes
      at += filled >> 3;
      buffer >>= filled & ~7;
      filled &= 7;
    }
    buffer_ = buffer;
    filled_ = filled;
    at_ = at;
  }

  std::uint8_t* at_;
  std::uint64_t buffer_ = 0;
  int filled_ = 0;
};

// Canonical codes for `lengths` (RFC 1951, 3.2.2), bit-reversed so that
// BitWriter, which writes least significant bit first, sends each code's
// most significant bit first as deflate requires.
std::vector<std::uint32_t> canonical_codes(const std::vector<std::uint8_t>& lengths) {
  std::array<std::uint32_t, 16> count{}, next{};
  for (std::uint8_t l : lengths) ++count[l];
  count[0] = 0;
  std::uint32_t code = 0;
  for (int bits = 1; bits < 16; ++bits) {
    code = (code + count[bits - 1]) << 1;
    next[bits] = code;
  }
  std::vector<std::uint32_t> codes(lengths.size(), 0);
  for (std::size_t s = 0; s < lengths.size(); ++s) {
    const int l = lengths[s];
    if (l == 0) continue;
    std::uint32_t c = next[l]++, reversed = 0;
    for (int b = 0; b < l; ++b, c >>= 1) reversed = (reversed << 1) | (c & 1u);
    codes[s] = reversed;
  }
  return codes;
}

// Code lengths as run-length symbols: 0-15 a length, 16 the previous length
// 3-6 more times (2 extra bits), 17 3-10 zeros (3 extra bits), 18 11-138
// zeros (7 extra bits). Pairs (symbol, extra value).
std::vector<std::pair<std::uint8_t, std::uint8_t>> run_length(const std::vector<std::uint8_t>& lengths) {
  std::vector<std::pair<std::uint8_t, std::uint8_t>> out;
  for (std::size_t i = 0; i < lengths.size();) {
    const std::uint8_t l = lengths[i];
    std::size_t run = 1;
    while (i + run < lengths.size() && lengths[i + run] == l) ++run;
    i += run;
    if (l == 0) {
      while (run >= 11) {
        const std::size_t n = std::min<std::size_t>(run, 138);
        out.emplace_back(18, static_cast<std::uint8_t>(n - 11));
        run -= n;
      }
      if (run >= 3) {
        out.emplace_back(17, static_cast<std::uint8_t>(run - 3));
        run = 0;
      }
      for (; run > 0; --run) out.emplace_back(0, 0);
      continue;
    }
    out.emplace_back(l, 0);
    --run;
    while (run >= 3) {
      const std::size_t n = std::min<std::size_t>(run, 6);
      out.emplace_back(16, static_cast<std::uint8_t>(n - 3));
      run -= n;
    }
    for (; run > 0; --run) out.emplace_back(l, 0);
  }
  return out;
}

// One dynamic block of `data`.
void write_block(const std::uint8_t* data, std::size_t size, bool final, BitWriter& bits) {
  // Eight histograms, so runs of one byte value do not serialise the counts
  // (16-bit rows repeat their high bytes every second byte: with four,
  // BM_Write/png16 took ~5% longer).
  constexpr int kTables = 8;
  std::array<std::array<std::uint32_t, 256>, kTables> counts{};
  std::size_t i = 0;
  for (; i + kTables <= size; i += kTables) {
    for (int k = 0; k < kTables; ++k) ++counts[k][data[i + k]];
  }
  for (; i < size; ++i) ++counts[0][data[i]];
  std::vector<std::uint32_t> freq(kLiteralCodes, 0);
  for (int b = 0; b < 256; ++b) {
    for (int k = 0; k < kTables; ++k) freq[b] += counts[k][b];
  }
  freq[kEndOfBlock] = 1;
  const std::vector<std::uint8_t> lengths = huffman_lengths(freq, 15);
  const std::vector<std::uint32_t> codes = canonical_codes(lengths);

  // Literal lengths, then the one distance code (1 bit: never used, but a
  // lone distance code is sent with one bit, RFC 1951 3.2.7).
  std::vector<std::uint8_t> all_lengths(lengths);
  all_lengths.push_back(1);
  const auto runs = run_length(all_lengths);
  std::vector<std::uint32_t> length_freq(19, 0);
  for (const auto& [symbol, extra] : runs) ++length_freq[symbol];
  const std::vector<std::uint8_t> length_lengths = huffman_lengths(length_freq, 7);
  const std::vector<std::uint32_t> length_codes = canonical_codes(length_lengths);
  int stored = 19;
  while (stored > 4 && length_lengths[kLengthOrder[stored - 1]] == 0) --stored;

  bits.put(final ? 1u : 0u, 1);
  bits.put(2, 2);  // dynamic Huffman codes
  bits.put(kLiteralCodes - 257, 5);
  bits.put(0, 5);  // one distance code
  bits.put(static_cast<std::uint32_t>(stored - 4), 4);
  for (int k = 0; k < stored; ++k) bits.put(length_lengths[kLengthOrder[k]], 3);
  for (const auto& [symbol, extra] : runs) {
    bits.put(length_codes[symbol], length_lengths[symbol]);
    if (symbol == 16) bits.put(extra, 2);
    if (symbol == 17) bits.put(extra, 3);
    if (symbol == 18) bits.put(extra, 7);
  }
  // The bytes: code and length fetched together from one table.
  std::array<std::uint32_t, 256> table;
  for (int b = 0; b < 256; ++b) table[b] = codes[b] | (static_cast<std::uint32_t>(lengths[b]) << 16);
  bits.put_codes(data, size, table.data(), *std::max_element(lengths.begin(), lengths.begin() + 256));
  bits.put(codes[kEndOfBlock], lengths[kEndOfBlock]);
}

}  // namespace

std::vector<std::uint8_t> huffman_lengths(const std::vector<std::uint32_t>& freq, int max_bits) {
  const std::size_t symbols = freq.size();
  std::vector<std::uint8_t> lengths(symbols, 0);
  std::vector<std::uint32_t> used;
  for (std::size_t s = 0; s < symbols; ++s)
    if (freq[s] > 0) used.push_back(static_cast<std::uint32_t>(s));
  NMBAKE_CHECK(
      symbols >= 2 && symbols <= 65536 && max_bits >= 1 && (std::size_t{1} << max_bits) >= used.size(),
      "a prefix code of this many symbols fits the length limit");
  if (used.size() < 2) {
    // One symbol (or none): a complete code needs two, so the first other
    // symbol gets the second one-bit code.
    const std::uint32_t a = used.empty() ? 0u : used[0];
    lengths[a] = 1;
    lengths[a == 0 ? 1 : 0] = 1;
    return lengths;
  }
  std::vector<std::uint64_t> weight(used.size());
  for (std::size_t i = 0; i < used.size(); ++i) weight[i] = freq[used[i]];
  for (;;) {
    // Two-queue Huffman: leaves sorted by (weight, symbol), internal nodes
    // created in non-decreasing weight; a leaf wins ties. Deterministic.
    const std::size_t n = used.size();
    // Sorted by (weight, position) as one key: a stable sort by weight
    // (weights stay below 2^40: counts of a block, halved).
    std::vector<std::uint64_t> keys(n);
    for (std::size_t i = 0; i < n; ++i) keys[i] = weight[i] << 16 | i;
    std::sort(keys.begin(), keys.end());
    std::vector<std::uint32_t> order(n);
    for (std::size_t i = 0; i < n; ++i) order[i] = static_cast<std::uint32_t>(keys[i] & 0xffffu);
    std::vector<std::uint64_t> node_weight(2 * n - 1);
    std::vector<std::uint32_t> parent(2 * n - 1, 0);
    for (std::size_t i = 0; i < n; ++i) node_weight[i] = weight[order[i]];
    std::size_t leaf = 0, inner = n;
    auto take = [&](std::size_t next) {
      if (leaf < n && (inner >= next || node_weight[leaf] <= node_weight[inner])) return leaf++;
      return inner++;
    };
    for (std::size_t next = n; next < 2 * n - 1; ++next) {
      const std::size_t a = take(next), b = take(next);
      node_weight[next] = node_weight[a] + node_weight[b];
      parent[a] = parent[b] = static_cast<std::uint32_t>(next);
    }
    std::vector<std::uint8_t> depth(2 * n - 1, 0);
    int deepest = 0;
    for (std::size_t k = 2 * n - 1; k-- > 0;) {
      if (k + 1 < 2 * n - 1) depth[k] = static_cast<std::uint8_t>(depth[parent[k]] + 1);
      if (k < n) deepest = std::max<int>(deepest, depth[k]);
    }
    if (deepest <= max_bits) {
      for (std::size_t i = 0; i < n; ++i) lengths[used[order[i]]] = depth[i];
      return lengths;
    }
    // Too deep: flatten the distribution and build again.
    for (std::uint64_t& w : weight) w = (w + 1) / 2;
  }
}

std::size_t deflate_huffman_bound(std::size_t size) {
  // At most 15 bits a byte, plus each block's header (< 400 bytes) and the
  // closing stored block; 8 bytes of slack for BitWriter.
  const std::size_t blocks = std::max<std::size_t>(1, (size + kHuffmanBlockBytes - 1) / kHuffmanBlockBytes);
  return size * 15 / 8 + blocks * 400 + 64;
}

std::size_t deflate_huffman(const std::uint8_t* data, std::size_t size, bool final, std::uint8_t* out) {
  const std::size_t blocks = std::max<std::size_t>(1, (size + kHuffmanBlockBytes - 1) / kHuffmanBlockBytes);
  BitWriter bits(out);
  for (std::size_t b = 0; b < blocks; ++b) {
    const std::size_t begin = b * kHuffmanBlockBytes;
    const std::size_t count = std::min(kHuffmanBlockBytes, size - std::min(size, begin));
    write_block(data + begin, count, final && b + 1 == blocks, bits);
  }
  if (!final) {
    // An empty stored block: 3 header bits, padding to the byte, LEN 0, NLEN ~0.
    bits.put(0, 3);
    std::uint8_t* end = bits.finish();
    const std::uint8_t empty[4] = {0x00, 0x00, 0xff, 0xff};
    std::memcpy(end, empty, 4);
    return static_cast<std::size_t>(end + 4 - out);
  }
  return static_cast<std::size_t>(bits.finish() - out);
}

void deflate_huffman(const std::uint8_t* data, std::size_t size, bool final, std::vector<std::uint8_t>& out) {
  const std::size_t start = out.size();
  out.resize(start + deflate_huffman_bound(size));
  out.resize(start + deflate_huffman(data, size, final, out.data() + start));
}

}  // namespace nmbake::image_detail
