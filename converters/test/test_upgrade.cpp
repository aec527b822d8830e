// `sandtable upgrade`: a version 1 database with culture, upgraded to
// version 2, still validates, and its modules match within the height step;
// a second upgrade is a no-op; a database built as version 2 validates too.
#include <gtest/gtest.h>
#include <unistd.h>

#include <cmath>
#include <cstring>
#include <filesystem>
#include <vector>

#include "sandtable/converters/elevation.h"
#include "sandtable/converters/modules.h"
#include "sandtable/converters/synth.h"
#include "sandtable/converters/validate.h"
#include "sandtable/formats/manifest.h"
#include "sandtable/formats/module.h"
#include "sandtable/formats/pack.h"

namespace fs = std::filesystem;
using namespace sandtable;

namespace {

struct Scratch {
  fs::path dir;
  explicit Scratch(const std::string& name)
      : dir(fs::temp_directory_path() / ("sandtable_upgrade_" + name + "_" + std::to_string(::getpid()))) {
    fs::remove_all(dir);
    fs::create_directories(dir);
  }
  ~Scratch() {
    std::error_code ec;
    fs::remove_all(dir, ec);
  }
};

/// A 2 km synth area with culture, built at 31.25 m (the figure).
std::string buildDb(const Scratch& s, const std::string& name, std::uint32_t version, double heightStep) {
  if (!fs::exists(s.dir / "synth")) {
    convert::SynthOptions so;
    so.outDir = (s.dir / "synth").string();
    so.sizeKm = 2;
    so.dted1 = false;
    so.dem = false;
    EXPECT_TRUE(convert::synthesize(so));
  }
  convert::ElevationOptions o;
  o.sources = {(s.dir / "synth" / "dted2").string()};
  o.culture = {(s.dir / "synth" / "culture.gpkg").string()};
  o.output = (s.dir / name).string();
  o.spacing = 31.25;
  o.moduleVersion = version;
  o.heightStep = heightStep;
  o.moduleNormals = version == 2;  // off by default; the v2 test checks them
  auto r = convert::buildElevation(o, {});
  EXPECT_TRUE(r) << (r ? "" : r.error());
  return o.output;
}

std::vector<module::Module> readAll(const std::string& dir, std::uint32_t& version) {
  auto reader = pack::PackReader::open(dir);
  EXPECT_TRUE(reader) << (reader ? "" : reader.error());
  std::vector<module::Module> out;
  if (!reader) return out;
  const auto& h = reader.value()->header();
  for (std::uint32_t kz = 0; kz < h.modulesZ; ++kz) {
    for (std::uint32_t kx = 0; kx < h.modulesX; ++kx) {
      auto raw = reader.value()->readRaw(kx, kz);
      EXPECT_TRUE(raw);
      version = module::encodedVersion(raw.value());
      auto m = reader.value()->read(kx, kz);
      EXPECT_TRUE(m) << (m ? "" : m.error());
      out.push_back(std::move(m.value()));
    }
  }
  return out;
}

TEST(Upgrade, Version1DatabaseUpgradesValidatesAndKeepsItsModules) {
  Scratch s("v1");
  const std::string db = buildDb(s, "db", 1, 0);
  ASSERT_TRUE(convert::validateDatabaseWithCrs(db).ok());
  std::uint32_t version = 0;
  const auto before = readAll(db, version);
  ASSERT_EQ(version, 1u);
  ASSERT_FALSE(before.empty());

  auto r = convert::upgradeDatabase(db, {}, {});
  ASSERT_TRUE(r) << r.error();
  EXPECT_TRUE(r->upgraded);
  EXPECT_EQ(r->fromVersion, 1u);
  EXPECT_LT(r->packBytesAfter, r->packBytesBefore);
  const Status valid = convert::validateDatabaseWithCrs(db);
  EXPECT_TRUE(valid.ok()) << valid.message();
  // Nothing left beside the database.
  for (const auto& e : fs::directory_iterator(s.dir)) {
    EXPECT_EQ(e.path().filename().string().find(".upgrade."), std::string::npos) << e.path();
  }
  auto man = manifest::readFromDirectory(db);
  ASSERT_TRUE(man);
  EXPECT_EQ(man->build["modules"]["format_version"], sandtable::module::kNewestVersion);
  // The record sizes are the new modules', not the build's.
  EXPECT_LT(man->build["modules"]["bytes"]["compressed_total"].get<std::uint64_t>(), r->packBytesAfter);
  EXPECT_GT(man->build["modules"]["bytes"]["compressed_total"].get<std::uint64_t>(), r->packBytesAfter / 2);

  const auto after = readAll(db, version);
  EXPECT_EQ(version, sandtable::module::kNewestVersion);
  ASSERT_EQ(after.size(), before.size());
  // Half a step, plus the rounding of the plane and of the offset to f32.
  const auto tol = [](float y) { return 0.5 * module::kDefaultHeightStep + 2.0 * (std::nextafter(std::fabs(y), INFINITY) - std::fabs(y)); };
  for (std::size_t k = 0; k < before.size(); ++k) {
    ASSERT_EQ(after[k].levels.size(), before[k].levels.size());
    for (std::size_t l = 0; l < before[k].levels.size(); ++l) {
      const auto& a = before[k].levels[l];
      const auto& b = after[k].levels[l];
      ASSERT_EQ(a.vertices.size(), b.vertices.size());
      for (std::size_t v = 0; v < a.vertices.size(); ++v) {
        ASSERT_EQ(a.vertices[v].x, b.vertices[v].x);
        ASSERT_EQ(a.vertices[v].z, b.vertices[v].z);
        ASSERT_EQ(a.vertices[v].s, b.vertices[v].s);
        ASSERT_EQ(a.vertices[v].t, b.vertices[v].t);
        ASSERT_LE(std::fabs(double(a.vertices[v].y) - b.vertices[v].y), tol(a.vertices[v].y)) << "module " << k << " level " << l;
      }
      EXPECT_EQ(a.indices, b.indices);
      ASSERT_EQ(a.groups.size(), b.groups.size());
      for (std::size_t g = 0; g < a.groups.size(); ++g) {
        EXPECT_EQ(a.groups[g].square, b.groups[g].square);
        EXPECT_EQ(a.groups[g].material, b.groups[g].material);
        EXPECT_EQ(a.groups[g].indexCount, b.groups[g].indexCount);
      }
    }
  }

  // Again: nothing to do, nothing touched.
  const auto packTime = fs::last_write_time(fs::path(db) / pack::kPackFileName);
  auto again = convert::upgradeDatabase(db, {}, {});
  ASSERT_TRUE(again) << again.error();
  EXPECT_FALSE(again->upgraded);
  EXPECT_EQ(again->fromVersion, sandtable::module::kNewestVersion);
  EXPECT_EQ(fs::last_write_time(fs::path(db) / pack::kPackFileName), packTime);
}

TEST(Upgrade, BuiltVersion2DatabaseValidatesCarriesNormalsAndUpgradesToVersion4) {
  Scratch s("v2");
  const std::string db = buildDb(s, "db", 2, 0);
  const Status valid = convert::validateDatabaseWithCrs(db);
  EXPECT_TRUE(valid.ok()) << valid.message();
  std::uint32_t version = 0;
  const auto mods = readAll(db, version);
  EXPECT_EQ(version, 2u);
  ASSERT_FALSE(mods.empty());
  for (const auto& m : mods) {
    for (const auto& l : m.levels) {
      ASSERT_EQ(l.normals.size(), l.vertices.size());
      for (const std::uint32_t n : l.normals) {
        const auto d = module::octDecode(n);
        EXPECT_GT(d[1], 0.0f);  // grid normals point up
      }
    }
  }
  // Version 2 upgrades to version 4 losslessly with exact heights: the
  // same modules, normals included, and it still validates.
  auto r = convert::upgradeDatabase(db, {.heightStep = 0}, {});
  ASSERT_TRUE(r) << r.error();
  EXPECT_TRUE(r->upgraded);
  EXPECT_EQ(r->fromVersion, 2u);
  EXPECT_LT(r->packBytesAfter, r->packBytesBefore);
  const Status upgraded = convert::validateDatabaseWithCrs(db);
  EXPECT_TRUE(upgraded.ok()) << upgraded.message();
  const auto after = readAll(db, version);
  EXPECT_EQ(version, sandtable::module::kNewestVersion);
  ASSERT_EQ(after.size(), mods.size());
  for (std::size_t k = 0; k < mods.size(); ++k) {
    for (std::size_t l = 0; l < mods[k].levels.size(); ++l) {
      const auto& a = mods[k].levels[l];
      const auto& b = after[k].levels[l];
      ASSERT_EQ(a.vertices.size(), b.vertices.size());
      EXPECT_EQ(std::memcmp(a.vertices.data(), b.vertices.data(), a.vertices.size() * sizeof(module::Vertex)), 0);
      EXPECT_EQ(a.normals, b.normals);
      EXPECT_EQ(a.indices, b.indices);
    }
  }
}

// A version 2 database with quantised heights (culture vertices up to
// half a step off their plane) upgrades to quantised version 4 and still
// validates: version 4 puts them back on the decoded plane.
TEST(Upgrade, QuantisedVersion2DatabaseUpgradesToVersion4AndValidates) {
  Scratch s("v2q");
  const std::string db = buildDb(s, "db", 2, 0.01);
  ASSERT_TRUE(convert::validateDatabaseWithCrs(db).ok());
  auto r = convert::upgradeDatabase(db, {}, {});
  ASSERT_TRUE(r) << r.error();
  EXPECT_TRUE(r->upgraded);
  const Status upgraded = convert::validateDatabaseWithCrs(db);
  EXPECT_TRUE(upgraded.ok()) << upgraded.message();
  std::uint32_t version = 0;
  EXPECT_FALSE(readAll(db, version).empty());
  EXPECT_EQ(version, sandtable::module::kNewestVersion);
}

}  // namespace
