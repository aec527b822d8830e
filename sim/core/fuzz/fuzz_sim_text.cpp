// libFuzzer target: the simulator's four text readers (scripts, scenarios,
// aircraft files, collision tables) on arbitrary bytes; the first byte
// picks the reader. Build with clang: -DSANDTABLE_FUZZ=ON
// (sim/core/CMakeLists.txt); run build/sim/core/sandtable_fuzz_sim_text
// -max_len=4096 with samples/*.script, *.scenario, aircraft/*.txt and
// collisions.txt as the corpus.
#include <cstddef>
#include <cstdint>
#include <string_view>

#include "sandtable/sim/aircraft.h"
#include "sandtable/sim/collision_response.h"
#include "sandtable/sim/scenario.h"
#include "sandtable/sim/script.h"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  using namespace sandtable::sim;
  if (size == 0) return 0;
  const std::string_view text(reinterpret_cast<const char*>(data) + 1, size - 1);
  switch (data[0] % 4) {
    case 0: (void)parseScript(text, "fuzz"); break;
    case 1: (void)parseScenario(text, "fuzz"); break;
    case 2: (void)parseAircraft(text, "fuzz"); break;
    default: (void)parseCollisionTable(text, "fuzz"); break;
  }
  return 0;
}
