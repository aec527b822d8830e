// libFuzzer target: path files (docs/PATH.md) on arbitrary text, then the
// eye sampled along what parsed. Lon/lat files get a plain stand-in
// projection (metres = degrees * 1000) so they reach the legs' checks too.
// Build with clang: -DSANDTABLE_FUZZ=ON; run by tools/fuzz.sh with
// samples/demo.path as the seed.
#include <cstddef>
#include <cstdint>
#include <string_view>

#include "sandtable/world/path.h"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  using namespace sandtable::world;
  PathOptions o;
  o.defaultSpeedKmh = 100;
  o.toProjected = [](double lon, double lat, double& e, double& n) -> std::string {
    e = lon * 1000;
    n = lat * 1000;
    return {};
  };
  const auto path = parsePath(std::string_view(reinterpret_cast<const char*>(data), size), "fuzz", o);
  if (!path.ok()) return 0;
  const double t0 = path->waypoints.front().timeS, d = path->durationS();
  for (int k = -1; k <= 9; ++k) (void)samplePath(path.value(), t0 + d * k / 8.0);
  return 0;
}
