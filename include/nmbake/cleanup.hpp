// Temp files and signals: every output is written to a temp file in its
// folder and renamed when complete (image.hpp, load.hpp's save_mesh, the
// CLI's reports). A temp file being written is registered here, so that
// SIGINT, SIGTERM or SIGHUP removes it before the process ends: an
// interrupted bake leaves neither a half-written map nor a stray temp file.
#pragma once

#include <initializer_list>
#include <string>
#include <string_view>
#include <vector>

#include "nmbake/common.hpp"

namespace nmbake {

// Exit code after a signal: 128 + its number (130 for SIGINT, 143 for
// SIGTERM, 129 for SIGHUP), as shells report a process killed by one.
constexpr int kSignalExitBase = 128;

// Installs handlers for SIGINT, SIGTERM and SIGHUP that remove every
// registered temp file and _exit(128 + signal); ignores SIGXFSZ, so a write
// past `ulimit -f` fails with EFBIG (and an exit 2 naming the file) instead
// of killing the process. Call once, from main().
void install_signal_cleanup();

// Registers `path` (a temp file about to be created) until release() or
// destruction. Up to 64 at once (one per output being written); beyond
// that a file is written unregistered (it is still removed on failure).
class TempFileGuard {
 public:
  explicit TempFileGuard(const std::string& path);
  ~TempFileGuard() { release(); }
  TempFileGuard(const TempFileGuard&) = delete;
  TempFileGuard& operator=(const TempFileGuard&) = delete;
  void release();  // the file was renamed or removed: nothing to clean up

 private:
  int slot_ = -1;
};

// Writes `pieces`, one after the other, to `path` through a registered temp
// file in its folder (named with the pid and a counter, so concurrent
// writers stay apart) and a rename: the file appears whole or not at all,
// and a failure or a signal leaves nothing behind. `what` names the file in
// messages: Status::io "PATH: cannot write WHAT: REASON". `mode` is the new
// file's permission bits.
Status write_file_atomically(const std::string& path, std::initializer_list<std::string_view> pieces,
                             const char* what, unsigned mode = 0666);
Status write_file_atomically(const std::string& path, const std::vector<std::string_view>& pieces,
                             const char* what, unsigned mode = 0666);

}  // namespace nmbake
