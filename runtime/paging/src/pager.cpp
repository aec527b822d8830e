// The pager: residency slots, loader threads and the lock-free read path
// (docs/PAGER.md). The strip logic is in pager_plan.cpp, storage helpers
// in pager_pool.cpp, mmap mode in pager_prefetch.cpp.
#include <algorithm>
#include <cassert>
#include <cmath>
#include <cstdio>
#include <optional>

#include "pager_internal.h"
#include "sandtable/paging/retrying_source.h"
#include "sandtable/paging/world.h"
#include "sandtable/paging/remote.h"

namespace sandtable::paging {

using namespace detail;

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

/// A remote grid's blocks that could not be fetched, each logged once.
void logGridProblems(const Impl& im) {
  for (const Problem& p : im.grid->takeRemoteProblems()) {
    im.log(p.file + " at byte " + std::to_string(p.offset) + ": " + p.message + " (it stands in flat until it comes)");
  }
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
  for (const ResidentModule& d : s.data) {
    for (const module::Level& l : d.levels) now += levelCapacityBytes(l);
    now += std::uint64_t(d.objects.capacity()) * sizeof(module::Object);
  }
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
        s.readers[0].load(std::memory_order_seq_cst) != 0 || s.readers[1].load(std::memory_order_seq_cst) != 0) {
      continue;
    }
    const std::uint64_t before = s.capacityBytes;
    for (std::size_t b = 0; b < s.data.size(); ++b) {
      std::vector<module::Object>().swap(s.data[b].objects);
      std::vector<module::Level>& levels = s.data[b].levels;
      for (std::size_t l = 0; l < levels.size(); ++l) {
        module::Level fresh;  // buffer 0 keeps the placeholder reserve; the reload buffer keeps nothing
        if (b == 0 && l + 1 == levels.size()) reserveLike(im.placeholderProto, fresh);
        if (levelCapacityBytes(fresh) < levelCapacityBytes(levels[l])) levels[l] = std::move(fresh);
      }
    }
    settleCapacity(im, s, 0);
    if (before > s.capacityBytes) {
      im.count.reclaimedBytes.fetch_add(before - s.capacityBytes, std::memory_order_relaxed);
    }
  }
}

/// Copies one decoded level into buffer `b` of the slot if the budget allows.
bool copyWithinBudget(Impl& im, Slot& s, const module::Level& src, std::uint32_t l, std::uint32_t b = 0) {
  const std::uint64_t growth = levelGrowthBytes(src, s.data[b].levels[l]);
  if (growth > 0 && !takeBudget(im, growth)) {
    reclaimEmptySlots(im, s, growth);
    if (!takeBudget(im, growth)) return false;
  }
  copyLevel(src, s.data[b].levels[l]);
  settleCapacity(im, s, growth);
  return true;
}

/// Copies a module's objects list into `d` if the budget allows (it counts
/// in the pool as the levels do); when it does not fit even after
/// reclaiming, the module stays without its objects (`budgetRefusals`).
void copyObjectsWithinBudget(Impl& im, Slot& s, ResidentModule& d, const std::vector<module::Object>& src) {
  const std::uint64_t growth =
      src.size() > d.objects.capacity() ? (src.size() - d.objects.capacity()) * sizeof(module::Object) : 0;
  if (growth > 0 && !takeBudget(im, growth)) {
    reclaimEmptySlots(im, s, growth);
    if (!takeBudget(im, growth)) {
      d.objects.clear();
      im.count.budgetRefusals.fetch_add(1, std::memory_order_relaxed);
      return;
    }
  }
  d.objects.assign(src.begin(), src.end());
  settleCapacity(im, s, growth);
}

// ------------------------------------------------------------ the loads

/// The module failed to read at the source's generation `gen`.
bool knownBad(Impl& im, std::uint32_t key, std::uint64_t gen) {
  const std::lock_guard lock(im.badMutex);
  const auto it = im.badModules.find(key);
  return it != im.badModules.end() && it->second == gen;
}

/// This loader's decoded module, whose capacity is reused from read to
/// read: in steady state a load allocates nothing.
module::Module& loaderModule() {
  thread_local module::Module loaded;
  return loaded;
}

struct ReadOutcome {
  std::uint64_t generation = 0;  ///< the source's, of what was read (or tried)
  std::string failure;           ///< "" when read
  bool missing = false;
};

/// The finest level a fresh load publishes at once: the source's coarse
/// level when coarse-first applies, else 0 (one read of every level).
std::uint32_t firstReadLevel(const Impl& im) {
  if (!im.options.coarseFirst || !im.source) return 0;
  return std::min(im.source->coarseLevel(), im.levels - 1);
}

