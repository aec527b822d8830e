// The synthetic terrain: a landform function (coast, plains, ridged
// mountains), basins part filled and river valleys carved along a drainage
// network traced on a coarse grid, and flat lakes. Everything is a
// deterministic function of (position, seed, size), so DTED1, DTED2 and the
// GeoTIFF agree.
#include <algorithm>
#include <atomic>
#include <cmath>
#include <limits>
#include <numbers>
#include <queue>

#include "synth_internal.h"
#include "sandtable/base/jobs.h"
#include "sandtable/converters/grid8.h"

namespace sandtable::convert::synth {

// ---------------------------------------------------------------- basics

Frame::Frame(double lon, double lat) : lon0(lon), lat0(lat) {
  // WGS 84 equatorial radius: a degree of latitude is ~111.3 km. The square
  // is small enough that one scale per axis is a fair "local metres".
  constexpr double kMetresPerDegree = 6378137.0 * std::numbers::pi / 180.0;
  mPerDegLat = kMetresPerDegree;
  mPerDegLon = kMetresPerDegree * std::cos(lat * std::numbers::pi / 180.0);
}

std::uint32_t hash32(std::uint32_t a, std::uint32_t b, std::uint32_t c) {
  std::uint32_t h = a * 0x9E3779B1u ^ (b + 0x7F4A7C15u) * 0x85EBCA77u ^ (c + 0x165667B1u) * 0xC2B2AE3Du;
  h ^= h >> 16;
  h *= 0x7FEB352Du;
  h ^= h >> 15;
  h *= 0x846CA68Bu;
  h ^= h >> 16;
  return h;
}

void parallelFor(std::size_t n, int threads, const std::function<void(std::size_t, std::size_t)>& fn) {
  // About four ranges per worker: balanced when rows cost unequal amounts.
  const std::size_t t = static_cast<std::size_t>(jobs::threadCount(threads));
  jobs::parallelRanges(n, threads, std::max<std::size_t>(1, n / (4 * t)), fn);
}

// ---------------------------------------------------------------- noise

namespace {

struct GradientTable {
  std::array<Vec2, 16> g;
  GradientTable() {
    for (std::size_t k = 0; k < g.size(); ++k) {
      const double a = (static_cast<double>(k) + 0.5) * 2.0 * std::numbers::pi / 16.0;
      g[k] = {std::cos(a), std::sin(a)};
    }
  }
};
const GradientTable kGradients;

inline int fastFloor(double v) {
  const int i = static_cast<int>(v);
  return v < i ? i - 1 : i;
}

inline double fade(double t) { return t * t * t * (t * (t * 6 - 15) + 10); }

// One multiply-xorshift is enough to pick one of 16 gradients (the top
// bits are the well mixed ones).
inline const Vec2& gradient(std::uint32_t h) {
  h ^= h >> 15;
  h *= 0x2C1B3C6Du;
  return kGradients.g[h >> 28];
}

/// 2-D gradient noise, roughly in [-1, 1], zero at lattice points.
/// Always inlined: it is most of the cost of a post.
[[gnu::always_inline]] inline double noise(double x, double y, std::uint32_t seed) {
  const int ix = fastFloor(x), iy = fastFloor(y);
  const double tx = x - ix, ty = y - iy;
  const std::uint32_t hx0 = static_cast<std::uint32_t>(ix) * 0x8DA6B343u;
  const std::uint32_t hx1 = hx0 + 0x8DA6B343u;
  const std::uint32_t hy0 = static_cast<std::uint32_t>(iy) * 0xD8163841u + seed * 0xCB1AB31Fu;
  const std::uint32_t hy1 = hy0 + 0xD8163841u;
  const Vec2& g00 = gradient(hx0 ^ hy0);
  const Vec2& g10 = gradient(hx1 ^ hy0);
  const Vec2& g01 = gradient(hx0 ^ hy1);
  const Vec2& g11 = gradient(hx1 ^ hy1);
  const double n00 = g00.x * tx + g00.y * ty;
  const double n10 = g10.x * (tx - 1) + g10.y * ty;
  const double n01 = g01.x * tx + g01.y * (ty - 1);
  const double n11 = g11.x * (tx - 1) + g11.y * (ty - 1);
  const double u = fade(tx), v = fade(ty);
  return 1.4 * lerp(lerp(n00, n10, u), lerp(n01, n11, u), v);
}

// Octaves are rotated by ~37 degrees and shifted so the lattice of one does
// not line up with the next (no visible grid directions).
inline void nextOctave(double& x, double& y) {
  const double nx = (0.8 * x - 0.6 * y) * 2.0 + 17.13;
  y = (0.6 * x + 0.8 * y) * 2.0 - 9.71;
  x = nx;
}

/// Fractal sum, normalised to roughly [-1, 1].
[[gnu::always_inline]] inline double fbmInline(double x, double y, std::uint32_t seed, int octaves) {
  double sum = 0, amp = 1, norm = 0;
  for (int i = 0; i < octaves; ++i) {
    sum += amp * noise(x, y, seed + static_cast<std::uint32_t>(i) * 101u);
    norm += amp;
    amp *= 0.5;
    nextOctave(x, y);
  }
  return sum / norm;
}

}  // namespace

double fbm(double x, double y, std::uint32_t seed, int octaves) { return fbmInline(x, y, seed, octaves); }

namespace {

/// Musgrave's ridged multifractal: sharp crests where the noise crosses
/// zero; each octave is weighted by the one before, so detail piles up on
/// crests and valleys stay smooth. Stops once what is left cannot add more
/// than `cutoff` (relative), which keeps valleys and plains cheap.
double ridged(double x, double y, std::uint32_t seed, int octaves, double cutoff) {
  double sum = 0, amp = 1, weight = 1;
  for (int i = 0; i < octaves; ++i) {
    double s = 1.0 - std::fabs(noise(x, y, seed + static_cast<std::uint32_t>(i) * 7919u));
    s *= s;
    s *= weight;
    weight = clamp01(s * 2.0);
    sum += s * amp;
    amp *= 0.52;
    if (weight * amp * 3.0 < cutoff) break;
    nextOctave(x, y);
  }
  return sum;
}

// Salts so each noise field gets its own stream.
enum Salt : std::uint32_t {
  kCoastLarge = 11,
  kCoastMid,
  kCoastSmall,
  kWarpX,
  kWarpY,
  kHills,
  kUplift,
  kRidges,
  kRanges,
  kSpurs,
  kLowland,
};

}  // namespace

// ---------------------------------------------------------------- terrain

namespace {
constexpr double kPeak = 2000.0;           // highest ridges, m
constexpr double kRidgeWavelength = 9000;  // m
constexpr double kPlainHeight = 100.0;     // lowland rise, m
constexpr double kHillHeight = 110.0;      // rolling relief on land, m
}  // namespace

TerrainSpec makeSpec(double sizeM, std::uint64_t seed) {
  TerrainSpec s;
  s.size = sizeM;
  s.seed = hash32(static_cast<std::uint32_t>(seed), static_cast<std::uint32_t>(seed >> 32), 0x5A17u);
  // The sea lies along one side of the square, picked by the seed, turned
  // a little so the coast is not parallel to the grid.
  const double side = static_cast<double>(hash32(s.seed, 1) % 4u) * 0.5 * std::numbers::pi;
  const double jitter = (unit(hash32(s.seed, 2)) - 0.5) * 0.6;
  const double a = -0.5 * std::numbers::pi + side + jitter;  // side 0: sea to the south
  s.inland = {-std::cos(a), -std::sin(a)};
  s.coastOffset = 0.3 * sizeM;  // the sea takes ~20% of the square
  return s;
}

Terrain::Terrain(const TerrainSpec& spec) : spec_(spec) {
  plainWidth_ = std::clamp(0.08 * spec.size, 1000.0, 30000.0);
  rampWidth_ = std::clamp(0.25 * spec.size, 4000.0, 80000.0);
  // Large squares get separate ranges with lowland between; small ones are
  // all one range (or they would be mostly plain).
  rangeBlend_ = smoothstep(100e3, 400e3, spec.size);
}

double Terrain::inland(Vec2 p) const {
  const double s = spec_.size;
  double d = p.x * spec_.inland.x + p.y * spec_.inland.y + spec_.coastOffset;
  const double large = 0.45 * s;
  d += 0.07 * s * fbmInline(p.x / large, p.y / large, spec_.seed + kCoastLarge, 1);
  const double mid = std::max(5000.0, 0.1 * s);
  d += std::clamp(0.03 * s, 1200.0, 8000.0) * fbmInline(p.x / mid, p.y / mid, spec_.seed + kCoastMid, 1);
  d += 350.0 * fbmInline(p.x / 1800.0, p.y / 1800.0, spec_.seed + kCoastSmall, 2);  // coves, points
  return d;
}

double Terrain::base(Vec2 p) const {
  const double d = inland(p);
  if (d <= 0) return -20.0 * smoothstep(0, 1500, -d);  // shallow shelf, never above 0

  // Domain warp bends the ridges so they do not look like stretched noise.
  const double w = kRidgeWavelength * 1.3;
  const Vec2 q{p.x + 0.35 * kRidgeWavelength * fbmInline(p.x / w, p.y / w, spec_.seed + kWarpX, 2),
               p.y + 0.35 * kRidgeWavelength * fbmInline(p.x / w, p.y / w, spec_.seed + kWarpY, 2)};

  // The coastal lowland widens and narrows along the coast.
  const double lowland = plainWidth_ * (0.3 + 1.4 * (0.5 + 0.5 * fbmInline(p.x / 7000.0, p.y / 7000.0, spec_.seed + kLowland, 1)));
  const double shore = smoothstep(0, 400, d);  // keeps the coastline where d = 0
  double h = kPlainHeight * (1.0 - std::exp(-d / lowland));
  h += shore * kHillHeight * (0.5 + 0.5 * fbmInline(q.x / 3500.0, q.y / 3500.0, spec_.seed + kHills, 3));

  const double foot = 0.4 * lowland;
  double m = smoothstep(foot, foot + rampWidth_, d);
  if (rangeBlend_ > 0 && m > 0) {
    const double r = fbmInline(q.x / 160e3, q.y / 160e3, spec_.seed + kRanges, 2);
    m *= lerp(1.0, smoothstep(-0.2, 0.35, r), rangeBlend_);
  }
  if (m <= 0) return h;
  const double uplift = 0.75 + 0.25 * fbmInline(q.x / 30e3, q.y / 30e3, spec_.seed + kUplift, 1);
  const double cutoff = 0.3 / (kPeak * m * uplift);
  const double r = ridged(q.x / kRidgeWavelength, q.y / kRidgeWavelength, spec_.seed + kRidges, 10, cutoff) / 1.5;
  // Squaring widens valleys and sharpens crests; the exponential keeps the
  // rare very high crest from towering over the range.
  h += m * kPeak * uplift * (1.0 - std::exp(-1.3 * r * r)) / (1.0 - std::exp(-1.3));
  // Spurs and hollows on the flanks: without them long smooth slopes drain
  // in parallel lines, which no real range does.
  h += m * 160.0 * (0.5 + 0.5 * fbmInline(q.x / 1600.0, q.y / 1600.0, spec_.seed + kSpurs, 4));
  return h;
}

double Terrain::landform(Vec2 p) const {
  const double b = base(p);
  if (valleyShape_.empty()) return b;
  const Grid& g = valleyGrid_;
  const double gx = (p.x - g.x0) / g.step, gy = (p.y - g.y0) / g.step;
  if (!(gx >= 0 && gy >= 0 && gx < g.nx - 1 && gy < g.ny - 1)) return b;
  const int i = static_cast<int>(gx), j = static_cast<int>(gy);
  const double fx = gx - i, fy = gy - j;
  const std::size_t k = g.index(i, j), up = static_cast<std::size_t>(g.nx);
  auto at = [&](const std::vector<float>& v) {
    return lerp(lerp(v[k], v[k + 1], fx), lerp(v[k + up], v[k + up + 1], fx), fy);
  };
  // Basins filled to their spill level (flat floors, no closed pits).
  const double filled = b + at(basinFill_);
  // Valleys. Interpolating the linear form (shape * h + offset) blends the
  // corners' carves evaluated at this h; interpolating bed and shape
  // separately would raise spikes where neighbouring cells follow
  // different rivers.
  const double s = at(valleyShape_);
  const double carved = s >= 1.0 ? filled : std::min(filled, s * filled + at(valleyOffset_));
  // Fade out towards the edge of the grid: no cliff where the model ends
  // (the edge lies well outside the square).
  const double edge = std::min({gx, gy, g.nx - 1 - gx, g.ny - 1 - gy});
  return b + (carved - b) * smoothstep(0.0, 20.0, edge);
}

namespace {
/// Position of p relative to a lake: distance from centre and rim radius.
struct LakeHit {
  double r, rim;
};
LakeHit lakeHit(const Lake& lake, Vec2 p) {
  const double dx = p.x - lake.centre.x, dy = p.y - lake.centre.y;
  return {std::sqrt(dx * dx + dy * dy), lake.rimRadius(std::atan2(dy, dx))};
}
}  // namespace

double Terrain::withLakes(Vec2 p, double h) const {
  if (lakes_.empty()) return h;
  const Grid& g = lakeGrid_;
  const int i = static_cast<int>(std::floor((p.x - g.x0) / g.step));
  const int j = static_cast<int>(std::floor((p.y - g.y0) / g.step));
  if (i < 0 || j < 0 || i >= g.nx || j >= g.ny) return h;
  for (std::uint32_t id : lakeBuckets_[g.index(i, j)]) {
    const Lake& lake = lakes_[id];
    const double reach = lake.maxRadius() + lake.margin;
    const double dx = p.x - lake.centre.x, dy = p.y - lake.centre.y;
    if (dx * dx + dy * dy >= reach * reach) continue;
    const LakeHit hit = lakeHit(lake, p);
    if (hit.r <= hit.rim) return lake.level;
    // The shore blends into the land: the lake sits in a basin, not a pit.
    h = lake.level + (h - lake.level) * smoothstep(0, lake.margin, hit.r - hit.rim);
  }
  return h;
}

bool Terrain::inLake(Vec2 p) const {
  for (const Lake& lake : lakes_) {
    const double reach = lake.maxRadius();
    const double dx = p.x - lake.centre.x, dy = p.y - lake.centre.y;
    if (dx * dx + dy * dy > reach * reach) continue;
    const LakeHit hit = lakeHit(lake, p);
    if (hit.r <= hit.rim) return true;
  }
  return false;
}

void Terrain::setValleys(const Grid& g, std::vector<float> fill, std::vector<float> shape, std::vector<float> offset) {
  valleyGrid_ = g;
  basinFill_ = std::move(fill);
  valleyShape_ = std::move(shape);
  valleyOffset_ = std::move(offset);
}

void Terrain::setLakes(std::vector<Lake> lakes) {
  lakes_ = std::move(lakes);
  lakeBuckets_.clear();
  if (lakes_.empty()) return;
  double x0 = std::numeric_limits<double>::max(), y0 = x0, x1 = -x0, y1 = -x0;
  for (const Lake& l : lakes_) {
    const double r = l.maxRadius() + l.margin;
    x0 = std::min(x0, l.centre.x - r), y0 = std::min(y0, l.centre.y - r);
    x1 = std::max(x1, l.centre.x + r), y1 = std::max(y1, l.centre.y + r);
  }
  Grid& g = lakeGrid_;
  g.step = 4000.0;
  g.x0 = x0, g.y0 = y0;
  g.nx = static_cast<int>((x1 - x0) / g.step) + 1;
  g.ny = static_cast<int>((y1 - y0) / g.step) + 1;
  lakeBuckets_.assign(g.size(), {});
  for (std::uint32_t id = 0; id < lakes_.size(); ++id) {
    const Lake& l = lakes_[id];
    const double r = l.maxRadius() + l.margin;
    const int i0 = static_cast<int>((l.centre.x - r - x0) / g.step), i1 = static_cast<int>((l.centre.x + r - x0) / g.step);
    const int j0 = static_cast<int>((l.centre.y - r - y0) / g.step), j1 = static_cast<int>((l.centre.y + r - y0) / g.step);
    for (int j = std::max(0, j0); j <= std::min(g.ny - 1, j1); ++j) {
      for (int i = std::max(0, i0); i <= std::min(g.nx - 1, i1); ++i) lakeBuckets_[g.index(i, j)].push_back(id);
    }
  }
}

// ---------------------------------------------------------------- drainage

namespace {

/// The landform with every closed depression filled to its spill level
/// (priority flood from the sea and the grid border). buildWorld fills
/// basins part way towards it (kBasinFill): rivers then leave a basin
/// through a shallow gorge instead of one cut down to its floor, and the
/// basin floor is a gentle bowl, as sediment would make it.
std::vector<float> fillDepressions(const Grid& g, const std::vector<float>& h) {
  using Item = std::pair<float, std::uint32_t>;
  std::priority_queue<Item, std::vector<Item>, std::greater<>> open;
  std::vector<float> f(h.begin(), h.end());
  std::vector<std::uint8_t> seen(g.size(), 0);
  for (int j = 0; j < g.ny; ++j) {
    for (int i = 0; i < g.nx; ++i) {
      const std::size_t c = g.index(i, j);
      if (h[c] <= 0 || i == 0 || j == 0 || i == g.nx - 1 || j == g.ny - 1) {
        seen[c] = 1;
        open.push({h[c], static_cast<std::uint32_t>(c)});
      }
    }
  }
  while (!open.empty()) {
    const auto [level, c] = open.top();
    open.pop();
    grid8::forEachNeighbour(g.nx, g.ny, c, [&](int, std::size_t nc) {
      if (seen[nc]) return;
      seen[nc] = 1;
      f[nc] = std::max(h[nc], level);
      open.push({f[nc], static_cast<std::uint32_t>(nc)});
    });
  }
  return f;
}

/// Flow routing. Priority flood (Barnes et al.) reaches every cell from the
/// sea and the grid border upwards; its tree gives each pit a way out.
/// Pits are breached along that way (cells lowered just enough to keep
/// falling), then every cell drains to its steepest lower neighbour (D8).
/// Plain priority-flood directions would do, but inside depressions they
/// fan out in straight lines; steepest descent follows the ground.
struct Drainage {
  std::vector<std::int32_t> parent;  ///< downstream cell, -1 at outlets
  std::vector<std::uint32_t> order;  ///< downstream before upstream
  std::vector<float> area;           ///< upstream area in cells (self included)
};

Drainage drain(const Grid& g, const std::vector<float>& h, std::uint32_t seed) {
  // Inside a filled depression every cell has the spill level; the lower
  // ground goes first there, so ways out follow the floor instead of
  // spreading breadth-first in straight lines.
  struct Item {
    float level, ground;
    std::uint32_t seq, cell;
    bool operator>(const Item& o) const {
      if (level != o.level) return level > o.level;
      if (ground != o.ground) return ground > o.ground;
      return seq > o.seq;
    }
  };
  const std::size_t n = g.size();
  // Routing heights: the landform plus a little smooth noise, so flow on
  // gentle slopes wanders instead of running in straight D8 lines.
  std::vector<float> z(h.begin(), h.end());
  for (std::size_t c = 0; c < n; ++c) {
    if (h[c] <= 0) continue;
    const Vec2 p = g.at(c);
    const double wander = fbm(p.x / (6.0 * g.step), p.y / (6.0 * g.step), seed + 0x9A1Du, 2);
    z[c] += static_cast<float>(g.step * (0.1 * wander + 0.01 * unit(hash32(seed, static_cast<std::uint32_t>(c)))));
  }
  std::vector<std::int32_t> floodParent(n, -1);
  std::vector<std::uint32_t> floodOrder;
  floodOrder.reserve(n);
  std::vector<std::uint8_t> outlet(n, 0);
  {
    std::vector<std::uint8_t> seen(n, 0);
    std::priority_queue<Item, std::vector<Item>, std::greater<>> open;
    std::uint32_t seq = 0;
    for (int j = 0; j < g.ny; ++j) {
      for (int i = 0; i < g.nx; ++i) {
        const std::size_t c = g.index(i, j);
        if (h[c] <= 0 || i == 0 || j == 0 || i == g.nx - 1 || j == g.ny - 1) {
          seen[c] = outlet[c] = 1;
          open.push({z[c], z[c], seq++, static_cast<std::uint32_t>(c)});
        }
      }
    }
    while (!open.empty()) {
      const Item it = open.top();
      open.pop();
      floodOrder.push_back(it.cell);
      grid8::forEachNeighbour(g.nx, g.ny, it.cell, [&](int, std::size_t nc) {
        if (seen[nc]) return;
        seen[nc] = 1;
        floodParent[nc] = static_cast<std::int32_t>(it.cell);
        open.push({std::max(z[nc], it.level), z[nc], seq++, static_cast<std::uint32_t>(nc)});
      });
    }
  }

  // Breach: from each pit follow the flood tree out, lowering cells until
  // one is already lower. Lowering never makes a new pit (each lowered cell
  // has its lower successor), so one pass over the cells does.
  auto lowestNeighbour = [&](std::size_t c, float& drop) {
    std::int32_t best = -1;
    drop = 0;
    grid8::forEachNeighbour(g.nx, g.ny, c, [&](int k, std::size_t nc) {
      const float d = (z[c] - z[nc]) / (grid8::diagonal(k) ? std::numbers::sqrt2_v<float> : 1.0f);
      if (d > drop) drop = d, best = static_cast<std::int32_t>(nc);
    });
    return best;
  };
  for (std::uint32_t c : floodOrder) {
    if (outlet[c]) continue;
    float drop;
    if (lowestNeighbour(c, drop) >= 0) continue;
    float level = z[c];
    for (std::int32_t q = floodParent[c]; q >= 0 && !outlet[static_cast<std::size_t>(q)]; q = floodParent[static_cast<std::size_t>(q)]) {
      float& zq = z[static_cast<std::size_t>(q)];
      if (zq < level) break;
      zq = std::nextafter(std::nextafter(level, -1e30f), -1e30f);
      level = zq;
    }
  }

  Drainage d;
  d.parent.assign(n, -1);
  for (std::size_t c = 0; c < n; ++c) {
    if (outlet[c]) continue;
    float drop;
    // After breaching every land cell has a lower neighbour; were one left
    // without, it would simply be a sink (-1), never a cycle.
    d.parent[c] = lowestNeighbour(c, drop);
  }
  // Downstream before upstream: by lowered height, outlets first.
  d.order.resize(n);
  for (std::size_t c = 0; c < n; ++c) d.order[c] = static_cast<std::uint32_t>(c);
  std::sort(d.order.begin(), d.order.end(), [&](std::uint32_t a, std::uint32_t b) {
    if (outlet[a] != outlet[b]) return outlet[a] > outlet[b];
    return z[a] != z[b] ? z[a] < z[b] : a < b;
  });
  d.area.assign(n, 1.0f);
  for (std::size_t k = n; k-- > 0;) {
    const std::uint32_t c = d.order[k];
    if (d.parent[c] >= 0) d.area[static_cast<std::size_t>(d.parent[c])] += d.area[c];
  }
  return d;
}

/// A river from its source to where it ends: the sea, the grid border, or
/// a bigger river (the confluence cell is its last).
struct Stem {
  std::vector<std::uint32_t> cells;  ///< upstream first
  std::uint32_t nameId = 0;
};

struct Network {
  std::vector<Stem> stems;
  std::vector<float> bed;  ///< river bed per cell (rivers only)
};

/// How deep a river has cut below the landform, from its drainage area:
/// small streams a few metres, big rivers a few hundred.
double incision(double areaKm2) { return 20.0 * std::pow(areaKm2, 0.45); }

Network riverNetwork(const Grid& g, const std::vector<float>& h, const Drainage& d, float threshold) {
  const std::size_t n = g.size();
  std::vector<std::uint8_t> river(n, 0);
  for (std::size_t c = 0; c < n; ++c) river[c] = d.area[c] >= threshold ? 1 : 0;
  const double cellKm2 = g.step * g.step * 1e-6;

  Network net;
  // Bed: the running minimum of the landform downstream (so every river
  // runs downhill; leaving a pit it cuts a gorge through the rim), lowered
  // by the incision, but never below half that minimum (no fjords); then
  // itself a running minimum, so it never rises downstream.
  net.bed.assign(n, std::numeric_limits<float>::max());
  std::vector<float> runMin(n, std::numeric_limits<float>::max());
  std::vector<std::uint8_t> hasChild(n, 0);
  std::vector<std::int32_t> mainChild(n, -1);
  for (std::size_t k = n; k-- > 0;) {
    const std::uint32_t c = d.order[k];
    if (!river[c]) continue;
    runMin[c] = std::min(h[c], runMin[c]);
    // Lowland streams barely cut in (no gullied coastal plains); the bed
    // may not rise downstream where the cut lessens, hence the min.
    const double cut = incision(d.area[c] * cellKm2) * (0.2 + 0.8 * smoothstep(30.0, 400.0, runMin[c]));
    net.bed[c] = std::min(net.bed[c], static_cast<float>(std::max(runMin[c] - cut, 0.5 * runMin[c])));
    const std::int32_t p = d.parent[c];
    if (p < 0) continue;
    const auto pc = static_cast<std::size_t>(p);
    runMin[pc] = std::min(runMin[pc], runMin[c]);
    net.bed[pc] = std::min(net.bed[pc], net.bed[c]);
    hasChild[pc] = 1;
    const std::int32_t m = mainChild[pc];
    if (m < 0 || d.area[c] > d.area[static_cast<std::size_t>(m)]) mainChild[pc] = static_cast<std::int32_t>(c);
  }
  // Stems start at sources and follow the flow while they stay the main
  // branch; a tributary ends in the confluence cell.
  std::uint32_t nextName = 0;
  for (std::uint32_t c : d.order) {
    if (!river[c] || hasChild[c] || d.parent[c] < 0) continue;
    Stem s;
    s.nameId = nextName++;
    s.cells.push_back(c);
    std::uint32_t cur = c;
    for (std::int32_t p = d.parent[c]; p >= 0; p = d.parent[cur]) {
      const auto pc = static_cast<std::uint32_t>(p);
      s.cells.push_back(pc);
      if (mainChild[pc] != static_cast<std::int32_t>(cur)) break;
      cur = pc;
    }
    net.stems.push_back(std::move(s));
  }
  return net;
}

std::string riverName(std::uint32_t seed, std::uint32_t id) {
  static const char* kStart[] = {"Al", "Bra", "Cor", "Dun", "El", "Fen", "Gar", "Ka", "Lo", "Mar",
                                 "Nor", "Or", "Pra", "Ros", "Sal", "Tor", "Ul", "Var", "Wen", "Zel"};
  static const char* kMiddle[] = {"a", "e", "i", "o", "en", "an", "ar", "is", "on", "u"};
  static const char* kEnd[] = {"mo", "na", "ra", "ssa", "ven", "dor", "lia", "ta", "ne", "sk"};
  const std::uint32_t h = hash32(seed, id, 0x4E41u);
  std::string s = kStart[h % 20u];
  s += kMiddle[(h >> 8) % 10u];
  s += kEnd[(h >> 16) % 10u];
  return s;
}

/// One segment of a river centreline with its bed heights.
struct Segment {
  Vec2 a, b;
  double bedA, bedB;
  double floorWidth;  ///< half-width of the flat valley floor, m
  double maxWidth;    ///< widest the valley gets (half-width), m
  bool major;         ///< a written river (counts for riverDist)
};

/// A stem as a line in metres: smoothed, meandering, with bed and area.
struct RiverLine {
  std::vector<Vec2> pts;
  std::vector<double> bed, areaKm2;
  std::uint32_t nameId = 0;
};

/// Douglas-Peucker: fewer, longer segments to carve (the written river is
/// this same line, densified, so it stays on the valley floor).
void simplify(RiverLine& line, double tolerance) {
  const std::size_t n = line.pts.size();
  if (n < 3) return;
  std::vector<std::uint8_t> keep(n, 0);
  keep.front() = keep.back() = 1;
  std::vector<std::pair<std::size_t, std::size_t>> todo{{0, n - 1}};
  while (!todo.empty()) {
    const auto [a, b] = todo.back();
    todo.pop_back();
    const Vec2 pa = line.pts[a], pb = line.pts[b];
    const double ex = pb.x - pa.x, ey = pb.y - pa.y, len = std::max(std::hypot(ex, ey), 1e-9);
    double worst = 0;
    std::size_t at = a;
    for (std::size_t k = a + 1; k < b; ++k) {
      const double d = std::fabs((line.pts[k].x - pa.x) * ey - (line.pts[k].y - pa.y) * ex) / len;
      if (d > worst) worst = d, at = k;
    }
    if (worst > tolerance) {
      keep[at] = 1;
      todo.push_back({a, at});
      todo.push_back({at, b});
    }
  }
  RiverLine out;
  out.nameId = line.nameId;
  for (std::size_t k = 0; k < n; ++k) {
    if (!keep[k]) continue;
    out.pts.push_back(line.pts[k]);
    out.bed.push_back(line.bed[k]);
    out.areaKm2.push_back(line.areaKm2[k]);
  }
  line = std::move(out);
}

RiverLine riverLine(const Grid& g, const Stem& s, const Network& net, const Drainage& d, std::uint32_t seed) {
  RiverLine line;
  line.nameId = s.nameId;
  const double cellKm2 = g.step * g.step * 1e-6;
  for (std::uint32_t c : s.cells) {
    line.pts.push_back(g.at(c));
    line.bed.push_back(net.bed[c]);
    line.areaKm2.push_back(d.area[c] * cellKm2);
  }
  // The last cell is the confluence or outlet: its area includes the other
  // river's; this stem carries what it had just above.
  if (line.areaKm2.size() >= 2) line.areaKm2.back() = line.areaKm2[line.areaKm2.size() - 2];
  // chaikin/resample carry one value each: the second pass only for area.
  std::vector<Vec2> pts = line.pts;
  chaikin(line.pts, &line.bed, 2);
  resample(line.pts, &line.bed, std::max(50.0, g.step));
  chaikin(pts, &line.areaKm2, 2);
  resample(pts, &line.areaKm2, std::max(50.0, g.step));
  // Meanders: a sideways offset, phased by distance from the downstream
  // end and tapered at both ends so stems still meet. Grid-routed rivers
  // are otherwise too straight.
  const std::size_t n = line.pts.size();
  if (n >= 3) {
    std::vector<double> along(n, 0.0);
    for (std::size_t k = n - 1; k-- > 0;) {
      along[k] = along[k + 1] + std::hypot(line.pts[k + 1].x - line.pts[k].x, line.pts[k + 1].y - line.pts[k].y);
    }
    std::vector<Vec2> moved = line.pts;
    const double wave = 12.0 * g.step;
    for (std::size_t k = 1; k + 1 < n; ++k) {
      const Vec2 a = line.pts[k - 1], b = line.pts[k + 1];
      double tx = b.x - a.x, ty = b.y - a.y;
      const double len = std::hypot(tx, ty);
      if (len <= 0) continue;
      tx /= len, ty /= len;
      const double taper = smoothstep(0, wave, std::min(along[k], along[0] - along[k]));
      const double off = 0.7 * g.step * taper * noise(along[k] / wave, 0.5, seed + 0x3EA4u);
      moved[k] = {line.pts[k].x - ty * off, line.pts[k].y + tx * off};
    }
    line.pts = std::move(moved);
  }
  simplify(line, 0.15 * g.step);
  return line;
}

/// The valley grid: at each cell the carve (bed, shape) that lowers the
/// landform most, over every river segment within reach. Stored as
/// (bed, shape) so posts between cells interpolate smoothly.
struct Valleys {
  std::vector<float> bed, shape, dist;
};

constexpr double kValleySide = 2.5;  // half-width gained per metre of depth
// Closed basins are filled this far towards their spill level: full fill
// leaves wide dead-flat floors, none leaves rivers to cut gorges as deep as
// the basins; partial fill keeps bowls and makes the gorges shallow.
constexpr float kBasinFill = 0.65f;

/// How far each segment's valley can reach: the widest it gets given the
/// highest ground near it (a max over 8x8-cell blocks), so the carving loop
/// skips the cells it cannot touch. Written rivers reach their full width,
/// since riverDist must be known that far.
std::vector<double> valleyReaches(const Grid& g, const std::vector<float>& h, const std::vector<Segment>& segs) {
  constexpr int kBlock = 8;
  const int bx = (g.nx + kBlock - 1) / kBlock, by = (g.ny + kBlock - 1) / kBlock;
  std::vector<float> blockMax(static_cast<std::size_t>(bx) * static_cast<std::size_t>(by), -1e30f);
  for (int j = 0; j < g.ny; ++j) {
    for (int i = 0; i < g.nx; ++i) {
      float& m = blockMax[static_cast<std::size_t>(j / kBlock) * static_cast<std::size_t>(bx) + static_cast<std::size_t>(i / kBlock)];
      m = std::max(m, h[g.index(i, j)]);
    }
  }
  std::vector<double> out(segs.size());
  const double block = kBlock * g.step;
  for (std::size_t k = 0; k < segs.size(); ++k) {
    const Segment& s = segs[k];
    if (s.major) {
      out[k] = s.maxWidth + g.step;
      continue;
    }
    const double r = s.maxWidth + g.step;
    const int i0 = std::max(0, static_cast<int>((std::min(s.a.x, s.b.x) - r - g.x0) / block));
    const int i1 = std::min(bx - 1, static_cast<int>((std::max(s.a.x, s.b.x) + r - g.x0) / block));
    const int j0 = std::max(0, static_cast<int>((std::min(s.a.y, s.b.y) - r - g.y0) / block));
    const int j1 = std::min(by - 1, static_cast<int>((std::max(s.a.y, s.b.y) + r - g.y0) / block));
    double top = -1e30;
    for (int j = j0; j <= j1; ++j) {
      for (int i = i0; i <= i1; ++i) top = std::max(top, static_cast<double>(blockMax[static_cast<std::size_t>(j) * static_cast<std::size_t>(bx) + static_cast<std::size_t>(i)]));
    }
    const double depth = std::max(0.0, top - std::min(s.bedA, s.bedB));
    out[k] = std::clamp(s.floorWidth + g.step + kValleySide * depth, s.floorWidth + 2 * g.step, s.maxWidth) + g.step;
  }
  return out;
}

Valleys carveValleys(const Grid& g, const std::vector<float>& h, const std::vector<Segment>& segs, int threads) {
  const std::size_t n = g.size();
  Valleys v;
  v.bed.assign(h.begin(), h.end());
  v.shape.assign(n, 1.0f);
  v.dist.assign(n, static_cast<float>(1e9));
  std::vector<float> best(h.begin(), h.end());
  const std::vector<double> reaches = valleyReaches(g, h, segs);
  parallelFor(static_cast<std::size_t>(g.ny), threads, [&](std::size_t jb, std::size_t je) {
    for (std::size_t k = 0; k < segs.size(); ++k) {
      const Segment& s = segs[k];
      const double reach = reaches[k];
      const int j0 = std::max(static_cast<int>(jb), static_cast<int>(std::floor((std::min(s.a.y, s.b.y) - reach - g.y0) / g.step)));
      const int j1 = std::min(static_cast<int>(je) - 1, static_cast<int>(std::ceil((std::max(s.a.y, s.b.y) + reach - g.y0) / g.step)));
      if (j0 > j1) continue;
      const int i0 = std::max(0, static_cast<int>(std::floor((std::min(s.a.x, s.b.x) - reach - g.x0) / g.step)));
      const int i1 = std::min(g.nx - 1, static_cast<int>(std::ceil((std::max(s.a.x, s.b.x) + reach - g.x0) / g.step)));
      const double ex = s.b.x - s.a.x, ey = s.b.y - s.a.y;
      const double len2 = std::max(ex * ex + ey * ey, 1e-9);
      for (int j = j0; j <= j1; ++j) {
        for (int i = i0; i <= i1; ++i) {
          const Vec2 p = g.at(i, j);
          const double t = clamp01(((p.x - s.a.x) * ex + (p.y - s.a.y) * ey) / len2);
          const double dx = p.x - (s.a.x + t * ex), dy = p.y - (s.a.y + t * ey);
          const double dist = std::sqrt(dx * dx + dy * dy);
          const std::size_t c = g.index(i, j);
          if (s.major && dist < v.dist[c]) v.dist[c] = static_cast<float>(dist);
          const double bed = lerp(s.bedA, s.bedB, t);
          const double b = h[c];
          if (b <= bed) continue;
          const double w = std::clamp(s.floorWidth + g.step + kValleySide * (b - bed), s.floorWidth + 2 * g.step, s.maxWidth);
          if (dist >= w) continue;
          const double f = smoothstep(s.floorWidth, w, dist);
          const double carve = bed + (b - bed) * f;
          if (carve < best[c]) {
            best[c] = static_cast<float>(carve);
            v.bed[c] = static_cast<float>(bed);
            v.shape[c] = static_cast<float>(f);
          }
        }
      }
    }
  });
  return v;
}

/// River width (m) written for a drainage area.
double riverWidth(double areaKm2) { return std::clamp(1.2 * std::sqrt(areaKm2), 3.0, 200.0); }

/// The written part of a stem: from where it drains minArea on, split where
/// the width grows by a third, clipped to the square.
void addRivers(World& w, const RiverLine& line, double minAreaKm2, double spacing) {
  std::size_t k0 = 0;
  while (k0 < line.pts.size() && line.areaKm2[k0] < minAreaKm2) ++k0;
  while (k0 + 1 < line.pts.size()) {
    const double w0 = riverWidth(line.areaKm2[k0]);
    std::size_t k1 = k0 + 1;
    while (k1 + 1 < line.pts.size() && riverWidth(line.areaKm2[k1]) < 1.33 * w0) ++k1;
    std::vector<Vec2> piece(line.pts.begin() + static_cast<std::ptrdiff_t>(k0), line.pts.begin() + static_cast<std::ptrdiff_t>(k1) + 1);
    const double width = std::round(riverWidth(line.areaKm2[k1]) * 10.0) / 10.0;
    for (auto& part : clipToSquare(piece, w.half)) {
      densify(part, spacing);
      w.rivers.push_back({riverName(w.spec.seed, line.nameId), width, std::move(part)});
    }
    k0 = k1;
  }
}

/// Lakes in flat basins away from rivers: the level is near the lowest point
/// of the rim (a low shore dam closes the rest), and the inside is flattened
/// to it.
std::vector<Lake> placeLakes(const World& w, std::uint32_t seed) {
  const Grid& g = w.grid;
  const double s = w.spec.size;
  const int wanted = std::clamp(static_cast<int>(std::lround(3.0 * s / 20000.0)), 3, 40);
  const double scale = std::sqrt(std::clamp(s / 20000.0, 1.0, 6.0));
  auto heightAt = [&](Vec2 p) {
    const double gx = std::clamp((p.x - g.x0) / g.step, 0.0, g.nx - 1.001);
    const double gy = std::clamp((p.y - g.y0) / g.step, 0.0, g.ny - 1.001);
    const int i = static_cast<int>(gx), j = static_cast<int>(gy);
    const std::size_t k = g.index(i, j), up = static_cast<std::size_t>(g.nx);
    const double fx = gx - i, fy = gy - j;
    return lerp(lerp(w.height[k], w.height[k + 1], fx), lerp(w.height[k + up], w.height[k + up + 1], fx), fy);
  };
  auto riverDistAt = [&](Vec2 p) {
    const int i = std::clamp(static_cast<int>(std::lround((p.x - g.x0) / g.step)), 0, g.nx - 1);
    const int j = std::clamp(static_cast<int>(std::lround((p.y - g.y0) / g.step)), 0, g.ny - 1);
    return static_cast<double>(w.riverDist[g.index(i, j)]);
  };

  std::vector<Lake> lakes;
  // Strict flatness first; relax when the landscape has too few flat spots.
  for (double tolerance = 1.0; tolerance <= 8.0 && static_cast<int>(lakes.size()) < wanted; tolerance *= 2) {
    for (std::uint32_t attempt = 0; attempt < 8000 && static_cast<int>(lakes.size()) < wanted; ++attempt) {
      const std::uint32_t h = hash32(seed, attempt, static_cast<std::uint32_t>(tolerance * 16));
      Lake lake;
      lake.radius = (250.0 + 450.0 * unit(hash32(h, 1))) * scale;
      lake.margin = 1.2 * lake.radius;
      for (std::size_t k = 0; k < 3; ++k) {
        lake.amp[k] = (k == 0 ? 0.18 : (k == 1 ? 0.12 : 0.06)) * unit(hash32(h, 2, static_cast<std::uint32_t>(k)));
        lake.phase[k] = 2.0 * std::numbers::pi * unit(hash32(h, 3, static_cast<std::uint32_t>(k)));
      }
      const double room = w.half - lake.maxRadius() - lake.margin;
      if (room <= 0) break;
      lake.centre = {(2.0 * unit(hash32(h, 4)) - 1.0) * room, (2.0 * unit(hash32(h, 5)) - 1.0) * room};
      // Clear of rivers, shore blend included (it would dam them).
      if (riverDistAt(lake.centre) < lake.maxRadius() + lake.margin + 150.0) continue;
      if (w.terrain->inland(lake.centre) < 3.0 * lake.maxRadius()) continue;
      bool clear = true;
      for (const Lake& o : lakes) {
        const double gap = std::hypot(o.centre.x - lake.centre.x, o.centre.y - lake.centre.y);
        if (gap < 2.0 * (o.maxRadius() + lake.maxRadius()) + o.margin + lake.margin) clear = false;
      }
      if (!clear) continue;
      std::array<double, 48> rim;
      for (std::size_t k = 0; k < rim.size(); ++k) {
        const double a = 2.0 * std::numbers::pi * static_cast<double>(k) / static_cast<double>(rim.size());
        const double r = lake.rimRadius(a);
        rim[k] = heightAt({lake.centre.x + r * std::cos(a), lake.centre.y + r * std::sin(a)});
      }
      std::sort(rim.begin(), rim.end());
      const double lo = rim.front(), hi = rim.back(), centre = heightAt(lake.centre);
      if (lo < 8.0 || lo > 1500.0) continue;
      if (hi - lo > tolerance * (15.0 + 0.03 * lake.radius)) continue;
      if (centre > lo + tolerance * 10.0) continue;  // a basin, not a hill
      // A little above the lowest rim point: the shore blend then builds a
      // low natural dam there rather than cutting the basin into a pit.
      lake.level = std::floor(rim[rim.size() / 5]);
      lakes.push_back(lake);
    }
  }
  return lakes;
}

/// The analysis grid: the square plus a margin, so rivers entering the
/// square come from somewhere. At most ~1600 cells a side keeps it a few
/// seconds even for 1000 km.
Grid analysisGrid(double sizeM) {
  Grid g;
  const double extent = sizeM + 2.0 * std::max(2500.0, 0.15 * sizeM);
  g.step = std::max(50.0, extent / 1600.0);
  g.nx = g.ny = static_cast<int>(std::ceil(extent / g.step)) + 1;
  g.x0 = g.y0 = -0.5 * (g.nx - 1) * g.step;
  return g;
}

/// Traces the drainage of `landform`, writes the big rivers into w and
/// returns every stream's centreline segments for carving.
std::vector<Segment> traceRivers(World& w, const std::vector<float>& landform) {
  const Grid& g = w.grid;
  const Drainage d = drain(g, landform, w.spec.seed);
  // Every stream above a small area carves a valley, which is what gives
  // the landform its dendritic, eroded look; the bigger ones are written.
  const double cellArea = g.step * g.step;
  const double carveArea = std::max(0.25e6, 30.0 * cellArea);
  const double riverArea = std::max({2e6, 40.0 * cellArea, 5e-4 * w.spec.size * w.spec.size});
  const Network net = riverNetwork(g, landform, d, static_cast<float>(carveArea / cellArea));
  std::vector<Segment> segs;
  const double spacing = std::clamp(g.step, 50.0, 150.0);
  for (const Stem& s : net.stems) {
    if (s.cells.size() < 2) continue;
    const RiverLine line = riverLine(g, s, net, d, w.spec.seed);
    for (std::size_t k = 0; k + 1 < line.pts.size(); ++k) {
      const double a = line.areaKm2[k + 1];
      const double floorWidth = std::max(g.step, 0.2 * (120.0 + 35.0 * std::sqrt(a)));
      const double maxWidth = std::clamp(250.0 + 600.0 * std::sqrt(a), 4.0 * g.step, 4000.0);
      segs.push_back({line.pts[k], line.pts[k + 1], line.bed[k], line.bed[k + 1], floorWidth, maxWidth,
                      a * 1e6 >= riverArea});
    }
    addRivers(w, line, riverArea * 1e-6, spacing);
  }
  return segs;
}

/// Places the lakes and flattens them into w.height too.
void addLakes(World& w) {
  const Grid& g = w.grid;
  w.terrain->setLakes(placeLakes(w, w.spec.seed));
  for (const Lake& lake : w.terrain->lakes()) {
    const double r = lake.maxRadius() + lake.margin;
    const int i0 = std::max(0, static_cast<int>((lake.centre.x - r - g.x0) / g.step));
    const int i1 = std::min(g.nx - 1, static_cast<int>((lake.centre.x + r - g.x0) / g.step) + 1);
    const int j0 = std::max(0, static_cast<int>((lake.centre.y - r - g.y0) / g.step));
    const int j1 = std::min(g.ny - 1, static_cast<int>((lake.centre.y + r - g.y0) / g.step) + 1);
    for (int j = j0; j <= j1; ++j) {
      for (int i = i0; i <= i1; ++i) {
        const std::size_t c = g.index(i, j);
        w.height[c] = static_cast<float>(w.terrain->withLakes(g.at(i, j), w.height[c]));
      }
    }
  }
}

}  // namespace

World buildWorld(const Frame& frame, double sizeM, std::uint64_t seed, int threads, bool withCulture,
                 const Fraction& progress) {
  World w;
  w.frame = frame;
  w.spec = makeSpec(sizeM, seed);
  w.terrain = std::make_unique<Terrain>(w.spec);
  w.half = 0.5 * sizeM;
  w.grid = analysisGrid(sizeM);
  const Grid& g = w.grid;

  std::vector<float> land(g.size());
  parallelFor(g.size(), threads, [&](std::size_t b, std::size_t e) {
    for (std::size_t k = b; k < e; ++k) land[k] = static_cast<float>(w.terrain->base(g.at(k)));
  });
  if (progress) progress(0.4);

  // From here on rivers see the landform with its basins part filled.
  const std::vector<float> filled = fillDepressions(g, land);
  std::vector<float> fill(g.size());
  for (std::size_t k = 0; k < g.size(); ++k) {
    fill[k] = kBasinFill * (filled[k] - land[k]);
    land[k] += fill[k];
  }
  const std::vector<Segment> segs = traceRivers(w, land);
  if (progress) progress(0.55);

  Valleys v = carveValleys(g, land, segs, threads);
  w.height.resize(g.size());
  std::vector<float> offset(g.size());
  for (std::size_t k = 0; k < g.size(); ++k) {
    offset[k] = v.bed[k] * (1.0f - v.shape[k]);
    w.height[k] = std::min(land[k], v.shape[k] * land[k] + offset[k]);
  }
  w.riverDist = std::move(v.dist);
  w.terrain->setValleys(g, std::move(fill), std::move(v.shape), std::move(offset));
  if (progress) progress(0.75);

  addLakes(w);
  if (progress) progress(0.85);
  if (withCulture) buildCulture(w);
  if (progress) progress(1.0);
  return w;
}

}  // namespace sandtable::convert::synth
