// The HTTP range client (client.h; docs/HTTP.md).
#include "sandtable/http/client.h"

#include <curl/curl.h>

#include <algorithm>
#include <atomic>
#include <chrono>
#include <condition_variable>
#include <cstring>
#include <list>
#include <mutex>
#include <thread>
#include <unordered_map>
#include <unordered_set>
#include <string_view>

namespace sandtable::http {

namespace {

std::once_flag curlOnce;

/// One transfer's outcome before it is judged.
struct Response {
  CURLcode code = CURLE_OK;
  std::string curlError;
  long status = 0;
  std::vector<std::byte> body;
  bool overlong = false;  ///< more bytes came than the cap allowed
  std::string contentRange, etag, contentType;
  std::uint64_t contentLength = UINT64_MAX;  ///< from the header; UINT64_MAX: none
  double firstByteSeconds = 0;
  long connects = 0;
  long httpVersion = 0;  ///< CURLINFO_HTTP_VERSION
};

struct Sink {
  Response* r = nullptr;
  std::uint64_t cap = 0;
};

std::size_t onBody(char* data, std::size_t size, std::size_t n, void* user) {
  auto* s = static_cast<Sink*>(user);
  const std::size_t bytes = size * n;
  if (s->r->body.size() + bytes > s->cap) {
    s->r->overlong = true;
    return 0;  // aborts the transfer (CURLE_WRITE_ERROR)
  }
  const auto* p = reinterpret_cast<const std::byte*>(data);
  s->r->body.insert(s->r->body.end(), p, p + bytes);
  return bytes;
}

std::string trim(std::string s) {
  while (!s.empty() && (s.back() == '\r' || s.back() == '\n' || s.back() == ' ')) s.pop_back();
  std::size_t k = 0;
  while (k < s.size() && s[k] == ' ') ++k;
  return s.substr(k);
}

std::size_t onHeader(char* data, std::size_t size, std::size_t n, void* user) {
  auto* r = static_cast<Response*>(user);
  const std::string line(data, size * n);
  const std::size_t colon = line.find(':');
  if (line.rfind("HTTP/", 0) == 0) {  // a new response (after a redirect): forget the last one's
    r->contentRange.clear();
    r->etag.clear();
    r->contentType.clear();
    r->contentLength = UINT64_MAX;
  }
  if (colon == std::string::npos) return size * n;
  std::string name = line.substr(0, colon);
  std::transform(name.begin(), name.end(), name.begin(), [](unsigned char c) { return char(std::tolower(c)); });
  const std::string value = trim(line.substr(colon + 1));
  if (name == "content-range") r->contentRange = value;
  if (name == "etag") r->etag = value;
  if (name == "content-type") r->contentType = value;
  if (name == "content-length") {
    char* end = nullptr;
    const unsigned long long v = std::strtoull(value.c_str(), &end, 10);
    if (end && *end == '\0' && !value.empty()) r->contentLength = v;
  }
  return size * n;
}

/// "bytes A-B/T" -> A, B, T (T may be "*": UINT64_MAX).
bool parseContentRange(const std::string& v, std::uint64_t& a, std::uint64_t& b, std::uint64_t& total) {
  unsigned long long x = 0, y = 0, t = 0;
  char star = 0;
  if (std::sscanf(v.c_str(), "bytes %llu-%llu/%llu", &x, &y, &t) == 3) {
    a = x, b = y, total = t;
    return true;
  }
  if (std::sscanf(v.c_str(), "bytes %llu-%llu/%c", &x, &y, &star) == 3 && star == '*') {
    a = x, b = y, total = UINT64_MAX;
    return true;
  }
  return false;
}

/// One part of a multipart/byteranges body: its Content-Range and bytes.
struct BodyPart {
  std::uint64_t first = 0, last = 0, total = 0;
  std::span<const std::byte> bytes;
};

/// The parts of a multipart/byteranges body (RFC 9110, 14.6) whose
/// Content-Type is `type`. False when it is not one or does not parse.
bool parseByteranges(std::span<const std::byte> body, const std::string& type, std::vector<BodyPart>& parts) {
  const std::size_t at = type.find("boundary=");
  if (type.rfind("multipart/byteranges", 0) != 0 || at == std::string::npos) return false;
  std::string boundary = type.substr(at + 9);
  boundary = boundary.substr(0, boundary.find(';'));
  if (boundary.size() >= 2 && boundary.front() == '"' && boundary.back() == '"') boundary = boundary.substr(1, boundary.size() - 2);
  if (boundary.empty()) return false;
  const std::string_view text(reinterpret_cast<const char*>(body.data()), body.size());
  const std::string delimiter = "--" + boundary;
  std::size_t p = text.find(delimiter);
  while (p != std::string_view::npos) {
    p += delimiter.size();
    if (text.substr(p, 2) == "--") return !parts.empty();  // the closing delimiter
    const std::size_t headersEnd = text.find("\r\n\r\n", p);
    if (headersEnd == std::string_view::npos) return false;
    BodyPart part;
    bool ranged = false;
    for (std::size_t line = text.find("\r\n", p); line < headersEnd;) {
      const std::size_t next = text.find("\r\n", line + 2);
      std::string header(text.substr(line + 2, next - line - 2));
      std::transform(header.begin(), header.begin() + std::ptrdiff_t(std::min<std::size_t>(header.size(), 14)),
                     header.begin(), [](unsigned char c) { return char(std::tolower(c)); });
      if (header.rfind("content-range:", 0) == 0) {
        ranged = parseContentRange(trim(header.substr(14)), part.first, part.last, part.total);
      }
      line = next;
    }
    const std::size_t data = headersEnd + 4;
    if (!ranged || part.last < part.first || part.last - part.first + 1 > text.size() - data) return false;
    part.bytes = body.subspan(data, part.last - part.first + 1);
    parts.push_back(part);
    p = text.find(delimiter, data + part.bytes.size());
  }
  return false;
}

bool transient(const Response& r) {
  switch (r.code) {
    case CURLE_PEER_FAILED_VERIFICATION:  // an untrusted certificate stays untrusted
    case CURLE_SSL_CACERT_BADFILE:
    case CURLE_UNSUPPORTED_PROTOCOL:
    case CURLE_URL_MALFORMAT:
    case CURLE_COULDNT_RESOLVE_HOST:
      return false;
    default:
      break;
  }
  if (r.code != CURLE_OK) return true;  // no connection, a timeout, a cut transfer, an overlong body
  return r.status >= 500;
}

}  // namespace

bool isUrl(std::string_view s) { return s.rfind("http://", 0) == 0 || s.rfind("https://", 0) == 0; }

struct Client::Impl {
  ClientOptions o;

