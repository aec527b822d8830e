// Culture::decalLevel: the module's exact partition (culture_cgal.cpp,
// cached across levels) cut to one level's grid triangles in double
// precision (docs/CULTURE.md, "Cutting to the triangles").
//
// A grid triangle that no label boundary of a layer crosses is one
// triangle (the fast path: the skin reuses the lattice vertices). Any
// other triangle gets every convex piece that may overlap it clipped to it
// (Sutherland-Hodgman against its three edges, diagonal first), the
// vertices merged within the tolerance without leaving its edges, and the
// pieces fanned into triangles in its plane.
//
// The rest of LevelWork (culture_level_work.h) lives by concern in
// culture_lookup.cpp, culture_clip.cpp, culture_merge.cpp and
// culture_emit.cpp; this file runs a level and keeps the cell cache.
#include <algorithm>
#include <cmath>
#include <cstring>

#include "culture_level_work.h"
#include "sandtable/converters/elevation.h"  // cancelRequested
#include "sandtable/formats/terrain_rule.h"

namespace sandtable::convert {
namespace culture {

LevelWork::LevelWork(const CultureImpl& culture, const ModuleCell& cell, const LevelLattice& lat, Level& out)
    : culture_(culture), cell_(cell), lat_(lat), out_(out) {
  nx_ = lat.xs.size() - 1;
  nz_ = lat.zs.size() - 1;
  tol_ = culture.options.mergeTolerance;
  double maxCoord = 0;
  for (double x : lat.xs) maxCoord = std::max(maxCoord, std::fabs(x));
  for (double z : lat.zs) maxCoord = std::max(maxCoord, std::fabs(z));
  // Spacing of floats at the largest coordinate.
  quantum_ = maxCoord > 0 ? std::ldexp(1.0, std::ilogb(maxCoord) - 23) : 0;
  auto multiple = [&](double v) { return quantum_ > 0 && std::fmod(v, quantum_) == 0; };
  // Vertices on a coarser step of whole powers of two give the module
  // format small integer x and z codes (FORMAT.md 9.8) instead of float
  // mantissas that do not compress. Only where every lattice line is on
  // that step, so that edge points stay exactly on their edge.
  const double step = culture.options.vertexStep;
  if (step > quantum_ && quantum_ > 0) {
    const double floatQuantum = quantum_;
    quantum_ = step;
    stepped_ = std::all_of(lat.xs.begin(), lat.xs.end(), multiple) &&
               std::all_of(lat.zs.begin(), lat.zs.end(), multiple);
    if (!stepped_) quantum_ = floatQuantum;
  }
  gridMultiple_ = std::all_of(lat.xs.begin(), lat.xs.end(), multiple) &&
                  std::all_of(lat.zs.begin(), lat.zs.end(), multiple);
  skinS0_ = wrap(lat.moduleX);
  skinT0_ = wrap(lat.moduleZ);
}

DecalStats LevelWork::run() {
  out_.vertices.clear();
  out_.indices.clear();
  out_.groups.clear();
  out_.spacing = lat_.spacing;
  out_.squaresX = std::uint32_t(nx_);
  out_.squaresZ = std::uint32_t(nz_);
  // The lattice posts, shared by every skin triangle with a corner there.
  out_.vertices.reserve((nx_ + 1) * (nz_ + 1) * 2);
  for (std::size_t j = 0; j <= nz_; ++j) {
    for (std::size_t i = 0; i <= nx_; ++i) {
      out_.vertices.push_back({float(lat_.xs[i]), lat_.heights[j * (nx_ + 1) + i], float(lat_.zs[j]),
                               skinS(lat_.xs[i]), skinT(lat_.zs[j])});
    }
  }
  const std::size_t nl = cell_.layers.size();
  layers_.resize(nl);
  centre_.resize(nl);
  runs_.assign(nl, {});
  runIndices_.assign(nl, {});
  for (std::size_t l = 0; l < nl; ++l) prepare(l);
  stats_.failures = cell_.failures;
  // Skin groups are written as each grid triangle is done (their order is
  // the square order); decal groups are kept per layer and appended after
  // all skin, in (priority, square, half, material) order.
  for (std::size_t sq = 0; sq < nx_ * nz_; ++sq) {
    for (int half = 0; half < 2; ++half) gridTriangle(sq, half);
  }
  flushDecals();
  stats_.triangles = out_.indices.size() / 3;
  return stats_;
}


void LevelWork::gridTriangle(std::size_t sq, int half) {
  const Tri t = tri(sq, half);
  const Vec2 centroid = (1.0 / 3.0) * (t.c[0] + t.c[1] + t.c[2]);
  const std::size_t nl = cell_.layers.size();
  modes_.assign(nl, Mode::none);
  labels_.assign(nl, kNone);
  bool anyCut = false;
  for (std::size_t l = 0; l < nl; ++l) {
    const LevelLayer& ll = layers_[l];
    const bool touched = ll.touched[sq] & (1 << half);
    if (l > 0 && (cell_.layers[l].geo.pieces.empty() || ll.start[sq] == ll.start[sq + 1])) continue;
    if (touched) {
      modes_[l] = Mode::cut;
      anyCut = true;
      continue;
    }
    const std::uint16_t label = labelAt(l, sq, centroid);
    if (l == 0 || label != kNone) modes_[l] = Mode::whole, labels_[l] = label;
  }
  if (!anyCut) {
    // The fast path: one triangle per layer, the skin on the lattice posts.
    beginGroup(sq, half, module::kPrioritySkin, labels_[0]);
    triangle(out_.indices, t.cv[0], t.cv[1], t.cv[2]);
    endGroup();
    ++stats_.skinPolygons;
    for (std::size_t l = 1; l < nl; ++l) {
      if (modes_[l] != Mode::whole) continue;
      const std::uint32_t base = std::uint32_t(decalVertices_.size());
      for (int k = 0; k < 3; ++k) {
        Vertex v{float(t.c[k].x), lat_.heights[t.cv[k]], float(t.c[k].z), 0, 0};
        roadST(l, t.c[k], v.s, v.t);
        decalVertices_.push_back(v);
      }
      Run run{std::uint32_t(sq), std::uint8_t(half), std::uint32_t(runIndices_[l].size()), 3};
      triangle(runIndices_[l], base, base + 1, base + 2);
      runs_[l].push_back(run);
      ++stats_.decalPolygons;
    }
    return;
  }
  ++stats_.slowTriangles;
  // Each priority is one draw pass: its layers are merged together.
  std::size_t l = 0;
  while (l < nl) {
    std::size_t end = l + 1;
    while (end < nl && l > 0 && cell_.layers[end].priority == cell_.layers[l].priority) ++end;
    passTriangle(sq, half, t, centroid, l, end);
    l = end;
  }
}


/// Cuts, merges and writes layers [first, end) of one grid triangle.
void LevelWork::passTriangle(std::size_t sq, int half, const Tri& t, Vec2 centroid, std::size_t first, std::size_t end) {
  bool cutHere = false, anyHere = false;
  for (std::size_t l = first; l < end; ++l) cutHere |= modes_[l] == Mode::cut, anyHere |= modes_[l] != Mode::none;
  if (!anyHere) return;
  gather(sq, t, first, end);
  if (cutHere) {
    for (int attempt = 0;; ++attempt) {
      snap(t);
      if (triangulate() || attempt == 64) break;
    }
    countClose();
  } else {
    for (SnapPoint& p : points_) p.rep = std::uint32_t(&p - points_.data());
    triangulate();
  }
  bool skinOk = true;
  if (first == 0) {
    // The skin must tile the triangle; if rounding ever defeats that,
    // the triangle keeps one skin triangle (counted as a failure).
    double skin2 = 0;
    for (const OutTri& o : tris_) skin2 += area2(o);
    const double want2 = cross(round(t.c[1]) - round(t.c[0]), round(t.c[2]) - round(t.c[0]));
    skinOk = std::fabs(skin2 - want2) <= 1e-6 * want2;
    if (!skinOk) ++stats_.failures;
  }
  emit(sq, half, t, skinOk, centroid);
}


namespace {

std::string cacheKey(double a, double b, const Box& r) {
  std::string k(6 * sizeof(double), '\0');
  const double v[6] = {a, b, r.x0, r.z0, r.x1, r.z1};
  std::memcpy(k.data(), v, sizeof v);
  return k;
}

}  // namespace

std::shared_ptr<const ModuleCell> CultureImpl::cellFor(const LevelLattice& lat, bool* built) const {
  const Box rect{lat.xs.front(), lat.zs.front(), lat.xs.back(), lat.zs.back()};
  const std::string key = cacheKey(lat.moduleX, lat.moduleZ, rect);
  std::unique_lock lock(cacheMutex_);
  for (;;) {
    auto it = std::find_if(cache_.begin(), cache_.end(), [&](const auto& e) { return e.first == key; });
    if (it == cache_.end()) break;
    if (it->second.cell) {
      cache_.splice(cache_.begin(), cache_, it);
      return it->second.cell;
    }
    cacheReady_.wait(lock);  // another thread is building it
  }
  cache_.push_front({key, {}});
  const auto mine = cache_.begin();
  if (built) *built = true;
  lock.unlock();
  std::shared_ptr<const ModuleCell> cell = computeCell(lat.moduleX, lat.moduleZ, rect);
  lock.lock();
  mine->second.cell = cell;
  for (auto it = std::prev(cache_.end()); cache_.size() > cacheCapacity_ && it != cache_.begin();) {
    auto victim = it--;
    if (victim->second.cell && victim != mine) cache_.erase(victim);
  }
  cacheReady_.notify_all();
  return cell;
}

std::shared_ptr<const ModuleCell> CultureImpl::computeCell(double mx, double mz, const Box& rect) const {
  const double t0 = threadCpuSeconds();
  auto cell = std::make_shared<ModuleCell>();
  cell->moduleX = mx, cell->moduleZ = mz, cell->rect = rect;
  const Box world{mx + rect.x0, mz + rect.z0, mx + rect.x1, mz + rect.z1};
  auto gather = [&](const std::vector<std::vector<std::uint32_t>>& index) {
    std::vector<std::uint32_t> ids;
    const auto col = [&](double x) { return std::uint32_t(std::clamp(std::floor(x / indexCell), 0.0, double(indexCols - 1))); };
    const auto row = [&](double z) { return std::uint32_t(std::clamp(std::floor(z / indexCell), 0.0, double(indexRows - 1))); };
    for (std::uint32_t r = row(world.z0); r <= row(world.z1); ++r) {
      for (std::uint32_t c = col(world.x0); c <= col(world.x1); ++c) {
        const auto& v = index[std::size_t(r) * indexCols + c];
        ids.insert(ids.end(), v.begin(), v.end());
      }
    }
    std::sort(ids.begin(), ids.end());
    ids.erase(std::unique(ids.begin(), ids.end()), ids.end());
    return ids;
  };
  CellInput in;
  in.rect = rect;
  in.defaultClass = table.defaultArea;
  std::unordered_map<std::uint16_t, std::uint16_t> slotOf;
  auto slot = [&](std::uint16_t cls, bool skin) {
    auto [it, fresh] = slotOf.try_emplace(cls, std::uint16_t(in.slots.size()));
    if (fresh) {
      const materials::Class* c = table.find(cls);
      in.slots.push_back({cls, skin, c ? c->rank : std::uint16_t(0)});
    }
    return it->second;
  };
  // Into module-local metres; points on the rectangle's edges exactly on them.
  auto local = [&](Ring r) {
    for (Vec2& p : r) {
      p = {p.x - mx, p.z - mz};
      for (double e : {rect.x0, rect.x1}) {
        if (std::fabs(p.x - e) < 1e-9) p.x = e;
      }
      for (double e : {rect.z0, rect.z1}) {
        if (std::fabs(p.z - e) < 1e-9) p.z = e;
      }
    }
    return r;
  };
  // A cancelled build discards the module: stop early, leave it default skin.
  bool cancelled = cancelRequested();
  std::uint32_t seen = 0;
  auto stop = [&] { return cancelled || (++seen % 256 == 0 && (cancelled = cancelRequested())); };
  for (std::uint32_t id : gather(areaIndex)) {
    if (stop()) break;
    const AreaFeature& f = areas[id];
    if (!f.box.overlaps(world)) continue;
    for (const Ring& r : f.rings) {
      Ring c = clipRingToRect(r, world);
      if (!c.empty()) in.rings.push_back({local(std::move(c)), slot(f.classId, true)});
    }
  }
  const std::vector<std::uint32_t> lineIds = gather(lineIndex);
  for (std::uint32_t id : lineIds) {
    if (stop()) break;
    const LineFeature& f = lines[id];
    if (!f.box.overlaps(world)) continue;
    for (const Ring& r : f.outline) {
      Ring c = clipRingToRect(r, world);
      if (!c.empty()) in.rings.push_back({local(std::move(c)), slot(f.classId, false)});
    }
  }
  std::vector<LayerGeometry> geo;
  cell->gatherSeconds = threadCpuSeconds() - t0;
  if (!in.rings.empty() && !cancelled && !cancelRequested()) {
    try {
      geo = buildCell(in, &cell->times);
    } catch (const std::exception&) {
      geo.clear();
      cell->failures = 1;
    }
  }
  if (geo.empty()) {
    LayerGeometry skin;
    skin.uniform = table.defaultArea;
    const Ring r = {{rect.x0, rect.z0}, {rect.x1, rect.z0}, {rect.x1, rect.z1}, {rect.x0, rect.z1}};
    skin.pieces.push_back({skin.uniform, boxOf(r), r});
    geo.push_back(std::move(skin));
  }
  for (LayerGeometry& g : geo) {
    ModuleCell::Layer layer;
    if (!g.skin) {
      if (g.pieces.empty()) continue;
      const materials::Class* c = table.find(g.classId);
      layer.priority = c ? c->priority : module::kPriorityRoad;
      // Centrelines near the module, for texture coordinates.
      for (std::uint32_t id : lineIds) {
        const LineFeature& f = lines[id];
        if (f.classId != g.classId || !f.box.overlaps(world)) continue;
        for (const Polyline& p : f.parts) {
          double along = 0;
          for (std::size_t k = 0; k + 1 < p.size(); ++k) {
            const Vec2 a = p[k], b = p[k + 1];
            const double len = length(b - a);
            Box sb;
            sb.add(a), sb.add(b);
            if (sb.overlaps(world.grown(2 * f.width + 1))) {
              layer.centre.push_back({{a.x - mx, a.z - mz}, {b.x - mx, b.z - mz}, along, f.width});
            }
            along += len;
          }
        }
      }
    }
    layer.geo = std::move(g);
    cell->layers.push_back(std::move(layer));
  }
  std::stable_sort(cell->layers.begin() + 1, cell->layers.end(), [](const auto& a, const auto& b) {
    return a.priority != b.priority ? a.priority < b.priority : a.geo.classId < b.geo.classId;
  });
  return cell;
}

DecalStats CultureImpl::decalLevel(const LevelLattice& lat, module::Level& out) const {
  assert(lat.xs.size() >= 2 && lat.zs.size() >= 2 && lat.heights.size() == lat.xs.size() * lat.zs.size());
  if (lat.xs.size() < 2 || lat.zs.size() < 2 || lat.heights.size() != lat.xs.size() * lat.zs.size()) return {};
  const double t0 = threadCpuSeconds();
  bool built = false;
  const std::shared_ptr<const ModuleCell> cell = cellFor(lat, &built);
  const double t1 = threadCpuSeconds();
  DecalStats st = LevelWork(*this, *cell, lat, out).run();
  addBuildings(lat, out, st);
  st.cutSeconds = threadCpuSeconds() - t1;
  if (built) {
    st.partitionSeconds = t1 - t0;
    st.gatherSeconds = cell->gatherSeconds;
    st.arrangementSeconds = cell->times.arrangement;
    st.piecesSeconds = cell->times.pieces;
  }
  return st;
}

}  // namespace culture
}  // namespace sandtable::convert
