// Mesh export: OBJ + MTL parsed back, glTF JSON structure (accessor counts,
// buffer length, bounds) and its buffer decoded, GLB chunks, orientation.
#include <gtest/gtest.h>

#include <unistd.h>

#include <cstring>
#include <filesystem>
#include <set>
#include <sstream>

#include "hand_modules.h"
#include "sandtable/formats/bytes.h"
#include "sandtable/formats/mesh_export.h"

namespace sandtable::mesh_export {
namespace {

namespace fs = std::filesystem;
using namespace module::handmade;

class MeshExport : public ::testing::Test {
 protected:
  void SetUp() override {
    dir_ = (fs::temp_directory_path() / ("st-mx." + std::to_string(::getpid()))).string();
    grid_ = writeGrid(dir_, 8, 9);
    header_.modulesX = 2;
    header_.modulesZ = 2;
    header_.levels = 3;
    header_.moduleSquares = 4;
    header_.moduleSize = 4 * kSpacing;
    table_ = table();
    west_ = buildModule(*grid_, header_, 0, 0);
    east_ = buildModule(*grid_, header_, 1, 0);
  }
  void TearDown() override {
    grid_.reset();
    fs::remove_all(dir_);
  }
  /// Modules (0,0) and (1,0) side by side.
  Mesh pair(std::uint32_t level, bool skirts = true) {
    Options o;
    o.level = level;
    o.skirts = skirts;
    o.materials = &table_;
    MeshBuilder b(o);
    EXPECT_EQ(b.add(west_, 0, 0).message(), "");
    EXPECT_EQ(b.add(east_, header_.moduleSize, 0).message(), "");
    return b.finish();
  }
  static std::size_t triangles(const module::Module& m, std::uint32_t level, bool skirts) {
    std::size_t n = 0;
    for (const auto& g : m.levels[level].groups) {
      if (skirts || g.half != module::Half::skirt) n += g.indexCount / 3;
    }
    return n;
  }

