// Running gnuplot: a child process fed its script on stdin, its exit status and last message checked.
#include "apps/gnuplot.h"

#include <fcntl.h>
#include <signal.h>
#include <spawn.h>
#include <sys/wait.h>
#include <unistd.h>

#include <fmt/format.h>

#include <cerrno>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <sstream>

#include "specula/core/atomic_file.h"
#include "specula/core/error.h"

extern char** environ;

namespace specula::app {

/// The gnuplot executable on PATH, or an empty path when there is none.
std::filesystem::path find_gnuplot() {
  const char* env = std::getenv("PATH");
  std::stringstream dirs(env ? env : "/usr/local/bin:/usr/bin:/bin");
  for (std::string dir; std::getline(dirs, dir, ':');) {
    const std::filesystem::path p = std::filesystem::path(dir.empty() ? "." : dir) / "gnuplot";
    std::error_code ec;
    if (std::filesystem::is_regular_file(p, ec) && ::access(p.c_str(), X_OK) == 0) return p;
  }
  return {};
}

/// A gnuplot string literal (single-quoted, quotes doubled).
std::string gnuplot_quote(std::string_view s) {
  std::string out = "'";
  for (char c : s) out += c == '\'' ? std::string("''") : std::string(1, c);
  return out + "'";
}

/// The terminal line of a PNG of width x height pixels: pngcairo when this gnuplot has it, else png.
std::string gnuplot_png_terminal(int width, int height) {
  return fmt::format(
      "if (strstrt(GPVAL_TERMINALS, 'pngcairo') > 0) {{ set terminal pngcairo size {0},{1} "
      "font 'sans,11' linewidth 1.5 }} else {{ set terminal png size {0},{1} }}\n",
      width, height);
}

/// Runs gnuplot with `script` on its stdin; throws LibraryError naming `what` with gnuplot's last message.
void run_gnuplot(const std::filesystem::path& gnuplot, const std::string& script, const std::string& what) {
  int in[2];
  if (::pipe2(in, O_CLOEXEC) != 0) throw LibraryError(what + ": cannot create a pipe: " + std::strerror(errno));
  FILE* log = std::tmpfile();
  if (!log) {
    ::close(in[0]);
    ::close(in[1]);
    throw LibraryError(what + ": cannot create a temporary file: " + std::strerror(errno));
  }
  posix_spawn_file_actions_t actions;
  posix_spawn_file_actions_init(&actions);
  posix_spawn_file_actions_adddup2(&actions, in[0], 0);
  posix_spawn_file_actions_adddup2(&actions, fileno(log), 1);
  posix_spawn_file_actions_adddup2(&actions, fileno(log), 2);
  pid_t pid = 0;
  char* argv[] = {const_cast<char*>("gnuplot"), nullptr};
  const int spawned = ::posix_spawn(&pid, gnuplot.c_str(), &actions, nullptr, argv, environ);
  posix_spawn_file_actions_destroy(&actions);
  ::close(in[0]);
  if (spawned != 0) {
    ::close(in[1]);
    std::fclose(log);
    throw LibraryError(what + ": cannot run " + gnuplot.string() + ": " + std::strerror(spawned));
  }
  struct sigaction ignore {
  }, previous{};
  ignore.sa_handler = SIG_IGN;
  ::sigaction(SIGPIPE, &ignore, &previous);
  for (std::size_t done = 0; done < script.size();) {
    const ssize_t n = ::write(in[1], script.data() + done, script.size() - done);
    if (n < 0 && errno == EINTR) continue;
    if (n <= 0) break;
    done += std::size_t(n);
  }
  ::close(in[1]);
  ::sigaction(SIGPIPE, &previous, nullptr);
  int status = 0;
  while (::waitpid(pid, &status, 0) < 0 && errno == EINTR) {}
  std::string output;
  std::rewind(log);
  char buf[4096];
  for (std::size_t n; (n = std::fread(buf, 1, sizeof buf, log)) > 0;) output.append(buf, n);
  std::fclose(log);
  if (WIFEXITED(status) && WEXITSTATUS(status) == 0) return;
  std::string last;
  std::istringstream lines(output);
  for (std::string line; std::getline(lines, line);) {
    const auto first = line.find_first_not_of(" \t\r");
    if (first != std::string::npos) last = line.substr(first);
  }
  const std::string how = WIFEXITED(status) ? fmt::format("exit status {}", WEXITSTATUS(status))
                                            : fmt::format("signal {}", WIFSIGNALED(status) ? WTERMSIG(status) : 0);
  throw LibraryError(fmt::format("{}: gnuplot failed ({}){}{}", what, how, last.empty() ? "" : ": ", last));
}

/// Draws `target` (a PNG) with a gnuplot script whose output line is added here, so it appears only when complete.
void plot_png(const std::filesystem::path& gnuplot, const std::filesystem::path& target, const std::string& terminal,
              const std::string& body) {
  AtomicOutput out(target);
  run_gnuplot(gnuplot,
              terminal + "set output " + gnuplot_quote(out.temp_path().string()) + "\n" + body + "set output\n",
              target.string());
  std::error_code ec;
  if (std::filesystem::file_size(out.temp_path(), ec) == 0 || ec)
    throw LibraryError(target.string() + ": gnuplot wrote no image; run it by hand to see why");
  out.commit();
}

}  // namespace specula::app
