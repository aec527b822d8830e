// validateDatabase and openDatabase on a database with load modules: a
// hand-built 2 x 2-module database is sound; module damage, disagreements
// between pack index and manifest, and missing files each get their message.
#include <gtest/gtest.h>

#include <unistd.h>

#include <algorithm>
#include <filesystem>
#include <functional>

#include "hand_modules.h"
#include "sandtable/formats/bytes.h"
#include "sandtable/formats/database.h"
#include "sandtable/formats/edit_journal.h"
#include "sandtable/formats/manifest.h"
#include "sandtable/formats/module_check.h"

namespace sandtable {
namespace {

namespace fs = std::filesystem;
using namespace module::handmade;

using Damage = std::function<void(module::Module&)>;

class DatabaseModules : public ::testing::Test {
 protected:
  void SetUp() override {
    dir_ = (fs::temp_directory_path() / ("st-dbm." + std::to_string(::getpid()))).string();
    fs::remove_all(dir_);
    grid_ = writeGrid(dir_, 8, 9);
    header_.modulesX = 2;
    header_.modulesZ = 2;
    header_.levels = 3;
    header_.moduleSquares = 4;
    header_.moduleSize = 4 * kSpacing;
  }
  void TearDown() override {
    grid_.reset();
    fs::remove_all(dir_);
  }

  /// Writes modules.pack/.idx (each module through `damage`), materials.txt
  /// and manifest.json; `edit` may change the manifest before it is written.
  void write(const Damage& damage = nullptr,
             const std::function<void(manifest::Manifest&)>& edit = nullptr) {
    auto w = pack::PackWriter::create(dir_, header_, 3);
    ASSERT_TRUE(w.ok()) << w.error();
    for (std::uint32_t kz = 0; kz < header_.modulesZ; ++kz) {
      for (std::uint32_t kx = 0; kx < header_.modulesX; ++kx) {
        module::Module m = buildModule(*grid_, header_, kx, kz);
        if (damage) damage(m);
        ASSERT_EQ(w.value()->add(m).message(), "");
      }
    }
    ASSERT_EQ(w.value()->finish().message(), "");
    const std::string text = materials::format(table());
    ASSERT_EQ(writeFileAtomic(dir_ + "/" + materials::kFileName,
                              std::as_bytes(std::span(text.data(), text.size()))).message(),
              "");
    manifest::Manifest m;
    m.toolVersion = "0.1.0";
    m.createdUtc = "2026-11-22T00:00:00Z";
    m.crsWkt = "PROJCRS[\"WGS 84 / UTM zone 32N\"]";
    m.crsName = "WGS 84 / UTM zone 32N";
    m.epsg = 32632;
    m.originEasting = grid_->header().originEasting;
    m.originNorthing = grid_->header().originNorthing;
    m.spacing = grid_->spacing();
    m.postsX = grid_->postsX();
    m.postsZ = grid_->postsZ();
    m.minElevation = grid_->header().minElevation;
    m.maxElevation = grid_->header().maxElevation;
    m.cornersLonLat = {{{9.0, 36.1}, {9.001, 36.1}, {9.001, 36.09}, {9.0, 36.09}}};
    m.moduleSize = header_.moduleSize;
    m.levels = int(header_.levels);
    for (const char* name : {manifest::kGridFileName, pack::kPackFileName, pack::kIndexFileName,
                             materials::kFileName}) {
      const auto c = crc32File(dir_ + "/" + name);
      ASSERT_TRUE(c.ok()) << c.error();
      m.files.push_back({name, c->bytes, c->crc});
    }
    if (edit) edit(m);
    const std::string json = manifest::encode(m);
    ASSERT_EQ(writeFileAtomic(dir_ + "/" + manifest::kFileName,
                              std::as_bytes(std::span(json.data(), json.size()))).message(),
              "");
  }

  std::uint64_t offsetOf(std::uint32_t kx, std::uint32_t kz) const {
    auto r = pack::PackReader::open(dir_);
    EXPECT_TRUE(r.ok()) << r.error();
    return r ? r.value()->entry(kx, kz).offset : 0;
  }

  std::string packPath() const { return (fs::path(dir_) / pack::kPackFileName).string(); }

