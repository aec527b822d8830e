// From definitions to icons.pack on the real models in ../shared/data/models
// and on the procedural tree: states, components, textures embedded once,
// bounds and cylinder derived, switch ranges from the screen-space error,
// and problems that name the definition line.
#include <gtest/gtest.h>

#include <unistd.h>

#include <cmath>
#include <filesystem>
#include <fstream>
#include <numbers>

#include "sandtable/icons/icon_build.h"
#include "sandtable/testing/require.h"

namespace fs = std::filesystem;
using namespace sandtable;
using namespace sandtable::icons;

namespace {

const std::string kSource = SANDTABLE_SOURCE_DIR;
const std::string kModels = kSource + "/../shared/data/models";

#define NEED_MODELS() SANDTABLE_REQUIRE(fs::exists(kModels), "the models of ../shared/data at " << kModels)

Result<Definitions> parse(const std::string& text) {
  return parseDefinitions(std::as_bytes(std::span(text.data(), text.size())), "defs.txt", kModels);
}

std::vector<std::byte> fileBytes(const std::string& p) {
  std::ifstream f(p, std::ios::binary);
  const std::string s((std::istreambuf_iterator<char>(f)), {});
  const auto* b = reinterpret_cast<const std::byte*>(s.data());
  return {b, b + s.size()};
}

const iconpack::Icon* find(const iconpack::Pack& p, const std::string& name) {
  for (const auto& i : p.icons) {
    if (i.name == name) return &i;
  }
  return nullptr;
}

/// Every alive vertex in the icon frame, offsets of the parent chain added.
std::vector<std::array<float, 3>> aliveVertices(const iconpack::Icon& icon) {
  std::vector<std::array<float, 3>> out;
  for (std::size_t i = 0; i < icon.parts.size(); ++i) {
    if (icon.parts[i].state != iconpack::State::alive) continue;
    std::array<float, 3> off{0, 0, 0};
    for (std::int32_t k = std::int32_t(i); k >= 0; k = icon.parts[std::size_t(k)].parent) {
      for (int a = 0; a < 3; ++a) off[a] += icon.parts[std::size_t(k)].offset[a];
    }
    for (const auto& m : icon.parts[i].meshes) {
      for (std::size_t v = 0; v < m.positions.size(); v += 3) {
        out.push_back({m.positions[v] + off[0], m.positions[v + 1] + off[1], m.positions[v + 2] + off[2]});
      }
    }
  }
  return out;
}

std::array<float, 3> corner(const Mesh& m, std::uint32_t i) {
  return {m.positions[3 * i], m.positions[3 * i + 1], m.positions[3 * i + 2]};
}

/// Twice the area vector of triangle k (its normal, by the winding).
std::array<double, 3> triangleNormal(const Mesh& m, std::size_t k) {
  const auto a = corner(m, m.indices[k]), b = corner(m, m.indices[k + 1]), c = corner(m, m.indices[k + 2]);
  const double u[3] = {b[0] - a[0], b[1] - a[1], b[2] - a[2]}, v[3] = {c[0] - a[0], c[1] - a[1], c[2] - a[2]};
  return {u[1] * v[2] - u[2] * v[1], u[2] * v[0] - u[0] * v[2], u[0] * v[1] - u[1] * v[0]};
}

TEST(TreeModel, isTheDocumentedTrunkAndCrown) {
  const Model t = treeModel();
  ASSERT_EQ(t.meshes.size(), 2u);
  const Mesh& trunk = t.meshes[0];
  const Mesh& crown = t.meshes[1];
  EXPECT_EQ(trunk.triangleCount(), 8u * 2);       // an open 8-sided tube
  EXPECT_EQ(crown.triangleCount(), 2u * 16 * 2);  // two 16-sided cones with caps
  EXPECT_NEAR(t.bounds.min[1], 0, 1e-6);  // base-below lowers it in the pack
  EXPECT_NEAR(t.bounds.max[1], 8, 1e-6);
  EXPECT_NEAR(t.bounds.max[0], 2.5, 1e-5);  // a vertex at angle 0
  EXPECT_NEAR(t.bounds.min[0], -2.5, 1e-5);
  // The trunk's sides face away from its axis.
  for (std::size_t k = 0; k < trunk.indices.size(); k += 3) {
    const auto n = triangleNormal(trunk, k);
    const auto a = corner(trunk, trunk.indices[k]), b = corner(trunk, trunk.indices[k + 1]);
    EXPECT_GT(n[0] * (a[0] + b[0]) + n[2] * (a[2] + b[2]), 0) << "trunk triangle " << k / 3;
  }
  // The crown is closed and wound outward: its signed volume (divergence
  // theorem) is the two 16-gon cones' volume, one third of base times height.
  double volume = 0;
  for (std::size_t k = 0; k < crown.indices.size(); k += 3) {
    const auto a = corner(crown, crown.indices[k]);
    const auto n = triangleNormal(crown, k);
    volume += (a[0] * n[0] + a[1] * n[1] + a[2] * n[2]) / 6;
  }
  auto cone = [](double r, double h) { return 8 * r * r * std::sin(2 * std::numbers::pi / 16) * h / 3; };
  EXPECT_NEAR(volume, cone(2.5, 4) + cone(1.8, 3.5), 1e-3);
}

TEST(BuildPack, theDefaultPackHoldsTheTreeAndReadsBack) {
  const iconpack::Pack p = defaultPack();
  ASSERT_EQ(p.icons.size(), 1u);
  const iconpack::Icon& tree = p.icons[0];
  EXPECT_EQ(tree.name, kDefaultTreeName);
  EXPECT_EQ(iconpack::triangleCount(tree, 0), 80u);
  EXPECT_NEAR(tree.cylinderRadius, 2.5, 1e-5);
  EXPECT_NEAR(tree.cylinderHeight, 8, 1e-6);
  // The last range: the tree's 8.5 m extent (the trunk's foot included)
  // covers one pixel of 1080 at 60 degrees.
  const double last = 8.5 * 1080 / (2 * std::tan(std::numbers::pi / 6));
  EXPECT_NEAR(tree.ranges.back(), last, last * 1e-5);
  for (std::size_t i = 1; i < tree.ranges.size(); ++i) EXPECT_GT(tree.ranges[i], tree.ranges[i - 1]);
  auto bytes = iconpack::encode(p);
  ASSERT_TRUE(bytes) << bytes.error();
  auto back = iconpack::decode(bytes.value(), "icons.pack");
  ASSERT_TRUE(back) << back.error();
  EXPECT_EQ(back.value(), p);
}

TEST(BuildPack, theSampleFileBuildsWithoutModelFiles) {
  auto defs = readDefinitions(kSource + "/samples/icons.txt");
  ASSERT_TRUE(defs) << defs.error();
  auto p = buildPack(defs.value());
  ASSERT_TRUE(p) << p.error();
  ASSERT_EQ(p->icons.size(), 11u);  // its own tree replaces the default one
  const iconpack::Icon* small = find(p.value(), "tree-small");
  const iconpack::Icon* tall = find(p.value(), "tree-tall");
  ASSERT_TRUE(small && tall);
  EXPECT_FLOAT_EQ(small->cylinderRadius, 1.5f);  // given in the file
  EXPECT_NEAR(tall->cylinderHeight, 8 * 1.6, 1e-4);  // scaled
  EXPECT_EQ(tall->ranges, (std::vector<float>{400, 1500, 6000}));
}

TEST(BuildPack, baseBelowLowersTheFootOfEachHullInMetres) {
  // A 2 m cube standing on y = 0, written here: 8 corners, 12 triangles.
  const fs::path dir = fs::temp_directory_path() / ("st-base-" + std::to_string(::getpid()));
  fs::create_directories(dir);
  std::ofstream(dir / "cube.obj") << "v -1 0 -1\nv 1 0 -1\nv 1 0 1\nv -1 0 1\nv -1 2 -1\nv 1 2 -1\nv 1 2 1\nv -1 2 1\n"
                                     "f 1 2 3\nf 1 3 4\nf 5 7 6\nf 5 8 7\nf 1 5 6\nf 1 6 2\nf 2 6 7\nf 2 7 3\n"
                                     "f 3 7 8\nf 3 8 4\nf 4 8 5\nf 4 5 1\n";
  const auto build = [&](const std::string& extra) {
    const std::string text = "sandtable-icons 1\nicon cube\n  model cube.obj\n  scale 3\n" + extra;
    auto defs = parseDefinitions(std::as_bytes(std::span(text.data(), text.size())), "defs.txt", dir.string());
    EXPECT_TRUE(defs) << defs.error();
    auto p = buildPack(defs.value());
    EXPECT_TRUE(p) << p.error();
    return p.value().icons.at(0);
  };
  const iconpack::Icon byDefault = build(""), deep = build("  base-below 4\n"), none = build("  base-below 0\n");
  // The foot goes down in metres after the scale (the cube is 6 m tall); the
  // top stays. A model file keeps its foot unless asked.
  EXPECT_FLOAT_EQ(byDefault.bounds[1], 0.0f);
  EXPECT_FLOAT_EQ(deep.bounds[1], -4.0f);
  EXPECT_FLOAT_EQ(none.bounds[1], 0.0f);
  for (const auto* icon : {&byDefault, &deep, &none}) {
    EXPECT_FLOAT_EQ(icon->bounds[4], 6.0f);
    EXPECT_EQ(iconpack::triangleCount(*icon, 0), 12u);
  }
  // The stored vertices: four at the top, the rest exactly at the new foot.
  const auto& m = deep.parts.at(0).meshes.at(0);
  for (std::size_t v = 0; v < m.vertexCount(); ++v) {
    const float y = m.positions[3 * v + 1];
    EXPECT_TRUE(y == 6.0f || y == -4.0f) << y;
  }
  // The built-in tree's trunk stands on 0 and reaches kDefaultBaseBelow down in the pack.
  EXPECT_FLOAT_EQ(defaultPack().icons.at(0).bounds[1], -kDefaultBaseBelow);
  const std::string bad = "sandtable-icons 1\nicon c\n  model cube.obj\n  base-below -1\n";
  auto refused = parseDefinitions(std::as_bytes(std::span(bad.data(), bad.size())), "defs.txt", dir.string());
  ASSERT_FALSE(refused);
  EXPECT_NE(refused.error().find("base-below must be metres from 0 to 1000"), std::string::npos) << refused.error();
  fs::remove_all(dir);
}

TEST(BuildPack, realModelsWithStatesComponentsAndTextures) {
  NEED_MODELS();
  auto defs = readDefinitions(kSource + "/samples/icons-models.txt");
  ASSERT_TRUE(defs) << defs.error();
  auto r = buildPack(defs.value());
  ASSERT_TRUE(r) << r.error();
  const iconpack::Pack& p = r.value();
  ASSERT_EQ(p.icons.size(), 5u);  // four, and the default tree
  ASSERT_TRUE(find(p, kDefaultTreeName));

  // The jeep's JPEG and the Kenney palette PNG, embedded byte for byte,
  // the palette once although two icons use it (two sets ship one file each).
  const auto jpeg = fileBytes(kModels + "/assimp/jeep1.jpg");
  const auto racing = fileBytes(kModels + "/kenney-racing/Textures/colormap.png");
  int jpegs = 0, palettes = 0;
  for (const auto& t : p.textures) {
    jpegs += t.bytes == jpeg;
    palettes += t.bytes == racing;
  }
  EXPECT_EQ(jpegs, 1);
  EXPECT_EQ(palettes, 1);

  const iconpack::Icon* jeep = find(p, "jeep");
  ASSERT_TRUE(jeep);
  EXPECT_TRUE(jeep->armed);
  ASSERT_EQ(jeep->dis.size(), 2u);
  EXPECT_EQ(jeep->dis[0].type.country, 225);
  EXPECT_EQ(jeep->dis[1].wild, 0x74);  // 1.1.*.6: country, subcategory, specific, extra
  // Hull alive, its rock component, the dead hull.
  ASSERT_EQ(jeep->parts.size(), 3u);
  EXPECT_EQ(jeep->parts[1].name, "rock");
  EXPECT_EQ(jeep->parts[1].parent, 0);
  EXPECT_FLOAT_EQ(jeep->parts[1].offset[1], 1.2f);
  EXPECT_EQ(jeep->parts[2].state, iconpack::State::dead);
  // The alive state's triangles at level 0: the jeep (2032) and the rock (768).
  EXPECT_EQ(iconpack::triangleCount(*jeep, 0), 2032u + 768u);
  EXPECT_EQ(iconpack::triangleCount(*jeep, 0, iconpack::State::dead), 768u);
  for (std::size_t l = 1; l < jeep->ranges.size(); ++l) {
    EXPECT_LE(iconpack::triangleCount(*jeep, l), iconpack::triangleCount(*jeep, l - 1));
  }
  // Bounds and cylinder against the vertices, offsets applied here.
  const auto verts = aliveVertices(*jeep);
  std::array<float, 6> box{INFINITY, INFINITY, INFINITY, -INFINITY, -INFINITY, -INFINITY};
  float radius = 0;
  for (const auto& v : verts) {
    for (int a = 0; a < 3; ++a) box[a] = std::min(box[a], v[a]), box[a + 3] = std::max(box[a + 3], v[a]);
    radius = std::max(radius, std::sqrt(v[0] * v[0] + v[2] * v[2]));
  }
  EXPECT_EQ(jeep->bounds, box);
  EXPECT_FLOAT_EQ(jeep->cylinderRadius, radius);
  EXPECT_FLOAT_EQ(jeep->cylinderHeight, box[4]);
  EXPECT_NEAR(box[5] - box[2], 16.646 * 0.3, 0.01);  // scale 0.3

  // Every icon reads back bit for bit.
  auto bytes = iconpack::encode(p);
  ASSERT_TRUE(bytes) << bytes.error();
  auto back = iconpack::decode(bytes.value(), "icons.pack");
  ASSERT_TRUE(back) << back.error();
  EXPECT_EQ(back.value(), p);
}

TEST(BuildPack, problemsNameTheDefinitionLine) {
  NEED_MODELS();
  const std::string text =
      "sandtable-icons 1\n"
      "icon good\n  model assimp/fels.3ds\n"
      "icon missing\n  model assimp/nothing-here.glb\n"
      "icon wreck\n  model assimp/fels.3ds\n  component t assimp/fels.3ds offset=0,1,0 state=dead\n";
  auto defs = parse(text);
  ASSERT_TRUE(defs) << defs.error();
  auto r = buildPack(defs.value());
  ASSERT_FALSE(r);
  ASSERT_EQ(r.problems().size(), 2u);
  EXPECT_EQ(r.problems()[0].file, "defs.txt");
  EXPECT_EQ(r.problems()[0].offset, text.find("icon missing"));
  EXPECT_NE(r.problems()[0].message.find("nothing-here.glb"), std::string::npos);
  EXPECT_NE(r.problems()[0].message.find("not found"), std::string::npos);
  EXPECT_EQ(r.problems()[1].offset, text.find("icon wreck"));
  EXPECT_NE(r.problems()[1].message.find("no 'dead FILE' line"), std::string::npos);
}

TEST(BuildPack, aFaceLimitInTheDefinitionRefusesTheModel) {
  NEED_MODELS();
  auto defs = parse("sandtable-icons 1\nicon w\n  model assimp/WusonOBJ.obj\n  max-triangles 1000\n");
  ASSERT_TRUE(defs);
  auto r = buildPack(defs.value());
  ASSERT_FALSE(r);
  EXPECT_NE(r.error().find("more than the limit of 1000"), std::string::npos) << r.error();
}

TEST(BuildPack, givenRangesStayAndAutomaticOnesFollowTheError) {
  NEED_MODELS();
  auto defs = parse("sandtable-icons 1\nicon w\n  model assimp/WusonOBJ.obj\n  lod 1 50\n  lod 0.5\n  lod 0.2\n");
  ASSERT_TRUE(defs);
  PackOptions coarse;
  coarse.pixelError = 4;
  auto fine = buildPack(defs.value()), rough = buildPack(defs.value(), coarse);
  ASSERT_TRUE(fine && rough);
  const iconpack::Icon& f = fine->icons[0];
  const iconpack::Icon& c = rough->icons[0];
  EXPECT_EQ(f.ranges[0], 50.0f);
  // Four times the pixel budget: the automatic ranges come four times closer.
  EXPECT_NEAR(c.ranges[2], f.ranges[2] / 4, f.ranges[2] * 1e-5);
  EXPECT_GT(f.ranges[1], f.ranges[0]);
  EXPECT_GT(f.ranges[2], f.ranges[1]);
}

}  // namespace
