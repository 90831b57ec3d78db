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

// --progress json: one JSON line a update on stderr,
//   {"stage": "trace", "fraction": 0.42, "elapsed_seconds": 3.1, "eta_seconds": 2.2}
// elapsed since the bake began; eta of the current stage, from its own rate
// (null before it has a fraction above 0). At most ten lines a second, and
// always the start and the end of a stage.
class JsonProgress {
 public:
  JsonProgress();
  void update(const char* stage, double fraction);

 private:
  std::chrono::steady_clock::time_point begin_, stage_begin_, last_line_{};
  std::string stage_;
};

bool stderr_is_terminal();

}  // namespace nmbake::cli
