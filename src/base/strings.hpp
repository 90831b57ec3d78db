// Private string helpers shared by the library's sources.
#pragma once

#include <string>

namespace nmbake::detail {

// Joins pieces; GCC 12 warns falsely (-Wrestrict) on "literal" + std::string.
template <typename... Pieces>
std::string concat(const Pieces&... pieces) {
  std::string out;
  (out.append(pieces), ...);
  return out;
}

}  // namespace nmbake::detail
