// The four text readers on hostile text, without a fuzzer: every truncated
// prefix of each shipped sample and thousands of seeded byte mutations
// parse or fail cleanly, and every failure names a line and a column (the
// libFuzzer target sim/core/fuzz/fuzz_sim_text.cpp does the same at length).
#include <gtest/gtest.h>

#include <fstream>
#include <functional>
#include <sstream>

#include "sandtable/base/hash.h"
#include "sandtable/sim/aircraft.h"
#include "sandtable/sim/collision_response.h"
#include "sandtable/sim/scenario.h"
#include "sandtable/sim/script.h"

namespace sandtable::sim {
namespace {

std::string slurp(const std::string& rel) {
  std::ifstream in(std::string(SANDTABLE_SOURCE_DIR) + "/" + rel, std::ios::binary);
  std::stringstream s;
  s << in.rdbuf();
  return s.str();
}

/// Parses `text`; on failure every problem must say where.
using Reader = std::function<std::vector<Problem>(std::string_view)>;

template <typename F>
Reader reader(F f) {
  return [f](std::string_view t) {
    auto r = f(t, std::string("hostile"));
    return r ? std::vector<Problem>{} : r.problems();
  };
}

void expectClean(const std::vector<Problem>& problems, const std::string& what) {
  for (const Problem& p : problems) {
    EXPECT_EQ(p.file, "hostile") << what;
    const bool placed = p.message.find("line ") != std::string::npos || p.message.find("empty") != std::string::npos ||
                        p.message.find("header") != std::string::npos;
    EXPECT_TRUE(placed) << what << ": " << p.message;
  }
}

TEST(TextHostile, everyPrefixAndManyMutationsOfTheSamplesFailCleanly) {
  const std::vector<std::pair<std::string, Reader>> cases = {
      {"samples/demo.script", reader(parseScript)},
      {"samples/demo.scenario", reader(parseScenario)},
      {"samples/terrain.scenario", reader(parseScenario)},  // crater, berm, ditch and flatten lines
      {"samples/aircraft/trainer.txt", reader(parseAircraft)},
      {"samples/collisions.txt", reader(parseCollisionTable)},
  };
  for (const auto& [file, read] : cases) {
    const std::string text = slurp(file);
    ASSERT_FALSE(text.empty()) << file;
    EXPECT_TRUE(read(text).empty()) << file << " does not parse";
    for (std::size_t n = 0; n < text.size(); ++n) expectClean(read(std::string_view(text).substr(0, n)), file);
    const char alphabet[] = "0123456789 .-=,#\n\t\r\x01\xff" "eEnaNifxyz";
    for (std::uint64_t k = 0; k < 3000; ++k) {
      std::string m = text;
      const std::uint64_t h = hash::mix(k * 7919 + text.size());
      const std::size_t at = std::size_t(h % m.size());
      const char c = alphabet[(h >> 20) % (sizeof alphabet - 1)];
      if ((h >> 40) % 3 == 0) m.insert(at, 1, c);
      else if ((h >> 40) % 3 == 1) m.erase(at, 1 + (h >> 50) % 8);
      else m[at] = c;
      expectClean(read(m), file + " mutation " + std::to_string(k));
    }
  }
}

}  // namespace
}  // namespace sandtable::sim
