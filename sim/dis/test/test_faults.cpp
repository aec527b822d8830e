// Faults and bad input on the DIS link (issue 36, docs/DIS.md §11.5): a
// publishing simulation A and a watching simulation B (TwoSims), with
// faults injected where B drains its queue: packet loss, reordering and
// duplicates, hostile and truncated datagrams among the real traffic, a
// sender that stops and restarts, two senders claiming one entity id.
// Truth is A's own entity state after every step; B's remote entities are
// compared with it (horizontally: land entities are aligned to B's ground).
#include <gtest/gtest.h>

#include <algorithm>
#include <cstdio>
#include <functional>
#include <limits>
#include <map>
#include <random>
#include <vector>

#include "sandtable/dis/monitor.h"
#include "sim_dis_support.h"

namespace sandtable::sim_dis {
namespace {

using test::horizontal;
using test::TwoSims;

constexpr double kThresholdM = 1.0;  // PublishOptions' default position threshold
constexpr double kEncodingSlackM = 0.05;  // float velocities, the anchor's linear map (§11.1)

/// Faults on B's side of the link, seeded: each datagram is lost with
/// probability `loss`, copied with probability `duplicate` (the copy held
/// back 1..copyDelaySteps steps), held back 0..delaySteps steps itself
/// (reordering: a later PDU overtakes it), and each step's batch is
/// shuffled when `shuffle`.
struct Faults {
  double loss = 0, duplicate = 0;
  int delaySteps = 0, copyDelaySteps = 0;
  bool shuffle = false;
  std::mt19937_64 rng{36};
  std::uint64_t step = 0, lost = 0, copies = 0;
  std::vector<std::pair<std::uint64_t, dis::Datagram>> held;  ///< release step, datagram

  void operator()(std::vector<dis::Datagram>& batch) {
    ++step;
    std::uniform_real_distribution<double> u(0, 1);
    for (dis::Datagram& d : batch) {
      if (u(rng) < loss) {
        ++lost;
        continue;
      }
      if (u(rng) < duplicate) {
        ++copies;
        held.emplace_back(step + std::uniform_int_distribution<int>(1, std::max(1, copyDelaySteps))(rng), d);
      }
      held.emplace_back(step + std::uniform_int_distribution<int>(0, delaySteps)(rng), std::move(d));
    }
    batch.clear();
    for (auto it = held.begin(); it != held.end();) {
      if (it->first > step) {
        ++it;
        continue;
      }
      batch.push_back(std::move(it->second));
      it = held.erase(it);
    }
    if (shuffle) std::shuffle(batch.begin(), batch.end(), rng);
  }
};

/// The last timestamp A sent for each of its entities: read off every
/// datagram before the faults touch it.
struct SentLog {
  std::map<std::uint64_t, std::uint32_t> lastStamp;
  std::map<std::uint64_t, std::uint64_t> count;
  void operator()(const std::vector<dis::Datagram>& batch) {
    for (const dis::Datagram& d : batch) {
      auto pdu = dis::decode(d.bytes, "sent");
      if (!pdu || !pdu->entityState) continue;
      const std::uint64_t k = RemoteEntities::key(pdu->entityState->id);
      lastStamp[k] = pdu->header.timestamp;
      ++count[k];
    }
  }
};

/// `n` land entities that zig-zag (Figure 68, a new leg every 3 to 6 s,
/// turns up to 45 degrees at 30 deg/s) at 6 to 12 m/s, kept inside the
/// 2 km world by the edge behaviour.
sim::SimOptions zigzagOptions() {
  sim::SimOptions o;
  o.seed = 36;
  o.behaviour.zigzagPeriodS = 3;
  return o;
}
void addZigzaggers(sim::Simulation& s, int n) {
  for (int k = 0; k < n; ++k) {
    sim::Entity e;
    e.name = "Z-" + std::to_string(k);
    e.position = {500.0 + 300.0 * (k % 4), 0, 600.0 + 500.0 * (k / 4 % 2)};
    e.speedMs = 6 + 2 * (k % 4);
    e.headingDeg = 45.0 * k;
    e.controller = sim::Controller::behaviour;
    e.behaviours.zigzag = true;
    e.behaviours.edge = true;
    ASSERT_TRUE(s.add(e).ok());
  }
}

/// B's position error for A's entities, step by step, against the bound a
/// receiver can promise (see boundM).
struct ErrorLog {
  std::vector<double> samples;
  std::uint64_t unseen = 0;      ///< entity-steps before B had any PDU of the entity
  std::uint64_t fresh = 0;       ///< entity-steps where B held the latest PDU A sent
  std::uint64_t violations = 0;  ///< entity-steps past the bound
  double worstOverBound = -1e9;  ///< error minus bound, largest
  double oldestS = 0;            ///< the oldest PDU B was reckoning from
  double vmax = 0;