  // Handles: each keeps its connection; a transfer borrows one.
  std::mutex handlesMu;
  std::condition_variable handlesFree;
  std::vector<CURL*> idle;
  std::uint32_t made = 0;

  // The block cache: least recently used first.
  struct Block {
    std::string key;
    std::vector<std::byte> bytes;
  };
  mutable std::mutex cacheMu;
  std::list<Block> lru;
  std::unordered_map<std::string, std::list<Block>::iterator> blocks;
  std::uint64_t cached = 0;
  /// Blocks a read is fetching now: another read of them waits for it
  /// (`landed`) instead of asking again.
  std::unordered_set<std::string> inflight;
  std::condition_variable landed;
  std::atomic<bool> oneRangeOnly{false};  ///< the server answered a request for several ranges otherwise

  mutable std::mutex statsMu;
  ClientStats stats;

  ~Impl() {
    for (CURL* h : idle) curl_easy_cleanup(h);
  }

  CURL* borrow() {
    std::unique_lock lock(handlesMu);
    handlesFree.wait(lock, [&] { return !idle.empty() || made < o.connections; });
    if (!idle.empty()) {
      CURL* h = idle.back();
      idle.pop_back();
      return h;
    }
    ++made;
    return curl_easy_init();
  }
  void giveBack(CURL* h) {
    {
      std::lock_guard lock(handlesMu);
      idle.push_back(h);
    }
    handlesFree.notify_one();
  }

