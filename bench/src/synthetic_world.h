#pragma once
// What the simulator benchmarks share (bench sim, bench dis): a synthetic
// world of rolling hills in UTM 33N and the zig-zagging land entities of
// the seed's Fort Hunter-Liggett case (VII.C.1). Internal to sandtable_bench.
//
// Thread safety: pure functions; makeHillsGrid writes a work file named
// after the process id and a tag (one call per tag at a time).
#include <cstdint>
#include <memory>

#include "sandtable/base/result.h"
#include "sandtable/formats/grid.h"
#include "sandtable/sim/entity.h"
#include "sandtable/sim/sim_world.h"

namespace sandtable::bench {

/// The grid's north-west corner (UTM 33N easting and northing, metres):
/// the projection a DIS frame over it needs (bench dis).
inline constexpr const char* kHillsCrs = "EPSG:32633";
inline constexpr double kHillsEasting = 500000.0, kHillsNorthing = 4000000.0;

/// A uniform number in [0, 1) for key `k` of stream `seed`.
double unitRandom(std::uint64_t seed, std::uint64_t k);

/// Elevation of the hills at world (x, z), metres.
double hillsAt(double x, double z);

/// A square of `sizeKm` with posts `squareM` apart, written to a work file
/// ("sandtable_bench_TAG_PID.grid", removed at once) and mapped.
Result<std::shared_ptr<const grid::GridFile>> makeHillsGrid(double sizeKm, double squareM, const char* tag);

/// Land entity `k` of `seed`: somewhere 300 m inside the edges, 3 to
/// 15 m/s, simple, tracked or wheeled, zig-zagging with the environment and
/// edge behaviours on.
sim::Entity zigzagEntity(const sim::SimWorld& w, std::uint64_t seed, std::uint32_t k);

}  // namespace sandtable::bench
