#include "progress.h"

#include <unistd.h>

#include <algorithm>
#include <cmath>

namespace sandtable::cli {

Progress::Progress(bool quiet)
    : quiet_(quiet), tty_(::isatty(STDERR_FILENO) == 1), start_(std::chrono::steady_clock::now()) {}

Progress::~Progress() { done(); }

void Progress::update(double fraction, const std::string& stage, const std::string& detail) {
  if (quiet_) return;
  std::lock_guard lock(mutex_);
  fraction = std::clamp(fraction, 0.0, 1.0);
  const auto now = std::chrono::steady_clock::now();
  const double elapsed = std::chrono::duration<double>(now - start_).count();
  if (tty_) {
    if (open_ && stage == lastStage_ && fraction < 1.0 && now - lastDraw_ < std::chrono::milliseconds(100)) return;
    lastDraw_ = now;
    const int width = 30;
    const int filled = static_cast<int>(std::lround(fraction * width));
    std::string bar(static_cast<std::size_t>(filled), '#');
    bar.resize(width, '.');
    std::fprintf(stderr, "\r%-18.18s [%s] %5.1f%% %6.1fs%s%s\x1b[K", stage.c_str(), bar.c_str(),
                 fraction * 100.0, elapsed, detail.empty() ? "" : "  ", detail.c_str());
    std::fflush(stderr);
    open_ = true;
    lastStage_ = stage;
    return;
  }
  const int step = static_cast<int>(fraction * 4.0);
  if (step == lastStep_ && stage == lastStage_) return;
  lastStep_ = step;
  lastStage_ = stage;
  std::fprintf(stderr, "%s: %3d%% (%.1fs)%s%s\n", stage.c_str(), step * 25, elapsed,
               detail.empty() ? "" : "  ", detail.c_str());
}

void Progress::done() {
  if (quiet_) return;
  std::lock_guard lock(mutex_);
  if (tty_ && open_) std::fprintf(stderr, "\n");
  open_ = false;
}

}  // namespace sandtable::cli