  /// One request: GET (range `first`..`last` when asked) or HEAD.
  Response once(const std::string& url, bool head, bool ranged, std::uint64_t first, std::uint64_t last, std::uint64_t cap) {
    return onceWith(url, head, ranged ? std::to_string(first) + "-" + std::to_string(last) : std::string(), cap);
  }

  /// One request: GET (of the ranges `range`, "A-B[,C-D...]", when not
  /// empty) or HEAD.
  Response onceWith(const std::string& url, bool head, const std::string& range, std::uint64_t cap) {
    const bool ranged = !range.empty();
    Response r;
    CURL* h = borrow();
    if (!h) {
      r.code = CURLE_FAILED_INIT;
      r.curlError = "curl_easy_init failed";
      return r;
    }
    curl_easy_reset(h);  // keeps the connection cache
    char err[CURL_ERROR_SIZE] = {0};
    Sink sink{&r, cap};
    curl_easy_setopt(h, CURLOPT_URL, url.c_str());
    curl_easy_setopt(h, CURLOPT_NOSIGNAL, 1L);
    curl_easy_setopt(h, CURLOPT_ERRORBUFFER, err);
    curl_easy_setopt(h, CURLOPT_FOLLOWLOCATION, 1L);
    curl_easy_setopt(h, CURLOPT_MAXREDIRS, 5L);
    curl_easy_setopt(h, CURLOPT_HTTP_VERSION, long(CURL_HTTP_VERSION_2TLS));
    curl_easy_setopt(h, CURLOPT_TCP_KEEPALIVE, 1L);
    curl_easy_setopt(h, CURLOPT_CONNECTTIMEOUT_MS, long(o.connectTimeoutSeconds * 1000));
    curl_easy_setopt(h, CURLOPT_TIMEOUT_MS, long(o.timeoutSeconds * 1000));
    curl_easy_setopt(h, CURLOPT_ACCEPT_ENCODING, nullptr);  // identity: ranges are of the file's bytes
    curl_easy_setopt(h, CURLOPT_HEADERFUNCTION, onHeader);
    curl_easy_setopt(h, CURLOPT_HEADERDATA, &r);
    curl_easy_setopt(h, CURLOPT_WRITEFUNCTION, onBody);
    curl_easy_setopt(h, CURLOPT_WRITEDATA, &sink);
    if (!o.caFile.empty()) curl_easy_setopt(h, CURLOPT_CAINFO, o.caFile.c_str());
    if (head) curl_easy_setopt(h, CURLOPT_NOBODY, 1L);
    if (ranged) curl_easy_setopt(h, CURLOPT_RANGE, range.c_str());
    if (!head && !ranged) curl_easy_setopt(h, CURLOPT_MAXFILESIZE_LARGE, curl_off_t(cap));
    r.code = curl_easy_perform(h);
    r.curlError = err[0] ? err : curl_easy_strerror(r.code);
    curl_easy_getinfo(h, CURLINFO_RESPONSE_CODE, &r.status);
    curl_easy_getinfo(h, CURLINFO_STARTTRANSFER_TIME, &r.firstByteSeconds);
    curl_easy_getinfo(h, CURLINFO_NUM_CONNECTS, &r.connects);
    curl_easy_getinfo(h, CURLINFO_HTTP_VERSION, &r.httpVersion);
    giveBack(h);
    std::lock_guard lock(statsMu);
    ++stats.requests;
    stats.bytesFetched += r.body.size();
    stats.connectionsOpened += std::uint64_t(std::max(0L, r.connects));
    if (r.code == CURLE_OK && r.httpVersion == long(CURL_HTTP_VERSION_2_0)) ++stats.http2Responses;
    if (r.code == CURLE_OK && r.firstByteSeconds > 0) {
      stats.rttSeconds = stats.rttSeconds == 0 ? r.firstByteSeconds : 0.875 * stats.rttSeconds + 0.125 * r.firstByteSeconds;
    }
    return r;
  }

