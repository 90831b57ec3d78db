// Temp-file cleanup on signals (cleanup.hpp). A signal handler may only call
// async-signal-safe functions and touch lock-free state, so the registry is
// a fixed table of path buffers, each claimed and published through an
// atomic state; the handler unlink()s the published ones and _exit()s.
#include "nmbake/cleanup.hpp"

#include <fcntl.h>
#include <sys/stat.h>
#include <unistd.h>

#include <atomic>
#include <cerrno>
#include <csignal>
#include <cstring>

namespace nmbake {

namespace {

constexpr int kSlots = 64;
constexpr std::size_t kPathBytes = 4096;

enum SlotState : int { kFree = 0, kClaimed = 1, kPublished = 2 };

struct Slot {
  std::atomic<int> state{kFree};
  char path[kPathBytes];
};

Slot g_slots[kSlots];
static_assert(std::atomic<int>::is_always_lock_free, "the signal handler reads the slots");

void on_signal(int signal_number) {
  for (Slot& slot : g_slots) {
    if (slot.state.load(std::memory_order_acquire) == kPublished) ::unlink(slot.path);
  }
  ::_exit(kSignalExitBase + signal_number);
}

}  // namespace

void install_signal_cleanup() {
  struct sigaction action {};
  action.sa_handler = on_signal;
  sigemptyset(&action.sa_mask);
  // A second signal during the cleanup waits: the files go first.
  for (const int s : {SIGINT, SIGTERM, SIGHUP}) sigaddset(&action.sa_mask, s);
  for (const int s : {SIGINT, SIGTERM, SIGHUP}) sigaction(s, &action, nullptr);
  std::signal(SIGXFSZ, SIG_IGN);
}

TempFileGuard::TempFileGuard(const std::string& path) {
  if (path.size() >= kPathBytes) return;
  for (int i = 0; i < kSlots; ++i) {
    int expected = kFree;
    if (!g_slots[i].state.compare_exchange_strong(expected, kClaimed, std::memory_order_acquire)) continue;
    std::memcpy(g_slots[i].path, path.c_str(), path.size() + 1);
    g_slots[i].state.store(kPublished, std::memory_order_release);
    slot_ = i;
    return;
  }
}

void TempFileGuard::release() {
  if (slot_ < 0) return;
  g_slots[slot_].state.store(kFree, std::memory_order_release);
  slot_ = -1;
}

Status write_file_atomically(const std::string& path, std::initializer_list<std::string_view> pieces,
                             const char* what, unsigned mode) {
  return write_file_atomically(path, std::vector<std::string_view>(pieces), what, mode);
}

Status write_file_atomically(const std::string& path, const std::vector<std::string_view>& pieces,
                             const char* what, unsigned mode) {
  static std::atomic<unsigned> counter{0};
  const std::string temp = path + ".tmp" + std::to_string(::getpid()) + "_" + std::to_string(counter++);
  const TempFileGuard guard(temp);
  const int fd = ::open(temp.c_str(), O_WRONLY | O_CREAT | O_EXCL | O_CLOEXEC, static_cast<mode_t>(mode));
  const auto fail = [&](int error) {
    ::unlink(temp.c_str());
    return Status::io(path + ": cannot write " + what + ": " + std::strerror(error));
  };
  if (fd < 0) return Status::io(path + ": cannot write " + what + ": " + std::strerror(errno));
  for (std::string_view piece : pieces) {
    while (!piece.empty()) {
      const ssize_t written = ::write(fd, piece.data(), piece.size());
      if (written < 0 && errno == EINTR) continue;
      if (written <= 0) {
        const int error = written < 0 ? errno : ENOSPC;
        ::close(fd);
        return fail(error);
      }
      piece.remove_prefix(static_cast<std::size_t>(written));
    }
  }
  if (::close(fd) != 0) return fail(errno);
  if (::rename(temp.c_str(), path.c_str()) != 0) return fail(errno);
  return Status::ok();
}

}  // namespace nmbake
