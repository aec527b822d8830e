// Synthetic culture that agrees with the synthetic terrain: towns on the
// lowland, roads routed around steep ground and water, forest on mid
// slopes; written to a GeoPackage in EPSG:4326.
#include <algorithm>
#include <cmath>
#include <limits>
#include <numbers>
#include <queue>

#include <gdal.h>
#include <gdal_alg.h>
#include <ogr_api.h>
#include <ogr_srs_api.h>

#include "synth_internal.h"
#include "sandtable/converters/clip.h"
#include "sandtable/converters/grid8.h"

namespace sandtable::convert::synth {

// ---------------------------------------------------------------- polylines

void chaikin(std::vector<Vec2>& pts, std::vector<double>* values, int iterations) {
  for (int it = 0; it < iterations && pts.size() >= 3; ++it) {
    std::vector<Vec2> out{pts.front()};
    std::vector<double> vout;
    if (values) vout.push_back(values->front());
    for (std::size_t k = 0; k + 1 < pts.size(); ++k) {
      const Vec2 a = pts[k], b = pts[k + 1];
      out.push_back({0.75 * a.x + 0.25 * b.x, 0.75 * a.y + 0.25 * b.y});
      out.push_back({0.25 * a.x + 0.75 * b.x, 0.25 * a.y + 0.75 * b.y});
      if (values) {
        const double va = (*values)[k], vb = (*values)[k + 1];
        vout.push_back(0.75 * va + 0.25 * vb);
        vout.push_back(0.25 * va + 0.75 * vb);
      }
    }
    out.push_back(pts.back());
    if (values) vout.push_back(values->back());
    pts = std::move(out);
    if (values) *values = std::move(vout);
  }
}

void resample(std::vector<Vec2>& pts, std::vector<double>* values, double spacing) {
  if (pts.size() < 2) return;
  double total = 0;
  for (std::size_t k = 0; k + 1 < pts.size(); ++k) total += std::hypot(pts[k + 1].x - pts[k].x, pts[k + 1].y - pts[k].y);
  const std::size_t steps = std::max<std::size_t>(1, static_cast<std::size_t>(std::ceil(total / spacing)));
  const double ds = total / static_cast<double>(steps);
  std::vector<Vec2> out{pts.front()};
  std::vector<double> vout;
  if (values) vout.push_back(values->front());
  std::size_t seg = 0;
  double segStart = 0;
  for (std::size_t s = 1; s < steps; ++s) {
    const double at = ds * static_cast<double>(s);
    double segLen = std::hypot(pts[seg + 1].x - pts[seg].x, pts[seg + 1].y - pts[seg].y);
    while (segStart + segLen < at && seg + 2 < pts.size()) {
      segStart += segLen;
      ++seg;
      segLen = std::hypot(pts[seg + 1].x - pts[seg].x, pts[seg + 1].y - pts[seg].y);
    }
    const double f = segLen > 0 ? clamp01((at - segStart) / segLen) : 0.0;
    out.push_back({lerp(pts[seg].x, pts[seg + 1].x, f), lerp(pts[seg].y, pts[seg + 1].y, f)});
    if (values) vout.push_back(lerp((*values)[seg], (*values)[seg + 1], f));
  }
  out.push_back(pts.back());
  if (values) vout.push_back(values->back());
  pts = std::move(out);
  if (values) *values = std::move(vout);
}

void densify(std::vector<Vec2>& pts, double maxGap) {
  if (pts.size() < 2) return;
  std::vector<Vec2> out{pts.front()};
  for (std::size_t k = 0; k + 1 < pts.size(); ++k) {
    const Vec2 a = pts[k], b = pts[k + 1];
    const auto steps = static_cast<int>(std::ceil(std::hypot(b.x - a.x, b.y - a.y) / maxGap));
    for (int s = 1; s < steps; ++s) {
      const double t = static_cast<double>(s) / steps;
      out.push_back({lerp(a.x, b.x, t), lerp(a.y, b.y, t)});
    }
    out.push_back(b);
  }
  pts = std::move(out);
}

std::vector<std::vector<Vec2>> clipToSquare(const std::vector<Vec2>& pts, double half) {
  return clip::polyline(pts, clip::Rect{-half, -half, half, half}, &Vec2::x, &Vec2::y);
}

// ---------------------------------------------------------------- routing

namespace {


/// How a class of road trades distance against gradient.
struct CostModel {
  double slopeScale;    ///< gradient at which a step costs double
  double maxSlope;      ///< steeper cells are impassable
  double bridgePenalty; ///< extra metres for entering a river cell
};

// Gradients are measured over one grid cell, across valley walls too, so
// the hard limits are loose: the quadratic cost does the steering (a real
// road would switch back where this one climbs straight).
constexpr CostModel kMotorway{0.035, 0.6, 400.0};
constexpr CostModel kMainRoad{0.07, 0.9, 150.0};
constexpr CostModel kTrack{0.16, 1.2, 60.0};

/// Grid layers the router reads.
struct Terrain2d {
  const Grid* g;
  std::vector<float> slope;          ///< gradient magnitude (rise over run)
  std::vector<std::uint8_t> blocked; ///< water, shore, outside the square
  std::vector<std::uint8_t> river;
  std::vector<float> wiggle;         ///< cost factor ~1: roads on open flats would run dead straight
};

/// Least-cost path (8-connected Dijkstra) from `from` to the first cell
/// with target[c] set. Empty when none is reachable.
std::vector<std::size_t> route(const Terrain2d& t, std::size_t from, const std::vector<std::uint8_t>& target,
                               const CostModel& m) {
  const Grid& g = *t.g;
  const std::size_t n = g.size();
  std::vector<float> dist(n, std::numeric_limits<float>::max());
  std::vector<std::int32_t> prev(n, -1);
  using Item = std::pair<float, std::uint32_t>;
  std::priority_queue<Item, std::vector<Item>, std::greater<>> open;
  dist[from] = 0;
  open.push({0.0f, static_cast<std::uint32_t>(from)});
  std::int64_t reached = -1;
  while (!open.empty()) {
    const auto [dc, c] = open.top();
    open.pop();
    if (dc > dist[c]) continue;
    if (target[c] && c != from) {
      reached = c;
      break;
    }
    grid8::forEachNeighbour(g.nx, g.ny, c, [&](int k, std::size_t nc) {
      if (t.blocked[nc]) return;
      const double s = 0.5 * (t.slope[c] + t.slope[nc]);
      if (s > m.maxSlope) return;
      const double len = (grid8::diagonal(k) ? std::numbers::sqrt2 : 1.0) * g.step;
      const double ratio = s / m.slopeScale;
      double cost = len * (1.0 + ratio * ratio) * t.wiggle[nc];
      if (t.river[nc] && !t.river[c]) cost += m.bridgePenalty;
      const float nd = dist[c] + static_cast<float>(cost);
      if (nd < dist[nc]) {
        dist[nc] = nd;
        prev[nc] = static_cast<std::int32_t>(c);
        open.push({nd, static_cast<std::uint32_t>(nc)});
      }
    });
  }
  std::vector<std::size_t> path;
  if (reached < 0) return path;
  for (std::int64_t c = reached; c >= 0; c = prev[static_cast<std::size_t>(c)]) path.push_back(static_cast<std::size_t>(c));
  std::reverse(path.begin(), path.end());  // from `from` to the target
  return path;
}

Terrain2d layers(const World& w) {
  const Grid& g = w.grid;
  Terrain2d t;
  t.g = &g;
  const std::size_t n = g.size();
  t.slope.assign(n, 0.0f);
  t.blocked.assign(n, 1);
  t.river.assign(n, 0);
  t.wiggle.assign(n, 1.0f);
  std::vector<std::uint8_t> water(n, 0);
  for (int j = 0; j < g.ny; ++j) {
    for (int i = 0; i < g.nx; ++i) {
      const std::size_t c = g.index(i, j);
      const Vec2 p = g.at(i, j);
      t.wiggle[c] = static_cast<float>(1.0 + 0.5 * (0.5 + 0.5 * fbm(p.x / (7.0 * g.step), p.y / (7.0 * g.step), w.spec.seed + 0x31Du, 2)));
      water[c] = (w.height[c] <= 0.5f || w.terrain->inLake(p)) ? 1 : 0;
      t.river[c] = w.riverDist[c] < 0.75 * g.step ? 1 : 0;
      if (i == 0 || j == 0 || i == g.nx - 1 || j == g.ny - 1) continue;
      const double gx = (w.height[c + 1] - w.height[c - 1]) / (2 * g.step);
      const double gy = (w.height[c + static_cast<std::size_t>(g.nx)] - w.height[c - static_cast<std::size_t>(g.nx)]) / (2 * g.step);
      t.slope[c] = static_cast<float>(std::hypot(gx, gy));
    }
  }
  // Blocked: water plus two cells of shore (smoothing cuts corners by less
  // than that), and everything outside the square.
  for (int j = 0; j < g.ny; ++j) {
    for (int i = 0; i < g.nx; ++i) {
      const Vec2 p = g.at(i, j);
      if (std::max(std::fabs(p.x), std::fabs(p.y)) > w.half - g.step) continue;
      bool wet = false;
      for (int dj = -2; dj <= 2 && !wet; ++dj) {
        for (int di = -2; di <= 2 && !wet; ++di) wet = water[g.index(i + di, j + dj)] != 0;
      }
      t.blocked[g.index(i, j)] = wet ? 1 : 0;
    }
  }
  return t;
}

std::vector<Vec2> smoothPath(const Grid& g, const std::vector<std::size_t>& cells) {
  std::vector<Vec2> pts;
  for (std::size_t c : cells) pts.push_back(g.at(c));
  chaikin(pts, nullptr, 3);
  resample(pts, nullptr, std::clamp(g.step, 50.0, 150.0));
  return pts;
}

/// Moves the end of a new road onto the nearest vertex of the roads it joins.
void snapEnd(std::vector<Vec2>& pts, const std::vector<Road>& roads) {
  if (pts.empty() || roads.empty()) return;
  Vec2 best = pts.back();
  double bestD = std::numeric_limits<double>::max();
  for (const Road& r : roads) {
    for (const Vec2& q : r.pts) {
      const double d = std::hypot(q.x - pts.back().x, q.y - pts.back().y);
      if (d < bestD) bestD = d, best = q;
    }
  }
  pts.back() = best;
}

/// Towns: flat, dry ground, lower preferred, spread over the square
/// (farthest-point picking, so inland basins get towns, not only the
/// coast). The first is the largest.
std::vector<std::size_t> placeTowns(const World& w, const Terrain2d& t) {
  const Grid& g = w.grid;
  const auto wanted = static_cast<std::size_t>(std::clamp(static_cast<int>(std::lround(5.0 * w.spec.size / 20000.0)), 4, 30));
  struct Site {
    std::size_t cell;
    double quality;  ///< 0..~1.3, higher is better
    double gap;      ///< distance to the nearest chosen town
  };
  std::vector<Site> sites;
  for (std::size_t c = 0; c < g.size(); ++c) {
    if (t.blocked[c] || t.river[c]) continue;
    const double h = w.height[c];
    if (h < 3.0 || h > 1300.0 || t.slope[c] > 0.1) continue;
    const double q = 1.0 - 0.5 * h / 1300.0 - 3.0 * t.slope[c] + 0.3 * unit(hash32(w.spec.seed, static_cast<std::uint32_t>(c), 0x7A1u));
    sites.push_back({c, q, std::numeric_limits<double>::max()});
  }
  std::vector<std::size_t> towns;
  while (towns.size() < wanted && !sites.empty()) {
    // Best quality first; then the best trade of distance and quality.
    const auto best = std::max_element(sites.begin(), sites.end(), [&](const Site& a, const Site& b) {
      if (towns.empty()) return a.quality < b.quality;
      return std::min(a.gap, w.spec.size) * a.quality * a.quality < std::min(b.gap, w.spec.size) * b.quality * b.quality;
    });
    if (!towns.empty() && best->gap < 4.0 * g.step) break;  // no room left
    const std::size_t pick = best->cell;
    towns.push_back(pick);
    const Vec2 p = g.at(pick);
    for (Site& s : sites) {
      const Vec2 q = g.at(s.cell);
      s.gap = std::min(s.gap, std::hypot(p.x - q.x, p.y - q.y));
    }
  }
  return towns;
}

/// A cell on the edge of the square for the motorway to enter or leave by:
/// low, gentle, on the side given by `dir` (along the coast).
std::int64_t edgeCell(const World& w, const Terrain2d& t, Vec2 dir) {
  const Grid& g = w.grid;
  double best = std::numeric_limits<double>::max();
  std::int64_t pick = -1;
  for (std::size_t c = 0; c < g.size(); ++c) {
    if (t.blocked[c]) continue;
    const Vec2 p = g.at(c);
    if (std::max(std::fabs(p.x), std::fabs(p.y)) < w.half - 2.5 * g.step) continue;
    if (p.x * dir.x + p.y * dir.y < 0.4 * w.half) continue;
    // Near the coast: a coastal motorway, not a mountain pass.
    const double score = std::fabs(w.height[c] - 40.0) + 3000.0 * t.slope[c] + 0.05 * w.terrain->inland(p);
    if (score < best) best = score, pick = static_cast<std::int64_t>(c);
  }
  return pick;
}

class RoadBuilder {
 public:
  RoadBuilder(World& w, const Terrain2d& t) : w_(w), t_(t), network_(w.grid.size(), 0) {}

