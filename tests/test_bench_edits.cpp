// `sandtable bench edits --quick --json` runs every part and prints the
// keys docs/DYNAMIC.md ("Benchmark") names. A smoke test: no timing is
// checked, only the shape and the counts that follow from the options.
#include <gtest/gtest.h>

#include "test_support.h"

namespace sandtable::test {
namespace {

void expectSpread(const nlohmann::json& s, const char* what) {
  for (const char* k : {"p50", "p95", "max"}) EXPECT_TRUE(s.at(k).is_number()) << what << "." << k;
  EXPECT_LE(s["p50"].get<double>(), s["max"].get<double>()) << what;
}

TEST(BenchEdits, quickJsonRunsEveryPartAndPrintsTheKeys) {
  const auto r = runCli({"bench", "edits", "--quick", "--json"});
  ASSERT_EQ(r.exitCode, 0) << r.err;
  const auto j = nlohmann::json::parse(r.out);
  for (const char* key : {"database", "synthesized", "spacing_m", "module_size_m", "modules", "levels", "baseline",
                          "remesh", "journal", "memory", "pager", "latency", "sustained", "max_sustained_rate_per_s",
                          "battle", "goals"}) {
    EXPECT_TRUE(j.contains(key)) << key;
  }
  EXPECT_TRUE(j["synthesized"].get<bool>());
  // A crater inside a square, on a module edge and on a module corner.
  ASSERT_EQ(j["remesh"].size(), 3u);
  const unsigned expected[] = {1, 2, 4};
  for (std::size_t k = 0; k < 3; ++k) {
    const auto& c = j["remesh"][k];
    EXPECT_EQ(c["modules"].get<unsigned>(), expected[k]);
    EXPECT_EQ(c["cpu_runs_ms"].size(), 3u);  // --quick: 3 repeats
    for (const char* f : {"cold_ms", "cpu_ms", "wall_ms", "baseline_cpu_ms", "baseline_over_remesh"}) {
      EXPECT_GT(c[f].get<double>(), 0) << f;
    }
  }
  const auto& jr = j["journal"];
  EXPECT_EQ(jr["edits"].get<unsigned>(), 2000u);
  EXPECT_EQ(jr["meshed"]["edits"].get<unsigned>(), 20u);
  EXPECT_GT(jr["replay_per_100k_s"].get<double>(), 0);
  EXPECT_EQ(j["memory"]["craters"].get<unsigned>(), 20u);
  EXPECT_GT(j["memory"]["heights_bytes"].get<double>(), 0);
  EXPECT_GT(j["memory"]["modules_remeshed"].get<unsigned>(), 0u);
  const auto& l = j["latency"];
  EXPECT_EQ(l["samples"].get<unsigned>(), 3u);
  // Drawn within the 5 s a sample may wait: timing, so not checked beyond its bound.
  EXPECT_LE(l["drawn"].get<unsigned>(), 3u);
  for (const char* s : {"worker_cpu_ms", "published_ms", "drawn_ms", "drawn_frames_60hz"}) expectSpread(l[s], s);
  ASSERT_EQ(j["sustained"].size(), 1u);  // --quick: one rate
  const auto& s = j["sustained"][0];
  EXPECT_EQ(s["rate_per_s"].get<double>(), 30);
  EXPECT_EQ(s["craters"].get<unsigned>(), 15u);  // 30/s for 0.5 s
  EXPECT_TRUE(s["keeps_up"].is_boolean());
  expectSpread(s["latency_frames"], "latency_frames");
  const auto& b = j["battle"];
  EXPECT_EQ(b["craters"].get<unsigned>(), 100u);
  EXPECT_TRUE(b["holes"].is_number_unsigned());
  EXPECT_EQ(b["undrawn"].get<unsigned>(), 0u);
  for (const char* g : {"worker_ms_per_crater_4_modules", "journal_replay_per_100k", "drawn_frames_max", "battle_holes",
                        "battle_frames_over_budget", "battle_craters"}) {
    ASSERT_TRUE(j["goals"].contains(g)) << g;
    EXPECT_TRUE(j["goals"][g]["met"].is_boolean()) << g;
  }
}

TEST(BenchEdits, badOptionsAreUsageErrorsNamingTheFlag) {
  const auto r = runCli({"bench", "edits", "--size-km", "2"});
  EXPECT_EQ(r.exitCode, 2);
  EXPECT_NE(r.err.find("--size-km"), std::string::npos) << r.err;
}

}  // namespace
}  // namespace sandtable::test
