#include "sandtable/viewer/video.h"

#include <fcntl.h>
#include <signal.h>
#include <spawn.h>
#include <sys/stat.h>
#include <sys/wait.h>
#include <unistd.h>

#include <cerrno>
#include <cstdlib>
#include <cstdio>
#include <cstring>
#include <ctime>
#include <fstream>
#include <sstream>
#include <vector>

extern char** environ;

namespace sandtable::viewer {
namespace {

bool executable(const std::string& path) {
  struct stat st {};
  return ::stat(path.c_str(), &st) == 0 && S_ISREG(st.st_mode) && ::access(path.c_str(), X_OK) == 0;
}

std::string tail(const std::string& file, std::size_t bytes) {
  std::ifstream in(file, std::ios::binary);
  std::ostringstream s;
  s << in.rdbuf();
  std::string t = s.str();
  if (t.size() > bytes) t = "..." + t.substr(t.size() - bytes);
  while (!t.empty() && (t.back() == '\n' || t.back() == '\r')) t.pop_back();
  return t;
}

/// write() without SIGPIPE: block it on this thread, and swallow the one a
/// dead reader raised before unblocking.
bool writeAll(int fd, const std::uint8_t* p, std::size_t n, int& err) {
  sigset_t pipeSet, old;
  sigemptyset(&pipeSet);
  sigaddset(&pipeSet, SIGPIPE);
  pthread_sigmask(SIG_BLOCK, &pipeSet, &old);
  bool ok = true;
  while (n > 0) {
    const ssize_t w = ::write(fd, p, n);
    if (w < 0) {
      if (errno == EINTR) continue;
      err = errno;
      ok = false;
      break;
    }
    p += w;
    n -= std::size_t(w);
  }
  if (!ok && err == EPIPE) {
    const timespec zero{0, 0};
    sigtimedwait(&pipeSet, nullptr, &zero);
  }
  pthread_sigmask(SIG_SETMASK, &old, nullptr);
  return ok;
}

}  // namespace

bool VideoWriter::available(const std::string& program) {
  if (program.find('/') != std::string::npos) return executable(program);
  const char* path = std::getenv("PATH");
  std::istringstream dirs(path ? path : "/usr/bin:/bin");
  for (std::string dir; std::getline(dirs, dir, ':');) {
    if (executable((dir.empty() ? "." : dir) + "/" + program)) return true;
  }
  return false;
}

std::string VideoWriter::notInstalledMessage() {
  return "video output needs the ffmpeg program, which is not on PATH; install it "
         "(Debian: apt-get install ffmpeg) or write PNG frames instead";
}

Result<std::unique_ptr<VideoWriter>> VideoWriter::open(const std::string& path, std::uint32_t width,
                                                        std::uint32_t height, const VideoOptions& o) {
  if (!available(o.ffmpeg)) return Problem{kVideoProblem, 0, notInstalledMessage()};
  if (width == 0 || height == 0) return Problem{kVideoProblem, 0, "frame size must not be zero"};
  if (!(o.fps > 0)) return Problem{kVideoProblem, 0, "fps must be positive"};
  std::unique_ptr<VideoWriter> v(new VideoWriter());
  v->path_ = path;
  v->logPath_ = path + ".ffmpeg.log";
  v->width_ = width;
  v->height_ = height;

  const std::string size = std::to_string(width) + "x" + std::to_string(height);
  const std::string fps = std::to_string(o.fps), crf = std::to_string(o.crf);
  // Arguments go straight to exec (no shell), so any path is safe.
  std::vector<std::string> args = {o.ffmpeg, "-hide_banner", "-loglevel", "error", "-y",
                                   "-f", "rawvideo", "-pix_fmt", "rgba", "-s", size, "-r", fps,
                                   "-i", "-", "-vf", "pad=ceil(iw/2)*2:ceil(ih/2)*2",
                                   "-c:v", "libx264", "-preset", o.preset, "-crf", crf,
                                   "-pix_fmt", "yuv420p", path};
  std::vector<char*> argv;
  for (auto& a : args) argv.push_back(a.data());
  argv.push_back(nullptr);

  // ffmpeg's messages go to a log beside the video; opening it here also
  // finds an output directory that is missing or read-only.
  const int log = ::open(v->logPath_.c_str(), O_WRONLY | O_CREAT | O_TRUNC | O_CLOEXEC, 0644);
  if (log < 0) {
    return Problem{kVideoProblem, 0, "cannot write " + v->logPath_ + " (" + std::strerror(errno) +
                                         "): is the video's directory there and writable?"};
  }
  int fds[2];
  if (::pipe2(fds, O_CLOEXEC) != 0) {
    ::close(log);
    return Problem{kVideoProblem, 0, std::string("pipe: ") + std::strerror(errno)};
  }
  posix_spawn_file_actions_t fa;
  posix_spawn_file_actions_init(&fa);
  posix_spawn_file_actions_adddup2(&fa, fds[0], STDIN_FILENO);
  posix_spawn_file_actions_addopen(&fa, STDOUT_FILENO, "/dev/null", O_WRONLY, 0);
  posix_spawn_file_actions_adddup2(&fa, log, STDERR_FILENO);
  pid_t pid = -1;
  const int rc = posix_spawnp(&pid, o.ffmpeg.c_str(), &fa, nullptr, argv.data(), environ);
  posix_spawn_file_actions_destroy(&fa);
  ::close(fds[0]);
  ::close(log);
  if (rc != 0) {
    ::close(fds[1]);
    return Problem{kVideoProblem, 0, "cannot start " + o.ffmpeg + ": " + std::strerror(rc)};
  }
  v->fd_ = fds[1];
  v->pid_ = pid;
  return v;
}

Status VideoWriter::write(const render::Image& frame) {
  const auto fail = [](std::string m) { return Problem{kVideoProblem, 0, std::move(m)}; };
  if (fd_ < 0) return fail("video " + path_ + ": already finished");
  if (frame.width != width_ || frame.height != height_ || frame.rgba.size() != std::size_t(width_) * height_ * 4) {
    return fail("video " + path_ + ": frame is " + std::to_string(frame.width) + "x" + std::to_string(frame.height) +
                ", the video is " + std::to_string(width_) + "x" + std::to_string(height_));
  }
  int err = 0;
  if (!writeAll(fd_, frame.rgba.data(), frame.rgba.size(), err)) {
    const Status why = finish();
    return fail("video " + path_ + ": ffmpeg stopped reading (" + std::strerror(err) + ")" +
                (why ? "" : "; " + why.problems().front().message));
  }
  ++frames_;
  return {};
}

Status VideoWriter::finish() {
  if (finished_) return {};
  finished_ = true;
  if (fd_ >= 0) ::close(fd_);
  fd_ = -1;
  int status = 0;
  while (::waitpid(pid_, &status, 0) < 0 && errno == EINTR) {
  }
  if (WIFEXITED(status) && WEXITSTATUS(status) == 0) {
    std::remove(logPath_.c_str());
    return {};
  }
  const std::string how = WIFEXITED(status) ? "exit status " + std::to_string(WEXITSTATUS(status))
                                            : "signal " + std::to_string(WTERMSIG(status));
  return Problem{kVideoProblem, 0,
                 "ffmpeg failed writing " + path_ + " (" + how + "): " + tail(logPath_, 600) + " (full log: " +
                     logPath_ + ")"};
}

VideoWriter::~VideoWriter() { (void)finish(); }

}  // namespace sandtable::viewer
