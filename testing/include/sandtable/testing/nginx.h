#pragma once
// Test helper: a private nginx (Debian's nginx-light) serving a directory
// on a loopback port, for the HTTP tests (docs/HTTP.md). One process
// (master_process off), as the invoking user, its config, logs and temp
// files in a directory of its own; stopped by the destructor.
//
// Thread safety: one owner; start() and stop() from the test's thread.
#include <sys/types.h>

#include <cstdint>
#include <memory>
#include <string>

namespace sandtable::testsupport {

class Nginx {
 public:
  /// Serves `root` on 127.0.0.1:`port` (0: a free port picked here). Null,
  /// with `why` set, when nginx is not installed or does not come up within
  /// 5 s.
  static std::unique_ptr<Nginx> start(const std::string& root, std::uint16_t port, std::string& why);
  /// The same over TLS with HTTP/2 (`listen ... ssl http2`), with this
  /// PEM certificate and key; url() is then https://.
  static std::unique_ptr<Nginx> startTls(const std::string& root, const std::string& certFile, const std::string& keyFile,
                                         std::string& why);
  ~Nginx();

  /// Stops the server (the port is free again); start() it again with
  /// restart().
  void stop();
  /// The same root and port again after stop(); false when it does not come up.
  bool restart(std::string& why);

  std::uint16_t port() const { return port_; }
  /// "http://127.0.0.1:PORT" (https:// over TLS).
  std::string url() const;
  /// Requests nginx logged so far (its access log's lines).
  std::uint64_t requests() const;
  /// What the access log says was served for `path` (e.g. "/db/grid.stg"):
  /// requests, of them 206 (a range) and 200 with a body (the whole
  /// file), and body bytes sent.
  struct Served {
    std::uint64_t requests = 0, ranges = 0, whole = 0, bytes = 0;
  };
  Served served(const std::string& path) const;

 private:
  Nginx() = default;
  /// Makes its directory, then launch().
  bool begin(std::string& why);
  bool launch(std::string& why);

  std::string root_, dir_, cert_, key_;
  std::uint16_t port_ = 0;
  pid_t pid_ = -1;
};

}  // namespace sandtable::testsupport
