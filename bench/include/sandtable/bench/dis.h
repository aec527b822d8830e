#pragma once
// The DIS benchmark (`sandtable bench dis`; docs/DIS.md §12): the issue's
// network figures, each beside a baseline measured in the same run.
//
// Timing: the one-core parts (1, 3, 5) count the measuring thread's CPU
// time (CLOCK_THREAD_CPUTIME_ID), so that a shared machine charges them
// only for the time they ran; the loopback part counts wall time.
//
// 1. Memory: a pre-encoded stream of Entity State PDUs (one per datagram,
//    two articulation parameters each) for `entities` remote entities,
//    `pdusPerEntity` each, applied by a sim_dis::Gateway over a Simulation
//    on a synthetic world. Baseline: dis::decode alone over the same
//    stream. The first round creates the entities (PROJ anchors) and is
//    timed apart; the headline is the update rounds.
// 2. Loopback: a sender thread blasts the same PDUs over UDP to
//    127.0.0.1, a dis::Receiver queues them and this thread drains and
//    applies them. Baseline: the same run draining without applying.
//    PDUs received and applied per second, kernel and queue drops, and the
//    one-way latency (the sender's steady clock rides in the PDU's
//    relative timestamp field as a sequence number into a side table).
// 3. Dead reckoning: RemoteEntities::stateAt for every tracked entity at
//    60 Hz, for each of `trackedCounts`. Baseline: dis::advance alone
//    (the closed-form motion, no frame conversion).
// 4. The seed's Table 9: one scripted exercise (zig-zagging land entities
//    and aircraft), published by a Publisher per setting into its own
//    RemoteEntities; PDUs per second and the receivers' position error
//    for each threshold and air algorithm, beside time-based sending at
//    the seed's fixed intervals. Deterministic: one run each.
// 5. Watching: the gateway's pre-step work with N tracked entities and no
//    PDUs (placing every remote entity in the simulation), and a whole
//    step, in ms per frame against 30 fps. The viewer's own frame rate
//    with N tracked entities is not measured (fly --dis does not exist yet).
//
// Thread safety: one benchmark at a time per process (work files named
// after the process id); the loopback part starts its own threads.
#include <cstdint>
#include <vector>

#include <nlohmann/json.hpp>

#include "sandtable/base/result.h"
#include "sandtable/bench/notes.h"

namespace sandtable::bench {

struct DisBenchOptions {
  std::uint32_t entities = 10000;      ///< remote entities in the memory and loopback streams, 1..1,000,000
  std::uint32_t pdusPerEntity = 6;     ///< PDUs of each in the stream, 2..100 (the first creates it)
  std::uint32_t loopbackPdus = 200000; ///< sent over the socket per run, 1,000..10,000,000
  std::vector<std::uint32_t> trackedCounts = {1000, 10000, 100000};  ///< each 1..1,000,000
  std::vector<std::uint32_t> exerciseCounts = {100, 1000};           ///< Table 9 exercises, each 1..100,000
  double exerciseSeconds = 30;         ///< simulated seconds per Table 9 exercise, 1..3600
  int repeat = 3;                      ///< timed runs of each; medians (1..100)
  std::uint64_t seed = 1;
};

/// `sandtable bench dis --quick`: the same parts at sizes a smoke test runs
/// in seconds.
DisBenchOptions quickDisBenchOptions();

struct DisBenchReport {
  /// What `sandtable bench dis --json` prints: options, memory {decode,
  /// apply, create, apply_over_decode, goal_pdus_per_s, meets_goal},
  /// loopback {receive, apply, latency_ms, drops, goal_pdus_per_s,
  /// meets_goal}, dead_reckoning[] {entities, state_at, advance,
  /// state_at_over_advance, step_ms, fits_60hz}, table9 {exercises[] with
  /// error-based and time-based cases}, watch[] {entities, before_step_ms,
  /// step_ms, fits_30fps}, viewer_measured (false) and notes.
  nlohmann::json json;
};

Result<DisBenchReport> runDisBench(const DisBenchOptions& options, const Notes& notes = {});

}  // namespace sandtable::bench
