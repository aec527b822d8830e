// CappedProblems: what is kept, what is counted, and the summary lines,
// against counts worked by hand.
#include <gtest/gtest.h>

#include <string>

#include "sandtable/base/capped_problems.h"

using namespace sandtable;

TEST(CappedProblems, keepsTheFirstCapOfEachKindAndSumsUpTheRest) {
  CappedProblems<> c(3);
  for (int k = 0; k < 5; ++k) c.add("zeta", Problem{"z.bin", std::uint64_t(k), std::to_string(k)});
  c.add("alpha", Problem{"a.bin", 9, "a0"});
  for (int k = 0; k < 4; ++k) c.add("beta", Problem{k == 0 ? "first.bin" : "later.bin", 0, "b"});
  const Status s = c.take("grid");
  // 3 zeta + 1 alpha + 3 beta kept, in the order added; then one line per
  // kind over the cap, alphabetically, naming the kind's first file.
  ASSERT_EQ(s.problems().size(), 9u);
  EXPECT_EQ(s.problems()[0].message, "0");
  EXPECT_EQ(s.problems()[2].message, "2");
  EXPECT_EQ(s.problems()[3].message, "a0");
  EXPECT_EQ(s.problems()[7].str(), "first.bin @0: grid: 1 more beta problems not listed");
  EXPECT_EQ(s.problems()[8].str(), "z.bin @0: grid: 2 more zeta problems not listed");
}

TEST(CappedProblems, wantCountsWithoutKeepingAndEnumKindsSumUpInDeclarationOrder) {
  enum Kind { second, first };
  CappedProblems<Kind> c(1);
  int formatted = 0;
  for (int k = 0; k < 3; ++k) formatted += c.want(first, "m.pack");
  for (int k = 0; k < 2; ++k) formatted += c.want(second, "m.pack");
  EXPECT_EQ(formatted, 2);
  Status out;
  c.appendSummary(out, "module check: module (0,0)", 77, [](Kind k) { return k == first ? "first" : "second"; });
  ASSERT_EQ(out.problems().size(), 2u);
  EXPECT_EQ(out.problems()[0].str(), "m.pack @77: module check: module (0,0): 1 more second problems not listed");
  EXPECT_EQ(out.problems()[1].str(), "m.pack @77: module check: module (0,0): 2 more first problems not listed");
}

TEST(CappedProblems, capZeroKeepsEverything) {
  CappedProblems<> c(0);
  for (int k = 0; k < 50; ++k) c.add("x", Problem{"f", 0, "m"});
  const Status s = c.take("pack");
  EXPECT_EQ(s.problems().size(), 50u);
}
