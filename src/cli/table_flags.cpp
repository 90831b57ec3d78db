// The option table's rows as command-line flags (commands.hpp): `bake`
// registers every row, `preview` the rows that say how a map was baked.
#include <string>

#include "commands.hpp"

namespace nmbake::cli {

void add_table_flags(CLI::App* cmd, TableFlags& flags, std::initializer_list<std::string_view> keys) {
  for (const OptionSpec& spec : bake_option_table()) {
    if (keys.size() > 0 && std::find(keys.begin(), keys.end(), spec.key) == keys.end()) continue;
    if (spec.is_switch) {
      cmd->add_flag(flag_of(spec), flags.switches[std::string(spec.key)], std::string(spec.help));
    } else {
      cmd->add_option(flag_of(spec), flags.values[std::string(spec.key)], help_of(spec))
          ->type_name(std::string(spec.value))
          ->allow_extra_args(false);
    }
  }
}

Status apply_table_flags(const TableFlags& flags, BakeOptions& options) {
  std::vector<GivenOption> given;
  for (const OptionSpec& spec : bake_option_table()) {
    GivenOption g{&spec, {}, flag_of(spec), true};
    if (spec.is_switch) {
      const auto it = flags.switches.find(spec.key);
      if (it == flags.switches.end() || !it->second) continue;
      g.value = OptionValue::of_text("true");
    } else {
      const auto it = flags.values.find(spec.key);
      if (it == flags.values.end() || it->second.empty()) continue;
      // A repeated flag is its last value; a repeated --map is one list
      // (--map normal --map ao).
      std::string joined;
      for (const std::string& word : it->second) joined += (joined.empty() ? "" : ",") + word;
      if (spec.repeated) {
        g.value.kind = OptionValue::Kind::list;
        g.value.list = it->second;
      } else {
        g.value = OptionValue::of_text(spec.key == "maps" ? joined : it->second.back());
      }
    }
    given.push_back(std::move(g));
  }
  return apply_options(given, options);
}

}  // namespace nmbake::cli
