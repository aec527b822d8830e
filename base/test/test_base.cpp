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

TEST(Jobs, orderedPipelineFinishesInIndexOrder) {
  for (const int threads : {1, 2, 0}) {
    const std::size_t n = 500, inFlight = 4;
    std::vector<std::atomic<int>> worked(n);
    std::vector<std::size_t> order;
    std::atomic<int> live{0}, mostLive{0}, finishing{0};
    bool overlapped = false;
    jobs::orderedPipeline<std::size_t>(
        n, threads, inFlight,
        [&](std::size_t i) {
          const int now = ++live;
          int m = mostLive.load();
          while (now > m && !mostLive.compare_exchange_weak(m, now)) {}
          worked[i]++;
          return i * i;
        },
        [&](std::size_t i, std::size_t&& square) {
          if (++finishing != 1) overlapped = true;
          EXPECT_EQ(square, i * i);
          order.push_back(i);
          --finishing;
          --live;
        });
    std::vector<std::size_t> want(n);
    std::iota(want.begin(), want.end(), std::size_t{0});
    EXPECT_EQ(order, want) << "threads " << threads;
    for (auto& w : worked) ASSERT_EQ(w.load(), 1);
    EXPECT_FALSE(overlapped) << "finish ran concurrently with itself";
    EXPECT_LE(mostLive.load(), int(inFlight));
  }
}

TEST(Jobs, orderedPipelineCancelFinishesWhatItStarted) {
  std::atomic<bool> cancel{false};
  std::atomic<int> worked{0};
  int finished = 0;
  std::size_t last = 0;
  jobs::orderedPipeline(
      100000, 2, 8,
      [&](std::size_t i) {
        worked++;
        if (i == 20) cancel = true;
      },
      [&](std::size_t i) {
        ++finished;
        last = i;
      },
      &cancel);
  EXPECT_LT(worked.load(), 100000);
  EXPECT_EQ(finished, worked.load());
  EXPECT_EQ(last + 1, std::size_t(finished));  // no gap: items 0..last
}

TEST(Jobs, scratchIsNeverShared) {
  struct State {
    std::atomic<int> users{0};
    int uses = 0;
  };
  jobs::Scratch<State> scratch;
  std::atomic<int> made{0}, shared{0};
  jobs::parallelFor(2000, 2, [&](std::size_t) {
    scratch.use([&](State& s) {
      if (s.users++ != 0) shared++;
      if (s.uses++ == 0) made++;
      --s.users;
    });
  });
  EXPECT_EQ(shared.load(), 0);
  EXPECT_GE(made.load(), 1);
  EXPECT_LE(made.load(), 2);  // at most one per worker of the two
}

TEST(Jobs, bothRunsBoth) {
  std::atomic<int> a{0}, b{0};
  jobs::both(2, [&] { a = 1; }, [&] { jobs::parallelFor(10, 0, [&](std::size_t) { b++; }); });
  EXPECT_EQ(a.load(), 1);
  EXPECT_EQ(b.load(), 10);
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

namespace sandtable {
namespace {

TEST(SerialQueue, itemsRunOneAtATimeInTheOrderSubmitted) {
  jobs::SerialQueue q;
  std::vector<int> order;
  std::atomic<int> running{0}, most{0};
  for (int k = 0; k < 200; ++k) {
    q.submit([&, k] {
      const int now = ++running;
      most = std::max(most.load(), now);
      order.push_back(k);
      --running;
    });
  }
  q.wait();
  EXPECT_EQ(q.pending(), 0u);
  ASSERT_EQ(order.size(), 200u);
  for (int k = 0; k < 200; ++k) EXPECT_EQ(order[std::size_t(k)], k);
  EXPECT_EQ(most.load(), 1);
}

TEST(SerialQueue, submitsFromManyThreadsAllRun) {
  jobs::SerialQueue q;
  std::atomic<int> ran{0};
  jobs::parallelFor(64, 0, [&](std::size_t) { q.submit([&] { ++ran; }); });
  q.wait();
  EXPECT_EQ(ran.load(), 64);
}

}  // namespace
}  // namespace sandtable
