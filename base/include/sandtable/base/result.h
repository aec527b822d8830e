#pragma once
// Result<T>: a value or a list of errors, with warnings carried beside
// either (as cesium-native's ErrorList does). Status is Result<void>.
// Readers return it instead of throwing, so hostile bytes never unwind
// through callers, and a library never prints: the caller decides where
// errors and warnings go.
//
// Messages name the stage that found the problem and, for options, the
// option *field* ("ElevationOptions::spacing"), never a CLI flag; the CLI
// maps fields to flags.
//
// Thread safety: a value type; distinct objects may be used from any
// threads, one object from one thread at a time.
#include <cstdint>
#include <optional>
#include <string>
#include <utility>
#include <vector>

namespace sandtable {

/// One problem found in a file: where it is and what is wrong.
struct Problem {
  std::string file;        ///< path as given by the caller
  std::uint64_t offset = 0;///< byte offset in that file (0 when not byte-specific)
  std::string message;     ///< starts with the stage that found it

  /// "file @offset: message", the form every tool prints.
  /// "FILE @OFFSET: MESSAGE"; the message alone when there is no file or
  /// place to name (an option's value, a computed result).
  std::string str() const {
    if (file.empty() && offset == 0) return message;
    return file + " @" + std::to_string(offset) + ": " + message;
  }
};

/// Things that did not stop the work but that a user must see: dropped,
/// repaired or defaulted input.
using Warnings = std::vector<Problem>;

namespace detail {

/// What Result<T> and Status share: errors and warnings.
class Outcome {
 public:
  const std::vector<Problem>& problems() const { return problems_; }
  const Warnings& warnings() const { return warnings_; }
  void addWarning(Problem p) { warnings_.push_back(std::move(p)); }
  void addWarnings(const Warnings& w) { warnings_.insert(warnings_.end(), w.begin(), w.end()); }
  /// First problem as a printable line, or "" when there is none.
  std::string error() const { return problems_.empty() ? std::string() : problems_.front().str(); }
  /// First problem's message alone (no file, no offset), or "": for a
  /// caller that wraps a lower layer's words in its own.
  std::string message() const { return problems_.empty() ? std::string() : problems_.front().message; }

 protected:
  std::vector<Problem> problems_;
  Warnings warnings_;
};

}  // namespace detail

template <typename T>
class Result : public detail::Outcome {
 public:
  Result(T value) : value_(std::move(value)) {}
  Result(Problem p) { problems_.push_back(std::move(p)); }
  /// An error result; an empty list still makes a failed result, with a
  /// problem that says so, so that ok() and problems() never disagree.
  Result(std::vector<Problem> ps) {
    problems_ = std::move(ps);
    if (problems_.empty()) problems_.push_back({"", 0, "internal: failed result without a problem"});
  }

  bool ok() const { return value_.has_value(); }
  explicit operator bool() const { return ok(); }
  T& value() { return *value_; }
  const T& value() const { return *value_; }
  T* operator->() { return &*value_; }
  const T* operator->() const { return &*value_; }

 private:
  std::optional<T> value_;
};

/// Success, or the problems that stopped the work. Validators return one
/// Status holding every finding.
template <>
class Result<void> : public detail::Outcome {
 public:
  Result() = default;
  Result(Problem p) { problems_.push_back(std::move(p)); }
  /// Every problem in `ps`; an empty list is success.
  Result(std::vector<Problem> ps) { problems_ = std::move(ps); }

  bool ok() const { return problems_.empty(); }
  explicit operator bool() const { return ok(); }
  void add(Problem p) { problems_.push_back(std::move(p)); }
  void add(const std::vector<Problem>& ps) { problems_.insert(problems_.end(), ps.begin(), ps.end()); }
  /// Another outcome's problems and warnings, appended (validators that
  /// run sub-validators).
  void merge(const detail::Outcome& o) {
    add(o.problems());
    addWarnings(o.warnings());
  }
};

using Status = Result<void>;

}  // namespace sandtable
