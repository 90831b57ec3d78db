// Private to the library: big buffers sized so their first touch is cheap.
//
// A page fault costs about 9 us on these virtual machines (DESIGN.md), so
// first-touching a 64 MB array in 4 KB pages costs ~0.15 s. Transparent huge
// pages (2 MB) are enabled per mapping ("madvise" mode on Debian), so a new
// allocation is reserved untouched, advised, and only then sized. The advice
// is a hint: the contents are the same without it.
#pragma once

#include <sys/mman.h>
#include <tbb/parallel_for.h>

#include <algorithm>
#include <cstddef>
#include <cstdint>
#include <type_traits>
#include <vector>

namespace nmbake::detail {

inline void advise_huge_pages(const void* data, std::size_t bytes) {
#if defined(__linux__) && defined(MADV_HUGEPAGE)
  constexpr std::uintptr_t huge_page = std::uintptr_t{2} << 20;
  const std::uintptr_t begin = reinterpret_cast<std::uintptr_t>(data);
  const std::uintptr_t end = begin + bytes;
  const std::uintptr_t aligned_begin = (begin + huge_page - 1) & ~(huge_page - 1);
  if (end > aligned_begin + huge_page) {
    (void)madvise(reinterpret_cast<void*>(aligned_begin), (end - aligned_begin) & ~(huge_page - 1),
                  MADV_HUGEPAGE);
  }
#else
  (void)data;
  (void)bytes;
#endif
}

// Faults in the pages of [data, data + bytes) from every core: a byte
// written per 4 KB page. On these machines the first touch of memory the
// host has not backed yet sometimes costs ~4 ms per 2 MB page (0.14 s for
// 64 MB instead of 0.012 s, BENCHMARKS.md); spread over the cores it costs
// a core's share.
inline void touch_pages(void* data, std::size_t bytes) {
  constexpr std::size_t page = 4096, chunk = std::size_t{2} << 20;
  unsigned char* p = static_cast<unsigned char*>(data);
  tbb::parallel_for(std::size_t{0}, (bytes + chunk - 1) / chunk, [&](std::size_t c) {
    const std::size_t end = std::min(bytes, (c + 1) * chunk);
    for (std::size_t i = c * chunk; i < end; i += page) p[i] = 0;
  });
}

// Reserves room for n elements in an empty `v` and advises it for huge
// pages before anything touches it (the loaders' arrays, size_output()).
template <typename T>
void reserve_huge_pages(std::vector<T>& v, std::size_t n) {
  v.reserve(n);
  advise_huge_pages(v.data(), v.capacity() * sizeof(T));
}

// Sizes `v` to n elements. When the capacity is too small the old contents
// are dropped (an output buffer) and the new allocation is reserved, advised,
// faulted in on every core, and only then sized (zero-filled).
template <typename T>
void size_output(std::vector<T>& v, std::size_t n) {
  static_assert(std::is_trivially_copyable_v<T>, "raw storage is written before the elements exist");
  if (v.capacity() < n) {
    std::vector<T>().swap(v);
    reserve_huge_pages(v, n);
    touch_pages(v.data(), n * sizeof(T));
  }
  v.resize(n);
}

}  // namespace nmbake::detail
