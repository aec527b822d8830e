// Model import on the real models in ../shared/data/models, checked against
// counts and bounds read from the files without assimp: the glTF JSON and
// binary chunk, the OBJ and OFF lines, the 3DS chunks.
#include <gtest/gtest.h>
#include <sys/stat.h>

#include <nlohmann/json.hpp>

#include <array>
#include <cmath>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <map>
#include <set>
#include <sstream>

#include "sandtable/icons/model.h"
#include "sandtable/testing/require.h"

namespace fs = std::filesystem;
using namespace sandtable;
using namespace sandtable::icons;

namespace {

const std::string kModels = std::string(SANDTABLE_SOURCE_DIR) + "/../shared/data/models";

#define NEED_MODELS() SANDTABLE_REQUIRE(fs::exists(kModels), "the models of ../shared/data at " << kModels)

std::string slurp(const std::string& p) {
  std::ifstream f(p, std::ios::binary);
  return std::string(std::istreambuf_iterator<char>(f), {});
}

/// What a file says of itself, read without assimp.
struct Facts {
  std::size_t triangles = 0;
  std::size_t vertices = 0;  ///< distinct vertices (every attribute equal), 0 = not known
  std::array<double, 3> min{INFINITY, INFINITY, INFINITY}, max{-INFINITY, -INFINITY, -INFINITY};
  void grow(double x, double y, double z) {
    const double p[3] = {x, y, z};
    for (int a = 0; a < 3; ++a) min[a] = std::min(min[a], p[a]), max[a] = std::max(max[a], p[a]);
  }
};

std::uint32_t u32(const std::string& b, std::size_t at) {
  std::uint32_t v;
  std::memcpy(&v, b.data() + at, 4);
  return v;
}

/// glTF binary: per primitive, the index count / 3, the distinct tuples of
/// position, normal and texture coordinate, and the POSITION accessor's min and max moved by
/// the node's translation (the test refuses rotated or scaled nodes).
Facts glbFacts(const std::string& path) {
  const std::string b = slurp(path);
  const std::uint32_t jsonLen = u32(b, 12);
  const auto j = nlohmann::json::parse(b.substr(20, jsonLen));
  const std::size_t bin = 20 + jsonLen + 8;
  Facts f;
  auto accessorFloats = [&](int k) {
    const auto& a = j["accessors"][k];
    const auto& v = j["bufferViews"][a["bufferView"].get<int>()];
    const int comps = std::map<std::string, int>{{"SCALAR", 1}, {"VEC2", 2}, {"VEC3", 3}, {"VEC4", 4}}[a["type"]];
    EXPECT_EQ(a["componentType"], 5126) << path;  // float
    const std::size_t stride = v.value("byteStride", comps * 4);
    const std::size_t at = bin + v.value("byteOffset", 0) + a.value("byteOffset", 0);
    std::vector<std::vector<float>> out(a["count"].get<std::size_t>(), std::vector<float>(std::size_t(comps)));
    for (std::size_t e = 0; e < out.size(); ++e) std::memcpy(out[e].data(), b.data() + at + e * stride, 4 * comps);
    return out;
  };
  std::function<void(int, std::array<double, 3>)> visit = [&](int n, std::array<double, 3> t) {
    const auto& node = j["nodes"][n];
    EXPECT_FALSE(node.contains("rotation") || node.contains("scale") || node.contains("matrix")) << path;
    if (node.contains("translation")) {
      for (int a = 0; a < 3; ++a) t[a] += node["translation"][a].get<double>();
    }
    if (node.contains("mesh")) {
      for (const auto& p : j["meshes"][node["mesh"].get<int>()]["primitives"]) {
        EXPECT_EQ(p.value("mode", 4), 4) << path;
        const auto& pos = j["accessors"][p["attributes"]["POSITION"].get<int>()];
        f.triangles += (p.contains("indices") ? j["accessors"][p["indices"].get<int>()]["count"] : pos["count"])
                           .get<std::size_t>() / 3;
        f.grow(pos["min"][0].get<double>() + t[0], pos["min"][1].get<double>() + t[1], pos["min"][2].get<double>() + t[2]);
        f.grow(pos["max"][0].get<double>() + t[0], pos["max"][1].get<double>() + t[1], pos["max"][2].get<double>() + t[2]);
        std::vector<std::vector<std::vector<float>>> attrs;
        // What an icon vertex keeps; tangents and colours are dropped.
        for (const char* name : {"POSITION", "NORMAL", "TEXCOORD_0"}) {
          if (p["attributes"].contains(name)) attrs.push_back(accessorFloats(p["attributes"][name].get<int>()));
        }
        std::set<std::vector<float>> distinct;
        for (std::size_t e = 0; e < attrs[0].size(); ++e) {
          std::vector<float> tuple;
          for (const auto& a : attrs) tuple.insert(tuple.end(), a[e].begin(), a[e].end());
          distinct.insert(tuple);
        }
        f.vertices += distinct.size();
      }
    }
    for (const auto& c : node.value("children", nlohmann::json::array())) visit(c.get<int>(), t);
  };
  for (const auto& n : j["scenes"][j.value("scene", 0)]["nodes"]) visit(n.get<int>(), {0, 0, 0});
  return f;
}

/// OBJ or OFF: polygons of n corners make n - 2 triangles; vertices are
/// the distinct corner tuples (v/vt/vn in OBJ, positions in OFF); bounds
/// over the positions that faces use.
Facts polygonFacts(const std::string& path, bool off) {
  std::istringstream in(slurp(path));
  std::vector<std::array<double, 3>> v;
  std::vector<std::string> vt, vn;
  std::set<std::string> corners;
  Facts f;
  std::string line;
  auto corner = [&](std::size_t k) { f.grow(v[k][0], v[k][1], v[k][2]); };
  if (off) {
    std::getline(in, line);  // OFF
    std::size_t nv = 0, nf = 0, ne = 0;
    in >> nv >> nf >> ne;
    v.resize(nv);
    for (auto& p : v) in >> p[0] >> p[1] >> p[2];
    std::set<std::array<double, 3>> used;
    for (std::size_t k = 0; k < nf; ++k) {
      std::size_t n = 0;
      in >> n;
      for (std::size_t c = 0; c < n; ++c) {
        std::size_t i = 0;
        in >> i;
        used.insert(v[i]);
        corner(i);
      }
      f.triangles += n - 2;
    }
    f.vertices = used.size();
    return f;
  }
  while (std::getline(in, line)) {
    std::istringstream l(line);
    std::string tag;
    l >> tag;
    if (tag == "v") {
      std::array<double, 3> p{};
      l >> p[0] >> p[1] >> p[2];
      v.push_back(p);
    } else if (tag == "vt" || tag == "vn") {
      std::string rest;
      std::getline(l, rest);
      (tag == "vt" ? vt : vn).push_back(rest);
    } else if (tag == "f") {
      std::string c;
      std::size_t n = 0;
      while (l >> c) {
        std::size_t a = 0, b = 0, d = 0;
        std::sscanf(c.c_str(), "%zu/%zu/%zu", &a, &b, &d);
        std::ostringstream key;
        key << v[a - 1][0] << ' ' << v[a - 1][1] << ' ' << v[a - 1][2] << '|' << (b ? vt[b - 1] : "") << '|'
            << (d ? vn[d - 1] : "");
        corners.insert(key.str());
        corner(a - 1);
        ++n;
      }
      f.triangles += n - 2;
    }
  }
  f.vertices = corners.size();
  return f;
}

/// 3DS: the face lists' counts (chunk 0x4120, triangles) and the bounds of
/// the vertex lists (chunk 0x4110, world coordinates in 3DS, Z up), turned
/// to Y up as assimp's 3DS importer does: (x, y, z) -> (x, z, -y).
Facts tdsFacts(const std::string& path) {
  const std::string b = slurp(path);
  Facts f;
  std::function<void(std::size_t, std::size_t)> walk = [&](std::size_t at, std::size_t end) {
    while (at + 6 <= end) {
      std::uint16_t id;
      std::memcpy(&id, b.data() + at, 2);
      const std::uint32_t len = u32(b, at + 2);
      if (len < 6 || at + len > end) return;
      std::size_t body = at + 6;
      if (id == 0x4D4D || id == 0x3D3D || id == 0x4100) walk(body, at + len);
      if (id == 0x4000) {  // object: a name, then chunks
        while (b[body] != '\0') ++body;
        walk(body + 1, at + len);
      }
      if (id == 0x4110) {
        std::uint16_t n;
        std::memcpy(&n, b.data() + body, 2);
        for (std::uint16_t k = 0; k < n; ++k) {
          float p[3];
          std::memcpy(p, b.data() + body + 2 + 12 * k, 12);
          f.grow(p[0], p[1], p[2]);
        }
      }
      if (id == 0x4120) {
        std::uint16_t n;
        std::memcpy(&n, b.data() + body, 2);
        f.triangles += n;
      }
      at += len;
    }
  };
  walk(0, b.size());
  Facts up = f;
  up.min = {f.min[0], f.min[2], -f.max[1]};
  up.max = {f.max[0], f.max[2], -f.min[1]};
  return up;
}

void expectBounds(const Model& m, const Facts& f, double tol) {
  for (int a = 0; a < 3; ++a) {
    EXPECT_NEAR(m.bounds.min[a], f.min[a], tol) << m.source << " axis " << a;
    EXPECT_NEAR(m.bounds.max[a], f.max[a], tol) << m.source << " axis " << a;
  }
}

class Kenney : public ::testing::TestWithParam<const char*> {};

TEST_P(Kenney, importsWithTheCountsBoundsAndTextureOfTheFile) {
  NEED_MODELS();
  const std::string path = kModels + "/" + GetParam();
  auto r = importModel(path);
  ASSERT_TRUE(r) << r.error();
  EXPECT_TRUE(r.warnings().empty()) << r.warnings().front().str();
  const Facts f = glbFacts(path);
  EXPECT_EQ(r->triangleCount(), f.triangles);
  EXPECT_EQ(r->vertexCount(), f.vertices);
  expectBounds(r.value(), f, 1e-5);
  ASSERT_FALSE(r->materials.empty());
  bool textured = false;
  for (const Material& m : r->materials) {
    if (m.texture.empty()) continue;
    textured = true;
    EXPECT_EQ(fs::path(m.texturePath).filename(), "colormap.png") << m.texture;
    EXPECT_TRUE(fs::exists(m.texturePath));
  }
  EXPECT_TRUE(textured);
  for (const Mesh& m : r->meshes) {
    EXPECT_EQ(m.texcoords.size(), 2 * m.vertexCount());
    for (std::uint32_t i : m.indices) ASSERT_LT(i, m.vertexCount());
  }
}

INSTANTIATE_TEST_SUITE_P(Models, Kenney,
                         ::testing::Values("kenney-city/building-garage.glb", "kenney-city/building-small-a.glb",
                                           "kenney-city/grass-trees-tall.glb", "kenney-racing/decoration-forest.glb",
                                           "kenney-racing/vehicle-motorcycle.glb",
                                           "kenney-racing/vehicle-truck-red.glb"));

TEST(Import, offAndObjWusonHaveTheirFilesCounts) {
  NEED_MODELS();
  for (const bool off : {true, false}) {
    const std::string path = kModels + (off ? "/assimp/Wuson.off" : "/assimp/WusonOBJ.obj");
    auto r = importModel(path);
    ASSERT_TRUE(r) << r.error();
    const Facts f = polygonFacts(path, off);
    EXPECT_EQ(r->triangleCount(), f.triangles) << path;
    EXPECT_EQ(r->vertexCount(), f.vertices) << path;
    expectBounds(r.value(), f, 1e-5);
  }
}

TEST(Import, threeDsModelsHaveTheirFacesAndTheJeepItsTexture) {
  NEED_MODELS();
  for (const char* name : {"/assimp/fels.3ds", "/assimp/jeep1.3ds"}) {
    const std::string path = kModels + name;
    auto r = importModel(path);
    ASSERT_TRUE(r) << r.error();
    const Facts f = tdsFacts(path);
    EXPECT_EQ(r->triangleCount(), f.triangles) << path;
    expectBounds(r.value(), f, 1e-3);
  }
  auto jeep = importModel(kModels + "/assimp/jeep1.3ds");
  ASSERT_TRUE(jeep);
  bool found = false;
  for (const Material& m : jeep->materials) found |= fs::path(m.texturePath).filename() == "jeep1.jpg";
  EXPECT_TRUE(found);
}

TEST(Import, zUpAndScaleAreApplied) {
  NEED_MODELS();
  const std::string path = kModels + "/assimp/fels.3ds";
  ImportOptions y;
  y.up = UpAxis::kY;
  ImportOptions z = y;
  z.up = UpAxis::kZ;
  z.scale = 2;
  auto a = importModel(path, y), b = importModel(path, z);
  ASSERT_TRUE(a && b);
  // Z up to Y up: y' = z, z' = -y.
  EXPECT_NEAR(b->bounds.min[1], 2 * a->bounds.min[2], 1e-3);
  EXPECT_NEAR(b->bounds.max[1], 2 * a->bounds.max[2], 1e-3);
  EXPECT_NEAR(b->bounds.min[2], -2 * a->bounds.max[1], 1e-3);
  EXPECT_NEAR(b->bounds.max[0], 2 * a->bounds.max[0], 1e-3);
}

/// A scratch folder removed at the end of a test.
struct Scratch {
  fs::path dir = fs::temp_directory_path() / ("sandtable-icons-" + std::to_string(::getpid()) + "-" +
                                              ::testing::UnitTest::GetInstance()->current_test_info()->name());
  Scratch() { fs::create_directories(dir); }
  ~Scratch() { fs::remove_all(dir); }
  std::string write(const std::string& name, const std::string& bytes) const {
    std::ofstream(dir / name, std::ios::binary) << bytes;
    return (dir / name).string();
  }
};

void expectRefused(const Result<Model>& r, const std::string& path, const std::string& words) {
  ASSERT_FALSE(r);
  EXPECT_EQ(r.problems().front().file, path);
  EXPECT_NE(r.error().find(words), std::string::npos) << r.error();
}

TEST(Import, aTruncatedGltfIsRefusedNamingTheFile) {
  NEED_MODELS();
  Scratch s;
  const std::string whole = slurp(kModels + "/kenney-city/building-garage.glb");
  for (const std::size_t n : {std::size_t(0), std::size_t(11), std::size_t(300), whole.size() / 2}) {
    const std::string p = s.write("cut.glb", whole.substr(0, n));
    expectRefused(importModel(p), p, "icons:");
  }
}

TEST(Import, noFacesNanVerticesAndTooManyTrianglesAreRefused) {
  Scratch s;
  const std::string points = s.write("points.obj", "v 0 0 0\nv 1 0 0\nv 0 1 0\n");
  expectRefused(importModel(points), points, "icons:");
  const std::string nan = s.write("nan.off", "OFF\n3 1 0\n0 0 0\nnan 0 0\n0 1 0\n3 0 1 2\n");
  expectRefused(importModel(nan), nan, "not a finite number");
  std::string grid = "";
  for (int k = 0; k < 50; ++k) grid += "v " + std::to_string(k) + " 0 0\nv " + std::to_string(k) + " 0 1\n";
  for (int k = 1; k < 50; ++k) {
    grid += "f " + std::to_string(2 * k - 1) + " " + std::to_string(2 * k + 1) + " " + std::to_string(2 * k) + "\n";
    grid += "f " + std::to_string(2 * k) + " " + std::to_string(2 * k + 1) + " " + std::to_string(2 * k + 2) + "\n";
  }
  const std::string big = s.write("big.obj", grid);
  ImportOptions o;
  o.maxTriangles = 97;
  expectRefused(importModel(big, o), big, "ImportOptions::maxTriangles");
  o.maxTriangles = 98;
  EXPECT_TRUE(importModel(big, o));
  expectRefused(importModel((s.dir / "absent.glb").string()), (s.dir / "absent.glb").string(), "not found");
}

TEST(Import, aMissingTextureIsAWarningAndTheBaseColourStays) {
  NEED_MODELS();
  Scratch s;
  const std::string p = s.write("garage.glb", slurp(kModels + "/kenney-city/building-garage.glb"));
  auto r = importModel(p);
  ASSERT_TRUE(r) << r.error();
  ASSERT_FALSE(r.warnings().empty());
  EXPECT_NE(r.warnings().front().message.find("colormap.png"), std::string::npos);
  for (const Material& m : r->materials) EXPECT_TRUE(m.texturePath.empty());
}

TEST(Import, devicesFifosAndDirectoriesAreNotRegularFiles) {
  Scratch s;
  const std::string fifo = (s.dir / "model.obj").string();
  ASSERT_EQ(::mkfifo(fifo.c_str(), 0600), 0);
  for (const std::string& p : {std::string("/dev/zero"), fifo, s.dir.string()}) {
    expectRefused(importModel(p), p, "not a regular file");
  }
}

/// A one-triangle OBJ in the folder m/ whose material names `texture`, and its MTL.
std::string texturedObj(Scratch& s, const std::string& texture) {
  fs::create_directories(s.dir / "m");
  s.write("m/t.mtl", "newmtl skin\nKd 0.5 0.5 0.5\nmap_Kd " + texture + "\n");
  return s.write("m/t.obj", "mtllib t.mtl\nv 0 0 0\nv 1 0 0\nv 0 1 0\nvt 0 0\nvt 1 0\nvt 0 1\nusemtl skin\n"
                            "f 1/1 2/2 3/3\n");
}

/// The MTL's material (assimp adds a default one beside it).
const Material& skin(const Result<Model>& r) {
  for (const Material& m : r->materials) {
    if (m.name == "skin") return m;
  }
  ADD_FAILURE() << "no material skin";
  return r->materials.front();
}

std::string allWarnings(const Result<Model>& r) {
  std::string w;
  for (const Problem& p : r.warnings()) w += p.message + "\n";
  return w;
}

TEST(Import, aTextureTheViewerCannotDecodeIsNamedAndNotKept) {
  // The renderer decodes PNG and JPEG only (render/src/icon_textures.cpp):
  // a BMP or GIF beside the model is named at import, not silently dropped
  // when drawn. Magic numbers from the BMP and GIF specifications.
  Scratch s;
  fs::create_directories(s.dir / "m");
  s.write("m/skin.bmp", std::string("BM\x36\0\0\0\0\0\0\0\x36\0", 12));
  auto bmp = importModel(texturedObj(s, "skin.bmp"));
  ASSERT_TRUE(bmp) << bmp.error();
  EXPECT_TRUE(skin(bmp).texturePath.empty());
  EXPECT_NE(allWarnings(bmp).find("is a BMP image, which the viewer does not decode (PNG or JPEG only)"),
            std::string::npos)
      << allWarnings(bmp);
  s.write("m/skin.gif", "GIF89a\x01\0\x01\0\0\0");
  auto gif = importModel(texturedObj(s, "skin.gif"));
  ASSERT_TRUE(gif) << gif.error();
  EXPECT_TRUE(skin(gif).texturePath.empty());
  EXPECT_NE(allWarnings(gif).find("is a GIF image"), std::string::npos) << allWarnings(gif);
}

TEST(Import, texturePathsStayInsideTheModelsFolder) {
  Scratch s;
  // /etc/passwd is a readable file outside the folder: never taken.
  auto outside = importModel(texturedObj(s, "/etc/passwd"));
  ASSERT_TRUE(outside) << outside.error();
  EXPECT_EQ(skin(outside).texture, "/etc/passwd");
  EXPECT_TRUE(skin(outside).texturePath.empty());
  EXPECT_NE(allWarnings(outside).find("points outside the model's folder"), std::string::npos) << allWarnings(outside);

  // "../x/skin.png" exists, but the file name in the model's folder is taken.
  const std::string png("\x89PNG\r\n\x1a\n\0\0\0\x0dIHDR", 16);
  fs::create_directories(s.dir / "x");
  s.write("x/skin.png", png);
  auto absent = importModel(texturedObj(s, "../x/skin.png"));
  ASSERT_TRUE(absent) << absent.error();
  EXPECT_TRUE(skin(absent).texturePath.empty());
  const std::string inFolder = s.write("m/skin.png", png);
  auto up = importModel(texturedObj(s, "../x/skin.png"));
  ASSERT_TRUE(up) << up.error();
  EXPECT_EQ(skin(up).texturePath, inFolder);
  EXPECT_NE(allWarnings(up).find("points outside the model's folder"), std::string::npos) << allWarnings(up);

  // A file of that name that is not an image is reported as such.
  s.write("m/passwd", "root:x:0:0:root:/root:/bin/bash\n");
  auto text = importModel(texturedObj(s, "/etc/passwd"));
  ASSERT_TRUE(text) << text.error();
  EXPECT_TRUE(skin(text).texturePath.empty());
  EXPECT_NE(allWarnings(text).find("is not an image"), std::string::npos) << allWarnings(text);

  // A plain relative name inside the folder: no warning.
  auto plain = importModel(texturedObj(s, "skin.png"));
  ASSERT_TRUE(plain) << plain.error();
  EXPECT_EQ(skin(plain).texturePath, inFolder);
  EXPECT_TRUE(plain.warnings().empty()) << allWarnings(plain);
}

TEST(Levels, simplifyDownWithValidIndicesAndLevelZeroWhole) {
  NEED_MODELS();
  auto r = importModel(kModels + "/assimp/Wuson.off");
  ASSERT_TRUE(r);
  const auto levels = makeLevels(r.value());
  ASSERT_EQ(levels.size(), defaultLevelRatios().size());
  EXPECT_EQ(levels[0].triangleCount(), r->triangleCount());
  for (std::size_t k = 1; k < levels.size(); ++k) {
    EXPECT_LT(levels[k].triangleCount(), levels[k - 1].triangleCount()) << k;
    EXPECT_LE(levels[k].error, 0.05f);
    for (std::size_t m = 0; m < levels[k].indices.size(); ++m) {
      for (std::uint32_t i : levels[k].indices[m]) ASSERT_LT(i, r->meshes[m].vertexCount());
    }
  }
  // The half level gets near its target on a smooth closed figure.
  EXPECT_LE(levels[1].triangleCount(), r->triangleCount() * 6 / 10);
}

}  // namespace
