// Hostile inputs to the CLI on a real database (DTED0 n43 with modules):
// manifests whose informational `build` object has the wrong shape; damage
// that only `validate` can see (every checksum resealed, so only the damage
// is wrong); bad command lines, with and without --json; export by a point.
#include <atomic>
#include <cmath>
#include <sstream>

#include <nlohmann/json.hpp>
#include <ogr_spatialref.h>

#include "sandtable/converters/elevation.h"
#include "sandtable/converters/validate.h"
#include "sandtable/formats/bytes.h"
#include "sandtable/formats/database.h"
#include "test_support.h"

namespace sandtable::test {
namespace {

namespace fs = std::filesystem;
using nlohmann::json;

/// One small real database with load modules, built once for the suite.
class HostileCli : public ::testing::Test {
 protected:
  static void SetUpTestSuite() {
    if (!haveData()) return;
    tmp_ = new TempDir("hostile");
    convert::ElevationOptions o;
    o.sources = {data("elevation/dted/n43.dt0")};
    o.output = *tmp_ / "db";
    // Exact heights: tests decode, edit and re-encode modules, which must
    // not quantise derived heights (skirt bottoms) a second time.
    o.heightStep = 0;
    auto r = convert::buildElevation(o, nullptr);
    ASSERT_TRUE(r.ok()) << r.error();
    db_ = o.output;
  }
  static void TearDownTestSuite() {
    delete tmp_;
    tmp_ = nullptr;
  }
  void SetUp() override { SANDTABLE_REQUIRE_DATA(); }

  /// A fresh copy of the database, removed by the suite's TempDir.
  static std::string copy(const std::string& name) {
    const std::string to = *tmp_ / name;
    fs::remove_all(to);
    fs::copy(db_, to);
    return to;
  }

