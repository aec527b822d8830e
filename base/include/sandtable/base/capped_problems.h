#pragma once
// Problems collected up to a cap per kind, so that a badly damaged file
// gives a readable report: the first `cap` problems of each kind are kept,
// the rest only counted and summed up in one line per kind,
// "STAGE: N more KIND problems not listed". The validators of the grid,
// the pack and the module checks share it.
//
// Thread safety: a value type; one object from one thread at a time.
#include <cstdint>
#include <functional>
#include <map>
#include <string>
#include <type_traits>
#include <utility>

#include "sandtable/base/result.h"

namespace sandtable {

/// `Kind` orders the summary lines (std::string: alphabetical; an enum:
/// its declaration order).
template <typename Kind = std::string>
class CappedProblems {
 public:
  /// `cap` problems of each kind are kept; 0 keeps every problem.
  explicit CappedProblems(std::uint64_t cap) : cap_(cap) {}

  /// Counts one problem of `kind`; true when it is to be kept, so a caller
  /// formats the message only then. `file` names the kind's summary line
  /// (the file of its first problem).
  bool want(const Kind& kind, const std::string& file = {}) {
    Count& c = counts_[kind];
    if (c.n++ == 0) c.file = file;
    return cap_ == 0 || c.n <= cap_;
  }
  /// Counts `p` and keeps it within the cap.
  void add(const Kind& kind, Problem p) {
    if (want(kind, p.file)) kept_.add(std::move(p));
  }
  void add(const Kind& kind, const Status& st) {
    for (const Problem& p : st.problems()) add(kind, p);
  }

  /// Appends one line per kind over the cap to `out`, in Kind order, at
  /// `offset`; `name` spells a kind (a string kind is its own name).
  void appendSummary(Status& out, const std::string& stage, std::uint64_t offset = 0,
                     const std::function<std::string(const Kind&)>& name = {}) const {
    for (const auto& [kind, c] : counts_) {
      if (cap_ == 0 || c.n <= cap_) continue;
      std::string kindName;
      if (name) kindName = name(kind);
      else if constexpr (std::is_convertible_v<Kind, std::string>) kindName = kind;
      out.add({c.file, offset, stage + ": " + std::to_string(c.n - cap_) + " more " + kindName + " problems not listed"});
    }
  }

  /// The kept problems, then the summary lines (at offset 0).
  Status take(const std::string& stage) {
    appendSummary(kept_, stage);
    return std::move(kept_);
  }

 private:
  struct Count {
    std::uint64_t n = 0;
    std::string file;
  };
  std::uint64_t cap_;
  Status kept_;
  std::map<Kind, Count> counts_;
};

}  // namespace sandtable
