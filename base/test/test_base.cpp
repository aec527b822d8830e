// Result/Status semantics, the job system's coverage and cancellation,
// and the percentile definitions the reports rely on.
#include <gtest/gtest.h>

#include <atomic>
#include <numeric>
#include <vector>

#include "sandtable/base/jobs.h"
#include "sandtable/base/result.h"
#include "sandtable/base/stats.h"

using namespace sandtable;

TEST(Result, valueAndWarningsTravelTogether) {
  Result<int> r(42);
  r.addWarning({"a.shp", 7, "culture: feature 3 repaired"});
  ASSERT_TRUE(r.ok());
  EXPECT_EQ(r.value(), 42);
  ASSERT_EQ(r.warnings().size(), 1u);
  EXPECT_EQ(r.warnings()[0].str(), "a.shp @7: culture: feature 3 repaired");
  EXPECT_TRUE(r.problems().empty());
}

TEST(Result, emptyProblemListIsStillAFailure) {
  Result<int> r(std::vector<Problem>{});
  EXPECT_FALSE(r.ok());
  EXPECT_EQ(r.problems().size(), 1u);
  EXPECT_NE(r.error(), "");
}

TEST(Status, okUntilAProblemIsAdded) {
  Status s;
  EXPECT_TRUE(s.ok());
  s.addWarning({"f", 0, "w"});
  EXPECT_TRUE(s.ok());
  s.add(Problem{"f", 12, "grid: truncated"});
  EXPECT_FALSE(s.ok());
  EXPECT_EQ(s.error(), "f @12: grid: truncated");
  EXPECT_TRUE(Status(std::vector<Problem>{}).ok());
}

TEST(Status, messageIsTheFirstProblemWithoutItsPlace) {
  Status s;
  EXPECT_EQ(s.message(), "");
  s.add(Problem{"x.tmp", 5, "No space left on device"});
  s.add(Problem{"y", 0, "second"});
  EXPECT_EQ(s.message(), "No space left on device");
  EXPECT_EQ(s.error(), "x.tmp @5: No space left on device");
}

TEST(Status, mergeKeepsEveryProblemAndWarningInOrder) {
  Status all;
  all.add(Problem{"a", 1, "first"});
  Status sub;
  sub.addWarning({"b", 2, "defaulted"});
  all.merge(sub);
  EXPECT_EQ(all.problems().size(), 1u);  // a sound sub-check adds no problem
  Result<int> failed(Problem{"c", 3, "second"});
  failed.addWarning({"c", 4, "repaired"});
  all.merge(failed);
  ASSERT_EQ(all.problems().size(), 2u);
  EXPECT_EQ(all.problems()[1].str(), "c @3: second");
  ASSERT_EQ(all.warnings().size(), 2u);
  EXPECT_EQ(all.warnings()[0].message, "defaulted");
  EXPECT_EQ(all.warnings()[1].message, "repaired");
}

TEST(Jobs, everyIndexRunsOnce) {
  for (int threads : {1, 2, 0}) {
    std::vector<std::atomic<int>> hits(1000);
    jobs::parallelFor(hits.size(), threads, [&](std::size_t i) { hits[i]++; });
    for (auto& h : hits) ASSERT_EQ(h.load(), 1) << "threads " << threads;
  }
  std::vector<std::atomic<int>> hits(10007);
  jobs::parallelRanges(hits.size(), 0, 64, [&](std::size_t b, std::size_t e) {
    for (std::size_t i = b; i < e; ++i) hits[i]++;
  });
  for (auto& h : hits) ASSERT_EQ(h.load(), 1);
}

TEST(Jobs, cancelSkipsWorkNotStarted) {
  std::atomic<bool> cancel{false};
  std::atomic<int> ran{0};
  jobs::parallelFor(100000, 2, [&](std::size_t i) {
    ran++;
    if (i == 10) cancel = true;
  }, &cancel);
  EXPECT_LT(ran.load(), 100000);
}

TEST(Jobs, threadLimitIsHonoured) {
  std::atomic<int> inside{0}, most{0};
  jobs::parallelFor(64, 1, [&](std::size_t) {
    const int now = ++inside;
    int m = most.load();
    while (now > m && !most.compare_exchange_weak(m, now)) {}
    --inside;
  });
  EXPECT_EQ(most.load(), 1);
  EXPECT_EQ(jobs::threadCount(3), 3);
  EXPECT_GE(jobs::threadCount(0), 1);
}

TEST(Stats, nearestRankAndMedian) {
  // Independent: nearest rank of p=0.9 over 1..10 is the 9th value.
  std::vector<double> v(10);
  std::iota(v.begin(), v.end(), 1.0);
  EXPECT_EQ(stats::percentile(v, 0.9), 9.0);
  EXPECT_EQ(stats::percentile(v, 1.0), 10.0);
  EXPECT_EQ(stats::percentile(v, 0.0), 1.0);
  EXPECT_EQ(stats::median({3, 1, 2}), 2.0);
  EXPECT_EQ(stats::median({4, 1, 3, 2}), 2.5);
  EXPECT_EQ(stats::median({}), 0.0);
}