/// One read from the source into loaderModule(), timed and counted: the
/// coarse part only with `coarseOnly` (and a source that splits), else the
/// whole module.
ReadOutcome readModule(Impl& im, ModuleKey k, bool coarseOnly = false) {
  ReadOutcome out;
  const ModuleInfo info = im.source->info(k.kx, k.kz);
  if (info.storedBytes > 0 && im.options.simulatedReadSeconds > 0) {
    std::this_thread::sleep_for(std::chrono::duration<double>(im.options.simulatedReadSeconds));
  }
  out.generation = im.source->generation(k.kx, k.kz);
  const std::int64_t t0 = nowNs();
  const bool split = coarseOnly && firstReadLevel(im) > 0;
  const Result<std::uint64_t> r =
      split ? im.source->readCoarse(k.kx, k.kz, loaderModule()) : im.source->read(k.kx, k.kz, loaderModule());
  if (info.storedBytes > 0) {
    im.readNs.fetch_add(std::uint64_t(nowNs() - t0), std::memory_order_relaxed);
    im.count.bytesRead.fetch_add(split ? info.storedBytes - info.fineBytes : info.storedBytes,
                                 std::memory_order_relaxed);
  }
  if (r.ok()) {
    out.generation = r.value();
    if (loaderModule().levels.size() != im.levels) {
      out.failure = "pager: module (" + std::to_string(k.kx) + ", " + std::to_string(k.kz) + ") has " +
                    std::to_string(loaderModule().levels.size()) + " levels, the source's layout " +
                    std::to_string(im.levels);
    }
  } else {
    out.failure = r.error();
    out.missing = im.source->missing(k.kx, k.kz);
  }
  return out;
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

void publishFinerLevels(Impl& im, Slot& s, const module::Module& m, std::uint32_t from, std::uint32_t to);

/// Publishes a loader's backlog counts; called with its pendingMutex held.
void storeBacklog(Loader& ld) {
  ld.backlog.store(std::uint32_t(ld.pending.size()), std::memory_order_relaxed);
  const auto coarse = std::count_if(ld.pending.begin(), ld.pending.end(), [](const Pending& q) { return q.fine == 0; });
  ld.coarseBacklog.store(std::uint32_t(coarse), std::memory_order_relaxed);
}

/// PagerOptions::prepareLevel on level l of d, written and not yet
/// published (the worker phase of the load).
void prepareLevel(Impl& im, ResidentModule& d, std::uint32_t l) {
  if (im.options.prepareLevel) im.options.prepareLevel(d, l);
}

/// Reads module p.key into slot s (whose `write` the caller holds) and
/// publishes it, coarse level first, unless it is resident already. With
/// coarse-first, only the coarse levels are read and published; returns
/// true when the fine levels are still to be loaded (loadFine).
bool loadFresh(Impl& im, Loader& ld, Slot& s, const Pending& p) {
  const ModuleKey k = unpackKey(p.key);
  // Claim the slot. The seq_cst CAS stops new readers from being admitted
  // to the old occupant; the seq_cst load of `readers` after it then sees
  // every reader that was admitted (docs/PAGER.md, section 4).
  std::uint64_t w = s.word.load(std::memory_order_seq_cst);
  std::uint64_t gen = 0;
  for (;;) {
    if (wordKey(w) == p.key && wordState(w) != SlotState::empty) {
      const bool stale = wordState(w) == SlotState::resident &&
                         s.data[wordBuffer(w)].generation < im.source->generation(k.kx, k.kz);
      if (!stale) im.count.duplicates.fetch_add(1, std::memory_order_relaxed);
      return false;  // a stale one is a change notice: loadModule reloads it
    }
    gen = (wordGen(w) + 1) & kGenMask;
    if (s.word.compare_exchange_weak(w, makeWord(p.key, SlotState::loading, gen),
                                     std::memory_order_seq_cst)) {
      break;
    }
  }
  // Reusing a slot whose module left the window frees that module.
  if (wordState(w) != SlotState::empty) im.count.freed.fetch_add(1, std::memory_order_relaxed);
  // A fresh load goes into buffer 0; readers of the other buffer (an older
  // module's reloaded generation) are never in its way.
  if (s.readers[0].load(std::memory_order_seq_cst) != 0) {
    im.count.readerWaits.fetch_add(1, std::memory_order_relaxed);
    while (s.readers[0].load(std::memory_order_seq_cst) != 0) std::this_thread::yield();
  }

  // Read (for the pack: one pread, CRC, zstd, decode) into this loader's
  // own module, whose capacity is reused: a load allocates nothing.
  const std::uint64_t sourceGen = im.source->generation(k.kx, k.kz);
  const bool bad = knownBad(im, p.key, sourceGen);
  ReadOutcome read;
  read.generation = sourceGen;
  const std::uint32_t firstLevel = firstReadLevel(im);
  if (!bad) read = readModule(im, k, true);
  const module::Module& loaded = loaderModule();
  const std::string& failure = read.failure;
  const bool missing = read.missing;
  if (!im.window.load().window.contains(k.kx, k.kz)) {
    // Left the window during the read: give the slot back unpublished.
    im.count.cancelledInFlight.fetch_add(1, std::memory_order_relaxed);
    std::uint64_t expect = makeWord(p.key, SlotState::loading, gen);
    s.word.compare_exchange_strong(expect, makeWord(p.key, SlotState::empty, gen + 1),
                                   std::memory_order_seq_cst);
    return false;
  }

  // The coarsest level first (or a placeholder).
  const PublishTimer timer(im);
  const std::uint32_t coarse = im.levels - 1;
  ResidentModule& d = s.data[0];
  d.kx = k.kx;
  d.kz = k.kz;
  d.generation = read.generation;
  bool placeholder = bad || !failure.empty();
  if (!placeholder && !copyWithinBudget(im, s, loaded.levels[coarse], coarse)) {
    placeholder = true;
    im.count.budgetRefusals.fetch_add(1, std::memory_order_relaxed);
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
        first = im.badModules.insert_or_assign(p.key, read.generation).second;
      }
      if (first) {
        (missing ? im.count.missingModules : im.count.corruptModules).fetch_add(1, std::memory_order_relaxed);
        im.log(failure + " (a coarse placeholder stands in; logged once per module)");
      }
    }
    buildPlaceholder(*im.grid, im.header, k.kx, k.kz, im.placeholderMaterial, d.levels[coarse]);
    settleCapacity(im, s, 0);
    im.count.placeholders.fetch_add(1, std::memory_order_relaxed);
  }
  d.placeholder = placeholder;
  if (placeholder) d.objects.clear();
  else copyObjectsWithinBudget(im, s, d, loaded.objects);
  prepareLevel(im, d, coarse);
  s.finest[0].store(coarse, std::memory_order_release);
  std::uint64_t expect = makeWord(p.key, SlotState::loading, gen);
  if (!s.word.compare_exchange_strong(expect, makeWord(p.key, SlotState::resident, gen),
                                      std::memory_order_seq_cst)) {
    im.count.cancelledInFlight.fetch_add(1, std::memory_order_relaxed);  // freed meanwhile
    return false;
  }
  recordLatency(im, p);
  ld.published.fetch_add(1, std::memory_order_relaxed);
  if (!placeholder) im.count.loaded.fetch_add(1, std::memory_order_relaxed);
  if (im.options.onResident) im.options.onResident(ld.index, k, placeholder);
  if (placeholder) return false;
  publishFinerLevels(im, s, loaded, coarse, firstLevel);
  return firstLevel > 0 && s.finest[0].load(std::memory_order_relaxed) == firstLevel;
}

