#include "sandtable/scene/module_scene.h"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <array>
#include <limits>

#include "sandtable/scene/camera_math.h"

namespace sandtable::scene {
namespace {

std::uint64_t keyOf(std::uint32_t kx, std::uint32_t kz) { return (std::uint64_t(kz) << 32) | kx; }

/// Distance from (x, z) to the rectangle [x0, x1] x [z0, z1] (0 inside).
double rectDistance(double x, double z, double x0, double z0, double x1, double z1) {
  const double dx = std::max({x0 - x, 0.0, x - x1});
  const double dz = std::max({z0 - z, 0.0, z - z1});
  return std::hypot(dx, dz);
}

}  // namespace

struct ModuleScene::Walk {
  const Camera* cam = nullptr;
  const Info* info = nullptr;
  const std::array<Eigen::Vector4d, 5>* planes = nullptr;
  std::uint32_t moduleIndex = 0, levels = 1, finest = 0;
  bool placeholder = false;
  double x0 = 0, z0 = 0;  ///< the module's north-west corner, world metres
  double ppr = 0;
  DisplayBuffer* out = nullptr;
};

ModuleScene::ModuleScene(const paging::Pager& pager, const ModuleSceneSettings& s)
    : pager_(pager), settings_(s) {
  const paging::PagingGeometry& g = pager.geometry();
  moduleSize_ = g.moduleSize;
  modulesX_ = g.modulesX;
  modulesZ_ = g.modulesZ;
  levels_ = std::max<std::uint32_t>(pager.levels(), 1);
  nodeSquares_ = std::max<std::uint32_t>(s.moduleSquares >> (levels_ - 1), 1);
}

const ModuleScene::Info& ModuleScene::infoFor(const paging::ResidentRef& ref) {
  const paging::ResidentModule& m = ref.module();
  Info& info = info_[keyOf(m.kx, m.kz)];
  if (info.generation == ref.generation() && info.finest == ref.finestLevel() &&
      !info.errors.empty()) {
    return info;
  }
  info.generation = ref.generation();
  info.finest = ref.finestLevel();
  const std::size_t n = m.levels.size();
  info.minY.assign(n, 0);
  info.maxY.assign(n, 0);
  info.nodeTriangles.assign(n, {});
  for (std::size_t l = info.finest; l < n; ++l) {
    const module::Level& level = m.levels[l];
    float lo = std::numeric_limits<float>::max(), hi = std::numeric_limits<float>::lowest();
    for (const auto& v : level.vertices) {
      lo = std::min(lo, v.y);
      hi = std::max(hi, v.y);
    }
    if (level.vertices.empty()) lo = hi = 0;
    info.minY[l] = lo;
    info.maxY[l] = hi;
    info.nodeTriangles[l] =
        nodeTrianglePrefix(level, nodeSquares_, nodesPerSide(std::uint32_t(l), std::uint32_t(n)));
  }
  info.errors = levelErrors(std::span(m.levels), info.finest);
  info.cellsPerSide = nodesPerSide(0, std::uint32_t(std::max<std::size_t>(n, 1)));
  const double cell = moduleSize_ / info.cellsPerSide;
  info.cellErrors = cellErrors(std::span(m.levels), info.finest, cell, info.cellsPerSide);
  info.cellTop = cellMaxHeights(std::span(m.levels), info.finest, cell, info.cellsPerSide);
  return info;
}

namespace {

/// LodOptions::shareMorph over one module's runs nodes[from..]: each level
/// takes its smallest morph (a smaller factor only lowers the error, so
/// the bound holds), then runs that now touch merge (visit emits them in
/// Morton order).
void shareMorph(std::vector<NodeDraw>& nodes, std::size_t from) {
  std::array<float, module::kMaxLevels> least;
  least.fill(1.0f);
  for (std::size_t k = from; k < nodes.size(); ++k) {
    float& m = least[std::min<std::size_t>(nodes[k].level, module::kMaxLevels - 1)];
    m = std::min(m, nodes[k].morph);
  }
  std::size_t out = from;
  for (std::size_t k = from; k < nodes.size(); ++k) {
    NodeDraw n = nodes[k];
    n.morph = least[std::min<std::size_t>(n.level, module::kMaxLevels - 1)];
    if (out > from) {
      NodeDraw& p = nodes[out - 1];
      if (p.level == n.level && p.last == n.first) {
        p.last = n.last;
        continue;
      }
    }
    nodes[out++] = n;
  }
  nodes.resize(out);
}

}  // namespace

void ModuleScene::emit(const Walk& w, std::uint32_t level, std::uint32_t depth, std::uint32_t a,
                       std::uint32_t b, float morph) {
  DisplayBuffer& out = *w.out;
  // The depth-d node is a block of 4^s Morton indices at `level`.
  const std::uint32_t s = (w.levels - 1 - level) - depth;
  const std::uint32_t first = mortonIndex(a, b) << (2 * s);
  const std::uint32_t last = (mortonIndex(a, b) + 1) << (2 * s);
  const auto& prefix = w.info->nodeTriangles[level];
  const std::uint64_t tris = prefix[std::min<std::size_t>(last, prefix.size() - 1)] -
                             prefix[std::min<std::size_t>(first, prefix.size() - 1)];
  out.triangles += tris;
  out.modules[w.moduleIndex].triangles += tris;
  ++out.scene.nodesDrawn;
  ++out.scene.levelCounts[std::min(level, levels_ - 1)];
  // Runs of nodes at one level and morph merge into one draw.
  if (!out.nodes.empty()) {
    NodeDraw& p = out.nodes.back();
    if (p.module == w.moduleIndex && p.level == level && p.morph == morph && p.last == first) {
      p.last = last;
      return;
    }
  }
  out.nodes.push_back({w.moduleIndex, level, first, last, morph});
}

void ModuleScene::visit(const Walk& w, std::uint32_t depth, std::uint32_t a, std::uint32_t b) {
  const Camera& cam = *w.cam;
  const double size = moduleSize_ / double(1u << depth);
  const double x0 = w.x0 + a * size, z0 = w.z0 + b * size, x1 = x0 + size, z1 = z0 + size;
  const double ground = rectDistance(cam.x, cam.z, x0, z0, x1, z1);
  if (ground > cam.viewDistance) return;  // beyond the fog
  // The node's cells of the finest node grid: its errors and its top.
  const Info& info = *w.info;
  const std::uint32_t s = (w.levels - 1) - depth;
  const std::uint32_t c0 = mortonIndex(a, b) << (2 * s), c1 = (mortonIndex(a, b) + 1) << (2 * s);
  std::array<double, module::kMaxLevels> errors{};
  float top = -std::numeric_limits<float>::infinity();
  for (std::uint32_t c = c0; c < c1 && c < info.cellTop.size(); ++c) {
    top = std::max(top, info.cellTop[c]);
    for (std::uint32_t l = 0; l < w.levels; ++l) errors[l] = std::max(errors[l], info.cellErrors[l][c]);
  }
  const std::span<const double> nodeErrors(errors.data(), w.levels);
  const float lo = info.minY[w.finest];
  const float hi = std::isfinite(top) ? top : info.maxY[w.finest];
  if (!boxInFrustum(*w.planes, {x0, lo, z0}, {x1, hi, z1})) {
    ++w.out->scene.nodesCulled;
    return;
  }
  const double dy = std::max({double(lo) - cam.y, 0.0, cam.y - double(hi)});
  const double distance = std::hypot(ground, dy);
  const LodOptions& lod = settings_.lod;
  std::uint32_t want = 0;
  if (lod.mode == LodMode::rings) want = ringLevel(lod, ground, cam.viewDistance, w.levels);
  if (lod.mode == LodMode::sse) want = sseLevel(nodeErrors, distance, w.ppr, lod.pixelError, 0);
  const std::uint32_t coarsest = w.levels - 1 - depth;  // the coarsest level with skirts round it
  const bool finestDepth = coarsest <= w.finest;        // no finer level resident below this
  if (want < coarsest && !finestDepth) {
    for (std::uint32_t c = 0; c < 4; ++c) visit(w, depth + 1, 2 * a + (c & 1), 2 * b + (c >> 1));
    return;
  }
  const std::uint32_t level = std::max(std::min(want, coarsest), w.finest);
  if (level > want) ++w.out->scene.nodesCoarser;
  if (w.placeholder) ++w.out->scene.nodesPlaceholder;
  float morph = 0;
  if (lod.morph && lod.mode == LodMode::rings) {
    morph = float(ringMorph(lod, level, ground, cam.viewDistance, w.levels));
  } else if (lod.morph && lod.mode == LodMode::sse) {
    morph = float(sseMorph(nodeErrors, level, distance, w.ppr, lod.pixelError));
  }
  const double e0 = nodeErrors[level];
  const double e1 = level + 1 < w.levels ? nodeErrors[level + 1] : e0;
  const double errorPx = projectedError((1.0 - morph) * e0 + morph * e1, distance, w.ppr);
  w.out->scene.maxErrorPx = std::max(w.out->scene.maxErrorPx, errorPx);
  emit(w, level, depth, a, b, morph);
}

void ModuleScene::fill(const Camera& cam, std::uint64_t frame, DisplayBuffer& out) {
  const auto start = std::chrono::steady_clock::now();
  out.frame = frame;
  out.camera = cam;
  // A buffer origin on a module corner makes every module's offset a whole
  // number of module edges, exact in float, so two neighbours place their
  // shared edge posts at bit-identical positions: no pixel cracks between
  // them from rounding (rasterization is only watertight for equal vertices).
  out.originX = std::floor(cam.x / moduleSize_) * moduleSize_;
  out.originZ = std::floor(cam.z / moduleSize_) * moduleSize_;
  out.moduleMode = true;
  out.moduleSize = moduleSize_;
  out.nodeSquares = nodeSquares_;
  out.spans.clear();
  out.vertices.clear();
  out.firsts.clear();
  out.counts.clear();
  out.modules.clear();
  out.nodes.clear();
  out.triangles = 0;
  out.scene = SceneStats{};
  out.scene.levelCounts.assign(levels_, 0);
  out.pagerWindow = pager_.window();

  // Figure 76/78 at module granularity: the modules under the triangle,
  // grown by one module so the ground round the eye is always in.
  out.triangle = viewTriangleFor(cam, settings_.gridSpacing);
  const auto spans = paging::selectSquares(out.triangle, moduleSize_, modulesX_, modulesZ_, 1);
  const auto planes = frustumPlanes(viewProjection(cam, 0, 0));
  struct Candidate {
    std::uint32_t kx, kz;
    double distance;
  };
  std::vector<Candidate> candidates;
  for (const paging::RowSpan& span : spans) {
    for (std::uint32_t kx = span.firstI; kx <= span.lastI; ++kx) {
      const double x0 = kx * moduleSize_, z0 = span.j * moduleSize_;
      const double d = rectDistance(cam.x, cam.z, x0, z0, x0 + moduleSize_, z0 + moduleSize_);
      if (d <= cam.viewDistance) candidates.push_back({kx, span.j, d});
    }
  }
  // Nearest first: the depth test then rejects most hidden fragments early.
  std::sort(candidates.begin(), candidates.end(),
            [](const Candidate& a, const Candidate& b) { return a.distance < b.distance; });
  Walk w;
  w.cam = &cam;
  w.planes = &planes;
  w.ppr = pixelsPerRadian(cam.vfovDeg(), settings_.imageHeight);
  w.out = &out;
  for (const Candidate& c : candidates) {
    ++out.scene.modulesSelected;
    paging::ResidentRef ref = pager_.resident(c.kx, c.kz, 0);
    if (!ref) {
      ++out.scene.modulesMissing;
      continue;
    }
    const Info& info = infoFor(ref);
    w.info = &info;
    w.levels = std::uint32_t(ref.module().levels.size());
    w.finest = ref.finestLevel();
    w.placeholder = ref.placeholder();
    w.x0 = c.kx * moduleSize_;
    w.z0 = c.kz * moduleSize_;
    w.moduleIndex = std::uint32_t(out.modules.size());
    ModuleDraw d;
    d.kx = c.kx;
    d.kz = c.kz;
    d.distance = c.distance;
    d.ref = std::move(ref);
    out.modules.push_back(std::move(d));
    const std::size_t before = out.nodes.size();
    const std::uint32_t culled = out.scene.nodesCulled;
    visit(w, 0, 0, 0);
    if (settings_.lod.mode == LodMode::sse && settings_.lod.morph && settings_.lod.shareMorph) {
      shareMorph(out.nodes, before);
    }
    if (out.nodes.size() == before) {
      // Nothing of it in view: give the guard back now.
      out.modules.pop_back();
      if (out.scene.nodesCulled > culled) ++out.scene.modulesCulled;
    }
  }
  out.scene.modulesDrawn = std::uint32_t(out.modules.size());
  const paging::PagerMetrics pm = pager_.metrics();
  out.scene.residentInWindow = pm.residentInWindow;
  out.scene.windowModules = pm.windowModules;
  for (auto q : pm.queueLength) out.scene.pagerQueue += q;
  out.scene.pagerPlaceholders = pm.placeholders;
  out.scene.pagerBudgetRefusals = pm.budgetRefusals;
  out.scene.pagerTrimmedLevels = pm.budgetTrimmedLevels;
  out.scene.pagerPoolBytes = pm.poolBytes;

  // Forget modules the pager has let go of, now and then.
  if (++frame_ % 64 == 0) {
    const paging::ModuleRect win = out.pagerWindow;
    std::erase_if(info_, [&](const auto& kv) {
      return !win.contains(std::int64_t(kv.first & 0xFFFFFFFFu), std::int64_t(kv.first >> 32));
    });
  }
  out.cpuMs =
      std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - start).count();
}

}  // namespace sandtable::scene

