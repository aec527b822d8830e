#include "sandtable/runtime/module_scene.h"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <limits>

#include "camera_math.h"

namespace sandtable::runtime {
namespace {

std::uint64_t keyOf(std::uint32_t kx, std::uint32_t kz) { return (std::uint64_t(kz) << 32) | kx; }

/// Distance from (x, z) to the rectangle [x0, x1] x [z0, z1] (0 inside).
double rectDistance(double x, double z, double x0, double z0, double x1, double z1) {
  const double dx = std::max({x0 - x, 0.0, x - x1});
  const double dz = std::max({z0 - z, 0.0, z - z1});
  return std::hypot(dx, dz);
}

}  // namespace

ModuleScene::ModuleScene(const Pager& pager, const ModuleSceneSettings& s)
    : pager_(pager), settings_(s) {
  const PagingGeometry& g = pager.geometry();
  moduleSize_ = g.moduleSize;
  modulesX_ = g.modulesX;
  modulesZ_ = g.modulesZ;
  levels_ = std::max<std::uint32_t>(pager.levels(), 1);
}

const ModuleScene::Info& ModuleScene::infoFor(const ResidentRef& ref) {
  const ResidentModule& m = ref.module();
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
  info.triangles.assign(n, 0);
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
    // The renderer adds the plain lattice under culture-cut skin
    // (module_draw.cpp, appendUnderlay): count it too.
    std::uint64_t skin = 0;
    for (const auto& g : level.groups) {
      if (g.priority == module::kPrioritySkin && g.half != module::Half::skirt) skin += g.indexCount / 3;
    }
    const std::uint64_t lattice = 2ull * level.squaresX * level.squaresZ;
    info.triangles[l] = level.indices.size() / 3 + (skin > lattice ? lattice : 0);
  }
  info.errors = levelErrors(std::span(m.levels), info.finest);
  return info;
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
  out.spans.clear();
  out.vertices.clear();
  out.firsts.clear();
  out.counts.clear();
  out.modules.clear();
  out.triangles = 0;
  out.scene = SceneStats{};
  out.scene.levelCounts.assign(levels_, 0);
  out.pagerWindow = pager_.window();

  // Figure 76/78 at module granularity: the modules under the triangle,
  // grown by one module so the ground round the eye is always in.
  out.triangle = viewTriangleFor(cam, settings_.gridSpacing);
  const auto spans = selectSquares(out.triangle, moduleSize_, modulesX_, modulesZ_, 1);
  const auto planes = detail::frustumPlanes(detail::viewProjection(cam, 0, 0));
  const double ppr = pixelsPerRadian(cam.vfovDeg(), settings_.imageHeight);
  const LodOptions& lod = settings_.lod;
  for (const RowSpan& span : spans) {
    for (std::uint32_t kx = span.firstI; kx <= span.lastI; ++kx) {
      const std::uint32_t kz = span.j;
      const double x0 = kx * moduleSize_, z0 = kz * moduleSize_;
      const double x1 = x0 + moduleSize_, z1 = z0 + moduleSize_;
      const double ground = rectDistance(cam.x, cam.z, x0, z0, x1, z1);
      if (ground > cam.viewDistance) continue;  // beyond the fog
      ++out.scene.modulesSelected;
      std::uint32_t want = 0;
      if (lod.mode == LodMode::rings) want = ringLevel(lod, ground, cam.viewDistance, levels_);
      ResidentRef ref = pager_.resident(kx, kz, want);
      if (!ref) {
        ++out.scene.modulesMissing;
        continue;
      }
      const Info& info = infoFor(ref);
      const std::uint32_t finest = ref.finestLevel();
      const auto nLevels = std::uint32_t(ref.module().levels.size());
      // The vertical extent of the view volume: the module's box, skirts
      // included, against the frustum's side and far planes.
      const Eigen::Vector3d lo(x0, info.minY[finest], z0), hi(x1, info.maxY[finest], z1);
      if (!detail::boxInFrustum(planes, lo, hi)) {
        ++out.scene.modulesCulled;
        continue;
      }
      const double dy = std::max({lo.y() - cam.y, 0.0, cam.y - hi.y()});
      const double distance = std::hypot(ground, dy);
      ModuleDraw d;
      d.kx = kx;
      d.kz = kz;
      if (lod.mode == LodMode::sse) {
        want = sseLevel(info.errors, distance, ppr, lod.pixelError, 0);
      }
      d.wantedLevel = std::min(want, nLevels - 1);
      d.level = std::max(d.wantedLevel, finest);
      if (lod.morph && lod.mode == LodMode::rings) {
        d.morph = float(ringMorph(lod, d.level, ground, cam.viewDistance, nLevels));
      } else if (lod.morph && lod.mode == LodMode::sse) {
        d.morph = float(sseMorph(info.errors, d.level, distance, ppr, lod.pixelError));
      }
      const double e0 = info.errors[d.level];
      const double e1 = d.level + 1 < nLevels ? info.errors[d.level + 1] : e0;
      d.errorPx = projectedError((1.0 - d.morph) * e0 + d.morph * e1, distance, ppr);
      d.distance = distance;
      d.triangles = info.triangles[d.level];
      if (d.level > d.wantedLevel) ++out.scene.modulesCoarser;
      out.scene.maxErrorPx = std::max(out.scene.maxErrorPx, d.errorPx);
      ++out.scene.levelCounts[std::min(d.level, levels_ - 1)];
      out.triangles += d.triangles;
      d.ref = std::move(ref);
      out.modules.push_back(std::move(d));
    }
  }
  // Nearest first: the depth test then rejects most hidden fragments early.
  std::sort(out.modules.begin(), out.modules.end(),
            [](const ModuleDraw& a, const ModuleDraw& b) { return a.distance < b.distance; });
  out.scene.modulesDrawn = std::uint32_t(out.modules.size());
  const PagerMetrics pm = pager_.metrics();
  out.scene.residentInWindow = pm.residentInWindow;
  out.scene.windowModules = pm.windowModules;
  for (auto q : pm.queueLength) out.scene.pagerQueue += q;

  // Forget modules the pager has let go of, now and then.
  if (++frame_ % 64 == 0) {
    const ModuleRect w = out.pagerWindow;
    std::erase_if(info_, [&](const auto& kv) {
      return !w.contains(std::int64_t(kv.first & 0xFFFFFFFFu), std::int64_t(kv.first >> 32));
    });
  }
  out.cpuMs =
      std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - start).count();
}

}  // namespace sandtable::runtime
