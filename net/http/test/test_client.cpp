// The HTTP range client (client.h) against a real nginx on loopback serving
// ../shared/data: every byte read equals the file on disk (pread, an
// independent path); the cache and keep-alive cut requests and
// connections; many threads at once; and the failures a user meets, each a
// clear error: a missing file, a server that stops (and comes back), and,
// from a small server of the test's own on loopback, a server that ignores
// Range, one that cuts the body short and one that answers another range.
#include <arpa/inet.h>
#include <fcntl.h>
#include <gtest/gtest.h>
#include <netinet/in.h>
#include <poll.h>
#include <sys/socket.h>
#include <unistd.h>

#include <atomic>
#include <cstdlib>
#include <chrono>
#include <filesystem>
#include <functional>
#include <random>
#include <thread>

#include "sandtable/http/client.h"
#include "sandtable/testing/nginx.h"
#include "sandtable/testing/require.h"

namespace sandtable::http {
namespace {

namespace fs = std::filesystem;

std::string dataDir() { return std::string(SANDTABLE_SOURCE_DIR) + "/../shared/data"; }
const char* kFile = "elevation/srtm/N49E011.hgt.zip";  // 1.2 MB of real SRTM

std::vector<std::byte> preadFile(const std::string& path, std::uint64_t off, std::size_t n) {
  std::vector<std::byte> out(n);
  const int fd = ::open(path.c_str(), O_RDONLY);
  EXPECT_GE(fd, 0) << path;
  EXPECT_EQ(::pread(fd, out.data(), n, off_t(off)), ssize_t(n));
  ::close(fd);
  return out;
}

#define START_NGINX(n)                                                                          \
  SANDTABLE_REQUIRE(fs::exists(dataDir() + "/" + kFile), "../shared/data (" << kFile << ")"); \
  std::string why;                                                                            \
  auto n = testsupport::Nginx::start(dataDir(), 0, why);                                      \
  SANDTABLE_REQUIRE(n != nullptr, "nginx: " << why)

std::shared_ptr<Client> client(ClientOptions o = {}) {
  auto c = Client::create(o);
  EXPECT_TRUE(c.ok()) << c.error();
  return c.value();
}

TEST(HttpClient, everyRangeReadsTheFilesBytes) {
  START_NGINX(nginx);
  const std::string local = dataDir() + "/" + kFile;
  ClientOptions o;
  o.blockBytes = 64 << 10;
  const auto c = client(o);
  const auto f = c->open(nginx->url() + "/" + kFile);
  ASSERT_TRUE(f.ok()) << f.error();
  EXPECT_EQ(f->size, fs::file_size(local));
  EXPECT_FALSE(f->etag.empty());
  std::mt19937_64 rng(7);
  for (int k = 0; k < 200; ++k) {
    // Short and long ranges, across block edges, at both ends of the file.
    const std::uint64_t n = 1 + rng() % (k % 4 == 0 ? 300000 : 5000);
    std::uint64_t off = rng() % (f->size - n + 1);
    if (k == 1) off = 0;
    if (k == 2) off = f->size - n;
    std::vector<std::byte> got(n);
    ASSERT_TRUE(c->read(f.value(), off, got).ok()) << off << " + " << n;
    ASSERT_EQ(got, preadFile(local, off, n)) << "bytes " << off << " + " << n;
  }
}

TEST(HttpClient, theCacheFetchesABlockOnceAndKeepsToItsBound) {
  START_NGINX(nginx);
  ClientOptions o;
  o.blockBytes = 64 << 10;
  o.cacheBytes = 4 * o.blockBytes;
  const auto c = client(o);
  const auto f = c->open(nginx->url() + "/" + kFile);
  ASSERT_TRUE(f.ok()) << f.error();
  std::vector<std::byte> a(1000), b(1000);
  const std::uint64_t before = c->stats().requests;
  ASSERT_TRUE(c->read(f.value(), 100, a).ok());
  ASSERT_TRUE(c->read(f.value(), 3000, b).ok());  // the same block
  EXPECT_EQ(c->stats().requests, before + 1);
  EXPECT_EQ(c->stats().cacheHits, 1u);
  // refresh() drops it: the next read asks the server again.
  c->refresh(f.value(), 100, 1);
  ASSERT_TRUE(c->read(f.value(), 100, a).ok());
  EXPECT_EQ(c->stats().requests, before + 2);
  for (std::uint64_t k = 0; k < 12; ++k) ASSERT_TRUE(c->read(f.value(), k * o.blockBytes, a).ok());
  EXPECT_LE(c->stats().cacheBytes, o.cacheBytes);
  // nginx's own count (its access log, written after it answers; open()'s
  // HEAD included on both sides).
  for (int k = 0; k < 100 && nginx->requests() < c->stats().requests; ++k) {
    std::this_thread::sleep_for(std::chrono::milliseconds(10));
  }
  EXPECT_EQ(nginx->requests(), c->stats().requests);
  EXPECT_EQ(c->stats().requests, 1u + 2u + 11u);  // HEAD, block 0 twice, blocks 1..11 (block 0 still cached)
}

// Single flight: readers of blocks another read is fetching wait for it.
// Claiming a block and finding it cached happen under one lock, so
// however the threads interleave, the range is asked for once.
TEST(HttpClient, blocksBeingFetchedAreWaitedForNotAskedAgain) {
  START_NGINX(nginx);
  const std::string local = dataDir() + "/" + kFile;
  ClientOptions o;
  o.blockBytes = 64 << 10;
  const auto c = client(o);
  const auto f = c->open(nginx->url() + "/" + kFile);
  ASSERT_TRUE(f.ok()) << f.error();
  const std::uint64_t off = 123456, n = 1u << 20;
  const auto want = preadFile(local, off, n);
  std::atomic<int> bad{0}, ready{0};
  std::vector<std::thread> threads;
  for (int t = 0; t < 8; ++t) {
    threads.emplace_back([&] {
      ++ready;
      while (ready.load() < 8) std::this_thread::yield();
      std::vector<std::byte> got(n);
      if (!c->read(f.value(), off, got).ok() || got != want) ++bad;
    });
  }
  for (auto& t : threads) t.join();
  EXPECT_EQ(bad.load(), 0);
  EXPECT_EQ(c->stats().requests, 1u + 1u);  // HEAD, then the range once
  EXPECT_EQ(c->stats().bytesFetched, (off + n + o.blockBytes - 1) / o.blockBytes * o.blockBytes - off / o.blockBytes * o.blockBytes);
}

// A prefetch of several runs is one request (Range: bytes=A-B,C-D,...,
// answered multipart/byteranges by nginx); the reads after it are cache
// hits with the file's bytes.
TEST(HttpClient, aPrefetchOfSeveralRangesIsOneRequest) {
  START_NGINX(nginx);
  const std::string local = dataDir() + "/" + kFile;
  ClientOptions o;
  o.blockBytes = 64 << 10;
  const auto c = client(o);
  const auto f = c->open(nginx->url() + "/" + kFile);
  ASSERT_TRUE(f.ok()) << f.error();
  const std::vector<std::pair<std::uint64_t, std::uint64_t>> ranges = {
      {10, 5000}, {300000, 300100}, {700000, 900000}, {f->size - 7, f->size}};
  ASSERT_TRUE(c->prefetch(f.value(), ranges).ok());
  EXPECT_EQ(c->stats().requests, 1u + 1u);  // HEAD, then the four runs at once
  EXPECT_EQ(c->stats().multiRangeRequests, 1u);
  for (const auto& [a, e] : ranges) {
    std::vector<std::byte> got(e - a);
    ASSERT_TRUE(c->read(f.value(), a, got).ok());
    EXPECT_EQ(got, preadFile(local, a, e - a)) << a;
  }
  ASSERT_TRUE(c->prefetch(f.value(), ranges).ok());  // all cached: nothing asked
  EXPECT_EQ(c->stats().requests, 2u);
  for (int k = 0; k < 100 && nginx->requests() < 2; ++k) std::this_thread::sleep_for(std::chrono::milliseconds(10));
  const auto served = nginx->served("/" + std::string(kFile));
  EXPECT_EQ(served.ranges, 1u);
}

TEST(HttpClient, connectionsAreKeptAliveAcrossRequestsAndThreads) {
  START_NGINX(nginx);
  const std::string local = dataDir() + "/" + kFile;
  ClientOptions o;
  o.cacheBytes = 0;
  o.connections = 3;
  const auto c = client(o);
  const auto f = c->open(nginx->url() + "/" + kFile);
  ASSERT_TRUE(f.ok()) << f.error();
  std::atomic<int> bad{0};
  std::vector<std::thread> threads;
  for (int t = 0; t < 6; ++t) {
    threads.emplace_back([&, t] {
      std::mt19937_64 rng(t);
      for (int k = 0; k < 40; ++k) {
        const std::uint64_t n = 1 + rng() % 20000, off = rng() % (f->size - n);
        std::vector<std::byte> got(n);
        if (!c->read(f.value(), off, got).ok() || got != preadFile(local, off, n)) ++bad;
      }
    });
  }
  for (auto& t : threads) t.join();
  EXPECT_EQ(bad.load(), 0);
  const ClientStats s = c->stats();
  EXPECT_EQ(s.requests, 1u + 240u);
  EXPECT_LE(s.connectionsOpened, o.connections + 1u) << "a connection per request: keep-alive is not working";
  EXPECT_GT(s.rttSeconds, 0);
}

TEST(HttpClient, aMissingFileAndAReadPastTheEndAreClearErrors) {
  START_NGINX(nginx);
  const auto c = client();
  const std::string url = nginx->url() + "/elevation/no-such-file.hgt";
  const auto missing = c->open(url);
  ASSERT_FALSE(missing.ok());
  EXPECT_EQ(missing.problems()[0].file, url);
  EXPECT_NE(missing.error().find("not found (HTTP 404)"), std::string::npos) << missing.error();
  EXPECT_FALSE(c->get(url, 1000).ok());
  const auto f = c->open(nginx->url() + "/" + kFile);
  ASSERT_TRUE(f.ok()) << f.error();
  std::vector<std::byte> out(10);
  const Status past = c->read(f.value(), f->size - 5, out);
  ASSERT_FALSE(past.ok());
  EXPECT_NE(past.error().find("past the end"), std::string::npos) << past.error();
  EXPECT_EQ(past.problems()[0].offset, f->size - 5);
  // get() caps before it allocates.
  const auto big = c->get(nginx->url() + "/" + kFile, 1000);
  ASSERT_FALSE(big.ok());
  EXPECT_NE(big.error().find("longer than the 1000 bytes"), std::string::npos) << big.error();
  const std::string provenance = fs::path("../shared/data/PROVENANCE.md").filename().string();  // served at the root
  const auto small = c->get(nginx->url() + "/" + provenance, 1 << 20);
  ASSERT_TRUE(small.ok()) << small.error();
  EXPECT_EQ(small->size(), fs::file_size(dataDir() + "/" + provenance));
}

TEST(HttpClient, aServerThatStopsIsAnErrorAndReadsRecoverWhenItReturns) {
  START_NGINX(nginx);
  ClientOptions o;
  o.cacheBytes = 0;
  o.retries = 1;
  o.connectTimeoutSeconds = 2;
  const auto c = client(o);
  const auto f = c->open(nginx->url() + "/" + kFile);
  ASSERT_TRUE(f.ok()) << f.error();
  std::vector<std::byte> out(4096);
  ASSERT_TRUE(c->read(f.value(), 0, out).ok());
  nginx->stop();
  const Status down = c->read(f.value(), 0, out);
  ASSERT_FALSE(down.ok());
  EXPECT_EQ(down.problems()[0].file, f->url);
  EXPECT_GE(c->stats().retries, 1u);
  ASSERT_TRUE(nginx->restart(why)) << why;
  EXPECT_TRUE(c->read(f.value(), 0, out).ok());
  EXPECT_EQ(out, preadFile(dataDir() + "/" + kFile, 0, out.size()));
}

TEST(HttpClient, httpsWithHttp2ReadsTheSameBytesAndAnUntrustedCertificateIsRefused) {
  SANDTABLE_REQUIRE(fs::exists(dataDir() + "/" + kFile), "../shared/data (" << kFile << ")");
  // A certificate for 127.0.0.1 made here (openssl), trusted through caFile.
  const fs::path tmp = fs::temp_directory_path() / ("sandtable-tls-" + std::to_string(::getpid()));
  fs::create_directories(tmp);
  const std::string cert = (tmp / "cert.pem").string(), key = (tmp / "key.pem").string();
  const std::string cmd = "openssl req -x509 -newkey rsa:2048 -nodes -keyout " + key + " -out " + cert +
                          " -days 2 -subj /CN=127.0.0.1 -addext subjectAltName=IP:127.0.0.1 >/dev/null 2>&1";
  SANDTABLE_REQUIRE(std::system(cmd.c_str()) == 0 && fs::exists(cert), "openssl (to make a test certificate)");
  std::string why;
  auto nginx = testsupport::Nginx::startTls(dataDir(), cert, key, why);
  SANDTABLE_REQUIRE(nginx != nullptr, "nginx with TLS: " << why);
  ASSERT_EQ(nginx->url().rfind("https://", 0), 0u);
  ClientOptions o;
  o.caFile = cert;
  const auto c = client(o);
  const auto f = c->open(nginx->url() + "/" + kFile);
  ASSERT_TRUE(f.ok()) << f.error();
  std::vector<std::byte> got(100000);
  ASSERT_TRUE(c->read(f.value(), 12345, got).ok());
  EXPECT_EQ(got, preadFile(dataDir() + "/" + kFile, 12345, got.size()));
  EXPECT_EQ(c->stats().http2Responses, c->stats().requests) << "the server offers HTTP/2 over TLS";
  // Without the certificate: refused, and said why.
  const auto plain = client();
  const auto untrusted = plain->open(nginx->url() + "/" + kFile);
  ASSERT_FALSE(untrusted.ok());
  EXPECT_EQ(plain->stats().retries, 0u) << "not a transient failure";
  EXPECT_NE(untrusted.error().find("certificate"), std::string::npos) << untrusted.error();
  fs::remove_all(tmp);
}

// ------------------------------------------------- a misbehaving server

/// A loopback server that answers each request with `answer(request)` and
/// closes the connection; at most `limit` connections, each wait bounded.
class BadServer {
 public:
  BadServer(std::function<std::string(const std::string&)> answer, int limit) : answer_(std::move(answer)) {
    fd_ = ::socket(AF_INET, SOCK_STREAM, 0);
    sockaddr_in a{};
    a.sin_family = AF_INET;
    a.sin_addr.s_addr = htonl(INADDR_LOOPBACK);
    socklen_t len = sizeof a;
    EXPECT_EQ(::bind(fd_, reinterpret_cast<sockaddr*>(&a), sizeof a), 0);
    EXPECT_EQ(::listen(fd_, 8), 0);
    ::getsockname(fd_, reinterpret_cast<sockaddr*>(&a), &len);
    port_ = ntohs(a.sin_port);
    thread_ = std::thread([this, limit] {
      for (int k = 0; k < limit && !stop_; ++k) {
        pollfd p{fd_, POLLIN, 0};
        if (::poll(&p, 1, 200) <= 0) {
          --k;  // a timeout is not a connection; stop_ ends the loop
          continue;
        }
        const int s = ::accept(fd_, nullptr, nullptr);
        if (s < 0) continue;
        std::string req;
        char buf[4096];
        while (req.find("\r\n\r\n") == std::string::npos) {
          pollfd q{s, POLLIN, 0};
          if (::poll(&q, 1, 2000) <= 0) break;
          const ssize_t r = ::recv(s, buf, sizeof buf, 0);
          if (r <= 0) break;
          req.append(buf, std::size_t(r));
        }
        const std::string out = answer_(req);
        ::send(s, out.data(), out.size(), MSG_NOSIGNAL);
        ::close(s);
      }
    });
  }
  ~BadServer() {
    stop_ = true;
    thread_.join();
    ::close(fd_);
  }
  std::string url() const { return "http://127.0.0.1:" + std::to_string(port_) + "/f.bin"; }

