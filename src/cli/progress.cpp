#include "progress.hpp"

#include <unistd.h>

#include <cstdio>

namespace nmbake::cli {

bool stderr_is_terminal() { return ::isatty(STDERR_FILENO) == 1; }

ProgressBar::ProgressBar(bool enabled) : enabled_(enabled) {}

ProgressBar::~ProgressBar() { finish(); }

void ProgressBar::update(const char* stage, double fraction) {
  if (!enabled_) return;
  const auto now = std::chrono::steady_clock::now();
  const bool new_stage = last_stage_ != stage;
  if (!new_stage && fraction < 1.0 && now - last_draw_ < std::chrono::milliseconds(50)) return;
  last_draw_ = now;
  last_stage_ = stage;
  constexpr int kWidth = 30;
  const int filled = static_cast<int>(fraction * kWidth + 0.5);
  char bar[kWidth + 1];
  for (int i = 0; i < kWidth; ++i) bar[i] = i < filled ? '#' : '.';
  bar[kWidth] = '\0';
  std::fprintf(stderr, "\r%-9s [%s] %3d%%", stage, bar, static_cast<int>(fraction * 100.0 + 0.5));
  std::fflush(stderr);
  drawn_ = true;
}

void ProgressBar::finish() {
  if (!drawn_) return;
  std::fprintf(stderr, "\r%*s\r", 50, "");
  std::fflush(stderr);
  drawn_ = false;
}

}  // namespace nmbake::cli
