// HeightField (height_field.h): the grid file's adapter answers what the
// written posts were, and a field that changes tells its listeners and its
// region generations exactly which posts moved. Also the database open
// counter.
#include <gtest/gtest.h>

#include <unistd.h>

#include <atomic>
#include <filesystem>
#include <map>

#include "sandtable/formats/database.h"
#include "sandtable/formats/height_field.h"

namespace sandtable::grid {
namespace {

namespace fs = std::filesystem;

/// 70 x 66 posts (2 x 2 blocks, partly filled), elevation 3 i - 2 j + 0.5,
/// material (i * 7 + j) % 5, normal (i % 2 ? 0.6 : 0, 0.8, j % 2 ? -0.6 : 0) unnormalised.
constexpr std::uint32_t kX = 70, kZ = 66;
float elevationOf(std::uint32_t i, std::uint32_t j) { return 3.0f * float(i) - 2.0f * float(j) + 0.5f; }
std::uint8_t materialOf(std::uint32_t i, std::uint32_t j) { return std::uint8_t((i * 7 + j) % 5); }

std::shared_ptr<const GridFile> writeGrid() {
  const std::string path = (fs::temp_directory_path() / ("hf_" + std::to_string(::getpid()) + ".grid")).string();
  auto w = GridWriter::create(path, makeHeader(kX, kZ, 12.5, 400000.0, 5000000.0));
  EXPECT_TRUE(w.ok()) << w.error();
  const Header& h = w.value()->header();
  auto b = std::make_unique<BlockData>();
  for (std::uint32_t bz = 0; bz < h.blocksZ; ++bz) {
    for (std::uint32_t bx = 0; bx < h.blocksX; ++bx) {
      for (std::uint32_t k = 0; k < kPostsPerBlock; ++k) {
        const std::uint32_t i = std::min(kX - 1, bx * kBlockPosts + k % kBlockPosts);
        const std::uint32_t j = std::min(kZ - 1, bz * kBlockPosts + k / kBlockPosts);
        b->elevation[k] = elevationOf(i, j);
        b->normalX[k] = toSnorm(i % 2 ? 0.6f : 0.0f);
        b->normalY[k] = toSnorm(0.8f);
        b->normalZ[k] = toSnorm(j % 2 ? -0.6f : 0.0f);
        b->material[k] = materialOf(i, j);
      }
      EXPECT_EQ(w.value()->writeBlock(bx, bz, *b).message(), "");
    }
  }
  EXPECT_EQ(w.value()->finish().message(), "");
  auto g = GridFile::open(path);
  EXPECT_TRUE(g.ok()) << g.error();
  fs::remove(path);  // the mapping stays valid
  return g.value();
}

TEST(HeightField, theGridAdapterAnswersThePostsAsWritten) {
  const auto g = writeGrid();
  const auto field = heightField(g);
  ASSERT_NE(field, nullptr);
  EXPECT_EQ(field->postsX(), kX);
  EXPECT_EQ(field->postsZ(), kZ);
  EXPECT_DOUBLE_EQ(field->spacing(), 12.5);
  EXPECT_DOUBLE_EQ(field->originEasting(), 400000.0);
  EXPECT_DOUBLE_EQ(field->originNorthing(), 5000000.0);
  for (std::uint32_t j = 0; j < kZ; ++j) {
    for (std::uint32_t i = 0; i < kX; ++i) {
      ASSERT_EQ(field->elevation(i, j), elevationOf(i, j)) << i << "," << j;
      ASSERT_EQ(field->material(i, j), materialOf(i, j));
      const auto n = field->normal(i, j);
      ASSERT_NEAR(n[0], i % 2 ? 0.6f : 0.0f, 1e-4f);
      ASSERT_NEAR(n[1], 0.8f, 1e-4f);
      ASSERT_NEAR(n[2], j % 2 ? -0.6f : 0.0f, 1e-4f);
    }
  }
  // Bounds: the writer's header holds the posts' range, 3*69+0.5 and -2*65+0.5.
  EXPECT_FLOAT_EQ(field->elevationBounds().first, -129.5f);
  EXPECT_FLOAT_EQ(field->elevationBounds().second, 207.5f);
  // The grid never changes.
  EXPECT_EQ(field->generation(), 0u);
  EXPECT_EQ(field->regionGeneration(field->all()), 0u);
  EXPECT_EQ(heightField(nullptr), nullptr);
}

/// A field that changes: a base plus per-post offsets, one generation per
/// change, each post remembering the change that last touched it.
class Editable final : public HeightField {
 public:
  explicit Editable(std::shared_ptr<const HeightField> base)
      : base_(std::move(base)), touched_(std::size_t(base_->postsX()) * base_->postsZ(), 0) {}
  const PostLayout& layout() const override { return base_->layout(); }
  float elevation(std::uint32_t i, std::uint32_t j) const override {
    const auto it = offsets_.find({i, j});
    return base_->elevation(i, j) + (it == offsets_.end() ? 0.0f : it->second);
  }
  std::array<float, 3> normal(std::uint32_t i, std::uint32_t j) const override { return base_->normal(i, j); }
  std::uint8_t material(std::uint32_t i, std::uint32_t j) const override { return base_->material(i, j); }
  std::pair<float, float> elevationBounds() const override { return {-1e9f, 1e9f}; }
  std::uint64_t generation() const override { return generation_.load(std::memory_order_acquire); }
  std::uint64_t regionGeneration(const PostRect& r) const override {
    std::uint64_t g = 0;
    for (std::uint32_t j = r.j0; j < r.j1 && j < postsZ(); ++j) {
      for (std::uint32_t i = r.i0; i < r.i1 && i < postsX(); ++i) g = std::max(g, touched_[std::size_t(j) * postsX() + i]);
    }
    return g;
  }
  void raise(const PostRect& r, float dz) {
    const std::uint64_t g = generation_.load() + 1;
    for (std::uint32_t j = r.j0; j < r.j1; ++j) {
      for (std::uint32_t i = r.i0; i < r.i1; ++i) {
        offsets_[{i, j}] += dz;
        touched_[std::size_t(j) * postsX() + i] = g;
      }
    }
    generation_.store(g, std::memory_order_release);
    notifyChanged({r, g});
  }