  /// Retries `once` while the failure is transient; the last response.
  template <class F>
  Response withRetries(F&& attempt) {
    Response r = attempt();
    double pause = o.retryPauseSeconds;
    for (std::uint32_t k = 0; k < o.retries && transient(r); ++k) {
      std::this_thread::sleep_for(std::chrono::duration<double>(pause));
      pause *= 2;
      {
        std::lock_guard lock(statsMu);
        ++stats.retries;
      }
      r = attempt();
    }
    return r;
  }

  static std::string describe(const Response& r) {
    if (r.overlong) return "the server sent more bytes than asked";
    if (r.code == CURLE_PARTIAL_FILE) return "truncated: the connection closed before the whole body came (" + r.curlError + ")";
    if (r.code != CURLE_OK) return r.curlError;
    if (r.status == 404) return "not found (HTTP 404)";
    return "HTTP " + std::to_string(r.status);
  }

  void failed() {
    std::lock_guard lock(statsMu);
    ++stats.failures;
  }

  /// Fetches bytes [first, last] of f, checked.
  Result<std::vector<std::byte>> fetch(const RemoteFile& f, std::uint64_t first, std::uint64_t last) {
    const std::uint64_t want = last - first + 1;
    Response r;
    std::string why;
    auto attempt = [&] {
      Response x = once(f.url, false, true, first, last, want);
      why.clear();
      if (x.status == 200) {
        // The whole file came (or began to): not a server to page from.
        why = "the server ignored the Range request (HTTP 200): it must serve byte ranges";
        x.code = CURLE_OK;
      } else if (x.code == CURLE_OK && x.status == 206) {
        std::uint64_t a = 0, b = 0, total = 0;
        if (!parseContentRange(x.contentRange, a, b, total) || a != first || b != last) {
          why = "the server answered with bytes '" + x.contentRange + "', not the range asked (" + std::to_string(first) +
                "-" + std::to_string(last) + ")";
        } else if (total != UINT64_MAX && total != f.size) {
          why = "the file changed on the server: now " + std::to_string(total) + " bytes, " + std::to_string(f.size) +
                " when opened";
        } else if (!f.etag.empty() && !x.etag.empty() && x.etag != f.etag) {
          why = "the file changed on the server: ETag " + x.etag + ", " + f.etag + " when opened";
        } else if (x.body.size() != want) {
          why = "truncated: " + std::to_string(x.body.size()) + " of " + std::to_string(want) + " bytes";
          x.code = CURLE_PARTIAL_FILE;  // transient: retried
        }
      }
      return x;
    };
    r = withRetries(attempt);
    if (why.empty() && !(r.code == CURLE_OK && r.status == 206)) why = describe(r);
    if (!why.empty()) {
      failed();
      return Problem{f.url, first, "http: " + why};
    }
    return std::move(r.body);
  }

