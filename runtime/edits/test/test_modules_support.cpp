// The re-meshing tests' database, height field and crater patches
// (test_modules_support.h).
#include "test_modules_support.h"

#include <unistd.h>

#include <algorithm>
#include <cmath>
#include <cstdlib>
#include <filesystem>

#include "sandtable/edits/profile.h"
#include "sandtable/formats/terrain_rule.h"

namespace sandtable::edits::test {

namespace fs = std::filesystem;

namespace {

std::string dataDir() { return std::string(SANDTABLE_SOURCE_DIR) + "/../shared/data"; }

/// Removes the database when the tests end.
class RemoveDatabase : public ::testing::Environment {
 public:
  void TearDown() override {
    std::error_code ec;
    if (!dir.empty()) fs::remove_all(dir, ec);
  }
  static inline std::string dir;
};
const auto* const kRemove = ::testing::AddGlobalTestEnvironment(new RemoveDatabase);

}  // namespace

const Database* bayreuth() {
  static std::optional<Database> db;
  static bool tried = false;
  if (tried) return db ? &*db : nullptr;
  tried = true;
  if (!fs::is_directory(dataDir() + "/elevation")) return nullptr;
  const std::string dir = (fs::temp_directory_path() / ("sandtable-edits-bayreuth." + std::to_string(::getpid()))).string();
  RemoveDatabase::dir = dir;
  fs::remove_all(dir);
  const std::string cmd = std::string("'") + SANDTABLE_CLI + "' build --elevation '" + dataDir() +
                          "/elevation/srtm/N49E011.hgt.zip' --extent 11.55 49.94 11.62 49.99 --spacing 30 --culture '" +
                          dataDir() + "/culture/osm/north-bayreuth.osm.gz' --icons '" + SANDTABLE_SOURCE_DIR +
                          "/samples/icons.txt' -o '" + dir + "' > '" + dir + ".log' 2>&1";
  const int rc = std::system(cmd.c_str());
  if (rc != 0) {
    ADD_FAILURE() << "build failed (" << rc << "): " << cmd;
    return nullptr;
  }
  fs::remove(dir + ".log");
  auto opened = openDatabase(dir);
  if (!opened) {
    ADD_FAILURE() << opened.error();
    return nullptr;
  }
  db = std::move(opened.value());
  return &*db;
}

TestHeights::TestHeights(std::shared_ptr<const grid::GridFile> grid) : grid_(std::move(grid)), base_(*grid_) {}

float TestHeights::elevation(std::uint32_t i, std::uint32_t j) const {
  const auto it = posts_.find({i, j});
  return it == posts_.end() ? base_.elevation(i, j) : it->second;
}

std::pair<float, float> TestHeights::elevationBounds() const {
  auto [lo, hi] = base_.elevationBounds();
  for (const auto& [k, y] : posts_) lo = std::min(lo, y), hi = std::max(hi, y);
  return {lo - 100, hi + 100};  // refined posts may dig below
}

std::uint64_t TestHeights::regionGeneration(const grid::PostRect& posts) const {
  for (const auto& [k, y] : posts_) {
    if (posts.contains(k.first, k.second)) return generation_;
  }
  return 0;
}

std::shared_ptr<const grid::RefinedSquare> TestHeights::refined(std::uint32_t i, std::uint32_t j) const {
  const auto it = refined_.find({i, j});
  return it == refined_.end() ? nullptr : it->second;
}

void TestHeights::set(std::uint32_t i, std::uint32_t j, float y) {
  posts_[{i, j}] = y;
  ++generation_;
}

void TestHeights::refine(grid::RefinedSquare r) {
  r.generation = ++generation_;
  refined_[{r.i, r.j}] = std::make_shared<const grid::RefinedSquare>(std::move(r));
}

std::vector<std::pair<std::uint32_t, std::uint32_t>> craterPatches(TestHeights& h, const edit::Edit& e, std::uint32_t cells) {
  const Box box = support(e);
  const double s = h.spacing(), n = cells, f = s / n;
  std::vector<std::pair<std::uint32_t, std::uint32_t>> out;
  const auto i0 = std::uint32_t(std::floor(box.x0 / s)), i1 = std::uint32_t(std::ceil(box.x1 / s));
  const auto j0 = std::uint32_t(std::floor(box.z0 / s)), j1 = std::uint32_t(std::ceil(box.z1 / s));
  for (std::uint32_t j = j0; j < j1; ++j) {
    for (std::uint32_t i = i0; i < i1; ++i) {
      grid::RefinedSquare r;
      r.i = i, r.j = j, r.cells = cells;
      auto fine = [&](double v, double origin, bool up) {
        const double k = up ? std::ceil((v - origin) / f) : std::floor((v - origin) / f);
        return std::uint32_t(std::clamp(k, 0.0, n));
      };
      r.a0 = fine(box.x0, i * s, false), r.a1 = fine(box.x1, i * s, true);
      r.b0 = fine(box.z0, j * s, false), r.b1 = fine(box.z1, j * s, true);
      const double nw = h.elevation(i, j), ne = h.elevation(i + 1, j), sw = h.elevation(i, j + 1), se = h.elevation(i + 1, j + 1);
      for (std::uint32_t b = r.b0; b <= r.b1; ++b) {
        for (std::uint32_t a = r.a0; a <= r.a1; ++a) {
          const double t = double(b) / n, u = double(a) / n;
          double before = 0;
          if (a == 0 || a == cells) {
            const double e0 = a == 0 ? nw : ne, e1 = a == 0 ? sw : se;
            before = e0 + t * (e1 - e0);
          } else if (b == 0 || b == cells) {
            const double e0 = b == 0 ? nw : sw, e1 = b == 0 ? ne : se;
            before = e0 + u * (e1 - e0);
          } else {
            before = terrain::planeHeight(u, t, nw, ne, sw, se);
          }
          r.heights.push_back(float(newHeight(e, (i + u) * s, (j + t) * s, before)));
        }
      }
      out.push_back({i, j});
      h.refine(std::move(r));
    }
  }
  return out;
}

}  // namespace sandtable::edits::test
