// Shared vocabulary of every stage: status values for input/I-O problems and
// the always-on invariant check.
//
// Errors come in three tiers (STYLE.md):
//   * invariants: NMBAKE_CHECK (always on) aborts with file:line;
//   * input and I/O problems: a Status with a message that names the file and
//     the place (line, byte offset) and the reason;
//   * the CLI maps Status codes to the exit codes of DESIGN.md.
#pragma once

#include <cstdint>
#include <string>
#include <string_view>
#include <utility>

namespace nmbake {

enum class StatusCode : std::uint8_t {
  ok = 0,
  bad_input,  // a file or option the user gave is wrong (exit code 2)
  io,         // reading or writing failed (exit code 2)
  internal,   // a bug or an environment failure (exit code 3)
};

class [[nodiscard]] Status {
 public:
  Status() = default;
  static Status ok() { return {}; }
  static Status bad_input(std::string message) { return {StatusCode::bad_input, std::move(message)}; }
  static Status io(std::string message) { return {StatusCode::io, std::move(message)}; }
  static Status internal(std::string message) { return {StatusCode::internal, std::move(message)}; }

  bool is_ok() const { return code_ == StatusCode::ok; }
  explicit operator bool() const { return is_ok(); }
  StatusCode code() const { return code_; }
  const std::string& message() const { return message_; }

 private:
  Status(StatusCode code, std::string message) : code_(code), message_(std::move(message)) {}
  StatusCode code_ = StatusCode::ok;
  std::string message_;
};

// `text` safe to print to a terminal: every byte that could control it is
// written as \xNN (NUL and the other C0 controls, DEL, the C1 controls
// U+0080-U+009F, and any byte that is not part of valid UTF-8); other UTF-8
// is kept. Messages pass file content and paths through it, so a broken or
// hostile file cannot send escape codes, and a NUL cannot cut a message.
std::string printable_text(std::string_view text);
// `text` as a double-quoted string that JSON and TOML (basic strings) both
// read back exactly: quotes and backslashes escaped, control bytes as \u00XX,
// every other byte as it is.
std::string quoted_string(std::string_view text);

// Outputs are written to a temp file and renamed over the target, which
// replaces whatever the target is: as root, `--report /dev/full` replaced the
// device with a regular file. io "cannot write 'PATH': not a regular file"
// when PATH exists as anything but a regular file or a symlink (a symlink
// itself is replaced, never what it points to); ok otherwise.
Status check_output_target(const std::string& path);

[[noreturn]] void check_failed(const char* expression, const char* file, int line, const char* message);

}  // namespace nmbake

// Always on, in every build type: an invariant of the program, not of the input.
#define NMBAKE_CHECK(cond, msg)                                            \
  do {                                                                     \
    if (!(cond)) ::nmbake::check_failed(#cond, __FILE__, __LINE__, (msg)); \
  } while (0)

#ifdef NDEBUG
#define NMBAKE_DCHECK(cond, msg) \
  do {                           \
  } while (0)
#else
#define NMBAKE_DCHECK(cond, msg) NMBAKE_CHECK(cond, msg)
#endif

// Propagates a non-ok Status to the caller.
#define NMBAKE_TRY(expr)                                \
  do {                                                  \
    ::nmbake::Status nmbake_status_ = (expr);           \
    if (!nmbake_status_.is_ok()) return nmbake_status_; \
  } while (0)