  std::string dir_;
  std::shared_ptr<const grid::GridFile> grid_;
  pack::IndexHeader header_;
};

std::string joined(const std::vector<Problem>& ps) {
  std::string s;
  for (const auto& p : ps) s += p.str() + "\n";
  return s;
}

const Problem* find(const std::vector<Problem>& ps, const std::string& needle) {
  for (const auto& p : ps) {
    if (p.message.find(needle) != std::string::npos) return &p;
  }
  return nullptr;
}

TEST_F(DatabaseModules, soundDatabaseValidatesAndOpensWithModulesAndMaterials) {
  write();
  EXPECT_EQ(joined(validateDatabase(dir_).problems()), "");
  auto db = openDatabase(dir_);
  ASSERT_TRUE(db.ok()) << db.error();
  ASSERT_TRUE(db->modules);
  EXPECT_EQ(db->modules->header().levels, 3u);
  EXPECT_EQ(db->modules->header().modulesX, 2u);
  ASSERT_TRUE(db->materials.has_value());
  EXPECT_EQ(db->materials->classes.size(), 4u);
}

TEST_F(DatabaseModules, gridOnlyDatabaseOpensWithoutModules) {
  write(nullptr, [](manifest::Manifest& m) { m.files.resize(1); });
  for (const char* name : {pack::kPackFileName, pack::kIndexFileName, materials::kFileName}) {
    fs::remove(dir_ + "/" + name);
  }
  EXPECT_EQ(joined(validateDatabase(dir_).problems()), "");
  auto db = openDatabase(dir_);
  ASSERT_TRUE(db.ok()) << db.error();
  EXPECT_FALSE(db->modules);
  EXPECT_FALSE(db->materials.has_value());
}

TEST_F(DatabaseModules, moduleProblemsNameThePackAndTheModulesOffset) {
  write([](module::Module& m) {
    if (m.kx == 1 && m.kz == 1) m.levels[0].maxHeight[0] += 0.5f;
  });
  const auto ps = validateDatabase(dir_).problems();
  ASSERT_EQ(ps.size(), 1u) << joined(ps);
  EXPECT_EQ(ps[0].file, packPath());
  EXPECT_EQ(ps[0].offset, offsetOf(1, 1));
  EXPECT_EQ(ps[0].message.rfind("module check: module (1,1) level 0 square 0: maxHeight 127 but the highest vertex is 126.5", 0), 0u)
      << ps[0].message;
}

TEST_F(DatabaseModules, eachDamageHasItsOwnMessage) {
  struct Case {
    const char* what;
    Damage damage;
    std::function<void(manifest::Manifest&)> edit;
    const char* expected;
  };
  const Case cases[] = {
      {"neighbour edge differs",
       [this](module::Module& m) {
         if (m.kx == 0 && m.kz == 1) {
           BuildOptions o;
           o.splitEastEdge = true;
           m = buildModule(*grid_, header_, 0, 1, o);
         }
       },
       nullptr, "module (0,1) level 0 east edge: skin vertex at z 15.000 y 123.250 has no twin on the west edge of module (1,1)"},
      {"material not in the table",
       [](module::Module& m) {
         if (m.kx == 1 && m.kz == 0) {
           for (auto& g : m.levels[2].groups) {
             if (g.half == module::Half::skirt) g.material = 9;
           }
         }
       },
       nullptr, "module check: module (1,0) level 2 group 3 (skirt, priority 1) uses material 9, which materials.txt does not define"},
      {"skin hole",
       [](module::Module& m) {
         if (m.kx == 0 && m.kz == 0) {
           auto& lv = m.levels[1];
           lv.indices.erase(lv.indices.begin(), lv.indices.begin() + 3);  // group 0: one triangle
           lv.groups.erase(lv.groups.begin());
           for (auto& g : lv.groups) g.firstIndex -= 3;
         }
       },
       nullptr, "module check: module (0,0) level 1 square 0 upper: skin covers 0.5 of the triangle (area 900 of 1800 m^2)"},
      {"levels disagree", nullptr, [](manifest::Manifest& m) { m.levels = 4; },
       "database: pack index and manifest disagree on levels (index 3, manifest 4)"},
      {"module size disagrees", nullptr, [](manifest::Manifest& m) { m.moduleSize = 1000; },
       "database: pack index and manifest disagree on module_size_m (index 120.000000, manifest 1000.000000)"},
      {"materials not listed", nullptr,
       [this](manifest::Manifest& m) {
         m.files.pop_back();
         fs::remove(dir_ + "/" + materials::kFileName);
       },
       "database: the manifest lists load modules but not materials.txt, the table their material ids refer to"},
      {"pack not listed", nullptr,
       [this](manifest::Manifest& m) {
         m.files.erase(m.files.begin() + 1);
         fs::remove(dir_ + "/" + pack::kPackFileName);
       },
       "database: the manifest lists modules.idx but not modules.pack"},
  };
  for (const auto& c : cases) {
    fs::remove_all(dir_);
    grid_ = writeGrid(dir_, 8, 9);
    write(c.damage, c.edit);
    const auto ps = validateDatabase(dir_).problems();
    EXPECT_TRUE(find(ps, c.expected)) << c.what << ": expected \"" << c.expected << "\" in\n" << joined(ps);
  }
}

TEST_F(DatabaseModules, openDatabaseRefusesAPackIndexThatDisagrees) {
  write(nullptr, [](manifest::Manifest& m) { m.levels = 2; });
  auto db = openDatabase(dir_);
  ASSERT_FALSE(db.ok());
  EXPECT_NE(db.error().find("disagree on levels (index 3, manifest 2)"), std::string::npos) << db.error();
}

TEST_F(DatabaseModules, badlyBrokenModulesGiveAShortReportInPackOrder) {
  write([](module::Module& m) {
    for (auto& lv : m.levels) {
      for (float& h : lv.maxHeight) h += 2.0f;
      lv.skirtDepth = 0.5f;  // too shallow, and the skirts (20 m) leave the band
    }
  });
  const auto ps = validateDatabase(dir_).problems();
  ASSERT_FALSE(ps.empty());
  // Per module: at most 5 of each kind plus one count line per kind.
  std::map<std::uint64_t, int> perModule;
  for (const auto& p : ps) {
    EXPECT_EQ(p.file, packPath()) << p.str();
    ++perModule[p.offset];
  }
  EXPECT_EQ(perModule.size(), 4u);
  for (const auto& [off, n] : perModule) EXPECT_LE(n, 5 * 4 + 4) << "module at " << off;
  EXPECT_TRUE(std::is_sorted(ps.begin(), ps.end(), [](const Problem& a, const Problem& b) { return a.offset < b.offset; }));
  EXPECT_TRUE(find(ps, "more max-height problems not listed"));
  EXPECT_TRUE(find(ps, "more skirt problems not listed"));
  EXPECT_TRUE(find(ps, "skirt depth 0.500 m is less than"));
}

// The edit journal beside the database is not an unlisted entry; it is read
// when present: damage is a problem, a torn tail a warning.
TEST_F(DatabaseModules, journalBesideTheDatabaseIsReadNotCalledUnlisted) {
  write();
  const std::string path = journal::defaultPath(dir_);
  EXPECT_EQ(path, dir_ + "/edits.journal");
  edit::Edit crater;
  crater.id = 1;
  crater.points = {{40.0, 50.0}};
  crater.radius = 3;
  crater.depth = 1;
  {
    auto w = journal::JournalWriter::open(path);
    ASSERT_TRUE(w.ok()) << w.error();
    ASSERT_EQ(w.value()->append(crater).message(), "");
    crater.id = 2;
    ASSERT_EQ(w.value()->append(crater).message(), "");
    ASSERT_EQ(w.value()->close().message(), "");
  }
  const Status sound = validateDatabase(dir_);
  EXPECT_EQ(joined(sound.problems()), "");
  EXPECT_TRUE(sound.warnings().empty());
  // A torn tail: a warning naming the journal and the cut.
  const auto size = fs::file_size(path);
  fs::resize_file(path, size - 3);
  const Status torn = validateDatabase(dir_);
  EXPECT_EQ(joined(torn.problems()), "");
  ASSERT_EQ(torn.warnings().size(), 1u);
  EXPECT_EQ(torn.warnings().front().file, path);
  EXPECT_EQ(torn.warnings().front().offset, journal::kHeaderBytes + (size - journal::kHeaderBytes) / 2);
  // Damage to the first of two records: a problem.
  {
    auto w = journal::JournalWriter::open(path);  // cuts the tail
    ASSERT_TRUE(w.ok()) << w.error();
    ASSERT_EQ(w.value()->append(crater).message(), "");
  }
  auto bytes = readSmallFile(path, 1 << 20);
  ASSERT_TRUE(bytes.ok());
  bytes.value()[journal::kHeaderBytes + 30] ^= std::byte{1};
  ASSERT_EQ(writeFileAtomic(path, bytes.value()).message(), "");
  const auto ps = validateDatabase(dir_).problems();
  ASSERT_EQ(ps.size(), 1u) << joined(ps);
  EXPECT_EQ(ps.front().file, path);
  EXPECT_EQ(ps.front().offset, journal::kHeaderBytes);
  EXPECT_NE(ps.front().message.find("payload checksum mismatch"), std::string::npos) << ps.front().message;
  // Any other file is still an unlisted entry.
  fs::rename(path, dir_ + "/edits.journal.old");
  const auto other = validateDatabase(dir_).problems();
  ASSERT_EQ(other.size(), 1u) << joined(other);
  EXPECT_EQ(other.front().message, "database: file is not listed in the manifest");
}

}  // namespace
}  // namespace sandtable
