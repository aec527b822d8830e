// validate on a real (small) database: flipped bytes, truncation at every
// structural boundary, hand-edited manifests; each with its own message.
#include <zlib.h>

#include <fstream>
#include <random>
#include <sstream>

#include <nlohmann/json.hpp>

#include "sandtable/converters/elevation.h"
#include "sandtable/formats/bytes.h"
#include "sandtable/formats/database.h"
#include "sandtable/formats/grid.h"
#include "test_support.h"

namespace sandtable::test {
namespace {

namespace fs = std::filesystem;


bool anyMessageHas(const std::vector<Problem>& ps, const std::string& needle) {
  for (const auto& p : ps) {
    if (p.message.find(needle) != std::string::npos) return true;
  }
  return false;
}

class ValidateRealDatabase : public ::testing::Test {
 protected:
  void SetUp() override {
    SANDTABLE_REQUIRE_DATA();
    convert::ElevationOptions o;
    o.sources = {data("elevation/dted/n43.dt0")};
    o.output = tmp_ / "db";
    auto r = convert::buildElevation(o, nullptr);
    ASSERT_TRUE(r.ok()) << r.error();
    db_ = o.output;
    gridPath_ = db_ + "/grid.stg";
    manifestPath_ = db_ + "/manifest.json";
    ASSERT_TRUE(validateDatabase(db_).ok());
  }
  TempDir tmp_{"val"};
  std::string db_, gridPath_, manifestPath_;
};

TEST_F(ValidateRealDatabase, catchesEachOfAThousandRandomByteFlips) {
  const std::string original = slurpFile(gridPath_);
  ASSERT_LT(original.size(), 1u << 20) << "the test wants a small grid file";
  std::mt19937 rng(2026);
  std::uniform_int_distribution<std::size_t> at(0, original.size() - 1);
  std::uniform_int_distribution<int> bit(0, 7);
  int missed = 0;
  for (int k = 0; k < 1000; ++k) {
    std::string bytes = original;
    const std::size_t off = at(rng);
    bytes[off] = static_cast<char>(bytes[off] ^ (1 << bit(rng)));
    spit(gridPath_, bytes);
    const auto problems = validateDatabase(db_).problems();
    if (problems.empty()) {
      ++missed;
      ADD_FAILURE() << "flip at byte " << off << " was not caught";
    }
  }
  spit(gridPath_, original);
  EXPECT_EQ(missed, 0);
  EXPECT_TRUE(validateDatabase(db_).ok());
}

TEST_F(ValidateRealDatabase, catchesTruncationAtEveryStructuralBoundary) {
  const std::string original = slurpFile(gridPath_);
  auto g = grid::GridFile::open(gridPath_);
  ASSERT_TRUE(g.ok());
  const grid::Header h = g.value()->header();
  g = Problem{};  // unmap before rewriting the file
  std::vector<std::uint64_t> cuts = {0, 4, 8, 12, 64, grid::kHeaderFieldBytes - 1, grid::kHeaderFieldBytes,
                                     grid::kPageBytes, h.blockTableOffset + h.blockCount() * grid::kBlockEntryBytes,
                                     h.dataOffset};
  for (std::uint64_t b = 0; b < h.blockCount(); ++b) {
    const std::uint64_t base = h.dataOffset + b * grid::kBlockBytes;
    for (std::uint64_t plane : {grid::kNormalXPlane, grid::kNormalYPlane, grid::kNormalZPlane, grid::kMaterialPlane}) {
      cuts.push_back(base + plane);
    }
    cuts.push_back(base + grid::kBlockBytes);
  }
  cuts.back() = h.fileBytes - 1;
  for (std::uint64_t cut : cuts) {
    spit(gridPath_, original.substr(0, cut));
    const auto problems = validateDatabase(db_).problems();
    ASSERT_FALSE(problems.empty()) << "truncation at " << cut;
    EXPECT_TRUE(anyMessageHas(problems, "truncated")) << "cut " << cut << ": " << problems.front().str();
    bool named = false;
    for (const auto& p : problems) named = named || (p.file == gridPath_ && p.offset <= cut);
    EXPECT_TRUE(named) << "no problem names the grid file and an offset within it, cut " << cut;
  }
  spit(gridPath_, original);
}

TEST_F(ValidateRealDatabase, eachDamageHasItsOwnMessage) {
  const std::string manifest = slurpFile(manifestPath_);
  const std::string gridBytes = slurpFile(gridPath_);
  struct Case {
    const char* what;
    std::function<void()> damage;
    const char* expected;
  };
  const Case cases[] = {
      {"hand-edited manifest", [&] {
         std::string m = manifest;
         const auto p = m.find("\"levels\": 4");
         ASSERT_NE(p, std::string::npos);
         m.replace(p, 11, "\"levels\": 5");
         spit(manifestPath_, m);
       }, "the manifest was edited or corrupted"},
      {"manifest not JSON", [&] { spit(manifestPath_, manifest.substr(0, manifest.size() / 2)); }, "not valid JSON"},
      {"manifest missing", [&] { fs::remove(manifestPath_); }, "cannot open"},
      {"grid block flipped", [&] {
         std::string b = gridBytes;
         b[b.size() - 100] = static_cast<char>(b[b.size() - 100] ^ 1);
         spit(gridPath_, b);
       }, "checksum mismatch"},
      {"grid header flipped", [&] {
         std::string b = gridBytes;
         b[20] = static_cast<char>(b[20] ^ 1);
         spit(gridPath_, b);
       }, "header checksum mismatch"},
      {"grid grown", [&] { spit(gridPath_, gridBytes + "x"); }, "trailing bytes"},
      {"grid replaced", [&] { spit(gridPath_, "not a grid at all, but long enough to hold a header......................................................................................................................................."); }, "bad magic"},
  };
  for (const auto& c : cases) {
    c.damage();
    const auto problems = validateDatabase(db_).problems();
    EXPECT_TRUE(anyMessageHas(problems, c.expected)) << c.what << ": "
                                                      << (problems.empty() ? "no problem" : problems.front().str());
    spit(manifestPath_, manifest);
    spit(gridPath_, gridBytes);
  }
  EXPECT_TRUE(validateDatabase(db_).ok());
}

TEST_F(ValidateRealDatabase, cliExitCodes) {
  auto ok = runCli({"validate", db_});
  EXPECT_EQ(ok.exitCode, 0) << ok.err;
  std::string b = slurpFile(gridPath_);
  b[5000] = static_cast<char>(b[5000] ^ 0x10);
  spit(gridPath_, b);
  auto bad = runCli({"validate", db_, "--json"});
  EXPECT_EQ(bad.exitCode, 1);
  EXPECT_NE(bad.out.find("\"ok\": false"), std::string::npos) << bad.out;
  EXPECT_NE(bad.out.find("\"offset\""), std::string::npos);
  EXPECT_EQ(runCli({"validate", tmp_ / "nope"}).exitCode, 2);
}

TEST_F(ValidateRealDatabase, gridCorruptionUnderAResealedManifestIsCaughtByTheGridCheck) {
  // One post's byte in block (0,0) changed, then the manifest's grid.stg
  // CRC recomputed (zlib, here) and the manifest resealed: the whole-file
  // check now passes, so only validateGrid's own block CRCs can catch it.
  std::string b = slurpFile(gridPath_);
  std::uint64_t dataOffset = 0;
  for (int k = 7; k >= 0; --k) dataOffset = dataOffset << 8 | std::uint8_t(b[grid::field::dataOffset + std::size_t(k)]);
  ASSERT_GT(dataOffset, 0u);
  ASSERT_LT(dataOffset + 1000, b.size());
  b[dataOffset + 1000] = static_cast<char>(b[dataOffset + 1000] ^ 0x04);
  spit(gridPath_, b);
  const auto crc = static_cast<std::uint32_t>(::crc32(0L, reinterpret_cast<const Bytef*>(b.data()), uInt(b.size())));
  char hex[16];
  std::snprintf(hex, sizeof hex, "0x%08x", crc);
  resealManifest(db_, [&](nlohmann::json& j) {
    for (auto& f : j["files"]) {
      if (f["path"] == "grid.stg") f["crc32"] = hex;
    }
  });

  const Status problems = validateDatabase(db_);
  ASSERT_FALSE(problems.ok());
  for (const Problem& p : problems.problems()) {
    EXPECT_EQ(p.message.find("manifest"), std::string::npos) << "the manifest should now agree: " << p.str();
    EXPECT_EQ(p.message.find("crc32"), std::string::npos) << p.str();
  }
  const Status gridProblems = grid::validateGrid(gridPath_);
  ASSERT_FALSE(gridProblems.ok());
  bool named = false;
  for (const Problem& p : gridProblems.problems()) {
    named |= p.message.find("block (0,0) checksum mismatch") != std::string::npos && p.offset == dataOffset;
  }
  EXPECT_TRUE(named) << gridProblems.error();

  // And through the CLI: exit 1, the block named at its offset in grid.stg.
  const auto v = runCli({"validate", db_, "--json"});
  EXPECT_EQ(v.exitCode, 1) << v.out << v.err;
  const auto report = nlohmann::json::parse(v.out);
  EXPECT_FALSE(report["ok"].get<bool>());
  bool cli = false;
  for (const auto& p : report["problems"]) {
    cli |= p.value("message", "").find("block (0,0) checksum mismatch") != std::string::npos &&
           p.value("offset", std::uint64_t(0)) == dataOffset && p.value("file", "").find("grid.stg") != std::string::npos;
  }
  EXPECT_TRUE(cli) << v.out;
}

}  // namespace
}  // namespace sandtable::test
