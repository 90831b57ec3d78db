// The id map's palette file (maps.hpp, IdPalette): TOML, NAME = "#RRGGBB".
#include <toml++/toml.h>

#include <cctype>
#include <cstdint>
#include <filesystem>
#include <optional>
#include <string>

#include "nmbake/maps.hpp"

namespace nmbake {

const glm::vec3* IdPalette::find(const std::string& name) const {
  for (const auto& [n, color] : colors) {
    if (n == name) return &color;
  }
  return nullptr;
}

namespace {

int hex_digit(char c) {
  if (c >= '0' && c <= '9') return c - '0';
  const char lower = static_cast<char>(std::tolower(static_cast<unsigned char>(c)));
  if (lower >= 'a' && lower <= 'f') return lower - 'a' + 10;
  return -1;
}

// "#RRGGBB" as display values in [0, 1]; false for anything else.
bool parse_hex_color(const std::string& text, glm::vec3& out) {
  if (text.size() != 7 || text[0] != '#') return false;
  for (int c = 0; c < 3; ++c) {
    const int high = hex_digit(text[static_cast<std::size_t>(1 + 2 * c)]);
    const int low = hex_digit(text[static_cast<std::size_t>(2 + 2 * c)]);
    if (high < 0 || low < 0) return false;
    out[c] = static_cast<float>(high * 16 + low) / 255.0f;
  }
  return true;
}

// ":N" for a line number, "" for none (0). (Appended, not `":" + string`:
// GCC 12 warns falsely (-Wrestrict) on that.)
std::string line_suffix(std::uint32_t line) {
  std::string out;
  if (line > 0) out.append(":").append(std::to_string(line));
  return out;
}

}  // namespace

Status read_id_palette(const std::string& path, IdPalette& out) {
  out = IdPalette{};
  std::error_code error;
  if (!std::filesystem::is_regular_file(path, error)) {
    return Status::bad_input(
        printable_text(path) + ": the id palette " +
        (std::filesystem::exists(path, error) ? "is not a regular file" : "does not exist"));
  }
  toml::table table;
  try {
    table = toml::parse_file(path);
  } catch (const toml::parse_error& e) {
    const std::string message = printable_text(e.description());
    const auto line = e.source().begin.line;
    return Status::bad_input(printable_text(path) + line_suffix(line) + ": " + message +
                             " (an id palette is NAME = \"#RRGGBB\" lines)");
  }
  for (const auto& [key, value] : table) {
    const std::string name(key.str());
    const std::string line = line_suffix(key.source().begin.line);
    const std::optional<std::string> text = value.value<std::string>();
    glm::vec3 color(0.0f);
    if (!text || !parse_hex_color(*text, color)) {
      return Status::bad_input(printable_text(path) + line + ": '" + printable_text(name) +
                               "': expected a colour \"#RRGGBB\" (8-bit sRGB, as a colour picker shows it)");
    }
    out.colors.emplace_back(name, color);
  }
  return Status::ok();
}

}  // namespace nmbake