 private:
  std::function<std::string(const std::string&)> answer_;
  int fd_ = -1;
  std::uint16_t port_ = 0;
  std::atomic<bool> stop_{false};
  std::thread thread_;
};

RemoteFile thousandBytes(const std::string& url) {
  RemoteFile f;
  f.url = url;
  f.size = 1000;
  return f;
}

ClientOptions quick() {
  ClientOptions o;
  o.cacheBytes = 0;
  o.retries = 2;
  o.retryPauseSeconds = 0.01;
  o.timeoutSeconds = 5;
  return o;
}

TEST(HttpClient, aServerIgnoringRangeIsRefused) {
  BadServer s([](const std::string&) { return "HTTP/1.1 200 OK\r\nContent-Length: 1000\r\n\r\n" + std::string(1000, 'x'); }, 4);
  const auto c = client(quick());
  std::vector<std::byte> out(100);
  const Status st = c->read(thousandBytes(s.url()), 0, out);
  ASSERT_FALSE(st.ok());
  EXPECT_NE(st.error().find("ignored the Range request"), std::string::npos) << st.error();
}

TEST(HttpClient, aBodyCutShortIsRetriedThenReportedAsTruncated) {
  std::atomic<int> served{0};
  BadServer s(
      [&](const std::string&) {
        ++served;
        return "HTTP/1.1 206 Partial Content\r\nContent-Range: bytes 0-99/1000\r\nContent-Length: 100\r\n\r\n" +
               std::string(40, 'x');
      },
      8);
  const auto c = client(quick());
  std::vector<std::byte> out(100);
  const Status st = c->read(thousandBytes(s.url()), 0, out);
  ASSERT_FALSE(st.ok());
  EXPECT_NE(st.error().find("truncated"), std::string::npos) << st.error();
  EXPECT_EQ(served.load(), 3);  // the first try and two retries
  EXPECT_EQ(c->stats().retries, 2u);
}

TEST(HttpClient, anotherRangeOrAnotherSizeIsRefused) {
  BadServer other([](const std::string&) {
    return "HTTP/1.1 206 Partial Content\r\nContent-Range: bytes 100-199/1000\r\nContent-Length: 100\r\n\r\n" +
           std::string(100, 'x');
  }, 4);
  const auto c = client(quick());
  std::vector<std::byte> out(100);
  const Status wrong = c->read(thousandBytes(other.url()), 0, out);
  ASSERT_FALSE(wrong.ok());
  EXPECT_NE(wrong.error().find("not the range asked"), std::string::npos) << wrong.error();
  BadServer grown([](const std::string&) {
    return "HTTP/1.1 206 Partial Content\r\nContent-Range: bytes 0-99/2000\r\nContent-Length: 100\r\n\r\n" +
           std::string(100, 'x');
  }, 4);
  const Status changed = c->read(thousandBytes(grown.url()), 0, out);
  ASSERT_FALSE(changed.ok());
  EXPECT_NE(changed.error().find("changed on the server"), std::string::npos) << changed.error();
}

TEST(HttpClient, optionsOutOfRangeNameTheirField) {
  ClientOptions o;
  o.blockBytes = 1000;
  const auto c = Client::create(o);
  ASSERT_FALSE(c.ok());
  EXPECT_NE(c.error().find("ClientOptions::blockBytes"), std::string::npos);
  EXPECT_TRUE(isUrl("https://example.org/db"));
  EXPECT_FALSE(isUrl("/data/db"));
}

// A server that answers a request for several ranges with the first one
// only: the client asks one run at a time from then on, and the bytes are
// right.
TEST(HttpClient, aServerThatAnswersOneRangeOfSeveralIsAskedOneByOne) {
  std::string content(20000, ' ');
  for (std::size_t k = 0; k < content.size(); ++k) content[k] = char('a' + k % 26);
  BadServer s(
      [&](const std::string& req) {
        unsigned long long a = 0, b = 0;
        const auto at = req.find("Range: bytes=");
        if (at == std::string::npos || std::sscanf(req.c_str() + at, "Range: bytes=%llu-%llu", &a, &b) != 2) {
          return std::string("HTTP/1.1 400 Bad Request\r\nContent-Length: 0\r\n\r\n");
        }
        return "HTTP/1.1 206 Partial Content\r\nContent-Range: bytes " + std::to_string(a) + "-" + std::to_string(b) +
               "/20000\r\nContent-Length: " + std::to_string(b - a + 1) + "\r\n\r\n" + content.substr(a, b - a + 1);
      },
      3);
  ClientOptions o = quick();
  o.blockBytes = 4096;
  o.cacheBytes = 1 << 20;
  const auto c = client(o);
  RemoteFile f;
  f.url = s.url();
  f.size = content.size();
  const std::vector<std::pair<std::uint64_t, std::uint64_t>> ranges = {{0, 100}, {10000, 10100}};
  ASSERT_TRUE(c->prefetch(f, ranges).ok());
  EXPECT_EQ(c->stats().multiRangeRequests, 0u);
  EXPECT_EQ(c->stats().requests, 3u);  // the one for both, then one each
  std::vector<std::byte> got(101);
  ASSERT_TRUE(c->read(f, 10000, got).ok());
  EXPECT_EQ(std::string(reinterpret_cast<const char*>(got.data()), got.size()), content.substr(10000, 101));
  EXPECT_EQ(c->stats().requests, 3u);  // from the cache
}

}  // namespace
}  // namespace sandtable::http
