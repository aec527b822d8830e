// Prefetch. NPSStealth mode (seed chapter V.H): no load modules; a
// prefetch thread keeps the memory-mapped grid blocks of the active area,
// and first of all its leading edge, resident by advising and touching
// their pages, then sleeps longer the slower the viewer moves. Module
// modes: readahead hints for the strip a loader has just taken.
#include <sys/mman.h>
#include <sys/resource.h>

#include <algorithm>
#include <cmath>

#include "pager_internal.h"

namespace sandtable::paging {

namespace {

struct BlockOrder {
  std::uint8_t group = 0;  ///< 0: leading edge (beyond the base area), 1: the rest
  double distance2 = 0;    ///< from the eye
  std::uint32_t bx = 0, bz = 0;
};

void faults(long& minor, long& major) {
  rusage r{};
  ::getrusage(RUSAGE_THREAD, &r);
  minor = r.ru_minflt;
  major = r.ru_majflt;
}

}  // namespace

void hintStrip(Pager::Impl& im, std::span<const ModuleKey> keys) {
  // The coarse records and the fine ones: the loader reads every coarse
  // record of its pending list first, so by the time it reaches a fine one
  // the disk has had the whole strip's coarse reads to fetch it. (A pack
  // v2 in Morton order holds the strip's records in a few runs each.)
  if (im.source) im.source->willNeed(keys, true);
}

void fetchGridAhead(Pager::Impl& im, double eyeX, double eyeZ, double vx, double vz) {
  // The grid's readers in module modes are the ground under the eye (the
  // viewer's clamp, the simulator's entities near it) and placeholders:
  // the blocks around the eye and along its way for the next few seconds,
  // fetched when the eye enters another block. (The modules carry their
  // own heights; the blocks under every strip would be bytes nobody reads.)
  constexpr double kAheadSeconds = 2;
  constexpr double kMaxAheadBlocks = 16;
  const grid::GridFile& g = *im.grid;
  const double blockMetres = grid::kBlockPosts * g.spacing();
  if (!std::isfinite(eyeX) || !std::isfinite(eyeZ)) return;
  auto blockOf = [&](double m) { return std::floor(m / blockMetres); };
  const std::int64_t key = (std::int64_t(blockOf(eyeZ)) << 32) ^ std::int64_t(blockOf(eyeX));
  if (key == im.gridAheadKey || im.gridFetches->pending() >= 2) return;
  im.gridAheadKey = key;
  const double ax = std::clamp(std::isfinite(vx) ? vx * kAheadSeconds : 0.0, -kMaxAheadBlocks * blockMetres, kMaxAheadBlocks * blockMetres);
  const double az = std::clamp(std::isfinite(vz) ? vz * kAheadSeconds : 0.0, -kMaxAheadBlocks * blockMetres, kMaxAheadBlocks * blockMetres);
  auto clampBlock = [](double b, std::uint32_t count) { return std::uint32_t(std::clamp(b, 0.0, double(count) - 1)); };
  const grid::Header& h = g.header();
  const std::uint32_t bx0 = clampBlock(blockOf(eyeX + std::min(0.0, ax)) - 1, h.blocksX);
  const std::uint32_t bx1 = clampBlock(blockOf(eyeX + std::max(0.0, ax)) + 1, h.blocksX);
  const std::uint32_t bz0 = clampBlock(blockOf(eyeZ + std::min(0.0, az)) - 1, h.blocksZ);
  const std::uint32_t bz1 = clampBlock(blockOf(eyeZ + std::max(0.0, az)) + 1, h.blocksZ);
  im.gridFetches->submit([grid = im.grid, bx0, bz0, bx1, bz1] { (void)grid->fetchBlocks(bx0, bz0, bx1, bz1); });
}

void runPrefetcher(Pager::Impl& im) {
  using namespace detail;
  const grid::GridFile& g = *im.grid;
  const grid::Header& h = g.header();
  const double blockMetres = grid::kBlockPosts * g.spacing();
  const double edge = im.geometry.moduleSize;
  std::vector<BlockOrder> order;
  double passEstimate = im.options.initialLatencySeconds;
  volatile std::uint8_t sink = 0;  // keeps the page touches

  while (!im.stopping.load(std::memory_order_acquire)) {
    const WindowState ws = im.window.load();
    double sleep = im.options.maxSleepSeconds;
    if (im.count.updates.load(std::memory_order_relaxed) > 0 && h.blocksX > 0 && h.blocksZ > 0) {
      const std::int64_t t0 = nowNs();
      const double speed = std::hypot(ws.vx, ws.vz);
      // Slower viewer, longer sleep: the time to cover a fraction of a block.
      sleep = speed > 0 ? im.options.prefetchSleepBlocks * blockMetres / speed
                        : im.options.maxSleepSeconds;
      sleep = std::clamp(sleep, im.options.minSleepSeconds, im.options.maxSleepSeconds);
      // The active area (side 2 vd + 2 modules) and the leading edge: as far
      // as the viewer goes, times lookAheadScale, before the next pass is
      // done (this sleep plus one pass).
      const double half = im.liveViewDistance.load(std::memory_order_relaxed) + edge;
      const double lead = im.options.lookAheadScale * (passEstimate + sleep);
      im.leadSeconds.store(lead, std::memory_order_relaxed);
      const double bx0m = ws.eyeX - half, bx1m = ws.eyeX + half;
      const double bz0m = ws.eyeZ - half, bz1m = ws.eyeZ + half;
      const double ex0 = bx0m + std::min(0.0, ws.vx * lead), ex1 = bx1m + std::max(0.0, ws.vx * lead);
      const double ez0 = bz0m + std::min(0.0, ws.vz * lead), ez1 = bz1m + std::max(0.0, ws.vz * lead);
      auto blockIndex = [&](double m, std::uint32_t count) {
        return std::clamp<double>(std::floor(m / blockMetres), 0, double(count) - 1);
      };
      const auto x0 = std::uint32_t(blockIndex(ex0, h.blocksX));
      const auto x1 = std::uint32_t(blockIndex(ex1, h.blocksX));
      const auto z0 = std::uint32_t(blockIndex(ez0, h.blocksZ));
      const auto z1 = std::uint32_t(blockIndex(ez1, h.blocksZ));
      order.clear();
      for (std::uint32_t bz = z0; bz <= z1; ++bz) {
        for (std::uint32_t bx = x0; bx <= x1; ++bx) {
          const double cx = (bx + 0.5) * blockMetres, cz = (bz + 0.5) * blockMetres;
          const bool inBase = (bx + 1) * blockMetres > bx0m && bx * blockMetres < bx1m &&
                              (bz + 1) * blockMetres > bz0m && bz * blockMetres < bz1m;
          const double dx = cx - ws.eyeX, dz = cz - ws.eyeZ;
          order.push_back({std::uint8_t(inBase ? 1 : 0), dx * dx + dz * dz, bx, bz});
        }
      }
      std::sort(order.begin(), order.end(), [](const BlockOrder& a, const BlockOrder& b) {
        return a.group != b.group ? a.group < b.group : a.distance2 < b.distance2;
      });
      long min0 = 0, maj0 = 0, min1 = 0, maj1 = 0;
      faults(min0, maj0);
      // Read-ahead for all of them first, then touch each page in order, so
      // the leading edge is waited for first and the rest streams behind.
      const auto page = std::uintptr_t(grid::kPageBytes);
      for (const BlockOrder& b : order) {
        const std::span<const std::byte> bytes = g.blockBytes(b.bx, b.bz);
        const auto start = reinterpret_cast<std::uintptr_t>(bytes.data()) & ~(page - 1);
        const auto end = reinterpret_cast<std::uintptr_t>(bytes.data() + bytes.size());
        ::madvise(reinterpret_cast<void*>(start), end - start, MADV_WILLNEED);
      }
      std::uint64_t pages = 0;
      for (const BlockOrder& b : order) {
        if (im.stopping.load(std::memory_order_relaxed)) break;
        const std::span<const std::byte> bytes = g.blockBytes(b.bx, b.bz);
        for (std::size_t o = 0; o < bytes.size(); o += grid::kPageBytes) {
          sink = static_cast<std::uint8_t>(sink + std::to_integer<std::uint8_t>(bytes[o]));
          ++pages;
        }
      }
      faults(min1, maj1);
      const double pass = double(nowNs() - t0) / 1e9;
      passEstimate = 0.875 * passEstimate + 0.125 * pass;
      im.latencyEstimate.store(passEstimate, std::memory_order_relaxed);
      im.latency.add(nowNs() - t0);
      im.count.prefetchPasses.fetch_add(1, std::memory_order_relaxed);
      im.count.prefetchBlocks.fetch_add(order.size(), std::memory_order_relaxed);
      im.count.prefetchPages.fetch_add(pages, std::memory_order_relaxed);
      im.count.prefetchMinorFaults.fetch_add(std::uint64_t(std::max(0L, min1 - min0)),
                                       std::memory_order_relaxed);
      im.count.prefetchMajorFaults.fetch_add(std::uint64_t(std::max(0L, maj1 - maj0)),
                                       std::memory_order_relaxed);
      im.lastPassSeconds.store(pass, std::memory_order_relaxed);
    }
    im.touchSink.store(sink, std::memory_order_relaxed);
    im.lastSleepSeconds.store(sleep, std::memory_order_relaxed);
    std::unique_lock lock(im.sleepMutex);
    im.sleepCv.wait_for(lock, std::chrono::duration<double>(sleep), [&] {
      return im.stopping.load(std::memory_order_relaxed) || im.wake.exchange(false);
    });
  }
}

}  // namespace sandtable::paging
