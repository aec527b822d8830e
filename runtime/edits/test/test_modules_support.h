#pragma once
// What the re-meshing tests share: the Bayreuth database (SRTM and OSM from
// ../shared/data, built once per test binary through the CLI), a
// HeightField over its grid whose posts and refined squares a test sets
// (the heights overlay is another helper's: these tests build against the
// HeightField interface only), and crater patches made the way the overlay
// makes them (docs/DYNAMIC.md): every square the crater's support touches
// refined, fine posts moved by the crater profile (profile.h).
#include <gtest/gtest.h>

#include <cstdint>
#include <map>
#include <memory>
#include <string>
#include <utility>
#include <vector>

#include "sandtable/formats/database.h"
#include "sandtable/formats/edit.h"
#include "sandtable/formats/height_field.h"

namespace sandtable::edits::test {

/// The Bayreuth database (11.55 49.94 11.62 49.99 at 30 m, north-bayreuth
/// OSM, samples/icons.txt), or null when ../shared/data is missing (the
/// caller skips) or the build failed (a test failure is added).
const Database* bayreuth();

/// A grid's posts with some moved and some squares refined by the test.
/// Not thread-safe for writes: tests change it while nothing reads.
class TestHeights final : public grid::HeightField {
 public:
  explicit TestHeights(std::shared_ptr<const grid::GridFile> grid);

  const grid::PostLayout& layout() const override { return base_.layout(); }
  float elevation(std::uint32_t i, std::uint32_t j) const override;
  std::array<float, 3> normal(std::uint32_t i, std::uint32_t j) const override { return base_.normal(i, j); }
  std::uint8_t material(std::uint32_t i, std::uint32_t j) const override { return base_.material(i, j); }
  std::pair<float, float> elevationBounds() const override;
  std::uint64_t generation() const override { return generation_; }
  std::uint64_t regionGeneration(const grid::PostRect& posts) const override;
  std::shared_ptr<const grid::RefinedSquare> refined(std::uint32_t i, std::uint32_t j) const override;
  bool anyRefined() const override { return !refined_.empty(); }

  /// Moves post (i, j) to y.
  void set(std::uint32_t i, std::uint32_t j, float y);
  /// Publishes square (r.i, r.j)'s patch (its generation set here).
  void refine(grid::RefinedSquare r);

 private:
  std::shared_ptr<const grid::GridFile> grid_;
  grid::GridHeightField base_;
  std::map<std::pair<std::uint32_t, std::uint32_t>, float> posts_;
  std::map<std::pair<std::uint32_t, std::uint32_t>, std::shared_ptr<const grid::RefinedSquare>> refined_;
  std::uint64_t generation_ = 0;
};

/// Refines every grid square crater `e`'s support touches into `cells`
/// fine squares a side (the patch: the support snapped outward to the fine
/// lattice), fine posts at newHeight over the ground before (the square's
/// planes; on a grid edge, the straight line between its posts, which both
/// squares share). The support must hold no grid post. Returns the squares.
std::vector<std::pair<std::uint32_t, std::uint32_t>> craterPatches(TestHeights& h, const edit::Edit& e, std::uint32_t cells);

}  // namespace sandtable::edits::test
