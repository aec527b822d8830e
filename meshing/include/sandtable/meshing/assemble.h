#pragma once
// A load module assembled from a window of a HeightField's posts: for each level its lattice,
// a skin filled by the caller (the converters' culture decaler, or the
// plain grid triangles), skirts, and per-square heights. The converters'
// module builder, the pager's placeholders and (later) dynamic terrain all
// make their modules here, so the three agree on lattices and skirts.
//
// Thread safety: pure functions over a HeightField (lattice.h); the skin callback
// is called on the caller's thread, level by level, finest first.
#include <cstdint>
#include <functional>
#include <span>

#include "sandtable/formats/height_field.h"
#include "sandtable/formats/module.h"
#include "sandtable/meshing/lattice.h"

namespace sandtable::meshing {

/// Fills `out` with the skin of one level from its lattice, replacing what
/// it held: vertices (the lattice posts first, row by row, y = the lattice
/// height bit for bit), indices and groups sorted by (priority, square,
/// half, material). Returns false to stop the assembly (cancelled: the
/// module is incomplete and must be discarded).
using SkinFn = std::function<bool(int level, const LevelLattice& lattice, module::Level& out)>;

/// The grid's own triangles as the skin: every square split along its
/// SW-NE diagonal into the upper (NW, SW, NE) and lower (NE, SW, SE)
/// triangle, one group each, all of `material` at the skin priority;
/// texture coordinates 0. Reuses out's capacity.
void plainSkin(const LevelLattice& lat, std::uint16_t material, module::Level& out);

/// Completes a level whose skin is filled: spacing and squares from the
/// lattice, skirts of `depth` along every node edge (`node` squares, the
/// same at every level), maxHeight. Returns the skirt triangles added.
/// `lineVertices`: as addSkirts' (a re-meshed level's fine edge vertices).
std::uint64_t finishLevel(const LevelLattice& lat, std::uint32_t node, float depth, std::uint16_t skirtMaterial,
                          module::Level& level, std::span<const std::uint32_t> lineVertices = {});

/// Module (kx, kz) of `levels` levels with `squares` level-0 squares a
/// side: every level's lattice, skirt depths from all of them
/// (skirtDepths), `skin` per level, then finishLevel. Stops early when
/// `skin` returns false (the later levels stay empty).
module::Module assembleModule(const grid::HeightField& g, std::uint32_t squares, int levels, std::uint32_t kx,
                              std::uint32_t kz, std::uint16_t skirtMaterial, const SkinFn& skin);

}  // namespace sandtable::meshing
