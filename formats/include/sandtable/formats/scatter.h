#pragma once
// The scatter rule (docs/ICONS.md §8, docs/FORMAT.md §9.11): one jittered
// candidate per world-anchored cell, kept where the level-0 skin is the
// rule's class and no decal or building roof covers it, with a scale and
// heading hashed from the seed and the cell. The converter places trees
// with it and module version 6 decodes them with it: one rule, one place.
// Every object's base on a level is found here too (seed Figure 87's yloc).
#include <cstdint>
#include <limits>
#include <vector>

#include "sandtable/formats/module.h"

namespace sandtable::module {

/// The cells a rule's candidates may fall in over a scattering's rectangle:
/// columns i0..i1 and rows j0..j1, floor(x0 / cell) .. floor((x0 + width) / cell).
/// Candidate k of the range is cell (i0 + k % columns, j0 + k / columns).
struct CellRange {
  std::int64_t i0 = 0, i1 = -1, j0 = 0, j1 = -1;
  std::uint64_t columns() const { return i1 >= i0 ? std::uint64_t(i1 - i0 + 1) : 0; }
  std::uint64_t rows() const { return j1 >= j0 ? std::uint64_t(j1 - j0 + 1) : 0; }
  std::uint64_t count() const { return columns() * rows(); }
};

/// The range of `rule` over `s`; empty (count 0) when the cell, the corner or
/// the extent is not finite and positive where it must be, or when a cell
/// index would not fit an id (|i|, |j| > kMaxCellIndex). Candidates can
/// still be more than kMaxObjects: callers check count() first.
CellRange cellRange(const ScatterRule& rule, const Scattering& s);

/// A rule's candidate in cell (i, j), before the surface tests: module-local
/// position (inside: whether it is this module's), scale and heading.
struct Candidate {
  double x = 0, z = 0;
  bool inside = false;
  Object object;  ///< icon, class, x, z, heading, scale, radius, height and id set
};
Candidate candidate(const ScatterRule& rule, const Scattering& s, std::int64_t i, std::int64_t j);

/// Deterministic variation: scale in [min, max] and a heading over the
/// whole turn, from a hash of the seed and a cell key.
void vary(double scaleMin, double scaleMax, std::uint64_t seed, std::uint64_t key, float& scale,
          std::uint16_t& heading);

/// One level's triangles indexed for point queries: the skin groups of each
/// square, and (with cover) the decal groups and the building boxes.
class Surface {
 public:
  Surface(const Level& level, bool cover);
  /// The skin triangle that holds (x, z) best (largest smallest barycentric
  /// coordinate; -inf: none), its height there and its material.
  struct Hit {
    double inside = -std::numeric_limits<double>::infinity();
    float y = std::numeric_limits<float>::quiet_NaN();
    std::uint16_t material = 0;
  };
  Hit skin(double x, double z) const;
  /// Whether a scatter candidate of class `cls` stands at (x, z): on that
  /// class's skin and under no decal nor building roof (needs cover).
  bool accepts(std::uint16_t cls, double x, double z) const;
  /// An object's base on this level: the skin's height at (x, z), 0 off it.
  float base(double x, double z) const;

  /// Group indices per square in one array (square s: groups[start[s]] ..
  /// groups[start[s + 1]]), in group order: one allocation per level, not
  /// one per square, since a loader builds these for every module it decodes.
  struct Buckets {
    std::vector<std::uint32_t> start, groups;
  };

 private:
  struct Box {
    float x0, z0, x1, z1;
    std::uint32_t group;
  };
  const Level* level_;
  Buckets skin_, decals_;
  /// Per square: bit (material % 64) set when a skin group of that material
  /// lies in the square or one of its eight neighbours, the only squares a
  /// lookup searches. A clear bit proves the skin there is not the class, so
  /// most refused candidates cost one load instead of two triangle searches.
  std::vector<std::uint64_t> nearMaterials_;
  std::vector<Box> buildings_;
};

/// The kept candidates of rules[r] on level 0's `surface` (made with cover),
/// in cell order (row j, then column i); `refused` counts the others that
/// lie in the module. Callers check cellRange(...).count() first.
std::vector<Object> scatter(const Scattering& s, std::size_t r, const Surface& surface,
                            std::uint64_t* refused = nullptr);

/// The order of Module::objects: icon, z, x, then id (a total order).
void sortObjects(std::vector<Object>& objects);

/// Each level's objectY: every object's base on that level's skin.
void placeBases(Module& m);

}  // namespace sandtable::module
