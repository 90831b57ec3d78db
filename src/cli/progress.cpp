#include "progress.hpp"

#include <unistd.h>

#include <cstdio>

namespace nmbake::cli {

JsonProgress::JsonProgress() : begin_(std::chrono::steady_clock::now()), stage_begin_(begin_) {}

void JsonProgress::update(const char* stage, double fraction) {
  const auto now = std::chrono::steady_clock::now();
  const bool new_stage = stage_ != stage;
  if (new_stage) {
    stage_ = stage;
    stage_begin_ = now;
  }
  if (!new_stage && fraction > 0.0 && fraction < 1.0 && now - last_line_ < std::chrono::milliseconds(100))
    return;
  last_line_ = now;
  const double elapsed = std::chrono::duration<double>(now - begin_).count();
  const double in_stage = std::chrono::duration<double>(now - stage_begin_).count();
  char eta[32] = "null";
  if (fraction > 0.0) std::snprintf(eta, sizeof eta, "%.3f", in_stage * (1.0 - fraction) / fraction);
  // Stage names are the pipeline's own words (no quoting needed).
  std::fprintf(stderr, "{\"stage\":\"%s\",\"fraction\":%.4f,\"elapsed_seconds\":%.3f,\"eta_seconds\":%s}\n",
               stage, fraction, elapsed, eta);
  std::fflush(stderr);
}

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
