// Packed outputs (bake_options.hpp PackSpec): the words of a spec. The
// packed files are written by write_pack_files() (outputs.cpp).
#include <charconv>
#include <cmath>
#include <string>
#include <vector>

#include "nmbake/bake_options.hpp"
#include "nmbake/maps.hpp"

namespace nmbake {
namespace {

std::string trim(std::string text) {
  text.erase(0, text.find_first_not_of(" \t"));
  text.erase(text.find_last_not_of(" \t") + 1);
  return text;
}

Status read_channel(const std::string& spec, const std::string& word, PackChannel& out) {
  const auto bad = [&](const std::string& why) {
    return Status::bad_input("pack '" + printable_text(spec) + "': channel '" + printable_text(word) +
                             "': " + why);
  };
  std::string source = word;
  // A number in [0, 1]: a constant.
  float value = 0.0f;
  const auto [end, ec] = std::from_chars(source.data(), source.data() + source.size(), value);
  if (ec == std::errc() && end == source.data() + source.size()) {
    if (!(value >= 0.0f && value <= 1.0f)) return bad("a constant must lie in [0, 1]");
    out.constant = true;
    out.value = value;
    return Status::ok();
  }
  if (source.rfind("1-", 0) == 0) {
    out.invert = true;
    source = trim(source.substr(2));
  }
  const std::size_t dot = source.rfind('.');
  std::string name = source;
  if (dot != std::string::npos && dot + 2 == source.size()) {
    const char c = source[dot + 1];
    if (c != 'r' && c != 'g' && c != 'b') return bad("a map's component is .r, .g or .b");
    out.component = c == 'r' ? 0 : c == 'g' ? 1 : 2;
    name = source.substr(0, dot);
  }
  if (!parse_word(name, out.map))
    return bad("unknown map '" + printable_text(name) + "': " + expected_words<MapKind>());
  if (dot == std::string::npos && map_traits(out.map).channels != 1) {
    return bad("'" + name + "' has three channels: name one (" + name + ".r, .g or .b)");
  }
  if (dot != std::string::npos && map_traits(out.map).channels == 1) {
    return bad("'" + name + "' has one channel: no component");
  }
  return Status::ok();
}

}  // namespace

Status parse_pack(const std::string& text, PackSpec& out) {
  out = PackSpec{};
  const std::size_t equals = text.rfind('=');
  if (equals == std::string::npos || equals == 0) {
    return Status::bad_input("pack '" + printable_text(text) +
                             "': expected FILE=r:MAP,g:MAP,... (e.g. orm.png=r:ao,g:roughness,b:metallic)");
  }
  out.path = trim(text.substr(0, equals));
  if (has_map_token(out.path)) {
    return Status::bad_input("pack '" + printable_text(text) +
                             "': a packed file holds several maps: no <MAP>");
  }
  const std::string list = text.substr(equals + 1);
  const char* names = "rgba";
  std::size_t begin = 0;
  while (begin <= list.size()) {
    std::size_t end = list.find(',', begin);
    if (end == std::string::npos) end = list.size();
    const std::string item = trim(list.substr(begin, end - begin));
    begin = end + 1;
    if (item.empty()) continue;
    const std::size_t colon = item.find(':');
    const std::string channel = colon == std::string::npos ? "" : trim(item.substr(0, colon));
    const std::size_t index = out.channels.size();
    if (index >= 4 || channel.size() != 1 || channel[0] != names[index]) {
      return Status::bad_input(
          "pack '" + printable_text(text) + "': channels are r, g, b, a in that order (" +
          std::string(1, index < 4 ? names[index] : 'a') + " next), written as c:SOURCE");
    }
    PackChannel c;
    NMBAKE_TRY(read_channel(text, trim(item.substr(colon + 1)), c));
    out.channels.push_back(c);
  }
  if (out.channels.size() != 1 && out.channels.size() != 3 && out.channels.size() != 4) {
    return Status::bad_input("pack '" + printable_text(text) +
                             "': 1 (r), 3 (r, g, b) or 4 (r, g, b, a) channels, not " +
                             std::to_string(out.channels.size()));
  }
  return Status::ok();
}

std::string pack_text(const PackSpec& pack) {
  std::string text = pack.path + "=";
  const char* names = "rgba";
  for (std::size_t i = 0; i < pack.channels.size(); ++i) {
    const PackChannel& c = pack.channels[i];
    // (Appended piece by piece: GCC 12 warns falsely (-Wrestrict) on "literal" + std::string.)
    if (i > 0) text += ',';
    text += names[i];
    text += ':';
    if (c.constant) {
      char number[32];
      const auto [end, ec] = std::to_chars(number, number + sizeof number, c.value);
      text += std::string(number, ec == std::errc() ? end : number);
      continue;
    }
    if (c.invert) text += "1-";
    text += to_string(c.map);
    if (map_traits(c.map).channels != 1) text += std::string(".") + "rgb"[c.component];
  }
  return text;
}

}  // namespace nmbake
