// The pager's pure parts: strip logic (seed Figures 28, 30, 31) and the
// needed set (Figure 76, Table 8). No threads, no I/O.
#include <algorithm>
#include <cassert>
#include <cmath>

#include "sandtable/paging/pager.h"
#include "sandtable/paging/view_triangle.h"

namespace sandtable::paging {

const char* directionName(Direction d) {
  switch (d) {
    case Direction::north: return "north";
    case Direction::east: return "east";
    case Direction::south: return "south";
    case Direction::west: return "west";
  }
  return "?";
}

const char* modeName(PagerMode m) {
  switch (m) {
    case PagerMode::predictive: return "predictive";
    case PagerMode::demand: return "demand";
    case PagerMode::mmap: return "mmap";
  }
  return "?";
}

ModuleRect ModuleRect::intersect(const ModuleRect& o) const {
  ModuleRect r{std::max(x0, o.x0), std::max(z0, o.z0), std::min(x1, o.x1), std::min(z1, o.z1)};
  if (r.empty()) return {};
  return r;
}

ModuleRect ModuleRect::clipped(std::uint32_t modulesX, std::uint32_t modulesZ) const {
  return intersect({0, 0, std::int64_t(modulesX), std::int64_t(modulesZ)});
}

std::int64_t PagingGeometry::radius() const {
  assert(moduleSize > 0);
  // The tolerance keeps an exact multiple (6100 / 1000 m = 6.1, 6000 / 1000
  // = 6) from rounding up through floating-point noise.
  return std::max<std::int64_t>(
      0, std::int64_t(std::ceil((viewDistance + hysteresis) / moduleSize - 1e-9)));
}

std::int64_t PagingGeometry::maxRadius() const {
  PagingGeometry g = *this;
  g.viewDistance = std::max(viewDistance, maxViewDistance);
  return g.radius();
}

std::uint32_t PagingGeometry::ringX() const {
  return std::uint32_t(std::min<std::int64_t>(modulesX, maxSide() + 2 * std::int64_t(maxLeadStrips)));
}

std::uint32_t PagingGeometry::ringZ() const {
  return std::uint32_t(std::min<std::int64_t>(modulesZ, maxSide() + 2 * std::int64_t(maxLeadStrips)));
}

// ---------------------------------------------------------------- planner

namespace {

std::int64_t floorIndex(double metres, double edge) {
  return std::int64_t(std::floor(metres / edge));
}

/// Squared distance from the eye to a module's centre: the nearest-first key.
double centreDistance2(ModuleKey k, double eyeX, double eyeZ, double edge) {
  const double dx = (double(k.kx) + 0.5) * edge - eyeX;
  const double dz = (double(k.kz) + 0.5) * edge - eyeZ;
  return dx * dx + dz * dz;
}

void sortNearestFirst(std::vector<ModuleKey>& keys, double eyeX, double eyeZ, double edge) {
  std::sort(keys.begin(), keys.end(), [&](ModuleKey a, ModuleKey b) {
    const double da = centreDistance2(a, eyeX, eyeZ, edge);
    const double db = centreDistance2(b, eyeX, eyeZ, edge);
    if (da != db) return da < db;
    return a.kz != b.kz ? a.kz < b.kz : a.kx < b.kx;
  });
}

}  // namespace

void StripPlanner::setViewDistance(double metres) {
  // maxViewDistance 0 (fixed) leaves the distance the planner opened with as the most.
  if (geometry_.maxViewDistance < geometry_.viewDistance) geometry_.maxViewDistance = geometry_.viewDistance;
  if (std::isfinite(metres) && metres > 0) geometry_.viewDistance = std::min(metres, geometry_.maxViewDistance);
}

StripPlanner::StripPlanner(const PagingGeometry& g) : geometry_(g) {
  const std::size_t side = std::size_t(std::max<std::int64_t>(1, g.maxSide() + 2 * std::int64_t(g.maxLeadStrips)));
  for (StripJob& j : step_.jobs) {
    j.load.reserve(side * (2 * std::size_t(g.maxLeadStrips) + 1));
    j.free.reserve(side * (2 * std::size_t(g.maxLeadStrips) + 1));
  }
}

ModuleRect StripPlanner::activeArea() const {
  if (!started_) return {};
  const std::int64_t r = geometry_.radius();
  return ModuleRect{cx_ - r, cz_ - r, cx_ + r + 1, cz_ + r + 1}.clipped(geometry_.modulesX,
                                                                      geometry_.modulesZ);
}

MetreBox StripPlanner::boundingBox() const {
  const double e = geometry_.moduleSize, h = geometry_.hysteresis;
  return {double(cx_) * e - h, double(cz_) * e - h, double(cx_ + 1) * e + h,
          double(cz_ + 1) * e + h};
}

const PlanStep& StripPlanner::update(double eyeX, double eyeZ, double vx, double vz, double leadSeconds,
                                     double guardSeconds) {
  const PagingGeometry& g = geometry_;
  const double e = g.moduleSize;
  for (StripJob& j : step_.jobs) {
    j.load.clear();
    j.free.clear();
  }
  step_.changed = step_.refill = step_.crossed = false;
  step_.before = window_;

  // 1. The bounding box (Figure 30): the centre moves only when the eye
  // leaves the centre module grown by the hysteresis.
  std::int64_t ncx = cx_, ncz = cz_;
  const MetreBox box = boundingBox();
  if (!started_ || eyeX < box.x0 || eyeX > box.x1) ncx = floorIndex(eyeX, e);
  if (!started_ || eyeZ < box.z0 || eyeZ > box.z1) ncz = floorIndex(eyeZ, e);
  const bool movedX = !started_ || ncx != cx_;
  const bool movedZ = !started_ || ncz != cz_;
  step_.crossed = started_ && (movedX || movedZ);

  // 2. Lead strips: exact on an axis whose centre moved, otherwise they may
  // only grow on the side already leading (or on either side from none).
  // Whole strips covering `metres`, at most maxLeadStrips (0 for none).
  auto strips = [&](double metres) -> std::uint32_t {
    const double n = metres / e;
    if (!(n > 0)) return 0;
    return std::uint32_t(std::min<double>(g.maxLeadStrips, std::ceil(n - 1e-9)));
  };
  auto want = [&](double v) { return strips(v * leadSeconds); };
  auto leadAxis = [&](bool moved, double v, Direction plus, Direction minus) {
    const std::uint32_t wantPlus = v > 0 ? want(v) : 0, wantMinus = v < 0 ? want(-v) : 0;
    std::uint32_t& p = lead_[std::size_t(plus)];
    std::uint32_t& m = lead_[std::size_t(minus)];
    if (moved) {
      p = wantPlus;
      m = wantMinus;
    } else if (wantPlus > p && m == 0) {
      p = wantPlus;
    } else if (wantMinus > m && p == 0) {
      m = wantMinus;
    }
  };
  leadAxis(movedX, vx, Direction::east, Direction::west);
  leadAxis(movedZ, vz, Direction::south, Direction::north);

  // 3. The guard: one update's travel in any direction, beyond what the
  // hysteresis already covers.
  const std::uint32_t wantGuard = strips(std::hypot(vx, vz) * guardSeconds - g.hysteresis);
  if (movedX || movedZ) guard_ = wantGuard;
  else guard_ = std::max(guard_, wantGuard);
  const auto extent = [&](Direction d) { return std::int64_t(std::max(lead_[std::size_t(d)], guard_)); };

  const std::int64_t r = g.radius();
  const ModuleRect raw{ncx - r - extent(Direction::west), ncz - r - extent(Direction::north),
                       ncx + r + 1 + extent(Direction::east), ncz + r + 1 + extent(Direction::south)};
  const ModuleRect after = raw.clipped(g.modulesX, g.modulesZ);
  const bool first = !started_;
  started_ = true;
  cx_ = ncx;
  cz_ = ncz;
  step_.after = after;
  if (!first && after == window_) return step_;
  const ModuleRect before = window_;
  window_ = after;

  // 4. What to load and free. A jump that keeps less than half of the
  // window refills it: every new module, nearest first, dealt round robin
  // so that all four loaders work on the nearest ones at once.
  const ModuleRect kept = before.intersect(after);
  step_.refill = first || kept.count() * 2 < after.count();
  if (step_.refill) {
    std::vector<ModuleKey>& all = step_.jobs[0].load;  // gathered here, then dealt
    for (std::int64_t z = after.z0; z < after.z1; ++z) {
      for (std::int64_t x = after.x0; x < after.x1; ++x) {
        if (!before.contains(x, z)) all.push_back({std::uint32_t(x), std::uint32_t(z)});
      }
    }
    sortNearestFirst(all, eyeX, eyeZ, e);
    // Deal in place: job d takes elements d, d + 4, ... Walk backwards so
    // job 0's own list can be compacted last.
    const std::size_t n = all.size();
    for (std::size_t d = 1; d < kDirections; ++d) {
      for (std::size_t i = d; i < n; i += kDirections) step_.jobs[d].load.push_back(all[i]);
    }
    std::size_t w = 0;
    for (std::size_t i = 0; i < n; i += kDirections) all[w++] = all[i];
    all.resize(w);
    std::size_t k = 0;
    for (std::int64_t z = before.z0; z < before.z1; ++z) {
      for (std::int64_t x = before.x0; x < before.x1; ++x) {
        if (!after.contains(x, z)) {
          step_.jobs[k++ % kDirections].free.push_back({std::uint32_t(x), std::uint32_t(z)});
        }
      }
    }
  } else {
    // Strips (Figure 31): a new module belongs to the side of the old
    // window it lies beyond (east/west first, so a diagonal's corner goes
    // east or west); an old module is freed by the loader moving away from
    // it (beyond the new west edge: the east loader).
    for (std::int64_t z = after.z0; z < after.z1; ++z) {
      for (std::int64_t x = after.x0; x < after.x1; ++x) {
        if (before.contains(x, z)) continue;
        const Direction d = x >= before.x1  ? Direction::east
                            : x < before.x0 ? Direction::west
                            : z < before.z0 ? Direction::north
                                            : Direction::south;
        step_.jobs[std::size_t(d)].load.push_back({std::uint32_t(x), std::uint32_t(z)});
      }
    }
    for (std::int64_t z = before.z0; z < before.z1; ++z) {
      for (std::int64_t x = before.x0; x < before.x1; ++x) {
        if (after.contains(x, z)) continue;
        const Direction d = x < after.x0    ? Direction::east
                            : x >= after.x1 ? Direction::west
                            : z >= after.z1 ? Direction::north
                                            : Direction::south;
        step_.jobs[std::size_t(d)].free.push_back({std::uint32_t(x), std::uint32_t(z)});
      }
    }
    for (StripJob& j : step_.jobs) sortNearestFirst(j.load, eyeX, eyeZ, e);
  }
  for (const StripJob& j : step_.jobs) step_.changed = step_.changed || j.signalled();
  return step_;
}

// ------------------------------------------------------------- needed set

std::uint32_t levelForDistance(double distance, double viewDistance, std::uint32_t levels,
                               std::span<const double> ringEdges) {
  if (levels <= 1) return 0;
  if (!ringEdges.empty()) {
    for (std::size_t l = 0; l < ringEdges.size() && l < levels; ++l) {
      if (distance <= ringEdges[l]) return std::uint32_t(l);
    }
    return levels - 1;
  }
  if (!(viewDistance > 0)) return 0;
  const double bin = viewDistance / double(levels);
  // A distance on a bin edge belongs to the finer bin (Table 8: 0-1500 is high).
  const double l = std::ceil(distance / bin - 1e-9) - 1;
  return std::uint32_t(std::clamp<double>(l, 0, double(levels - 1)));
}

void neededModules(const NeedParams& p, double moduleSize, std::uint32_t modulesX,
                   std::uint32_t modulesZ, std::uint32_t levels, std::vector<NeededModule>& out) {
  out.clear();
  if (!(moduleSize > 0) || modulesX == 0 || modulesZ == 0) return;
  ViewTriangleParams t;
  t.eyeX = p.eyeX;
  t.eyeZ = p.eyeZ;
  t.headingDeg = p.headingDeg;
  t.halfAngleDeg = p.halfAngleDeg;
  t.viewDistance = p.viewDistance;
  t.pullback = p.pullback;
  // Modules are the squares of a grid whose spacing is the module edge.
  const std::vector<RowSpan> spans =
      selectSquares(makeViewTriangle(t), moduleSize, modulesX, modulesZ, 0);
  for (const RowSpan& s : spans) {
    for (std::uint32_t kx = s.firstI; kx <= s.lastI; ++kx) {
      const double x0 = double(kx) * moduleSize, z0 = double(s.j) * moduleSize;
      const double dx = std::max({x0 - p.eyeX, 0.0, p.eyeX - (x0 + moduleSize)});
      const double dz = std::max({z0 - p.eyeZ, 0.0, p.eyeZ - (z0 + moduleSize)});
      const double d = std::hypot(dx, dz);
      if (d > p.viewDistance) continue;  // beyond the fog: the triangle's far corners
      out.push_back({kx, s.j, levelForDistance(d, p.viewDistance, levels, p.ringEdges), d});
    }
  }
}

std::vector<NeededModule> neededModules(const NeedParams& p, double moduleSize,
                                        std::uint32_t modulesX, std::uint32_t modulesZ,
                                        std::uint32_t levels) {
  std::vector<NeededModule> out;
  neededModules(p, moduleSize, modulesX, modulesZ, levels, out);
  return out;
}

}  // namespace sandtable::paging
