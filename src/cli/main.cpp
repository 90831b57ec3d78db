// nmbake: the command-line front end. Argument parsing lives here and in the
// command files; the library only ever sees option structs.
#include <tbb/global_control.h>

#include <CLI/CLI.hpp>
#include <cstdio>
#include <exception>
#include <memory>

#include "commands.hpp"
#include "nmbake/cleanup.hpp"
#include "nmbake/task.hpp"

namespace nmbake::cli {

void print_error(const std::string& message) {
  const std::string text = printable_text(message);
  std::fprintf(stderr, "nmbake: error: %s\n", text.c_str());
}

}  // namespace nmbake::cli

int main(int argc, char** argv) {
  using namespace nmbake::cli;
  CLI::App app{"nmbake: bakes the detail of a high-poly mesh into a normal map of a low-poly mesh"};
  app.set_version_flag("--version", version_text,
                       "print the version, the commit and the libraries in use, and exit");
  app.require_subcommand(1);
  app.fallthrough();  // --threads, -q, -v also after the subcommand
  app.get_formatter()->column_width(36);
  GlobalOptions global;
  app.add_option("--threads", global.threads, "worker threads, 0 = all cores")
      ->default_val(0)
      ->check(CLI::Range(0, 1024));
  app.add_flag("-q,--quiet", global.quiet, "print nothing but errors");
  app.add_flag("-v,--verbose", global.verbose, "print the stage times");

  const Runner bake = add_bake_command(app, global);
  const Runner preview = add_preview_command(app, global);
  const Runner diff = add_diff_command(app, global);
  const Runner height2normal = add_height2normal_command(app, global);
  const Runner tangents = add_tangents_command(app, global);
  const Runner unwrap = add_unwrap_command(app, global);
  const Runner merge = add_merge_command(app, global);
  const Runner plan = add_plan_command(app, global);
  const Runner serve = add_serve_command(app, global);
  const Runner view = add_view_command(app, global);
  const Runner docs = add_docs_command(app, global);  // last: it walks the others

  try {
    app.parse(argc, argv);
  } catch (const CLI::ParseError& e) {
    const int code = app.exit(e);
    return code == 0 ? kSuccess : kBadInput;
  }
  // Ctrl-C or a farm's SIGTERM removes the temp files of the outputs being
  // written and exits 128 + signal (README, "Reliability").
  nmbake::install_signal_cleanup();
  try {
    std::unique_ptr<tbb::global_control> limit;
    if (global.threads > 0) {
      limit = std::make_unique<tbb::global_control>(tbb::global_control::max_allowed_parallelism,
                                                    static_cast<std::size_t>(global.threads));
    }
    if (app.got_subcommand("bake")) return bake();
    if (app.got_subcommand("preview")) return preview();
    if (app.got_subcommand("diff")) return diff();
    if (app.got_subcommand("height2normal")) return height2normal();
    if (app.got_subcommand("tangents")) return tangents();
    if (app.got_subcommand("unwrap")) return unwrap();
    if (app.got_subcommand("merge")) return merge();
    if (app.got_subcommand("plan")) return plan();
    if (app.got_subcommand("serve")) return serve();
    if (app.got_subcommand("view")) return view();
    if (app.got_subcommand("docs")) return docs();
  } catch (const std::exception& e) {
    std::fprintf(stderr, "nmbake: internal error: %s\n", nmbake::printable_text(e.what()).c_str());
    return kInternal;
  }
  return kBadInput;
}