  /// Runs [first, last] of f (sorted, apart) in one request of several
  /// ranges, each part checked. `unsupported` is set when the server
  /// answered, but not with those ranges in one response: ask one by one.
  Result<std::vector<std::vector<std::byte>>> fetchMany(const RemoteFile& f,
                                                        const std::vector<std::pair<std::uint64_t, std::uint64_t>>& runs,
                                                        bool& unsupported) {
    std::string spec;
    std::uint64_t want = 0;
    for (const auto& [a, b] : runs) {
      if (!spec.empty()) spec += ',';
      spec += std::to_string(a);
      spec += '-';
      spec += std::to_string(b);
      want += b - a + 1;
    }
    std::vector<std::vector<std::byte>> out;
    std::string why;
    auto attempt = [&] {
      Response x = onceWith(f.url, false, spec, want + 256 * runs.size() + 1024);
      why.clear();
      unsupported = false;
      out.assign(runs.size(), {});
      if (x.code != CURLE_OK || x.status != 206) {
        unsupported = x.code == CURLE_OK && x.status == 200;
        if (unsupported) why = "the server ignored the ranges (HTTP 200)";
        return x;
      }
      std::vector<BodyPart> parts;
      if (!parseByteranges(x.body, x.contentType, parts)) {
        // One range for all of them (a server that merges), or not ranges.
        BodyPart whole;
        if (!parseContentRange(x.contentRange, whole.first, whole.last, whole.total) || whole.first > runs.front().first ||
            whole.last < runs.back().second || x.body.size() != whole.last - whole.first + 1) {
          unsupported = true;
          why = "the server did not answer the ranges in one response";
          return x;
        }
        whole.bytes = x.body;
        parts.push_back(whole);
      }
      std::size_t found = 0;
      for (std::size_t k = 0; k < runs.size(); ++k) {
        for (const BodyPart& part : parts) {
          if (part.first > runs[k].first || part.last < runs[k].second) continue;
          if (part.total != UINT64_MAX && part.total != f.size) break;
          const auto from = part.bytes.begin() + std::ptrdiff_t(runs[k].first - part.first);
          out[k].assign(from, from + std::ptrdiff_t(runs[k].second - runs[k].first + 1));
          ++found;
          break;
        }
      }
      if (found != runs.size()) {
        unsupported = true;
        why = "the server's parts are not the ranges asked";
      } else if (!f.etag.empty() && !x.etag.empty() && x.etag != f.etag) {
        why = "the file changed on the server: ETag " + x.etag + ", " + f.etag + " when opened";
      }
      return x;
    };
    const Response r = withRetries(attempt);
    if (why.empty() && !(r.code == CURLE_OK && r.status == 206)) why = describe(r);
    if (!why.empty()) {
      failed();
      return Problem{f.url, runs.front().first, "http: " + why};
    }
    std::lock_guard lock(statsMu);
    ++stats.multiRangeRequests;
    return out;
  }

  // Cache.
  std::string key(const RemoteFile& f, std::uint64_t block) const { return f.url + '#' + std::to_string(block); }
  bool lookup(const std::string& k, std::vector<std::byte>& out) {
    std::lock_guard lock(cacheMu);
    const auto it = blocks.find(k);
    if (it == blocks.end()) return false;
    lru.splice(lru.end(), lru, it->second);
    out = it->second->bytes;
    return true;
  }
  void insert(const std::string& k, std::vector<std::byte> bytes) {
    std::lock_guard lock(cacheMu);
    insertLocked(k, std::move(bytes));
  }
  void insertLocked(const std::string& k, std::vector<std::byte> bytes) {
    if (bytes.size() > o.cacheBytes) return;
    if (const auto it = blocks.find(k); it != blocks.end()) {
      cached -= it->second->bytes.size();
      lru.erase(it->second);
      blocks.erase(it);
    }
    cached += bytes.size();
    lru.push_back({k, std::move(bytes)});
    blocks[k] = std::prev(lru.end());
    while (cached > o.cacheBytes && !lru.empty()) {
      cached -= lru.front().bytes.size();
      blocks.erase(lru.front().key);
      lru.pop_front();
    }
  }
  void drop(const std::string& k) {
    std::lock_guard lock(cacheMu);
    if (const auto it = blocks.find(k); it != blocks.end()) {
      cached -= it->second->bytes.size();
      lru.erase(it->second);
      blocks.erase(it);
    }
  }
  /// Blocks [first, first + count) of f, claimed by this thread, are no
  /// longer in flight: cached from `body` (their run's bytes) when it came,
  /// and their waiters woken. Every claimed block is landed, fetched or
  /// not, so no waiter is left waiting for a failed read.
  void land(const RemoteFile& f, std::uint64_t first, std::uint64_t count, const std::vector<std::byte>* body) {
    {
      std::lock_guard lock(cacheMu);
      for (std::uint64_t k = 0; k < count; ++k) {
        const std::string kk = key(f, first + k);
        if (body) {
          const std::uint64_t at = k * o.blockBytes, n = std::min<std::uint64_t>(o.blockBytes, body->size() - at);
          insertLocked(kk, std::vector<std::byte>(body->begin() + std::ptrdiff_t(at), body->begin() + std::ptrdiff_t(at + n)));
        }
        inflight.erase(kk);
      }
    }
    landed.notify_all();
  }

