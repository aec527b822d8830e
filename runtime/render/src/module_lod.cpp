// Level of detail as drawn: each node run at its wanted level or, while
// the upload budget defers that level, at the nearest coarser one resident
// (runs merged so no ground is drawn twice), what covers each finest-level
// node, and which node sides need a skirt.
#include <algorithm>
#include <cmath>

#include "module_draw.h"
#include "sandtable/base/morton.h"
#include "sandtable/scene/lod.h"

namespace sandtable::render::detail {

void ModuleRenderer::resolveModule(const scene::DisplayBuffer& buf, std::size_t i0, std::size_t i1, RenderStats& stats) {
  const scene::ModuleDraw& d = buf.modules[buf.nodes[i0].module];
  const auto levels = std::uint32_t(d.ref.module().levels.size());
  const auto entryAt = [&](std::uint32_t l) { return ready(cacheKey(d.kx, d.kz, l)); };
  spans_.clear();
  bool anyFallback = false;
  for (std::size_t k = i0; k < i1; ++k) {
    const scene::NodeDraw& nd = buf.nodes[k];
    std::uint32_t l = nd.level;
    while (l + 1 < levels && !entryAt(l)) ++l;
    if (!entryAt(l)) continue;  // nothing resident at all (cannot happen: the coarsest is forced)
    // In the finest level's node grid (Morton): level l's node m covers [m 4^l, (m + 1) 4^l).
    const std::uint32_t s0 = 2 * nd.level, s = 2 * l;
    std::uint64_t f = std::uint64_t(nd.first) << s0, t = std::uint64_t(nd.last) << s0;
    if (l != nd.level) {
      // The coarser level's nodes round it: the run widened to them.
      anyFallback = true;
      ++stats.nodesFallback;
      f = (f >> s) << s;
      t = ((t + (1ull << s) - 1) >> s) << s;
    }
    spans_.push_back({l, f, t, l == nd.level ? nd.morph : 0.0f, l != nd.level});
  }
  if (anyFallback) {
    // A widened run covers its siblings too: they and any run it overlaps
    // merge into it at the coarser of their levels (re-widened to it), so
    // no ground is drawn twice.
    std::sort(spans_.begin(), spans_.end(), [](const Span& a, const Span& b) { return a.f < b.f; });
    std::size_t out = 0;
    for (std::size_t k = 0; k < spans_.size(); ++k) {
      spans_[out++] = spans_[k];
      while (out >= 2 && spans_[out - 2].t > spans_[out - 1].f) {
        Span& a = spans_[out - 2];
        const Span& b = spans_[out - 1];
        a.level = std::max(a.level, b.level);
        a.t = std::max(a.t, b.t);
        a.morph = 0;
        a.fallback = true;
        const std::uint32_t s = 2 * a.level;
        a.f = (a.f >> s) << s;
        a.t = ((a.t + (1ull << s) - 1) >> s) << s;
        --out;
      }
    }
    spans_.resize(out);
  }
  // What covers each node of the finest level: where a skirt is needed.
  const std::uint32_t side0 = scene::nodesPerSide(0, levels);
  const auto cells = std::uint32_t(cells_.size());
  cells_.resize(cells_.size() + std::size_t(side0) * side0);
  moduleCells_[buf.nodes[i0].module] = {cells, side0};
  for (const Span& sp : spans_) {
    for (std::uint64_t m = sp.f; m < sp.t; ++m) {
      const auto [x, z] = morton::decode(std::uint32_t(m));
      if (x < side0 && z < side0) cells_[cells + std::size_t(z) * side0 + x] = {sp.level, sp.morph};
    }
  }
  for (const Span& sp : spans_) {
    const std::uint32_t s = 2 * sp.level;
    drawn_.push_back({entryAt(sp.level), sp.level, std::uint32_t(sp.f >> s), std::uint32_t(sp.t >> s), sp.morph,
                      buf.nodes[i0].module, cells, side0});
  }
}

bool ModuleRenderer::drawnAt(std::uint32_t module, double x, double z, std::uint32_t& level,
                             float& morph) const {
  if (module >= moduleCells_.size() || moduleSize_ <= 0) return false;
  const auto [first, side] = moduleCells_[module];
  if (side == 0) return false;
  const double cell = moduleSize_ / side;
  const auto cx = std::uint32_t(std::clamp(std::floor(x / cell), 0.0, double(side - 1)));
  const auto cz = std::uint32_t(std::clamp(std::floor(z / cell), 0.0, double(side - 1)));
  const Cell& c = cells_[first + std::size_t(cz) * side + cx];
  if (c.level == UINT32_MAX) return false;
  level = c.level;
  morph = c.morph;
  return true;
}

bool ModuleRenderer::skirtNeeded(const Drawn& dr, std::uint32_t node, std::uint32_t side) const {
  const auto [a, b] = morton::decode(node);
  const std::uint32_t scale = 1u << dr.level, n = dr.side0;
  // The finest-level cells just across the side, from x0/z0 along the other axis.
  std::int64_t x = std::int64_t(a) * scale, z = std::int64_t(b) * scale;
  std::int64_t dx = 0, dz = 0;
  if (side == kSideNorth) --z, dx = 1;
  if (side == kSideSouth) z += scale, dx = 1;
  if (side == kSideWest) --x, dz = 1;
  if (side == kSideEast) x += scale, dz = 1;
  for (std::uint32_t k = 0; k < scale; ++k, x += dx, z += dz) {
    if (x < 0 || z < 0 || x >= n || z >= n) return true;  // another module's
    const Cell& c = cells_[dr.cells + std::size_t(z) * n + std::size_t(x)];
    if (c.level != dr.level || c.morph != dr.morph) return true;
  }
  return false;
}

}  // namespace sandtable::render::detail
