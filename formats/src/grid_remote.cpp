// A grid on a web server, read by block into a sparse local copy
// (grid.h, GridFile::openRemote; docs/HTTP.md, "The grid by range").
//
// Each block has a state: unchecked (the copy may hold it from an earlier
// run, or a hole), good (checked against its table CRC in this process),
// or standing in (its fetch failed; the copy holds a flat block until a
// retry succeeds). Readers test the state with one acquire load; the
// first reader of a block that is not good takes the lock and settles it.
// The table itself is trusted only after header, table and the table's
// block CRCs combine to the manifest's CRC of the whole file.
#include <fcntl.h>
#include <sys/mman.h>
#include <sys/stat.h>
#include <unistd.h>
#include <zlib.h>

#include <algorithm>
#include <atomic>
#include <cerrno>
#include <chrono>
#include <condition_variable>
#include <cmath>
#include <cstring>
#include <mutex>
#include <optional>
#include <unordered_map>
#include <utility>
#include <vector>

#include "sandtable/formats/bytes.h"
#include "sandtable/formats/grid.h"

namespace sandtable::grid {

namespace {

enum : std::uint8_t { kUnchecked = 0, kGood = 1, kStandIn = 2, kFetching = 3 };

double secondsSince(std::chrono::steady_clock::time_point t0) {
  return std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
}

/// CRC-32 of the whole file from its first dataOffset bytes and the
/// table's block CRCs (as GridWriter::finish combines it).
std::uint32_t combinedCrc(std::span<const std::byte> headAndTable, const Header& h) {
  uLong c = crc32(headAndTable);
  const uLong op = crc32_combine_gen(static_cast<z_off_t>(kBlockBytes));
  const std::byte* table = headAndTable.data() + h.blockTableOffset;
  for (std::uint64_t k = 0; k < h.blockCount(); ++k) c = crc32_combine_op(c, loadLE<std::uint32_t>(table + k * kBlockEntryBytes), op);
  return static_cast<std::uint32_t>(c);
}

}  // namespace

class GridFile::Remote {
 public:
  std::shared_ptr<const RangeSource> source;
  RemoteGridOptions options;
  int fd = -1;
  std::uint64_t blocks = 0, blocksX = 0, dataOffset = 0;
  std::vector<std::uint32_t> crcs;
  std::vector<float> middles;  ///< each block's stand-in elevation
  std::unique_ptr<std::atomic<std::uint8_t>[]> state;
  std::unique_ptr<std::atomic<std::uint32_t>[]> lastUse;  ///< whole seconds since open
  std::chrono::steady_clock::time_point opened = std::chrono::steady_clock::now();

  std::mutex mutex;  ///< everything below, and every state change
  std::condition_variable landed;  ///< a fetch ended
  struct Failure {
    double retryAt = 0, pause = 0;
  };
  std::unordered_map<std::uint64_t, Failure> failures;
  /// Apart from `mutex`, so a caller polling them never waits on a fetch.
  std::mutex problemMutex;
  std::vector<Problem> problems;
  std::atomic<std::size_t> problemCount{0};
  std::vector<std::byte> buffer;
  std::uint64_t sweep = 0;
  RemoteGridStats stats;

  ~Remote() {
    if (fd >= 0) ::close(fd);
  }

  std::uint32_t now() const { return static_cast<std::uint32_t>(secondsSince(opened)); }
  std::uint64_t offsetOf(std::uint64_t b) const { return dataOffset + b * kBlockBytes; }

  /// Whether the copy holds block b whole (its table CRC).
  bool copyHolds(std::uint64_t b) {
    buffer.resize(kBlockBytes);
    return preadAll(fd, buffer.data(), kBlockBytes, offsetOf(b)) && crc32(buffer) == crcs[b];
  }

  /// Settles block b (the lock held): good from the copy, or fetched with
  /// the blocks after it in its row that also need it, or standing in, or
  /// waited for while another thread fetches it.
  void settle(std::unique_lock<std::mutex>& lock, std::uint64_t b) {
    for (;;) {
      const std::uint8_t s = state[b].load(std::memory_order_acquire);
      if (s == kGood) return;
      if (s == kFetching) {
        landed.wait(lock);
        continue;
      }
      if (s == kUnchecked && copyHolds(b)) {
        markGood(b, false, s);
        return;
      }
      if (s == kStandIn && secondsSince(opened) < failures[b].retryAt) return;
      std::uint64_t e = b + 1;
      const std::uint64_t rowEnd = (b / blocksX + 1) * blocksX;
      while (e < rowEnd && e - b < 1 + options.readaheadBlocks && wanted(e)) ++e;
      fetch(lock, b, e);
      return;
    }
  }

