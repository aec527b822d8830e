// `sandtable bench dis --quick --json` runs and prints every key the docs
// (docs/DIS.md §12) name. A smoke test: no timing is checked, only that
// each part ran and its counts add up.
#include <gtest/gtest.h>

#include "test_support.h"

namespace sandtable::test {
namespace {

TEST(BenchDis, quickJsonRunsAndPrintsTheKeys) {
  const auto r = runCli({"bench", "dis", "--quick", "--json", "--repeat", "1"});
  ASSERT_EQ(r.exitCode, 0) << r.err;
  const auto j = nlohmann::json::parse(r.out);
  for (const char* key : {"options", "memory", "loopback", "dead_reckoning", "table9", "watch", "viewer_measured", "notes"}) {
    EXPECT_TRUE(j.contains(key)) << key;
  }
  const auto& m = j["memory"];
  for (const char* part : {"decode", "apply", "create"}) {
    EXPECT_GT(m[part]["per_s"].get<double>(), 0) << part;
  }
  EXPECT_GT(m["apply_over_decode"].get<double>(), 0);
  EXPECT_TRUE(m["meets_goal"].is_boolean());
  const auto& l = j["loopback"];
  EXPECT_GT(l["apply"]["per_s"].get<double>(), 0);
  EXPECT_GT(l["receive"]["per_s"].get<double>(), 0);
  for (const char* which : {"latency_blast", "latency_paced"}) {
    EXPECT_GT(l[which]["applied"]["samples"].get<std::uint64_t>(), 0u) << which;
    EXPECT_GE(l[which]["applied"]["p99_ms"].get<double>(), l[which]["applied"]["p50_ms"].get<double>()) << which;
  }
  EXPECT_TRUE(l["drops"].contains("kernel"));
  EXPECT_TRUE(l["drops"].contains("queue"));
  ASSERT_EQ(j["dead_reckoning"].size(), 1u);
  EXPECT_GT(j["dead_reckoning"][0]["state_at"]["per_s"].get<double>(), 0);
  EXPECT_TRUE(j["dead_reckoning"][0]["fits_60hz"].is_boolean());
  ASSERT_EQ(j["watch"].size(), 1u);
  EXPECT_TRUE(j["watch"][0]["fits_30fps"].is_boolean());
  EXPECT_FALSE(j["viewer_measured"].get<bool>());
  const auto& ex = j["table9"]["exercises"];
  ASSERT_EQ(ex.size(), 1u);
  EXPECT_EQ(ex[0]["error_based"].size(), 12u);  // 4 thresholds x 3 air algorithms
  EXPECT_EQ(ex[0]["time_based"].size(), 3u);    // the seed's 1/15, 1 and 5 s
  // Time-based sending every 1/15 s sends a PDU per entity every 4 steps.
  EXPECT_NEAR(ex[0]["time_based"][0]["pdus_per_entity_s"].get<double>(), 15, 0.5);
  for (const auto& c : ex[0]["error_based"]) EXPECT_GT(c["pdus"].get<std::uint64_t>(), 0u);
}

TEST(BenchDis, badSizesAreUsageErrors) {
  const auto r = runCli({"bench", "dis", "--pdus-per-entity", "1"});
  EXPECT_EQ(r.exitCode, 2);
  EXPECT_NE(r.err.find("--pdus-per-entity"), std::string::npos) << r.err;
}

}  // namespace
}  // namespace sandtable::test
