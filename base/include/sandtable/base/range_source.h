#pragma once
// Bytes read by offset from somewhere that is not a local file descriptor:
// a file on a web server (net/http's RemoteRange), read by the pack reader
// in place of pread (issue 38: load modules paged from a web server).
//
// Thread contract: every member is const and may be called from any
// thread at once.
#include <cstddef>
#include <cstdint>
#include <span>
#include <string>
#include <utility>

#include "sandtable/base/result.h"

namespace sandtable {

class RangeSource {
 public:
  virtual ~RangeSource() = default;
  /// What the bytes are (a URL), for messages.
  virtual const std::string& name() const = 0;
  /// The whole size in bytes.
  virtual std::uint64_t size() const = 0;
  /// Exactly out.size() bytes at `offset` into `out`, or the problem (its
  /// message says why).
  virtual Status read(std::uint64_t offset, std::span<std::byte> out) const = 0;
  /// Forgets anything cached over [offset, offset + n), so the next read
  /// fetches it again: the caller's checksum refused what came.
  virtual void refresh(std::uint64_t /*offset*/, std::uint64_t /*n*/) const {}
  /// Brings [offset, end) of each range closer, so that reads of them soon
  /// are cheap: over HTTP, one request for all of them. A hint: a failure
  /// is the later read's to report. Nothing by default.
  virtual void prefetch(std::span<const std::pair<std::uint64_t, std::uint64_t>> /*ranges*/) const {}
};

}  // namespace sandtable
