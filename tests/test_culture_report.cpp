// Culture loses nothing in silence: a GeoJSON with features of known kinds
// (lines no rule matches, figure-8 roads, a bow-tie lake, an unmatched area,
// a road far outside) is built through the CLI over a real SRTM cell, and
// the counts by reason in `build --json`, `info --json` and manifest.json
// must be the numbers this test wrote, each with a sample feature id.
#include <set>
#include <sstream>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "test_support.h"

namespace sandtable::test {
namespace {

using LonLat = std::vector<std::pair<double, double>>;

struct Written {
  std::string file;
  int unmatchedLines = 0, figure8 = 0, plain = 0, outside = 0, unmatchedAreas = 0, bowTies = 0;
  int total() const { return unmatchedLines + figure8 + plain + outside + unmatchedAreas + bowTies; }
};

std::string coords(const LonLat& p) {
  std::ostringstream o;
  o.precision(10);
  o << "[";
  for (std::size_t k = 0; k < p.size(); ++k) o << (k ? "," : "") << "[" << p[k].first << "," << p[k].second << "]";
  o << "]";
  return o.str();
}

/// The scene, in lon/lat over 11.50..11.53 E, 49.95..49.97 N. Features get
/// ids 0, 1, ... in this order, so the unmatched lines are 0, 1 and 2.
Written writeScene(const std::string& file) {
  Written w;
  w.file = file;
  std::vector<std::string> features;
  auto line = [&](const std::string& props, const LonLat& p) {
    features.push_back("{\"type\":\"Feature\",\"properties\":{" + props +
                       "},\"geometry\":{\"type\":\"LineString\",\"coordinates\":" + coords(p) + "}}");
  };
  auto polygon = [&](const std::string& props, const LonLat& ring) {
    features.push_back("{\"type\":\"Feature\",\"properties\":{" + props +
                       "},\"geometry\":{\"type\":\"Polygon\",\"coordinates\":[" + coords(ring) + "]}}");
  };
  for (int k = 0; k < 3; ++k, ++w.unmatchedLines) {  // no rule has the key "foo"; default-line is none
    line("\"foo\": \"bar\"", {{11.503, 49.952 + 0.004 * k}, {11.527, 49.953 + 0.004 * k}});
  }
  // An open Z that crosses itself, and a closed figure 8.
  line("\"highway\": \"residential\"", {{11.505, 49.955}, {11.515, 49.965}, {11.515, 49.955}, {11.505, 49.965}});
  ++w.figure8;
  line("\"highway\": \"residential\"",
       {{11.518, 49.952}, {11.526, 49.960}, {11.526, 49.952}, {11.518, 49.960}, {11.518, 49.952}});
  ++w.figure8;
  for (int k = 0; k < 2; ++k, ++w.plain) {
    line("\"highway\": \"primary\"", {{11.501 + 0.01 * k, 49.951}, {11.504 + 0.01 * k, 49.969}});
  }
  line("\"highway\": \"primary\"", {{11.90, 50.30}, {11.91, 50.31}});  // 30 km away
  ++w.outside;
  polygon("\"foo\": \"baz\"", {{11.52, 49.965}, {11.525, 49.965}, {11.525, 49.968}, {11.52, 49.968}, {11.52, 49.965}});
  ++w.unmatchedAreas;
  polygon("\"natural\": \"water\"",
          {{11.501, 49.966}, {11.509, 49.969}, {11.509, 49.966}, {11.501, 49.969}, {11.501, 49.966}});
  ++w.bowTies;
  std::string text = "{\"type\":\"FeatureCollection\",\"features\":[\n";
  for (std::size_t k = 0; k < features.size(); ++k) text += (k ? ",\n" : "") + features[k];
  spit(file, text + "\n]}\n");
  return w;
}

/// The culture object's reasons against what was written.
void expectReasons(const nlohmann::json& culture, const Written& w, const std::string& where) {
  SCOPED_TRACE(where);
  ASSERT_TRUE(culture.is_object()) << culture.dump(2);
  EXPECT_EQ(culture.value("features_read", 0), w.total());
  EXPECT_EQ(culture.value("features_outside", 0), w.outside);
  // A warning each: unmatched lines, figure 8s, the defaulted area, the bow tie.
  EXPECT_EQ(culture.value("warnings", 0), w.unmatchedLines + w.figure8 + w.unmatchedAreas + w.bowTies);
  const auto& r = culture["reasons"];
  ASSERT_TRUE(r.is_object()) << culture.dump(2);
  std::set<std::string> keys;
  for (const auto& [k, v] : r.items()) keys.insert(k);
  EXPECT_EQ(keys, (std::set<std::string>{"unmatched_line", "self_intersecting_line", "no_rule_default",
                                         "invalid_polygon_repaired", "outside"}))
      << r.dump(2);
  auto expect = [&](const char* key, int count, const char* action, bool warning) {
    SCOPED_TRACE(key);
    if (!r.contains(key)) return;
    const auto& e = r[key];
    EXPECT_EQ(e.value("count", 0), count);
    EXPECT_EQ(e.value("action", ""), action);
    EXPECT_EQ(e.value("warning", !warning), warning);
    EXPECT_NE(e.value("sample", "").find("scene.geojson layer scene feature "), std::string::npos) << e.dump();
    EXPECT_FALSE(e.value("text", "").empty());
  };
  expect("unmatched_line", w.unmatchedLines, "dropped", true);
  expect("self_intersecting_line", w.figure8, "repaired", true);
  expect("no_rule_default", w.unmatchedAreas, "defaulted", true);
  expect("invalid_polygon_repaired", w.bowTies, "repaired", true);
  expect("outside", w.outside, "dropped", false);
  // The samples are the first feature of each kind.
  EXPECT_EQ(r["unmatched_line"].value("sample", "").substr(r["unmatched_line"].value("sample", "").rfind(' ') + 1), "0");
  EXPECT_EQ(r["self_intersecting_line"].value("sample", "").substr(r["self_intersecting_line"].value("sample", "").rfind(' ') + 1),
            std::to_string(w.unmatchedLines));
  // Per class: both figure 8s are streets, read and repaired.
  EXPECT_EQ(culture["classes"]["street"].value("read", 0), w.figure8);
  EXPECT_EQ(culture["classes"]["street"].value("repaired", 0), w.figure8);
  EXPECT_EQ(culture["classes"]["primary"].value("repaired", 0), 0);
}

TEST(CultureReport, droppedRepairedAndDefaultedFeaturesAreCountedEverywhere) {
  SANDTABLE_REQUIRE_DATA();
  TempDir tmp("culture-report");
  const Written w = writeScene(tmp / "scene.geojson");
  const std::string db = tmp / "db";
  const auto b = runCli({"build", "--elevation", data("elevation/srtm/N49E011.hgt.zip"), "--culture", w.file,
                         "--extent", "11.50", "49.95", "11.53", "49.97", "--spacing", "30", "--json", "-o", db});
  ASSERT_EQ(b.exitCode, 0) << b.err;
  const auto built = nlohmann::json::parse(b.out);
  expectReasons(built["culture"], w, "build --json");

  const auto i = runCli({"info", db, "--json"});
  ASSERT_EQ(i.exitCode, 0) << i.err;
  expectReasons(nlohmann::json::parse(i.out)["culture"], w, "info --json");

  const auto manifest = nlohmann::json::parse(slurpFile(db + "/manifest.json"));
  expectReasons(manifest["build"]["culture"], w, "manifest.json");

  // The human forms: one line per reason, with the count and a sample.
  const auto h = runCli({"info", db});
  ASSERT_EQ(h.exitCode, 0) << h.err;
  EXPECT_NE(h.out.find("warning: 3 features dropped: line whose attributes match no rule"), std::string::npos)
      << h.out;
  EXPECT_NE(h.out.find("warning: 2 features repaired: line that crosses or touches itself"), std::string::npos)
      << h.out;
  EXPECT_NE(h.out.find("feature 0)"), std::string::npos) << h.out;
  EXPECT_NE(h.out.find("note: 1 feature dropped: wholly outside the database"), std::string::npos) << h.out;
  const auto hb = runCli({"build", "--elevation", data("elevation/srtm/N49E011.hgt.zip"), "--culture", w.file,
                          "--extent", "11.50", "49.95", "11.53", "49.97", "--spacing", "30", "-o", tmp / "db2"});
  ASSERT_EQ(hb.exitCode, 0) << hb.err;
  EXPECT_NE(hb.out.find("warning: 3 features dropped: line whose attributes match no rule"), std::string::npos)
      << hb.out;
  EXPECT_NE(hb.out.find("warning: 2 features repaired: line that crosses or touches itself"), std::string::npos)
      << hb.out;
}

}  // namespace
}  // namespace sandtable::test
