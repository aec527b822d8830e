// DIS entity type -> icon (docs/ICONS.md §3.1): the pattern text, matching,
// the best-match order, each fallback with its flag, and the cache.
#include <gtest/gtest.h>

#include <random>
#include <string>
#include <vector>

#include "sandtable/formats/dis_icons.h"

namespace sandtable::iconpack {
namespace {

DisPattern pat(const std::string& text) {
  std::string why;
  const auto p = parseDisPattern(text, why);
  EXPECT_TRUE(p) << text << ": " << why;
  return p.value_or(DisPattern{});
}

Icon icon(const std::string& name, const std::vector<std::string>& patterns) {
  Icon i;
  i.name = name;
  for (const auto& t : patterns) i.dis.push_back(pat(t));
  return i;
}

TEST(DisIcons, patternTextTakesWildcardsAndLeftOffFields) {
  EXPECT_EQ(pat("1.1.225.1.1.3.0"), (DisPattern{{1, 1, 225, 1, 1, 3, 0}, 0}));
  // Left-off trailing fields are wildcards: country (bit 2) and everything after.
  EXPECT_EQ(pat("1.1"), (DisPattern{{1, 1, 0, 0, 0, 0, 0}, 0x7C}));
  EXPECT_EQ(pat("1.1.*.1"), (DisPattern{{1, 1, 0, 1, 0, 0, 0}, 0x04 | 0x10 | 0x20 | 0x40}));
  EXPECT_EQ(pat("*"), (DisPattern{{}, kDisAllWild}));
  EXPECT_EQ(pat("*.*.65535"), (DisPattern{{0, 0, 65535, 0, 0, 0, 0}, 0x7B}));
  // The canonical text leaves trailing wildcards off; the same pattern, however written.
  EXPECT_EQ(disText(pat("1.1.*.1.*.*.*")), "1.1.*.1");
  EXPECT_EQ(disText(pat("1.2.*")), "1.2");
  EXPECT_EQ(disText(pat("*.*")), "*");
  EXPECT_EQ(disText(pat("1.1.225.1.1.3.0")), "1.1.225.1.1.3.0");
  EXPECT_EQ(pat(disText(pat("2.*.225.*.3"))), pat("2.*.225.*.3"));
  const std::pair<std::string, std::string> bad[] = {
      {"", "field 1 (kind) '' is not a number from 0 to 255 or *"},
      {"256", "field 1 (kind) '256' is not a number from 0 to 255 or *"},
      {"1.1.65536", "field 3 (country) '65536' is not a number from 0 to 65535 or *"},
      {"1..1", "field 2 (domain) '' is not"},
      {"1.1.", "field 3 (country) '' is not"},
      {"1.+1", "field 2 (domain) '+1' is not"},
      {"1.**", "field 2 (domain) '**' is not"},
      {"1.1.225.1.1.3.0.0", "has more than 7 fields"},
  };
  for (const auto& [text, message] : bad) {
    std::string why;
    EXPECT_FALSE(parseDisPattern(text, why)) << text;
    EXPECT_EQ(why.rfind(message, 0), 0u) << text << ": " << why;
  }
}

TEST(DisIcons, specificityComparesExactFieldsInFieldOrder) {
  EXPECT_EQ(specificity(pat("1.1.225.1.1.3.0")), 0x7F);
  EXPECT_EQ(specificity(pat("*")), 0);
  EXPECT_EQ(specificity(pat("1")), 0x40);
  // An exact country outranks any number of exact fields after it.
  EXPECT_GT(specificity(pat("1.1.225")), specificity(pat("1.1.*.1.1.3.0")));
  EXPECT_GT(specificity(pat("1.1.225.*.2")), specificity(pat("1.1.*.1.2")));
  EXPECT_TRUE(matches(pat("1.1.*.1"), DisType{1, 1, 222, 1, 9, 9, 9}));
  EXPECT_FALSE(matches(pat("1.1.*.1"), DisType{1, 1, 222, 2, 9, 9, 9}));
  EXPECT_TRUE(matches(pat("*"), DisType{9, 9, 9, 9, 9, 9, 9}));
  EXPECT_EQ(packedDisType(DisType{1, 2, 0x0304, 5, 6, 7, 8}), 0x0102030405060708ull);
}

TEST(DisIcons, theMostSpecificMatchingPatternWins) {
  const std::vector<Icon> icons = {
      icon("land", {"1.1"}),
      icon("any-tank", {"1.1.*.1"}),
      icon("m1", {"1.1.225.1.1.3.0"}),
      icon("us-land", {"1.1.225"}),
      icon("us-sub-2", {"1.1.225.*.2"}),
      icon("sub-2-tank", {"1.1.*.1.2"}),
  };
  const DisIconMap map(icons);
  EXPECT_EQ(map.patterns(), 6u);
  auto best = [&](DisType t) { return icons[map.match(t).icon].name; };
  EXPECT_EQ(best({1, 1, 225, 1, 1, 3, 0}), "m1");        // exact beats every wildcard
  EXPECT_EQ(best({1, 1, 225, 1, 1, 3, 1}), "us-land");   // another extra: the M1 no longer matches
  EXPECT_EQ(best({1, 1, 222, 1, 1, 0, 0}), "any-tank");  // a Russian tank
  EXPECT_EQ(best({1, 1, 222, 7, 1, 0, 0}), "land");      // a Russian truck: only 1.1 matches
  EXPECT_EQ(best({1, 1, 225, 7, 1, 0, 0}), "us-land");   // the longer prefix beats 1.1
  EXPECT_EQ(best({1, 1, 225, 1, 2, 0, 0}), "us-sub-2");  // country exact beats category exact
  EXPECT_EQ(best({1, 1, 222, 1, 2, 0, 0}), "sub-2-tank");
  EXPECT_FALSE(map.match({1, 1, 225, 1, 1, 3, 0}).fallback());
  // The same pattern on two icons (the definition file refuses it; a pack
  // may hold it): the icon first in the pack.
  const std::vector<Icon> twice = {icon("first", {"1.2"}), icon("second", {"1.2"})};
  EXPECT_EQ(DisIconMap(twice).match({1, 2, 225, 1, 0, 0, 0}).icon, 0u);
  // A wildcard kind matches every type: nothing is a fallback then.
  const std::vector<Icon> all = {icon("tree", {}), icon("anything", {"*"})};
  EXPECT_EQ(DisIconMap(all).match({4, 0, 0, 0, 0, 0, 0}), (DisMatch{1, DisMatchBy::pattern}));
}

TEST(DisIcons, anUnknownTypeFallsBackByCategoryThenKindAndDomainThenName) {
  const std::vector<Icon> icons = {
      icon("tree", {}),
      icon("truck", {"1.1.225.7"}),
      icon("tank", {"1.1.225.1.1.3.0"}),
      icon("jeep", {"1.1.225.6.1.1.0"}),
      icon("boat", {}),
      icon("missile", {}),
      icon("f16", {"1.2.225.1.9"}),
  };
  const DisIconMap map(icons);
  // Country, subcategory and below ignored: a Russian tank gets the tank, a
  // Russian truck the truck (SISO numbers the category alike for every country).
  EXPECT_EQ(map.match({1, 1, 222, 1, 2, 0, 0}), (DisMatch{2, DisMatchBy::category}));
  EXPECT_EQ(map.match({1, 1, 222, 7, 3, 1, 0}), (DisMatch{1, DisMatchBy::category}));
  // No land pattern has category 9: kind and domain only, most specific first
  // (the tank's and the jeep's are both exact; the tank comes first in the pack).
  EXPECT_EQ(map.match({1, 1, 222, 9, 1, 0, 0}), (DisMatch{2, DisMatchBy::kindDomain}));
  // An air platform of another category: the F-16's pattern by kind and domain.
  EXPECT_EQ(map.match({1, 2, 222, 20, 1, 0, 0}), (DisMatch{6, DisMatchBy::kindDomain}));
  // No pattern for surface platforms or munitions: the built-in default names.
  EXPECT_EQ(map.match({1, 3, 222, 1, 0, 0, 0}), (DisMatch{4, DisMatchBy::defaultName}));
  EXPECT_EQ(map.match({1, 4, 225, 1, 0, 0, 0}), (DisMatch{4, DisMatchBy::defaultName}));  // a submarine: "boat"
  EXPECT_EQ(map.match({2, 2, 225, 1, 1, 0, 0}), (DisMatch{5, DisMatchBy::defaultName}));
  // Nothing at all for an environmental entity (kind 4): icon 0.
  EXPECT_EQ(map.match({4, 1, 0, 0, 0, 0, 0}), (DisMatch{0, DisMatchBy::firstIcon}));
  for (const DisType t : {DisType{1, 1, 222, 1, 0, 0, 0}, DisType{1, 3, 0, 0, 0, 0, 0}, DisType{4, 0, 0, 0, 0, 0, 0}}) {
    EXPECT_TRUE(map.match(t).fallback());
  }
  // No icon at all.
  EXPECT_EQ(DisIconMap(Pack{}).match({1, 1, 225, 1, 1, 3, 0}), (DisMatch{kNoIcon, DisMatchBy::none}));
  EXPECT_TRUE(DisMatch{}.fallback());
}

TEST(DisIcons, theCacheGivesWhatMatchGivesAndStaysBounded) {
  std::vector<Icon> icons = {icon("tank", {"1.1.225.1.1.3.0", "1.1.*.1"}), icon("jet", {"1.2"}),
                             icon("truck", {"1.1.*.7"}), icon("missile", {"2"})};
  DisIconMap map(icons);
  std::mt19937 rng(36);
  std::vector<DisType> types;
  for (int k = 0; k < 3000; ++k) {
    types.push_back(DisType{static_cast<std::uint8_t>(rng() % 4), static_cast<std::uint8_t>(rng() % 4),
                            static_cast<std::uint16_t>(rng() % 300), static_cast<std::uint8_t>(rng() % 10),
                            static_cast<std::uint8_t>(rng() % 3), static_cast<std::uint8_t>(rng() % 5), 0});
  }
  for (int pass = 0; pass < 2; ++pass) {
    for (const DisType& t : types) ASSERT_EQ(map.lookup(t), map.match(t));
  }
  EXPECT_LE(map.cached(), types.size());
  // Hostile traffic of ever new types: the cache is emptied, never grown past its bound.
  for (std::uint32_t k = 0; k < DisIconMap::kCacheEntries + 100; ++k) {
    map.lookup(DisType{1, 1, static_cast<std::uint16_t>(k), static_cast<std::uint8_t>(k >> 16), 0, 0, 0});
  }
  EXPECT_LE(map.cached(), DisIconMap::kCacheEntries);
  EXPECT_EQ(map.lookup({1, 1, 225, 1, 1, 3, 0}), (DisMatch{0, DisMatchBy::pattern}));
}

}  // namespace
}  // namespace sandtable::iconpack
