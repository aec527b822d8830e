#pragma once
// A file on a web server as a RangeSource (base/range_source.h): what the
// pack reader reads a remote modules.pack through (docs/HTTP.md).
//
// Thread contract: RangeSource's (any thread); the Client is shared.
#include <memory>
#include <string>

#include "sandtable/base/range_source.h"
#include "sandtable/http/client.h"

namespace sandtable::http {

class RemoteRange final : public RangeSource {
 public:
  /// open()s `url` through `client` (its size and ETag).
  static Result<std::shared_ptr<const RemoteRange>> open(std::shared_ptr<const Client> client, const std::string& url);

  const std::string& name() const override { return file_.url; }
  std::uint64_t size() const override { return file_.size; }
  Status read(std::uint64_t offset, std::span<std::byte> out) const override { return client_->read(file_, offset, out); }
  void refresh(std::uint64_t offset, std::uint64_t n) const override { client_->refresh(file_, offset, n); }
  void prefetch(std::span<const std::pair<std::uint64_t, std::uint64_t>> ranges) const override {
    (void)client_->prefetch(file_, ranges);
  }
  const Client& client() const { return *client_; }

 private:
  RemoteRange(std::shared_ptr<const Client> c, RemoteFile f) : client_(std::move(c)), file_(std::move(f)) {}
  std::shared_ptr<const Client> client_;
  RemoteFile file_;
};

}  // namespace sandtable::http