  static TempDir* tmp_;
  static std::string db_;
};
TempDir* HostileCli::tmp_ = nullptr;
std::string HostileCli::db_;

struct BuildShape {
  const char* name;
  std::function<void(json& build)> edit;
};

TEST_F(HostileCli, infoAndValidateTreatTheBuildObjectAsInformational) {
  const BuildShape shapes[] = {
      {"build = {}", [](json& b) { b = json::object(); }},
      {"culture = {}", [](json& b) { b["culture"] = json::object(); }},
      {"modules = {}", [](json& b) { b["modules"] = json::object(); }},
      {"culture and modules = {}", [](json& b) { b["culture"] = json::object(), b["modules"] = json::object(); }},
      {"culture is an array", [](json& b) { b["culture"] = json::array({1, 2}); }},
      {"modules is a string", [](json& b) { b["modules"] = "many"; }},
      {"culture is null", [](json& b) { b["culture"] = nullptr; }},
      {"modules.bytes is an array", [](json& b) { b["modules"]["bytes"] = json::array(); }},
      {"modules.per_level is an object", [](json& b) { b["modules"]["per_level"] = {{"a", 1}}; }},
      {"per_level holds numbers", [](json& b) { b["modules"]["per_level"] = json::array({1, "x", nullptr}); }},
      {"counts are strings", [](json& b) { b["modules"]["count"] = "315", b["modules"]["modules_x"] = true; }},
      {"counts are huge or negative", [](json& b) {
         b["modules"]["count"] = 1e300, b["modules"]["modules_z"] = -7, b["voids_filled"] = -1.5e308;
       }},
      {"classes is an array", [](json& b) { b["culture"]["classes"] = json::array({"road"}); }},
      {"a class is a number", [](json& b) { b["culture"]["classes"] = {{"road", 5}, {"rail", json::array()}}; }},
      {"materials is a number", [](json& b) { b["culture"]["materials"] = 3; }},
      {"resample and seconds of the wrong type", [](json& b) { b["resample"] = 7, b["seconds"] = "slow"; }},
  };
  int n = 0;
  for (const auto& s : shapes) {
    const std::string db = copy("shape" + std::to_string(n++));
    resealManifest(db, [&](json& j) { s.edit(j["build"]); });
    const auto text = runCli({"info", db});
    EXPECT_EQ(text.exitCode, 0) << s.name << ": " << text.err;
    EXPECT_NE(text.out.find("posts      117 x 163"), std::string::npos) << s.name << ": " << text.out;
    EXPECT_EQ(text.err, "") << s.name;
    const auto asJson = runCli({"info", db, "--json"});
    EXPECT_EQ(asJson.exitCode, 0) << s.name << ": " << asJson.err;
    EXPECT_TRUE(json::accept(asJson.out)) << s.name << ": " << asJson.out;
    const auto v = runCli({"validate", db});
    EXPECT_EQ(v.exitCode, 0) << s.name << ": " << v.out << v.err;
  }
}

// ---------------------------------------------------------------- validate

std::uint32_t crcOf(const std::string& bytes, std::size_t from, std::size_t n) {
  return crc32(std::as_bytes(std::span(bytes.data() + from, n)));
}

void putU32(std::string& bytes, std::size_t at, std::uint32_t v) {
  for (int k = 0; k < 4; ++k) bytes[at + std::size_t(k)] = char((v >> (8 * k)) & 0xff);
}

/// grid.stg after `edit` of its bytes, with the block CRCs, the table CRC
/// and the header CRC resealed (FORMAT.md §4), then the manifest.
void damageGrid(const std::string& db, const std::function<void(std::string&, const grid::Header&)>& edit) {
  const std::string path = db + "/grid.stg";
  grid::Header h;
  {
    auto g = grid::GridFile::open(path);
    ASSERT_TRUE(g.ok()) << g.error();
    h = g.value()->header();
  }
  std::string b = slurpFile(path);
  edit(b, h);
  for (std::uint64_t k = 0; k < h.blockCount(); ++k) {
    putU32(b, h.blockTableOffset + k * grid::kBlockEntryBytes,
           crcOf(b, h.dataOffset + k * grid::kBlockBytes, grid::kBlockBytes));
  }
  putU32(b, grid::field::tableCrc, crcOf(b, h.blockTableOffset, h.blockCount() * grid::kBlockEntryBytes));
  putU32(b, grid::field::headerCrc, crcOf(b, 0, grid::field::headerCrc));
  spit(path, b);
  resealFiles(db);
}

std::vector<Problem> validateAll(const std::string& db) { return convert::validateDatabaseWithCrs(db).problems(); }

/// A number as the validator prints it: 17 significant digits, shortest form.
std::string fmt17(double v) {
  char buf[40];
  std::snprintf(buf, sizeof buf, "%.17g", v);
  return buf;
}

/// The one problem `validate` must find, with its file and offset.
void expectOnly(const std::vector<Problem>& ps, const std::string& file, std::uint64_t offset,
                const std::string& needle) {
  std::string all;
  for (const auto& p : ps) all += p.str() + "\n";
  ASSERT_EQ(ps.size(), 1u) << all;
  EXPECT_EQ(ps[0].file, file) << all;
  EXPECT_EQ(ps[0].offset, offset) << all;
  EXPECT_NE(ps[0].message.find(needle), std::string::npos) << all;
}

TEST_F(HostileCli, theSoundDatabaseValidates) {
  EXPECT_TRUE(validateAll(db_).empty());
  // The builder's corners are the grid's corner posts through PROJ: checked
  // here with OGR directly, not through the code under test.
  const auto m = manifest::readFromDirectory(db_);
  ASSERT_TRUE(m.ok());
  OGRSpatialReference proj, wgs;
  ASSERT_EQ(proj.importFromWkt(m->crsWkt.c_str()), OGRERR_NONE);
  wgs.SetWellKnownGeogCS("WGS84");
  proj.SetAxisMappingStrategy(OAMS_TRADITIONAL_GIS_ORDER);
  wgs.SetAxisMappingStrategy(OAMS_TRADITIONAL_GIS_ORDER);
  std::unique_ptr<OGRCoordinateTransformation> ct(OGRCreateCoordinateTransformation(&proj, &wgs));
  ASSERT_TRUE(ct);
  double x = m->eastEasting(), y = m->southNorthing();  // SE
  ASSERT_TRUE(ct->Transform(1, &x, &y));
  EXPECT_NEAR(x, m->cornersLonLat[2][0], 1e-9);
  EXPECT_NEAR(y, m->cornersLonLat[2][1], 1e-9);
}

TEST_F(HostileCli, validateRejectsAnUnusableCrs) {
  for (const auto& [wkt, needle] : {std::pair<std::string, std::string>{"PROJCRS[\"broken", "cannot be parsed"},
                                    {"not a CRS at all", "cannot be parsed"},
                                    {"GEOGCRS[\"WGS 84\",DATUM[\"World Geodetic System 1984\",ELLIPSOID[\"WGS 84\","
                                     "6378137,298.257223563]],CS[ellipsoidal,2],AXIS[\"latitude\",north,ANGLEUNIT["
                                     "\"degree\",0.0174532925199433]],AXIS[\"longitude\",east,ANGLEUNIT[\"degree\","
                                     "0.0174532925199433]]]",
                                     "is not a projected CRS"}}) {
    const std::string db = copy("crs");
    resealManifest(db, [&](json& j) { j["crs"]["wkt"] = wkt; });
    expectOnly(validateAll(db), db + "/manifest.json", 0, needle);
    const auto v = runCli({"validate", db});
    EXPECT_EQ(v.exitCode, 1) << v.out << v.err;
    EXPECT_NE(v.out.find("manifest.json @0: manifest: crs.wkt"), std::string::npos) << v.out;
    // What validate now catches is what made sample fail.
    EXPECT_EQ(runCli({"sample", db, "--lonlat", "-79.5", "43.5"}).exitCode, 2);
  }
}

TEST_F(HostileCli, validateCrossChecksTheCornersAgainstTheGrid) {
  const std::string db = copy("corners");
  resealManifest(db, [](json& j) { j["corners_lonlat"][1][0] = j["corners_lonlat"][1][0].get<double>() + 2e-6; });
  expectOnly(validateAll(db), db + "/manifest.json", 0, "corners_lonlat[1] (NE) is lon");
  const auto ps = validateAll(db);
  EXPECT_NE(ps[0].message.find("m away (more than 0.01 m)"), std::string::npos) << ps[0].message;
}

TEST_F(HostileCli, validateComparesMinElevationExactly) {
  const auto m = manifest::readFromDirectory(db_);
  ASSERT_TRUE(m.ok());
  {
    // Between two floats: rounding it to f32 would have hidden it.
    const std::string db = copy("minelev");
    resealManifest(db, [&](json& j) { j["grid"]["min_elevation"] = double(m->minElevation) + 1e-6; });
    expectOnly(validateAll(db), db + "/manifest.json", 0, "grid.min_elevation " + fmt17(double(m->minElevation) + 1e-6) + " is not an f32 value");
  }
  {
    const std::string db = copy("minelev2");
    const float next = std::nextafter(m->minElevation, 1e9f);
    resealManifest(db, [&](json& j) { j["grid"]["min_elevation"] = double(next); });
    expectOnly(validateAll(db), db + "/grid.stg", grid::field::minElevation,
               "disagree on min_elevation (header " + fmt17(m->minElevation) + ", manifest " +
                   fmt17(double(next)) + ")");
  }
}

TEST_F(HostileCli, validateChecksEdgePaddingAgainstTheEdgePosts) {
  // 117 x 163 posts: block column 1 holds posts 64..116 and pads 117..127.
  struct Case {
    std::uint64_t plane;
    std::uint32_t width;
    const char* what;
  };
  for (const Case c : {Case{grid::kMaterialPlane, 1, "material"}, Case{grid::kElevationPlane, 4, "elevation"},
                       Case{grid::kNormalYPlane, 2, "normal y"}}) {
    const std::string db = copy("edge");
    std::uint64_t at = 0;
    damageGrid(db, [&](std::string& b, const grid::Header& h) {
      ASSERT_EQ(h.postsX, 117u);
      const std::uint64_t block = h.dataOffset + 1 * grid::kBlockBytes;  // block (1,0)
      const std::uint64_t pad = 5 * 64 + 60;  // post (124, 5), which repeats post (116, 5)
      const std::uint64_t other = 5 * 64 + 10;  // post (74, 5): a value the block already holds
      at = block + c.plane + pad * c.width;
      std::string v = b.substr(block + c.plane + other * c.width, c.width);
      if (v == b.substr(at, c.width)) v[0] = char(v[0] ^ 1);
      b.replace(at, c.width, v);
    });
    const auto ps = validateAll(db);
    std::string all;
    for (const auto& p : ps) all += p.str() + "\n";
    ASSERT_FALSE(ps.empty()) << c.what;
    EXPECT_EQ(ps[0].file, db + "/grid.stg") << all;
    EXPECT_EQ(ps[0].offset, at) << all;
    EXPECT_NE(ps[0].message.find(std::string("block (1,0) post 380 lies beyond the grid at (124,5), but its ") + c.what +
                                 " differs from edge post (116,5)"),
              std::string::npos)
        << all;
    for (const auto& p : ps) {  // an elevation not in the block would also move the block's min/max
      EXPECT_TRUE(p.message.find("beyond the grid") != std::string::npos || p.message.find("normal") != std::string::npos ||
                  p.message.find("module check") != std::string::npos)
          << p.str();
    }
  }
}

TEST_F(HostileCli, validateChecksReservedHeaderBytes) {
  {
    const std::string db = copy("gridreserved");
    damageGrid(db, [](std::string& b, const grid::Header&) { b[110] = 7; });
    expectOnly(validateAll(db), db + "/grid.stg", 110, "grid: header reserved bytes 108..123 are not zero");
  }
  {
    // The pack header's CRC and its copy in the index resealed, then the index header.
    const std::string db = copy("packreserved");
    std::string pk = slurpFile(db + "/modules.pack"), ix = slurpFile(db + "/modules.idx");
    pk[30] = 1;
    putU32(pk, pack::packField::headerCrc, crcOf(pk, 0, pack::packField::headerCrc));
    putU32(ix, pack::indexField::packHeaderCrc, crcOf(pk, 0, pack::kPackHeaderBytes));  // of all 64 bytes
    putU32(ix, pack::indexField::headerCrc, crcOf(ix, 0, pack::indexField::headerCrc));
    spit(db + "/modules.pack", pk);
    spit(db + "/modules.idx", ix);
    resealFiles(db);
    expectOnly(validateAll(db), db + "/modules.pack", 30, "pack: header reserved bytes 24..59 are not zero");
  }
  {
    const std::string db = copy("idxreserved");
    std::string ix = slurpFile(db + "/modules.idx");
    ix[100] = 1;
    putU32(ix, pack::indexField::headerCrc, crcOf(ix, 0, pack::indexField::headerCrc));
    spit(db + "/modules.idx", ix);
    resealFiles(db);
    // The build writes pack v2, whose reserved bytes start at 84 (FORMAT.md 10.2).
    expectOnly(validateAll(db), db + "/modules.idx", 100, "pack index: header reserved bytes 84..123 are not zero");
  }
}

TEST_F(HostileCli, validateChecksSkinTextureCoordinates) {
  // Module (3,2)'s first vertex (a lattice post) given another module's s.
  const std::string db = copy("texture");
  std::uint64_t offset = 0;
  {
    auto reader = pack::PackReader::open(db_);
    ASSERT_TRUE(reader.ok()) << reader.error();
    const pack::IndexHeader h = reader.value()->header();
    offset = 0;
    fs::remove(db + "/modules.pack");
    fs::remove(db + "/modules.idx");
    auto w = pack::PackWriter::create(db, h, 3);
    ASSERT_TRUE(w.ok()) << w.error();
    for (std::uint32_t kz = 0; kz < h.modulesZ; ++kz) {
      for (std::uint32_t kx = 0; kx < h.modulesX; ++kx) {
        auto m = reader.value()->read(kx, kz);
        ASSERT_TRUE(m.ok()) << m.error();
        if (kx == 3 && kz == 2) m.value().levels[0].vertices[0].s += 0.5f;  // 32 m off
        ASSERT_EQ(w.value()->add(m.value()).message(), "");
      }
    }
    ASSERT_EQ(w.value()->finish().message(), "");
  }
  resealFiles(db);
  auto r = pack::PackReader::open(db);
  ASSERT_TRUE(r.ok());
  offset = r.value()->entry(3, 2).offset;
  const auto ps = validateAll(db);
  ASSERT_FALSE(ps.empty());
  EXPECT_EQ(ps[0].file, r.value()->packPath());
  EXPECT_EQ(ps[0].offset, offset);
  // S0 = (3 modules x 8 squares x 673.97 m) mod 4096 m = 16175.28 - 3 x 4096.
  EXPECT_NE(ps[0].message.find("module (3,2) level 0 square 0 upper: skin vertex 0 at x 0.000, z 0.000 has texture"),
            std::string::npos)
      << ps[0].message;
  EXPECT_NE(ps[0].message.find("from offsets 3887.280, "), std::string::npos) << ps[0].message;
  for (const auto& p : ps) EXPECT_NE(p.message.find("texture"), std::string::npos) << p.str();
}

TEST_F(HostileCli, validateShowsProgressAndStopsWhenCancelled) {
  std::vector<std::pair<std::string, double>> seen;
  Work work;
  work.progress = [&](double f, const std::string& stage) { seen.emplace_back(stage, f); };
  EXPECT_TRUE(convert::validateDatabaseWithCrs(db_, work).ok());
  std::vector<std::string> stages;
  for (const auto& [stage, f] : seen) {
    if (stages.empty() || stages.back() != stage) stages.push_back(stage);
    EXPECT_GE(f, 0.0);
    EXPECT_LE(f, 1.0);
  }
  EXPECT_EQ(stages, (std::vector<std::string>{"checking files", "checking grid", "checking pack", "checking modules"}));
  std::atomic<bool> cancel{false};
  work.cancel = &cancel;
  work.progress = [&](double, const std::string& stage) {
    if (stage == "checking pack") cancel = true;  // Ctrl-C during the pack
  };
  const auto ps = convert::validateDatabaseWithCrs(db_, work).problems();
  ASSERT_EQ(ps.size(), 1u);
  EXPECT_EQ(ps[0].message, kCancelledMessage);
  // Non-TTY progress is plain lines on stderr.
  const auto v = runCli({"validate", db_});
  EXPECT_EQ(v.exitCode, 0);
  EXPECT_NE(v.err.find("checking modules: 100%"), std::string::npos) << v.err;
  EXPECT_EQ(runCli({"validate", db_, "--json"}).err, "");
}

// ---------------------------------------------------------------- the CLI's errors

TEST_F(HostileCli, parseErrorsCarryTheCommandPrefix) {
  for (const auto& [args, prefix] : {std::pair<std::vector<std::string>, std::string>{{"build", "--bogus"}, "sandtable build: error: "},
                                     {{"info"}, "sandtable info: error: DB is required"},
                                     {{"info", db_, "--bogus"}, "sandtable info: error: The following argument was not expected: --bogus"},
                                     {{"export", db_, "--module", "1"}, "sandtable export: error: "},
                                     {{"bench", "render"}, "sandtable bench render: error: "},
                                     {{"no-such-command"}, "sandtable: error: "},
                                     {{}, "sandtable: error: A subcommand is required"}}) {
    const auto r = runCli(args);
    EXPECT_EQ(r.exitCode, 2) << r.err;
    EXPECT_EQ(r.err.rfind(prefix, 0), 0u) << r.err;
  }
}

TEST_F(HostileCli, withJsonErrorsAreOneJsonObject) {
  TempDir t("json");
  const std::string missing = t / "nope.dt1";
  const std::pair<std::vector<std::string>, std::string> cases[] = {
      {{"info", t / "nope", "--json"}, "database: not a directory"},
      {{"info", "--json"}, "DB is required"},
      {{"validate", t / "nope", "--json"}, "is not a directory"},
      {{"build", "--elevation", missing, "-o", t / "db", "--json"}, "source: file not found"},
      {{"build", "--elevation", data("elevation/dted/n43.dt0"), "--spacing", "0.001", "-o", t / "db", "--json"},
       "is too many"},
      {{"sample", db_, "--lonlat", "1", "2", "--xy", "3", "4", "--json"}, "give exactly one of"},
      {{"export", db_, "-o", t / "x.obj", "--json"}, "give exactly one of --module"},
      {{"synth", "-o", t / "s", "--size-km", "0", "--json"}, ""},
      {{"bench", "render", t / "nope", "--json"}, ""},
  };
  for (const auto& [args, needle] : cases) {
    const auto r = runCli(args);
    EXPECT_EQ(r.exitCode, 2) << args[0] << ": " << r.err;
    ASSERT_TRUE(json::accept(r.out)) << args[0] << ": stdout is not one JSON object: " << r.out;
    const json j = json::parse(r.out);
    EXPECT_FALSE(j["ok"].get<bool>());
    EXPECT_EQ(j["exit_code"].get<int>(), 2);
    EXPECT_EQ(j["command"].get<std::string>().rfind(args[0], 0), 0u) << r.out;
    ASSERT_FALSE(j["errors"].empty()) << r.out;
    EXPECT_NE(j["error"].get<std::string>().find(needle), std::string::npos) << r.out;
    // The same words on stderr, for a human.
    EXPECT_NE(r.err.find("error: "), std::string::npos) << r.err;
  }
  const auto withFile = json::parse(runCli({"build", "--elevation", missing, "-o", t / "db", "--json"}).out);
  EXPECT_EQ(withFile["errors"][0]["file"], missing);
  EXPECT_EQ(withFile["errors"][0]["offset"], 0);
}

TEST_F(HostileCli, aMissingCultureFileIsReportedAsNotFound) {
  TempDir t("culture");
  const auto r = runCli({"build", "--elevation", data("elevation/dted/n43.dt0"), "--culture", t / "roads.gpkg", "-o",
                         t / "db"});
  EXPECT_EQ(r.exitCode, 2);
  EXPECT_NE(r.err.find(t / "roads.gpkg @0: culture: file not found; check the --culture path"), std::string::npos)
      << r.err;
  EXPECT_FALSE(fs::exists(t / "db"));
}

TEST_F(HostileCli, tooManyPostsGivesTheLimitAndTheSmallestSpacingThatFits) {
  TempDir t("posts");
  const auto r = runCli({"build", "--elevation", data("elevation/dted/n43.dt0"), "--spacing", "0.01", "-o", t / "db"});
  EXPECT_EQ(r.exitCode, 2);
  EXPECT_NE(r.err.find("the limit is 4194304 posts along each axis and 4000000000 in all"), std::string::npos) << r.err;
  const auto at = r.err.find("the smallest spacing that fits this extent is ");
  ASSERT_NE(at, std::string::npos) << r.err;
  const double fitting = std::stod(r.err.substr(at + 46));
  // Independently: the extent is the database's at its native 673.97 m,
  // within a post; the bound is the total (4e9 posts) for this near-square cell.
  const auto m = manifest::readFromDirectory(db_);
  ASSERT_TRUE(m.ok());
  const double w = m->eastEasting() - m->originEasting, h = m->originNorthing - m->southNorthing();
  const double expected = std::sqrt(w * h / 4.0e9);
  EXPECT_NEAR(fitting, expected, 0.02 * expected + 0.01) << r.err;
  EXPECT_FALSE(fs::exists(t / "db"));
}

TEST_F(HostileCli, aPathHeightOutOfRangeNamesTheFileAndLine) {
  TempDir t("path");
  spit(t / "climb.path", "# up and away\n-79.5 43.5 300 speed=100\n-79.4 43.5 200000\n");
  const auto r = runCli({"fly", db_, "--path", t / "climb.path", "--png", t / "frames"});
  EXPECT_EQ(r.exitCode, 2);
  EXPECT_NE(r.err.find("sandtable fly: error: --path " + (t / "climb.path") +
                       ":3: height_m 200000 is metres above the ground and must be below 100000"),
            std::string::npos)
      << r.err;
}

// ---------------------------------------------------------------- export by a point

TEST_F(HostileCli, exportByLonLatOrXyPicksTheModuleHoldingThePoint) {
  const auto m = manifest::readFromDirectory(db_);
  ASSERT_TRUE(m.ok());
  const auto info = json::parse(runCli({"info", db_, "--json"}).out);
  const double edge = info["module_size_m"].get<double>();
  OGRSpatialReference proj, wgs;
  ASSERT_EQ(proj.importFromWkt(m->crsWkt.c_str()), OGRERR_NONE);
  wgs.SetWellKnownGeogCS("WGS84");
  proj.SetAxisMappingStrategy(OAMS_TRADITIONAL_GIS_ORDER);
  wgs.SetAxisMappingStrategy(OAMS_TRADITIONAL_GIS_ORDER);
  std::unique_ptr<OGRCoordinateTransformation> ct(OGRCreateCoordinateTransformation(&wgs, &proj));
  ASSERT_TRUE(ct);
  TempDir t("export");
  for (const auto& [lon, lat] : {std::pair{-79.5, 43.5}, std::pair{-79.95, 43.95}, std::pair{-79.1, 43.05}}) {
    double e = lon, n = lat;
    ASSERT_TRUE(ct->Transform(1, &e, &n));
    const auto kx = std::uint32_t(std::floor((e - m->originEasting) / edge));
    const auto kz = std::uint32_t(std::floor((m->originNorthing - n) / edge));
    const auto r = runCli({"export", db_, "--lonlat", std::to_string(lon), std::to_string(lat), "-o", t / "p.obj", "--json"});
    ASSERT_EQ(r.exitCode, 0) << r.err;
    const auto j = json::parse(r.out);
    EXPECT_EQ(j["modules"]["from"], json::array({kx, kz})) << lon << " " << lat << ": " << r.out;
    EXPECT_NEAR(j["point"]["easting"].get<double>(), e, 1e-3);
    // The module's origin, as export reports it, lies within one module edge west and north of the point.
    EXPECT_LE(j["origin_easting"].get<double>(), e);
    EXPECT_GT(j["origin_easting"].get<double>() + edge, e);
    const auto byXy = runCli({"export", db_, "--xy", std::to_string(e), std::to_string(n), "-o", t / "q.obj", "--json"});
    ASSERT_EQ(byXy.exitCode, 0) << byXy.err;
    EXPECT_EQ(json::parse(byXy.out)["modules"]["from"], json::array({kx, kz}));
  }
  const auto outside = runCli({"export", db_, "--lonlat", "-70", "43.5", "-o", t / "o.obj"});
  EXPECT_EQ(outside.exitCode, 2);
  EXPECT_NE(outside.err.find("--lonlat (E "), std::string::npos) << outside.err;
  EXPECT_NE(outside.err.find("is outside the database: it covers E"), std::string::npos) << outside.err;
  EXPECT_EQ(runCli({"export", db_, "--lonlat", "-79.5", "43.5", "--module", "1", "1", "-o", t / "o.obj"}).exitCode, 2);
}

}  // namespace
}  // namespace sandtable::test