namespace sandtable::scene {

DrawnLevels::DrawnLevels(const DisplayBuffer& buf) {
  if (!buf.moduleMode || !(buf.moduleSize > 0)) return;
  moduleSize_ = buf.moduleSize;
  for (const NodeDraw& nd : buf.nodes) {
    const ModuleDraw& md = buf.modules[nd.module];
    const auto levels = static_cast<std::uint32_t>(md.ref.module().levels.size());
    const std::uint64_t key = (std::uint64_t(md.kz) << 32) | md.kx;
    nodes_.push_back({key, Node{nd.level, nodesPerSide(nd.level, levels), nd.first, nd.last, nd.morph}});
  }
  std::stable_sort(nodes_.begin(), nodes_.end(), [](const auto& a, const auto& b) { return a.first < b.first; });
}

std::optional<world::DrawnLevel> DrawnLevels::at(double x, double z) const {
  if (!(moduleSize_ > 0)) return std::nullopt;
  const double kxf = std::floor(x / moduleSize_), kzf = std::floor(z / moduleSize_);
  if (kxf < 0 || kzf < 0) return std::nullopt;
  const std::uint64_t key = (std::uint64_t(kzf) << 32) | std::uint64_t(kxf);
  const double lx = x - kxf * moduleSize_, lz = z - kzf * moduleSize_;
  auto it = std::lower_bound(nodes_.begin(), nodes_.end(), key, [](const auto& n, std::uint64_t k) { return n.first < k; });
  for (; it != nodes_.end() && it->first == key; ++it) {
    const Node& n = it->second;
    const double node = moduleSize_ / n.side;
    const auto a = std::min(n.side - 1, static_cast<std::uint32_t>(lx / node));
    const auto b = std::min(n.side - 1, static_cast<std::uint32_t>(lz / node));
    const std::uint32_t m = mortonIndex(a, b);
    if (m >= n.first && m < n.last) return world::DrawnLevel{n.level, n.morph};
  }
  return std::nullopt;
}

std::optional<world::DrawnLevel> drawnLevelAt(const DisplayBuffer& buf, double x, double z) {
  if (!buf.moduleMode || !(buf.moduleSize > 0)) return std::nullopt;
  const double kxf = std::floor(x / buf.moduleSize), kzf = std::floor(z / buf.moduleSize);
  if (kxf < 0 || kzf < 0) return std::nullopt;
  const auto kx = static_cast<std::uint32_t>(kxf), kz = static_cast<std::uint32_t>(kzf);
  const double lx = x - kxf * buf.moduleSize, lz = z - kzf * buf.moduleSize;
  for (const NodeDraw& nd : buf.nodes) {
    const ModuleDraw& md = buf.modules[nd.module];
    if (md.kx != kx || md.kz != kz) continue;
    const auto levels = static_cast<std::uint32_t>(md.ref.module().levels.size());
    const std::uint32_t side = nodesPerSide(nd.level, levels);
    const double node = buf.moduleSize / side;
    const auto a = std::min(side - 1, static_cast<std::uint32_t>(lx / node));
    const auto b = std::min(side - 1, static_cast<std::uint32_t>(lz / node));
    const std::uint32_t m = mortonIndex(a, b);
    if (m >= nd.first && m < nd.last) return world::DrawnLevel{nd.level, nd.morph};
  }
  return std::nullopt;
}

}  // namespace sandtable::scene
