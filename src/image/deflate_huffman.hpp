// Private to the write stage: a deflate (RFC 1951) encoder that codes bytes
// with dynamic Huffman blocks only, no string matching. Filtered rows of a
// normal map are small residuals with few repeats, where LZ77 finds little
// (see image_png.cpp); zlib at Z_HUFFMAN_ONLY still runs its general block
// machinery per byte and was three quarters of the PNG write. This one counts
// a block's bytes, builds a length-limited canonical code and writes it with
// a 64-bit bit buffer.
#pragma once

#include <cstddef>
#include <cstdint>
#include <vector>

namespace nmbake::image_detail {

// Bytes per dynamic block: big enough that the ~70-byte code header is
// noise, small enough to follow changes of statistics across a map.
constexpr std::size_t kHuffmanBlockBytes = std::size_t{1} << 16;

// Appends `size` bytes of `data` to `out` as raw deflate blocks. `final`:
// the last block is marked final and the stream ends (padded to a byte).
// Otherwise the blocks are followed by an empty stored block, which ends the
// piece on a byte boundary, so pieces can be concatenated into one stream
// (what zlib's Z_SYNC_FLUSH does). The output depends only on the input.
void deflate_huffman(const std::uint8_t* data, std::size_t size, bool final, std::vector<std::uint8_t>& out);

// The same stream written at `out`, which has room for
// deflate_huffman_bound(size) bytes (none of them need be initialised);
// returns how many were written.
std::size_t deflate_huffman_bound(std::size_t size);
std::size_t deflate_huffman(const std::uint8_t* data, std::size_t size, bool final, std::uint8_t* out);

// Code lengths (at most `max_bits`) of a prefix code for `freq`; 0 for
// symbols of frequency 0. At least two symbols of non-zero frequency.
// Exposed for tests.
std::vector<std::uint8_t> huffman_lengths(const std::vector<std::uint32_t>& freq, int max_bits);

}  // namespace nmbake::image_detail
