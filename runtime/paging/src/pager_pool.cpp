// Pager storage helpers: the window seqlock, the latency histogram, slot
// level copies that reuse capacity, and the coarse placeholder module.
#include <algorithm>
#include <cmath>

#include "pager_internal.h"
#include "sandtable/meshing/assemble.h"
#include "sandtable/meshing/skirts.h"

namespace sandtable::paging::detail {

// ------------------------------------------------------------ SeqWindow

void SeqWindow::store(const WindowState& s) {
  const std::uint64_t q = seq_.load(std::memory_order_relaxed);
  seq_.store(q + 1, std::memory_order_relaxed);
  std::atomic_thread_fence(std::memory_order_release);
  x0_.store(s.window.x0, std::memory_order_relaxed);
  z0_.store(s.window.z0, std::memory_order_relaxed);
  x1_.store(s.window.x1, std::memory_order_relaxed);
  z1_.store(s.window.z1, std::memory_order_relaxed);
  eyeX_.store(s.eyeX, std::memory_order_relaxed);
  eyeZ_.store(s.eyeZ, std::memory_order_relaxed);
  vx_.store(s.vx, std::memory_order_relaxed);
  vz_.store(s.vz, std::memory_order_relaxed);
  seq_.store(q + 2, std::memory_order_release);
}

WindowState SeqWindow::load() const {
  for (;;) {
    const std::uint64_t q0 = seq_.load(std::memory_order_acquire);
    if (q0 & 1u) {
      std::this_thread::yield();
      continue;
    }
    WindowState s;
    s.window = {x0_.load(std::memory_order_relaxed), z0_.load(std::memory_order_relaxed),
                x1_.load(std::memory_order_relaxed), z1_.load(std::memory_order_relaxed)};
    s.eyeX = eyeX_.load(std::memory_order_relaxed);
    s.eyeZ = eyeZ_.load(std::memory_order_relaxed);
    s.vx = vx_.load(std::memory_order_relaxed);
    s.vz = vz_.load(std::memory_order_relaxed);
    std::atomic_thread_fence(std::memory_order_acquire);
    if (seq_.load(std::memory_order_relaxed) == q0) return s;
  }
}

// ------------------------------------------------------------ histogram

namespace {

int bucketOf(std::int64_t ns) {
  const double us = double(ns) / 1000.0;
  if (!(us >= 1.0)) return 0;
  const int b = int(std::floor(4.0 * std::log2(us))) + 1;
  return std::min(b, LatencyHistogram::kBuckets - 1);
}

/// Upper edge of bucket b in milliseconds.
double bucketUpperMs(int b) { return std::exp2(double(b) / 4.0) / 1000.0; }

}  // namespace

void LatencyHistogram::add(std::int64_t ns) {
  ns = std::max<std::int64_t>(ns, 0);
  counts_[std::size_t(bucketOf(ns))].fetch_add(1, std::memory_order_relaxed);
  count_.fetch_add(1, std::memory_order_relaxed);
  sumNs_.fetch_add(std::uint64_t(ns), std::memory_order_relaxed);
  std::uint64_t m = maxNs_.load(std::memory_order_relaxed);
  while (std::uint64_t(ns) > m &&
         !maxNs_.compare_exchange_weak(m, std::uint64_t(ns), std::memory_order_relaxed)) {
  }
}

void LatencyHistogram::reset() {
  for (auto& c : counts_) c.store(0, std::memory_order_relaxed);
  count_.store(0, std::memory_order_relaxed);
  sumNs_.store(0, std::memory_order_relaxed);
  maxNs_.store(0, std::memory_order_relaxed);
}

LatencyStats LatencyHistogram::stats() const {
  LatencyStats s;
  std::array<std::uint64_t, kBuckets> c{};
  std::uint64_t n = 0;
  for (int b = 0; b < kBuckets; ++b) {
    c[std::size_t(b)] = counts_[std::size_t(b)].load(std::memory_order_relaxed);
    n += c[std::size_t(b)];
  }
  s.count = n;
  if (n == 0) return s;
  s.maxMs = double(maxNs_.load(std::memory_order_relaxed)) / 1e6;
  s.meanMs = double(sumNs_.load(std::memory_order_relaxed)) / 1e6 / double(n);
  // Nearest rank: the bucket holding element ceil(q n), reported as its
  // upper edge (never above the true maximum).
  auto quantile = [&](double q) {
    const std::uint64_t rank = std::max<std::uint64_t>(1, std::uint64_t(std::ceil(q * double(n))));
    std::uint64_t cum = 0;
    for (int b = 0; b < kBuckets; ++b) {
      cum += c[std::size_t(b)];
      if (cum >= rank) return std::min(bucketUpperMs(b), s.maxMs);
    }
    return s.maxMs;
  };
  s.p50Ms = quantile(0.50);
  s.p90Ms = quantile(0.90);
  s.p99Ms = quantile(0.99);
  return s;
}

// ----------------------------------------------------------------- pool

namespace {

template <typename T>
std::uint64_t capBytes(const std::vector<T>& v) {
  return std::uint64_t(v.capacity()) * sizeof(T);
}

template <typename T>
std::uint64_t growBytes(const std::vector<T>& src, const std::vector<T>& dst) {
  return src.size() > dst.capacity() ? std::uint64_t(src.size() - dst.capacity()) * sizeof(T) : 0;
}

template <typename T>
void reserveAtLeast(std::vector<T>& v, std::size_t n) {
  if (n > v.capacity()) v.reserve(n);
}

}  // namespace

std::uint64_t levelCapacityBytes(const module::Level& l) {
  return capBytes(l.vertices) + capBytes(l.indices) + capBytes(l.groups) + capBytes(l.maxHeight) +
         capBytes(l.objectY);
}

std::uint64_t levelGrowthBytes(const module::Level& src, const module::Level& dst) {
  return growBytes(src.vertices, dst.vertices) + growBytes(src.indices, dst.indices) +
         growBytes(src.groups, dst.groups) + growBytes(src.maxHeight, dst.maxHeight) +
         growBytes(src.objectY, dst.objectY);
}

void copyLevel(const module::Level& src, module::Level& dst) {
  dst.spacing = src.spacing;
  dst.squaresX = src.squaresX;
  dst.squaresZ = src.squaresZ;
  dst.skirtDepth = src.skirtDepth;
  // assign() reuses the capacity when it suffices, and never shrinks it.
  dst.vertices.assign(src.vertices.begin(), src.vertices.end());
  dst.indices.assign(src.indices.begin(), src.indices.end());
  dst.groups.assign(src.groups.begin(), src.groups.end());
  dst.maxHeight.assign(src.maxHeight.begin(), src.maxHeight.end());
  dst.objectY.assign(src.objectY.begin(), src.objectY.end());
}

void reserveLike(const module::Level& src, module::Level& dst) {
  reserveAtLeast(dst.vertices, src.vertices.size());
  reserveAtLeast(dst.indices, src.indices.size());
  reserveAtLeast(dst.groups, src.groups.size());
  reserveAtLeast(dst.maxHeight, src.maxHeight.size());
}

void buildPlaceholder(const grid::GridFile& grid, const pack::IndexHeader& h, std::uint32_t kx,
                      std::uint32_t kz, std::uint16_t material, module::Level& out) {
  out.objectY.clear();  // a stand-in carries no objects
  const int levels = int(std::max<std::uint32_t>(h.levels, 1));
  const std::uint32_t S = std::max<std::uint32_t>(h.moduleSquares, 1);
  const std::uint32_t lastI = grid.postsX() - 1, lastJ = grid.postsZ() - 1;
  if (std::uint64_t(kx) * S >= lastI || std::uint64_t(kz) * S >= lastJ) {
    // A pack larger than its grid (only Pager::open on a mismatched pair):
    // nothing of the grid to show.
    out.squaresX = out.squaresZ = 0;
    out.vertices.clear();
    out.indices.clear();
    out.groups.clear();
    out.maxHeight.clear();
    return;
  }
  // The coarsest level's lattice with the grid's own heights (a flat
  // stand-in drew as a plain with walls round it), meshed as the module
  // builder meshes it. Its skirts hang as deep as the blocks' elevation
  // range: a stand-in has no finer levels to measure the builder's depth
  // against, and its neighbours may be drawn at any level.
  const grid::GridHeightField heights(grid);
  const meshing::ModuleWindow w = meshing::moduleWindow(heights, S, levels, kx, kz);
  const meshing::LevelLattice lat = meshing::levelLattice(heights, w, levels - 1, meshing::NonFinite::zero);
  meshing::plainSkin(lat, material, out);
  const float centre = grid.elevation(std::min(w.i0 + S / 2, lastI), std::min(w.j0 + S / 2, lastJ));
  const float depth = meshing::blockRangeDepth(grid, w, std::isfinite(centre) ? centre : 0.0f);
  const std::uint32_t node = std::max<std::uint32_t>(1, meshing::nodeSquares(S, levels));
  meshing::finishLevel(lat, node, depth, material, out);
}

}  // namespace sandtable::paging::detail
