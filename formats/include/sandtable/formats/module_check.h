#pragma once
// Geometric checks of decoded load modules against the grid they were built
// from (docs/VALIDATE.md): every skin and decal triangle lies in
// its grid triangle and in that triangle's plane, the skin tiles each grid
// triangle exactly, lattice vertices carry the grid's elevations bit for
// bit (within heightStep / 2 on a version 2 level with quantised heights),
// skirts hang along every module edge at least as deep as the worst
// crack between levels, maxHeight is the highest vertex of its square, and
// neighbouring modules share their edge vertices at every level.
//
// module::decode checks structure (counts, index ranges, group order); these
// checks need the grid and the pack index header as well, so they live
// beside them in formats/. Work is linear in the triangles of a module and
// allocates per level, never per triangle.
//
// Thread safety: a ModuleChecker is immutable after construction; check()
// and neighbours() may run concurrently on distinct modules.
#include <array>
#include <cstdint>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include "sandtable/formats/grid.h"
#include "sandtable/formats/height_field.h"
#include "sandtable/formats/materials.h"
#include "sandtable/formats/module.h"
#include "sandtable/formats/pack.h"
#include "sandtable/base/result.h"

namespace sandtable::module {

/// Distance tolerance of every geometric check, metres (plus one float ulp
/// of the coordinate's magnitude, so large coordinates stored as float32 do
/// not fail spuriously).
inline constexpr double kCheckTolerance = 1e-3;
/// Relative tolerance of the skin-area and skirt-area sums (plus an
/// absolute float32 rounding floor, see docs/VALIDATE.md, "Tolerances").
inline constexpr double kCheckAreaTolerance = 1e-6;
/// How far maxHeight may lie above the highest vertex of its square, metres.
inline constexpr double kCheckMaxHeightTolerance = 1e-3;

/// How far an object's base may lie from its level's surface, metres.
inline constexpr double kCheckObjectTolerance = 0.01;

/// What the checks may consult and how much they report.
struct CheckOptions {
  /// When set, every group's material id must be a class of this table,
  /// skin groups must use area classes and decal groups line classes of
  /// the group's priority.
  const materials::Table* materials = nullptr;
  /// When set, every object's icon must be below this count (icons.pack).
  std::optional<std::uint32_t> iconCount;
  /// Problems of one kind listed per module (or per neighbour pair) before
  /// the rest are summarised in one line; 0 lists them all.
  std::uint32_t maxPerKind = 5;
};

/// Module sides, in the order ModuleEdges stores them.
enum class Side : std::uint8_t { north = 0, south = 1, west = 2, east = 3 };

/// The skin vertices on a module's four edges at every level: what the
/// neighbour check compares. Small (a few values per edge post), so a
/// validator can keep one row of modules' edges instead of the modules.
struct ModuleEdges {
  /// One edge vertex: `t` is the coordinate along the edge (module-local x
  /// on north/south edges, z on west/east edges), `y` its elevation.
  struct Point {
    float t = 0, y = 0;
  };
  std::uint32_t kx = 0, kz = 0;
  std::uint64_t offset = 0;  ///< the module's offset in the pack, for problems
  /// [level][side]: sorted by t, duplicates (within tolerance) merged.
  std::vector<std::array<std::vector<Point>, 4>> levels;
};

/// Checks modules of one database. Construct once per database: it holds
/// the grid, the index header (module size, levels) and the options.
class ModuleChecker {
 public:
  /// `file` names the pack in problems (usually PackReader::packPath()).
  /// The grid must outlive the checker.
  ModuleChecker(const grid::GridFile& grid, const pack::IndexHeader& header, std::string file,
                CheckOptions options = {});
  /// The same against any HeightField's posts (dynamic terrain: modules
  /// re-meshed from edited heights are checked against those heights). The
  /// field must outlive the checker and hold still while it checks.
  ModuleChecker(const grid::HeightField& heights, const pack::IndexHeader& header, std::string file,
                CheckOptions options = {});
  ~ModuleChecker();

  /// Every per-module check, at every level. `offset` is the module's byte
  /// offset in the pack (named in every problem). Fills `edges` for the
  /// neighbour check when non-null. Ok when the module is sound.
  Status check(const Module& m, std::uint64_t offset, ModuleEdges* edges = nullptr) const;

  /// Compares the shared edge of two adjacent modules at every level: `a`
  /// must be the west or north neighbour of `b` (asserted). Ok when every
  /// skin vertex on the edge has a twin (x, z, y within tolerance).
  Status neighbours(const ModuleEdges& a, const ModuleEdges& b) const;

  const pack::IndexHeader& header() const { return header_; }
  const std::string& file() const { return file_; }
  const CheckOptions& options() const { return options_; }

 private:
  std::unique_ptr<const grid::HeightField> owned_;  ///< the GridFile constructor's adapter
  const grid::HeightField& grid_;
  pack::IndexHeader header_;
  std::string file_;
  CheckOptions options_;
  std::vector<int> classIndex_;  ///< material id -> index in options_.materials->classes, or -1
  void indexClasses();
};

/// One module: ModuleChecker(g, h, file, o).check(m, offset).
Status checkModule(const Module& m, const grid::GridFile& g, const pack::IndexHeader& h, const std::string& file,
                   std::uint64_t offset, const CheckOptions& o = {});

/// Two adjacent modules: `a` is the west or north neighbour of `b`.
Status checkNeighbours(const Module& a, std::uint64_t offsetA, const Module& b, std::uint64_t offsetB,
                       const grid::GridFile& g, const pack::IndexHeader& h, const std::string& file,
                       const CheckOptions& o = {});

}  // namespace sandtable::module