/// Coarse-first: reads the fine levels of module p.key, whose coarse
/// levels a loadFresh published into buffer 0, and publishes them finest
/// last. Nothing to do when the module left the slot, is a placeholder, was
/// reloaded (buffer 1 holds every level) or is fine already.
void loadFine(Impl& im, const Pending& p) {
  const ModuleKey k = unpackKey(p.key);
  if (!im.window.load().window.contains(k.kx, k.kz)) {
    im.count.cancelledQueued.fetch_add(1, std::memory_order_relaxed);
    return;
  }
  Slot& s = im.slotFor(k.kx, k.kz);
  const std::unique_lock lock(s.write);
  const std::uint32_t first = firstReadLevel(im);
  const std::uint64_t w = s.word.load(std::memory_order_seq_cst);
  ResidentModule& d = s.data[0];
  if (first == 0 || wordKey(w) != p.key || wordState(w) != SlotState::resident || wordBuffer(w) != 0 ||
      d.placeholder || s.finest[0].load(std::memory_order_relaxed) != first ||
      d.generation != im.source->generation(k.kx, k.kz)) {
    return;
  }
  // Holding `write`, no loader can claim the slot. A free may still empty
  // it meanwhile; the levels below `finest` written here are read by no
  // reader either way (docs/PAGER.md, section 4).
  const ModuleInfo info = im.source->info(k.kx, k.kz);
  const std::int64_t t0 = nowNs();
  const Status r = im.source->readFine(k.kx, k.kz, loaderModule());
  im.readNs.fetch_add(std::uint64_t(nowNs() - t0), std::memory_order_relaxed);
  im.count.bytesRead.fetch_add(info.fineBytes, std::memory_order_relaxed);
  if (!r) {
    im.count.fineFailed.fetch_add(1, std::memory_order_relaxed);
    im.log(r.message() + " (the coarse levels stay drawn)");
    return;
  }
  const std::uint64_t now = s.word.load(std::memory_order_seq_cst);
  if (now != w || !im.window.load().window.contains(k.kx, k.kz)) {
    im.count.cancelledInFlight.fetch_add(1, std::memory_order_relaxed);
    return;
  }
  const PublishTimer timer(im);
  publishFinerLevels(im, s, loaderModule(), first, 0);
  im.count.fineLoaded.fetch_add(1, std::memory_order_relaxed);
}

void reloadWhileStale(Impl& im, Loader& ld, Slot& s, std::uint32_t key);

/// Reads module p.key into its slot and publishes it, coarse level first.
/// A module resident at an older generation than the source's (a change
/// notice, or a source that moved on during the read) is reloaded.
void loadModule(Impl& im, Loader& ld, const Pending& p) {
  const ModuleKey k = unpackKey(p.key);
  if (!im.window.load().window.contains(k.kx, k.kz)) {
    im.count.cancelledQueued.fetch_add(1, std::memory_order_relaxed);
    return;
  }
  Slot& s = im.slotFor(k.kx, k.kz);
  bool fine = false;
  {
    const std::unique_lock lock(s.write);  // loaders only; readers never take it
    fine = loadFresh(im, ld, s, p);
    reloadWhileStale(im, ld, s, p.key);
  }
  if (!fine) return;
  // The fine levels wait behind every coarse load of this loader (takeNearest).
  {
    const std::lock_guard pl(ld.pendingMutex);
    if (ld.pending.size() < ld.pending.capacity()) {
      im.outstanding.fetch_add(1);
      ld.pending.push_back({p.key, p.refill, 1, p.requestNs});
      storeBacklog(ld);
      return;
    }
  }
  loadFine(im, {p.key, p.refill, 1, p.requestNs});  // no room to queue it: read it now
}

