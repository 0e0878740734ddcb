#pragma once
// Test support: start a real process, read its output with timeouts, stop
// it. Header-only; POSIX.

#include <fcntl.h>
#include <poll.h>
#include <signal.h>
#include <sys/wait.h>
#include <unistd.h>

#include <chrono>
#include <cstdlib>
#include <fstream>
#include <optional>
#include <sstream>
#include <string>
#include <vector>

namespace vloc::testing {

// Path of a vloc executable in the build's bin directory.
inline std::string BinPath(const std::string& name) {
  const char* dir = std::getenv("VLOC_BIN_DIR");
  return std::string(dir ? dir : VLOC_BIN_DIR) + "/" + name;
}

// A test-unique LCM URL on loopback multicast.
inline std::string TestLcmUrl(int port) {
  return "udpm://239.255.76.67:" + std::to_string(port) + "?ttl=0&recv_buf_size=33554432";
}

// Lines of a process's output that are not glog INFO/WARNING lines: what a
// user reads as its errors.
inline std::vector<std::string> ErrorLines(const std::string& output) {
  std::vector<std::string> lines;
  std::istringstream in(output);
  std::string line;
  while (std::getline(in, line))
    if (!line.empty() && line[0] != 'I' && line[0] != 'W') lines.push_back(line);
  return lines;
}

// How many times `text` occurs in a process's output (a message said once
// is one line naming it).
inline int CountOccurrences(const std::string& output, const std::string& text) {
  int n = 0;
  for (size_t pos = output.find(text); pos != std::string::npos; pos = output.find(text, pos + 1)) ++n;
  return n;
}

// A field of a running process's /proc/<pid>/status in MB (VmRSS: resident
// now, VmHWM: peak); -1 if there is none.
inline double ProcStatusMb(pid_t pid, const std::string& field) {
  std::ifstream f("/proc/" + std::to_string(pid) + "/status");
  std::string line;
  while (std::getline(f, line))
    if (line.rfind(field, 0) == 0) return std::stod(line.substr(field.size())) / 1024.0;
  return -1;
}

class Subprocess {
 public:
  // Starts argv[0] with arguments; stdout and stderr are captured (merged).
  explicit Subprocess(const std::vector<std::string>& argv, const std::vector<std::string>& env = {}) {
    int fds[2];
    if (pipe(fds) != 0) return;
    pid_ = fork();
    if (pid_ == 0) {
      dup2(fds[1], 1);
      dup2(fds[1], 2);
      close(fds[0]);
      close(fds[1]);
      setpgid(0, 0);
      for (const auto& kv : env) putenv(const_cast<char*>(kv.c_str()));
      std::vector<char*> args;
      for (const auto& a : argv) args.push_back(const_cast<char*>(a.c_str()));
      args.push_back(nullptr);
      execv(args[0], args.data());
      _exit(127);
    }
    close(fds[1]);
    fd_ = fds[0];
    fcntl(fd_, F_SETFL, O_NONBLOCK);
  }
  ~Subprocess() {
    if (pid_ > 0 && !exit_status_) {
      kill(-pid_, SIGKILL);
      int status = 0;
      waitpid(pid_, &status, 0);
    }
    if (fd_ >= 0) close(fd_);
  }
  Subprocess(const Subprocess&) = delete;
  Subprocess& operator=(const Subprocess&) = delete;

  pid_t pid() const { return pid_; }
  const std::string& output() const { return output_; }

  // Reads output until `text` appears or the timeout passes.
  bool WaitForOutput(const std::string& text, double timeout_s) {
    const auto deadline = Now() + timeout_s;
    while (output_.find(text) == std::string::npos) {
      const double left = deadline - Now();
      if (left <= 0) return false;
      if (!ReadSome(left) && exit_status_) return output_.find(text) != std::string::npos;
    }
    return true;
  }

  // Reads output until `text` appears at or after position `from`; its
  // position, or npos after the timeout (or once the process has exited).
  size_t WaitForOutputAfter(const std::string& text, size_t from, double timeout_s) {
    const auto deadline = Now() + timeout_s;
    for (;;) {
      const size_t at = output_.find(text, from);
      if (at != std::string::npos) return at;
      const double left = deadline - Now();
      if (left <= 0) return std::string::npos;
      if (!ReadSome(left) && exit_status_) return output_.find(text, from);
    }
  }

  // Waits for exit; returns the exit code (or 128 + signal), nullopt on timeout.
  std::optional<int> WaitExit(double timeout_s) {
    const auto deadline = Now() + timeout_s;
    while (!exit_status_) {
      ReadSome(0.05);
      int status = 0;
      if (waitpid(pid_, &status, WNOHANG) == pid_) {
        exit_status_ = WIFEXITED(status) ? WEXITSTATUS(status) : 128 + WTERMSIG(status);
        while (ReadSome(0.0)) {
        }
        break;
      }
      if (Now() > deadline) return std::nullopt;
    }
    return exit_status_;
  }

  // Reads what output is ready, without waiting: call it while the process
  // runs long, or it blocks once the pipe's buffer (64 kB) is full.
  void Drain() {
    while (ReadSome(0.0)) {
    }
  }

  void Signal(int sig) {
    if (pid_ > 0) kill(pid_, sig);
  }

 private:
  static double Now() {
    return std::chrono::duration<double>(std::chrono::steady_clock::now().time_since_epoch()).count();
  }
  bool ReadSome(double timeout_s) {
    if (fd_ < 0) return false;
    pollfd p{fd_, POLLIN, 0};
    if (poll(&p, 1, static_cast<int>(timeout_s * 1000)) <= 0) {
      int status = 0;
      if (!exit_status_ && waitpid(pid_, &status, WNOHANG) == pid_)
        exit_status_ = WIFEXITED(status) ? WEXITSTATUS(status) : 128 + WTERMSIG(status);
      return false;
    }
    char buf[4096];
    const ssize_t n = read(fd_, buf, sizeof(buf));
    if (n <= 0) return false;
    output_.append(buf, static_cast<size_t>(n));
    return true;
  }

  pid_t pid_ = -1;
  int fd_ = -1;
  std::string output_;
  std::optional<int> exit_status_;
};

}  // namespace vloc::testing
