// Manifest v1: golden text, round trip, every truncated prefix, hostile values.
#include <gtest/gtest.h>

#include "sandtable/formats/bytes.h"
#include "sandtable/formats/manifest.h"

namespace sandtable::manifest {
namespace {

Manifest sample() {
  Manifest m;
  m.toolVersion = "0.1.0";
  m.createdUtc = "2026-11-22T00:00:00Z";
  m.crsWkt = "PROJCRS[\"WGS 84 / UTM zone 32N\"]";
  m.crsName = "WGS 84 / UTM zone 32N";
  m.epsg = 32632;
  m.originEasting = 500000;
  m.originNorthing = 4000000;
  m.spacing = 30;
  m.postsX = 3;
  m.postsZ = 2;
  m.minElevation = 0;
  m.maxElevation = 21;
  m.cornersLonLat = {{{9.0, 36.1}, {9.001, 36.1}, {9.001, 36.09}, {9.0, 36.09}}};
  m.files.push_back({kGridFileName, 53248, 0xe847c078});
  m.sources.push_back({"/data/n36.dt1", 2902642, 0x01020304, "DTED"});
  m.build = {{"resample", "weighted"}};
  return m;
}

std::span<const std::byte> asBytes(const std::string& s) { return std::as_bytes(std::span(s.data(), s.size())); }

// Golden text of version 1. If this fails, the manifest changed: bump
// kVersion, keep reading version 1, and add a new golden test.
TEST(Manifest, version1GoldenText) {
  const std::string text = encode(sample());
  EXPECT_EQ(crcHex(crc32(asBytes(text))), "0x1b9792f3") << text;
  EXPECT_NE(text.find("\"checksum\": \"0xe3868f45\""), std::string::npos) << text;
  EXPECT_NE(text.find("\"format\": \"sandtable-manifest\""), std::string::npos);
  EXPECT_NE(text.find("\"version\": 1"), std::string::npos);
}

TEST(Manifest, roundTrips) {
  const std::string text = encode(sample());
  auto m = decode(asBytes(text), "manifest.json");
  ASSERT_TRUE(m.ok()) << m.error();
  EXPECT_EQ(m->postsX, 3u);
  EXPECT_EQ(m->epsg, 32632);
  EXPECT_EQ(m->files.at(0).crc, 0xe847c078u);
  EXPECT_EQ(m->sources.at(0).driver, "DTED");
  EXPECT_DOUBLE_EQ(m->cornersLonLat[1][0], 9.001);
  EXPECT_EQ(encode(m.value()), text);
}

TEST(Manifest, everyTruncatedPrefixFails) {
  const std::string text = encode(sample());
  for (std::size_t n = 0; n + 1 < text.size(); ++n) {  // the last byte is a newline
    auto m = decode(asBytes(text.substr(0, n)), "m.json");
    ASSERT_FALSE(m.ok()) << "prefix " << n;
    EXPECT_EQ(m.problems().front().file, "m.json");
    EXPECT_LE(m.problems().front().offset, n + 1);  // the parser reports one past the end
  }
}

TEST(Manifest, hostileValuesAreProblemsNotExceptions) {
  const std::string good = encode(sample());
  struct Case {
    std::string from, to, expected;
  };
  const Case cases[] = {
      {"\"crc32\": \"0xe847c078\"", "\"crc32\": \"0xzzzzzzzz\"", "8 lowercase hex digits"},
      {"\"format\": \"sandtable-manifest\"", "\"format\": 5", "this is not a sandtable database"},
      {"\"version\": 1", "\"version\": 4294967297", "version 4294967297 is not supported"},
      {"\"version\": 1", "\"version\": 1.5", "not a whole number"},
      {"\"posts_x\": 3", "\"posts_x\": 99999999999", "posts_x is out of range"},
      {"\"posts_x\": 3", "\"posts_x\": -3", "posts_x has the wrong type"},
      {"\"spacing_m\": 30.0", "\"spacing_m\": \"30\"", "spacing_m has the wrong type"},
      {"\"files\": [", "\"files\": [7, ", "entries must be objects"},
      {"\"spacing_m\": 30.0", "\"spacing_m\": 1e400", "not valid JSON"},
  };
  for (const auto& c : cases) {
    std::string text = good;
    const auto at = text.find(c.from);
    ASSERT_NE(at, std::string::npos) << c.from;
    text.replace(at, c.from.size(), c.to);
    Result<Manifest> m = Problem{};
    EXPECT_NO_THROW(m = decode(asBytes(text), "m.json")) << c.to;
    ASSERT_FALSE(m.ok()) << c.to;
    bool found = false;
    for (const auto& p : m.problems()) found = found || p.message.find(c.expected) != std::string::npos;
    EXPECT_TRUE(found) << c.to << " gave: " << m.error();
  }
}

}  // namespace
}  // namespace sandtable::manifest
