#pragma once
// Pager internals shared by pager.cpp (slots, loaders, readers),
// pager_pool.cpp (slot storage, placeholders, histogram) and
// pager_prefetch.cpp (mmap mode). The memory-ordering contract is written
// out in docs/PAGER.md, section 4.
#include <array>
#include <atomic>
#include <chrono>
#include <condition_variable>
#include <cstdint>
#include <memory>
#include <mutex>
#include <span>
#include <thread>
#include <unordered_map>
#include <vector>

#include "sandtable/base/jobs.h"
#include "sandtable/paging/pager.h"

namespace sandtable::paging::detail {

inline std::int64_t nowNs() {
  return std::chrono::duration_cast<std::chrono::nanoseconds>(
             std::chrono::steady_clock::now().time_since_epoch())
      .count();
}

// ------------------------------------------------------------- slot word
// One 64-bit word per slot holds the module key, the state, which of the
// slot's two buffers readers are admitted to, and a generation, so one CAS
// changes all of them.
//   bits  0..31  key = kz << 16 | kx (modules per axis <= 65536)
//   bits 32..33  state
//   bit  34      buffer: 0 for every fresh load, flipped by each reload
//   bits 35..63  generation (bumped on every claim, reload and free)
enum class SlotState : std::uint32_t { empty = 0, loading = 1, resident = 2 };
inline constexpr std::uint64_t kGenMask = 0x1fffffffull;

inline std::uint32_t packKey(std::uint32_t kx, std::uint32_t kz) { return (kz << 16) | kx; }
inline ModuleKey unpackKey(std::uint32_t k) { return {k & 0xffffu, k >> 16}; }
inline std::uint64_t makeWord(std::uint32_t key, SlotState s, std::uint64_t gen, std::uint32_t buffer = 0) {
  return std::uint64_t(key) | (std::uint64_t(s) << 32) | (std::uint64_t(buffer & 1u) << 34) |
         ((gen & kGenMask) << 35);
}
inline std::uint32_t wordKey(std::uint64_t w) { return std::uint32_t(w & 0xffffffffu); }
inline SlotState wordState(std::uint64_t w) { return SlotState((w >> 32) & 3u); }
inline std::uint32_t wordBuffer(std::uint64_t w) { return std::uint32_t((w >> 34) & 1u); }
inline std::uint64_t wordGen(std::uint64_t w) { return w >> 35; }

/// One residency slot. Readers touch word, readers[] and finest[] (atomics)
/// and, once admitted to a buffer, that buffer's published levels. Loaders
/// write a buffer only while holding `write` and after every reader of that
/// buffer has left. Buffer 0 takes every fresh load (it holds the
/// placeholder reserve); a reload writes the buffer readers are not
/// admitted to while the old generation stays readable in the other, then
/// flips the word's buffer bit (docs/PAGER.md, section 4).
struct alignas(64) Slot {
  std::atomic<std::uint64_t> word{0};
  std::array<std::atomic<std::uint32_t>, 2> readers{};
  std::array<std::atomic<std::uint32_t>, 2> finest{};  ///< finest published level per buffer
  /// Demand mode: 1 << 32 | key of a fault not yet taken, else 0.
  std::atomic<std::uint64_t> demand{0};
  std::atomic<std::int64_t> demandNs{0};  ///< time of that fault
  std::mutex write;                       ///< loaders only
  std::array<ResidentModule, 2> data;     ///< levels sized once at open
  std::uint64_t capacityBytes = 0;        ///< under `write`
};

// ------------------------------------------------------------ SPSC queue

struct Request {
  std::uint32_t key = 0;
  std::uint8_t free = 0;    ///< 1: free the module, 0: load it
  std::uint8_t refill = 0;  ///< part of a refill (kept out of the latency estimate)
  std::int64_t requestNs = 0;
};

/// Bounded single-producer (main thread) single-consumer (one loader)
/// ring. push never blocks: it fails when full.
class SpscQueue {
 public:
  explicit SpscQueue(std::size_t capacityPow2) : buf_(capacityPow2), mask_(capacityPow2 - 1) {}
  bool push(const Request& r) {
    const std::size_t t = tail_.load(std::memory_order_relaxed);
    if (t - head_.load(std::memory_order_acquire) == buf_.size()) return false;
    buf_[t & mask_] = r;
    tail_.store(t + 1, std::memory_order_release);
    return true;
  }
  bool pop(Request& r) {
    const std::size_t h = head_.load(std::memory_order_relaxed);
    if (h == tail_.load(std::memory_order_acquire)) return false;
    r = buf_[h & mask_];
    head_.store(h + 1, std::memory_order_release);
    return true;
  }
  std::size_t size() const {
    return tail_.load(std::memory_order_acquire) - head_.load(std::memory_order_acquire);
  }

