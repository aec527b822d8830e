// Load modules from the real builder (synthetic DTED2 + culture): validate
// passes, damage to a real module is found with its own message, and
// `sandtable export` writes what the pack holds, with exit 2 on bad input.
#include <fstream>
#include <sstream>

#include "sandtable/converters/elevation.h"
#include "sandtable/converters/synth.h"
#include "sandtable/formats/bytes.h"
#include "sandtable/formats/database.h"
#include "test_support.h"

namespace sandtable::test {
namespace {

namespace fs = std::filesystem;

/// One synthetic database with modules and culture, built once for the suite.
class ModulesEndToEnd : public ::testing::Test {
 protected:
  static void SetUpTestSuite() {
    tmp_ = new TempDir("mods");
    convert::SynthOptions so;
    so.outDir = *tmp_ / "inputs";
    so.sizeKm = 4;
    so.dted1 = false;
    so.dem = false;
    auto s = convert::synthesize(so);
    ASSERT_TRUE(s.ok()) << s.error();
    convert::ElevationOptions o;
    o.sources = {*tmp_ / "inputs/dted2"};
    o.culture = {*tmp_ / "inputs/culture.gpkg"};
    o.extent = std::array<double, 4>{s->west, s->south, s->east, s->north};
    o.spacing = 30;
    o.output = *tmp_ / "db";
    auto r = convert::buildElevation(o, nullptr);
    ASSERT_TRUE(r.ok()) << r.error();
    db_ = o.output;
  }
  static void TearDownTestSuite() {
    delete tmp_;
    tmp_ = nullptr;
  }
  static TempDir* tmp_;
  static std::string db_;
};
TempDir* ModulesEndToEnd::tmp_ = nullptr;
std::string ModulesEndToEnd::db_;

/// A copy of the database with every module passed through `damage`, the
/// pack rewritten and the manifest's sizes and CRCs brought up to date, so
/// only the damage itself is wrong.
std::string damagedCopy(const std::string& db, const std::string& to,
                        const std::function<void(module::Module&)>& damage) {
  fs::remove_all(to);
  fs::copy(db, to);
  auto reader = pack::PackReader::open(db);
  EXPECT_TRUE(reader.ok()) << reader.error();
  const pack::IndexHeader h = reader.value()->header();
  auto w = pack::PackWriter::create(to, h, 3);
  EXPECT_TRUE(w.ok()) << w.error();
  for (std::uint32_t kz = 0; kz < h.modulesZ; ++kz) {
    for (std::uint32_t kx = 0; kx < h.modulesX; ++kx) {
      auto m = reader.value()->read(kx, kz);
      EXPECT_TRUE(m.ok()) << m.error();
      damage(m.value());
      EXPECT_EQ(w.value()->add(m.value()).message(), "");
    }
  }
  EXPECT_EQ(w.value()->finish().message(), "");
  auto man = manifest::readFromDirectory(to);
  EXPECT_TRUE(man.ok()) << man.error();
  for (auto& f : man->files) {
    const auto c = crc32File(to + "/" + f.path);
    EXPECT_TRUE(c.ok()) << c.error();
    if (!c) continue;
    f.crc = c->crc;
    f.bytes = c->bytes;
  }
  const std::string text = manifest::encode(man.value());
  EXPECT_EQ(writeFileAtomic(to + "/" + manifest::kFileName, std::as_bytes(std::span(text.data(), text.size()))).message(), "");
  return to;
}

bool anyHas(const std::vector<Problem>& ps, const std::string& needle) {
  return std::any_of(ps.begin(), ps.end(), [&](const Problem& p) { return p.message.find(needle) != std::string::npos; });
}

std::string joined(const std::vector<Problem>& ps) {
  std::string s;
  for (const auto& p : ps) s += p.str() + "\n";
  return s;
}

TEST_F(ModulesEndToEnd, builtDatabaseValidates) {
  const auto ps = validateDatabase(db_).problems();
  EXPECT_TRUE(ps.empty()) << joined(ps);
  auto db = openDatabase(db_);
  ASSERT_TRUE(db.ok()) << db.error();
  ASSERT_TRUE(db->modules);
  EXPECT_TRUE(db->materials.has_value());
  EXPECT_GE(db->modules->header().modulesX, 4u);
}

TEST_F(ModulesEndToEnd, damageToARealModuleIsFound) {
  struct Case {
    const char* what;
    std::function<void(module::Module&)> damage;
    const char* expected;
  };
  auto only11 = [](auto f) {
    return [f](module::Module& m) {
      if (m.kx == 1 && m.kz == 1) f(m);
    };
  };
  const Case cases[] = {
      {"a skin vertex lifted", only11([](module::Module& m) {
         auto& lv = m.levels[1];
         lv.vertices[lv.indices[lv.groups[10].firstIndex]].y += 0.5f;
       }),
       "m off the grid triangle's plane"},
      {"a skin group dropped", only11([](module::Module& m) {
         auto& lv = m.levels[0];
         const module::Group g = lv.groups[3];
         lv.indices.erase(lv.indices.begin() + g.firstIndex, lv.indices.begin() + g.firstIndex + g.indexCount);
         lv.groups.erase(lv.groups.begin() + 3);
         for (std::size_t k = 3; k < lv.groups.size(); ++k) lv.groups[k].firstIndex -= g.indexCount;
       }),
       "module check: module (1,1) level 0 square"},
      {"skirts too shallow", only11([](module::Module& m) { m.levels[2].skirtDepth = 0.001f; }),
       "module check: module (1,1) level 2: skirt depth 0.001 m is less than"},
      {"maxHeight stale", only11([](module::Module& m) { m.levels[3].maxHeight[0] += 3.0f; }),
       "module check: module (1,1) level 3 square 0: maxHeight"},
  };
  for (const auto& c : cases) {
    const std::string copy = damagedCopy(db_, *tmp_ / "damaged", c.damage);
    const auto ps = validateDatabase(copy).problems();
    EXPECT_TRUE(anyHas(ps, c.expected)) << c.what << ": expected \"" << c.expected << "\" in\n" << joined(ps);
    for (const auto& p : ps) EXPECT_EQ(p.file, copy + "/modules.pack") << c.what << ": " << p.str();
  }
}

std::size_t trianglesAt(const std::string& db, std::uint32_t kx, std::uint32_t kz, std::uint32_t level) {
  auto r = pack::PackReader::open(db);
  EXPECT_TRUE(r.ok()) << r.error();
  auto m = r.value()->read(kx, kz);
  EXPECT_TRUE(m.ok()) << m.error();
  return m->levels[level].indices.size() / 3;
}

TEST_F(ModulesEndToEnd, exportWritesEveryTriangle) {
  const std::string obj = *tmp_ / "m11.obj";
  // The terrain alone: OBJ would flatten the module's trees into it by default.
  const auto r = runCli({"export", db_, "--module", "1", "1", "--objects", "none", "-o", obj});
  ASSERT_EQ(r.exitCode, 0) << r.err;
  EXPECT_NE(r.out.find("wrote " + obj + " + " + (*tmp_ / "m11.mtl")), std::string::npos) << r.out;
  std::istringstream in(slurpFile(obj));
  std::size_t faces = 0, vertices = 0;
  for (std::string line; std::getline(in, line);) {
    faces += line.rfind("f ", 0) == 0;
    vertices += line.rfind("v ", 0) == 0;
  }
  EXPECT_EQ(faces, trianglesAt(db_, 1, 1, 0));
  EXPECT_GT(vertices, 0u);
  EXPECT_NE(slurpFile(*tmp_ / "m11.mtl").find("newmtl skirt"), std::string::npos);

  const std::string glb = *tmp_ / "range.glb";
  const auto g = runCli({"export", db_, "--module", "0", "0", "--to", "1", "1", "--level", "2", "--json", "-o", glb});
  ASSERT_EQ(g.exitCode, 0) << g.err;
  const auto j = nlohmann::json::parse(g.out);
  std::size_t want = 0;
  for (std::uint32_t kz = 0; kz < 2; ++kz) {
    for (std::uint32_t kx = 0; kx < 2; ++kx) want += trianglesAt(db_, kx, kz, 2);
  }
  EXPECT_EQ(j["triangles"].get<std::size_t>(), want);
  EXPECT_EQ(j["format"], "glb");
  EXPECT_EQ(slurpFile(glb).substr(0, 4), "glTF");
}

TEST_F(ModulesEndToEnd, exportBadInputsExit2) {
  const std::string out = *tmp_ / "bad.obj";
  struct Bad {
    std::vector<std::string> args;
    const char* expected;
  };
  const Bad cases[] = {
      {{"export", db_, "--module", "99", "0", "-o", out}, "--module (99,0) is outside the database"},
      {{"export", db_, "--module", "1", "1", "--to", "0", "0", "-o", out}, "lies west or north of --module"},
      {{"export", db_, "--module", "0", "0", "--level", "9", "-o", out}, "level 9 is out of range: the database has 4 levels"},
      {{"export", db_, "--module", "0", "0", "-o", *tmp_ / "bad.stl"}, "give --format obj|gltf"},
      {{"export", db_, "--module", "0", "0", "--format", "obj", "-o", *tmp_ / "bad.glb"}, "--format obj but the output"},
      {{"export", *tmp_ / "nope", "--module", "0", "0", "-o", out}, "not a directory"},
  };
  for (const auto& c : cases) {
    const auto r = runCli(c.args);
    EXPECT_EQ(r.exitCode, 2) << c.expected << "\n" << r.out << r.err;
    EXPECT_NE(r.err.find(c.expected), std::string::npos) << r.err;
  }
  EXPECT_FALSE(fs::exists(out));
}

TEST_F(ModulesEndToEnd, exportOfAGridOnlyDatabaseExplainsWhy) {
  convert::ElevationOptions o;
  o.sources = {*tmp_ / "inputs/dted2"};
  o.spacing = 90;
  o.modules = false;
  o.output = *tmp_ / "gridonly";
  auto b = convert::buildElevation(o, nullptr);
  ASSERT_TRUE(b.ok()) << b.error();
  const auto r = runCli({"export", o.output, "--module", "0", "0", "-o", *tmp_ / "g.obj"});
  EXPECT_EQ(r.exitCode, 2);
  EXPECT_NE(r.err.find("has no load modules"), std::string::npos) << r.err;
}

}  // namespace
}  // namespace sandtable::test
