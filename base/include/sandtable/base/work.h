#pragma once
// Progress and cancellation for long checks: validateDatabase and the
// validators it runs (validateGrid, validatePack). A default Work reports
// nothing and never stops.
//
// Thread safety: the validators call `progress` on the caller's thread;
// `cancel` may be set from any thread or a signal handler.
#include <atomic>
#include <functional>
#include <string>

namespace sandtable {

struct Work {
  /// The fraction in [0, 1] of the named stage that is done.
  std::function<void(double fraction, const std::string& stage)> progress;
  /// Polled between blocks, records and modules: once it reads true the
  /// check stops and its problems end with kCancelledMessage.
  const std::atomic<bool>* cancel = nullptr;

  bool cancelled() const { return cancel && cancel->load(std::memory_order_relaxed); }
  void report(double fraction, const char* stage) const {
    if (progress) progress(fraction, stage);
  }
};

/// The message of the last problem of a cancelled check (at offset 0 of
/// the file being checked).
inline constexpr const char* kCancelledMessage = "validate: cancelled before the end; the check is incomplete";

}  // namespace sandtable
