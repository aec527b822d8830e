#include "synthetic_world.h"

#include <unistd.h>

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <string>

#include "sandtable/base/hash.h"

namespace sandtable::bench {

double unitRandom(std::uint64_t seed, std::uint64_t k) { return hash::unit(hash::mix(seed * 0x9e3779b97f4a7c15ull + k)); }

double hillsAt(double x, double z) {
  return 300 + 120 * std::sin(x / 2300.0) * std::cos(z / 3100.0) + 40 * std::sin((x + z) / 700.0);
}

Result<std::shared_ptr<const grid::GridFile>> makeHillsGrid(double sizeKm, double squareM, const char* tag) {
  const auto posts = static_cast<std::uint32_t>(std::llround(sizeKm * 1000 / squareM)) + 1;
  std::string name = "sandtable_bench_";
  name += tag;
  name += "_";
  name += std::to_string(::getpid());
  name += ".grid";
  const std::string path = (std::filesystem::temp_directory_path() / name).string();
  auto gw = grid::GridWriter::create(path, grid::makeHeader(posts, posts, squareM, kHillsEasting, kHillsNorthing));
  if (!gw) return gw.problems();
  const grid::Header& h = gw.value()->header();
  auto block = std::make_unique<grid::BlockData>();
  for (std::uint32_t bz = 0; bz < h.blocksZ; ++bz) {
    for (std::uint32_t bx = 0; bx < h.blocksX; ++bx) {
      for (std::uint32_t k = 0; k < grid::kPostsPerBlock; ++k) {
        const std::uint32_t i = std::min(posts - 1, bx * grid::kBlockPosts + k % grid::kBlockPosts);
        const std::uint32_t j = std::min(posts - 1, bz * grid::kBlockPosts + k / grid::kBlockPosts);
        block->elevation[k] = static_cast<float>(hillsAt(i * squareM, j * squareM));
        block->normalY[k] = grid::toSnorm(1.0f);
      }
      if (Status st = gw.value()->writeBlock(bx, bz, *block); !st) return st.problems();
    }
  }
  if (Status st = gw.value()->finish(); !st) return st.problems();
  auto g = grid::GridFile::open(path);
  std::filesystem::remove(path);  // the mapping stays valid
  return g;
}

sim::Entity zigzagEntity(const sim::SimWorld& w, std::uint64_t seed, std::uint32_t k) {
  sim::Entity e;
  e.name = std::to_string(k);  // (no "e" + ...: GCC 12's false -Wrestrict)
  const double margin = 300;
  e.position = {margin + unitRandom(seed ^ 0xe1, 3 * k) * (w.widthM() - 2 * margin), 0,
                margin + unitRandom(seed ^ 0xe1, 3 * k + 1) * (w.depthM() - 2 * margin)};
  e.headingDeg = 360 * unitRandom(seed ^ 0xe1, 3 * k + 2);
  e.speedMs = 3 + 12 * unitRandom(seed ^ 0xe2, k);
  const double m = unitRandom(seed ^ 0xe3, k);
  e.mobility = m < 0.6 ? sim::Mobility::simple : m < 0.9 ? sim::Mobility::tracked : sim::Mobility::wheeled;
  e.force = static_cast<std::uint8_t>(1 + k % 2);
  e.radius = 3;
  e.sphereRadius = 4;
  e.height = 2.5;
  e.halfLength = 3.5;
  e.halfWidth = 1.7;
  e.behaviours = {true, true, true, false, false};
  e.controller = sim::Controller::behaviour;
  return e;
}

}  // namespace sandtable::bench