  /// Blocks b0..b1 of `f` into `have`: from the cache, from a read of
  /// another thread that is fetching them now (waited for), or fetched
  /// here, each run of the missing ones in one request.
  Status gather(const RemoteFile& f, std::uint64_t b0, std::uint64_t b1, std::vector<std::vector<std::byte>>& have) {
    enum : std::uint8_t { kHave, kMine, kTheirs };
    std::vector<std::uint8_t> from(have.size(), kHave);
    {
      std::lock_guard lock(cacheMu);
      for (std::uint64_t b = b0; b <= b1; ++b) {
        const std::string k = key(f, b);
        if (const auto it = blocks.find(k); it != blocks.end()) {
          lru.splice(lru.end(), lru, it->second);
          have[b - b0] = it->second->bytes;
        } else {
          from[b - b0] = inflight.insert(k).second ? kMine : kTheirs;
        }
      }
    }
    for (std::uint64_t b = b0; b <= b1; ++b) count(from[b - b0] == kHave);
    for (std::uint64_t b = b0; b <= b1;) {
      if (from[b - b0] != kMine) {
        ++b;
        continue;
      }
      std::uint64_t e = b;
      while (e + 1 <= b1 && from[e + 1 - b0] == kMine) ++e;
      auto r = fetch(f, b * o.blockBytes, std::min(f.size, (e + 1) * o.blockBytes) - 1);
      if (!r) {
        for (std::uint64_t k = b; k <= b1; ++k) {
          if (from[k - b0] == kMine) land(f, k, 1, nullptr);
        }
        return r.problems();
      }
      for (std::uint64_t k = b; k <= e; ++k) {
        const std::uint64_t at = (k - b) * o.blockBytes, n = std::min<std::uint64_t>(o.blockBytes, r->size() - at);
        have[k - b0].assign(r->begin() + std::ptrdiff_t(at), r->begin() + std::ptrdiff_t(at + n));
      }
      land(f, b, e - b + 1, &r.value());
      b = e + 1;
    }
    for (std::uint64_t b = b0; b <= b1; ++b) {
      if (from[b - b0] != kTheirs) continue;
      const std::string k = key(f, b);
      {
        std::unique_lock lock(cacheMu);
        landed.wait(lock, [&] { return !inflight.contains(k); });
        if (const auto it = blocks.find(k); it != blocks.end()) {
          have[b - b0] = it->second->bytes;
          continue;
        }
      }
      // Their read failed, or the block was evicted already: ask for it here.
      auto r = fetch(f, b * o.blockBytes, std::min(f.size, (b + 1) * o.blockBytes) - 1);
      if (!r) return r.problems();
      have[b - b0] = std::move(r.value());
      insert(k, have[b - b0]);
    }
    return {};
  }

