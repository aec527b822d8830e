#pragma once
// Progress for long work: a redrawn bar on a TTY, plain lines otherwise
// (one per 25% step), so logs stay readable.
#include <chrono>
#include <cstdio>
#include <mutex>
#include <string>

namespace sandtable::cli {

class Progress {
 public:
  /// `quiet` suppresses everything (used with --json).
  explicit Progress(bool quiet = false);
  ~Progress();
  /// fraction in [0, 1]; stage names what is running; `detail` (e.g.
  /// "frame 120/900  31 fps  23 s left") follows the bar or the line.
  /// Thread-safe.
  void update(double fraction, const std::string& stage, const std::string& detail = "");
  /// Ends the bar line.
  void done();

 private:
  bool quiet_, tty_;
  int lastStep_ = -1;
  std::string lastStage_;
  bool open_ = false;
  std::chrono::steady_clock::time_point start_, lastDraw_;
  std::mutex mutex_;
};

}  // namespace sandtable::cli
