// sandtable bench dis: flags and printing for bench::runDisBench, the DIS
// figures of issue 36 (docs/DIS.md §12).
#include <cstdio>
#include <memory>

#include "cmd_bench.h"
#include "sandtable/bench/dis.h"

namespace sandtable::cli {
namespace {

constexpr const char* kCmd = "bench dis";

struct Args {
  bench::DisBenchOptions o;
  bool json = false, quick = false;
};

const FlagMap kFlags = {{"DisBenchOptions::entities", "--entities"},
                        {"DisBenchOptions::pdusPerEntity", "--pdus-per-entity"},
                        {"DisBenchOptions::loopbackPdus", "--loopback-pdus"},
                        {"DisBenchOptions::trackedCounts", "--tracked"},
                        {"DisBenchOptions::exerciseCounts", "--exercises"},
                        {"DisBenchOptions::exerciseSeconds", "--exercise-seconds"},
                        {"DisBenchOptions::repeat", "--repeat"}};

double d(const nlohmann::json& j, const char* key) { return j[key].get<double>(); }

void printHuman(const nlohmann::json& j) {
  const auto& o = j["options"];
  std::printf("bench dis: medians of %d runs, one core per part unless named (%u hardware threads)\n",
              o["repeat"].get<int>(), o["hardware_threads"].get<unsigned>());
  const auto& m = j["memory"];
  std::printf("\n1. Entity State PDUs from memory (%u entities x %u PDUs, %zu bytes each, one per datagram)\n",
              o["entities"].get<unsigned>(), o["pdus_per_entity"].get<unsigned>(), m["pdu_bytes"].get<std::size_t>());
  std::printf("   decode only (baseline)   %12.0f PDUs/s\n", d(m["decode"], "per_s"));
  std::printf("   decode + apply (gateway) %12.0f PDUs/s  (%.2f of decode; goal %.0f: %s)\n", d(m["apply"], "per_s"),
              d(m, "apply_over_decode"), d(m, "goal_pdus_per_s"), m["meets_goal"].get<bool>() ? "met" : "not met");
  std::printf("   first PDU (creates)      %12.0f PDUs/s\n", d(m["create"], "per_s"));
  const auto& l = j["loopback"];
  std::printf("\n2. Through a loopback UDP socket (%u PDUs per run, sender thread + receiver thread + consumer)\n",
              l["pdus_per_run"].get<unsigned>());
  std::printf("   received, drained only   %12.0f PDUs/s\n", d(l["receive"], "per_s"));
  std::printf("   received and applied     %12.0f PDUs/s  (%.2f of drain only, %.2f of memory; goal %.0f: %s)\n",
              d(l["apply"], "per_s"), d(l, "apply_over_receive"), d(l, "apply_over_memory"), d(l, "goal_pdus_per_s"),
              l["meets_goal"].get<bool>() ? "met" : "not met");
  std::printf("   sent                     %12.0f PDUs/s%s\n", d(l, "sent_per_s"),
              l["sender_limited"].get<bool>() ? "  (nothing lost: the sender set the rate; a lower bound)" : "");
  std::printf("   drops (all runs)         kernel %llu, queue %llu; most lost in one run %llu\n",
              (unsigned long long)l["drops"]["kernel"].get<std::uint64_t>(),
              (unsigned long long)l["drops"]["queue"].get<std::uint64_t>(),
              (unsigned long long)l["drops"]["max_lost_per_run"].get<std::uint64_t>());
  for (const char* which : {"latency_blast", "latency_paced"}) {
    const auto& x = l[which];
    std::printf("   latency %s  read p50 %.3f p99 %.3f ms, applied p50 %.3f p99 %.3f ms\n",
                std::string(which) == "latency_blast" ? "at full blast " : "paced 20,000/s",
                d(x["read"], "p50_ms"), d(x["read"], "p99_ms"), d(x["applied"], "p50_ms"), d(x["applied"], "p99_ms"));
  }
  std::printf("\n3. Remote entities dead reckoned on one core (60 Hz)\n");
  for (const auto& c : j["dead_reckoning"]) {
    std::printf("   %7u entities  stateAt %12.0f entity-steps/s  (advance alone %12.0f: %.1fx)  %.2f ms/step  %s\n",
                c["entities"].get<unsigned>(), d(c["state_at"], "per_s"), d(c["advance"], "per_s"),
                d(c, "state_at_over_advance"), d(c, "step_ms"), c["fits_60hz"].get<bool>() ? "fits 60 Hz" : "over 60 Hz");
  }
  std::printf("\n4. Table 9: PDUs and receivers' position error (errors at 10 Hz; land FPW 2, aircraft as named)\n");
  for (const auto& e : j["table9"]["exercises"]) {
    std::printf("   %u entities (%u aircraft), %.0f s, %llu entity collisions:\n", e["entities"].get<unsigned>(),
                e["air_entities"].get<unsigned>(), d(e, "seconds"),
                (unsigned long long)e["entity_collisions"].get<std::uint64_t>());
    std::printf("     %-22s %10s %9s %10s %10s %10s %10s\n", "sending", "PDUs/s", "/entity/s", "mean m", "max m",
                "air mean", "air max");
    for (const auto& c : e["error_based"]) {
      char name[64];
      std::snprintf(name, sizeof name, "threshold %.1f m, air %d", d(c, "threshold_m"), c["air_algorithm"].get<int>());
      std::printf("     %-22s %10.1f %9.3f %10.3f %10.3f %10.3f %10.3f\n", name, d(c, "pdus_per_s"),
                  d(c, "pdus_per_entity_s"), d(c["error"], "mean_m"), d(c["error"], "max_m"),
                  d(c["air_error"], "mean_m"), d(c["air_error"], "max_m"));
    }
    for (const auto& c : e["time_based"]) {
      char name[64];
      std::snprintf(name, sizeof name, "every %.4g s (FPW)", d(c, "interval_s"));
      std::printf("     %-22s %10.1f %9.3f %10.3f %10.3f %10.3f %10.3f  (%.2fx the PDUs, %.2fx the mean error of 1 m)\n",
                  name, d(c, "pdus_per_s"), d(c, "pdus_per_entity_s"), d(c["error"], "mean_m"), d(c["error"], "max_m"),
                  d(c["air_error"], "mean_m"), d(c["air_error"], "max_m"), d(c, "pdus_over_threshold_1m"),
                  d(c, "mean_error_over_threshold_1m"));
    }
  }
  std::printf("\n5. Watching N entities: the gateway's pre-step and the simulation's step, no rendering\n");
  for (const auto& c : j["watch"]) {
    std::printf("   %7u entities  pre-step %8.2f ms  step %8.2f ms  frame %8.2f ms  %s\n", c["entities"].get<unsigned>(),
                d(c, "before_step_ms"), d(c, "sim_step_ms"), d(c, "frame_ms"),
                c["fits_30fps"].get<bool>() ? "fits 30 fps" : "over 30 fps");
  }
  std::printf("   The viewer's own frame rate (drawing too) is measured with fly --dis beside sim --dis: docs/DIS.md §13.\n");
}

int run(Args a) {
  if (a.quick) {
    const bench::DisBenchOptions q = bench::quickDisBenchOptions();
    a.o.entities = q.entities;
    a.o.pdusPerEntity = q.pdusPerEntity;
    a.o.loopbackPdus = q.loopbackPdus;
    a.o.trackedCounts = q.trackedCounts;
    a.o.exerciseCounts = q.exerciseCounts;
    a.o.exerciseSeconds = q.exerciseSeconds;
  }
  auto r = bench::runDisBench(a.o, stderrNotes("bench", a.json, kFlags));
  if (!r) return reportBenchProblems(kCmd, r.problems(), kFlags);
  if (a.json) std::printf("%s\n", r->json.dump(2).c_str());
  else printHuman(r->json);
  return kOk;
}

}  // namespace

void registerBenchDis(CLI::App& bench, Commands& c) {
  auto a = std::make_shared<Args>();
  auto& o = a->o;
  auto* sub = bench.add_subcommand("dis", "DIS Entity State PDUs applied per second, dead reckoning, Table 9");
  sub->footer(
      "Example:\n  sandtable bench dis\n  sandtable bench dis --quick --json\n"
      "Parts (docs/DIS.md §12): Entity State PDUs decoded and applied from memory (baseline: decode only);\n"
      "through a loopback UDP socket (baseline: drained only), with one-way latency; remote entities dead\n"
      "reckoned at 60 Hz (baseline: the closed-form motion alone); the seed's Table 9 (threshold sending\n"
      "against time-based sending at 1/15, 1 and 5 s); the gateway's pre-step with N tracked entities.\n"
      "--quick runs every part at small sizes (the other size flags are then ignored).");
  sub->add_option("--entities", o.entities, "Remote entities in the memory and loopback streams")->default_val(10000);
  sub->add_option("--pdus-per-entity", o.pdusPerEntity, "Entity State PDUs of each in the stream")->default_val(6);
  sub->add_option("--loopback-pdus", o.loopbackPdus, "PDUs sent over the socket per run")->default_val(200000);
  sub->add_option("--tracked", o.trackedCounts, "Tracked entity counts, comma separated")
      ->delimiter(',')
      ->default_str("1000,10000,100000");
  sub->add_option("--exercises", o.exerciseCounts, "Table 9 exercise sizes, comma separated")
      ->delimiter(',')
      ->default_str("100,1000");
  sub->add_option("--exercise-seconds", o.exerciseSeconds, "Simulated seconds per Table 9 exercise")->default_val(30);
  sub->add_option("--repeat", o.repeat, "Timed runs of each (median reported)")->default_val(3);
  sub->add_option("--seed", o.seed, "Seed of the entities")->default_val(1);
  sub->add_flag("--quick", a->quick, "Small sizes: a smoke test in seconds");
  sub->add_flag("--json", a->json, "Print one JSON object");
  c.add(sub, [a] { return run(*a); });
}

}  // namespace sandtable::cli
