// Pager storage helpers: the window seqlock, the latency histogram, slot
// level copies that reuse capacity, and the coarse placeholder module.
#include <algorithm>
#include <cmath>

#include "pager_internal.h"

namespace sandtable::runtime::pager_detail {

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
  return capBytes(l.vertices) + capBytes(l.indices) + capBytes(l.groups) + capBytes(l.maxHeight);
}

std::uint64_t levelGrowthBytes(const module::Level& src, const module::Level& dst) {
  return growBytes(src.vertices, dst.vertices) + growBytes(src.indices, dst.indices) +
         growBytes(src.groups, dst.groups) + growBytes(src.maxHeight, dst.maxHeight);
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
}

void reserveLike(const module::Level& src, module::Level& dst) {
  reserveAtLeast(dst.vertices, src.vertices.size());
  reserveAtLeast(dst.indices, src.indices.size());
  reserveAtLeast(dst.groups, src.groups.size());
  reserveAtLeast(dst.maxHeight, src.maxHeight.size());
}

void buildPlaceholder(const grid::GridFile& grid, const pack::IndexHeader& h, std::uint32_t kx,
                      std::uint32_t kz, std::uint16_t material, module::Level& out) {
  const std::uint32_t S = h.moduleSquares;
  const std::uint32_t step = 1u << (h.levels > 0 ? h.levels - 1 : 0);
  const std::uint32_t lastI = grid.postsX() - 1, lastJ = grid.postsZ() - 1;
  const std::uint32_t i0 = kx * S, j0 = kz * S;
  const std::uint32_t i1 = std::max(i0 + 1, std::min(i0 + S, lastI));
  const std::uint32_t j1 = std::max(j0 + 1, std::min(j0 + S, lastJ));

  // The coarsest level's lattice with the grid's own heights, so a stand-in
  // has the right shape (coarse, not a flat plain with walls round it);
  // skirts as deep as the blocks' range.
  auto heightAt = [&](std::uint32_t i, std::uint32_t j) {
    const float e = grid.elevation(std::min(i, lastI), std::min(j, lastJ));
    return std::isfinite(e) ? e : 0.0f;
  };
  const float y = heightAt(i0 + S / 2, j0 + S / 2);
  const grid::Header& gh = grid.header();
  float lo = y, hi = y;
  for (std::uint32_t bz = std::min(j0, lastJ) / grid::kBlockPosts;
       bz <= std::min(j1, lastJ) / grid::kBlockPosts && bz < gh.blocksZ; ++bz) {
    for (std::uint32_t bx = std::min(i0, lastI) / grid::kBlockPosts;
         bx <= std::min(i1, lastI) / grid::kBlockPosts && bx < gh.blocksX; ++bx) {
      const grid::BlockEntry e = grid.blockEntry(bx, bz);
      if (std::isfinite(e.minElevation)) lo = std::min(lo, e.minElevation);
      if (std::isfinite(e.maxElevation)) hi = std::max(hi, e.maxElevation);
    }
  }
  const float depth = std::max(1.0f, hi - lo);

  // The coarse lattice: posts every `step`, the last one clamped.
  const std::uint32_t nx = (i1 - i0 + step - 1) / step, nz = (j1 - j0 + step - 1) / step;
  auto col = [&](std::uint32_t a) { return std::min(i0 + a * step, i1); };
  auto row = [&](std::uint32_t b) { return std::min(j0 + b * step, j1); };
  const double sp = grid.spacing();
  out.spacing = sp * step;
  out.squaresX = nx;
  out.squaresZ = nz;
  out.skirtDepth = depth;
  out.vertices.clear();
  out.indices.clear();
  out.groups.clear();
  out.maxHeight.assign(std::size_t(nx) * nz, y);
  for (std::uint32_t b = 0; b <= nz; ++b) {
    for (std::uint32_t a = 0; a <= nx; ++a) {
      out.vertices.push_back({float(double(col(a) - i0) * sp), heightAt(col(a), row(b)),
                              float(double(row(b) - j0) * sp), 0.0f, 0.0f});
    }
  }
  for (std::uint32_t sz = 0; sz < nz; ++sz) {
    for (std::uint32_t sx = 0; sx < nx; ++sx) {
      float top = lo;
      for (std::uint32_t c : {0u, 1u, 2u, 3u}) {
        top = std::max(top, out.vertices[(sz + (c >> 1)) * (nx + 1) + sx + (c & 1)].y);
      }
      out.maxHeight[std::size_t(sz) * nx + sx] = top;
    }
  }
  auto post = [&](std::uint32_t a, std::uint32_t b) { return b * (nx + 1) + a; };
  auto group = [&](std::uint32_t square, module::Half half, std::uint32_t first) {
    module::Group g;
    g.square = square;
    g.half = half;
    g.priority = module::kPrioritySkin;
    g.material = material;
    g.firstIndex = first;
    g.indexCount = std::uint32_t(out.indices.size()) - first;
    out.groups.push_back(g);
  };
  auto hang = [&](std::uint32_t top0, std::uint32_t top1) {
    module::Vertex b0 = out.vertices[top0], b1 = out.vertices[top1];
    b0.y -= depth;
    b1.y -= depth;
    const auto bb0 = std::uint32_t(out.vertices.size());
    out.vertices.push_back(b0);
    out.vertices.push_back(b1);
    for (std::uint32_t v : {top0, bb0, top1, top1, bb0, bb0 + 1}) out.indices.push_back(v);
  };
  for (std::uint32_t sz = 0; sz < nz; ++sz) {
    for (std::uint32_t sx = 0; sx < nx; ++sx) {
      const std::uint32_t sq = sz * nx + sx;
      const std::uint32_t nw = post(sx, sz), ne = post(sx + 1, sz), sw = post(sx, sz + 1),
                          se = post(sx + 1, sz + 1);
      std::uint32_t first = std::uint32_t(out.indices.size());
      for (std::uint32_t v : {nw, sw, ne}) out.indices.push_back(v);
      group(sq, module::Half::upper, first);
      first = std::uint32_t(out.indices.size());
      for (std::uint32_t v : {ne, sw, se}) out.indices.push_back(v);
      group(sq, module::Half::lower, first);
      first = std::uint32_t(out.indices.size());
      if (sz == 0) hang(nw, ne);
      if (sz == nz - 1) hang(sw, se);
      if (sx == 0) hang(nw, sw);
      if (sx == nx - 1) hang(ne, se);
      if (out.indices.size() > first) group(sq, module::Half::skirt, first);
    }
  }
}

}  // namespace sandtable::runtime::pager_detail
