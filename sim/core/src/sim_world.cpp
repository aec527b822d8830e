// The simulation's view of the database: drawn ground, soil, and the
// static objects in collision squares (seed Figures 56-58).
#include "sandtable/sim/sim_world.h"

#include <algorithm>
#include <cmath>
#include <limits>

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
    : grid_(grid), clamp_(grid, moduleSquares, levels), terrain_(grid), materials_(std::move(table)) {
  classById_.assign(256, nullptr);
  if (materials_) {
    for (const materials::Class& c : materials_->classes) {
      if (c.id < 256) classById_[c.id] = &c;
    }
  }
  buildSquares({});
}

double SimWorld::originEasting() const { return grid_->header().originEasting; }
double SimWorld::originNorthing() const { return grid_->header().originNorthing; }

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
    tallest_[sq] = std::max(tallest_[sq], objects_[i].baseY + objects_[i].height);
  }
}

namespace {

bool touches(const StaticObject& o, double x, double z, double radius, double bottomY) {
  if (o.state != ObjectState::standing) return false;
  const double dx = o.x - x, dz = o.z - z, r = o.radius + radius;
  if (dx * dx + dz * dz >= r * r) return false;  // level 2: Figure 58's cylinders
  return bottomY < o.baseY + o.height;           // level 3: below the object's top
}

}  // namespace

void SimWorld::objectsNear(double x, double z, double radius, double bottomY, std::vector<std::uint32_t>& out) const {
  const std::size_t first = out.size();
  const auto cx = static_cast<std::int64_t>(std::floor(x / square_));
  const auto cz = static_cast<std::int64_t>(std::floor(z / square_));
  for (std::int64_t sz = cz - 1; sz <= cz + 1; ++sz) {
    if (sz < 0 || sz >= std::int64_t(squaresZ_)) continue;
    for (std::int64_t sx = cx - 1; sx <= cx + 1; ++sx) {
      if (sx < 0 || sx >= std::int64_t(squaresX_)) continue;
      const std::size_t sq = std::size_t(sz) * squaresX_ + std::size_t(sx);
      ++stats_.squares;
      if (bottomY >= tallest_[sq]) continue;  // level 1: above every object of the square
      ++stats_.squaresPassed;
      for (std::uint32_t k = squareStart_[sq]; k < squareStart_[sq + 1]; ++k) {
        ++stats_.objectsTested;
        const std::uint32_t i = squareObjects_[k];
        if (touches(objects_[i], x, z, radius, bottomY)) out.push_back(i);
      }
    }
  }
  std::sort(out.begin() + std::ptrdiff_t(first), out.end());
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
/// drawn among equals).
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
    const std::size_t cell = (std::size_t(kz * moduleSquares + sz) * squaresX + (kx * moduleSquares + sx)) * 2 +
                             (g.half == module::Half::upper ? 0 : 1);
    if (cell >= classes.size() || (classes[cell] != 255 && g.priority < priority[cell])) continue;
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
      priority[cell] = g.priority;
      break;
    }
  }
}

}  // namespace

Status loadModules(SimWorld& world, const pack::PackReader& pack, std::vector<StaticObject>& out) {
  const pack::IndexHeader& h = pack.header();
  const iconpack::Pack& icons = world.icons();
  const std::uint32_t squaresX = world.grid().postsX() - 1, squaresZ = world.grid().postsZ() - 1;
  std::vector<std::uint8_t> classes(std::size_t(squaresX) * squaresZ * 2, 255), priority(classes.size(), 0);
  for (std::uint32_t kz = 0; kz < h.modulesZ; ++kz) {
    for (std::uint32_t kx = 0; kx < h.modulesX; ++kx) {
      auto m = pack.read(kx, kz);
      if (!m) return Status(m.problems());
      const module::Module& mod = m.value();
      classesOfModule(mod, kx, kz, h.moduleSquares, squaresX, classes, priority);
      const std::vector<float> none;
      const std::vector<float>& y0 = mod.levels.empty() ? none : mod.levels[0].objectY;
      for (std::uint32_t i = 0; i < mod.objects.size(); ++i) {
        const module::Object& o = mod.objects[i];
        StaticObject s;
        s.x = double(kx) * h.moduleSize + o.x;
        s.z = double(kz) * h.moduleSize + o.z;
        s.baseY = i < y0.size() ? double(y0[i]) : 0.0;
        s.radius = o.radius;
        s.height = o.height;
        s.headingDeg = module::headingRadians(o.heading) * 57.29577951308232;
        s.scale = o.scale;
        s.icon = o.icon;
        s.cls = o.cls;
        const std::string iconName = o.icon < icons.icons.size() ? icons.icons[o.icon].name : std::string();
        const materials::Class* c = world.materials_ ? world.materials_->find(o.cls) : nullptr;
        s.kind = objectKindOf(iconName, c ? c->name : std::string());
        s.moduleX = kx;
        s.moduleZ = kz;
        s.index = i;
        out.push_back(s);
      }
    }
  }
  world.setClasses(std::move(classes));
  return {};
}

Result<std::shared_ptr<SimWorld>> SimWorld::open(const std::string& directory, const SimWorldOptions& options) {
  auto db = openDatabase(directory);
  if (!db) return db.problems();
  Database& d = db.value();
  const std::uint32_t squares = d.modules ? d.modules->header().moduleSquares : 0;
  const std::uint32_t levels = d.modules ? d.modules->header().levels : 1;
  auto world = std::make_shared<SimWorld>(d.grid, squares, levels, d.materials);
  if (d.icons) world->icons_ = std::move(*d.icons);
  std::vector<StaticObject> objects;
  if (d.modules) {
    Status st = loadModules(*world, *d.modules, objects);
    if (!st) return st.problems();
  }
  world->setObjects(std::move(objects), options);
  return world;
}

}  // namespace sandtable::sim
