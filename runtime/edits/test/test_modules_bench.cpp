// Re-mesh and publish time per crater touching 1, 2 and 4 modules of the
// Bayreuth database (issue 37's goal: <= 5 ms of one core for 4). Not a
// test (no thresholds; timings are not pass/fail): run it on purpose,
//   sandtable_edits_test --gtest_also_run_disabled_tests --gtest_filter='*RemeshTime*'
// It prints the median of 21 warm repeats (thread CPU and wall) and the
// first, cold call (which also reads and decodes the base modules).
#include <gtest/gtest.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>

#include "sandtable/edits/modules.h"
#include "sandtable/edits/profile.h"
#include "sandtable/formats/terrain_rule.h"
#include "test_modules_support.h"

namespace sandtable::edits {
namespace {

struct Case {
  const char* name;
  double x, z;  ///< crater centre, world metres
};

double median(std::vector<double> v) {
  std::sort(v.begin(), v.end());
  return v[v.size() / 2];
}

TEST(EditedModulesBench, DISABLED_RemeshTimePerCraterTouchingOneTwoAndFourModules) {
  const Database* db = test::bayreuth();
  if (!db) GTEST_SKIP() << "../shared/data is missing";
  const pack::IndexHeader& hd = db->modules->header();
  const double s = db->grid->spacing(), edge = hd.moduleSize;
  const std::uint32_t sq = hd.moduleSquares;
  // A medium crater (3 m, 1.2 m deep; support 12 m) at 64 fine cells.
  const Case cases[] = {{"1 module (inside a square)", edge + (sq / 2 + 0.5) * s, edge + (sq / 2 + 0.5) * s},
                        {"2 modules (on a module edge)", 2 * edge, edge + (sq / 2 + 0.5) * s},
                        {"4 modules (on a module corner)", 2 * edge, 2 * edge}};
  std::printf("%-32s %8s %10s %10s %10s %10s %8s\n", "crater", "modules", "cold ms", "cpu ms", "wall ms", "l0 tris",
              "refined");
  for (const Case& c : cases) {
    auto heights = std::make_shared<test::TestHeights>(db->grid);
    edit::Edit e;
    e.kind = edit::Kind::crater;
    e.points = {{c.x, c.z}};
    e.radius = kCraterMedium.radius;
    e.depth = kCraterMedium.depth;
    grid::PostRect posts;
    // A post inside the support moves as the overlay moves it (the patches
    // below then stand on the old planes: timing only).
    const Box b = support(e);
    const auto pi = std::uint32_t(std::ceil(b.x0 / s)), pj = std::uint32_t(std::ceil(b.z0 / s));
    if (pi * s <= b.x1 && pj * s <= b.z1) {
      heights->set(pi, pj, float(newHeight(e, pi * s, pj * s, heights->elevation(pi, pj))));
      posts = {pi, pj, pi + 1, pj + 1};
    }
    const std::vector<std::pair<std::uint32_t, std::uint32_t>> squares = test::craterPatches(*heights, e, 64);
    EditedModules modules(std::make_shared<paging::PackSource>(db->modules), grid::heightField(db->grid), heights);
    auto t0 = std::chrono::steady_clock::now();
    auto first = modules.remesh(posts, squares);
    const double cold = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
    ASSERT_TRUE(first.ok()) << first.error();
    std::vector<double> cpu, wall;
    for (int r = 0; r < 21; ++r) {
      t0 = std::chrono::steady_clock::now();
      const auto rep = modules.remesh(posts, squares);
      wall.push_back(std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count());
      ASSERT_TRUE(rep.ok());
      cpu.push_back(rep->seconds);
    }
    std::printf("%-32s %8zu %10.2f %10.2f %10.2f %10llu %8llu\n", c.name, first->modules.size(), cold * 1e3,
                median(cpu) * 1e3, median(wall) * 1e3, (unsigned long long)first->triangles[0],
                (unsigned long long)first->refinedSquares);
  }
}

}  // namespace
}  // namespace sandtable::edits
