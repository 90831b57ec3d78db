// The option table (options.hpp): every option reads the same values, and
// gives the same options, as a command-line flag and as a job-file key.
#include "nmbake/options.hpp"

#include <gtest/gtest.h>

#include <algorithm>
#include <cctype>
#include <map>
#include <set>
#include <string>
#include <vector>

#include "nmbake/preset.hpp"
#include "test_util.hpp"

namespace nmbake {
namespace {

using test::run_command;
using test::TempDir;
using test::write_text;

std::vector<std::string> split_words(const std::string& list) {
  std::vector<std::string> words;
  std::size_t begin = 0;
  while (begin < list.size()) {
    std::size_t end = list.find(", ", begin);
    if (end == std::string::npos) end = list.size();
    words.push_back(list.substr(begin, end - begin));
    begin = end + 2;
  }
  return words;
}

// A value as a TOML value: a whole number or a plain decimal as a number,
// anything else as a string.
std::string toml_value(const std::string& value) {
  bool numeric = !value.empty();
  for (const char c : value) numeric &= std::isdigit(static_cast<unsigned char>(c)) || c == '.';
  return numeric ? value : "\"" + value + "\"";
}

std::string squote(const std::string& s) { return "'" + s + "'"; }

// Values of the options that take no words (a word option is tried with
// every word of its table). A row missing here fails the test.
const std::map<std::string, std::vector<std::string>> kSamples = {
    {"cage", {"CAGE"}},
    {"size", {"512", "256x128"}},
    {"width", {"300"}},
    {"height", {"200"}},
    {"samples", {"16", "adaptive"}},
    {"adaptive_max", {"64"}},
    {"adaptive_normal", {"0.01"}},
    {"adaptive_depth", {"0.5"}},
    {"adaptive_spread", {"0.04"}},
    {"adaptive_border", {"0.03"}},
    {"front", {"0.5", "2%", "auto"}},
    {"back", {"0.25", "3%", "auto"}},
    {"edge_band", {"3.5"}},
    {"ignore_backfaces", {"true"}},
    {"padding", {"8"}},
    {"uv_set", {"2"}},
    {"max_memory", {"8G"}},
    {"low_suffix", {"_lp"}},
    {"high_suffix", {"_hp"}},
    {"cage_suffix", {"_cg"}},
    {"groups_per_scene", {"4"}},
    {"debug_dump", {"DUMP"}},
    {"maps", {"normal,ao"}},
    {"height_range", {"0.1", "auto"}},
    {"curvature_range", {"2.5"}},
    {"ao_rays", {"32"}},
    {"ao_distance", {"0.3", "5%"}},
    {"thickness_rays", {"8"}},
    {"thickness_distance", {"0.2"}},
    {"pack", {"PACK"}},
    {"id_palette", {"PALETTE"}},
};

TEST(OptionTable, EveryWordAndValueGivesTheSameOptionsAsAFlagAndAsAJobKey) {
  TempDir dir;
  const std::string low = dir.file("low.obj"), high = dir.file("high.ply"), out = dir.file("out.png");
  const std::string job = dir.file("job.toml");
  const std::string base = test::cli_path() + " bake --print-options --low " + squote(low) + " --high " +
                           squote(high) + " -o " + squote(out);
  int tried = 0;
  for (const OptionSpec& spec : bake_option_table()) {
    const std::string key(spec.key);
    if (key == "low" || key == "high") continue;  // every bake names them: tried by every case
    std::vector<std::string> values = split_words(spec.words());
    if (const auto it = kSamples.find(key); it != kSamples.end()) {
      values.insert(values.end(), it->second.begin(), it->second.end());
    }
    ASSERT_FALSE(values.empty()) << key << ": neither words nor a sample value in this test";
    for (std::string value : values) {
      if (value == "CAGE" || value == "DUMP") value = dir.file(value == "CAGE" ? "cage.obj" : "dump");
      if (value == "PALETTE") value = dir.file("palette.toml");
      if (value == "PACK") value = dir.file("orm.png") + "=r:ao,g:0.5,b:1-base-color.g,a:1";
      const std::string flag = spec.is_switch ? flag_of(spec) : flag_of(spec) + " " + squote(value);
      const test::CommandResult by_flag = run_command(base + " " + flag);
      std::string toml = "[[bake]]\nname = 'b'\nlow = " + toml_value(low) + "\nhigh = " + toml_value(high) +
                         "\noutputs = [" + toml_value(out) + "]\n" + key + " = ";
      if (key == "maps") {
        // A job file's list: ["normal", "ao"] for "normal,ao".
        std::string list;
        for (std::size_t begin = 0; begin <= value.size();) {
          const std::size_t end = std::min(value.find(',', begin), value.size());
          list += (list.empty() ? "\"" : ", \"") + value.substr(begin, end - begin) + "\"";
          begin = end + 1;
        }
        toml += "[" + list + "]\n";
      } else if (spec.is_switch) {
        toml += value + "\n";
      } else {
        toml += toml_value(value) + "\n";
      }
      write_text(job, toml);
      const test::CommandResult by_key =
          run_command(test::cli_path() + " bake --print-options " + squote(job));
      ASSERT_EQ(by_flag.exit_code, 0) << flag << "\n" << by_flag.output;
      ASSERT_EQ(by_key.exit_code, 0) << toml << "\n" << by_key.output;
      EXPECT_EQ(by_flag.output, by_key.output) << flag << "\n" << toml;
      // And the value was taken: the options differ from the defaults'
      // unless the value is the default.
      const bool is_default = spec.show(BakeOptions{}) == value || (spec.is_switch && value == "false");
      if (!is_default && key != "size" && key != "tbn") {
        EXPECT_EQ(by_flag.output.find("\"" + key + "\":\"" + spec.show(BakeOptions{}) + "\""),
                  std::string::npos)
            << flag << ": the option kept its default\n"
            << by_flag.output;
      }
      ++tried;
    }
  }
  EXPECT_GT(tried, 80);
}

TEST(OptionTable, AnUnknownWordIsRefusedTheSameWayByBoth) {
  TempDir dir;
  const std::string job = dir.file("job.toml");
  for (const OptionSpec& spec : bake_option_table()) {
    const std::string words = spec.words();
    if (words.empty()) continue;
    const test::CommandResult by_flag =
        run_command(test::cli_path() + " bake --print-options --low l.obj --high h.ply -o o.png " +
                    flag_of(spec) + " nonsense");
    EXPECT_EQ(by_flag.exit_code, 2) << flag_of(spec);
    // (a list of maps names the word it does not know)
    const std::string unknown = spec.key == "maps" ? "unknown map 'nonsense': " : "";
    EXPECT_NE(by_flag.output.find(flag_of(spec) + " nonsense: " + unknown + "expected one of: " + words),
              std::string::npos)
        << by_flag.output;
    write_text(job, "[[bake]]\nlow = 'l.obj'\nhigh = 'h.ply'\noutputs = ['o.png']\n" + std::string(spec.key) +
                        " = 'nonsense'\n");
    const test::CommandResult by_key = run_command(test::cli_path() + " bake --print-options " + squote(job));
    EXPECT_EQ(by_key.exit_code, 2) << spec.key;
    EXPECT_NE(by_key.output.find(job + ":5: " + std::string(spec.key) + ": " + unknown +
                                 "expected one of: " + words),
              std::string::npos)
        << by_key.output;
  }
}

// Every value of every word table has a word to be written with, and no
// word stands for two values.
template <class E>
void expect_table_complete(std::initializer_list<E> values) {
  std::set<std::string_view> seen;
  for (const Word<E>& w : WordTable<E>::words) {
    if (w.use != WordUse::alias) {
      EXPECT_TRUE(seen.insert(w.word).second) << w.word;
    }
  }
  for (const E value : values) EXPECT_STRNE(to_string(value), "?");
}

TEST(OptionTable, EveryWordTableNamesEveryValueOnce) {
  expect_table_complete({CageMode::banded, CageMode::averaged, CageMode::interpolated, CageMode::mesh});
  expect_table_complete({HitRule::first, HitRule::nearest});
  expect_table_complete({BuildQuality::low, BuildQuality::medium, BuildQuality::high});
  expect_table_complete({BvhMemory::automatic, BvhMemory::fast, BvhMemory::compact});
  expect_table_complete({RetryMisses::automatic, RetryMisses::on, RetryMisses::off});
  expect_table_complete({NormalSpace::tangent, NormalSpace::object});
  expect_table_complete({GreenChannel::up, GreenChannel::down});
  expect_table_complete({HighNormals::smooth, HighNormals::face});
  expect_table_complete({TangentEncode::inverse, TangentEncode::transpose});
  expect_table_complete({Bitangent::pixel, Bitangent::vertex});
  expect_table_complete(
      {TangentBasis::mikktspace, TangentBasis::lengyel, TangentBasis::face, TangentBasis::file});
  expect_table_complete({MatchMode::automatic, MatchMode::name, MatchMode::off});
  expect_table_complete({Unmatched::error, Unmatched::all});
  expect_table_complete({IdSource::automatic, IdSource::part, IdSource::material});
  expect_table_complete({PixelFormat::png8, PixelFormat::png16, PixelFormat::tiff16, PixelFormat::exr_half,
                         PixelFormat::exr_float, PixelFormat::exr_float_piz, PixelFormat::tga8});
  expect_table_complete({MapKind::normal, MapKind::height, MapKind::ao, MapKind::bent_normal,
                         MapKind::curvature, MapKind::thickness, MapKind::position, MapKind::object_normal,
                         MapKind::vertex_color, MapKind::id, MapKind::miss, MapKind::base_color,
                         MapKind::roughness, MapKind::metallic, MapKind::emissive, MapKind::opacity});
  // The aliases still read: green's OpenGL and DirectX names.
  GreenChannel green = GreenChannel::up;
  EXPECT_TRUE(parse_word("directx", green));
  EXPECT_EQ(green, GreenChannel::down);
  // A reported-only value is never read: a cage mode of "mesh" means a cage file.
  CageMode mode = CageMode::banded;
  EXPECT_FALSE(parse_word("mesh", mode));
}

TEST(OptionTable, OptionsNotInADefaultsTableAreRefusedThere) {
  TempDir dir;
  const std::string job = dir.file("job.toml");
  write_text(job,
             "[defaults]\nlow = 'l.obj'\n[[bake]]\nlow = 'l.obj'\nhigh = 'h.ply'\noutputs = ['o.png']\n");
  const test::CommandResult r = run_command(test::cli_path() + " bake --print-options " + squote(job));
  EXPECT_EQ(r.exit_code, 2);
  EXPECT_NE(r.output.find(job + ":2: unknown key \"low\" in [defaults]"), std::string::npos) << r.output;
}

}  // namespace
}  // namespace nmbake