  void count(bool hit) {
    std::lock_guard lock(statsMu);
    (hit ? stats.cacheHits : stats.cacheMisses) += 1;
  }
};

Client::Client(std::unique_ptr<Impl> impl) : impl_(std::move(impl)) {}
Client::~Client() = default;

Result<std::shared_ptr<Client>> Client::create(const ClientOptions& o) {
  if (o.connections < 1 || o.connections > 256) return Problem{"", 0, "ClientOptions::connections must be 1 .. 256"};
  if (!(o.connectTimeoutSeconds > 0) || !(o.timeoutSeconds > 0)) {
    return Problem{"", 0, "ClientOptions::connectTimeoutSeconds and timeoutSeconds must be > 0"};
  }
  if (o.retries > 20) return Problem{"", 0, "ClientOptions::retries must be <= 20"};
  if (!(o.retryPauseSeconds >= 0 && o.retryPauseSeconds <= 10)) {
    return Problem{"", 0, "ClientOptions::retryPauseSeconds must be 0 .. 10"};
  }
  const std::uint32_t b = o.blockBytes;
  if (b < 4096 || b > (16u << 20) || (b & (b - 1)) != 0) {
    return Problem{"", 0, "ClientOptions::blockBytes must be a power of two from 4096 to 16 MiB"};
  }
  std::call_once(curlOnce, [] { curl_global_init(CURL_GLOBAL_DEFAULT); });
  auto impl = std::make_unique<Impl>();
  impl->o = o;
  return std::shared_ptr<Client>(new Client(std::move(impl)));
}

const ClientOptions& Client::options() const { return impl_->o; }

Result<RemoteFile> Client::open(const std::string& url) const {
  if (!isUrl(url)) return Problem{url, 0, "http: not an http:// or https:// URL"};
  Response r = impl_->withRetries([&] { return impl_->once(url, true, false, 0, 0, 0); });
  if (!(r.code == CURLE_OK && r.status == 200)) {
    impl_->failed();
    return Problem{url, 0, "http: " + Impl::describe(r)};
  }
  if (r.contentLength == UINT64_MAX) {
    impl_->failed();
    return Problem{url, 0, "http: the server gives no Content-Length for the file; it must serve it by byte ranges"};
  }
  RemoteFile f;
  f.url = url;
  f.size = r.contentLength;
  f.etag = r.etag;
  return f;
}

Status Client::read(const RemoteFile& f, std::uint64_t offset, std::span<std::byte> out) const {
  if (out.empty()) return {};
  if (offset > f.size || out.size() > f.size - offset) {
    impl_->failed();
    return Problem{f.url, offset, "http: " + std::to_string(out.size()) + " bytes at " + std::to_string(offset) +
                                      " run past the end of the file (" + std::to_string(f.size) + " bytes)"};
  }
  Impl& m = *impl_;
  if (m.o.cacheBytes == 0) {
    auto r = m.fetch(f, offset, offset + out.size() - 1);
    if (!r) return r.problems();
    std::memcpy(out.data(), r->data(), out.size());
    return {};
  }
  const std::uint64_t bs = m.o.blockBytes, b0 = offset / bs, b1 = (offset + out.size() - 1) / bs;
  std::vector<std::vector<std::byte>> have(b1 - b0 + 1);
  if (Status st = m.gather(f, b0, b1, have); !st) return st;
  std::size_t done = 0;
  for (std::uint64_t b = b0; b <= b1; ++b) {
    const std::uint64_t start = b == b0 ? offset - b * bs : 0;
    const std::size_t n = std::size_t(std::min<std::uint64_t>(have[b - b0].size() - start, out.size() - done));
    std::memcpy(out.data() + done, have[b - b0].data() + start, n);
    done += n;
  }
  return {};
}

Status Client::prefetch(const RemoteFile& f, std::span<const std::pair<std::uint64_t, std::uint64_t>> ranges) const {
  Impl& m = *impl_;
  if (m.o.cacheBytes == 0) return {};
  const std::uint64_t bs = m.o.blockBytes;
  std::vector<std::uint64_t> wanted;
  for (const auto& [a, e] : ranges) {
    if (e <= a || e > f.size) continue;
    for (std::uint64_t b = a / bs; b <= (e - 1) / bs; ++b) wanted.push_back(b);
  }
  std::sort(wanted.begin(), wanted.end());
  wanted.erase(std::unique(wanted.begin(), wanted.end()), wanted.end());
  std::vector<std::uint64_t> mine;  // claimed here: neither cached nor in flight
  {
    std::lock_guard lock(m.cacheMu);
    for (const std::uint64_t b : wanted) {
      const std::string k = m.key(f, b);
      if (!m.blocks.contains(k) && m.inflight.insert(k).second) mine.push_back(b);
    }
  }
  if (mine.empty()) return {};
  std::vector<std::pair<std::uint64_t, std::uint64_t>> runs;  // blocks [first, last]
  for (const std::uint64_t b : mine) {
    if (!runs.empty() && runs.back().second + 1 == b) {
      runs.back().second = b;
    } else {
      runs.emplace_back(b, b);
    }
  }
  std::vector<std::pair<std::uint64_t, std::uint64_t>> bytes;  // [first, last] of each run
  for (const auto& [b, e] : runs) bytes.emplace_back(b * bs, std::min(f.size, (e + 1) * bs) - 1);
  Result<std::vector<std::vector<std::byte>>> got = std::vector<std::vector<std::byte>>{};
  bool unsupported = false;
  if (bytes.size() > 1 && !m.oneRangeOnly.load(std::memory_order_relaxed)) {
    got = m.fetchMany(f, bytes, unsupported);
    if (!got && unsupported) m.oneRangeOnly.store(true, std::memory_order_relaxed);
  }
  if (bytes.size() == 1 || m.oneRangeOnly.load(std::memory_order_relaxed)) {
    got = std::vector<std::vector<std::byte>>{};
    for (const auto& [a, e] : bytes) {
      auto one = m.fetch(f, a, e);
      if (!one) {
        got = one.problems();
        break;
      }
      got->push_back(std::move(one.value()));
    }
  }
  for (std::size_t r = 0; r < runs.size(); ++r) {
    m.land(f, runs[r].first, runs[r].second - runs[r].first + 1, got && r < got->size() ? &got.value()[r] : nullptr);
  }
  if (!got) return got.problems();
  return {};
}

void Client::refresh(const RemoteFile& f, std::uint64_t offset, std::uint64_t n) const {
  if (n == 0 || impl_->o.cacheBytes == 0) return;
  const std::uint64_t bs = impl_->o.blockBytes;
  for (std::uint64_t b = offset / bs; b <= (offset + n - 1) / bs; ++b) impl_->drop(impl_->key(f, b));
}

Result<std::vector<std::byte>> Client::get(const std::string& url, std::uint64_t maxBytes) const {
  if (!isUrl(url)) return Problem{url, 0, "http: not an http:// or https:// URL"};
  Response r = impl_->withRetries([&] { return impl_->once(url, false, false, 0, 0, maxBytes); });
  if (r.code == CURLE_FILESIZE_EXCEEDED || r.overlong) {
    impl_->failed();
    return Problem{url, 0, "http: longer than the " + std::to_string(maxBytes) + " bytes allowed for it"};
  }
  if (!(r.code == CURLE_OK && r.status == 200)) {
    impl_->failed();
    return Problem{url, 0, "http: " + Impl::describe(r)};
  }
  if (r.contentLength != UINT64_MAX && r.contentLength != r.body.size()) {
    impl_->failed();
    return Problem{url, 0, "http: truncated: " + std::to_string(r.body.size()) + " of " + std::to_string(r.contentLength) + " bytes"};
  }
  return std::move(r.body);
}

ClientStats Client::stats() const {
  ClientStats s;
  {
    std::lock_guard lock(impl_->statsMu);
    s = impl_->stats;
  }
  std::lock_guard lock(impl_->cacheMu);
  s.cacheBytes = impl_->cached;
  return s;
}

}  // namespace sandtable::http
