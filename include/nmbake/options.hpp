// The option table: every option of a bake once — its name, the words or
// values it takes, its one-line help and its parser — read by everything
// that hands options to a bake: the command line (flags, --help), job files
// (keys of [defaults] and [[bake]]) and live requests. An option has one
// name (the job key; the flag is the key with '-' for '_'), one default
// (BakeOptions' own initialiser, shown by --help), one parser (here) and one
// check (validate_options), whichever way it arrives.
//
// Not in the table: what only one surface has — outputs (-o and --format,
// a job's `outputs` list), a job's name, report, cache and groups, and the
// command's own switches (--only, --tile, --keep-going, ...).
#pragma once

#include <cstdint>
#include <span>
#include <string>
#include <string_view>
#include <vector>

#include "nmbake/bake_options.hpp"
#include "nmbake/common.hpp"

namespace nmbake {

// An option's value as it arrived: a command-line word (text), or a job
// file's value (TOML string, integer, float, boolean or array of strings).
struct OptionValue {
  enum class Kind : std::uint8_t { text, integer, number, boolean, list };
  Kind kind = Kind::text;
  std::string text;               // Kind::text
  std::vector<std::string> list;  // Kind::list
  std::int64_t integer = 0;       // Kind::integer
  double number = 0.0;            // Kind::number (and integer's value)
  bool boolean = false;           // Kind::boolean
  // A job file's folder: relative paths resolve against it ("" for the
  // command line: as given).
  std::string folder;

  static OptionValue of_text(std::string text);
};

struct OptionSpec {
  std::string_view key;    // the job key; the flag is "--" + key with '-' for '_'
  std::string_view value;  // what it takes, for help: "N|WxH", "DISTANCE", "PATH" ("" for a switch)
  std::string_view help;   // one line
  // Parses `value` into `options`. bad_input with "expected ..." (the caller
  // says where the value came from).
  Status (*set)(BakeOptions& options, const OptionValue& value);
  // The option's value in `options`, as words: --help shows it of BakeOptions{}.
  std::string (*show)(const BakeOptions& options);
  // The words it takes ("" when it takes a number, a path or free text).
  std::string (*words)();
  // A switch: a flag without a value on the command line (a job file's
  // true or false).
  bool is_switch = false;
  // Allowed in a job file's [defaults] (else only in a [[bake]]).
  bool in_defaults = true;
  // Applied before the others: a preset, which explicit keys override
  // whatever order they were written in.
  bool first = false;
  // The flag's name when it is not the key's ("map" for `maps`).
  std::string_view flag = "";
  // Repeated on the command line, each flag one value of a list (--pack).
  bool repeated = false;
};

// Every option, in --help's order.
std::span<const OptionSpec> bake_option_table();
// The row of `key` (a job key, "cage_mode"), nullptr when there is none.
const OptionSpec* find_option(std::string_view key);
// "--cage-mode" for "cage_mode" (the row's own flag name when it has one).
std::string flag_of(const OptionSpec& spec);
// --help's text of a row: the help, its words and its default.
std::string help_of(const OptionSpec& spec);

// Every option of the table as its row shows it, one JSON object in table
// order ({"size": "2048", "space": "tangent", ...}), and the outputs: what
// `nmbake bake --print-options` prints. Two options that print the same
// bake alike as far as any surface can say.
std::string options_json(const BakeOptions& options);

// One option as given, and where it was given for messages: "--space" (the
// value is added) or "job.toml:12: space".
struct GivenOption {
  const OptionSpec* spec = nullptr;
  OptionValue value;
  std::string where;
  bool is_flag = false;  // a command-line flag: the message shows the value after `where`
};
// Applies `given` to `options` in order, rows marked `first` before the
// others. The first bad value is bad_input naming where it came from:
// "--space tangnet: expected one of: tangent, object",
// "job.toml:12: space: expected one of: tangent, object".
Status apply_options(const std::vector<GivenOption>& given, BakeOptions& options);

}  // namespace nmbake