/// Publishes m's levels from-1 down to `to` into buffer 0 of a slot whose
/// level `from` is published, finest last.
void publishFinerLevels(Impl& im, Slot& s, const module::Module& m, std::uint32_t from, std::uint32_t to) {
  // Each finer level is published by a release store of `finest`: readers
  // admitted meanwhile use only levels >= the finest they loaded, which
  // this loop no longer writes.
  for (std::uint32_t l = from; l-- > to;) {
    if (!copyWithinBudget(im, s, m.levels[l], l)) {
      im.count.budgetTrimmedLevels.fetch_add(l + 1, std::memory_order_relaxed);
      if (!im.loggedBudget.exchange(true)) {
        im.log("the memory budget of " + std::to_string(im.options.memoryBudgetBytes) +
               " bytes is spent: fine levels are left out (logged once)");
      }
      break;
    }
    prepareLevel(im, s.data[0], l);
    s.finest[0].store(l, std::memory_order_release);
  }
}

/// Replaces the resident module of slot `s` (word `w`, its key's module,
/// older than the source's generation) by the source's newer generation,
/// with no hole: the new levels go into the buffer readers are not
/// admitted to, and one CAS flips the word to it. If the read fails or
/// the budget refuses, the older generation stays. Holds s.write.
void reloadModule(Impl& im, Loader& ld, Slot& s, std::uint64_t w) {
  const ModuleKey k = unpackKey(wordKey(w));
  const ReadOutcome read = readModule(im, k);
  if (!read.failure.empty()) {
    im.log(read.failure + " (generation " + std::to_string(read.generation) + "; the older one stays drawn)");
    return;
  }
  if (!im.window.load().window.contains(k.kx, k.kz)) {
    im.count.cancelledInFlight.fetch_add(1, std::memory_order_relaxed);
    return;
  }
  const PublishTimer timer(im);
  const std::uint32_t nb = wordBuffer(w) ^ 1u;
  // Readers of buffer nb were admitted before the last flip away from it;
  // a reader that loaded an older word and arrives now sees the word
  // changed and leaves without reading (resident()).
  if (s.readers[nb].load(std::memory_order_seq_cst) != 0) {
    im.count.readerWaits.fetch_add(1, std::memory_order_relaxed);
    while (s.readers[nb].load(std::memory_order_seq_cst) != 0) std::this_thread::yield();
  }
  const module::Module& m = loaderModule();
  const std::uint32_t coarse = im.levels - 1;
  std::uint32_t finest = im.levels;
  for (std::uint32_t l = im.levels; l-- > 0;) {
    if (!copyWithinBudget(im, s, m.levels[l], l, nb)) {
      (l == coarse ? im.count.budgetRefusals : im.count.budgetTrimmedLevels)
          .fetch_add(l == coarse ? 1 : l + 1, std::memory_order_relaxed);
      break;
    }
    finest = l;
  }
  if (finest == im.levels) return;  // not even the coarsest fits: keep the older one
  ResidentModule& d = s.data[nb];
  d.kx = k.kx;
  d.kz = k.kz;
  d.placeholder = false;
  d.generation = read.generation;
  copyObjectsWithinBudget(im, s, d, m.objects);
  for (std::uint32_t l = im.levels; l-- > finest;) prepareLevel(im, d, l);
  s.finest[nb].store(finest, std::memory_order_release);
  std::uint64_t expect = w;
  if (!s.word.compare_exchange_strong(
          expect, makeWord(wordKey(w), SlotState::resident, (wordGen(w) + 1) & kGenMask, nb),
          std::memory_order_seq_cst)) {
    im.count.cancelledInFlight.fetch_add(1, std::memory_order_relaxed);  // freed meanwhile
    return;
  }
  {
    const std::lock_guard bl(im.badMutex);
    im.badModules.erase(wordKey(w));
  }
  im.count.reloaded.fetch_add(1, std::memory_order_relaxed);
  ld.published.fetch_add(1, std::memory_order_relaxed);
  if (im.options.onResident) im.options.onResident(ld.index, k, false);
}

/// While slot `s` holds `key` resident at an older generation than the
/// source's, reloads it (a few times at most: a source changing faster
/// than it reads is caught by its next change notice). Holds s.write.
void reloadWhileStale(Impl& im, Loader& ld, Slot& s, std::uint32_t key) {
  const ModuleKey k = unpackKey(key);
  for (int tries = 0; tries < 4; ++tries) {
    const std::uint64_t w = s.word.load(std::memory_order_seq_cst);
    if (wordKey(w) != key || wordState(w) != SlotState::resident) return;
    if (s.data[wordBuffer(w)].generation >= im.source->generation(k.kx, k.kz)) return;
    reloadModule(im, ld, s, w);
  }
}