  /// Whether block e should join a fetch (a readahead candidate; the lock
  /// held).
  bool wanted(std::uint64_t e) {
    const std::uint8_t s = state[e].load(std::memory_order_acquire);
    if (s != kUnchecked) return false;
    if (copyHolds(e)) {
      markGood(e, false, s);
      return false;
    }
    return true;
  }

  /// Fetches blocks [b0, b1) in one request. Called with the lock held;
  /// the blocks are marked fetching and the lock let go for the request,
  /// so readers of other blocks do not wait on it (readers of these wait
  /// on `landed`). Each block is checked, written, then marked.
  void fetch(std::unique_lock<std::mutex>& lock, std::uint64_t b0, std::uint64_t b1) {
    std::vector<std::uint8_t> before(b1 - b0);
    for (std::uint64_t b = b0; b < b1; ++b) before[b - b0] = state[b].exchange(kFetching, std::memory_order_acq_rel);
    lock.unlock();
    std::vector<std::string> why(b1 - b0);  // empty: the block is in the copy
    std::uint64_t requests = 1, refetches = 0;
    std::vector<std::byte> got((b1 - b0) * kBlockBytes);
    const Status st = source->read(offsetOf(b0), got);
    for (std::uint64_t b = b0; b < b1; ++b) {
      const std::span<std::byte> one(got.data() + (b - b0) * kBlockBytes, kBlockBytes);
      std::string& w = why[b - b0];
      if (!st) {
        w = st.problems().front().message;
        continue;
      }
      if (crc32(one) != crcs[b]) {
        // Once more past any cache: a cut or altered response.
        ++refetches, ++requests;
        source->refresh(offsetOf(b), kBlockBytes);
        if (Status again = source->read(offsetOf(b), one); !again) {
          w = again.problems().front().message;
          continue;
        }
        if (crc32(one) != crcs[b]) {
          w = "grid: block " + std::to_string(b) + " failed its checksum twice (table " + crcHex(crcs[b]) + ", got " +
              crcHex(crc32(one)) + "): the server's copy is damaged or from another build";
          continue;
        }
      }
      if (Status written = pwriteAll(fd, one.data(), one.size(), offsetOf(b)); !written) {
        w = "grid: cannot write the local copy: " + written.message();
      }
    }
    lock.lock();
    stats.requests += requests;
    stats.refetches += refetches;
    for (std::uint64_t b = b0; b < b1; ++b) {
      if (why[b - b0].empty()) {
        markGood(b, true, before[b - b0]);
      } else {
        fail(b, why[b - b0], before[b - b0]);
      }
    }
    landed.notify_all();
    evictIfOver(b0, b1);
  }

  /// `was`: the block's state before it was settled.
  void markGood(std::uint64_t b, bool fetched, std::uint8_t was) {
    if (was == kStandIn && stats.standIns > 0) --stats.standIns;
    failures.erase(b);
    lastUse[b].store(now(), std::memory_order_relaxed);  // readahead: kept as if read now
    state[b].store(kGood, std::memory_order_release);
    ++(fetched ? stats.fetchedBlocks : stats.diskBlocks);
  }

  /// Block b could not be had (the lock held): a flat stand-in in the
  /// copy, a retry later, the first failure reported.
  void fail(std::uint64_t b, const std::string& why, std::uint8_t was) {
    ++stats.failedFetches;
    const auto [it, first] = failures.try_emplace(b);
    Failure& f = it->second;
    f.pause = first ? options.retryFirstSeconds : std::min(f.pause * 2, options.retryMaxSeconds);
    f.retryAt = secondsSince(opened) + f.pause;
    if (first) {
      const std::lock_guard problemLock(problemMutex);
      problems.push_back({source->name(), offsetOf(b), why.rfind("grid: ", 0) == 0 ? why : "grid: " + why});
      problemCount.store(problems.size(), std::memory_order_release);
    }
    if (was != kStandIn) {
      BlockData flat;
      flat.elevation.fill(middles[b]);
      flat.normalY.fill(32767);
      std::vector<std::byte> bytes(kBlockBytes);
      encodeBlock(flat, bytes);
      (void)pwriteAll(fd, bytes.data(), bytes.size(), offsetOf(b));
      ++stats.standIns;
    }
    state[b].store(kStandIn, std::memory_order_release);
  }

