// The text parsers' numbers (src/load/parsers.hpp): every real is the
// correctly rounded value, bit for bit what strtof/strtod give, on the cases
// where a fast reader goes wrong (ties, mantissas longer than 19 digits,
// subnormals, the edges of the range), plus seeded random ones; and the
// forms and errors the OBJ and PLY readers rely on.
#include <gtest/gtest.h>

#include <algorithm>
#include <cerrno>
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <random>
#include <string>
#include <vector>

#include "load/parsers.hpp"

namespace nmbake::load_detail {
namespace {

std::uint32_t bits_of(float f) {
  std::uint32_t b = 0;
  std::memcpy(&b, &f, sizeof b);
  return b;
}
std::uint64_t bits_of(double d) {
  std::uint64_t b = 0;
  std::memcpy(&b, &d, sizeof b);
  return b;
}

// Expects parse_float and parse_double to accept `text` and give strtof's
// and strtod's value (sign of a zero included). Returns false on a mismatch,
// so a loop can stop after a few.
bool matches_strto(const std::string& text) {
  const char* first = text.c_str();
  const char* last = first + text.size();
  const float want_float = std::strtof(first, nullptr);
  const double want_double = std::strtod(first, nullptr);
  float got_float = -1.0f;
  double got_double = -1.0;
  bool ok = true;
  if (std::isfinite(want_float)) {
    const NumberError e = parse_float(first, last, got_float);
    EXPECT_EQ(e, NumberError::none) << "float '" << text << "'";
    EXPECT_EQ(bits_of(got_float), bits_of(want_float))
        << "float '" << text << "': " << got_float << " instead of strtof's " << want_float;
    ok = e == NumberError::none && bits_of(got_float) == bits_of(want_float);
  }
  if (std::isfinite(want_double)) {
    const NumberError e = parse_double(first, last, got_double);
    EXPECT_EQ(e, NumberError::none) << "double '" << text << "'";
    EXPECT_EQ(bits_of(got_double), bits_of(want_double))
        << "double '" << text << "': " << got_double << " instead of strtod's " << want_double;
    ok = ok && e == NumberError::none && bits_of(got_double) == bits_of(want_double);
  }
  return ok;
}

TEST(ParseReal, HardRoundingCasesMatchStrtod) {
  const std::vector<std::string> cases = {
      // Exactly halfway between two floats (1 + 2^-24, 1 + 3 * 2^-24): ties to even.
      "1.000000059604644775390625", "1.000000178813934326171875",
      // ... and a hair either side of that tie, past 19 digits.
      "1.00000005960464477539062500000000000000000001", "1.00000005960464477539062499999999999999999999",
      // Doubles: 2^53 + 1 (a tie) and just above it; 0.1's exact binary value.
      "9007199254740993", "9007199254740993.0000000000000000001",
      "0.1000000000000000055511151231257827021181583404541015625",
      // A mantissa of 60 digits, and one of 800.
      "3.14159265358979323846264338327950288419716939937510582097494", std::string(800, '7') + "e-790",
      // Subnormal floats and doubles, the smallest ones, and the halfway points
      // below them (just above rounds up, just below to zero).
      "1.4e-45", "1.401298464324817e-45", "7.006492321624085e-46", "7.006492321624087e-46", "1e-45",
      "1.1754942e-38", "1.17549435e-38", "2.2250738585072011e-308", "4.9406564584124654e-324",
      "2.4703282292062328e-324", "2.4703282292062327e-324",
      // Exponents; the largest float and the last value that still rounds to it.
      "1e10", "1E+10", "1e-10", "123.456e-2", "0.000123e5", "3.4028234e38", "3.4028235677973366e38",
      // A leading '+', leading zeros, no digit before or after the point.
      "+1.5", "+0.1", "+1e-50", "000001.5", "-0000.000001", "00000000000000000000000000000001e-5", ".5", "5.",
      "-.5e-3", "0", "-0", "0e0",
      // Underflow: a signed zero, as strtod gives it (with ERANGE), not an error,
      // with or without an exponent.
      "1e-50", "-1e-50", "1e-400", "-1e-400", "0." + std::string(60, '0') + "1"};
  for (const std::string& text : cases) matches_strto(text);
}

TEST(ParseReal, SeededRandomTiesAndDecimalsMatchStrtod) {
  std::mt19937_64 rng(20261203);
  int failures = 0;
  char buffer[1024];
  // The exact decimal of the midpoint between two neighbouring floats (a
  // double, so exact), and the shortest round-trip forms.
  for (int i = 0; i < 20000 && failures < 5; ++i) {
    const auto bits = static_cast<std::uint32_t>(rng() % 0x7f7fffffu);
    float below = 0.0f, above = 0.0f;
    const std::uint32_t next = bits + 1;
    std::memcpy(&below, &bits, sizeof below);
    std::memcpy(&above, &next, sizeof above);
    const double midpoint = (static_cast<double>(below) + static_cast<double>(above)) / 2;
    std::snprintf(buffer, sizeof buffer, "%.800g", midpoint);
    failures += matches_strto(buffer) ? 0 : 1;
    std::snprintf(buffer, sizeof buffer, "%.9g", static_cast<double>(below));
    failures += matches_strto(buffer) ? 0 : 1;
    // The midpoint to 15-17 digits: often a decimal whose nearest double is
    // the midpoint itself, where rounding through a double goes wrong.
    for (const int digits : {15, 16, 17}) {
      std::snprintf(buffer, sizeof buffer, "%.*f",
                    std::max(0, digits - 1 - static_cast<int>(std::floor(std::log10(midpoint)))), midpoint);
      failures += matches_strto(buffer) ? 0 : 1;
    }
  }
  // Random digit strings of 1 to 30 digits, a point anywhere, exponents
  // from -70 to 39.
  for (int i = 0; i < 20000 && failures < 5; ++i) {
    std::string text = rng() % 2 != 0 ? "-" : "";
    const int digits = 1 + static_cast<int>(rng() % 30);
    const int point = static_cast<int>(rng() % static_cast<std::uint64_t>(digits + 1));
    for (int d = 0; d < digits; ++d) {
      if (d == point) text += '.';
      text += static_cast<char>('0' + rng() % 10);
    }
    if (rng() % 2 != 0) text += "e" + std::to_string(static_cast<int>(rng() % 110) - 70);
    failures += matches_strto(text) ? 0 : 1;
  }
  EXPECT_EQ(failures, 0);
}

TEST(ParseReal, ErrorsAndRefusedForms) {
  const auto parse = [](const std::string& text) {
    float value = 0.0f;
    return parse_float(text.data(), text.data() + text.size(), value);
  };
  EXPECT_EQ(parse("1e39"), NumberError::overflow);
  EXPECT_EQ(parse("-1e39"), NumberError::overflow);
  EXPECT_EQ(parse(".5e99"), NumberError::overflow);
  EXPECT_EQ(parse("inf"), NumberError::non_finite);
  EXPECT_EQ(parse("-Infinity"), NumberError::non_finite);
  EXPECT_EQ(parse("nan"), NumberError::non_finite);
  EXPECT_EQ(parse("+nan"), NumberError::non_finite);
  for (const char* bad :
       {"", "+", "-", "++1", "+-1", "1e", "1e+", "0x1p3", "1,5", "1.5x", " 1", "1 ", "e5", "."}) {
    EXPECT_EQ(parse(bad), NumberError::syntax) << "'" << bad << "'";
  }
  double wide = 0.0;
  const std::string big = "1e309";
  EXPECT_EQ(parse_double(big.data(), big.data() + big.size(), wide), NumberError::overflow);
}

}  // namespace
}  // namespace nmbake::load_detail