 private:
  std::vector<Request> buf_;
  std::size_t mask_;
  alignas(64) std::atomic<std::size_t> head_{0};
  alignas(64) std::atomic<std::size_t> tail_{0};
};

// ------------------------------------------------------- window seqlock

struct WindowState {
  ModuleRect window;  ///< clipped
  double eyeX = 0, eyeZ = 0, vx = 0, vz = 0;
};

/// Written by the main thread only, read by loaders and the prefetcher
/// (Boehm's seqlock with atomic fields: no data race, readers retry).
class SeqWindow {
 public:
  void store(const WindowState& s);
  WindowState load() const;

 private:
  std::atomic<std::uint64_t> seq_{0};
  std::atomic<std::int64_t> x0_{0}, z0_{0}, x1_{0}, z1_{0};
  std::atomic<double> eyeX_{0}, eyeZ_{0}, vx_{0}, vz_{0};
};

// ------------------------------------------------------------- histogram

/// Log-scale latency histogram: bucket 0 is below 1 us, bucket b >= 1
/// holds [2^((b-1)/4), 2^(b/4)) us; the last bucket is open. Lock-free.
class LatencyHistogram {
 public:
  static constexpr int kBuckets = 104;  ///< up to 2^(103/4) us, about 55 s
  void add(std::int64_t ns);
  LatencyStats stats() const;
  void reset();

 private:
  std::array<std::atomic<std::uint64_t>, kBuckets> counts_{};
  std::atomic<std::uint64_t> count_{0}, sumNs_{0}, maxNs_{0};
};

// ------------------------------------------------------------ slot pool

/// Bytes of the vectors' capacities of one level.
std::uint64_t levelCapacityBytes(const module::Level& l);
/// Bytes copying `src` into `dst` would add to dst's capacities.
std::uint64_t levelGrowthBytes(const module::Level& src, const module::Level& dst);
/// Copies src into dst reusing dst's capacity (never shrinks it).
void copyLevel(const module::Level& src, module::Level& dst);
/// Reserves dst's vectors to at least src's sizes.
void reserveLike(const module::Level& src, module::Level& dst);

/// A coarse stand-in for module (kx, kz): the coarsest level as
/// sandtable_meshing assembles it from the grid (posts every 2^(levels-1)
/// grid posts, the grid's own heights, the grid triangles as the skin in
/// `material`), with skirts round the module as deep as the elevation range
/// of the grid blocks under it. Written into `out` reusing its capacity.
void buildPlaceholder(const grid::GridFile& grid, const pack::IndexHeader& h, std::uint32_t kx,
                      std::uint32_t kz, std::uint16_t material, module::Level& out);

// ---------------------------------------------------------------- loader

struct Pending {
  std::uint32_t key = 0;
  std::uint8_t refill = 0;
  std::uint8_t fine = 0;  ///< coarse-first: the fine levels of a module whose coarse ones are published
  std::int64_t requestNs = 0;
};

struct Loader {
  std::uint32_t index = 0;
  std::unique_ptr<SpscQueue> queue;
  std::atomic<std::uint32_t> signal{0};
  std::atomic<bool> resync{false};
  std::atomic<std::uint32_t> backlog{0};  ///< pending (drained, not yet loaded), for metrics
  /// The coarse loads among `pending` (coarse-first): other loaders read
  /// no fine record while this or a queue is nonzero (loaderLoop).
  std::atomic<std::uint32_t> coarseBacklog{0};
  std::atomic<std::uint64_t> published{0};
  /// Guards `pending`: its loader, and thieves (work stealing). Loaders
  /// only; the main thread and readers never take it.
  std::mutex pendingMutex;
  std::vector<Pending> pending;  ///< capacity fixed at open
  std::thread thread;
};

}  // namespace sandtable::paging::detail

