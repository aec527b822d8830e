// Definitions to icons.pack: import, levels of detail, derived bounds,
// cylinder and switch ranges, embedded textures (rules: docs/ICONS.md).
#include "sandtable/icons/icon_build.h"

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <map>
#include <numbers>

#include "sandtable/formats/bytes.h"
#include "sandtable/icons/builtin_models.h"

namespace sandtable::icons {
namespace {

namespace fs = std::filesystem;

/// The model name that asks for the procedural tree instead of a file.
constexpr std::string_view kBuiltinTree = "builtin:tree";

std::uint8_t toByte(float v) {
  return static_cast<std::uint8_t>(std::lround(std::clamp(v, 0.0f, 1.0f) * 255.0f));
}

/// A pack being built: textures shared by every icon, keyed by where they
/// came from so that two icons using one palette embed it once.
struct Builder {
  const Definitions& defs;
  const PackOptions& o;
  iconpack::Pack pack;
  std::map<std::string, std::uint32_t> textureIndex;
  Warnings warnings;

  Problem at(const IconDef& d, const std::string& what) const {
    return Problem{defs.file, d.line, "icons: icon '" + d.name + "': " + what};
  }
};

/// The texture of `m`, embedded into the pack, or kNoTexture when it has
/// none or it cannot be read (a warning; the base colour stays).
std::uint32_t embedTexture(Builder& b, const Model& model, const Material& m) {
  if (m.texture.empty()) return iconpack::kNoTexture;
  const std::string key = m.textureEmbedded ? model.source + "#" + m.texture : m.texturePath;
  if (key.empty()) return iconpack::kNoTexture;  // not found: importModel already warned
  if (const auto it = b.textureIndex.find(key); it != b.textureIndex.end()) return it->second;
  iconpack::Texture t;
  t.name = fs::path(m.texture).filename().string().substr(0, iconpack::kMaxNameBytes);
  if (m.textureEmbedded) {
    if (m.embeddedBytes.empty()) return iconpack::kNoTexture;  // raw texels: importModel warned
    t.bytes = m.embeddedBytes;
  } else {
    auto bytes = readSmallFile(m.texturePath, b.o.maxTextureBytes);
    if (!bytes) {
      for (Problem p : bytes.problems()) {
        p.message = "icons: texture skipped, the material keeps its base colour (PackOptions::maxTextureBytes): " +
                    p.message;
        b.warnings.push_back(std::move(p));
      }
      return iconpack::kNoTexture;
    }
    t.bytes = std::move(bytes.value());
  }
  const auto index = static_cast<std::uint32_t>(b.pack.textures.size());
  b.pack.textures.push_back(std::move(t));
  b.textureIndex.emplace(key, index);
  return index;
}

Model scaled(Model m, const ImportOptions& o) {
  const float s = static_cast<float>((o.unitMetres > 0 ? o.unitMetres : 1.0) * o.scale);
  for (Mesh& mesh : m.meshes) {
    for (float& v : mesh.positions) v *= s;
  }
  optimiseModel(m);
  return m;
}

Result<Model> loadModel(const Builder& b, const IconDef& d, const std::string& file) {
  if (isBuiltinName(file)) {
    // A built-in, never a file: an unknown name is refused here rather than
    // reported as a missing file.
    std::optional<Model> m = builtinModel(file);
    if (!m) return b.at(d, "model '" + file + "' is not a built-in model; the built-ins are " + builtinNames());
    return scaled(std::move(*m), d.import);
  }
  const fs::path p = fs::path(file).is_absolute() ? fs::path(file) : fs::path(b.defs.baseDir) / file;
  auto m = importModel(p.string(), d.import);
  if (!m) {
    std::vector<Problem> ps;
    for (const Problem& inner : m.problems()) ps.push_back(b.at(d, "model '" + file + "': " + inner.str()));
    return ps;
  }
  return m;
}

/// Lowers the model's foot: every vertex within 1 cm of its lowest point
/// goes down `metres` (walls and trunks lengthen; seed Figure 24).
void extendBase(Model& m, float metres) {
  if (!(metres > 0) || m.meshes.empty()) return;
  const float foot = m.bounds.min[1] + 0.01f;
  for (Mesh& mesh : m.meshes) {
    for (std::size_t k = 1; k < mesh.positions.size(); k += 3) {
      if (mesh.positions[k] <= foot) mesh.positions[k] -= metres;
    }
  }
  m.bounds.min[1] -= metres;
}

/// One rigid part: the model's meshes with their levels, the model's
/// materials appended to the icon's.
iconpack::Part makePart(Builder& b, iconpack::Icon& icon, const Model& model, const std::vector<float>& ratios,
                        std::vector<float>& levelErrors) {
  const auto firstMaterial = static_cast<std::uint32_t>(icon.materials.size());
  for (const Material& m : model.materials) {
    iconpack::Material pm;
    for (int c = 0; c < 4; ++c) pm.rgba[c] = toByte(m.baseColour[c]);
    pm.texture = embedTexture(b, model, m);
    icon.materials.push_back(pm);
  }
  const std::vector<Level> levels = makeLevels(model, ratios, b.o.maxError);
  for (std::size_t l = 0; l < levels.size(); ++l) levelErrors[l] = std::max(levelErrors[l], levels[l].errorMetres);
  iconpack::Part part;
  for (std::size_t k = 0; k < model.meshes.size(); ++k) {
    const Mesh& src = model.meshes[k];
    iconpack::Mesh mesh;
    mesh.material = firstMaterial + src.material;
    mesh.positions = src.positions;
    mesh.normals = src.normals;
    mesh.texcoords = src.texcoords;
    for (const Level& level : levels) mesh.levels.push_back(level.indices[k]);
    part.meshes.push_back(std::move(mesh));
  }
  return part;
}

/// The origin of part `i` in the icon's frame: its offset plus its parents'.
std::array<float, 3> worldOffset(const iconpack::Icon& icon, std::size_t i) {
  std::array<float, 3> o{0, 0, 0};
  for (auto k = static_cast<std::int32_t>(i); k != iconpack::kBody; k = icon.parts[std::size_t(k)].parent) {
    for (int a = 0; a < 3; ++a) o[a] += icon.parts[std::size_t(k)].offset[a];
  }
  return o;
}

/// Bounds and cylinder of the alive state, where the definition leaves them out.
void deriveExtent(iconpack::Icon& icon, const IconDef& d) {
  std::array<float, 6> box{INFINITY, INFINITY, INFINITY, -INFINITY, -INFINITY, -INFINITY};
  float radius = 0, height = 0;
  for (std::size_t i = 0; i < icon.parts.size(); ++i) {
    if (icon.parts[i].state != iconpack::State::alive) continue;
    const auto off = worldOffset(icon, i);
    for (const iconpack::Mesh& m : icon.parts[i].meshes) {
      for (std::size_t v = 0; v + 2 < m.positions.size(); v += 3) {
        const float p[3] = {m.positions[v] + off[0], m.positions[v + 1] + off[1], m.positions[v + 2] + off[2]};
        for (int a = 0; a < 3; ++a) {
          box[a] = std::min(box[a], p[a]);
          box[a + 3] = std::max(box[a + 3], p[a]);
        }
        radius = std::max(radius, std::hypot(p[0], p[2]));
        height = std::max(height, p[1]);
      }
    }
  }
  icon.bounds = d.bounds ? *d.bounds : box;
  icon.cylinderRadius = d.cylinder ? (*d.cylinder)[0] : radius;
  icon.cylinderHeight = d.cylinder ? (*d.cylinder)[1] : height;
}

/// Metres of error that cover `o.pixelError` pixels at distance 1 m.
double metresPerPixelAtOneMetre(const PackOptions& o) {
  const double halfFov = double(o.fovDegrees) * std::numbers::pi / 360.0;
  return 2.0 * std::tan(halfFov) * double(o.pixelError) / double(o.viewportHeight);
}

/// Switch ranges: the definition's where it gives them; else level i is
/// kept until the next level's error would cover the pixel budget, and the
/// last until the whole icon does. Then made strictly increasing.
std::vector<float> switchRanges(const IconDef& d, const iconpack::Icon& icon, const std::vector<float>& errors,
                                const PackOptions& o) {
  const std::size_t n = errors.size();
  const double k = metresPerPixelAtOneMetre(o);
  const double extent = std::max({icon.bounds[3] - icon.bounds[0], icon.bounds[4] - icon.bounds[1],
                                  icon.bounds[5] - icon.bounds[2], 0.01f});
  std::vector<float> ranges(n);
  for (std::size_t i = 0; i < n; ++i) {
    const float given = i < d.levels.size() ? d.levels[i].range : 0.0f;
    const double metres = i + 1 < n ? double(errors[i + 1]) : extent;
    ranges[i] = given > 0 ? given : static_cast<float>(metres / k);
  }
  // A level whose successor loses nothing (a box simplified) would get
  // range 0; each range is at least 1 % past the one before it.
  float floor = 1.0f;
  for (std::size_t i = 0; i < n; ++i) {
    const bool given = i < d.levels.size() && d.levels[i].range > 0;
    if (!given) ranges[i] = std::max(ranges[i], floor);
    floor = std::nextafter(ranges[i] * 1.01f, INFINITY);
  }
  return ranges;
}

/// A level is worth its memory and its switch only if it has at most this
/// fraction of the triangles of the level kept before it.
constexpr double kLevelGain = 0.9;

/// Drops each level that the simplifier could not make at least 10 %
/// lighter than the level before it (a low-poly model where the error
/// bound binds); the level before takes over its far range. A warning
/// names each one.
void dropFlatLevels(Builder& b, const IconDef& d, iconpack::Icon& icon) {
  std::vector<std::size_t> keep{0};
  for (std::size_t l = 1; l < icon.ranges.size(); ++l) {
    const auto before = iconpack::triangleCount(icon, keep.back()), now = iconpack::triangleCount(icon, l);
    if (double(now) <= kLevelGain * double(before)) {
      keep.push_back(l);
      continue;
    }
    b.warnings.push_back(b.at(d, "level " + std::to_string(l) + " dropped: " + std::to_string(now) +
                                     " triangles is not 10 % fewer than level " + std::to_string(keep.back()) +
                                     "'s " + std::to_string(before) + " (the simplifier's error bound binds)"));
    icon.ranges[keep.back()] = icon.ranges[l];
  }
  if (keep.size() == icon.ranges.size()) return;
  std::vector<float> ranges;
  for (const std::size_t l : keep) ranges.push_back(icon.ranges[l]);
  icon.ranges = std::move(ranges);
  for (iconpack::Part& part : icon.parts) {
    for (iconpack::Mesh& mesh : part.meshes) {
      std::vector<std::vector<std::uint32_t>> levels;
      for (const std::size_t l : keep) levels.push_back(std::move(mesh.levels[l]));
      mesh.levels = std::move(levels);
    }
  }
}

Status checkComponents(const Builder& b, const IconDef& d) {
  for (const ComponentDef& c : d.components) {
    if (c.state == iconpack::State::dead && d.dead.empty()) {
      return b.at(d, "component '" + c.name + "' has state=dead but the icon has no 'dead FILE' line");
    }
  }
  return {};
}

/// Hull and components of one state, appended to the icon's parts.
Status addState(Builder& b, iconpack::Icon& icon, const IconDef& d, iconpack::State state,
                const std::string& hullFile, const std::vector<float>& ratios, std::vector<float>& errors) {
  auto hull = loadModel(b, d, hullFile);
  if (!hull) return hull.problems();
  const BuiltinModel* builtin = findBuiltin(hullFile);
  extendBase(hull.value(), d.baseBelow.value_or(builtin && builtin->grounded ? kDefaultBaseBelow : 0.0f));
  b.warnings.insert(b.warnings.end(), hull.warnings().begin(), hull.warnings().end());
  std::map<std::string, std::int32_t> index;  // component name -> part index, this state
  iconpack::Part part = makePart(b, icon, hull.value(), ratios, errors);
  part.state = state;
  const auto hullIndex = static_cast<std::int32_t>(icon.parts.size());
  icon.parts.push_back(std::move(part));
  for (const ComponentDef& c : d.components) {
    if (c.state != state) continue;
    auto model = loadModel(b, d, c.model);
    if (!model) return model.problems();
    b.warnings.insert(b.warnings.end(), model.warnings().begin(), model.warnings().end());
    iconpack::Part comp = makePart(b, icon, model.value(), ratios, errors);
    comp.name = c.name;
    comp.state = state;
    comp.parent = c.parent.empty() ? hullIndex : index.at(c.parent);
    comp.offset = c.offset;
    index[c.name] = static_cast<std::int32_t>(icon.parts.size());
    icon.parts.push_back(std::move(comp));
  }
  return {};
}

Result<iconpack::Icon> buildIcon(Builder& b, const IconDef& d) {
  if (Status st = checkComponents(b, d); !st) return st.problems();
  std::vector<float> ratios;
  for (const LevelDef& l : d.levels) ratios.push_back(l.ratio);
  if (ratios.empty()) ratios = defaultLevelRatios();
  iconpack::Icon icon;
  icon.name = d.name;
  icon.armed = d.armed;
  icon.resupply = d.resupply;
  icon.dis = d.dis;
  std::vector<float> errors(ratios.size(), 0.0f);
  if (Status st = addState(b, icon, d, iconpack::State::alive, d.alive, ratios, errors); !st) return st.problems();
  if (!d.dead.empty()) {
    if (Status st = addState(b, icon, d, iconpack::State::dead, d.dead, ratios, errors); !st) return st.problems();
  }
  if (icon.materials.size() > 65535) return b.at(d, "more than 65535 materials over its models");
  deriveExtent(icon, d);
  icon.ranges = switchRanges(d, icon, errors, b.o);
  dropFlatLevels(b, d, icon);
  return icon;
}

IconDef treeDefinition() {
  IconDef d;
  d.name = kDefaultTreeName;
  d.alive = std::string(kBuiltinTree);
  // Three levels: a fourth at 1/10 cannot get lighter than 1/4 within the
  // error bound (80, 40, 24 triangles).
  d.levels = {{1.0f, 0.0f}, {0.5f, 0.0f}, {0.25f, 0.0f}};
  return d;
}

/// Builds every icon; the tree is appended unless the definitions have one.
Result<iconpack::Pack> run(Builder& b) {
  std::vector<Problem> problems;
  bool haveTree = false;
  for (const IconDef& d : b.defs.icons) {
    haveTree = haveTree || d.name == kDefaultTreeName;
    auto icon = buildIcon(b, d);
    if (!icon) {
      problems.insert(problems.end(), icon.problems().begin(), icon.problems().end());
      continue;
    }
    b.pack.icons.push_back(std::move(icon.value()));
  }
  if (!problems.empty()) return problems;
  if (b.o.addDefaultTree && !haveTree) {
    auto tree = buildIcon(b, treeDefinition());
    if (!tree) return tree.problems();
    b.pack.icons.push_back(std::move(tree.value()));
  }
  Result<iconpack::Pack> r(std::move(b.pack));
  r.addWarnings(b.warnings);
  return r;
}

// ---- the procedural tree -------------------------------------------------

/// A cone or a tube about the Y axis, its vertices shared between
/// neighbouring triangles so that the simplifier can take sides away.
/// A cone (topRadius 0) is closed by a base cap over the same ring; a tube
/// is open at both ends (its foot is in the ground, its top in the crown).
void addRing(Mesh& m, int sides, float baseY, float topY, float baseRadius, float topRadius) {
  const float slope = (baseRadius - topRadius) / (topY - baseY);
  const float len = std::sqrt(1 + slope * slope);
  auto push = [&](float x, float y, float z, float nx, float ny, float nz) {
    m.positions.insert(m.positions.end(), {x, y, z});
    m.normals.insert(m.normals.end(), {nx, ny, nz});
    return static_cast<std::uint32_t>(m.vertexCount() - 1);
  };
  const auto first = static_cast<std::uint32_t>(m.vertexCount());
  for (int s = 0; s < sides; ++s) {
    const double a = 2 * std::numbers::pi * s / sides;
    const float c = float(std::cos(a)), n = float(std::sin(a));
    push(baseRadius * c, baseY, baseRadius * n, c / len, slope / len, n / len);
    if (topRadius > 0) push(topRadius * c, topY, topRadius * n, c / len, slope / len, n / len);
  }
  const std::uint32_t stride = topRadius > 0 ? 2 : 1;
  auto base = [&](int s) { return first + stride * std::uint32_t(s % sides); };
  if (topRadius > 0) {
    // Counter-clockwise seen from outside, so every side faces out.
    for (int s = 0; s < sides; ++s) {
      m.indices.insert(m.indices.end(), {base(s), base(s) + 1, base(s + 1), base(s + 1), base(s) + 1, base(s + 1) + 1});
    }
    return;
  }
  const std::uint32_t apex = push(0, topY, 0, 0, 1, 0);
  const std::uint32_t centre = push(0, baseY, 0, 0, -1, 0);
  for (int s = 0; s < sides; ++s) {
    m.indices.insert(m.indices.end(), {base(s), apex, base(s + 1), centre, base(s), base(s + 1)});
  }
}

}  // namespace

Model treeModel() {
  Model m;
  m.source = std::string(kBuiltinTree);
  Material trunk, crown;
  trunk.name = "trunk";
  trunk.baseColour = {0.40f, 0.26f, 0.13f, 1.0f};
  crown.name = "crown";
  crown.baseColour = {0.13f, 0.39f, 0.13f, 1.0f};
  m.materials = {trunk, crown};
  Mesh wood, leaves;
  wood.material = 0;
  // The trunk stands on y = 0; the icon build lowers its foot by the
  // definition's base-below (0.5 m by default), so that on a slope no gap
  // opens under its downhill side (seed Figure 24).
  addRing(wood, 8, 0.0f, 3.0f, 0.25f, 0.25f);
  leaves.material = 1;
  addRing(leaves, 16, 2.0f, 6.0f, 2.5f, 0.0f);
  addRing(leaves, 16, 4.5f, 8.0f, 1.8f, 0.0f);
  m.meshes = {std::move(wood), std::move(leaves)};
  m.sourceMeshes = 2;
  optimiseModel(m);
  return m;
}

Result<iconpack::Pack> buildPack(const Definitions& defs, const PackOptions& o) {
  Builder b{defs, o, {}, {}, {}};
  return run(b);
}

iconpack::Pack defaultPack(const PackOptions& o) {
  const Definitions none;
  PackOptions withTree = o;
  withTree.addDefaultTree = true;
  auto p = buildPack(none, withTree);
  return p ? std::move(p.value()) : iconpack::Pack{};
}

}  // namespace sandtable::icons
