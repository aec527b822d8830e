#pragma once
// Where a benchmark's running commentary goes. The benchmarks never print:
// they hand each line to `note` and fractions to `progress`, and the caller
// (the CLI) decides whether and how to show them.
//
// Thread safety: `note` is called on the caller's thread, except where a
// benchmark's header says otherwise (bench paging: the pager's loader
// threads log through it too); `progress` may be called from worker
// threads. Both may be empty.
#include <functional>
#include <string>

namespace sandtable::bench {

struct Notes {
  /// One line of commentary, without a prefix or a newline.
  std::function<void(const std::string& line)> note;
  /// The fraction in [0, 1] of the named stage that is done.
  std::function<void(double fraction, const std::string& stage)> progress;

  void say(const std::string& line) const {
    if (note) note(line);
  }
  void report(double fraction, const std::string& stage) const {
    if (progress) progress(fraction, stage);
  }
};

}  // namespace sandtable::bench
