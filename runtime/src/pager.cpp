// The pager: residency slots, loader threads and the lock-free read path
// (docs/PAGER.md). The strip logic is in pager_plan.cpp, storage helpers
// in pager_pool.cpp, mmap mode in pager_prefetch.cpp.
#include <sys/stat.h>

#include <algorithm>
#include <cassert>
#include <cmath>
#include <cstdio>
#include <optional>

#include "pager_internal.h"

namespace sandtable::runtime {

using namespace pager_detail;

// ------------------------------------------------------------ ResidentRef

ResidentRef& ResidentRef::operator=(ResidentRef&& o) noexcept {
  if (this != &o) {
    release();
    readers_ = o.readers_;
    module_ = o.module_;
    level_ = o.level_;
    finest_ = o.finest_;
    coarser_ = o.coarser_;
    generation_ = o.generation_;
    o.readers_ = nullptr;
  }
  return *this;
}

void ResidentRef::release() {
  if (readers_ != nullptr) {
    // Release: this reader's reads of the module happen before a loader
    // that sees the count reach zero reuses the storage.
    readers_->fetch_sub(1, std::memory_order_release);
    readers_ = nullptr;
  }
}

const module::Level& ResidentRef::level(std::uint32_t l) const {
  assert(readers_ != nullptr && l >= finest_ && l < module_->levels.size());
  return module_->levels[l];
}

// ------------------------------------------------------------------- Impl

void Pager::Impl::log(const std::string& message) const {
  if (options.log) {
    options.log(message);
  } else {
    std::fprintf(stderr, "sandtable pager: %s\n", message.c_str());
  }
}

namespace {

using Impl = Pager::Impl;

std::size_t nextPow2(std::size_t n) {
  std::size_t p = 1;
  while (p < n) p <<= 1;
  return p;
}

void signalLoader(Loader& l) {
  l.signal.fetch_add(1, std::memory_order_release);
  l.signal.notify_one();
}

std::string checkOptions(const PagerOptions& o, double edge) {
  auto finite = [](double v) { return std::isfinite(v); };
  if (!finite(o.viewDistance) || o.viewDistance <= 0) return "viewDistance must be > 0";
  if (!finite(o.maxViewDistance) || (o.maxViewDistance != 0 && o.maxViewDistance < o.viewDistance)) {
    return "maxViewDistance must be 0 (fixed) or at least viewDistance";
  }
  if (!finite(o.hysteresis) || o.hysteresis < 0 || o.hysteresis >= edge / 2) {
    char half[32];
    std::snprintf(half, sizeof half, "%g", edge / 2);
    return std::string("hysteresis must be >= 0 and below half a module (") + half + " m)";
  }
  if (o.memoryBudgetBytes == 0) return "memoryBudgetBytes must be > 0";
  if (o.loaderThreads < 1 || o.loaderThreads > 4) return "loaderThreads must be 1 to 4";
  if (!finite(o.lookAheadScale) || o.lookAheadScale < 0) return "lookAheadScale must be >= 0";
  if (o.maxLeadStrips > 16) return "maxLeadStrips must be 0 to 16";
  if (!finite(o.initialLatencySeconds) || o.initialLatencySeconds < 0) {
    return "initialLatencySeconds must be >= 0";
  }
  if (!finite(o.simulatedReadSeconds) || o.simulatedReadSeconds < 0) {
    return "simulatedReadSeconds must be >= 0";
  }
  if (!finite(o.mmapModuleSize) || o.mmapModuleSize <= 0) return "mmapModuleSize must be > 0";
  if (!finite(o.prefetchSleepBlocks) || o.prefetchSleepBlocks <= 0 ||
      !finite(o.minSleepSeconds) || o.minSleepSeconds <= 0 || !finite(o.maxSleepSeconds) ||
      o.maxSleepSeconds < o.minSleepSeconds) {
    return "prefetch sleep must be > 0 with 0 < minSleepSeconds <= maxSleepSeconds";
  }
  return "";
}

// ------------------------------------------------------------- the pool

/// Takes `bytes` from the budget; false (nothing taken) when it would not fit.
bool takeBudget(Impl& im, std::uint64_t bytes) {
  std::uint64_t cur = im.poolBytes.load(std::memory_order_relaxed);
  do {
    if (cur + bytes > im.options.memoryBudgetBytes) return false;
  } while (!im.poolBytes.compare_exchange_weak(cur, cur + bytes, std::memory_order_relaxed));
  return true;
}

/// Brings the slot's capacity and the pool total up to date after a copy
/// for which `taken` bytes were taken from the budget.
void settleCapacity(Impl& im, Slot& s, std::uint64_t taken) {
  std::uint64_t now = 0;
  for (const module::Level& l : s.data.levels) now += levelCapacityBytes(l);
  const std::int64_t delta = std::int64_t(now) - std::int64_t(s.capacityBytes) - std::int64_t(taken);
  if (delta > 0) im.poolBytes.fetch_add(std::uint64_t(delta), std::memory_order_relaxed);
  if (delta < 0) im.poolBytes.fetch_sub(std::uint64_t(-delta), std::memory_order_relaxed);
  s.capacityBytes = now;
}

/// Gives back the storage of empty slots (beyond each one's placeholder
/// reserve) until `need` bytes fit in the budget. Slots keep their capacity
/// when their module leaves, so without this a pool that once held large
/// modules in some slots could refuse a module the window really needs.
/// Only slots that are empty, with no reader, whose write lock is free are
/// touched: no reader can be admitted to an empty slot, and no loader can
/// fill it while the lock is held. Runs only under budget pressure.
void reclaimEmptySlots(Impl& im, const Slot& self, std::uint64_t need) {
  auto fits = [&] { return im.poolBytes.load(std::memory_order_relaxed) + need <= im.options.memoryBudgetBytes; };
  for (std::uint32_t i = 0; i < im.slotCount && !fits(); ++i) {
    Slot& s = im.slots[i];
    if (&s == &self) continue;
    const std::unique_lock lock(s.write, std::try_to_lock);
    if (!lock.owns_lock()) continue;
    if (wordState(s.word.load(std::memory_order_seq_cst)) != SlotState::empty ||
        s.readers.load(std::memory_order_seq_cst) != 0) {
      continue;
    }
    const std::uint64_t before = s.capacityBytes;
    for (std::size_t l = 0; l < s.data.levels.size(); ++l) {
      module::Level fresh;
      if (l + 1 == s.data.levels.size()) reserveLike(im.placeholderProto, fresh);
      if (levelCapacityBytes(fresh) < levelCapacityBytes(s.data.levels[l])) {
        s.data.levels[l] = std::move(fresh);
      }
    }
    settleCapacity(im, s, 0);
    if (before > s.capacityBytes) {
      im.reclaimedBytes.fetch_add(before - s.capacityBytes, std::memory_order_relaxed);
    }
  }
}

/// Copies one decoded level into the slot if the budget allows.
bool copyWithinBudget(Impl& im, Slot& s, const module::Level& src, std::uint32_t l) {
  const std::uint64_t growth = levelGrowthBytes(src, s.data.levels[l]);
  if (growth > 0 && !takeBudget(im, growth)) {
    reclaimEmptySlots(im, s, growth);
    if (!takeBudget(im, growth)) return false;
  }
  copyLevel(src, s.data.levels[l]);
  settleCapacity(im, s, growth);
  return true;
}

// ------------------------------------------------------------ the loads

bool knownBad(Impl& im, std::uint32_t key) {
  const std::lock_guard lock(im.badMutex);
  return im.badModules.count(key) != 0;
}

/// True when the record lies (partly) beyond the end of modules.pack now:
/// the module is missing rather than corrupt.
bool recordBeyondEof(const Impl& im, const pack::Entry& e) {
  struct stat st {};
  if (::fstat(im.pack->packFd(), &st) != 0) return false;
  return e.offset + e.compressedBytes > std::uint64_t(st.st_size);
}

void recordLatency(Impl& im, const Pending& p) {
  const std::int64_t ns = nowNs() - p.requestNs;
  im.latency.add(ns);
  if (p.refill) return;  // a refill's queueing says nothing about strips
  im.stripLatency.add(ns);
  const double x = double(ns) / 1e9;
  const std::lock_guard lock(im.statsMutex);
  if (!im.haveRtt) {
    im.srtt = x;
    im.rttvar = x / 2;
    im.haveRtt = true;
  } else {
    im.rttvar = 0.75 * im.rttvar + 0.25 * std::abs(im.srtt - x);
    im.srtt = 0.875 * im.srtt + 0.125 * x;
  }
  im.latencyEstimate.store(im.srtt + 4 * im.rttvar, std::memory_order_relaxed);
}

/// Adds the time from construction to destruction to publishNs.
struct PublishTimer {
  Impl& im;
  std::int64_t t0 = nowNs();
  explicit PublishTimer(Impl& i) : im(i) {}
  ~PublishTimer() { im.publishNs.fetch_add(std::uint64_t(nowNs() - t0), std::memory_order_relaxed); }
  PublishTimer(const PublishTimer&) = delete;
  PublishTimer& operator=(const PublishTimer&) = delete;
};

/// Reads module p.key into its slot and publishes it, coarse level first.
void loadModule(Impl& im, Loader& ld, const Pending& p) {
  const ModuleKey k = unpackKey(p.key);
  if (!im.window.load().window.contains(k.kx, k.kz)) {
    im.cancelledQueued.fetch_add(1, std::memory_order_relaxed);
    return;
  }
  Slot& s = im.slotFor(k.kx, k.kz);
  const std::unique_lock lock(s.write);  // loaders only; readers never take it

  // Claim the slot. The seq_cst CAS stops new readers from being admitted
  // to the old occupant; the seq_cst load of `readers` after it then sees
  // every reader that was admitted (docs/PAGER.md, section 4).
  std::uint64_t w = s.word.load(std::memory_order_seq_cst);
  std::uint64_t gen = 0;
  for (;;) {
    if (wordKey(w) == p.key && wordState(w) != SlotState::empty) {
      im.duplicates.fetch_add(1, std::memory_order_relaxed);
      return;
    }
    gen = (wordGen(w) + 1) & 0x3fffffffull;
    if (s.word.compare_exchange_weak(w, makeWord(p.key, SlotState::loading, gen),
                                     std::memory_order_seq_cst)) {
      break;
    }
  }
  // Reusing a slot whose module left the window frees that module.
  if (wordState(w) != SlotState::empty) im.freed.fetch_add(1, std::memory_order_relaxed);
  if (s.readers.load(std::memory_order_seq_cst) != 0) {
    im.readerWaits.fetch_add(1, std::memory_order_relaxed);
    while (s.readers.load(std::memory_order_seq_cst) != 0) std::this_thread::yield();
  }

  // Read: one pread, CRC, zstd, decode (PackReader::readInto), into this
  // loader's own module and buffers, whose capacity is reused from read to
  // read: in steady state a load allocates nothing.
  const bool bad = knownBad(im, p.key);
  thread_local module::Module loaded;
  std::string failure;
  bool missing = false;
  if (!bad) {
    const pack::Entry e = im.pack->entry(k.kx, k.kz);
    if (e.compressedBytes == 0) {
      missing = true;
      failure = im.pack->indexPath() + ": pack index: module (" + std::to_string(k.kx) + ", " +
                std::to_string(k.kz) + ") is missing (its entry has no record)";
    } else {
      if (im.options.simulatedReadSeconds > 0) {
        std::this_thread::sleep_for(std::chrono::duration<double>(im.options.simulatedReadSeconds));
      }
      const std::int64_t t0 = nowNs();
      const Status read = im.pack->readInto(k.kx, k.kz, loaded);
      im.readNs.fetch_add(std::uint64_t(nowNs() - t0), std::memory_order_relaxed);
      im.bytesRead.fetch_add(e.compressedBytes, std::memory_order_relaxed);
      if (!read) {
        failure = read.error();
        missing = recordBeyondEof(im, e);
      }
    }
  }
  if (!im.window.load().window.contains(k.kx, k.kz)) {
    // Left the window during the read: give the slot back unpublished.
    im.cancelledInFlight.fetch_add(1, std::memory_order_relaxed);
    std::uint64_t expect = makeWord(p.key, SlotState::loading, gen);
    s.word.compare_exchange_strong(expect, makeWord(p.key, SlotState::empty, gen + 1),
                                   std::memory_order_seq_cst);
    return;
  }

  // The coarsest level first (or a placeholder).
  const PublishTimer timer(im);
  const std::uint32_t coarse = im.levels - 1;
  ResidentModule& d = s.data;
  d.kx = k.kx;
  d.kz = k.kz;
  bool placeholder = bad || !failure.empty();
  if (!placeholder && !copyWithinBudget(im, s, loaded.levels[coarse], coarse)) {
    placeholder = true;
    im.budgetRefusals.fetch_add(1, std::memory_order_relaxed);
    if (!im.loggedBudget.exchange(true)) {
      im.log("the memory budget of " + std::to_string(im.options.memoryBudgetBytes) +
             " bytes is spent (pool " +
             std::to_string(im.poolBytes.load(std::memory_order_relaxed)) +
             " bytes): modules that do not fit show as coarse placeholders; raise "
             "memoryBudgetBytes or lower viewDistance (logged once)");
    }
  }
  if (placeholder) {
    if (!failure.empty()) {
      bool first = false;
      {
        const std::lock_guard bl(im.badMutex);
        first = im.badModules.insert(p.key).second;
      }
      if (first) {
        (missing ? im.missingModules : im.corruptModules).fetch_add(1, std::memory_order_relaxed);
        im.log(failure + " (a coarse placeholder stands in; logged once per module)");
      }
    }
    buildPlaceholder(*im.grid, im.header, k.kx, k.kz, im.placeholderMaterial, d.levels[coarse]);
    settleCapacity(im, s, 0);
    im.placeholders.fetch_add(1, std::memory_order_relaxed);
  }
  d.placeholder = placeholder;
  s.finest.store(coarse, std::memory_order_release);
  std::uint64_t expect = makeWord(p.key, SlotState::loading, gen);
  if (!s.word.compare_exchange_strong(expect, makeWord(p.key, SlotState::resident, gen),
                                      std::memory_order_seq_cst)) {
    im.cancelledInFlight.fetch_add(1, std::memory_order_relaxed);  // freed meanwhile
    return;
  }
  recordLatency(im, p);
  ld.published.fetch_add(1, std::memory_order_relaxed);
  if (!placeholder) im.loaded.fetch_add(1, std::memory_order_relaxed);
  if (im.options.onResident) im.options.onResident(ld.index, k, placeholder);
  if (placeholder) return;

  // Then the finer levels, each published by a release store of `finest`:
  // readers admitted meanwhile use only levels >= the finest they loaded,
  // which this loop no longer writes.
  const module::Module& m = loaded;
  for (std::uint32_t l = coarse; l-- > 0;) {
    if (!copyWithinBudget(im, s, m.levels[l], l)) {
      im.budgetTrimmedLevels.fetch_add(l + 1, std::memory_order_relaxed);
      if (!im.loggedBudget.exchange(true)) {
        im.log("the memory budget of " + std::to_string(im.options.memoryBudgetBytes) +
               " bytes is spent: fine levels are left out (logged once)");
      }
      break;
    }
    s.finest.store(l, std::memory_order_release);
  }
}

/// Frees module `key` unless it is (again) in the window.
void freeModule(Impl& im, std::uint32_t key) {
  const ModuleKey k = unpackKey(key);
  if (im.window.load().window.contains(k.kx, k.kz)) return;  // stale: it came back
  Slot& s = im.slotFor(k.kx, k.kz);
  std::uint64_t w = s.word.load(std::memory_order_seq_cst);
  while (wordKey(w) == key && wordState(w) != SlotState::empty) {
    if (s.word.compare_exchange_weak(w, makeWord(key, SlotState::empty, wordGen(w) + 1),
                                     std::memory_order_seq_cst)) {
      im.freed.fetch_add(1, std::memory_order_relaxed);
      return;
    }
  }
}

void noteBacklog(Impl& im, Loader& ld) {
  ld.backlog.store(std::uint32_t(ld.pending.size()), std::memory_order_relaxed);
  const auto n = std::uint32_t(ld.pending.size() + ld.queue->size());
  std::uint32_t m = im.maxQueueLength.load(std::memory_order_relaxed);
  while (n > m && !im.maxQueueLength.compare_exchange_weak(m, n, std::memory_order_relaxed)) {
  }
}

/// Rebuilds a loader's pending list from the window (after an overflow).
void resync(Impl& im, Loader& ld) {
  im.outstanding.fetch_sub(std::int64_t(ld.pending.size()));
  ld.pending.clear();
  const ModuleRect w = im.window.load().window;
  const std::int64_t now = nowNs();
  for (std::int64_t z = w.z0; z < w.z1 && ld.pending.size() < ld.pending.capacity(); ++z) {
    for (std::int64_t x = w.x0; x < w.x1 && ld.pending.size() < ld.pending.capacity(); ++x) {
      const std::uint32_t key = packKey(std::uint32_t(x), std::uint32_t(z));
      const std::uint64_t word = im.slotFor(std::uint32_t(x), std::uint32_t(z)).word.load();
      if (wordKey(word) == key && wordState(word) != SlotState::empty) continue;
      im.outstanding.fetch_add(1);
      ld.pending.push_back({key, 1, now});
    }
  }
}

/// Takes the pending module nearest the eye, dropping those that left the
/// window (cancelled before their read began).
std::optional<Pending> takeNearest(Impl& im, Loader& ld) {
  const WindowState ws = im.window.load();
  const double e = im.geometry.moduleSize;
  std::optional<Pending> best;
  double bestD = 0;
  std::size_t bestI = 0;
  for (std::size_t i = 0; i < ld.pending.size();) {
    const ModuleKey k = unpackKey(ld.pending[i].key);
    if (!ws.window.contains(k.kx, k.kz)) {
      im.cancelledQueued.fetch_add(1, std::memory_order_relaxed);
      im.outstanding.fetch_sub(1);
      ld.pending[i] = ld.pending.back();
      ld.pending.pop_back();
      continue;
    }
    const double dx = (k.kx + 0.5) * e - ws.eyeX, dz = (k.kz + 0.5) * e - ws.eyeZ;
    const double d = dx * dx + dz * dz;
    if (!best || d < bestD) {
      best = ld.pending[i];
      bestD = d;
      bestI = i;
    }
    ++i;
  }
  if (best) {
    ld.pending[bestI] = ld.pending.back();
    ld.pending.pop_back();
  }
  return best;
}

/// Predictive: drain the queue (frees at once, loads to pending).
void drainQueue(Impl& im, Loader& ld) {
  Request r;
  while (ld.queue->pop(r)) {
    if (r.free) {
      freeModule(im, r.key);
      im.outstanding.fetch_sub(1);
    } else if (ld.pending.size() == ld.pending.capacity()) {
      im.outstanding.fetch_sub(1);
      ld.resync.store(true);
    } else {
      ld.pending.push_back({r.key, r.refill, r.requestNs});
    }
  }
}

/// Demand: take the faults of this loader's slots.
void collectFaults(Impl& im, Loader& ld) {
  const std::uint32_t n = std::uint32_t(im.loaders.size());
  for (std::uint32_t i = ld.index; i < im.slotCount; i += n) {
    Slot& s = im.slots[i];
    if (s.demand.load(std::memory_order_relaxed) == 0) continue;
    if (ld.pending.size() == ld.pending.capacity()) return;  // left set: taken later
    im.outstanding.fetch_add(1);  // before the flag clears, for waitIdle
    const std::uint64_t v = s.demand.exchange(0, std::memory_order_acq_rel);
    const std::int64_t t = s.demandNs.load(std::memory_order_relaxed);
    const auto key = std::uint32_t(v & 0xffffffffu);
    const bool queued = std::any_of(ld.pending.begin(), ld.pending.end(),
                                    [&](const Pending& q) { return q.key == key; });
    if (v == 0 || queued) {
      im.outstanding.fetch_sub(1);
      continue;
    }
    im.requested.fetch_add(1, std::memory_order_relaxed);
    ld.pending.push_back({key, 0, t});
  }
}

/// Work stealing: the nearest pending module of the loader with the
/// largest backlog, taken under that loader's pending mutex.
std::optional<Pending> steal(Impl& im, const Loader& self) {
  Loader* victim = nullptr;
  std::uint32_t most = 0;
  for (const auto& l : im.loaders) {
    const std::uint32_t b = l->backlog.load(std::memory_order_relaxed);
    if (l.get() != &self && b > most) {
      most = b;
      victim = l.get();
    }
  }
  if (victim == nullptr) return std::nullopt;
  const std::lock_guard lock(victim->pendingMutex);
  std::optional<Pending> p = takeNearest(im, *victim);
  victim->backlog.store(std::uint32_t(victim->pending.size()), std::memory_order_relaxed);
  return p;
}

/// Another loader has modules queued or pending.
bool workElsewhere(const Impl& im, const Loader& self) {
  return std::any_of(im.loaders.begin(), im.loaders.end(), [&](const auto& l) {
    return l.get() != &self &&
           (l->backlog.load(std::memory_order_relaxed) > 0 || l->queue->size() > 0);
  });
}

void loaderLoop(Impl& im, Loader& ld) {
  const bool demand = im.options.mode == PagerMode::demand;
  const bool stealing = !demand && im.options.workStealing && im.loaders.size() > 1;
  for (;;) {
    const std::uint32_t seen = ld.signal.load(std::memory_order_acquire);
    if (im.stopping.load(std::memory_order_acquire)) break;
    std::optional<Pending> p;
    {
      const std::lock_guard lock(ld.pendingMutex);
      if (demand) {
        collectFaults(im, ld);
      } else {
        drainQueue(im, ld);
        if (ld.resync.exchange(false)) resync(im, ld);
      }
      noteBacklog(im, ld);
      if (!ld.pending.empty()) {
        p = takeNearest(im, ld);
        ld.backlog.store(std::uint32_t(ld.pending.size()), std::memory_order_relaxed);
      }
    }
    bool stolen = false;
    if (!p && stealing) {
      p = steal(im, ld);
      stolen = p.has_value();
    }
    if (p) {
      if (stolen) im.stolen.fetch_add(1, std::memory_order_relaxed);
      loadModule(im, ld, *p);
      im.outstanding.fetch_sub(1);
      continue;
    }
    // The owner of that work drains its queue only between loads, so poll
    // briefly rather than sleep until this loader's own next signal.
    if (stealing && workElsewhere(im, ld)) {
      std::this_thread::sleep_for(std::chrono::microseconds(200));
      continue;
    }
    ld.signal.wait(seen, std::memory_order_acquire);
  }
  const std::lock_guard lock(ld.pendingMutex);
  im.outstanding.fetch_sub(std::int64_t(ld.pending.size()));
  ld.pending.clear();
}

/// Reserves every slot for the largest module of the pack, slot by slot,
/// while the budget allows.
/// Reserves every slot for a typical module: the median by encoded size.
/// Not the largest: with culture a few town modules are 40× the median, and
/// reserving every slot for one of those spent the whole budget before
/// anything loaded, so the window filled with placeholders (issue 9). The
/// 90th percentile cost 170 MB more peak RSS on north Bayreuth at 20 km than
/// the median. At most a quarter of the budget goes to reserves; a slot
/// grows once for a larger module and keeps it, and reclaimEmptySlots gives
/// back what empty slots hold.
void preallocate(Impl& im) {
  const pack::IndexHeader& h = im.header;
  std::vector<std::pair<std::uint32_t, std::uint32_t>> sizes;  // (raw bytes, index)
  sizes.reserve(std::size_t(h.modulesX) * h.modulesZ);
  for (std::uint32_t z = 0; z < h.modulesZ; ++z) {
    for (std::uint32_t x = 0; x < h.modulesX; ++x) {
      const std::uint32_t raw = im.pack->entry(x, z).rawBytes;
      if (raw > 0) sizes.emplace_back(raw, z * h.modulesX + x);
    }
  }
  if (sizes.empty()) return;
  const auto nth = sizes.begin() + std::ptrdiff_t((sizes.size() - 1) / 2);
  std::nth_element(sizes.begin(), nth, sizes.end());
  const Result<module::Module> m = im.pack->read(nth->second % h.modulesX, nth->second / h.modulesX);
  if (!m.ok() || m->levels.size() != im.levels) return;
  const std::uint64_t cap = im.options.memoryBudgetBytes / 4;
  for (std::uint32_t i = 0; i < im.slotCount; ++i) {
    Slot& s = im.slots[i];
    std::uint64_t growth = 0;
    for (std::uint32_t l = 0; l < im.levels; ++l) {
      growth += levelGrowthBytes(m->levels[l], s.data.levels[l]);
    }
    if (im.poolBytes.load(std::memory_order_relaxed) + growth > cap || !takeBudget(im, growth)) {
      return;
    }
    for (std::uint32_t l = 0; l < im.levels; ++l) reserveLike(m->levels[l], s.data.levels[l]);
    settleCapacity(im, s, growth);
  }
}

}  // namespace

// ------------------------------------------------------------------ Pager

Pager::Pager(std::unique_ptr<Impl> impl) : impl_(std::move(impl)) {}

Pager::~Pager() { stop(); }

Result<std::unique_ptr<Pager>> Pager::open(std::shared_ptr<const grid::GridFile> grid,
                                           std::shared_ptr<const pack::PackReader> pack,
                                           const PagerOptions& options) {
  return openWith(std::move(grid), std::move(pack), options, 0);
}

Result<std::unique_ptr<Pager>> Pager::open(const Database& db, const PagerOptions& options) {
  return openWith(db.grid, db.modules, options, db.materials ? db.materials->defaultArea : 0);
}

Result<std::unique_ptr<Pager>> Pager::open(const std::string& directory,
                                           const PagerOptions& options) {
  auto db = openDatabase(directory);
  if (!db) return db.problems();
  return open(db.value(), options);
}

Result<std::unique_ptr<Pager>> Pager::openWith(std::shared_ptr<const grid::GridFile> grid,
                                               std::shared_ptr<const pack::PackReader> pack,
                                               const PagerOptions& options,
                                               std::uint16_t material) {
  if (!grid) return Problem{"pager", 0, "pager: no grid"};
  if (options.mode != PagerMode::mmap && !pack) {
    return Problem{grid->path(), 0,
                   "pager: the database has no load modules (modules.pack); build it with "
                   "modules or use mode mmap"};
  }
  const pack::IndexHeader header = pack ? pack->header() : pack::IndexHeader{};
  PagingGeometry g;
  g.moduleSize = pack ? header.moduleSize : options.mmapModuleSize;
  if (!(g.moduleSize > 0)) return Problem{"pager", 0, "pager: the module size is not positive"};
  if (const std::string err = checkOptions(options, g.moduleSize); !err.empty()) {
    return Problem{"pager options", 0, "pager options: " + err};
  }
  if (pack) {
    g.modulesX = header.modulesX;
    g.modulesZ = header.modulesZ;
  } else {
    const double w = grid->spacing() * (grid->postsX() - 1), d = grid->spacing() * (grid->postsZ() - 1);
    g.modulesX = std::max<std::uint32_t>(1, std::uint32_t(std::ceil(w / g.moduleSize)));
    g.modulesZ = std::max<std::uint32_t>(1, std::uint32_t(std::ceil(d / g.moduleSize)));
  }
  g.viewDistance = options.viewDistance;
  g.maxViewDistance = std::max(options.viewDistance, options.maxViewDistance);
  g.hysteresis = options.hysteresis;
  g.maxLeadStrips = options.mode == PagerMode::predictive ? options.maxLeadStrips : 0;

  auto im = std::make_unique<Impl>(g);
  im->options = options;
  im->grid = std::move(grid);
  im->pack = std::move(pack);
  im->header = header;
  im->levels = im->pack ? std::max<std::uint32_t>(1, header.levels) : 1;
  im->ringX = std::max<std::uint32_t>(1, g.ringX());
  im->ringZ = std::max<std::uint32_t>(1, g.ringZ());
  im->placeholderMaterial = material;
  im->latencyEstimate.store(options.initialLatencySeconds);
  im->liveViewDistance.store(options.viewDistance);
  im->openNs = nowNs();

  if (options.mode != PagerMode::mmap) {
    im->slotCount = im->ringX * im->ringZ;
    im->slots = std::make_unique<Slot[]>(im->slotCount);
    // Every slot can always hold a placeholder: its coarse level is
    // reserved to the placeholder lattice of a full-size module.
    module::Level& proto = im->placeholderProto;
    buildPlaceholder(*im->grid, im->header, 0, 0, material, proto);
    for (std::uint32_t i = 0; i < im->slotCount; ++i) {
      Slot& s = im->slots[i];
      s.data.levels.resize(im->levels);
      reserveLike(proto, s.data.levels[im->levels - 1]);
      settleCapacity(*im, s, 0);
    }
    const std::uint64_t base = im->poolBytes.load();
    if (base > options.memoryBudgetBytes) {
      return Problem{"pager options", 0,
                     "pager: the placeholders of " + std::to_string(im->slotCount) +
                         " slots need " + std::to_string(base) +
                         " bytes, more than the memory budget of " +
                         std::to_string(options.memoryBudgetBytes) +
                         " bytes; raise memoryBudgetBytes or lower viewDistance"};
    }
    if (options.preallocate) preallocate(*im);
    const std::uint32_t n = options.loaderThreads;
    for (std::uint32_t i = 0; i < n; ++i) {
      auto ld = std::make_unique<Loader>();
      ld->index = i;
      ld->queue = std::make_unique<SpscQueue>(nextPow2(std::max<std::size_t>(64, 4 * im->slotCount)));
      ld->pending.reserve(2 * std::size_t(im->slotCount) + 16);
      im->loaders.push_back(std::move(ld));
    }
    Impl& ref = *im;
    for (auto& ld : im->loaders) {
      Loader& l = *ld;
      l.thread = std::thread([&ref, &l] { loaderLoop(ref, l); });
    }
  } else {
    Impl& ref = *im;
    im->prefetcher = std::thread([&ref] { runPrefetcher(ref); });
  }
  return std::unique_ptr<Pager>(new Pager(std::move(im)));
}

void Pager::update(double eyeX, double eyeZ, double velocityX, double velocityZ, double timeNow) {
  Impl& im = *impl_;
  if (im.stopped) return;
  im.updates.fetch_add(1, std::memory_order_relaxed);
  // Velocity not given: from the last update's position and time.
  if (!std::isfinite(velocityX) || !std::isfinite(velocityZ)) {
    const WindowState last = im.window.load();
    const double dt = timeNow - im.lastTime;
    velocityX = velocityZ = 0;
    if (im.haveTime && dt > 0) {
      velocityX = (eyeX - last.eyeX) / dt;
      velocityZ = (eyeZ - last.eyeZ) / dt;
    }
  }
  im.lastTime = timeNow;
  im.haveTime = true;

  const double lead = im.options.mode == PagerMode::demand
                          ? 0.0
                          : im.options.lookAheadScale * im.latencyEstimate.load(std::memory_order_relaxed);
  im.leadSeconds.store(lead, std::memory_order_relaxed);
  const PlanStep& st = im.planner.update(eyeX, eyeZ, velocityX, velocityZ,
                                         im.options.mode == PagerMode::predictive ? lead : 0.0);
  im.window.store({st.after, eyeX, eyeZ, velocityX, velocityZ});
  for (std::size_t d = 0; d < kDirections; ++d) {
    im.leadStrips[d].store(im.planner.lead()[d], std::memory_order_relaxed);
  }
  if (st.crossed) im.boxCrossings.fetch_add(1, std::memory_order_relaxed);
  if (st.refill) im.refills.fetch_add(1, std::memory_order_relaxed);
  if (im.options.mode == PagerMode::mmap) {
    if (st.refill) {  // a jump: wake the prefetcher (a lost wake costs one sleep)
      im.wake.store(true);
      im.sleepCv.notify_one();
    }
    return;
  }
  // Demand mode pages nothing here: resident() faults bring modules in and
  // slots are replaced when reused.
  if (!st.changed || im.options.mode == PagerMode::demand) return;
  const std::int64_t now = nowNs();
  const std::size_t n = im.loaders.size();
  for (std::size_t d = 0; d < kDirections; ++d) {
    const StripJob& job = st.jobs[d];
    if (!job.signalled()) continue;
    if (!st.refill) im.stripSignals[d].fetch_add(1, std::memory_order_relaxed);
    Loader& ld = *im.loaders[d % n];
    auto push = [&](const Request& r) {
      im.outstanding.fetch_add(1);
      if (!ld.queue->push(r)) {
        im.outstanding.fetch_sub(1);
        im.queueOverflows.fetch_add(1, std::memory_order_relaxed);
        ld.resync.store(true);
      }
    };
    for (const ModuleKey& k : job.free) push({packKey(k.kx, k.kz), 1, 0, now});
    for (const ModuleKey& k : job.load) {
      push({packKey(k.kx, k.kz), 0, std::uint8_t(st.refill ? 1 : 0), now});
    }
    im.requested.fetch_add(job.load.size(), std::memory_order_relaxed);
    signalLoader(ld);
  }
  // Wake the idle loaders too, so they can steal from the busy ones.
  if (im.options.workStealing && n > 1) {
    for (auto& l : im.loaders) signalLoader(*l);
  }
}

ResidentRef Pager::resident(std::uint32_t kx, std::uint32_t kz, std::uint32_t wantLevel) const {
  const Impl& im = *impl_;
  ResidentRef ref;
  if (!im.slots || kx >= im.header.modulesX || kz >= im.header.modulesZ) return ref;
  im.residentQueries.fetch_add(1, std::memory_order_relaxed);
  Slot& s = im.slotFor(kx, kz);
  const std::uint32_t key = packKey(kx, kz);
  // Admission: announce, then check (seq_cst both; see loadModule).
  s.readers.fetch_add(1, std::memory_order_seq_cst);
  const std::uint64_t w = s.word.load(std::memory_order_seq_cst);
  if (wordKey(w) != key || wordState(w) != SlotState::resident) {
    s.readers.fetch_sub(1, std::memory_order_release);
    im.residentMisses.fetch_add(1, std::memory_order_relaxed);
    if (im.options.mode == PagerMode::demand) {
      const std::uint64_t tagged = (1ull << 32) | key;
      if (s.demand.load(std::memory_order_relaxed) != tagged) {
        s.demandNs.store(nowNs(), std::memory_order_relaxed);
        s.demand.store(tagged, std::memory_order_release);
        im.demandFaults.fetch_add(1, std::memory_order_relaxed);
        const auto slot = std::size_t(&s - im.slots.get());
        signalLoader(*im.loaders[slot % im.loaders.size()]);
      }
    }
    return ref;
  }
  const std::uint32_t finest = s.finest.load(std::memory_order_acquire);
  ref.readers_ = &s.readers;
  ref.module_ = &s.data;
  ref.finest_ = finest;
  ref.level_ = std::max(std::min(wantLevel, im.levels - 1), finest);
  ref.coarser_ = finest > wantLevel;
  ref.generation_ = wordGen(w);
  return ref;
}

PagerMetrics Pager::metrics() const {
  const Impl& im = *impl_;
  auto get = [](const std::atomic<std::uint64_t>& a) { return a.load(std::memory_order_relaxed); };
  PagerMetrics m;
  m.mode = im.options.mode;
  m.updates = get(im.updates);
  m.boxCrossings = get(im.boxCrossings);
  m.refills = get(im.refills);
  for (std::size_t d = 0; d < kDirections; ++d) {
    m.stripSignals[d] = get(im.stripSignals[d]);
    m.leadStrips[d] = im.leadStrips[d].load(std::memory_order_relaxed);
  }
  for (std::size_t i = 0; i < im.loaders.size() && i < 4; ++i) {
    m.loadsByLoader[i] = get(im.loaders[i]->published);
    m.queueLength[i] = std::uint32_t(im.loaders[i]->queue->size()) +
                       im.loaders[i]->backlog.load(std::memory_order_relaxed);
  }
  m.requested = get(im.requested);
  m.loaded = get(im.loaded);
  m.freed = get(im.freed);
  m.duplicates = get(im.duplicates);
  m.cancelledQueued = get(im.cancelledQueued);
  m.cancelledInFlight = get(im.cancelledInFlight);
  m.placeholders = get(im.placeholders);
  m.missingModules = get(im.missingModules);
  m.corruptModules = get(im.corruptModules);
  m.budgetRefusals = get(im.budgetRefusals);
  m.budgetTrimmedLevels = get(im.budgetTrimmedLevels);
  m.reclaimedBytes = get(im.reclaimedBytes);
  m.bytesRead = get(im.bytesRead);
  m.readerWaits = get(im.readerWaits);
  m.queueOverflows = get(im.queueOverflows);
  m.residentQueries = get(im.residentQueries);
  m.residentMisses = get(im.residentMisses);
  m.demandFaults = get(im.demandFaults);
  m.stolen = get(im.stolen);
  m.maxQueueLength = im.maxQueueLength.load(std::memory_order_relaxed);
  m.latency = im.latency.stats();
  m.stripLatency = im.stripLatency.stats();
  m.slots = im.slotCount;
  const ModuleRect w = im.window.load().window;
  m.windowModules = std::uint32_t(w.count());
  if (im.slots) {
    for (std::int64_t z = w.z0; z < w.z1; ++z) {
      for (std::int64_t x = w.x0; x < w.x1; ++x) {
        const std::uint64_t word =
            im.slotFor(std::uint32_t(x), std::uint32_t(z)).word.load(std::memory_order_acquire);
        if (wordKey(word) == packKey(std::uint32_t(x), std::uint32_t(z)) &&
            wordState(word) == SlotState::resident) {
          ++m.residentInWindow;
        }
      }
    }
  }
  m.holesInWindow = im.slots ? m.windowModules - m.residentInWindow : 0;
  m.poolBytes = get(im.poolBytes);
  m.poolBudgetBytes = im.options.memoryBudgetBytes;
  m.latencyEstimateSeconds = im.latencyEstimate.load(std::memory_order_relaxed);
  m.leadSeconds = im.leadSeconds.load(std::memory_order_relaxed);
  m.elapsedSeconds = double(nowNs() - im.openNs) / 1e9;
  m.modulesPerSecond = m.elapsedSeconds > 0 ? double(m.loaded) / m.elapsedSeconds : 0;
  m.readSeconds = double(get(im.readNs)) / 1e9;
  m.publishSeconds = double(get(im.publishNs)) / 1e9;
  m.prefetchPasses = get(im.prefetchPasses);
  m.prefetchBlocks = get(im.prefetchBlocks);
  m.prefetchPages = get(im.prefetchPages);
  m.prefetchMajorFaults = get(im.prefetchMajorFaults);
  m.prefetchMinorFaults = get(im.prefetchMinorFaults);
  m.lastPassSeconds = im.lastPassSeconds.load(std::memory_order_relaxed);
  m.lastSleepSeconds = im.lastSleepSeconds.load(std::memory_order_relaxed);
  return m;
}

void Pager::resetLatency() {
  impl_->latency.reset();
  impl_->stripLatency.reset();
}

bool Pager::waitIdle(double timeoutSeconds) const {
  const Impl& im = *impl_;
  const std::int64_t end = nowNs() + std::int64_t(timeoutSeconds * 1e9);
  auto idle = [&] {
    if (im.outstanding.load() != 0) return false;
    if (im.options.mode == PagerMode::demand) {
      for (std::uint32_t i = 0; i < im.slotCount; ++i) {
        if (im.slots[i].demand.load() != 0) return false;
      }
    }
    for (const auto& ld : im.loaders) {
      if (ld->queue->size() != 0) return false;
    }
    return true;
  };
  while (!idle()) {
    if (nowNs() > end) return false;
    std::this_thread::sleep_for(std::chrono::microseconds(200));
  }
  return true;
}

void Pager::stop() {
  Impl& im = *impl_;
  if (im.stopped) return;
  {
    const std::lock_guard lock(im.sleepMutex);
    im.stopping.store(true, std::memory_order_release);
  }
  im.sleepCv.notify_all();
  for (auto& ld : im.loaders) signalLoader(*ld);
  for (auto& ld : im.loaders) {
    if (ld->thread.joinable()) ld->thread.join();
  }
  if (im.prefetcher.joinable()) im.prefetcher.join();
  im.stopped = true;
}

const PagerOptions& Pager::options() const { return impl_->options; }
const PagingGeometry& Pager::geometry() const { return impl_->geometry; }

double Pager::setViewDistance(double metres) {
  impl_->planner.setViewDistance(metres);
  const double vd = impl_->planner.geometry().viewDistance;
  impl_->liveViewDistance.store(vd, std::memory_order_relaxed);
  return vd;
}

double Pager::viewDistance() const { return impl_->planner.geometry().viewDistance; }

double Pager::residentDistance(double eyeX, double eyeZ) const {
  const Impl& im = *impl_;
  const double vd = im.planner.geometry().viewDistance;
  if (!im.slots) return vd;  // mmap mode: the grid is always there
  const double e = im.geometry.moduleSize;
  const ModuleRect win = im.window.load().window;
  double nearest = vd;
  for (std::int64_t z = win.z0; z < win.z1; ++z) {
    const double dz = std::max({double(z) * e - eyeZ, 0.0, eyeZ - double(z + 1) * e});
    if (dz >= nearest) continue;
    for (std::int64_t x = win.x0; x < win.x1; ++x) {
      const double dx = std::max({double(x) * e - eyeX, 0.0, eyeX - double(x + 1) * e});
      const double d = std::hypot(dx, dz);
      if (d >= nearest) continue;
      const auto kx = std::uint32_t(x), kz = std::uint32_t(z);
      const std::uint64_t w = im.slotFor(kx, kz).word.load(std::memory_order_acquire);
      if (wordKey(w) != packKey(kx, kz) || wordState(w) != SlotState::resident) nearest = d;
    }
  }
  return nearest;
}
std::uint32_t Pager::levels() const { return impl_->levels; }
ModuleRect Pager::window() const { return impl_->window.load().window; }

}  // namespace sandtable::runtime