namespace sandtable::paging {

struct Pager::Impl {
  using Slot = detail::Slot;
  using Loader = detail::Loader;

  PagerOptions options;
  std::shared_ptr<const grid::GridFile> grid;
  std::shared_ptr<const ModuleSource> source;  ///< null in mmap mode without modules
  /// A remote grid's blocks around and ahead of the eye, fetched off the
  /// main thread (fetchGridAhead); null for a local grid.
  std::unique_ptr<jobs::SerialQueue> gridFetches;
  std::int64_t gridAheadKey = INT64_MIN;  ///< the eye's block at the last fetch (main thread)
  pack::IndexHeader header;                       ///< zero levels without a pack
  PagingGeometry geometry;
  std::uint32_t levels = 1;
  std::uint32_t ringX = 1, ringZ = 1;
  std::unique_ptr<Slot[]> slots;
  std::uint32_t slotCount = 0;
  std::vector<std::unique_ptr<Loader>> loaders;
  std::uint16_t placeholderMaterial = 0;
  module::Level placeholderProto;  ///< a full-size placeholder: every slot's coarse reserve

  // Main thread only.
  StripPlanner planner;
  std::uint64_t seenChanges = 0;    ///< the source's changes() last polled
  std::vector<ModuleKey> changed;   ///< reused by the poll
  double lastTime = 0;
  bool haveTime = false;
  double updateInterval = 0;  ///< running mean of the time between updates (main thread)
  bool haveInterval = false;

  detail::SeqWindow window;
  std::atomic<bool> stopping{false};
  bool stopped = false;
  std::int64_t openNs = 0;
  std::atomic<std::int64_t> outstanding{0};  ///< loads and frees not yet done

  // Loader-shared state that may block (loaders only).
  std::mutex badMutex;
  /// Keys known missing or corrupt, with the source generation that failed
  /// (a newer generation is read again).
  std::unordered_map<std::uint32_t, std::uint64_t> badModules;
  std::mutex statsMutex;
  double srtt = 0, rttvar = 0;
  bool haveRtt = false;
  std::atomic<double> latencyEstimate{0};
  std::atomic<double> leadSeconds{0};
  std::atomic<double> liveViewDistance{0};  ///< the planner's, for the prefetch thread
  std::atomic<bool> loggedBudget{false};

  // Counters (relaxed); metrics() snapshots them in one loop.
  mutable PagerCountersOf<std::atomic<std::uint64_t>> count;
  std::atomic<std::uint64_t> readNs{0}, publishNs{0};
  std::array<std::atomic<std::uint64_t>, kDirections> stripSignals{};
  std::array<std::atomic<std::uint32_t>, kDirections> leadStrips{};
  std::atomic<std::uint32_t> maxQueueLength{0};
  std::atomic<std::uint64_t> poolBytes{0};
  detail::LatencyHistogram latency, stripLatency;

  // mmap mode.
  std::thread prefetcher;
  std::mutex sleepMutex;
  std::condition_variable sleepCv;
  std::atomic<bool> wake{false};
  std::atomic<double> lastPassSeconds{0}, lastSleepSeconds{0};
  std::atomic<std::uint64_t> touchSink{0};

  explicit Impl(const PagingGeometry& g) : geometry(g), planner(g) {}

  Slot& slotFor(std::uint32_t kx, std::uint32_t kz) const {
    return slots[std::size_t(kz % ringZ) * ringX + kx % ringX];
  }
  void log(const std::string& message) const;
};

/// The prefetch loop of mmap mode (pager_prefetch.cpp).
void runPrefetcher(Pager::Impl& impl);

/// Readahead for a loader (pager_prefetch.cpp): tells the source that the
/// modules just taken from the queue (a strip, or part of a refill) will be
/// read, coarse and fine records.
void hintStrip(Pager::Impl& impl, std::span<const ModuleKey> keys);
/// Queues the fetch of a remote grid's blocks around the eye and ahead of
/// it when the eye enters another block (gridFetches; main thread).
void fetchGridAhead(Pager::Impl& impl, double eyeX, double eyeZ, double vx, double vz);

}  // namespace sandtable::paging