  /// Routes from `from` to the network (or to `to` when given) and adds the road.
  bool add(std::size_t from, std::int64_t to, const CostModel& m, const std::string& type, double width) {
    std::vector<std::uint8_t> single;
    const std::vector<std::uint8_t>* target = &network_;
    if (to >= 0) {
      single.assign(w_.grid.size(), 0);
      single[static_cast<std::size_t>(to)] = 1;
      target = &single;
    }
    const auto cells = route(t_, from, *target, m);
    if (cells.size() < 2) return false;
    append(cells, type, width, to < 0);
    return true;
  }

  void seed(std::size_t c) { network_[c] = 1; }
  bool onNetwork(std::size_t c) const { return network_[c] != 0; }

 private:
  void append(const std::vector<std::size_t>& cells, const std::string& type, double width, bool joins) {
    Road r{type, width, smoothPath(w_.grid, cells)};
    if (joins) snapEnd(r.pts, w_.roads);
    for (std::size_t c : cells) network_[c] = 1;
    w_.roads.push_back(std::move(r));
  }

  World& w_;
  const Terrain2d& t_;
  std::vector<std::uint8_t> network_;
};

void buildRoads(World& w, const Terrain2d& t) {
  const Grid& g = w.grid;
  const auto towns = placeTowns(w, t);
  for (std::size_t c : towns) w.towns.push_back(g.at(c));
  if (towns.empty()) return;
  RoadBuilder roads(w, t);

  // A motorway across the square along the coast, edge to edge.
  const Vec2 along{w.spec.inland.y, -w.spec.inland.x};
  const std::int64_t entry = edgeCell(w, t, along), exit = edgeCell(w, t, {-along.x, -along.y});
  if (entry < 0 || exit < 0 || !roads.add(static_cast<std::size_t>(entry), exit, kMotorway, "motorway", 25.0)) {
    roads.seed(towns[0]);
  }

  // Towns join the network by their cheapest route; the longest third of
  // those links carry the through traffic and become primary roads.
  const std::size_t first = w.roads.size();
  for (std::size_t k = 0; k < towns.size(); ++k) {
    if (roads.onNetwork(towns[k])) continue;
    const double r = unit(hash32(w.spec.seed, static_cast<std::uint32_t>(k), 0x80ADu));
    roads.add(towns[k], -1, kMainRoad, "secondary", std::round(70.0 + 15.0 * r) / 10.0);
  }
  std::vector<std::size_t> links;
  for (std::size_t k = first; k < w.roads.size(); ++k) links.push_back(k);
  std::sort(links.begin(), links.end(), [&](std::size_t a, std::size_t b) {
    return w.roads[a].pts.size() > w.roads[b].pts.size();  // vertices are evenly spaced
  });
  for (std::size_t k = 0; k < links.size() && k < std::max<std::size_t>(1, links.size() / 3); ++k) {
    Road& road = w.roads[links[k]];
    road.type = "primary";
    road.width = std::round(90.0 + 30.0 * unit(hash32(w.spec.seed, static_cast<std::uint32_t>(k), 0x9A1Bu))) / 10.0;
  }

  // Tracks climb from the network into the hills.
  const int wanted = std::clamp(static_cast<int>(std::lround(6.0 * w.spec.size / 20000.0)), 4, 40);
  int made = 0;
  for (std::uint32_t attempt = 0; attempt < 3000 && made < wanted; ++attempt) {
    const std::uint32_t h = hash32(w.spec.seed, attempt, 0x78ACu);
    const auto c = static_cast<std::size_t>(h % static_cast<std::uint32_t>(g.size()));
    if (t.blocked[c] || t.river[c] || roads.onNetwork(c)) continue;
    if (w.height[c] < 250.0f || w.height[c] > 1900.0f || t.slope[c] > 0.45f) continue;
    if (roads.add(c, -1, kTrack, "track", 3.5)) ++made;
  }
}

// ---------------------------------------------------------------- forest

void buildForest(World& w, const Terrain2d& t) {
  const Grid& g = w.grid;
  w.forest.assign(g.size(), 0);
  for (std::size_t c = 0; c < g.size(); ++c) {
    const Vec2 p = g.at(c);
    if (std::max(std::fabs(p.x), std::fabs(p.y)) > w.half) continue;
    const double h = w.height[c];
    if (h <= 1.0 || w.riverDist[c] < 0.5 * g.step || w.terrain->inLake(p)) continue;
    // Mid elevations on slopes too steep to farm, below the tree line.
    const double band = smoothstep(120, 320, h) * (1.0 - smoothstep(1450, 1750, h));
    const double slope = smoothstep(0.06, 0.16, t.slope[c]) * (1.0 - smoothstep(1.0, 1.4, t.slope[c]));
    // Patchiness: clearings and woods independent of the terrain.
    const double n = fbm(p.x / 1800.0, p.y / 1800.0, w.spec.seed + 0xF0u, 3);
    if (band * slope > 0.45 && n > 0.0) w.forest[c] = 1;
  }
}

}  // namespace

// ------------------------------------------------------------- buildings

/// Distance from p to the nearest road's edge (its centreline less half
/// its width), m.
double roadClearance(const World& w, Vec2 p) {
  double best = std::numeric_limits<double>::max();
  for (const Road& r : w.roads) {
    for (std::size_t k = 0; k + 1 < r.pts.size(); ++k) {
      const Vec2 a = r.pts[k], b = r.pts[k + 1];
      const double dx = b.x - a.x, dy = b.y - a.y, len2 = dx * dx + dy * dy;
      const double s = len2 > 0 ? std::clamp(((p.x - a.x) * dx + (p.y - a.y) * dy) / len2, 0.0, 1.0) : 0.0;
      best = std::min(best, std::hypot(p.x - a.x - s * dx, p.y - a.y - s * dy) - 0.5 * r.width);
    }
  }
  return best;
}

/// Villages: houses scattered round each town (more round the first), on
/// dry, gentle ground, clear of roads, rivers and each other, turned to a
/// per-town street grid, 3 to 12 m high.
void buildBuildings(World& w, const Terrain2d& t) {
  const Grid& g = w.grid;
  for (std::size_t k = 0; k < w.towns.size(); ++k) {
    const Vec2 town = w.towns[k];
    const int wanted = k == 0 ? 40 : 16;
    const double radius = k == 0 ? 450.0 : 250.0;
    const double grid = unit(hash32(w.spec.seed, std::uint32_t(k), 0xB11Du)) * std::numbers::pi / 2;
    int placed = 0;
    for (std::uint32_t tries = 0; placed < wanted && tries < std::uint32_t(wanted) * 20; ++tries) {
      const auto h = [&](std::uint32_t salt) { return unit(hash32(w.spec.seed, std::uint32_t(k) * 7919u + tries, salt)); };
      const double r = radius * std::sqrt(h(1)), a = 2 * std::numbers::pi * h(2);
      Building b;
      b.centre = {town.x + r * std::cos(a), town.y + r * std::sin(a)};
      b.a = 4.0 + 6.0 * h(3);
      b.b = 4.0 + 3.0 * h(4);
      b.angle = grid + (h(5) < 0.5 ? 0.0 : std::numbers::pi / 2);
      b.height = 3.0 * std::floor(1.0 + 4.0 * h(6));
      if (std::abs(b.centre.x) > w.half - 50 || std::abs(b.centre.y) > w.half - 50) continue;
      const int i = int(std::lround((b.centre.x - g.x0) / g.step)), j = int(std::lround((b.centre.y - g.y0) / g.step));
      if (i < 0 || j < 0 || i >= g.nx || j >= g.ny) continue;
      const std::size_t c = g.index(i, j);
      if (t.blocked[c] || t.river[c] || t.slope[c] > 0.15 || w.riverDist[c] < 40) continue;
      const double reach = std::hypot(b.a, b.b);
      if (roadClearance(w, b.centre) < reach + 4) continue;
      bool clear = true;
      for (const Building& o : w.buildings) {
        clear = clear && std::hypot(o.centre.x - b.centre.x, o.centre.y - b.centre.y) > reach + std::hypot(o.a, o.b) + 3;
      }
      if (!clear) continue;
      w.buildings.push_back(b);
      ++placed;
    }
  }
}

void buildCulture(World& w) {
  const Terrain2d t = layers(w);
  buildRoads(w, t);
  buildForest(w, t);
  buildBuildings(w, t);
}

// ---------------------------------------------------------------- GeoPackage

namespace {

/// Closes an OGR geometry handle on scope exit.
struct GeomGuard {
  OGRGeometryH h;
  ~GeomGuard() {
    if (h) OGR_G_DestroyGeometry(h);
  }
};

Problem gpkgProblem(const std::string& path, const std::string& what) {
  const char* msg = CPLGetLastErrorMsg();
  return Problem{path, 0, "synth: culture: " + what + (msg && *msg ? std::string(": ") + msg : std::string())};
}

OGRGeometryH lineString(const World& w, const std::vector<Vec2>& pts) {
  OGRGeometryH g = OGR_G_CreateGeometry(wkbLineString);
  for (const Vec2& p : pts) OGR_G_AddPoint_2D(g, w.frame.lonOf(p.x), w.frame.latOf(p.y));
  return g;
}

/// A layer with its fields; nullptr (with the error set) on failure.
OGRLayerH makeLayer(GDALDatasetH ds, const char* name, OGRwkbGeometryType type, OGRSpatialReferenceH srs,
                    const std::vector<std::pair<const char*, OGRFieldType>>& fields) {
  const char* opts[] = {"GEOMETRY_NAME=geom", "FID=fid", nullptr};
  OGRLayerH layer = GDALDatasetCreateLayer(ds, name, srs, type, const_cast<char**>(opts));
  if (!layer) return nullptr;
  for (const auto& [fname, ftype] : fields) {
    OGRFieldDefnH f = OGR_Fld_Create(fname, ftype);
    const OGRErr err = OGR_L_CreateField(layer, f, TRUE);
    OGR_Fld_Destroy(f);
    if (err != OGRERR_NONE) return nullptr;
  }
  return layer;
}

/// Adds a feature with geometry g (taken) and fields set by `fill`.
template <typename Fill>
bool addFeature(OGRLayerH layer, OGRGeometryH g, Fill fill) {
  OGRFeatureH f = OGR_F_Create(OGR_L_GetLayerDefn(layer));
  OGR_F_SetGeometryDirectly(f, g);
  fill(f);
  const OGRErr err = OGR_L_CreateFeature(layer, f);
  OGR_F_Destroy(f);
  return err == OGRERR_NONE;
}

OGRGeometryH lakePolygon(const World& w, const Lake& lake) {
  const double perimeter = 2.0 * std::numbers::pi * lake.radius;
  const int n = std::max(48, static_cast<int>(perimeter / 60.0));
  OGRGeometryH ring = OGR_G_CreateGeometry(wkbLinearRing);
  for (int k = 0; k <= n; ++k) {
    const double a = 2.0 * std::numbers::pi * (k % n) / n;
    const double r = lake.rimRadius(a);
    OGR_G_AddPoint_2D(ring, w.frame.lonOf(lake.centre.x + r * std::cos(a)), w.frame.latOf(lake.centre.y + r * std::sin(a)));
  }
  OGRGeometryH poly = OGR_G_CreateGeometry(wkbPolygon);
  OGR_G_AddGeometryDirectly(poly, ring);
  return poly;
}

/// A building's footprint in lon/lat, counter-clockwise.
OGRGeometryH buildingPolygon(const World& w, const Building& b) {
  const double c = std::cos(b.angle), s = std::sin(b.angle);
  OGRGeometryH ring = OGR_G_CreateGeometry(wkbLinearRing);
  const double corners[5][2] = {{-1, -1}, {1, -1}, {1, 1}, {-1, 1}, {-1, -1}};
  for (const auto& k : corners) {
    const double x = k[0] * b.a, y = k[1] * b.b;
    OGR_G_AddPoint_2D(ring, w.frame.lonOf(b.centre.x + x * c - y * s), w.frame.latOf(b.centre.y + x * s + y * c));
  }
  OGRGeometryH poly = OGR_G_CreateGeometry(wkbPolygon);
  OGR_G_AddGeometryDirectly(poly, ring);
  return poly;
}

/// Converts every point of a polygon from local metres to lon/lat in place.
void polygonToLonLat(const World& w, OGRGeometryH poly) {
  for (int r = 0; r < OGR_G_GetGeometryCount(poly); ++r) {
    OGRGeometryH ring = OGR_G_GetGeometryRef(poly, r);
    for (int k = 0; k < OGR_G_GetPointCount(ring); ++k) {
      OGR_G_SetPoint_2D(ring, k, w.frame.lonOf(OGR_G_GetX(ring, k)), w.frame.latOf(OGR_G_GetY(ring, k)));
    }
  }
}

/// Forest polygons: the mask, sieved of specks, polygonized in local metres,
/// simplified (grid staircases to straight edges), then put in lon/lat.
Result<int> writeForest(const World& w, OGRLayerH out, const std::string& path) {
  const Grid& g = w.grid;
  int i0 = g.nx, i1 = -1, j0 = g.ny, j1 = -1;
  for (int j = 0; j < g.ny; ++j) {
    for (int i = 0; i < g.nx; ++i) {
      const Vec2 p = g.at(i, j);
      if (std::max(std::fabs(p.x), std::fabs(p.y)) > w.half) continue;
      i0 = std::min(i0, i), i1 = std::max(i1, i), j0 = std::min(j0, j), j1 = std::max(j1, j);
    }
  }
  if (i1 < i0 || j1 < j0) return 0;
  const int nx = i1 - i0 + 1, ny = j1 - j0 + 1;
  std::vector<std::uint8_t> mask(static_cast<std::size_t>(nx) * static_cast<std::size_t>(ny));
  for (int r = 0; r < ny; ++r) {
    for (int i = 0; i < nx; ++i) {
      mask[static_cast<std::size_t>(r) * static_cast<std::size_t>(nx) + static_cast<std::size_t>(i)] =
          w.forest[g.index(i0 + i, j1 - r)];  // row 0 is north
    }
  }
  GDALDatasetH mem = GDALCreate(GDALGetDriverByName("MEM"), "", nx, ny, 1, GDT_Byte, nullptr);
  if (!mem) return gpkgProblem(path, "cannot create the forest mask");
  double gt[6] = {g.x0 + i0 * g.step - 0.5 * g.step, g.step, 0, g.y0 + j1 * g.step + 0.5 * g.step, 0, -g.step};
  GDALSetGeoTransform(mem, gt);
  GDALRasterBandH band = GDALGetRasterBand(mem, 1);
  CPLErr err = GDALRasterIO(band, GF_Write, 0, 0, nx, ny, mask.data(), nx, ny, GDT_Byte, 0, 0);
  // Sieve away specks of a few cells: they would be single-pixel polygons.
  if (err == CE_None) err = GDALSieveFilter(band, nullptr, band, 6, 8, nullptr, nullptr, nullptr);

  GDALDriverH memVec = GDALGetDriverByName("Memory");
  GDALDatasetH tmp = memVec ? GDALCreate(memVec, "", 0, 0, 0, GDT_Unknown, nullptr) : nullptr;
  OGRLayerH polys = tmp ? GDALDatasetCreateLayer(tmp, "forest", nullptr, wkbPolygon, nullptr) : nullptr;
  if (polys) {
    OGRFieldDefnH f = OGR_Fld_Create("v", OFTInteger);
    OGR_L_CreateField(polys, f, TRUE);
    OGR_Fld_Destroy(f);
  }
  if (err == CE_None && polys) err = GDALPolygonize(band, band, polys, 0, nullptr, nullptr, nullptr);
  if (err != CE_None || !polys) {
    if (tmp) GDALClose(tmp);
    GDALClose(mem);
    return gpkgProblem(path, "cannot polygonize the forest mask");
  }
  int count = 0;
  bool ok = true;
  OGR_L_ResetReading(polys);
  OGRFeatureH f;
  while (ok && (f = OGR_L_GetNextFeature(polys)) != nullptr) {
    OGRGeometryH geom = OGR_F_GetGeometryRef(f);
    GeomGuard simple{geom ? OGR_G_SimplifyPreserveTopology(geom, 0.7 * g.step) : nullptr};
    OGR_F_Destroy(f);
    if (!simple.h || OGR_G_IsEmpty(simple.h)) continue;
    // A polygon, or the parts of a multipolygon.
    std::vector<OGRGeometryH> parts;
    if (wkbFlatten(OGR_G_GetGeometryType(simple.h)) == wkbPolygon) {
      parts.push_back(OGR_G_Clone(simple.h));
    } else {
      for (int k = 0; k < OGR_G_GetGeometryCount(simple.h); ++k) parts.push_back(OGR_G_Clone(OGR_G_GetGeometryRef(simple.h, k)));
    }
    for (OGRGeometryH part : parts) {
      if (!ok || OGR_G_Area(part) < 4.0 * g.step * g.step) {
        OGR_G_DestroyGeometry(part);
        continue;
      }
      polygonToLonLat(w, part);
      ok = addFeature(out, part, [](OGRFeatureH) {});
      if (ok) ++count;
    }
  }
  GDALClose(tmp);
  GDALClose(mem);
  if (!ok) return gpkgProblem(path, "cannot write forest");
  return count;
}

}  // namespace

Result<CultureCounts> writeCulture(const World& w, const std::string& path) {
  GDALDriverH drv = GDALGetDriverByName("GPKG");
  if (!drv) return Problem{path, 0, "synth: culture: GDAL has no GPKG driver"};
  GDALDatasetH ds = GDALCreate(drv, path.c_str(), 0, 0, 0, GDT_Unknown, nullptr);
  if (!ds) return gpkgProblem(path, "cannot create");
  OGRSpatialReferenceH srs = OSRNewSpatialReference(nullptr);
  OSRImportFromEPSG(srs, 4326);
  OSRSetAxisMappingStrategy(srs, OAMS_TRADITIONAL_GIS_ORDER);

  OGRLayerH roads = makeLayer(ds, "roads", wkbLineString, srs, {{"type", OFTString}, {"width", OFTReal}});
  OGRLayerH rivers = roads ? makeLayer(ds, "rivers", wkbLineString, srs, {{"name", OFTString}, {"width", OFTReal}}) : nullptr;
  OGRLayerH lakes = rivers ? makeLayer(ds, "lakes", wkbPolygon, srs, {{"level", OFTReal}}) : nullptr;
  OGRLayerH forest = lakes ? makeLayer(ds, "forest", wkbPolygon, srs, {}) : nullptr;
  OGRLayerH buildings = forest ? makeLayer(ds, "buildings", wkbPolygon, srs, {{"height", OFTReal}}) : nullptr;
  OSRRelease(srs);
  if (!buildings) {
    const Problem p = gpkgProblem(path, "cannot create layers");
    GDALClose(ds);
    return p;
  }

  CultureCounts n;
  // One transaction: a GeoPackage commits per feature otherwise (slow).
  bool ok = GDALDatasetStartTransaction(ds, FALSE) == OGRERR_NONE;
  for (const Road& r : w.roads) {
    if (!ok) break;
    ok = addFeature(roads, lineString(w, r.pts), [&](OGRFeatureH f) {
      OGR_F_SetFieldString(f, 0, r.type.c_str());
      OGR_F_SetFieldDouble(f, 1, r.width);
    });
    n.roads += ok;
  }
  for (const River& r : w.rivers) {
    if (!ok) break;
    ok = addFeature(rivers, lineString(w, r.pts), [&](OGRFeatureH f) {
      OGR_F_SetFieldString(f, 0, r.name.c_str());
      OGR_F_SetFieldDouble(f, 1, r.width);
    });
    n.rivers += ok;
  }
  for (const Lake& l : w.terrain->lakes()) {
    if (!ok) break;
    ok = addFeature(lakes, lakePolygon(w, l), [&](OGRFeatureH f) { OGR_F_SetFieldDouble(f, 0, l.level); });
    n.lakes += ok;
  }
  for (const Building& b : w.buildings) {
    if (!ok) break;
    ok = addFeature(buildings, buildingPolygon(w, b), [&](OGRFeatureH f) { OGR_F_SetFieldDouble(f, 0, b.height); });
    n.buildings += ok;
  }
  if (ok) {
    auto forests = writeForest(w, forest, path);
    if (!forests) {
      GDALDatasetRollbackTransaction(ds);
      GDALClose(ds);
      return forests.problems();
    }
    n.forests = forests.value();
  }
  if (ok) ok = GDALDatasetCommitTransaction(ds) == OGRERR_NONE;
  if (!ok) {
    const Problem p = gpkgProblem(path, "write failed");
    GDALClose(ds);
    return p;
  }
  GDALClose(ds);
  return n;
}

}  // namespace sandtable::convert::synth
