// The network monitor (monitor.h): hand-built PDUs (encoded with pdu.h)
// fed as datagrams; counts, rates, gaps, id conflicts, malformed reasons
// and offsets, the exercise filter, caps, and dead reckoning at a time
// against values worked out by hand.
#include <gtest/gtest.h>

#include <cmath>
#include <cstdint>
#include <random>
#include <vector>

#include "sandtable/dis/monitor.h"

namespace sandtable::dis {
namespace {

constexpr Address kA{0x0A000001, 3000};  // 10.0.0.1:3000
constexpr Address kB{0x0A000002, 3000};  // 10.0.0.2:3000

Header header(std::uint8_t exercise = 1) {
  Header h;
  h.exercise = exercise;
  return h;
}

EntityState entity(EntityId id, Vec3d location = {6378137.0, 0, 0}) {
  EntityState e;
  e.id = id;
  e.force = 1;
  e.type = {1, 1, 225, 1, 1, 3, 0};
  e.location = location;
  e.marking = Marking::ascii("TANK");
  e.deadReckoning.algorithm = 2;
  return e;
}

/// A header-only PDU of a type this library does not decode (Comment, 22).
std::vector<std::byte> comment() {
  std::vector<std::byte> b(kHeaderBytes + 8, std::byte{0});
  b[0] = std::byte(7);
  b[1] = std::byte(1);
  b[2] = std::byte(22);
  b[3] = std::byte(5);
  b[9] = std::byte(b.size());
  return b;
}

Datagram datagram(double t, Address from, std::vector<std::vector<std::byte>> pdus) {
  Datagram d;
  d.timeS = t;
  d.sender = from;
  d.destination = {0, 3000};
  for (const auto& p : pdus) d.bytes.insert(d.bytes.end(), p.begin(), p.end());
  return d;
}

const SenderReport* findSender(const Report& r, Address a, bool site) {
  for (const SenderReport& s : r.senders) {
    if (s.address == a && s.hasSiteApplication == site) return &s;
  }
  return nullptr;
}

std::uint64_t countOf(const SenderReport& s, std::uint8_t type) {
  for (const TypeCount& t : s.types) {
    if (t.type == type) return t.count;
  }
  return 0;
}

TEST(DisMonitor, countsPdusByTypeWithRatesOverTheWindow) {
  Monitor m;
  // 10.0.0.1 sends its tank 1:2:1 every second from t = 100 to 110 (11 PDUs),
  // one Fire and one Detonation, and a datagram carrying an Entity State PDU
  // for 1:2:2 and a Comment back to back.
  for (int k = 0; k <= 10; ++k) m.add(datagram(100.0 + k, kA, {encode(header(), entity({1, 2, 1}))}));
  Fire f;
  f.firing = {1, 2, 1};
  m.add(datagram(104.5, kA, {encode(header(), f)}));
  Detonation det;
  det.firing = {1, 2, 1};
  m.add(datagram(104.7, kA, {encode(header(), det)}));
  m.add(datagram(105.2, kA, {encode(header(), entity({1, 2, 2})), comment()}));

  const Report r = m.report();
  EXPECT_EQ(r.datagrams, 14u);
  EXPECT_EQ(r.pdus, 15u);
  EXPECT_EQ(r.fires, 1u);
  EXPECT_EQ(r.detonations, 1u);
  EXPECT_EQ(r.unknownTypes, 1u);
  EXPECT_EQ(r.malformed, 0u);
  EXPECT_DOUBLE_EQ(r.windowS, 10.0);

  const SenderReport* s = findSender(r, kA, true);
  ASSERT_NE(s, nullptr);
  EXPECT_EQ(s->site, 1);
  EXPECT_EQ(s->application, 2);
  EXPECT_EQ(s->pdus, 14u);  // the Comment carries no id: it goes to the address's other row
  EXPECT_EQ(countOf(*s, 1), 12u);
  EXPECT_EQ(countOf(*s, 2), 1u);
  EXPECT_EQ(countOf(*s, 3), 1u);
  EXPECT_DOUBLE_EQ(s->ratePerS, 1.4);  // 14 PDUs over 10 s
  EXPECT_DOUBLE_EQ(s->types.front().ratePerS, 1.2);
  EXPECT_EQ(s->fires, 1u);
  EXPECT_EQ(s->detonations, 1u);
  EXPECT_EQ(s->entities, 2u);
  EXPECT_EQ(s->unknownTypes, 0u);

  const SenderReport* other = findSender(r, kA, false);
  ASSERT_NE(other, nullptr);
  EXPECT_EQ(other->pdus, 1u);
  EXPECT_EQ(other->unknownTypes, 1u);
  EXPECT_EQ(countOf(*other, 22), 1u);
  EXPECT_EQ(pduTypeName(22), "Comment");
  EXPECT_EQ(pduTypeName(1), "Entity State");
  EXPECT_EQ(pduTypeName(72), "Attribute");
  EXPECT_EQ(pduTypeName(200), "");

  // A live report divides by the time up to now.
  EXPECT_DOUBLE_EQ(findSender(m.report(120.0), kA, true)->ratePerS, 14.0 / 20.0);
}

TEST(DisMonitor, keepsEntitiesWithTheirPartsAlgorithmsAndHeartbeatGaps) {
  Monitor m;
  EntityState e = entity({1, 2, 7});
  e.force = 2;
  e.marking = Marking::ascii("T72 A");
  e.parameters.push_back(toParameter(ArticulatedPart{1, 0, 4096 + 11, 1.5f}));
  e.parameters.push_back(toParameter(AttachedPart{0, 0, 1, {2, 9, 225, 2, 1, 0, 0}}));
  e.parameters.push_back(VariableParameter{3, {}});
  // PDUs at 0, 1, 6 (a 5 s gap), 7; the third and fourth use algorithm 4.
  for (double t : {0.0, 1.0, 6.0, 7.0}) {
    if (t > 5) e.deadReckoning.algorithm = 4;
    e.location.x += 1.0;
    m.add(datagram(t, kA, {encode(header(), e)}));
  }
  const Report r = m.report();
  ASSERT_EQ(r.entities.size(), 1u);
  const EntityReport& x = r.entities.front();
  EXPECT_EQ(x.exercise, 1);
  EXPECT_EQ(x.id, (EntityId{1, 2, 7}));
  EXPECT_EQ(x.sender, kA);
  EXPECT_EQ(x.type, (EntityType{1, 1, 225, 1, 1, 3, 0}));
  EXPECT_EQ(x.force, 2);
  EXPECT_EQ(x.marking, "T72 A");
  ASSERT_EQ(x.articulated.size(), 1u);
  EXPECT_EQ(x.articulated[0].parameterType, 4107u);
  EXPECT_EQ(x.articulated[0].value, 1.5f);
  ASSERT_EQ(x.attached.size(), 1u);
  EXPECT_EQ(x.attached[0].type, (EntityType{2, 9, 225, 2, 1, 0, 0}));
  EXPECT_EQ(x.otherRecords, 1u);
  EXPECT_EQ(x.algorithms, (std::vector<std::uint8_t>{2, 4}));
  EXPECT_EQ(x.algorithm, 4);
  EXPECT_EQ(x.updates, 4u);
  EXPECT_DOUBLE_EQ(x.firstS, 0.0);
  EXPECT_DOUBLE_EQ(x.lastS, 7.0);
  EXPECT_DOUBLE_EQ(x.largestGapS, 5.0);
  EXPECT_DOUBLE_EQ(x.location.x, 6378137.0 + 4.0);  // the last PDU's
  const SenderReport* s = findSender(r, kA, true);
  ASSERT_NE(s, nullptr);
  EXPECT_DOUBLE_EQ(s->largestGapS, 5.0);
  EXPECT_DOUBLE_EQ(s->largestHeartbeatGapS, 5.0);
}

TEST(DisMonitor, countsAndListsAnIdClaimedByTwoAddresses) {
  Monitor m;
  m.add(datagram(0, kA, {encode(header(), entity({1, 2, 3}, {1, 0, 0}))}));
  m.add(datagram(1, kB, {encode(header(), entity({1, 2, 3}, {2, 0, 0}))}));
  m.add(datagram(2, kB, {encode(header(), entity({1, 2, 3}, {3, 0, 0}))}));
  m.add(datagram(3, kA, {encode(header(), entity({1, 2, 4}))}));
  const Report r = m.report();
  EXPECT_EQ(r.conflictPdus, 2u);
  ASSERT_EQ(r.conflicts.size(), 1u);
  EXPECT_EQ(r.conflicts[0].id, (EntityId{1, 2, 3}));
  EXPECT_EQ(r.conflicts[0].owner, kA);
  EXPECT_EQ(r.conflicts[0].other, kB);
  EXPECT_EQ(r.conflicts[0].pdus, 2u);
  // The first owner's track is kept; the other address is still a sender.
  ASSERT_EQ(r.entities.size(), 2u);
  EXPECT_EQ(r.entities[0].location.x, 1.0);
  EXPECT_EQ(r.entities[0].updates, 1u);
  const SenderReport* b = findSender(r, kB, true);
  ASSERT_NE(b, nullptr);
  EXPECT_EQ(b->pdus, 2u);
  EXPECT_EQ(b->entities, 0u);
}

TEST(DisMonitor, countsMalformedPdusByReasonWithTheirOffsetInTheDatagram) {
  Monitor m;
  const auto good = encode(header(), entity({1, 2, 1}));  // 144 bytes
  Fire f;
  auto fire = encode(header(), f);                        // 96 bytes
  // 1: a good PDU, then a Fire cut after 50 bytes: the decoder stops at the
  // end of what arrived, byte 144 + 50 of the datagram.
  m.add(datagram(1, kA, {good, std::vector<std::byte>(fire.begin(), fire.begin() + 50)}));
  // 2: a Fire whose length says 100 (4 bytes of junk after it), then a good
  // PDU, which is still read: the bad one's length is usable.
  auto longFire = fire;
  longFire[9] = std::byte(100);
  longFire.resize(100, std::byte{0});
  m.add(datagram(2, kA, {longFire, good}));
  // 3: version 9 at the start: nothing after it can be trusted.
  auto v9 = good;
  v9[0] = std::byte(9);
  m.add(datagram(3, kA, {v9, good}));
  // 4: another truncated PDU, 5 bytes alone; 5: an empty datagram.
  m.add(datagram(4, kB, {std::vector<std::byte>(5, std::byte{7})}));
  m.add(datagram(5, kB, {}));

  const Report r = m.report();
  EXPECT_EQ(r.malformed, 5u);
  EXPECT_EQ(r.pdus, 2u);  // the good PDUs of datagrams 1 and 2
  ASSERT_EQ(r.reasons.size(), 4u);
  // Most frequent first: the 12-byte header reason twice (datagrams 4 and 5).
  EXPECT_EQ(r.reasons[0].reason, "truncated: a PDU header needs N bytes, N arrived");
  EXPECT_EQ(r.reasons[0].count, 2u);
  ASSERT_EQ(r.reasons[0].examples.size(), 2u);
  EXPECT_EQ(r.reasons[0].examples[0].offset, 5u);
  EXPECT_EQ(r.reasons[0].examples[0].datagram, 4u);
  EXPECT_EQ(r.reasons[0].examples[0].sender, kB);
  EXPECT_EQ(r.reasons[0].examples[1].offset, 0u);
  auto find = [&](const std::string& reason) -> const ReasonReport* {
    for (const ReasonReport& x : r.reasons) {
      if (x.reason == reason) return &x;
    }
    return nullptr;
  };
  const ReasonReport* cut = find("truncated: the header gives N bytes, N arrived");
  ASSERT_NE(cut, nullptr);
  EXPECT_EQ(cut->examples.at(0).offset, 194u);
  EXPECT_EQ(cut->examples.at(0).message, "dis: truncated: the header gives 96 bytes, 50 arrived");
  EXPECT_DOUBLE_EQ(cut->examples.at(0).timeS, 1.0);
  const ReasonReport* length = find("a Fire PDU is N bytes; the length is N");
  ASSERT_NE(length, nullptr);
  EXPECT_EQ(length->examples.at(0).offset, 8u);  // the length field
  const ReasonReport* version = find("protocol version N is not supported (N or N)");
  ASSERT_NE(version, nullptr);
  EXPECT_EQ(version->examples.at(0).offset, 0u);
  EXPECT_EQ(version->examples.at(0).datagram, 3u);
  // Malformed PDUs go to their address's row without a site:application.
  const SenderReport* a = findSender(r, kA, false);
  ASSERT_NE(a, nullptr);
  EXPECT_EQ(a->malformed, 3u);
  EXPECT_EQ(findSender(r, kB, false)->malformed, 2u);
}

TEST(DisMonitor, theExerciseFilterIgnoresOtherExercises) {
  MonitorOptions o;
  o.exercise = 3;
  Monitor m(o);
  m.add(datagram(0, kA, {encode(header(3), entity({1, 2, 1})), encode(header(4), entity({1, 2, 2}))}));
  auto bad = encode(header(4), entity({1, 2, 3}));
  bad[9] = std::byte(200);  // malformed, but another exercise's: not counted as malformed
  m.add(datagram(1, kA, {bad}));
  const Report r = m.report();
  EXPECT_EQ(r.pdus, 1u);
  EXPECT_EQ(r.otherExercise, 2u);
  EXPECT_EQ(r.malformed, 0u);
  ASSERT_EQ(r.entities.size(), 1u);
  EXPECT_EQ(r.entities[0].id.entity, 1);
  EXPECT_EQ(r.entities[0].exercise, 3);
}

TEST(DisMonitor, capsAreCountedNotStored) {
  MonitorOptions o;
  o.maxSenders = 2;
  o.maxEntities = 2;
  o.maxReasons = 1;
  o.examplesPerReason = 1;
  o.maxConflictsListed = 0;
  Monitor m(o);
  for (std::uint16_t k = 1; k <= 3; ++k) m.add(datagram(k, kA, {encode(header(), entity({1, 2, k}))}));
  m.add(datagram(4, kB, {encode(header(), entity({1, 2, 1}))}));  // a conflict, past its list cap
  m.add(datagram(5, {0x0A000003, 1}, {encode(header(), entity({1, 9, 1}))}));  // a third sender
  m.add(datagram(6, kA, {std::vector<std::byte>(3, std::byte{0})}));  // the only reason kept
  m.add(datagram(7, kA, {std::vector<std::byte>(4, std::byte{0})}));  // the same reason, no example
  auto v9 = encode(header(), entity({1, 2, 1}));
  v9[0] = std::byte(9);
  m.add(datagram(8, kA, {v9}));  // a second reason, past the cap
  const Report r = m.report();
  EXPECT_EQ(r.senders.size(), 2u);
  EXPECT_EQ(r.entities.size(), 2u);
  EXPECT_EQ(r.capped.entities, 2u);  // 1:2:3, and 1:9:1 (whose sender is past its cap too)
  EXPECT_EQ(r.capped.conflicts, 1u);
  EXPECT_EQ(r.conflictPdus, 1u);
  EXPECT_TRUE(r.conflicts.empty());
  EXPECT_EQ(r.capped.senders, 4u);  // the third sender's PDU and kA's three malformed ones (a third key)
  EXPECT_EQ(r.malformed, 3u);
  ASSERT_EQ(r.reasons.size(), 1u);
  EXPECT_EQ(r.reasons[0].count, 2u);
  EXPECT_EQ(r.reasons[0].examples.size(), 1u);
  EXPECT_EQ(r.capped.reasons, 1u);
}

TEST(DisMonitor, deadReckonsAnEntityToATimeByHand) {
  Monitor m;
  // FPW (2): x = x0 + v dt.
  EntityState a = entity({1, 2, 1}, {6378137.0, 100.0, -50.0});
  a.velocity = {2.0f, -4.0f, 0.5f};
  m.add(datagram(10.0, kA, {encode(header(), a)}));
  // FVW (5): x = x0 + v dt + a dt^2 / 2.
  EntityState b = entity({1, 2, 2}, {0.0, 6378137.0, 0.0});
  b.deadReckoning.algorithm = 5;
  b.velocity = {10.0f, 0, 0};
  b.deadReckoning.acceleration = {0, 0, 2.0f};
  m.add(datagram(11.0, kA, {encode(header(), b)}));
  // FPB (6) heading psi = 90 degrees about ECEF Z: body x is ECEF +Y, so 10 m/s
  // forward in body axes moves +Y in the world.
  EntityState c = entity({1, 2, 3}, {6378137.0, 0.0, 0.0});
  c.deadReckoning.algorithm = 6;
  c.orientation = {float(M_PI / 2), 0, 0};
  c.velocity = {10.0f, 0, 0};
  m.add(datagram(12.0, kA, {encode(header(), c)}));

  const auto sa = m.state({1, 2, 1}, 12.5);
  ASSERT_TRUE(sa.has_value());
  EXPECT_DOUBLE_EQ(sa->pduTimeS, 10.0);
  EXPECT_NEAR(sa->location.x, 6378137.0 + 5.0, 1e-6);
  EXPECT_NEAR(sa->location.y, 100.0 - 10.0, 1e-9);
  EXPECT_NEAR(sa->location.z, -50.0 + 1.25, 1e-9);
  EXPECT_NEAR(sa->worldVelocity.y, -4.0, 1e-9);

  const auto sb = m.state(1, {1, 2, 2}, 14.0);  // dt 3: 30 m along X, 9 m along Z
  ASSERT_TRUE(sb.has_value());
  EXPECT_NEAR(sb->location.x, 30.0, 1e-9);
  EXPECT_NEAR(sb->location.y, 6378137.0, 1e-6);
  EXPECT_NEAR(sb->location.z, 9.0, 1e-9);
  EXPECT_NEAR(sb->worldVelocity.z, 6.0, 1e-9);

  const auto sc = m.state({1, 2, 3}, 14.0);  // dt 2: 20 m along +Y
  ASSERT_TRUE(sc.has_value());
  EXPECT_NEAR(sc->location.x, 6378137.0, 1e-5);
  EXPECT_NEAR(sc->location.y, 20.0, 1e-5);
  EXPECT_NEAR(sc->location.z, 0.0, 1e-9);
  EXPECT_NEAR(sc->worldVelocity.x, 0.0, 1e-5);
  EXPECT_NEAR(sc->worldVelocity.y, 10.0, 1e-5);
  EXPECT_NEAR(sc->orientation.psi, M_PI / 2, 1e-6);

  // Before the first PDU, or for an unknown entity (or exercise): nothing.
  EXPECT_FALSE(m.state({1, 2, 1}, 9.0).has_value());
  EXPECT_FALSE(m.state({1, 2, 99}, 20.0).has_value());
  EXPECT_FALSE(m.state(2, {1, 2, 1}, 20.0).has_value());
}

TEST(DisMonitor, reckonsFromThePduBeforeATimeBetweenTheLastTwo) {
  Monitor m;
  EntityState a = entity({1, 2, 1}, {6378137.0, 0, 0});
  a.velocity = {0, 1.0f, 0};
  m.add(datagram(10.0, kA, {encode(header(), a)}));
  a.location.y = 1000.0;  // a correction: the sender's true position at 20
  m.add(datagram(20.0, kA, {encode(header(), a)}));
  const auto before = m.state({1, 2, 1}, 15.0);
  ASSERT_TRUE(before.has_value());
  EXPECT_DOUBLE_EQ(before->pduTimeS, 10.0);
  EXPECT_NEAR(before->location.y, 5.0, 1e-9);
  const auto after = m.state({1, 2, 1}, 21.0);
  ASSERT_TRUE(after.has_value());
  EXPECT_NEAR(after->location.y, 1001.0, 1e-9);
  EXPECT_FALSE(m.state({1, 2, 1}, 5.0).has_value());
}

// Hostile bytes: every prefix of a two-PDU datagram and random datagrams
// (some with a plausible header) are counted, never crash, and every
// datagram is accounted for as at least one PDU or one malformed PDU.
TEST(DisMonitor, everyPrefixAndRandomBytesAreCounted) {
  Monitor m;
  EntityState e = entity({1, 2, 1});
  e.parameters.push_back(toParameter(ArticulatedPart{1, 0, 4096 + 11, 1.5f}));
  const auto a = encode(header(), e);
  Fire f;
  const auto b = encode(header(), f);
  std::vector<std::byte> both(a);
  both.insert(both.end(), b.begin(), b.end());
  std::uint64_t datagrams = 0;
  for (std::size_t n = 0; n <= both.size(); ++n) {
    Datagram d = datagram(double(n), kA, {});
    d.bytes.assign(both.begin(), both.begin() + std::ptrdiff_t(n));
    m.add(d);
    ++datagrams;
    const Report r = m.report();
    ASSERT_GE(r.pdus + r.malformed, datagrams) << n;
  }
  std::mt19937 rng(36);
  for (int k = 0; k < 20000; ++k) {
    Datagram d = datagram(1000.0 + k, Address{std::uint32_t(rng()), std::uint16_t(rng())}, {});
    d.bytes.resize(rng() % 400);
    for (auto& x : d.bytes) x = std::byte(rng());
    if (k % 2 == 0 && d.bytes.size() >= 12) {  // a plausible header, so bodies are reached
      d.bytes[0] = std::byte(7);
      d.bytes[2] = std::byte(1 + rng() % 3);
      d.bytes[8] = std::byte(d.bytes.size() >> 8);
      d.bytes[9] = std::byte(d.bytes.size() & 255);
    }
    m.add(d);
  }
  const Report r = m.report();
  EXPECT_EQ(r.datagrams, datagrams + 20000);
  EXPECT_GE(r.pdus + r.malformed, r.datagrams);
  EXPECT_LE(r.senders.size(), MonitorOptions{}.maxSenders);
  EXPECT_LE(r.reasons.size(), MonitorOptions{}.maxReasons);
}

}  // namespace
}  // namespace sandtable::dis
