// The simulation's view of the database: drawn ground, soil, and the
// static objects in collision squares (seed Figures 56-58).
#include "sandtable/sim/sim_world.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <unordered_map>

#include "sandtable/formats/database.h"
#include "sandtable/formats/pack.h"
#include "sandtable/formats/terrain_rule.h"

namespace sandtable::sim {

const char* objectStateName(ObjectState s) {
  switch (s) {
    case ObjectState::standing: return "standing";
    case ObjectState::knockedOver: return "knocked-over";
    case ObjectState::stump: return "stump";
    case ObjectState::ruins: return "ruins";
    case ObjectState::destroyed: return "destroyed";
  }
  return "?";
}

const char* objectKindName(ObjectKind k) {
  switch (k) {
    case ObjectKind::tree: return "tree";
    case ObjectKind::house: return "house";
    case ObjectKind::rock: return "rock";
  }
  return "?";
}

ObjectKind objectKindOf(const std::string& iconName, const std::string& className) {
  auto has = [&](const char* word) {
    return iconName.find(word) != std::string::npos || className.find(word) != std::string::npos;
  };
  if (has("tree") || has("forest") || has("wood")) return ObjectKind::tree;
  if (has("house") || has("building") || has("garage") || has("hut")) return ObjectKind::house;
  return ObjectKind::rock;
}

SimWorld::SimWorld(std::shared_ptr<const grid::GridFile> grid, std::uint32_t moduleSquares, std::uint32_t levels,
                   std::optional<materials::Table> table)
    : SimWorld(grid::heightField(std::move(grid)), moduleSquares, levels, std::move(table)) {}

SimWorld::SimWorld(std::shared_ptr<const grid::HeightField> heights, std::uint32_t moduleSquares,
                   std::uint32_t levels, std::optional<materials::Table> table)
    : grid_(heights), clamp_(heights, moduleSquares, levels), terrain_(heights), materials_(std::move(table)) {
  classById_.assign(256, nullptr);
  if (materials_) {
    for (const materials::Class& c : materials_->classes) {
      if (c.id < 256) classById_[c.id] = &c;
    }
  }
  buildSquares({});
}

double SimWorld::originEasting() const { return grid_->originEasting(); }
double SimWorld::originNorthing() const { return grid_->originNorthing(); }

std::optional<double> SimWorld::groundAt(double x, double z) const { return clamp_.surfaceXZ(x, z, drawnAt(x, z)); }

std::optional<std::uint16_t> SimWorld::classAt(double x, double z) const {
  if (classes_.empty() || !onGrid(x, z)) return std::nullopt;
  const double s = grid_->spacing();
  const std::uint32_t sqX = grid_->postsX() - 1, sqZ = grid_->postsZ() - 1;
  const auto i = std::min<std::uint32_t>(sqX - 1, static_cast<std::uint32_t>(x / s));
  const auto j = std::min<std::uint32_t>(sqZ - 1, static_cast<std::uint32_t>(z / s));
  const double u = x / s - i, v = z / s - j;
  const std::uint8_t c = classes_[(std::size_t(j) * sqX + i) * 2 + std::size_t(terrain::halfAt(u, v))];
  if (c == 255) return std::nullopt;
  return c;
}

SimWorld::Soil SimWorld::soilAt(double x, double z) const {
  Soil soil;
  const auto id = classAt(x, z);
  if (!id) return soil;
  if (const materials::Class* c = classById_[*id]) {
    soil.stickDeg = c->stickDeg;
    soil.resist = c->resist;
    soil.water = c->water;
    soil.known = true;
  }
  return soil;
}

bool SimWorld::navigable(double x, double z) const {
  if (!onGrid(x, z)) return false;
  const auto s = terrain_.sampleXZ(x, z);
  if (!s) return false;
  if (s->material == kGridWater) return true;  // the builder's sea and elevation <= 0
  const Soil soil = soilAt(x, z);
  if (soil.known) return soil.water;
  return s->elevation <= 0;
}

std::optional<std::uint16_t> SimWorld::iconIndex(const std::string& name) const {
  for (std::size_t k = 0; k < icons_.icons.size(); ++k) {
    if (icons_.icons[k].name == name) return static_cast<std::uint16_t>(k);
  }
  return std::nullopt;
}

void SimWorld::setObjects(std::vector<StaticObject> objects, const SimWorldOptions& options) {
  objects_ = std::move(objects);
  options_ = options;
  buildSquares(options);
}

void SimWorld::buildSquares(const SimWorldOptions& options) {
  double maxRadius = 0;
  for (const StaticObject& o : objects_) maxRadius = std::max(maxRadius, o.radius);
  // 3x3 squares are enough when nothing reaches past the neighbouring square.
  square_ = std::max(options.squareM, maxRadius + options.maxEntityRadiusM + options.maxStepM);
  squaresX_ = std::max<std::uint32_t>(1, static_cast<std::uint32_t>(std::ceil(widthM() / square_)));
  squaresZ_ = std::max<std::uint32_t>(1, static_cast<std::uint32_t>(std::ceil(depthM() / square_)));
  const std::size_t n = std::size_t(squaresX_) * squaresZ_;
  squareStart_.assign(n + 1, 0);
  tallest_.assign(n, -std::numeric_limits<double>::infinity());
  auto squareOf = [&](const StaticObject& o) {
    const auto sx = std::min<std::uint32_t>(squaresX_ - 1, static_cast<std::uint32_t>(std::max(0.0, o.x / square_)));
    const auto sz = std::min<std::uint32_t>(squaresZ_ - 1, static_cast<std::uint32_t>(std::max(0.0, o.z / square_)));
    return std::size_t(sz) * squaresX_ + sx;
  };
  for (const StaticObject& o : objects_) ++squareStart_[squareOf(o) + 1];
  for (std::size_t k = 0; k < n; ++k) squareStart_[k + 1] += squareStart_[k];
  squareObjects_.assign(objects_.size(), 0);
  std::vector<std::uint32_t> fill(squareStart_.begin(), squareStart_.end() - 1);
  for (std::uint32_t i = 0; i < objects_.size(); ++i) {
    const std::size_t sq = squareOf(objects_[i]);
    squareObjects_[fill[sq]++] = i;
    if (objects_[i].current) tallest_[sq] = std::max(tallest_[sq], objects_[i].baseY + objects_[i].height);
  }
}

namespace {

bool touches(const StaticObject& o, double x, double z, double radius, double bottomY) {
  if (o.state != ObjectState::standing || !o.current) return false;
  const double dx = o.x - x, dz = o.z - z, r = o.radius + radius;
  if (dx * dx + dz * dz >= r * r) return false;  // level 2: Figure 58's cylinders
  return bottomY < o.baseY + o.height;           // level 3: below the object's top
}

}  // namespace

void SimWorld::objectsNear(double x, double z, double radius, double bottomY, std::vector<std::uint32_t>& out,
                           SearchStats* stats) const {
  const std::size_t first = out.size();
  SearchStats n;  // counted here, added once: the world itself stays unwritten (const is thread-safe)
  const auto cx = static_cast<std::int64_t>(std::floor(x / square_));
  const auto cz = static_cast<std::int64_t>(std::floor(z / square_));
  for (std::int64_t sz = cz - 1; sz <= cz + 1; ++sz) {
    if (sz < 0 || sz >= std::int64_t(squaresZ_)) continue;
    for (std::int64_t sx = cx - 1; sx <= cx + 1; ++sx) {
      if (sx < 0 || sx >= std::int64_t(squaresX_)) continue;
      const std::size_t sq = std::size_t(sz) * squaresX_ + std::size_t(sx);
      ++n.squares;
      if (bottomY >= tallest_[sq]) continue;  // level 1: above every object of the square
      ++n.squaresPassed;
      for (std::uint32_t k = squareStart_[sq]; k < squareStart_[sq + 1]; ++k) {
        ++n.objectsTested;
        const std::uint32_t i = squareObjects_[k];
        if (touches(objects_[i], x, z, radius, bottomY)) out.push_back(i);
      }
    }
  }
  std::sort(out.begin() + std::ptrdiff_t(first), out.end());
  if (stats) {
    stats->squares += n.squares;
    stats->squaresPassed += n.squaresPassed;
    stats->objectsTested += n.objectsTested;
  }
}

void SimWorld::objectsNearBruteForce(double x, double z, double radius, double bottomY,
                                     std::vector<std::uint32_t>& out) const {
  for (std::uint32_t i = 0; i < objects_.size(); ++i) {
    if (touches(objects_[i], x, z, radius, bottomY)) out.push_back(i);
  }
}

namespace {

/// Level 0's class at the centroid of each grid triangle of module (kx, kz):
/// the highest priority group whose triangles hold the centroid (the last
/// drawn among equals). `priority` is the module's own, (sz * moduleSquares
/// + sx) * 2 + half: a module writes only its own squares' cells.
void classesOfModule(const module::Module& m, std::uint32_t kx, std::uint32_t kz, std::uint32_t moduleSquares,
                     std::uint32_t squaresX, std::vector<std::uint8_t>& classes, std::vector<std::uint8_t>& priority) {
  if (m.levels.empty()) return;
  const module::Level& lv = m.levels[0];
  const double s = lv.spacing;
  for (const module::Group& g : lv.groups) {
    if (g.half == module::Half::skirt || g.priority >= module::kPriorityObject || g.material > 254) continue;
    const std::uint32_t sx = g.square % lv.squaresX, sz = g.square / lv.squaresX;
    const double third = g.half == module::Half::upper ? 1.0 / 3.0 : 2.0 / 3.0;
    const double px = (sx + third) * s, pz = (sz + third) * s;
    const std::size_t half = g.half == module::Half::upper ? 0 : 1;
    const std::size_t cell = (std::size_t(kz * moduleSquares + sz) * squaresX + (kx * moduleSquares + sx)) * 2 + half;
    const std::size_t own = (std::size_t(sz) * moduleSquares + sx) * 2 + half;
    if (cell >= classes.size() || own >= priority.size() || (classes[cell] != 255 && g.priority < priority[own])) {
      continue;
    }
    for (std::uint32_t k = g.firstIndex; k + 2 < g.firstIndex + g.indexCount; k += 3) {
      const module::Vertex& a = lv.vertices[lv.indices[k]];
      const module::Vertex& b = lv.vertices[lv.indices[k + 1]];
      const module::Vertex& c = lv.vertices[lv.indices[k + 2]];
      auto side = [&](const module::Vertex& p, const module::Vertex& q) {
        return (q.x - p.x) * (pz - p.z) - (q.z - p.z) * (px - p.x);
      };
      const double d1 = side(a, b), d2 = side(b, c), d3 = side(c, a);
      const bool neg = d1 < 0 || d2 < 0 || d3 < 0, pos = d1 > 0 || d2 > 0 || d3 > 0;
      if (neg && pos) continue;
      classes[cell] = static_cast<std::uint8_t>(g.material);
      priority[own] = g.priority;
      break;
    }
  }
}

}  // namespace

Status SimWorld::readModule(std::uint32_t kx, std::uint32_t kz, module::Module& mod) {
  const pack::IndexHeader& h = modules_->header();
  auto generation = modules_->read(kx, kz, mod);
  if (!generation) return Status(generation.problems());
  moduleGeneration_[std::size_t(kz) * h.modulesX + kx] = generation.value();
  // This module's cells only: another module's soil stays as it was.
  const std::uint32_t squaresX = grid_->postsX() - 1, squaresZ = grid_->postsZ() - 1, S = h.moduleSquares;
  for (std::uint32_t sz = 0; sz < S && std::uint64_t(kz) * S + sz < squaresZ; ++sz) {
    for (std::uint32_t sx = 0; sx < S && std::uint64_t(kx) * S + sx < squaresX; ++sx) {
      const std::size_t cell = (std::size_t(kz * S + sz) * squaresX + (kx * S + sx)) * 2;
      classes_[cell] = classes_[cell + 1] = 255;
    }
  }
  std::vector<std::uint8_t> priority(std::size_t(S) * S * 2, 0);
  classesOfModule(mod, kx, kz, S, squaresX, classes_, priority);
  const std::vector<float> none;
  const std::vector<float>& y0 = mod.levels.empty() ? none : mod.levels[0].objectY;
  for (std::uint32_t i = 0; i < mod.objects.size(); ++i) {
    const module::Object& o = mod.objects[i];
    StaticObject st;
    st.x = double(kx) * h.moduleSize + o.x;
    st.z = double(kz) * h.moduleSize + o.z;
    st.baseY = i < y0.size() ? double(y0[i]) : 0.0;
    st.radius = o.radius;
    st.height = o.height;
    st.headingDeg = module::headingRadians(o.heading) * 57.29577951308232;
    st.scale = o.scale;
    st.icon = o.icon;
    st.cls = o.cls;
    const std::string iconName = o.icon < icons_.icons.size() ? icons_.icons[o.icon].name : std::string();
    const materials::Class* c = materials_ ? materials_->find(o.cls) : nullptr;
    st.kind = objectKindOf(iconName, c ? c->name : std::string());
    st.moduleX = kx;
    st.moduleZ = kz;
    st.index = i;
    st.id = o.id;
    objects_.push_back(st);
  }
  return {};
}

void SimWorld::retire(std::uint32_t kx, std::uint32_t kz, std::size_t first) {
  // The module's objects of older generations are retired (their indices
  // stay valid for events and the viewer's overrides); each hands its
  // state to the object of the same id in the new generation, so a tree
  // knocked over stays down when a crater re-meshes its module.
  std::unordered_map<std::uint64_t, std::uint32_t> fresh;
  for (std::size_t i = first; i < objects_.size(); ++i) fresh.emplace(objects_[i].id, std::uint32_t(i));
  for (std::size_t i = 0; i < first; ++i) {
    StaticObject& o = objects_[i];
    if (!o.current || o.moduleX != kx || o.moduleZ != kz) continue;
    o.current = false;
    const auto it = fresh.find(o.id);
    if (it == fresh.end()) continue;
    o.successor = it->second;
    objects_[it->second].state = o.state;
  }
}

Status SimWorld::loadModules() {
  const pack::IndexHeader& h = modules_->header();
  const std::uint32_t squaresX = grid_->postsX() - 1, squaresZ = grid_->postsZ() - 1;
  classes_.assign(std::size_t(squaresX) * squaresZ * 2, 255);
  moduleGeneration_.assign(std::size_t(h.modulesX) * h.modulesZ, 0);
  // Read before the first module, so a change made while loading is seen
  // by the first refresh().
  changesSeen_ = modules_->changes();
  module::Module scratch;
  for (std::uint32_t kz = 0; kz < h.modulesZ; ++kz) {
    for (std::uint32_t kx = 0; kx < h.modulesX; ++kx) {
      if (Status st = readModule(kx, kz, scratch); !st) return st;
    }
  }
  return {};
}

Result<std::uint32_t> SimWorld::refresh() {
  if (!modules_) return 0u;
  const std::uint64_t now = modules_->changes();
  if (now == changesSeen_) return 0u;
  std::vector<paging::ModuleKey> changed;
  changesSeen_ = modules_->changedSince(changesSeen_, changed);
  const pack::IndexHeader& h = modules_->header();
  std::sort(changed.begin(), changed.end(), [](const paging::ModuleKey& a, const paging::ModuleKey& b) {
    return a.kz != b.kz ? a.kz < b.kz : a.kx < b.kx;
  });
  changed.erase(std::unique(changed.begin(), changed.end()), changed.end());
  std::uint32_t read = 0;
  std::vector<Problem> problems;
  module::Module scratch;
  for (const paging::ModuleKey& k : changed) {
    if (k.kx >= h.modulesX || k.kz >= h.modulesZ) continue;
    if (modules_->generation(k.kx, k.kz) == moduleGeneration_[std::size_t(k.kz) * h.modulesX + k.kx]) continue;
    const std::size_t first = objects_.size();
    if (Status st = readModule(k.kx, k.kz, scratch); !st) {
      problems.insert(problems.end(), st.problems().begin(), st.problems().end());
      continue;
    }
    retire(k.kx, k.kz, first);
    ++read;
  }
  if (read) buildSquares(options_);
  if (!problems.empty()) return problems;
  return read;
}

Result<std::shared_ptr<SimWorld>> SimWorld::open(const paging::World& w, const SimWorldOptions& options) {
  const std::shared_ptr<const paging::ModuleSource>& source = w.modules();
  const std::uint32_t squares = source ? source->header().moduleSquares : 0;
  const std::uint32_t levels = source ? source->header().levels : 1;
  auto world = std::make_shared<SimWorld>(w.heights(), squares, levels, w.materials());
  if (w.icons()) world->icons_ = *w.icons();
  world->options_ = options;
  if (source) {
    world->modules_ = source;
    if (Status st = world->loadModules(); !st) return st.problems();
  }
  world->buildSquares(options);
  return world;
}

Result<std::shared_ptr<SimWorld>> SimWorld::open(const std::string& directory, const SimWorldOptions& options) {
  auto w = paging::World::open(directory);
  if (!w) return w.problems();
  return open(*w.value(), options);
}

}  // namespace sandtable::sim