  std::string dir_;
  std::shared_ptr<const grid::GridFile> grid_;
  pack::IndexHeader header_;
  materials::Table table_;
  module::Module west_, east_;
};

struct ParsedObj {
  std::vector<std::array<double, 3>> v;
  std::size_t vt = 0;
  std::map<std::string, std::vector<std::array<std::size_t, 3>>> faces;  // by usemtl
  std::string mtllib;
};

ParsedObj parseObj(const std::string& text) {
  ParsedObj o;
  std::istringstream in(text);
  std::string line, current;
  while (std::getline(in, line)) {
    std::istringstream l(line);
    std::string tag;
    l >> tag;
    if (tag == "v") {
      std::array<double, 3> p{};
      l >> p[0] >> p[1] >> p[2];
      o.v.push_back(p);
    } else if (tag == "vt") {
      ++o.vt;
    } else if (tag == "usemtl") {
      l >> current;
    } else if (tag == "mtllib") {
      l >> o.mtllib;
    } else if (tag == "f") {
      std::array<std::size_t, 3> f{};
      for (auto& i : f) {
        std::string ref;
        l >> ref;
        const auto slash = ref.find('/');
        i = std::stoul(ref.substr(0, slash));
        EXPECT_EQ(ref.substr(slash + 1), ref.substr(0, slash)) << "v and vt indices agree";
      }
      std::string extra;
      EXPECT_FALSE(l >> extra) << "triangles only: " << line;
      o.faces[current].push_back(f);
    }
  }
  return o;
}

TEST_F(MeshExport, objHasEveryTriangleGroupedByMaterial) {
  const Mesh mesh = pair(0);
  const ParsedObj obj = parseObj(toObj(mesh, "pair.mtl", {"test"}));
  EXPECT_EQ(obj.mtllib, "pair.mtl");
  EXPECT_EQ(obj.v.size(), mesh.positions.size());
  EXPECT_EQ(obj.vt, obj.v.size());
  std::size_t faces = 0;
  for (const auto& [name, fs] : obj.faces) {
    faces += fs.size();
    for (const auto& f : fs) {
      for (std::size_t i : f) {
        EXPECT_GE(i, 1u);
        EXPECT_LE(i, obj.v.size());
      }
    }
  }
  EXPECT_EQ(faces, triangles(west_, 0, true) + triangles(east_, 0, true));
  EXPECT_EQ(faces, mesh.triangles());
  // Classes 0, 1 (skin), 2 (road) and the skirts; the skirts' class (3,
  // "rock") is not a part of its own.
  EXPECT_EQ(std::set<std::string>({"grass", "forest", "road", "skirt"}),
            [&] { std::set<std::string> s; for (auto& [n, f] : obj.faces) s.insert(n); return s; }());
  // Road: one triangle per module at level 0.
  EXPECT_EQ(obj.faces.at("road").size(), 2u);
  // 4 x 4 + 3 x 4 level-0 squares: forest is one upper piece per square,
  // grass the other upper piece and the lower triangle.
  EXPECT_EQ(obj.faces.at("forest").size(), 28u);
  EXPECT_EQ(obj.faces.at("grass").size(), 56u);
  // Part order: skin, decals, skirts last.
  ASSERT_EQ(mesh.parts.size(), 4u);
  EXPECT_EQ(mesh.parts[0].name, "grass");
  EXPECT_EQ(mesh.parts[1].name, "forest");
  EXPECT_EQ(mesh.parts[2].name, "road");
  EXPECT_EQ(mesh.parts[3].name, "skirt");
  EXPECT_TRUE(mesh.parts[3].skirt);
}

TEST_F(MeshExport, placesModulesSideBySideWithoutMirroring) {
  const Mesh mesh = pair(1);
  // West module x 0..120, east module (3 squares) 120..210; z 0..120 south.
  EXPECT_EQ(mesh.min[0], 0.0f);
  EXPECT_EQ(mesh.max[0], 210.0f);
  EXPECT_EQ(mesh.min[2], 0.0f);
  EXPECT_EQ(mesh.max[2], 120.0f);
  // Elevation of post (7, 4), the database's east edge, in the east module.
  bool found = false;
  for (const auto& p : mesh.positions) {
    if (p[0] == 210.0f && p[2] == 120.0f && p[1] == elevationAt(7, 4)) found = true;
  }
  EXPECT_TRUE(found);
  // Every skin and decal triangle faces up (+Y) in the exported right-handed
  // frame: counter-clockwise seen from above, glTF's front face.
  for (const Part& part : mesh.parts) {
    if (part.skirt) continue;
    for (std::size_t k = 0; k < part.indices.size(); k += 3) {
      const auto& a = mesh.positions[part.indices[k]];
      const auto& b = mesh.positions[part.indices[k + 1]];
      const auto& c = mesh.positions[part.indices[k + 2]];
      const double ux = b[0] - a[0], uz = b[2] - a[2], vx = c[0] - a[0], vz = c[2] - a[2];
      const double normalY = uz * vx - ux * vz;  // (b - a) x (c - a), y component
      EXPECT_GT(normalY, 0) << part.name << " triangle " << k / 3;
    }
  }
}

TEST_F(MeshExport, noSkirtsLeavesThemAndTheirVerticesOut) {
  const Mesh with = pair(2, true), without = pair(2, false);
  EXPECT_EQ(without.triangles(), triangles(west_, 2, false) + triangles(east_, 2, false));
  EXPECT_LT(without.positions.size(), with.positions.size());
  for (const Part& p : without.parts) EXPECT_NE(p.name, "skirt");
}

TEST_F(MeshExport, mtlHasOneMaterialPerPart) {
  const std::string mtl = toMtl(pair(0));
  EXPECT_NE(mtl.find("newmtl grass\nKa 0.000000 0.000000 0.000000\nKd 0.333333 0.666667 0.200000\n"),
            std::string::npos)
      << mtl;
  EXPECT_NE(mtl.find("newmtl skirt\n"), std::string::npos);
  std::size_t n = 0;
  for (std::size_t p = mtl.find("newmtl "); p != std::string::npos; p = mtl.find("newmtl ", p + 1)) ++n;
  EXPECT_EQ(n, 4u);
}

TEST_F(MeshExport, unknownClassesAndNamesAreMadeSafe) {
  materials::Table t = table_;
  t.classes[0].name = "tall grass";
  t.classes[1].name = "skirt";
  t.classes.erase(t.classes.begin() + 2);  // no road class
  Options o;
  o.materials = &t;
  MeshBuilder b(o);
  ASSERT_EQ(b.add(west_, 0, 0).message(), "");
  const Mesh m = b.finish();
  ASSERT_EQ(m.parts.size(), 4u);
  EXPECT_EQ(m.parts[0].name, "tall_grass");
  EXPECT_EQ(m.parts[1].name, "skirt_1");
  EXPECT_EQ(m.parts[2].name, "class_2");
  EXPECT_EQ(m.parts[2].rgb, kUnknownRgb);
  EXPECT_EQ(m.parts[3].name, "skirt");
}

TEST_F(MeshExport, levelOutOfRangeIsAnError) {
  Options o;
  o.level = 3;
  MeshBuilder b(o);
  EXPECT_EQ(b.add(west_, 0, 0).message(), "export: module (0,0) has 3 levels; there is no level 3");
}

std::vector<std::byte> unbase64(const std::string& s) {
  auto val = [](char c) -> int {
    if (c >= 'A' && c <= 'Z') return c - 'A';
    if (c >= 'a' && c <= 'z') return c - 'a' + 26;
    if (c >= '0' && c <= '9') return c - '0' + 52;
    return c == '+' ? 62 : c == '/' ? 63 : -1;
  };
  std::vector<std::byte> out;
  std::uint32_t acc = 0;
  int bits = 0;
  for (char c : s) {
    const int v = val(c);
    if (v < 0) break;
    acc = acc << 6 | std::uint32_t(v);
    bits += 6;
    if (bits >= 8) {
      bits -= 8;
      out.push_back(std::byte((acc >> bits) & 0xff));
    }
  }
  return out;
}

TEST_F(MeshExport, base64MatchesRfc4648) {
  auto b = [](const std::string& s) {
    std::vector<std::byte> v(s.size());
    if (!s.empty()) std::memcpy(v.data(), s.data(), s.size());
    return base64(v);
  };
  EXPECT_EQ(b(""), "");
  EXPECT_EQ(b("f"), "Zg==");
  EXPECT_EQ(b("fo"), "Zm8=");
  EXPECT_EQ(b("foo"), "Zm9v");
  EXPECT_EQ(b("foobar"), "Zm9vYmFy");
}

/// Checks a glTF document against its binary buffer: structure, counts,
/// byte lengths, bounds; returns the decoded triangles.
std::size_t checkGltf(const nlohmann::json& doc, const std::vector<std::byte>& bin, const Mesh& mesh) {
  EXPECT_EQ(doc["asset"]["version"], "2.0");
  EXPECT_EQ(doc["buffers"].size(), 1u);
  EXPECT_EQ(doc["buffers"][0]["byteLength"].get<std::size_t>(), bin.size());
  const auto& acc = doc["accessors"];
  const auto& views = doc["bufferViews"];
  const std::size_t n = mesh.positions.size();
  EXPECT_EQ(acc[0]["count"].get<std::size_t>(), n);
  EXPECT_EQ(acc[0]["type"], "VEC3");
  EXPECT_EQ(acc[0]["componentType"], 5126);
  EXPECT_EQ(acc[1]["count"].get<std::size_t>(), n);
  for (int k = 0; k < 3; ++k) {
    EXPECT_EQ(acc[0]["min"][k].get<float>(), mesh.min[std::size_t(k)]);
    EXPECT_EQ(acc[0]["max"][k].get<float>(), mesh.max[std::size_t(k)]);
  }
  std::size_t viewBytes = 0;
  for (const auto& v : views) {
    EXPECT_LE(v["byteOffset"].get<std::size_t>() + v["byteLength"].get<std::size_t>(), bin.size());
    viewBytes += v["byteLength"].get<std::size_t>();
  }
  EXPECT_EQ(viewBytes, bin.size());
  // Recompute bounds from the buffer.
  std::array<float, 3> mn{INFINITY, INFINITY, INFINITY}, mx{-INFINITY, -INFINITY, -INFINITY};
  for (std::size_t i = 0; i < n; ++i) {
    float p[3];
    std::memcpy(p, bin.data() + 12 * i, 12);
    for (int k = 0; k < 3; ++k) mn[std::size_t(k)] = std::min(mn[std::size_t(k)], p[k]), mx[std::size_t(k)] = std::max(mx[std::size_t(k)], p[k]);
  }
  EXPECT_EQ(mn, mesh.min);
  EXPECT_EQ(mx, mesh.max);
  const auto& prims = doc["meshes"][0]["primitives"];
  EXPECT_EQ(prims.size(), mesh.parts.size());
  EXPECT_EQ(doc["materials"].size(), mesh.parts.size());
  std::size_t tris = 0;
  for (std::size_t p = 0; p < prims.size(); ++p) {
    const auto& a = acc[prims[p]["indices"].get<std::size_t>()];
    EXPECT_EQ(a["componentType"], 5125);
    EXPECT_EQ(a["count"].get<std::size_t>() % 3, 0u);
    EXPECT_EQ(a["count"].get<std::size_t>(), mesh.parts[p].indices.size());
    EXPECT_EQ(doc["materials"][prims[p]["material"].get<std::size_t>()]["name"], mesh.parts[p].name);
    const auto& view = views[a["bufferView"].get<std::size_t>()];
    const std::size_t base = view["byteOffset"].get<std::size_t>() + a["byteOffset"].get<std::size_t>();
    EXPECT_LE(a["byteOffset"].get<std::size_t>() + 4 * a["count"].get<std::size_t>(), view["byteLength"].get<std::size_t>());
    for (std::size_t k = 0; k < a["count"].get<std::size_t>(); ++k) {
      std::uint32_t i;
      std::memcpy(&i, bin.data() + base + 4 * k, 4);
      EXPECT_LT(i, n);
      EXPECT_EQ(i, mesh.parts[p].indices[k]);
    }
    tris += a["count"].get<std::size_t>() / 3;
  }
  return tris;
}

TEST_F(MeshExport, gltfEmbedsAConsistentBuffer) {
  const Mesh mesh = pair(0);
  const nlohmann::json extras = {{"sandtable", {{"level", 0}}}};
  const auto doc = nlohmann::json::parse(toGltf(mesh, extras));
  const std::string uri = doc["buffers"][0]["uri"];
  const std::string prefix = "data:application/octet-stream;base64,";
  ASSERT_EQ(uri.rfind(prefix, 0), 0u);
  const auto bin = unbase64(uri.substr(prefix.size()));
  EXPECT_EQ(checkGltf(doc, bin, mesh), mesh.triangles());
  EXPECT_EQ(doc["asset"]["extras"]["sandtable"]["level"], 0);
  EXPECT_EQ(doc["materials"][3]["doubleSided"], true);
  EXPECT_EQ(doc["materials"][0]["doubleSided"], false);
  // grass 0x55aa33 as linear factors
  EXPECT_NEAR(doc["materials"][0]["pbrMetallicRoughness"]["baseColorFactor"][0].get<double>(), srgbToLinear(0x55), 1e-12);
  EXPECT_NEAR(srgbToLinear(255), 1.0, 1e-12);
  EXPECT_NEAR(srgbToLinear(0x80), 0.2158605, 1e-6);
}

TEST_F(MeshExport, glbHasHeaderJsonAndBinChunks) {
  const Mesh mesh = pair(1);
  const auto glb = toGlb(mesh, nullptr);
  ASSERT_GE(glb.size(), 28u);
  EXPECT_EQ(loadLE<std::uint32_t>(glb.data()), 0x46546C67u);
  EXPECT_EQ(loadLE<std::uint32_t>(glb.data() + 4), 2u);
  EXPECT_EQ(loadLE<std::uint32_t>(glb.data() + 8), glb.size());
  const std::uint32_t jsonLen = loadLE<std::uint32_t>(glb.data() + 12);
  EXPECT_EQ(jsonLen % 4, 0u);
  EXPECT_EQ(loadLE<std::uint32_t>(glb.data() + 16), 0x4E4F534Au);
  const std::string json(reinterpret_cast<const char*>(glb.data() + 20), jsonLen);
  const auto doc = nlohmann::json::parse(json);
  EXPECT_FALSE(doc["buffers"][0].contains("uri"));
  const std::byte* c = glb.data() + 20 + jsonLen;
  const std::uint32_t binLen = loadLE<std::uint32_t>(c);
  EXPECT_EQ(binLen % 4, 0u);
  EXPECT_EQ(loadLE<std::uint32_t>(c + 4), 0x004E4942u);
  EXPECT_EQ(20 + jsonLen + 8 + binLen, glb.size());
  const std::size_t byteLength = doc["buffers"][0]["byteLength"];
  ASSERT_LE(byteLength, binLen);
  const std::vector<std::byte> bin(c + 8, c + 8 + byteLength);
  EXPECT_EQ(checkGltf(doc, bin, mesh), mesh.triangles());
  EXPECT_FALSE(doc["asset"].contains("extras"));
}

}  // namespace
}  // namespace sandtable::mesh_export