  /// Past the bound, punches out blocks nobody read for evictAfterSeconds,
  /// except [keep0, keep1), the ones just fetched for a reader.
  void evictIfOver(std::uint64_t keep0, std::uint64_t keep1) {
    if (options.maxBytes == 0) return;
    struct stat st {};
    if (::fstat(fd, &st) != 0) return;
    std::uint64_t used = std::uint64_t(st.st_blocks) * 512;
    const std::uint32_t t = now();
    for (std::uint64_t n = 0; n < blocks && used > options.maxBytes; ++n, sweep = (sweep + 1) % blocks) {
      const std::uint8_t s = state[sweep].load(std::memory_order_relaxed);
      if (s == kStandIn || s == kFetching || (sweep >= keep0 && sweep < keep1)) continue;
      if (s == kGood && t - lastUse[sweep].load(std::memory_order_relaxed) < options.evictAfterSeconds) continue;
      state[sweep].store(kUnchecked, std::memory_order_release);
      // An unchecked block may be an earlier run's or a hole: punched
      // either way, counted as freed only when it was known to be there.
      if (::fallocate(fd, FALLOC_FL_PUNCH_HOLE | FALLOC_FL_KEEP_SIZE, off_t(offsetOf(sweep)), off_t(kBlockBytes)) == 0 &&
          s == kGood) {
        used -= std::min<std::uint64_t>(used, kBlockBytes);
        ++stats.evictedBlocks;
      }
    }
  }
};

namespace {

/// The header page and the block table, checked: the table's CRC, and
/// header, table and the table's block CRCs combined against `fileCrc`.
Result<Header> checkHead(std::span<const std::byte> head, const std::string& name, std::uint64_t size,
                         std::uint32_t fileCrc) {
  auto h = decodeHeader(head.first(kPageBytes), name, size);
  if (!h) return h.problems();
  const auto table = head.subspan(h->blockTableOffset, h->blockCount() * kBlockEntryBytes);
  if (crc32(table) != h->tableCrc) {
    return Problem{name, h->blockTableOffset, "grid: block table checksum mismatch: the server's copy is damaged"};
  }
  if (const std::uint32_t c = combinedCrc(head, h.value()); c != fileCrc) {
    return Problem{name, 0, "grid: header and block table combine to CRC " + crcHex(c) + ", the manifest says " +
                                crcHex(fileCrc) + ": the server's copy is damaged or from another build"};
  }
  return h;
}

/// The head of a local copy of the same size, when it checks.
std::optional<std::vector<std::byte>> localHead(int fd, const std::string& path, std::uint64_t size, std::uint32_t fileCrc) {
  struct stat st {};
  if (::fstat(fd, &st) != 0 || std::uint64_t(st.st_size) != size) return std::nullopt;
  std::vector<std::byte> page(kPageBytes);
  if (!preadAll(fd, page.data(), page.size(), 0)) return std::nullopt;
  auto h = decodeHeader(page, path, size);
  if (!h) return std::nullopt;
  std::vector<std::byte> head(h->dataOffset);
  if (!preadAll(fd, head.data(), head.size(), 0) || !checkHead(head, path, size, fileCrc)) return std::nullopt;
  return head;
}

/// The head from the server.
Result<std::vector<std::byte>> remoteHead(const RangeSource& source, std::uint32_t fileCrc) {
  const std::uint64_t size = source.size();
  if (size < kPageBytes) {
    return Problem{source.name(), size, "grid header: truncated: the file is " + std::to_string(size) + " bytes"};
  }
  std::vector<std::byte> page(kPageBytes);
  if (Status st = source.read(0, page); !st) return st.problems();
  // decodeHeader ties dataOffset to the block count and the file's size,
  // so the table read below is bounded by the file on the server.
  auto h = decodeHeader(page, source.name(), size);
  if (!h) return h.problems();
  std::vector<std::byte> head(h->dataOffset);
  std::copy(page.begin(), page.end(), head.begin());
  if (Status st = source.read(kPageBytes, std::span(head).subspan(kPageBytes)); !st) return st.problems();
  if (auto c = checkHead(head, source.name(), size, fileCrc); !c) return c.problems();
  return head;
}

}  // namespace

Result<std::shared_ptr<const GridFile>> GridFile::openRemote(std::shared_ptr<const RangeSource> source,
                                                             const std::string& localPath, std::uint32_t fileCrc,
                                                             const RemoteGridOptions& options) {
  const std::uint64_t size = source->size();
  auto r = std::make_shared<Remote>();
  r->fd = ::open(localPath.c_str(), O_RDWR | O_CREAT | O_CLOEXEC, 0644);
  if (r->fd < 0) return Problem{localPath, 0, std::string("grid: cannot open the local copy: ") + std::strerror(errno)};
  // The copy's own head when it checks (a second run asks the server for
  // nothing); else the server's, and a copy of another size is of another
  // grid: it starts empty. Blocks of an earlier run are kept; each is
  // checked by its CRC when first read.
  std::vector<std::byte> head;
  if (auto mine = localHead(r->fd, localPath, size, fileCrc)) {
    head = std::move(*mine);
  } else {
    auto theirs = remoteHead(*source, fileCrc);
    if (!theirs) return theirs.problems();
    head = std::move(theirs.value());
    struct stat st {};
    if (::fstat(r->fd, &st) != 0 || (std::uint64_t(st.st_size) != size && ::ftruncate(r->fd, 0) != 0) ||
        ::ftruncate(r->fd, off_t(size)) != 0 || !pwriteAll(r->fd, head.data(), head.size(), 0)) {
      return Problem{localPath, 0, std::string("grid: cannot write the local copy (is the disk full?): ") + std::strerror(errno)};
    }
  }
  const Header h = decodeHeader(std::span(head).first(kPageBytes), localPath, size).value();
  const auto table = std::span<const std::byte>(head).subspan(h.blockTableOffset, h.blockCount() * kBlockEntryBytes);
  r->source = std::move(source);
  r->options = options;
  r->blocks = h.blockCount();
  r->blocksX = h.blocksX;
  r->dataOffset = h.dataOffset;
  r->state = std::make_unique<std::atomic<std::uint8_t>[]>(r->blocks);
  r->lastUse = std::make_unique<std::atomic<std::uint32_t>[]>(r->blocks);
  r->crcs.resize(r->blocks);
  r->middles.resize(r->blocks);
  for (std::uint64_t k = 0; k < r->blocks; ++k) {
    const std::byte* e = table.data() + k * kBlockEntryBytes;
    r->crcs[k] = loadLE<std::uint32_t>(e);
    const float mid = 0.5f * (loadLE<float>(e + 4) + loadLE<float>(e + 8));
    r->middles[k] = std::isfinite(mid) ? mid : 0.0f;
  }
  void* m = ::mmap(nullptr, size, PROT_READ, MAP_SHARED, r->fd, 0);
  if (m == MAP_FAILED) return Problem{localPath, 0, std::string("grid: mmap failed: ") + std::strerror(errno)};
  std::shared_ptr<GridFile> g(new GridFile());
  g->path_ = localPath;
  g->base_ = static_cast<const std::byte*>(m);
  g->size_ = size;
  g->header_ = h;
  g->remote_ = std::move(r);
  return std::shared_ptr<const GridFile>(std::move(g));
}

void GridFile::ensureBlock(std::uint64_t block) const {
  Remote& r = *remote_;
  const std::uint32_t t = r.now();
  if (r.lastUse[block].load(std::memory_order_relaxed) != t) r.lastUse[block].store(t, std::memory_order_relaxed);
  if (r.state[block].load(std::memory_order_acquire) == kGood) return;
  std::unique_lock lock(r.mutex);
  r.settle(lock, block);
}

Status GridFile::fetchBlocks(std::uint32_t bx0, std::uint32_t bz0, std::uint32_t bx1, std::uint32_t bz1) const {
  if (!remote_ || header_.blocksX == 0 || header_.blocksZ == 0) return {};
  Remote& r = *remote_;
  bx1 = std::min(bx1, header_.blocksX - 1);
  bz1 = std::min(bz1, header_.blocksZ - 1);
  std::unique_lock lock(r.mutex);
  std::uint64_t standing = 0, first = 0;
  for (std::uint32_t bz = bz0; bz <= bz1; ++bz) {
    // Runs of the row that need fetching, each one request.
    std::uint64_t b = std::uint64_t(bz) * r.blocksX + bx0;
    const std::uint64_t end = std::uint64_t(bz) * r.blocksX + bx1 + 1;
    while (b < end) {
      if (!r.wanted(b)) {
        if (r.state[b].load(std::memory_order_relaxed) == kStandIn) r.settle(lock, b);
        ++b;
        continue;
      }
      std::uint64_t e = b + 1;
      while (e < end && r.wanted(e)) ++e;
      r.fetch(lock, b, e);
      b = e;
    }
    for (b = std::uint64_t(bz) * r.blocksX + bx0; b < end; ++b) {
      if (r.state[b].load(std::memory_order_relaxed) != kStandIn) continue;
      if (standing++ == 0) first = b;
    }
  }
  if (standing == 0) return {};
  return Problem{r.source->name(), r.offsetOf(first),
                 "grid: " + std::to_string(standing) + " blocks could not be fetched and stand in flat; they are asked again later"};
}

RemoteGridStats GridFile::remoteStats() const {
  if (!remote_) return {};
  std::lock_guard lock(remote_->mutex);
  return remote_->stats;
}

std::vector<Problem> GridFile::takeRemoteProblems() const {
  if (!remote_ || remote_->problemCount.load(std::memory_order_acquire) == 0) return {};
  const std::lock_guard lock(remote_->problemMutex);
  remote_->problemCount.store(0, std::memory_order_release);
  return std::exchange(remote_->problems, {});
}

}  // namespace sandtable::grid
