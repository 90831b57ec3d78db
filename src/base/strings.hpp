// Private string helpers shared by the library's sources.
#pragma once

#include <cstdio>
#include <string>

namespace nmbake::detail {

// Joins pieces; GCC 12 warns falsely (-Wrestrict) on "literal" + std::string.
template <typename... Pieces>
std::string concat(const Pieces&... pieces) {
  std::string out;
  (out.append(pieces), ...);
  return out;
}

// `text` as a double-quoted string that JSON and TOML (basic strings) both
// read back exactly: quotes and backslashes escaped, control bytes as \u00XX,
// every other byte as it is.
inline std::string quoted_string(const std::string& text) {
  std::string out = "\"";
  for (const char c : text) {
    const auto byte = static_cast<unsigned char>(c);
    if (c == '"' || c == '\\') {
      out += '\\';
      out += c;
    } else if (byte < 0x20 || byte == 0x7f) {
      char escaped[8];
      std::snprintf(escaped, sizeof escaped, "\\u%04x", byte);
      out += escaped;
    } else {
      out += c;
    }
  }
  return out + '"';
}

}  // namespace nmbake::detail