  /// The bound. B holds the latest PDU A sent: A's copy of it is within the
  /// threshold (A sends when it is not), and B, which reckons from the
  /// PDU's arrival, lags the copy by the PDU's delay: threshold + v x
  /// (delay + one step). B's PDU is older (a later one lost or held back):
  /// at its send time it was exact; since then the entity and its reckoned
  /// copy each moved at most v, so the error is at most 2 v x its age.
  double boundM(bool isFresh, double ageS, int delaySteps, double stepS) const {
    const double freshBound = kThresholdM + vmax * (delaySteps + 1) * stepS + kEncodingSlackM;
    return isFresh ? freshBound : std::max(freshBound, 2 * vmax * ageS + kEncodingSlackM);
  }

  void measure(TwoSims& t, const SentLog& sent, int delaySteps) {
    for (const sim::Entity& truth : t.a.entities()) {
      vmax = std::max(vmax, Eigen::Vector2d(truth.velocity.x(), truth.velocity.z()).norm());
    }
    for (const sim::Entity& truth : t.a.entities()) {
      const dis::EntityId id = t.ga->disId(truth.id);
      const RemoteEntity* r = t.gb->remotes().find(id);
      const sim::Entity* shown = r ? t.b.find(r->simId) : nullptr;
      if (!shown) {
        ++unseen;
        continue;
      }
      ASSERT_TRUE(r->timestamp.has_value());
      const double error = horizontal(shown->position, truth.position);
      const double ageS = t.a.timeS() - dis::timestampSeconds(*r->timestamp);
      const bool isFresh = sent.lastStamp.at(RemoteEntities::key(id)) == *r->timestamp;
      const double bound = boundM(isFresh, ageS, delaySteps, t.a.options().stepS);
      samples.push_back(error);
      fresh += isFresh;
      violations += error > bound;
      worstOverBound = std::max(worstOverBound, error - bound);
      oldestS = std::max(oldestS, ageS);
    }
  }
  double quantile(double q) const {
    std::vector<double> s = samples;
    if (s.empty()) return 0;
    const std::size_t i = std::min(s.size() - 1, std::size_t(q * double(s.size())));
    std::nth_element(s.begin(), s.begin() + std::ptrdiff_t(i), s.end());
    return s[i];
  }
  double mean() const {
    double sum = 0;
    for (double e : samples) sum += e;
    return samples.empty() ? 0 : sum / double(samples.size());
  }
  double beyond(double m) const {
    return samples.empty() ? 0 : double(std::count_if(samples.begin(), samples.end(), [&](double e) { return e > m; })) /
                                     double(samples.size());
  }
  double max() const { return samples.empty() ? 0 : *std::max_element(samples.begin(), samples.end()); }
};

struct Condition {
  const char* name;
  Faults faults;
};

struct Outcome {
  ErrorLog errors;
  std::uint64_t sent = 0, lost = 0, copies = 0, stale = 0, duplicates = 0;
};

/// Eight zig-zagging entities for 60 s simulated through `faults`.
Outcome runCondition(Faults faults) {
  TwoSims t(zigzagOptions());
  addZigzaggers(t.a, 8);
  SentLog sent;
  t.intoB = [&](std::vector<dis::Datagram>& batch) {
    sent(batch);
    faults(batch);
  };
  Outcome o;
  for (int k = 0; k < 60 * 60; ++k) {
    t.step();
    o.errors.measure(t, sent, faults.delaySteps);
  }
  o.sent = t.ga->counters().sentPdus;
  o.lost = faults.lost;
  o.copies = faults.copies;
  o.stale = t.gb->remotes().counters().stale;
  o.duplicates = t.gb->remotes().counters().duplicates;
  return o;
}

TEST(SimDisFaults, lossReorderingAndDuplicatesStayWithinWhatAMissedPduAllows) {
  std::vector<Condition> conditions;
  conditions.push_back({"none", {}});
  conditions.push_back({"loss 10%", {}});
  conditions.back().faults.loss = 0.10;
  conditions.push_back({"loss 50%", {}});
  conditions.back().faults.loss = 0.50;
  conditions.push_back({"reorder 0-10 steps", {}});
  conditions.back().faults.delaySteps = 10;
  conditions.back().faults.shuffle = true;
  conditions.push_back({"duplicates 20%", {}});
  conditions.back().faults.duplicate = 0.20;
  conditions.back().faults.copyDelaySteps = 10;
  conditions.push_back({"all three", {}});
  conditions.back().faults.loss = 0.10;
  conditions.back().faults.delaySteps = 10;
  conditions.back().faults.shuffle = true;
  conditions.back().faults.duplicate = 0.20;
  conditions.back().faults.copyDelaySteps = 10;

  std::printf("%-20s %6s %5s %5s %5s %5s %8s %8s %8s %9s %8s %7s %6s\n", "condition", "sent", "lost", "dups",
              "stale", "dupsB", "mean m", "p99 m", "max m", ">1m", "oldest s", "fresh", "unseen");
  for (const Condition& c : conditions) {
    const Outcome o = runCondition(c.faults);
    const ErrorLog& e = o.errors;
    std::printf("%-20s %6llu %5llu %5llu %5llu %5llu %8.3f %8.3f %8.3f %8.2f%% %8.2f %6.1f%% %6llu\n", c.name,
                (unsigned long long)o.sent, (unsigned long long)o.lost, (unsigned long long)o.copies,
                (unsigned long long)o.stale, (unsigned long long)o.duplicates, e.mean(), e.quantile(0.99), e.max(),
                100 * e.beyond(kThresholdM), e.oldestS, 100.0 * double(e.fresh) / double(e.samples.size()),
                (unsigned long long)e.unseen);
    EXPECT_EQ(e.violations, 0u) << c.name << ": worst " << e.worstOverBound << " m past the bound";
    EXPECT_GT(e.samples.size(), 8u * 3000) << c.name;
    EXPECT_GT(o.sent, 8u * 20) << c.name;  // the zig-zags make PDUs beyond the heartbeats
    if (c.faults.loss == 0 && c.faults.delaySteps == 0) {
      // No loss, no delay: the threshold plus one step's growth at the top speed.
      EXPECT_LE(e.max(), kThresholdM + e.vmax * zigzagOptions().stepS + kEncodingSlackM) << c.name;
      EXPECT_EQ(e.fresh, e.samples.size()) << c.name;
    }
    if (c.faults.delaySteps > 0) {
      EXPECT_GT(o.stale, 0u) << c.name;
    }
    if (c.faults.duplicate > 0) {
      EXPECT_GT(o.duplicates, 0u) << c.name;
    }
  }
}

TEST(SimDisFaults, anOlderPduArrivingAfterANewerOneDoesNotMoveTheEntityBack) {
  TwoSims t;
  sim::Entity e;
  e.position = {600, 0, 600};
  e.speedMs = 10;
  e.headingDeg = 90;
  auto id = t.a.add(e);
  ASSERT_TRUE(id.ok());
  // Hold B's input back and let A publish: its first PDU, then (turning
  // on the spot past the angle threshold) a second.
  std::vector<dis::Datagram> held;
  t.intoB = [&](std::vector<dis::Datagram>& batch) {
    held.insert(held.end(), batch.begin(), batch.end());
    batch.clear();
  };
  t.step();
  t.a.entity(id.value()).commands.headingDeg = 180;
  while (t.ga->counters().sentPdus < 2) t.step();
  ASSERT_EQ(held.size(), 2u);
  // B gets the newer PDU, then the older one.
  t.intoB = [&](std::vector<dis::Datagram>& batch) { batch = {held[1], held[0]}; };
  t.step();
  t.intoB = nullptr;
  const RemoteEntity* r = t.gb->remotes().find(t.ga->disId(id.value()));
  ASSERT_NE(r, nullptr);
  auto newer = dis::decode(held[1].bytes, "newer");
  ASSERT_TRUE(newer.ok());
  EXPECT_EQ(r->last.location, newer->entityState->location);  // the newer PDU's state holds
  EXPECT_EQ(t.gb->remotes().counters().stale, 1u);
  // The same PDU again, later: a duplicate, not a correction.
  const std::uint64_t corrections = t.gb->remotes().counters().corrections;
  t.toB.push_back(held[1]);
  t.hb.step();
  EXPECT_EQ(t.gb->remotes().counters().duplicates, 1u);
  EXPECT_EQ(t.gb->remotes().counters().corrections, corrections);
}

TEST(SimDisFaults, aSenderWhoseClockRestartsIsTakenAtOnceBeyondTheStaleWindow) {
  RemoteEntities remote(test::testFrame());
  Publisher publisher(remote.frame());
  sim::Entity e;
  e.position = {1000, 0, 1000};
  const Identity who{{1, 1, 1}, {1, 1, 225, 1, 1, 3, 0}, 1};
  auto at = [&](double senderS) {
    auto s = publisher.offer(e, who, senderS, true);
    return test::overTheWire(*s);
  };
  const dis::Address sender{0x7f000001, 3000};
  auto stamp = [](double s) { return dis::timestamp(s, false); };
  ASSERT_NE(remote.update(at(100), sender, 0, 0, stamp(100)), nullptr);
  e.position.x() += 5;
  remote.update(at(95), sender, 1, 1, stamp(95));  // 5 s older: stale
  EXPECT_EQ(remote.counters().stale, 1u);
  EXPECT_EQ(remote.counters().corrections, 0u);
  remote.update(at(2), sender, 2, 2, stamp(2));  // 98 s older: a restarted sender
  remote.update(at(3), sender, 3, 3, stamp(3));
  EXPECT_EQ(remote.counters().corrections, 2u);
  remote.update(at(3590), sender, 4, 4, stamp(3590));  // 13 s before 3 past the hour: a new clock too
  EXPECT_EQ(remote.counters().corrections, 3u);
  remote.update(at(0.5), sender, 5, 5, stamp(0.5));  // the hour turned: 10.5 s later
  EXPECT_EQ(remote.counters().corrections, 4u);
  remote.update(at(3599), sender, 6, 6, stamp(3599));  // 1.5 s before 0.5 past the next hour: stale
  EXPECT_EQ(remote.counters().stale, 2u);
  EXPECT_EQ(remote.counters().corrections, 4u);
  // Another address claiming the id is a conflict, whatever its clock says.
  remote.update(at(1), {0x7f000002, 3000}, 7, 7, stamp(1));
  EXPECT_EQ(remote.counters().conflicts, 1u);
  EXPECT_EQ(remote.counters().stale, 2u);
  EXPECT_EQ(remote.counters().corrections, 4u);
}

/// A hostile datagram: random bytes, a real PDU cut short, one with a
/// header byte changed, one of a type not applied, one with random bytes
/// changed in its body (its entity id moved to site 99 first, so what
/// still decodes is a ghost, not a forged state of a real entity), or a
/// ghost followed by garbage. Each comes from the real sender's address
/// (the worst case: a receiver cannot tell it by its address), so copies
/// of real PDUs that still decode meet the order check. Timestamps and
/// real ids are never forged: nothing can tell a forged state of a real
/// entity from a true one.
dis::Datagram hostile(std::mt19937_64& rng, const dis::Datagram& real) {
  auto pick = [&](int lo, int hi) { return std::uniform_int_distribution<int>(lo, hi)(rng); };
  auto byte = [&] { return std::byte(pick(0, 255)); };
  dis::Datagram d;
  d.sender = real.sender;
  std::vector<std::byte>& b = d.bytes;
  const std::size_t n = real.bytes.size();
  auto ghost = [&] {
    b = real.bytes;
    b[12] = std::byte{0};
    b[13] = std::byte{99};
  };
  switch (pick(0, 5)) {
    case 0:
      b.resize(std::size_t(pick(0, pick(0, 1) ? 40 : 1500)));
      for (std::byte& x : b) x = byte();
      break;
    case 1:
      b.assign(real.bytes.begin(), real.bytes.begin() + pick(0, int(n) - 1));
      break;
    case 2: {
      b = real.bytes;
      static constexpr int kHeaderBytes[] = {0, 1, 2, 3, 8, 9, 10, 11};  // not the timestamp
      b[std::size_t(kHeaderBytes[pick(0, 7)])] = byte();
      break;
    }
    case 3: {
      b = real.bytes;
      int type = pick(4, 255);
      while (type == 11 || type == 12 || type == 43 || type == 44) type = pick(4, 255);
      b[2] = std::byte(type);
      break;
    }
    case 4:
      ghost();
      for (int k = pick(1, 8); k > 0; --k) b[std::size_t(pick(18, int(n) - 1))] = byte();
      break;
    default:
      ghost();
      for (int k = pick(1, 64); k > 0; --k) b.push_back(byte());
      break;
  }
  return d;
}

TEST(SimDisFaults, hostileAndTruncatedDatagramsAreCountedAndTheRealEntitiesKeepUpdating) {
  TwoSims t(zigzagOptions());
  addZigzaggers(t.a, 8);
  SentLog sent;
  std::mt19937_64 rng(1278);
  std::vector<dis::Datagram> recent;  // the real datagrams of the last steps: what the mutations start from
  std::uint64_t hostileSent = 0, realSent = 0;
  constexpr std::uint64_t kHostile = 100000;
  constexpr int kSteps = 60 * 60;
  t.intoB = [&](std::vector<dis::Datagram>& batch) {
    sent(batch);
    realSent += batch.size();
    recent.insert(recent.end(), batch.begin(), batch.end());
    if (recent.size() > 64) recent.erase(recent.begin(), recent.end() - 64);
    if (recent.empty()) return;
    // Spread kHostile over the run, each at a random place among the real ones.
    const std::uint64_t due = kHostile * (t.b.steps() + 1) / kSteps;
    for (; hostileSent < due; ++hostileSent) {
      const dis::Datagram& base = recent[std::size_t(std::uniform_int_distribution<std::size_t>(0, recent.size() - 1)(rng))];
      const auto at = std::uniform_int_distribution<std::size_t>(0, batch.size())(rng);
      batch.insert(batch.begin() + std::ptrdiff_t(at), hostile(rng, base));
    }
  };
  ErrorLog errors;
  for (int k = 0; k < kSteps; ++k) {
    t.step();
    errors.measure(t, sent, 0);
  }
  const GatewayCounters& c = t.gb->counters();
  const RemoteCounters& r = t.gb->remotes().counters();
  std::printf("hostile %llu, real %llu: datagrams %llu, PDUs %llu, malformed %llu, unknown type %llu, other exercise "
              "%llu, entity states %llu (duplicates %llu, stale %llu), fires %llu, detonations %llu, removes %llu, "
              "unplaceable %llu, not added %llu; real entities: error mean %.3f p99 %.3f max %.3f m\n",
              (unsigned long long)hostileSent, (unsigned long long)realSent, (unsigned long long)c.datagrams,
              (unsigned long long)c.pdus, (unsigned long long)c.malformed, (unsigned long long)c.unknownType,
              (unsigned long long)c.otherExercise, (unsigned long long)c.entityStates,
              (unsigned long long)r.duplicates, (unsigned long long)r.stale, (unsigned long long)c.fires,
              (unsigned long long)c.detonations, (unsigned long long)c.removes, (unsigned long long)r.unplaceable,
              (unsigned long long)c.notAdded, errors.mean(), errors.quantile(0.99), errors.max());
  EXPECT_EQ(hostileSent, kHostile);
  // Every datagram is counted, and every PDU decoded is counted once by what became of it.
  EXPECT_EQ(c.datagrams, hostileSent + realSent);
  EXPECT_GE(c.pdus + c.malformed, c.datagrams);
  EXPECT_EQ(c.pdus, c.otherExercise + c.own + c.entityStates + c.fires + c.detonations + c.removes + c.unknownType);
  EXPECT_GT(c.malformed, kHostile / 3);
  EXPECT_GT(c.unknownType, kHostile / 10);
  EXPECT_GT(c.otherExercise, 0u);
  // The real entities: every PDU A sent applied, no more (the hostile copies
  // of real PDUs that still decode are duplicates), and within the threshold.
  for (const sim::Entity& e : t.a.entities()) {
    const dis::EntityId id = t.ga->disId(e.id);
    const RemoteEntity* seen = t.gb->remotes().find(id);
    ASSERT_NE(seen, nullptr) << e.name;
    EXPECT_EQ(seen->updates, sent.count.at(RemoteEntities::key(id))) << e.name;
  }
  EXPECT_EQ(errors.violations, 0u) << "worst " << errors.worstOverBound << " m past the bound";
  EXPECT_LE(errors.max(), kThresholdM + errors.vmax * t.a.options().stepS + kEncodingSlackM);
  EXPECT_EQ(r.conflicts, 0u);
}

TEST(SimDisFaults, aSilentSenderLeavesAtTwelveSecondsAndComesBackAsANewEntity) {
  TwoSims t;
  sim::Entity e;
  e.position = {1000, 0, 1000};
  e.speedMs = 2;
  auto id = t.a.add(e);
  ASSERT_TRUE(id.ok());
  bool cut = false;
  t.intoB = [&](std::vector<dis::Datagram>& batch) {
    if (cut) batch.clear();
  };
  for (int k = 0; k < 60; ++k) t.step();
  const dis::EntityId disId = t.ga->disId(id.value());
  const std::uint32_t firstSim = t.gb->simIdOf(disId);
  ASSERT_NE(firstSim, UINT32_MAX);
  const double heard = t.gb->remotes().find(disId)->heardS;
  cut = true;  // the sender's datagrams stop reaching B
  while (t.b.timeS() < heard + 12 - 1e-6) {
    t.step();  // its pre-step hook at B's time before the step: under 12 s of silence
    ASSERT_NE(t.gb->remotes().find(disId), nullptr) << t.b.timeS();
  }
  t.step();  // the pre-step hook at 12 s of silence expires it
  EXPECT_EQ(t.gb->remotes().find(disId), nullptr);
  EXPECT_EQ(t.b.find(firstSim), nullptr);
  EXPECT_EQ(t.gb->remotes().counters().timedOut, 1u);
  ASSERT_FALSE(t.gb->departed().empty());
  EXPECT_STREQ(t.gb->departed().back().why, "timed out");
  cut = false;  // it speaks again: at its next heartbeat at the latest
  for (int k = 0; k < 60 * 5 && t.gb->simIdOf(disId) == UINT32_MAX; ++k) t.step();
  const std::uint32_t secondSim = t.gb->simIdOf(disId);
  ASSERT_NE(secondSim, UINT32_MAX);
  EXPECT_NE(secondSim, firstSim);  // a new simulation entity
  EXPECT_EQ(t.gb->remotes().counters().created, 2u);
  EXPECT_LT(horizontal(t.b.entity(secondSim).position, t.a.entity(id.value()).position), kThresholdM);
}

TEST(SimDisFaults, twoSendersClaimingOneEntityIdAreCountedByTheGatewayAndTheMonitor) {
  TwoSims t;
  // A third simulation publishing as the same site and application from another address.
  sim::Simulation c(t.world);
  sim::StepHost hc(c);
  GatewayOptions oc;
  oc.site = 1;
  Gateway gc(c, test::testFrame(), oc, nullptr, TwoSims::sender(t.toB, {0x7f000002, 3000}));
  gc.attach(hc);
  sim::Entity e;
  e.position = {700, 0, 700};
  ASSERT_TRUE(t.a.add(e).ok());
  e.position = {900, 0, 700};
  ASSERT_TRUE(c.add(e).ok());  // the same entity number, 1:1:1
  dis::Monitor monitor;
  t.intoB = [&](std::vector<dis::Datagram>& batch) {
    for (const dis::Datagram& d : batch) monitor.add(d);
  };
  for (int k = 0; k < 60 * 6; ++k) {
    t.ha.step();
    hc.step();
    t.hb.step();
  }
  const std::uint64_t fromC = gc.counters().sentPdus, fromA = t.ga->counters().sentPdus;
  ASSERT_GE(fromA, 2u);  // the first PDU and a heartbeat each
  ASSERT_GE(fromC, 2u);
  // The gateway and the monitor both keep the first owner (A: its PDU came
  // first in B's queue) and count every PDU of the other.
  EXPECT_EQ(t.gb->remotes().counters().conflicts, fromC);
  ASSERT_EQ(t.gb->remotes().size(), 1u);
  const RemoteEntity& kept = t.gb->remotes().all().begin()->second;
  EXPECT_EQ(kept.sender, (dis::Address{0x7f000001, 3000}));
  EXPECT_EQ(kept.updates, fromA);
  EXPECT_LT(horizontal(t.b.entity(kept.simId).position, Eigen::Vector3d(700, 0, 700)), 0.05);
  const dis::Report r = monitor.report();
  EXPECT_EQ(r.conflictPdus, fromC);
  ASSERT_EQ(r.conflicts.size(), 1u);
  EXPECT_EQ(r.conflicts[0].id, (dis::EntityId{1, 1, 1}));
  EXPECT_EQ(r.conflicts[0].owner, (dis::Address{0x7f000001, 3000}));
  EXPECT_EQ(r.conflicts[0].other, (dis::Address{0x7f000002, 3000}));
}

}  // namespace
}  // namespace sandtable::sim_dis

