#pragma once
// Result<T>: a value or a list of errors. Readers return it instead of
// throwing, so hostile bytes never unwind through callers.
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
  std::string str() const {
    return file + " @" + std::to_string(offset) + ": " + message;
  }
};

template <typename T>
class Result {
 public:
  Result(T value) : value_(std::move(value)) {}
  Result(Problem p) { problems_.push_back(std::move(p)); }
  Result(std::vector<Problem> ps) : problems_(std::move(ps)) {}

  bool ok() const { return value_.has_value(); }
  explicit operator bool() const { return ok(); }
  T& value() { return *value_; }
  const T& value() const { return *value_; }
  T* operator->() { return &*value_; }
  const T* operator->() const { return &*value_; }
  const std::vector<Problem>& problems() const { return problems_; }
  /// First problem as a printable line, or "" when ok.
  std::string error() const { return problems_.empty() ? std::string() : problems_.front().str(); }

 private:
  std::optional<T> value_;
  std::vector<Problem> problems_;
};

}  // namespace sandtable
