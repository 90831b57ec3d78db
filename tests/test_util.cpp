#include "test_util.hpp"

#include <array>
#include <atomic>
#include <cstdio>
#include <fstream>
#include <random>
#include <stdexcept>

#include <sys/wait.h>
#include <unistd.h>

namespace nmbake::test {

LowSurface low_quad() {
  LowSurface s;
  const glm::vec3 p[4] = {{0, 0, 0}, {1, 0, 0}, {1, 1, 0}, {0, 1, 0}};
  for (int c : {0, 1, 2, 0, 2, 3}) {
    s.position.push_back(p[c]);
    s.uv.push_back({p[c].x, p[c].y});
    s.normal.push_back({0, 0, 1});
    s.cage_normal.push_back({0, 0, 1});
    s.tangent.push_back({1, 0, 0, 1});
  }
  return s;
}

TempDir::TempDir() {
  static std::atomic<int> counter{0};
  const auto base = std::filesystem::temp_directory_path();
  for (int attempt = 0; attempt < 1000; ++attempt) {
    auto candidate = base / ("nmbake_test_" + std::to_string(::getpid()) + "_" + std::to_string(counter++));
    if (std::filesystem::create_directory(candidate)) {
      path_ = candidate;
      return;
    }
  }
  throw std::runtime_error("cannot create a temporary directory");
}

TempDir::~TempDir() {
  std::error_code ignored;
  std::filesystem::remove_all(path_, ignored);
}

void write_text(const std::string& path, const std::string& text) {
  std::ofstream out(path, std::ios::binary | std::ios::trunc);
  out << text;
}

CommandResult run_command(const std::string& command_line) {
  CommandResult result;
  const std::string full = command_line + " 2>&1";
  FILE* pipe = ::popen(full.c_str(), "r");
  if (!pipe) return result;
  std::array<char, 4096> buffer{};
  size_t n = 0;
  while ((n = std::fread(buffer.data(), 1, buffer.size(), pipe)) > 0) result.output.append(buffer.data(), n);
  const int status = ::pclose(pipe);
  result.exit_code = WIFEXITED(status) ? WEXITSTATUS(status) : -1;
  return result;
}

std::string cli_path() { return NMBAKE_CLI_PATH; }
std::string gen_path() { return NMBAKE_GEN_PATH; }
std::string source_dir() { return NMBAKE_SOURCE_DIR; }

}  // namespace nmbake::test