namespace sandtable::sim_dis {
namespace {

TEST(SimDisFaults, nonFiniteValuesInAnEntityStateAreRefused) {
  TwoSims t;
  sim::Entity e;
  e.position = {800, 0, 800};
  e.speedMs = 3;
  auto id = t.a.add(e);
  ASSERT_TRUE(id.ok());
  std::vector<dis::Datagram> real;
  t.intoB = [&](std::vector<dis::Datagram>& batch) { real.insert(real.end(), batch.begin(), batch.end()); };
  t.step();
  t.step();
  ASSERT_EQ(real.size(), 1u);
  auto pdu = dis::decode(real[0].bytes, "real");
  ASSERT_TRUE(pdu.ok());
  const double nan = std::numeric_limits<double>::quiet_NaN(), inf = std::numeric_limits<double>::infinity();
  const std::vector<std::function<void(dis::EntityState&)>> spoil = {
      [&](dis::EntityState& s) { s.location.x = nan; },
      [&](dis::EntityState& s) { s.location.z = inf; },
      [&](dis::EntityState& s) { s.velocity.y = float(nan); },
      [&](dis::EntityState& s) { s.orientation.psi = float(inf); },
      [&](dis::EntityState& s) { s.deadReckoning.acceleration.x = float(nan); },
      [&](dis::EntityState& s) { s.deadReckoning.angularVelocity.z = float(-inf); },
  };
  std::uint32_t stamp = pdu->header.timestamp;
  for (const auto& f : spoil) {
    dis::Pdu bad = pdu.value();
    f(*bad.entityState);
    bad.header.timestamp = stamp += 2000;  // newer each time
    dis::Datagram d = real[0];
    d.bytes = dis::encode(bad.header, *bad.entityState);
    t.intoB = [&](std::vector<dis::Datagram>& batch) { batch.push_back(d); };
    t.step();
    t.intoB = nullptr;
    for (const sim::Entity& shown : t.b.entities()) EXPECT_TRUE(shown.position.allFinite());
  }
  const RemoteEntity* r = t.gb->remotes().find(t.ga->disId(id.value()));
  ASSERT_NE(r, nullptr);
  EXPECT_LT(horizontal(t.b.entity(r->simId).position, t.a.entity(id.value()).position), kThresholdM);
  EXPECT_EQ(t.gb->remotes().counters().nonFinite, spoil.size());
}

}  // namespace
}  // namespace sandtable::sim_dis
