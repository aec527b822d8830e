#pragma once
// Worlds for the simulator's unit tests: a grid of a given elevation
// function written to a temporary file, opened as a SimWorld.
#include <gtest/gtest.h>
#include <unistd.h>

#include <filesystem>
#include <functional>
#include <memory>
#include <string>

#include "sandtable/formats/grid.h"
#include "sandtable/sim/sim_world.h"
#include "sandtable/testing/fixtures.h"

namespace sandtable::sim::test {

/// Elevation at world (x, z), metres.
using Surface = std::function<double(double x, double z)>;

/// A posts x posts grid `spacing` apart with elevation f at every post,
/// level 0 drawn everywhere, no materials table (default soil).
inline std::shared_ptr<SimWorld> makeWorld(const Surface& f, std::uint32_t posts = 201, double spacing = 10) {
  static int counter = 0;
  const std::string path = std::filesystem::temp_directory_path().string() + "/sandtable_sim_test_" +
                           std::to_string(::getpid()) + "_" + std::to_string(counter++) + ".grid";
  const Status st = fixtures::writeGrid(path, posts, posts, spacing, [&](std::uint32_t i, std::uint32_t j) {
    return static_cast<float>(f(double(i) * spacing, double(j) * spacing));
  });
  EXPECT_TRUE(st) << st.error();
  auto grid = grid::GridFile::open(path);
  EXPECT_TRUE(grid) << grid.error();
  std::filesystem::remove(path);  // the mapping stays valid
  return std::make_shared<SimWorld>(grid.value(), 0, 1);
}

}  // namespace sandtable::sim::test
