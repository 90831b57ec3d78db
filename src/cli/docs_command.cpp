// `nmbake docs` (not listed in --help): the manual pages, the bash completion
// and the Markdown reference, written from the command line's own
// definitions — the CLI11 app with every subcommand, whose bake flags are the
// option table's rows — so that none of them can drift from --help. The build
// runs it (CMakeLists.txt) and installs what it writes.
#include <cctype>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <memory>
#include <regex>
#include <sstream>
#include <string>
#include <vector>

#include "commands.hpp"
#include "nmbake/image.hpp"
#include "nmbake/options.hpp"
#include "nmbake/task.hpp"

namespace nmbake::cli {
namespace {

namespace fs = std::filesystem;

struct DocsFlags {
  std::string man_dir;
  std::string bash_file;
  std::string markdown_dir;
};

// Examples of each command, for the manual pages and the reference: what a
// user types, in the order a user needs them.
struct Example {
  const char* what;
  const char* command;
};
struct CommandExamples {
  const char* command;
  std::vector<Example> examples;
};
const std::vector<CommandExamples>& command_examples() {
  static const std::vector<CommandExamples> table = {
      {"bake",
       {{"A normal map with every default (2048 by 2048, 4 samples a texel, MikkTSpace, green up)",
         "nmbake bake --low low.obj --high high.ply -o normal.png"},
        {"The map set for Unreal, with a report",
         "nmbake bake --low low.fbx --high high.ply --map normal,ao,curvature --preset unreal "
         "-o 'out/asset_<MAP>.png' --report out/report.json"},
        {"Every bake of a job file, going on past a failed one", "nmbake bake job.toml --keep-going"}}},
      {"preview",
       {{"The sheet [high | low+map | error] of a bake",
         "nmbake preview --low low.obj --high high.ply --map normal.png -o sheet.png"}}},
      {"diff", {{"Gate a re-bake on the mean angle", "nmbake diff old.png new.png --max-mean 0.5"}}},
      {"height2normal",
       {{"A normal map from a height map", "nmbake height2normal height.png -o normal.png"}}},
      {"tangents",
       {{"Draw the tangent frames of a low mesh", "nmbake tangents low.obj --view frames.png"},
        {"Write the tangents a map was baked in (glTF TANGENT)", "nmbake tangents low.fbx --write low.glb"}}},
      {"unwrap", {{"UVs for a low mesh without them", "nmbake unwrap low.obj -o low_uv.obj --size 2048"}}},
      {"merge", {{"Merge the tiles of a bake", "nmbake merge normal.png.tile-*-of-4"}}},
      {"plan",
       {{"A Ninja file that bakes a job in parallel, one task a bake",
         "nmbake plan job.toml --ninja build.ninja"}}},
      {"serve", {{"A live session answering JSON lines", "nmbake serve --memory-budget 8G"}}},
      {"view",
       {{"A page to turn the low mesh wearing its maps in 3D (opens from disk, offline)",
         "nmbake view --low low.obj --map normal.png --map ao.png --report report.json -o review.html"},
        {"The same page served on 127.0.0.1, reloading the maps when a re-bake rewrites them",
         "nmbake view --low low.obj --map normal.png -o review.html --serve --port 8790"}}},
  };
  return table;
}
const std::vector<Example>* examples_of(const std::string& command) {
  for (const CommandExamples& entry : command_examples()) {
    if (command == entry.command) return &entry.examples;
  }
  return nullptr;
}

// The words a flag takes, for completion: the option table's words for its
// rows, else a validator's set ("{auto,bar,json}") or a type name made of
// words ("png8|png16"); none for a number, a path or free text.
std::vector<std::string> split_words(const std::string& text, char separator) {
  std::vector<std::string> words;
  std::string word;
  std::istringstream in(text);
  while (std::getline(in, word, separator)) {
    const std::size_t begin = word.find_first_not_of(' ');
    const std::size_t end = word.find_last_not_of(' ');
    if (begin == std::string::npos) continue;
    word = word.substr(begin, end - begin + 1);
    // Placeholders (N, WxH, PATH) are upper case: not words.
    bool is_word = !word.empty();
    for (char c : word) {
      if (!(std::islower(static_cast<unsigned char>(c)) || std::isdigit(static_cast<unsigned char>(c)) ||
            c == '-' || c == '_' || c == '.')) {
        is_word = false;
      }
    }
    if (is_word) words.push_back(word);
  }
  return words;
}

std::vector<std::string> words_of(const CLI::Option& option) {
  for (const OptionSpec& spec : bake_option_table()) {
    for (const std::string& name : option.get_lnames()) {
      if ("--" + name == flag_of(spec)) {
        std::vector<std::string> words = split_words(spec.words(), ',');
        if (words.empty()) words = split_words(std::string(spec.value), '|');
        return words;
      }
    }
  }
  const std::string type = option.get_type_name();
  const std::size_t open = type.find('{');
  const std::size_t close = type.find('}', open);
  if (open != std::string::npos && close != std::string::npos) {
    return split_words(type.substr(open + 1, close - open - 1), ',');
  }
  if (type.find('|') != std::string::npos) return split_words(type, '|');
  // A help text that lists the words: "clamp (...) | wrap (...)", "png8 | png16".
  static const std::regex listed(
      R"(([a-z][a-z0-9-]*)(?: \([^)]*\))?((?: \| [a-z][a-z0-9-]*(?: \([^)]*\))?)+))");
  std::smatch match;
  const std::string help = option.get_description();
  if (std::regex_search(help, match, listed)) {
    std::vector<std::string> words{match[1].str()};
    static const std::regex word(R"(\| ([a-z][a-z0-9-]*))");
    const std::string rest = match[2].str();
    for (std::sregex_iterator it(rest.begin(), rest.end(), word), end; it != end; ++it)
      words.push_back((*it)[1]);
    return words;
  }
  if (option.get_lnames() == std::vector<std::string>{"format"})
    return split_words(word_list<PixelFormat>(","), ',');
  return {};
}

bool takes_value(const CLI::Option& option) { return option.get_items_expected_max() > 0; }

std::string flag_names(const CLI::Option& option, const char* separator) {
  std::string names;
  for (const std::string& s : option.get_snames())
    names.append(names.empty() ? "" : separator).append("-" + s);
  for (const std::string& l : option.get_lnames())
    names.append(names.empty() ? "" : separator).append("--" + l);
  return names;
}

std::vector<const CLI::App*> commands_of(const CLI::App& app) {
  std::vector<const CLI::App*> commands;
  for (const CLI::App* sub : app.get_subcommands([](const CLI::App*) { return true; })) {
    if (!sub->get_group().empty()) commands.push_back(sub);  // hidden ones (docs) have no group
  }
  return commands;
}

// --- groff -------------------------------------------------------------------

// Text as groff reads it: backslashes escaped, hyphens as minus signs where
// they are flags, a leading dot or quote made harmless.
std::string roff(const std::string& text) {
  std::string out;
  for (char c : text) {
    if (c == '\\') {
      out += "\\e";
    } else if (c == '-') {
      out += "\\-";
    } else {
      out += c;
    }
  }
  if (!out.empty() && (out[0] == '.' || out[0] == '\'')) out.insert(0, "\\&");
  return out;
}

void roff_option(std::ostream& out, const CLI::Option& option) {
  out << ".TP\n";
  std::string names;
  for (const std::string& s : option.get_snames())
    names.append(names.empty() ? "" : ", ").append("\\fB\\-" + s + "\\fR");
  for (const std::string& l : option.get_lnames()) {
    names.append(names.empty() ? "" : ", ").append("\\fB" + roff("--" + l) + "\\fR");
  }
  if (takes_value(option)) {
    std::string type = option.get_type_name();
    if (type.empty()) type = "VALUE";
    names += " \\fI" + roff(type) + "\\fR";
  }
  out << names << "\n" << roff(option.get_description()) << "\n";
  const std::string shown = option.get_default_str();
  if (!shown.empty() && option.get_description().find("(default") == std::string::npos) {
    out << "Default: " << roff(shown) << ".\n";
  }
}

const char* const kExitStatus =
    ".SH EXIT STATUS\n"
    ".TP\n.B 0\nsuccess\n"
    ".TP\n.B 1\nthe bake finished but a gate failed (\\fB\\-\\-max\\-miss\\-rate\\fR; \\fBdiff\\fR's "
    "bounds)\n"
    ".TP\n.B 2\nbad input or usage: the message names the file (and line, field or byte offset) and the "
    "reason, "
    "and nothing is written\n"
    ".TP\n.B 3\ninternal error\n"
    ".TP\n.B 128 + N\nended by signal N (130: Ctrl\\-C, 143: SIGTERM); the temporary files of the outputs "
    "being "
    "written are removed\n";

void write_global_options(std::ostream& out, const CLI::App& app) {
  for (const CLI::Option* option : app.get_options()) {
    if (option->get_lnames().empty() && option->get_snames().empty()) continue;
    roff_option(out, *option);
  }
}

std::string title_of(const std::string& name) {
  std::string title;
  for (char c : name) title += static_cast<char>(std::toupper(static_cast<unsigned char>(c)));
  return title;
}

void write_man_page(const fs::path& file, const CLI::App& app, const CLI::App& command) {
  const std::string name = "nmbake-" + command.get_name();
  std::ofstream out(file, std::ios::binary);
  out << ".TH " << roff(title_of(name)) << " 1 \"\" \"nmbake " << kNmbakeVersion << "\" \"nmbake manual\"\n";
  out << ".SH NAME\n" << roff(name) << " \\- " << roff(command.get_description()) << "\n";
  out << ".SH SYNOPSIS\n.B nmbake " << roff(command.get_name()) << "\n[\\fIOPTIONS\\fR]";
  for (const CLI::Option* option : command.get_options()) {
    if (option->get_positional() && !option->nonpositional()) {
      out << (option->get_required() ? " \\fI" : " [\\fI") << roff(option->get_name())
          << (option->get_required() ? "\\fR" : "\\fR]");
    }
  }
  std::string description = command.get_description();
  if (!description.empty())
    description[0] = static_cast<char>(std::toupper(static_cast<unsigned char>(description[0])));
  out << "\n.SH DESCRIPTION\n" << roff(description) << ".\n";
  out << "The global options (see \\fBnmbake\\fR(1)) come before or after the command.\n";
  bool any_positional = false;
  for (const CLI::Option* option : command.get_options()) {
    if (!option->get_positional() || option->nonpositional()) continue;
    if (!any_positional) out << ".SH ARGUMENTS\n";
    any_positional = true;
    out << ".TP\n\\fI" << roff(option->get_name()) << "\\fR\n" << roff(option->get_description()) << "\n";
  }
  out << ".SH OPTIONS\n";
  for (const CLI::Option* option : command.get_options()) {
    if (option->nonpositional()) roff_option(out, *option);
  }
  out << ".SS Global options\n";
  write_global_options(out, app);
  out << kExitStatus;
  if (const std::vector<Example>* examples = examples_of(command.get_name())) {
    out << ".SH EXAMPLES\n";
    for (const Example& example : *examples) {
      out << ".PP\n"
          << roff(example.what) << ":\n.PP\n.RS 4\n.nf\n"
          << roff(example.command) << "\n.fi\n.RE\n";
    }
  }
  out << ".SH SEE ALSO\n\\fBnmbake\\fR(1)\n";
}

void write_main_page(const fs::path& file, const CLI::App& app) {
  std::ofstream out(file, std::ios::binary);
  out << ".TH NMBAKE 1 \"\" \"nmbake " << kNmbakeVersion << "\" \"nmbake manual\"\n";
  out << ".SH NAME\nnmbake \\- " << roff(app.get_description().substr(app.get_description().find(": ") + 2))
      << "\n";
  out << ".SH SYNOPSIS\n.B nmbake\n[\\fIGLOBAL OPTIONS\\fR] \\fICOMMAND\\fR [\\fIOPTIONS\\fR]\n";
  out << ".SH DESCRIPTION\n"
         "nmbake rasterizes the low mesh's UV charts into texels, casts rays from a cage onto the high "
         "mesh, and stores each hit's normal in the low mesh's MikkTSpace tangent frame: 16\\-bit PNG, "
         "TIFF, EXR or 8\\-bit TGA normal maps, and a whole map set (AO, height, curvature, ids, "
         "transferred textures) from the same rays. The same inputs give the same bytes.\n";
  out << ".SH COMMANDS\n";
  for (const CLI::App* command : commands_of(app)) {
    out << ".TP\n\\fBnmbake\\-" << roff(command->get_name()) << "\\fR(1)\n"
        << roff(command->get_description()) << "\n";
  }
  out << ".SH GLOBAL OPTIONS\n";
  write_global_options(out, app);
  out << kExitStatus;
  out << ".SH ENVIRONMENT\n"
         ".TP\n.B NMBAKE_CACHE\nthe cache folder of \\fBbake \\-\\-cache\\fR\n"
         ".TP\n.B NMBAKE_MODULE_DIR\nthe folder of the image module (libnmbake_oiio.so: TIFF, PIZ EXR, TGA "
         "and "
         "reading images), instead of ../lib/nmbake beside the program\n";
  out << ".SH SEE ALSO\n";
  bool first = true;
  for (const CLI::App* command : commands_of(app)) {
    out << (first ? "" : ",\n") << "\\fBnmbake\\-" << roff(command->get_name()) << "\\fR(1)";
    first = false;
  }
  out << "\n";
}

// --- bash ----------------------------------------------------------------------

std::string shell_words(const std::vector<std::string>& words) {
  std::string text;
  for (const std::string& w : words) text.append(text.empty() ? "" : " ").append(w);
  return text;
}

void write_bash(std::ostream& out, const CLI::App& app) {
  std::vector<std::string> command_names, global_flags;
  for (const CLI::App* command : commands_of(app)) command_names.push_back(command->get_name());
  for (const CLI::Option* option : app.get_options()) {
    if (option->nonpositional()) global_flags.push_back(flag_names(*option, " "));
  }
  out << "# bash completion for nmbake, written by `nmbake docs --bash` from the program's own flags.\n"
         "_nmbake() {\n"
         "  local cur=${COMP_WORDS[COMP_CWORD]} prev=${COMP_WORDS[COMP_CWORD-1]} command='' i\n"
         "  for ((i = 1; i < COMP_CWORD; i++)); do\n"
         "    case ${COMP_WORDS[i]} in\n"
         "      "
      <<
      [&] {
        std::string alternatives;
        for (const std::string& c : command_names)
          alternatives.append(alternatives.empty() ? "" : "|").append(c);
        return alternatives;
      }()
      << ") command=${COMP_WORDS[i]}; break ;;\n"
         "    esac\n"
         "  done\n"
         "  local flags words=''\n"
         "  case $command in\n"
         "    '') flags='"
      << shell_words(global_flags)
      << "'\n"
         "      if [[ $cur != -* ]]; then COMPREPLY=($(compgen -W '"
      << shell_words(command_names) << "' -- \"$cur\")); return; fi ;;\n";
  for (const CLI::App* command : commands_of(app)) {
    std::vector<std::string> flags = global_flags;
    std::string cases;
    std::string value_flags;
    for (const CLI::Option* option : command->get_options()) {
      if (!option->nonpositional()) continue;
      flags.push_back(flag_names(*option, " "));
      if (!takes_value(*option)) continue;
      const std::vector<std::string> words = words_of(*option);
      if (!words.empty()) {
        cases += "        " + flag_names(*option, "|") + ") words='" + shell_words(words) + "' ;;\n";
      } else {
        value_flags.append(value_flags.empty() ? "" : "|").append(flag_names(*option, "|"));
      }
    }
    out << "    " << command->get_name() << ") flags='" << shell_words(flags) << "'\n";
    out << "      case $prev in\n" << cases;
    if (!value_flags.empty()) out << "        " << value_flags << ") words=FILES ;;\n";
    out << "      esac ;;\n";
  }
  out << "  esac\n"
         "  case $prev in --threads) return ;; esac\n"
         "  if [[ $words == FILES ]]; then\n"
         "    COMPREPLY=($(compgen -f -- \"$cur\"))\n"
         "  elif [[ -n $words ]]; then\n"
         "    COMPREPLY=($(compgen -W \"$words\" -- \"$cur\"))\n"
         "  elif [[ $cur == -* ]]; then\n"
         "    COMPREPLY=($(compgen -W \"$flags\" -- \"$cur\"))\n"
         "  else\n"
         "    COMPREPLY=($(compgen -f -- \"$cur\"))\n"
         "  fi\n"
         "}\n"
         "complete -o filenames -F _nmbake nmbake\n";
}

// --- Markdown -----------------------------------------------------------------

std::string md_cell(const std::string& text) {
  std::string out;
  for (char c : text) {
    if (c == '|') {
      out += "\\|";
    } else if (c == '<' || c == '>') {
      out += c == '<' ? "&lt;" : "&gt;";
    } else {
      out += c;
    }
  }
  return out;
}

void write_markdown(const fs::path& file, const CLI::App& command) {
  std::ofstream out(file, std::ios::binary);
  out << "# nmbake " << command.get_name() << "\n\n" << command.get_description() << ".\n\n";
  out << "<!-- Written by `nmbake docs --markdown` from the program's own flags: edit the source, not this "
         "page. -->\n\n";
  out << "| flag | value | meaning |\n|---|---|---|\n";
  for (const CLI::Option* option : command.get_options()) {
    if (!option->nonpositional()) continue;
    out << "| `" << flag_names(*option, "`, `") << "` | "
        << (takes_value(*option) ? md_cell(option->get_type_name()) : "") << " | "
        << md_cell(option->get_description()) << " |\n";
  }
  for (const CLI::Option* option : command.get_options()) {
    if (option->get_positional() && !option->nonpositional()) {
      out << "\nArgument `" << option->get_name() << "`: " << md_cell(option->get_description()) << ".\n";
    }
  }
  if (const std::vector<Example>* examples = examples_of(command.get_name())) {
    out << "\n## Examples\n";
    for (const Example& example : *examples) {
      out << "\n" << example.what << ":\n\n```sh\n" << example.command << "\n```\n";
    }
  }
}

Status write_all(const DocsFlags& flags, const CLI::App& app) {
  std::error_code ec;
  if (!flags.man_dir.empty()) {
    fs::create_directories(flags.man_dir, ec);
    if (ec) return Status::bad_input(flags.man_dir + ": cannot create the folder: " + ec.message());
    write_main_page(fs::path(flags.man_dir) / "nmbake.1", app);
    for (const CLI::App* command : commands_of(app)) {
      write_man_page(fs::path(flags.man_dir) / ("nmbake-" + command->get_name() + ".1"), app, *command);
    }
  }
  if (!flags.bash_file.empty()) {
    std::ofstream out(flags.bash_file, std::ios::binary);
    if (!out) return Status::bad_input(flags.bash_file + ": cannot write the file");
    write_bash(out, app);
  }
  if (!flags.markdown_dir.empty()) {
    fs::create_directories(flags.markdown_dir, ec);
    if (ec) return Status::bad_input(flags.markdown_dir + ": cannot create the folder: " + ec.message());
    for (const CLI::App* command : commands_of(app)) {
      write_markdown(fs::path(flags.markdown_dir) / (command->get_name() + ".md"), *command);
    }
  }
  return Status::ok();
}

}  // namespace

Runner add_docs_command(CLI::App& app, const GlobalOptions& /*global*/) {
  auto flags = std::make_shared<DocsFlags>();
  CLI::App* cmd =
      app.add_subcommand("docs", "write the manual pages, the bash completion and the Markdown reference");
  cmd->group("");  // not listed in --help: the build runs it
  cmd->add_option("--man", flags->man_dir, "write nmbake.1 and nmbake-COMMAND.1 into this folder");
  cmd->add_option("--bash", flags->bash_file, "write the bash completion script to this file");
  cmd->add_option("--markdown", flags->markdown_dir,
                  "write COMMAND.md (the flags and examples) into this folder");
  return [flags, &app]() {
    const Status status = write_all(*flags, app);
    if (!status) {
      print_error(status.message());
      return static_cast<int>(kBadInput);
    }
    return static_cast<int>(kSuccess);
  };
}

}  // namespace nmbake::cli
