// Links the GL-free libraries and touches one symbol of each, so that the
// linker keeps them; tests/boundary/check_closure.sh then reads what the
// executable needs. The probe is never run for its output.
#include <cstdio>

#include "sandtable/base/jobs.h"
#include "sandtable/dis/pdu.h"
#include "sandtable/formats/grid.h"
#include "sandtable/paging/view_triangle.h"
#include "sandtable/scene/lod.h"
#include "sandtable/world/terrain.h"

#ifdef SANDTABLE_PROBE_RENDER
#include "sandtable/render/image.h"
#endif

int main(int argc, char**) {
  using namespace sandtable;
  std::printf("%d\n", jobs::threadCount(argc));
  auto g = grid::GridFile::open("/nonexistent");
  scene::LodOptions lod;
  std::printf("%d %s\n", g.ok() ? 1 : 0, scene::checkLodOptions(lod).c_str());
  std::printf("%zu\n", dis::encode(dis::Header{}, dis::EntityState{}).size());
#ifdef SANDTABLE_PROBE_RENDER
  std::printf("%s\n", render::writePng("/nonexistent/x.png", render::Image{}).error().c_str());
#endif
  return 0;
}