 private:
  std::shared_ptr<const HeightField> base_;
  std::map<std::pair<std::uint32_t, std::uint32_t>, float> offsets_;
  std::vector<std::uint64_t> touched_;
  std::atomic<std::uint64_t> generation_{0};
};

TEST(HeightField, aChangeReachesItsListenersAndOnlyItsRegionsGeneration) {
  Editable field(heightField(writeGrid()));
  std::vector<HeightChange> seen;
  const std::uint64_t token = field.subscribe([&](const HeightChange& c) { seen.push_back(c); });
  const PostRect patch{10, 20, 14, 23};
  field.raise(patch, 50.0f);
  ASSERT_EQ(seen.size(), 1u);
  EXPECT_EQ(seen[0].posts, patch);
  EXPECT_EQ(seen[0].generation, 1u);
  EXPECT_EQ(field.generation(), 1u);
  EXPECT_EQ(field.regionGeneration(patch), 1u);
  EXPECT_EQ(field.regionGeneration({13, 22, 30, 30}), 1u);  // overlaps one corner post
  EXPECT_EQ(field.regionGeneration({14, 20, 30, 30}), 0u);  // just east of it
  EXPECT_EQ(field.regionGeneration({0, 0, 10, 66}), 0u);    // just west of it
  EXPECT_TRUE(patch.intersects({13, 22, 30, 30}));
  EXPECT_FALSE(patch.intersects({14, 20, 30, 30}));
  EXPECT_EQ(field.elevation(12, 21), elevationOf(12, 21) + 50.0f);
  EXPECT_EQ(field.elevation(14, 21), elevationOf(14, 21));
  // Unsubscribed: the next change reaches nobody.
  field.unsubscribe(token);
  field.raise({0, 0, 1, 1}, 1.0f);
  EXPECT_EQ(seen.size(), 1u);
  EXPECT_EQ(field.generation(), 2u);
  EXPECT_EQ(field.regionGeneration(patch), 1u);
}

TEST(HeightField, everyDatabaseOpenIsCounted) {
  const std::uint64_t before = databaseOpens();
  EXPECT_FALSE(openDatabase("/nonexistent/sandtable/db").ok());
  EXPECT_FALSE(openDatabase("/nonexistent/sandtable/db2").ok());
  EXPECT_EQ(databaseOpens(), before + 2);
}

}  // namespace
}  // namespace sandtable::grid
