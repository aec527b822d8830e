#pragma once
// What the two halves of bench edits share (edits.cpp: the re-mesh cases,
// the journal, memory; edits_live.cpp: the pager-driven runs). Internal to
// sandtable_bench.
#include <array>
#include <cstdint>
#include <memory>
#include <vector>

#include <nlohmann/json.hpp>

#include "sandtable/base/result.h"
#include "sandtable/bench/edits.h"
#include "sandtable/edits/profile.h"
#include "sandtable/formats/edit.h"
#include "sandtable/paging/world.h"

namespace sandtable::bench::editsbench {

/// 60 Hz: the frame the goals are counted in.
inline constexpr double kFrameSeconds = 1.0 / 60.0;

/// A crater of `size` at world (x, z), origin 1.
edit::Edit crater(double x, double z, edits::CraterSize size, std::uint64_t id, double time);

/// Crater site `k` of stream `seed`: uniform over the grid, 20 m inside its edges.
std::array<double, 2> site(const paging::World& w, std::uint64_t seed, std::uint64_t k);

/// {p50, p95, max} of `v` (0s when empty).
nlohmann::json spread(const std::vector<double>& v);

/// CPU seconds of the calling thread.
double threadCpuSeconds();

/// The process's resident set now, bytes.
std::uint64_t rssBytes();

/// The live parts over `world`: latency, sustained runs, the battle. Adds
/// "latency", "sustained", "max_sustained_rate_per_s" and "battle" to `out`.
Status runLive(const std::shared_ptr<const paging::World>& world, const EditsBenchOptions& o, const Notes& notes,
               nlohmann::json& out);

}  // namespace sandtable::bench::editsbench
