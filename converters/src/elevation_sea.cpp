// The sea rule: voids that reach the grid's edge at sea level are sea, not
// land to interpolate. DTED and SRTM cells often store the sea as nodata
// (the Danish DHM cells); filling it made whole cells "91.9 % voids filled"
// of land between the islands.
#include <algorithm>
#include <cmath>

#include "elevation_internal.h"

namespace sandtable::convert::detail {
namespace {

// Flags above the PostClass bits, used only during markSea.
constexpr std::uint8_t kClassBits = 0x03;
constexpr std::uint8_t kReached = 0x10;   // connected to the edge through water
constexpr std::uint8_t kFlooding = 0x20;  // in the void component being looked at
constexpr std::uint8_t kDone = 0x40;      // void component already decided
constexpr std::uint8_t kShore = 0x80;     // valid post already in the shore list

/// Scanline flood fill of the 4-connected posts around `seed` that `open`
/// accepts; `enter` must make `open` false for the post. The stack holds
/// one seed per run of a neighbouring row, not one per post.
template <typename Open, typename Enter>
void flood(std::uint32_t w, std::uint32_t h, std::size_t seed, Open open, Enter enter) {
  std::vector<std::size_t> stack{seed};
  while (!stack.empty()) {
    const std::size_t k = stack.back();
    stack.pop_back();
    if (!open(k)) continue;
    const std::size_t row = k / w * w;
    std::size_t a = k, b = k;
    while (a > row && open(a - 1)) --a;
    while (b + 1 < row + w && open(b + 1)) ++b;
    for (std::size_t x = a; x <= b; ++x) enter(x);
    const std::size_t j = k / w;
    for (const int dj : {-1, 1}) {
      if ((dj < 0 && j == 0) || (dj > 0 && j + 1 >= h)) continue;
      bool inRun = false;
      for (std::size_t x = a; x <= b; ++x) {
        const std::size_t n = dj < 0 ? x - w : x + w;
        const bool o = open(n);
        if (o && !inRun) stack.push_back(n);
        inRun = o;
      }
    }
  }
}

/// Median of the shore posts' elevations.
double median(const std::vector<float>& grid, const std::vector<std::size_t>& shore) {
  std::vector<float> z(shore.size());
  for (std::size_t k = 0; k < shore.size(); ++k) z[k] = grid[shore[k]];
  const auto mid = z.begin() + std::ptrdiff_t(z.size() / 2);
  std::nth_element(z.begin(), mid, z.end());
  return *mid;
}

}  // namespace

std::uint64_t markSea(const Frame& f, std::vector<float>& grid, std::vector<std::uint8_t>& cls) {
  const std::uint32_t w = f.postsX, h = f.postsZ;
  auto cl = [&](std::size_t k) { return std::uint8_t(cls[k] & kClassBits); };
  // 1. What the edge reaches through water: voids, and valid posts at or
  //    below 0 m (a sea stored as 0, which can enclose void patches).
  auto water = [&](std::size_t k) {
    return !(cls[k] & kReached) && (cl(k) == kVoidPost || (cl(k) == kValidPost && grid[k] <= 0.0f));
  };
  auto reach = [&](std::size_t k) { cls[k] |= kReached; };
  for (std::uint32_t i = 0; i < w; ++i) {
    flood(w, h, i, water, reach);
    flood(w, h, std::size_t(h - 1) * w + i, water, reach);
  }
  for (std::uint32_t j = 0; j < h; ++j) {
    flood(w, h, std::size_t(j) * w, water, reach);
    flood(w, h, std::size_t(j) * w + w - 1, water, reach);
  }
  // 2. Each reached void component is sea when its shore is at sea level.
  std::uint64_t sea = 0;
  std::vector<std::size_t> shore;
  auto undecided = [&](std::size_t k) { return cl(k) == kVoidPost && !(cls[k] & (kFlooding | kDone)); };
  auto gather = [&](std::size_t k) {
    cls[k] |= kFlooding;
    const std::size_t i = k % w, j = k / w;
    const std::size_t around[4] = {i > 0 ? k - 1 : k, i + 1 < w ? k + 1 : k, j > 0 ? k - w : k, j + 1 < h ? k + w : k};
    for (const std::size_t n : around) {
      if (cl(n) == kValidPost && !(cls[n] & kShore)) {
        cls[n] |= kShore;
        shore.push_back(n);
      }
    }
  };
  for (std::size_t k = 0; k < cls.size(); ++k) {
    if (!(cls[k] & kReached) || !undecided(k)) continue;
    shore.clear();
    flood(w, h, k, undecided, gather);
    for (const std::size_t n : shore) cls[n] &= std::uint8_t(~kShore);
    const bool isSea = !shore.empty() && std::fabs(median(grid, shore)) <= kSeaShoreMedianM;
    flood(w, h, k, [&](std::size_t n) { return (cls[n] & kFlooding) != 0; },
          [&](std::size_t n) {
            cls[n] = std::uint8_t((cls[n] & ~kFlooding) | kDone);
            if (isSea) {
              cls[n] = std::uint8_t((cls[n] & ~kClassBits) | kSeaPost);
              grid[n] = 0.0f;
              ++sea;
            }
          });
  }
  for (auto& c : cls) c &= kClassBits;
  return sea;
}

}  // namespace sandtable::convert::detail
