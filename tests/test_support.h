#pragma once
// Helpers shared by the tests: the optional ../shared data, scratch directories, running the CLI.
#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <string>

#include <sys/wait.h>
#include <unistd.h>
#include "specula/core/error.h"

namespace specula::test {

/// The ../shared directory beside the project, or an empty path when it is absent.
inline std::filesystem::path shared_dir() {
  std::filesystem::path p = SPECULA_SHARED_DIR;
  return std::filesystem::is_directory(p / "data") ? p : std::filesystem::path{};
}

/// Skips the current test with a clear message when ../shared is absent.
#define SPECULA_REQUIRE_SHARED()                                                      \
  do {                                                                                \
    if (::specula::test::shared_dir().empty())                                        \
      GTEST_SKIP() << "../shared (real reference data) is absent beside the project"; \
  } while (0)

/// A fresh directory under the system temp dir, removed with everything in it on destruction.
class ScratchDir {
 public:
  ScratchDir() {
    auto base = std::filesystem::temp_directory_path();
    const auto* info = ::testing::UnitTest::GetInstance()->current_test_info();
    std::string name = std::string("specula-") + (info ? info->test_suite_name() : "x") + "-" +
                       (info ? info->name() : "y") + "-" + std::to_string(::getpid());
    for (char& c : name)
      if (c == '/') c = '_';
    path_ = base / name;
    std::filesystem::remove_all(path_);
    std::filesystem::create_directories(path_);
  }
  ~ScratchDir() {
    std::error_code ec;
    std::filesystem::remove_all(path_, ec);
  }
  const std::filesystem::path& path() const { return path_; }
  std::filesystem::path operator/(const std::string& s) const { return path_ / s; }

 private:
  std::filesystem::path path_;
};

/// Writes `bytes` to `path` exactly (binary), failing the test if the write fails.
inline void write_file(const std::filesystem::path& path, const std::string& bytes) {
  std::ofstream out(path, std::ios::binary);
  out.write(bytes.data(), static_cast<std::streamsize>(bytes.size()));
  EXPECT_TRUE(out.good()) << path;
}

/// The what() of the E that f() throws; a test failure and "" when it throws none.
template <typename E = specula::InputError, typename F>
std::string error_of(F&& f) {
  try {
    f();
  } catch (const E& e) {
    return e.what();
  }
  ADD_FAILURE() << "expected an exception";
  return {};
}

/// The what() of the specula::InputError that f() throws, or "no InputError".
template <class F>
std::string input_error_text(F&& f) {
  try {
    f();
  } catch (const specula::InputError& e) {
    return e.what();
  }
  return "no InputError";
}

/// Whole file as bytes.
inline std::string read_bytes(const std::filesystem::path& p) {
  std::ifstream in(p, std::ios::binary);
  return {std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>()};
}

/// Result of running a command: exit status and everything it printed (stdout and stderr).
struct RunResult {
  int status = -1;
  std::string output;
};

/// Runs a shell command line (already quoted), capturing stdout and stderr together.
inline RunResult run_shell(const std::string& command) {
  const std::string cmd = command + " 2>&1";
  RunResult r;
  FILE* pipe = ::popen(cmd.c_str(), "r");
  if (!pipe) return r;
  char buf[4096];
  std::size_t n;
  while ((n = std::fread(buf, 1, sizeof buf, pipe)) > 0) r.output.append(buf, n);
  int st = ::pclose(pipe);
  r.status = WIFEXITED(st) ? WEXITSTATUS(st) : 128 + WTERMSIG(st);
  return r;
}

/// Runs `args` (a shell command line, already quoted) with the specula binary prepended.
inline RunResult run_specula(const std::string& args) {
  return run_shell(std::string("'") + SPECULA_BINARY + "' " + args);
}

/// The number after "key": in a one-line JSON object, or NaN when the key is absent.
inline double json_number(const std::string& json, const std::string& key) {
  const std::string pattern = "\"" + key + "\":";
  const auto at = json.find(pattern);
  if (at == std::string::npos) return std::nan("");
  return std::stod(json.substr(at + pattern.size()));
}

}  // namespace specula::test
