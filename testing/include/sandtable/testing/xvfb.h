#pragma once
// Test helper shared by viewer/test/test_window.cpp and
// tests/test_viewer_window.cpp: a private Xvfb server.
#include <fcntl.h>
#include <signal.h>
#include <spawn.h>
#include <sys/wait.h>
#include <unistd.h>

#include <memory>
#include <string>
#include <vector>

extern char** environ;

namespace sandtable::testsupport {

/// An Xvfb on a display number it picks itself (-displayfd), so tests
/// running side by side never collide; stopped by the destructor. start()
/// gives null when Xvfb is not installed or does not come up.
class Xvfb {
 public:
  static std::unique_ptr<Xvfb> start() {
    int fds[2];
    if (::pipe(fds) != 0) return nullptr;
    const std::string fd = std::to_string(fds[1]);
    std::vector<std::string> args = {"Xvfb", "-displayfd", fd, "-screen", "0", "640x480x24",
                                     "-nolisten", "tcp", "-noreset"};
    std::vector<char*> argv;
    for (auto& a : args) argv.push_back(a.data());
    argv.push_back(nullptr);
    posix_spawn_file_actions_t fa;
    posix_spawn_file_actions_init(&fa);
    posix_spawn_file_actions_addclose(&fa, fds[0]);
    posix_spawn_file_actions_addopen(&fa, STDOUT_FILENO, "/dev/null", O_WRONLY, 0);
    posix_spawn_file_actions_addopen(&fa, STDERR_FILENO, "/dev/null", O_WRONLY, 0);
    pid_t pid = -1;
    const int rc = posix_spawnp(&pid, "Xvfb", &fa, nullptr, argv.data(), environ);
    posix_spawn_file_actions_destroy(&fa);
    ::close(fds[1]);
    if (rc != 0) {
      ::close(fds[0]);
      return nullptr;
    }
    auto x = std::unique_ptr<Xvfb>(new Xvfb(pid));
    // Xvfb writes the display number once it accepts connections; EOF
    // means it gave up.
    std::string number;
    char c = 0;
    while (::read(fds[0], &c, 1) == 1 && c != '\n') number += c;
    ::close(fds[0]);
    if (number.empty()) return nullptr;
    x->display = ":" + number;
    return x;
  }
  ~Xvfb() {
    ::kill(pid_, SIGTERM);
    int status = 0;
    ::waitpid(pid_, &status, 0);
  }
  std::string display;

 private:
  explicit Xvfb(pid_t pid) : pid_(pid) {}
  pid_t pid_;
};

}  // namespace sandtable::testsupport