/// Frees module `key` unless it is (again) in the window.
void freeModule(Impl& im, std::uint32_t key) {
  const ModuleKey k = unpackKey(key);
  if (im.window.load().window.contains(k.kx, k.kz)) return;  // stale: it came back
  Slot& s = im.slotFor(k.kx, k.kz);
  std::uint64_t w = s.word.load(std::memory_order_seq_cst);
  while (wordKey(w) == key && wordState(w) != SlotState::empty) {
    if (s.word.compare_exchange_weak(w, makeWord(key, SlotState::empty, wordGen(w) + 1, wordBuffer(w)),
                                     std::memory_order_seq_cst)) {
      im.count.freed.fetch_add(1, std::memory_order_relaxed);
      return;
    }
  }
}

void noteBacklog(Impl& im, Loader& ld) {
  storeBacklog(ld);
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
      const Slot& s = im.slotFor(std::uint32_t(x), std::uint32_t(z));
      const std::uint64_t word = s.word.load();
      std::uint8_t fine = 0;
      if (wordKey(word) == key && wordState(word) != SlotState::empty) {
        // Resident with only its coarse levels: its fine job may be what was lost.
        const std::uint32_t first = firstReadLevel(im);
        if (first == 0 || wordState(word) != SlotState::resident || wordBuffer(word) != 0 ||
            s.finest[0].load() != first) {
          continue;
        }
        fine = 1;
      }
      im.outstanding.fetch_add(1);
      ld.pending.push_back({key, 1, fine, now});
    }
  }
}

/// Takes the pending module nearest the eye, dropping those that left the
/// window (cancelled before their read began).
std::optional<Pending> takeNearest(Impl& im, Loader& ld, bool coarseOnly = false) {
  const WindowState ws = im.window.load();
  const double e = im.geometry.moduleSize;
  std::optional<Pending> best;
  double bestD = 0;
  bool bestFine = false;
  std::size_t bestI = 0;
  for (std::size_t i = 0; i < ld.pending.size();) {
    const ModuleKey k = unpackKey(ld.pending[i].key);
    if (!ws.window.contains(k.kx, k.kz)) {
      im.count.cancelledQueued.fetch_add(1, std::memory_order_relaxed);
      im.outstanding.fetch_sub(1);
      ld.pending[i] = ld.pending.back();
      ld.pending.pop_back();
      continue;
    }
    const double dx = (k.kx + 0.5) * e - ws.eyeX, dz = (k.kz + 0.5) * e - ws.eyeZ;
    // Coarse-first: every coarse load before any fine one, each kind
    // nearest first.
    const double d = dx * dx + dz * dz;
    const bool fine = ld.pending[i].fine != 0;
    if (fine && coarseOnly) {
      ++i;
      continue;
    }
    if (!best || fine < bestFine || (fine == bestFine && d < bestD)) {
      best = ld.pending[i];
      bestD = d;
      bestFine = fine;
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
      ld.pending.push_back({r.key, r.refill, 0, r.requestNs});
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
                                    [&](const Pending& q) { return q.key == key && !q.fine; });
    if (v == 0 || queued) {
      im.outstanding.fetch_sub(1);
      continue;
    }
    im.count.requested.fetch_add(1, std::memory_order_relaxed);
    ld.pending.push_back({key, 0, 0, t});
  }
}

/// Work stealing: the nearest pending module of the loader with the
/// largest backlog, taken under that loader's pending mutex; with
/// `coarseOnly`, the nearest coarse load of the loader with the most of them.
std::optional<Pending> steal(Impl& im, const Loader& self, bool coarseOnly = false) {
  Loader* victim = nullptr;
  std::uint32_t most = 0;
  for (const auto& l : im.loaders) {
    const std::uint32_t b = (coarseOnly ? l->coarseBacklog : l->backlog).load(std::memory_order_relaxed);
    if (l.get() != &self && b > most) {
      most = b;
      victim = l.get();
    }
  }
  if (victim == nullptr) return std::nullopt;
  const std::lock_guard lock(victim->pendingMutex);
  std::optional<Pending> p = takeNearest(im, *victim, coarseOnly);
  storeBacklog(*victim);
  return p;
}

/// Another loader has requests it has not drained yet, or loads pending:
/// any, or with `coarseOnly` coarse ones (most undrained requests are
/// coarse loads, so they count either way).
bool workElsewhere(const Impl& im, const Loader& self, bool coarseOnly = false) {
  return std::any_of(im.loaders.begin(), im.loaders.end(), [&](const auto& l) {
    const auto& pending = coarseOnly ? l->coarseBacklog : l->backlog;
    return l.get() != &self && (pending.load(std::memory_order_relaxed) > 0 || l->queue->size() > 0);
  });
}

