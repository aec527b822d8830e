// Object export: an icon's mesh with its part offsets, materials and
// texture; objects instanced (EXT_mesh_gpu_instancing accessors decoded
// from the buffer and applied by the extension's own rule, T * R * S) and
// flattened, both against placements worked out by hand from the heading
// convention (clockwise from north seen from above).
#include <gtest/gtest.h>

#include <cmath>
#include <cstring>

#include "sandtable/formats/object_export.h"

namespace sandtable::mesh_export {
namespace {

/// An icon of one triangle whose first corner is 1 m north of its origin,
/// raised 0.5 m by a component offset, in one textured red material.
iconpack::Pack pack() {
  iconpack::Pack p;
  const unsigned char png[8] = {0x89, 'P', 'N', 'G', '\r', '\n', 0x1a, '\n'};
  p.textures.push_back({"dot.png", {}});
  for (unsigned char c : png) p.textures[0].bytes.push_back(std::byte{c});
  iconpack::Icon icon;
  icon.name = "marker";
  icon.materials.push_back({{255, 0, 0, 255}, 0});
  icon.ranges = {100, 400};
  iconpack::Part hull;
  iconpack::Mesh m;
  m.positions = {0, 0, -1, 0.5f, 0, 0, 0, 2, 0};
  m.normals = {0, 1, 0, 0, 1, 0, 0, 1, 0};
  m.texcoords = {0, 0, 1, 0.25f, 0, 1};
  m.levels = {{0, 1, 2}, {0, 1, 2}};
  hull.meshes.push_back(m);
  hull.offset = {0, 0.5f, 0};
  icon.parts.push_back(hull);
  p.icons.push_back(icon);
  return p;
}

module::Module moduleWithObjects() {
  module::Module m;
  m.kx = 2;
  m.kz = 3;
  m.levels.resize(2);
  // Heading 90 degrees (east), scale 2; heading 0, scale 1.
  m.objects.push_back({0, module::kObjectClassExplicit, 10, 20, module::headingCode(M_PI / 2), 2.0f, 1, 4});
  m.objects.push_back({0, module::kObjectClassExplicit, 30, 40, 0, 1.0f, 1, 2});
  m.levels[0].objectY = {100, 200};
  m.levels[1].objectY = {101, 201};
  return m;
}

template <std::size_t N>
std::vector<std::array<float, N>> readAccessor(const nlohmann::json& doc, const std::vector<std::byte>& bin,
                                               std::size_t accessor) {
  const auto& a = doc["accessors"][accessor];
  const auto& v = doc["bufferViews"][a["bufferView"].get<std::size_t>()];
  EXPECT_EQ(a["componentType"], 5126);
  const std::size_t count = a["count"], at = v["byteOffset"].get<std::size_t>() + a.value("byteOffset", 0);
  EXPECT_LE(at + count * N * 4, bin.size());
  std::vector<std::array<float, N>> out(count);
  std::memcpy(out.data(), bin.data() + at, count * N * 4);
  return out;
}

/// q v q* for a unit quaternion (x, y, z, w).
std::array<double, 3> rotate(const std::array<float, 4>& q, const std::array<double, 3>& v) {
  const double x = q[0], y = q[1], z = q[2], w = q[3];
  const double tx = 2 * (y * v[2] - z * v[1]), ty = 2 * (z * v[0] - x * v[2]), tz = 2 * (x * v[1] - y * v[0]);
  return {v[0] + w * tx + (y * tz - z * ty), v[1] + w * ty + (z * tx - x * tz), v[2] + w * tz + (x * ty - y * tx)};
}

TEST(ObjectExport, anIconMeshKeepsItsOffsetsColourAndTexture) {
  const iconpack::Pack p = pack();
  std::vector<Texture> textures;
  std::vector<std::int32_t> map;
  const Mesh m = iconMesh(p, 0, 0, textures, map);
  ASSERT_EQ(m.positions.size(), 3u);
  EXPECT_EQ(m.positions[0], (std::array<float, 3>{0, 0.5f, -1}));  // the part's offset applied
  EXPECT_EQ(m.positions[2], (std::array<float, 3>{0, 2.5f, 0}));
  EXPECT_EQ(m.texcoords[1], (std::array<float, 2>{1, 0.75f}));     // t flipped to glTF's origin
  ASSERT_EQ(m.parts.size(), 1u);
  EXPECT_EQ(m.parts[0].rgb, 0xFF0000u);
  EXPECT_EQ(m.parts[0].texture, 0);
  ASSERT_EQ(textures.size(), 1u);
  EXPECT_EQ(textures[0].mimeType, "image/png");
  EXPECT_EQ(m.min, (std::array<float, 3>{0, 0.5f, -1}));
  EXPECT_EQ(m.max, (std::array<float, 3>{0.5f, 2.5f, 0}));
  // A second icon mesh reuses the texture already added.
  const Mesh again = iconMesh(p, 0, 1, textures, map);
  EXPECT_EQ(textures.size(), 1u);
  EXPECT_EQ(again.parts[0].texture, 0);
}

TEST(ObjectExport, instancesStandOnTheExportedLevelTurnedClockwiseFromNorth) {
  const iconpack::Pack p = pack();
  ObjectCollector c(p, 1, 0);
  ASSERT_TRUE(c.add(moduleWithObjects(), 1000, 2000).ok());
  EXPECT_EQ(c.objects(), 2u);
  const GltfExtras more = c.instanced();
  ASSERT_EQ(more.instanced.size(), 1u);
  Mesh terrain;
  terrain.positions = {{0, 0, 0}, {1, 0, 0}, {0, 0, 1}};
  terrain.texcoords.resize(3);
  terrain.parts.push_back({"ground", 0x808080, false, kNoTexture, {0, 2, 1}});
  terrain.updateBounds();
  const auto [doc, bin] = gltfDocument(terrain, nullptr, false, more);
  EXPECT_EQ(doc["extensionsUsed"][0], "EXT_mesh_gpu_instancing");
  EXPECT_EQ(doc["extensionsRequired"][0], "EXT_mesh_gpu_instancing");
  ASSERT_EQ(doc["nodes"].size(), 2u);
  EXPECT_EQ(doc["scenes"][0]["nodes"], nlohmann::json::array({0, 1}));
  const auto& node = doc["nodes"][1];
  EXPECT_EQ(node["name"], "marker");
  const auto& attr = node["extensions"]["EXT_mesh_gpu_instancing"]["attributes"];
  const auto t = readAccessor<3>(doc, bin, attr["TRANSLATION"]);
  const auto r = readAccessor<4>(doc, bin, attr["ROTATION"]);
  const auto s = readAccessor<3>(doc, bin, attr["SCALE"]);
  ASSERT_EQ(t.size(), 2u);
  // Level 1's elevations, the module's corner added.
  EXPECT_EQ(t[0], (std::array<float, 3>{1010, 101, 2020}));
  EXPECT_EQ(t[1], (std::array<float, 3>{1030, 201, 2040}));
  EXPECT_EQ(s[0], (std::array<float, 3>{2, 2, 2}));
  // The corner 1 m north of the origin, headed east and scaled 2: 2 m east.
  const auto mesh = readAccessor<3>(doc, bin, doc["meshes"][1]["primitives"][0]["attributes"]["POSITION"]);
  const std::array<double, 3> scaled{mesh[0][0] * s[0][0], mesh[0][1] * s[0][1], mesh[0][2] * s[0][2]};
  const auto turned = rotate(r[0], scaled);
  EXPECT_NEAR(turned[0], 2.0, 1e-4);
  EXPECT_NEAR(turned[1], 1.0, 1e-6);  // the 0.5 m offset, scaled
  EXPECT_NEAR(turned[2], 0.0, 1e-4);
  const auto still = rotate(r[1], {0, 0, -1});
  EXPECT_NEAR(still[2], -1.0, 1e-6);
  // The texture is an image in the buffer, the material refers to it.
  ASSERT_EQ(doc["images"].size(), 1u);
  EXPECT_EQ(doc["images"][0]["mimeType"], "image/png");
  const auto& mat = doc["materials"][doc["meshes"][1]["primitives"][0]["material"].get<std::size_t>()];
  EXPECT_EQ(mat["pbrMetallicRoughness"]["baseColorTexture"]["index"], 0);
  const auto& view = doc["bufferViews"][doc["images"][0]["bufferView"].get<std::size_t>()];
  EXPECT_EQ(view["byteLength"], 8);
  EXPECT_EQ(std::memcmp(bin.data() + view["byteOffset"].get<std::size_t>(), p.textures[0].bytes.data(), 8), 0);
}

TEST(ObjectExport, flattenedObjectsAreTheIconsMovedIntoPlace) {
  const iconpack::Pack p = pack();
  ObjectCollector c(p, 0, 0);
  ASSERT_TRUE(c.add(moduleWithObjects(), 0, 0).ok());
  Mesh mesh;
  std::vector<Texture> textures;
  c.flattenInto(mesh, textures);
  ASSERT_EQ(mesh.positions.size(), 6u);
  EXPECT_EQ(mesh.triangles(), 2u);
  ASSERT_EQ(mesh.parts.size(), 1u);
  // Object 0: base (10, 100, 20), east-facing, scale 2: the north corner
  // goes 2 m east, the raised corner 5 m up.
  EXPECT_NEAR(mesh.positions[0][0], 12, 1e-4);
  EXPECT_NEAR(mesh.positions[0][1], 101, 1e-4);
  EXPECT_NEAR(mesh.positions[0][2], 20, 1e-4);
  EXPECT_NEAR(mesh.positions[2][1], 105, 1e-4);
  // Its east corner (0.5, 0, 0) turns to the south: +z.
  EXPECT_NEAR(mesh.positions[1][0], 10, 1e-4);
  EXPECT_NEAR(mesh.positions[1][2], 21, 1e-4);
  // Object 1: heading 0, scale 1, base (30, 200, 40).
  EXPECT_NEAR(mesh.positions[3][0], 30, 1e-5);
  EXPECT_NEAR(mesh.positions[3][2], 39, 1e-5);
  EXPECT_EQ(mesh.parts[0].indices, (std::vector<std::uint32_t>{0, 1, 2, 3, 4, 5}));
  EXPECT_EQ(textures.size(), 1u);
}

TEST(ObjectExport, anObjectOfAnIconNotInThePackIsAnError) {
  const iconpack::Pack p = pack();
  module::Module m = moduleWithObjects();
  m.objects[1].icon = 7;
  ObjectCollector c(p, 0, 0);
  const Status st = c.add(m, 0, 0);
  EXPECT_FALSE(st.ok());
  EXPECT_NE(st.message().find("icon 7, but icons.pack has 1 icons"), std::string::npos) << st.message();
  ObjectCollector missing(p, 5, 0);
  EXPECT_NE(missing.add(moduleWithObjects(), 0, 0).message().find("no object elevations for level 5"),
            std::string::npos);
}

TEST(ObjectExport, imageTypesAreKnownByTheirMagic) {
  EXPECT_EQ(imageMimeType({std::byte{0xff}, std::byte{0xd8}, std::byte{0xff}, std::byte{0xe0}}), "image/jpeg");
  EXPECT_EQ(imageMimeType({std::byte{'G'}, std::byte{'I'}, std::byte{'F'}}), "");
  EXPECT_EQ(imageMimeType({}), "");
}

}  // namespace
}  // namespace sandtable::mesh_export
