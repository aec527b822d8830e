#pragma once
// An HTTP(S) client for reading files by byte range (docs/HTTP.md): the
// transport a database served by a web server is paged over (issue 38).
// libcurl underneath: a pool of easy handles, each keeping its connection
// alive (HTTP/1.1 keep-alive, HTTP/2 where a TLS server offers it); a
// bounded in-memory cache of fixed-size blocks, so a module record read
// twice is fetched once. What a read returns is exactly the server's bytes
// of that range or an error: every response is checked (206 with the
// asked Content-Range, the file's size and ETag unchanged since open(),
// the body as long as asked); the caller's own checksums (the pack's
// record CRCs) judge the content, and refresh() drops what they refuse.
//
// Errors are Problem{url, offset, message}: 404 and other 4xx at once;
// transient failures (no connection, a timeout, 5xx, a short or overlong
// body) retried `retries` times with a doubling pause, then reported
// with the last cause.
//
// Thread contract: a Client is shared (shared_ptr) and every member may be
// called from any thread at once; at most `connections` transfers run at
// a time (the others wait for a handle). RemoteFile is a plain value.
#include <cstddef>
#include <cstdint>
#include <memory>
#include <span>
#include <string>
#include <string_view>
#include <utility>
#include <vector>

#include "sandtable/base/result.h"

namespace sandtable::http {

/// True for an http:// or https:// URL (what the tools take instead of a path).
bool isUrl(std::string_view s);

struct ClientOptions {
  std::uint32_t connections = 4;         ///< transfers at once, each handle keeping its connection
  double connectTimeoutSeconds = 5;      ///< to open a connection
  double timeoutSeconds = 30;            ///< a whole request
  std::uint32_t retries = 2;             ///< tries after the first, for transient failures
  double retryPauseSeconds = 0.05;       ///< before the first retry; doubled each time
  std::uint64_t cacheBytes = 256ull << 20;  ///< the block cache's bound (0: no cache)
  std::uint32_t blockBytes = 64u << 10;     ///< cache block size (a power of two, 4 KiB .. 16 MiB)
  /// PEM certificates to trust for https:// instead of the system's (a
  /// site's own CA); empty: the system's store.
  std::string caFile;
};

/// A file on a server, as open() found it.
struct RemoteFile {
  std::string url;
  std::uint64_t size = 0;
  std::string etag;  ///< empty when the server sends none
};

struct ClientStats {
  std::uint64_t requests = 0;           ///< HTTP requests made (retries included)
  std::uint64_t bytesFetched = 0;       ///< response bodies received
  std::uint64_t connectionsOpened = 0;  ///< new connections (keep-alive keeps this low)
  std::uint64_t cacheHits = 0, cacheMisses = 0;  ///< blocks
  std::uint64_t cacheBytes = 0;         ///< held now
  std::uint64_t retries = 0;            ///< requests repeated after a transient failure
  std::uint64_t failures = 0;           ///< reads and opens that returned an error
  std::uint64_t http2Responses = 0;     ///< responses that came over HTTP/2
  std::uint64_t multiRangeRequests = 0; ///< prefetch requests answered with several ranges at once
  double rttSeconds = 0;                ///< time to the first byte, smoothed over requests (0: none yet)
};

class Client {
 public:
  /// Problems: options out of range (named by field, ClientOptions::...).
  static Result<std::shared_ptr<Client>> create(const ClientOptions& options = {});
  ~Client();
  Client(const Client&) = delete;
  Client& operator=(const Client&) = delete;

  /// The file's size and ETag (a HEAD request). Problems: not found, not
  /// a file the server can serve by ranges, unreachable.
  Result<RemoteFile> open(const std::string& url) const;
  /// Bytes [offset, offset + out.size()) of `f` into `out`, through the
  /// cache. Problems: past the end, the file changed on the server since
  /// open() (size or ETag), a bad response; `out` is then unspecified.
  Status read(const RemoteFile& f, std::uint64_t offset, std::span<std::byte> out) const;
  /// Drops the cached blocks over [offset, offset + n) of `f`, so the next
  /// read fetches them again (a record whose checksum failed).
  void refresh(const RemoteFile& f, std::uint64_t offset, std::uint64_t n) const;
  /// Brings the blocks over `ranges` ([offset, end) each) into the cache in
  /// one request: every run of missing blocks is one range of a request
  /// for several (`Range: bytes=A-B,C-D`, answered multipart/byteranges).
  /// A server that answers otherwise is asked one run at a time from then
  /// on. Blocks cached or being fetched are left alone; the caller's reads
  /// wait for the ones this fetches (single flight). Nothing without a
  /// cache.
  Status prefetch(const RemoteFile& f, std::span<const std::pair<std::uint64_t, std::uint64_t>> ranges) const;
  /// A whole small file (a manifest, an index), refused before any
  /// allocation when it is longer than `maxBytes`.
  Result<std::vector<std::byte>> get(const std::string& url, std::uint64_t maxBytes) const;

  ClientStats stats() const;
  const ClientOptions& options() const;

 private:
  struct Impl;
  explicit Client(std::unique_ptr<Impl> impl);
  std::unique_ptr<Impl> impl_;
};

}  // namespace sandtable::http