void loaderLoop(Impl& im, Loader& ld) {
  const bool demand = im.options.mode == PagerMode::demand;
  const bool stealing = !demand && im.options.workStealing && im.loaders.size() > 1;
  for (;;) {
    const std::uint32_t seen = ld.signal.load(std::memory_order_acquire);
    if (im.stopping.load(std::memory_order_acquire)) break;
    std::optional<Pending> p;
    thread_local std::vector<ModuleKey> fresh;  // the loads just taken: hinted outside the lock
    fresh.clear();
    {
      const std::lock_guard lock(ld.pendingMutex);
      const std::size_t before = ld.pending.size();
      if (demand) {
        collectFaults(im, ld);
      } else {
        drainQueue(im, ld);
        if (ld.resync.exchange(false)) resync(im, ld);
      }
      if (im.options.readaheadHints) {
        for (std::size_t i = before; i < ld.pending.size(); ++i) {
          if (!ld.pending[i].fine) fresh.push_back(unpackKey(ld.pending[i].key));
        }
      }
      noteBacklog(im, ld);
      if (!ld.pending.empty()) {
        p = takeNearest(im, ld);
        storeBacklog(ld);
      }
    }
    if (!fresh.empty()) {
      hintStrip(im, fresh);
      im.count.readaheadHints.fetch_add(1, std::memory_order_relaxed);
    }
    bool stolen = false;
    if (p && p->fine && stealing && workElsewhere(im, ld, true)) {
      // Coarse first across loaders too: a fine record (a tenth of the
      // module's bytes but most of its decode, trees included) read here
      // would take a core from another loader's coarse loads, the ones
      // whose lateness is a hole. Put it back and help with those instead.
      {
        const std::lock_guard lock(ld.pendingMutex);
        ld.pending.push_back(*p);
        storeBacklog(ld);
      }
      p = steal(im, ld, true);
      stolen = p.has_value();
      if (!p) {
        // Only undrained queues: their owners take them after their
        // current load; leave them the core meanwhile.
        std::this_thread::sleep_for(std::chrono::microseconds(200));
        continue;
      }
    }
    if (!p && stealing) {
      p = steal(im, ld);
      stolen = p.has_value();
    }
    if (p) {
      if (stolen) im.count.stolen.fetch_add(1, std::memory_order_relaxed);
      if (p->fine) {
        loadFine(im, *p);
      } else {
        loadModule(im, ld, *p);
      }
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
      const auto raw = std::uint32_t(im.source->info(x, z).rawBytes);
      if (raw > 0) sizes.emplace_back(raw, z * h.modulesX + x);
    }
  }
  if (sizes.empty()) return;
  const auto nth = sizes.begin() + std::ptrdiff_t((sizes.size() - 1) / 2);
  std::nth_element(sizes.begin(), nth, sizes.end());
  module::Module median;
  const module::Module* m = &median;
  if (!im.source->read(nth->second % h.modulesX, nth->second / h.modulesX, median).ok() ||
      median.levels.size() != im.levels) {
    return;
  }
  const std::uint64_t cap = im.options.memoryBudgetBytes / 4;
  for (std::uint32_t i = 0; i < im.slotCount; ++i) {
    Slot& s = im.slots[i];
    std::uint64_t growth = 0;
    for (std::uint32_t l = 0; l < im.levels; ++l) {
      growth += levelGrowthBytes(m->levels[l], s.data[0].levels[l]);
    }
    if (im.poolBytes.load(std::memory_order_relaxed) + growth > cap || !takeBudget(im, growth)) {
      return;
    }
    for (std::uint32_t l = 0; l < im.levels; ++l) reserveLike(m->levels[l], s.data[0].levels[l]);
    settleCapacity(im, s, growth);
  }
}

/// Main thread, every update: the source's changed modules that are in
/// the window go to a loader (predictive) or are faulted (demand), which
/// reloads each one resident at an older generation. Changes outside the
/// window need nothing: a later load reads the newest generation.
void pollChanges(Impl& im, const ModuleRect& window, std::int64_t now) {
  const std::uint64_t c = im.source->changes();
  if (c == im.seenChanges) return;
  im.changed.clear();
  im.seenChanges = im.source->changedSince(im.seenChanges, im.changed);
  const std::size_t n = im.loaders.size();
  for (const ModuleKey& k : im.changed) {
    if (!window.contains(k.kx, k.kz)) continue;
    Slot& s = im.slotFor(k.kx, k.kz);
    const std::uint32_t key = packKey(k.kx, k.kz);
    const auto slot = std::size_t(&s - im.slots.get());
    Loader& ld = *im.loaders[slot % n];
    if (im.options.mode == PagerMode::demand) {
      s.demandNs.store(now, std::memory_order_relaxed);
      s.demand.store((1ull << 32) | key, std::memory_order_release);
    } else {
      im.outstanding.fetch_add(1);
      if (!ld.queue->push({key, 0, 0, now})) {
        im.outstanding.fetch_sub(1);
        im.count.queueOverflows.fetch_add(1, std::memory_order_relaxed);
        ld.resync.store(true);
      }
    }
    signalLoader(ld);
  }
}

}  // namespace

// ------------------------------------------------------------------ Pager

Pager::Pager(std::unique_ptr<Impl> impl) : impl_(std::move(impl)) {}

Pager::~Pager() { stop(); }

Result<std::unique_ptr<Pager>> Pager::open(std::shared_ptr<const grid::GridFile> grid,
                                           std::shared_ptr<const ModuleSource> source,
                                           const PagerOptions& options) {
  return openWith(std::move(grid), std::move(source), options, 0);
}

