// Private: GCC's __builtin_shuffle for clang, which has only
// __builtin_shufflevector (constant indices). The library is built with GCC;
// clang builds it only for the libFuzzer harnesses (tests/fuzz, NMBAKE_FUZZ),
// so there the lane-by-lane form below stands in, with GCC's semantics (mask
// elements taken modulo the lane count, twice that with two operands).
#pragma once

#if defined(__clang__)
template <class V, class M>
inline V nmbake_shuffle(V a, V b, M mask) {
  constexpr int n = static_cast<int>(sizeof(V) / sizeof(a[0]));
  V out = a;
  for (int k = 0; k < n; ++k) {
    const int j = static_cast<int>(mask[k]) & (2 * n - 1);
    out[k] = j < n ? a[j] : b[j - n];
  }
  return out;
}
template <class V, class M>
inline V nmbake_shuffle(V a, M mask) {
  constexpr int n = static_cast<int>(sizeof(V) / sizeof(a[0]));
  V out = a;
  for (int k = 0; k < n; ++k) out[k] = a[static_cast<int>(mask[k]) & (n - 1)];
  return out;
}
#define __builtin_shuffle nmbake_shuffle
#endif
