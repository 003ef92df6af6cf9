#pragma once

// Running the built commands from tests with their output captured, and spawning one in the
// background to signal it (issue 9: SIGINT during a solve, clear command lines).

#include <fcntl.h>
#include <signal.h>
#include <sys/types.h>
#include <sys/wait.h>
#include <unistd.h>

#include <cerrno>
#include <chrono>
#include <cstdio>
#include <cstdlib>
#include <string>
#include <thread>

#include "tests/support/test_support.hpp"

namespace epitrack::test {

/// `text` quoted for /bin/sh (single quotes).
inline std::string shellQuote(const std::string& text) {
  std::string q = "'";
  for (const char c : text) {
    if (c == '\'')
      q += "'\\''";
    else
      q += c;
  }
  return q + "'";
}

/// Exit status and captured output of one command.
struct CommandOutput {
  int exit_code = -1;  ///< -1: did not exit normally
  std::string out;
  std::string err;
};

/// Runs a shell command (e.g. built from binaryPath()) with stdin from /dev/null and stdout and
/// stderr captured through files named `scratch` + ".out"/".err".
inline CommandOutput runCaptured(const std::string& command, const std::string& scratch) {
  CommandOutput r;
  const std::string out = scratch + ".out";
  const std::string err = scratch + ".err";
  const int rc =
      std::system((command + " </dev/null >" + shellQuote(out) + " 2>" + shellQuote(err)).c_str());
  r.exit_code = (rc != -1 && WIFEXITED(rc)) ? WEXITSTATUS(rc) : -1;
  r.out = readWholeFile(out);
  r.err = readWholeFile(err);
  return r;
}

/// A command started in the background through /bin/sh -c "exec COMMAND", its standard input a
/// pipe the test writes, its stderr going to a file. The shell execs the command, so the pid is
/// the command's own (signals reach it, not a shell).
class SpawnedCommand {
 public:
  static constexpr int kKilledBySignal = 1000;

  SpawnedCommand(const std::string& command, const std::string& stderr_path)
      : stderr_path_(stderr_path) {
    int fds[2];
    if (::pipe(fds) != 0) return;
    pid_ = ::fork();
    if (pid_ == 0) {
      ::dup2(fds[0], 0);
      ::close(fds[0]);
      ::close(fds[1]);
      const int err = ::open(stderr_path.c_str(), O_WRONLY | O_CREAT | O_TRUNC, 0644);
      if (err >= 0) ::dup2(err, 2);
      const int null = ::open("/dev/null", O_WRONLY);
      if (null >= 0) ::dup2(null, 1);
      const std::string exec = "exec " + command;
      ::execl("/bin/sh", "sh", "-c", exec.c_str(), static_cast<char*>(nullptr));
      ::_exit(127);
    }
    ::close(fds[0]);
    stdin_ = fds[1];
    // A reader that died must not kill the test with SIGPIPE: writes then fail instead.
    ::signal(SIGPIPE, SIG_IGN);
  }
  ~SpawnedCommand() {
    closeInput();
    if (pid_ > 0 && !waited_) {
      ::kill(pid_, SIGKILL);
      wait();
    }
  }
  SpawnedCommand(const SpawnedCommand&) = delete;
  SpawnedCommand& operator=(const SpawnedCommand&) = delete;

  [[nodiscard]] bool started() const { return pid_ > 0 && stdin_ >= 0; }
  [[nodiscard]] pid_t pid() const { return pid_; }

  /// Writes all of `data` to the command's standard input (blocks while the pipe is full, that
  /// is until the command has read the rest). False when the command stopped reading.
  bool writeInput(const void* data, std::size_t size) {
    const auto* p = static_cast<const char*>(data);
    while (size > 0) {
      const ssize_t n = ::write(stdin_, p, size);
      if (n < 0 && errno == EINTR) continue;
      if (n <= 0) return false;
      p += n;
      size -= static_cast<std::size_t>(n);
    }
    return true;
  }
  void closeInput() {
    if (stdin_ >= 0) ::close(stdin_);
    stdin_ = -1;
  }
  bool signal(int signal_number) { return pid_ > 0 && ::kill(pid_, signal_number) == 0; }

  /// Polls the command's stderr until it contains `text` or `timeout_s` passes.
  bool waitForStderr(const std::string& text, double timeout_s) const {
    const auto end = std::chrono::steady_clock::now() + std::chrono::duration<double>(timeout_s);
    while (std::chrono::steady_clock::now() < end) {
      if (readWholeFile(stderr_path_).find(text) != std::string::npos) return true;
      std::this_thread::sleep_for(std::chrono::milliseconds(2));
    }
    return false;
  }

  /// Waits for the exit; returns the exit code, kKilledBySignal + signal when a signal killed it
  /// (kept apart from exit codes such as 130 that a command returns itself), -1 on error.
  int wait() {
    if (pid_ <= 0) return -1;
    int status = 0;
    while (::waitpid(pid_, &status, 0) < 0) {
      if (errno != EINTR) return -1;
    }
    waited_ = true;
    if (WIFEXITED(status)) return WEXITSTATUS(status);
    if (WIFSIGNALED(status)) return kKilledBySignal + WTERMSIG(status);
    return -1;
  }
  [[nodiscard]] std::string stderrText() const { return readWholeFile(stderr_path_); }

 private:
  std::string stderr_path_;
  pid_t pid_ = -1;
  int stdin_ = -1;
  bool waited_ = false;
};

}  // namespace epitrack::test