Result<std::unique_ptr<Pager>> Pager::open(std::shared_ptr<const grid::GridFile> grid,
                                           std::shared_ptr<const pack::PackReader> pack,
                                           const PagerOptions& options) {
  return openWith(std::move(grid), packSourceOf(std::move(pack)), options, 0);
}

Result<std::unique_ptr<Pager>> Pager::open(std::shared_ptr<const grid::GridFile> grid, std::nullptr_t,
                                           const PagerOptions& options) {
  return openWith(std::move(grid), nullptr, options, 0);
}

Result<std::unique_ptr<Pager>> Pager::open(const Database& db, const PagerOptions& options) {
  return openWith(db.grid, packSourceOf(db.modules), options, db.materials ? db.materials->defaultArea : 0);
}

Result<std::unique_ptr<Pager>> Pager::open(const World& world, const PagerOptions& options) {
  return openWith(world.gridFile(), world.modules(), options, world.materials() ? world.materials()->defaultArea : 0);
}

Result<std::unique_ptr<Pager>> Pager::open(const std::string& directory,
                                           const PagerOptions& options) {
  auto db = openDatabaseAt(directory);  // a URL too (remote.h)
  if (!db) return db.problems();
  return open(db.value(), options);
}

Result<std::unique_ptr<Pager>> Pager::openWith(std::shared_ptr<const grid::GridFile> grid,
                                               std::shared_ptr<const ModuleSource> source,
                                               const PagerOptions& options,
                                               std::uint16_t material) {
  if (!grid) return Problem{"pager", 0, "pager: no grid"};
  if (options.mode != PagerMode::mmap && !source) {
    return Problem{grid->path(), 0,
                   "pager: the database has no load modules (modules.pack); build it with "
                   "modules or use mode mmap"};
  }
  const pack::IndexHeader header = source ? source->header() : pack::IndexHeader{};
  PagingGeometry g;
  g.moduleSize = source ? header.moduleSize : options.mmapModuleSize;
  if (!(g.moduleSize > 0)) return Problem{"pager", 0, "pager: the module size is not positive"};
  if (const std::string err = checkOptions(options, g.moduleSize); !err.empty()) {
    return Problem{"pager options", 0, "pager options: " + err};
  }
  if (source) {
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
  if (im->grid->remote()) im->gridFetches = std::make_unique<jobs::SerialQueue>();
  im->source = std::move(source);
  im->header = header;
  im->levels = im->source ? std::max<std::uint32_t>(1, header.levels) : 1;
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
      s.data[0].levels.resize(im->levels);
      s.data[1].levels.resize(im->levels);
      if (options.prepareLevel) {
        s.data[0].prepared.resize(im->levels);
        s.data[1].prepared.resize(im->levels);
      }
      reserveLike(proto, s.data[0].levels[im->levels - 1]);
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
    im->changed.reserve(64);
    im->seenChanges = im->source->changes();
    const std::uint32_t n = options.loaderThreads;
    for (std::uint32_t i = 0; i < n; ++i) {
      auto ld = std::make_unique<Loader>();
      ld->index = i;
      ld->queue = std::make_unique<SpscQueue>(nextPow2(std::max<std::size_t>(64, 4 * im->slotCount)));
      // Room for a load and a fine job of every slot.
      ld->pending.reserve(3 * std::size_t(im->slotCount) + 16);
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

namespace {

/// Running mean of the time between updates (weight 1/8, like srtt), each
/// interval capped at kMaxUpdateInterval so that a pause does not turn into
/// a long lead.
void noteUpdateInterval(Pager::Impl& im, double timeNow) {
  constexpr double kMaxUpdateInterval = 0.25;
  const double dt = timeNow - im.lastTime;
  if (!im.haveTime || !(dt > 0) || !std::isfinite(dt)) return;
  const double x = std::min(dt, kMaxUpdateInterval);
  im.updateInterval = im.haveInterval ? 0.875 * im.updateInterval + 0.125 * x : x;
  im.haveInterval = true;
}

}  // namespace

void Pager::update(double eyeX, double eyeZ, double velocityX, double velocityZ, double timeNow) {
  Impl& im = *impl_;
  if (im.stopped) return;
  im.count.updates.fetch_add(1, std::memory_order_relaxed);
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
  noteUpdateInterval(im, timeNow);
  im.lastTime = timeNow;
  im.haveTime = true;
  if (im.gridFetches) {
    logGridProblems(im);
    fetchGridAhead(im, eyeX, eyeZ, velocityX, velocityZ);
  }

  // The window moves only at updates, so a strip asked for now must also
  // be in before the eye has gone one more update's way (at 1,000,000 km/h
  // and 60 Hz that is 4.6 modules, more than the latency alone asked for).
  const double lead = im.options.mode == PagerMode::demand || !(im.options.lookAheadScale > 0)
                          ? 0.0
                          : im.options.lookAheadScale * im.latencyEstimate.load(std::memory_order_relaxed) +
                                im.updateInterval;
  im.leadSeconds.store(lead, std::memory_order_relaxed);
  const bool predictive = im.options.mode == PagerMode::predictive && lead > 0;
  const PlanStep& st = im.planner.update(eyeX, eyeZ, velocityX, velocityZ, predictive ? lead : 0.0,
                                         predictive ? im.updateInterval : 0.0);
  im.window.store({st.after, eyeX, eyeZ, velocityX, velocityZ});
  for (std::size_t d = 0; d < kDirections; ++d) {
    im.leadStrips[d].store(im.planner.lead()[d], std::memory_order_relaxed);
  }
  if (im.source && im.options.mode != PagerMode::mmap) pollChanges(im, st.after, nowNs());
  if (st.crossed) im.count.boxCrossings.fetch_add(1, std::memory_order_relaxed);
  if (st.refill) im.count.refills.fetch_add(1, std::memory_order_relaxed);
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
        im.count.queueOverflows.fetch_add(1, std::memory_order_relaxed);
        ld.resync.store(true);
      }
    };
    for (const ModuleKey& k : job.free) push({packKey(k.kx, k.kz), 1, 0, now});
    for (const ModuleKey& k : job.load) {
      push({packKey(k.kx, k.kz), 0, std::uint8_t(st.refill ? 1 : 0), now});
    }
    im.count.requested.fetch_add(job.load.size(), std::memory_order_relaxed);
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
  im.count.residentQueries.fetch_add(1, std::memory_order_relaxed);
  Slot& s = im.slotFor(kx, kz);
  const std::uint32_t key = packKey(kx, kz);
  // Admission: see the word, announce on its buffer, then check that the
  // word is unchanged (seq_cst all three; see loadModule and reloadModule).
  // A reload flipping the buffer in between costs one more try; two flips
  // in that instant read as a miss, so the read stays wait-free.
  std::uint64_t w = s.word.load(std::memory_order_seq_cst);
  bool admitted = false;
  for (int tries = 0; tries < 2 && wordKey(w) == key && wordState(w) == SlotState::resident; ++tries) {
    std::atomic<std::uint32_t>& readers = s.readers[wordBuffer(w)];
    readers.fetch_add(1, std::memory_order_seq_cst);
    const std::uint64_t again = s.word.load(std::memory_order_seq_cst);
    if (again == w) {
      admitted = true;
      break;
    }
    readers.fetch_sub(1, std::memory_order_release);
    w = again;
  }
  if (!admitted) {
    im.count.residentMisses.fetch_add(1, std::memory_order_relaxed);
    if (im.options.mode == PagerMode::demand) {
      const std::uint64_t tagged = (1ull << 32) | key;
      if (s.demand.load(std::memory_order_relaxed) != tagged) {
        s.demandNs.store(nowNs(), std::memory_order_relaxed);
        s.demand.store(tagged, std::memory_order_release);
        im.count.demandFaults.fetch_add(1, std::memory_order_relaxed);
        const auto slot = std::size_t(&s - im.slots.get());
        signalLoader(*im.loaders[slot % im.loaders.size()]);
      }
    }
    return ref;
  }
  const std::uint32_t b = wordBuffer(w);
  const std::uint32_t finest = s.finest[b].load(std::memory_order_acquire);
  ref.readers_ = &s.readers[b];
  ref.module_ = &s.data[b];
  ref.finest_ = finest;
  ref.level_ = std::max(std::min(wantLevel, im.levels - 1), finest);
  ref.coarser_ = finest > wantLevel;
  ref.generation_ = wordGen(w);
  return ref;
}

namespace {

/// Every counter, each loaded once (relaxed).
PagerCounters snapshot(const PagerCountersOf<std::atomic<std::uint64_t>>& live) {
  static_assert(sizeof(PagerCounters) ==
                    std::tuple_size_v<decltype(std::declval<PagerCounters&>().fields())> * sizeof(std::uint64_t),
                "a counter of PagerCountersOf is missing from fields()");
  PagerCounters out;
  std::apply([&](auto&... dst) {
    std::apply([&](const auto&... src) { ((dst = src.load(std::memory_order_relaxed)), ...); }, live.fields());
  }, out.fields());
  return out;
}

}  // namespace

PagerMetrics Pager::metrics() const {
  const Impl& im = *impl_;
  auto get = [](const std::atomic<std::uint64_t>& a) { return a.load(std::memory_order_relaxed); };
  PagerMetrics m;
  static_cast<PagerCounters&>(m) = snapshot(im.count);
  m.mode = im.options.mode;
  for (std::size_t d = 0; d < kDirections; ++d) {
    m.stripSignals[d] = get(im.stripSignals[d]);
    m.leadStrips[d] = im.leadStrips[d].load(std::memory_order_relaxed);
  }
  for (std::size_t i = 0; i < im.loaders.size() && i < 4; ++i) {
    m.loadsByLoader[i] = get(im.loaders[i]->published);
    m.queueLength[i] = std::uint32_t(im.loaders[i]->queue->size()) +
                       im.loaders[i]->backlog.load(std::memory_order_relaxed);
  }
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
  if (im.gridFetches) {
    im.gridFetches->wait();
    logGridProblems(im);
  }
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

}  // namespace sandtable::paging
