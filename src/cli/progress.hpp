// A one-line progress bar on stderr, drawn only when stderr is a terminal.
#pragma once

#include <chrono>
#include <string>

namespace nmbake::cli {

class ProgressBar {
 public:
  explicit ProgressBar(bool enabled);
  ~ProgressBar();
  // Redraws at most 20 times a second.
  void update(const char* stage, double fraction);
  void finish();  // clears the line

 private:
  bool enabled_;
  bool drawn_ = false;
  std::string last_stage_;
  std::chrono::steady_clock::time_point last_draw_{};
};

bool stderr_is_terminal();

}  // namespace nmbake::cli
