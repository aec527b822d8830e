// Terrain edits as DIS objects (objects.h, object_tracker.h; docs/DIS.md
// §14): each kind through its PDU's bytes and back, the sender's edit
// (asReceived) equal to what a receiver makes and a fixed point of the
// round trip bit for bit, the fields pinned byte by byte, hostile PDUs
// refused with their message, and the tracker's heartbeat and dedupe
// between two gateways over a lossy link.
#include <gtest/gtest.h>

#include <algorithm>
#include <bit>
#include <cstdio>
#include <cmath>
#include <map>
#include <random>
#include <tuple>

#include "sandtable/edits/profile.h"
#include "sandtable/sim_dis/object_tracker.h"
#include "sandtable/sim_dis/objects.h"
#include "sim_dis_support.h"

namespace sandtable::sim_dis {
namespace {

using test::testFrame;
using test::TwoSims;

edit::Edit crater(std::uint64_t id, double x, double z, double radius, double time = 10) {
  edit::Edit e;
  e.id = id;
  e.time = time;
  e.kind = edit::Kind::crater;
  e.points = {{x, z}};
  e.radius = radius;
  e.depth = radius / 2;
  e.munition = 3;
  return e;
}

edit::Edit line(edit::Kind kind, std::uint64_t id, std::vector<std::array<double, 2>> points, double time = 10) {
  edit::Edit e;
  e.id = id;
  e.time = time;
  e.kind = kind;
  e.points = std::move(points);
  e.width = 3.3;
  e.height = kind == edit::Kind::berm ? 1.7 : 2.2;
  e.sideSlope = 0.7;
  return e;
}

ObjectSender sender(std::uint16_t site = 1, std::uint16_t application = 2) {
  ObjectSender s;
  s.exercise = 3;
  s.site = site;
  s.application = application;
  s.ground = [](double x, double z) { return 100 + 0.01 * x - 0.02 * z; };
  return s;
}

bool sameBits(double a, double b) { return std::bit_cast<std::uint64_t>(a) == std::bit_cast<std::uint64_t>(b); }

/// Every field equal, doubles bit for bit (so 0 and -0 differ).
::testing::AssertionResult bitIdentical(const edit::Edit& a, const edit::Edit& b) {
  auto fail = [](const char* field) { return ::testing::AssertionFailure() << field << " differs"; };
  if (a.id != b.id) return fail("id");
  if (!sameBits(a.time, b.time)) return fail("time");
  if (a.origin != b.origin) return fail("origin");
  if (a.kind != b.kind) return fail("kind");
  if (a.points.size() != b.points.size()) return fail("points.size");
  for (std::size_t k = 0; k < a.points.size(); ++k) {
    if (!sameBits(a.points[k][0], b.points[k][0]) || !sameBits(a.points[k][1], b.points[k][1])) return fail("points");
  }
  for (auto [x, y, name] : {std::tuple{a.radius, b.radius, "radius"}, {a.depth, b.depth, "depth"},
                            {a.width, b.width, "width"}, {a.height, b.height, "height"},
                            {a.sideSlope, b.sideSlope, "sideSlope"}, {a.heading, b.heading, "heading"},
                            {a.scale, b.scale, "scale"}}) {
    if (!sameBits(x, y)) return fail(name);
  }
  if (a.icon != b.icon || a.moduleX != b.moduleX || a.moduleZ != b.moduleZ || a.object != b.object ||
      a.munition != b.munition) {
    return fail("object fields");
  }
  return ::testing::AssertionSuccess();
}

/// What a receiver with clock `nowS` makes of the bytes.
edit::Edit received(const std::vector<std::byte>& bytes, const DisFrame& frame, double nowS) {
  auto pdu = dis::decode(bytes, "test");
  EXPECT_TRUE(pdu.ok()) << pdu.error();
  auto got = fromPdu(pdu.value(), frame, nowS);
  EXPECT_TRUE(got.ok()) << got.error();
  EXPECT_TRUE(got.value().has_value());
  return got.value().value_or(edit::Edit{});
}

std::vector<std::byte> hexBytes(const char* text) {
  std::vector<std::byte> out;
  for (const char* p = text; *p;) {
    if (*p == ' ' || *p == '\n') {
      ++p;
      continue;
    }
    out.push_back(std::byte(std::stoi(std::string(p, 2), nullptr, 16)));
    p += 2;
  }
  return out;
}

void expectBytes(const std::vector<std::byte>& got, std::size_t at, const char* hex, const char* what) {
  const std::vector<std::byte> want = hexBytes(hex);
  ASSERT_LE(at + want.size(), got.size()) << what;
  EXPECT_TRUE(std::equal(want.begin(), want.end(), got.begin() + std::ptrdiff_t(at))) << what;
}

// ------------------------------------------------------------ conversions

TEST(SimDisObjects, everyKindRoundTripsThroughItsBytesToTheSendersEdit) {
  const DisFrame frame = testFrame();
  const ObjectSender s = sender();
  const std::vector<edit::Edit> edits = {
      crater(1, 1000.3, 2000.7, 0.8),
      crater(2, 12345.678, 54321.001, 3.4, 7300.123456),
      crater(3, 90000.5, 90000.25, 9.0, 0.0),
      line(edit::Kind::berm, 4, {{100.1, 200.2}, {160.7, 230.9}, {161.0, 330.0}, {2161.0, 330.0}}),
      line(edit::Kind::ditch, 70000, {{5000, 5000}, {5003.3, 4990.1}}, 3599.9999999),
      line(edit::Kind::berm, 6, {{50000.004, 2.0}, {49000.0, 1500.0}}),
  };
  for (const edit::Edit& e : edits) {
    SCOPED_TRACE(std::string(edit::kindName(e.kind)) + " " + std::to_string(e.id));
    auto encoded = encodeEdit(e, frame, s);
    ASSERT_TRUE(encoded.ok()) << encoded.error();
    const edit::Edit sent = encoded->edit;
    // A receiver on the same clock makes exactly the sender's edit.
    EXPECT_TRUE(bitIdentical(received(encoded->bytes, frame, e.time), sent));
    auto again = asReceived(sent, frame, s);
    ASSERT_TRUE(again.ok()) << again.error();
    EXPECT_TRUE(bitIdentical(again.value(), sent)) << "asReceived is not idempotent";
    auto direct = asReceived(e, frame, s);
    ASSERT_TRUE(direct.ok());
    EXPECT_TRUE(bitIdentical(direct.value(), sent));
    // What it kept: the id, the sender, the time to the timestamp's unit, the places to the grid.
    EXPECT_EQ(sent.id, e.id);
    EXPECT_EQ(sent.origin, edit::Origin(1 << 16 | 2));
    EXPECT_EQ(sent.kind, e.kind);
    EXPECT_NEAR(sent.time, e.time, 3600.0 / 2147483648.0);
    ASSERT_EQ(sent.points.size(), e.points.size());
    for (std::size_t k = 0; k < e.points.size(); ++k) {
      EXPECT_NEAR(sent.points[k][0], e.points[k][0], kObjectGridM / 2 + 1e-6) << k;
      EXPECT_NEAR(sent.points[k][1], e.points[k][1], kObjectGridM / 2 + 1e-6) << k;
      EXPECT_EQ(std::fmod(sent.points[k][0], kObjectGridM), 0.0) << k;
    }
    EXPECT_EQ(sent.munition, 0);  // informative; it does not travel
    if (e.kind == edit::Kind::crater) {
      edit::Edit snapped = e;
      snapCrater(snapped);
      EXPECT_EQ(sent.radius, snapped.radius);
      EXPECT_EQ(sent.depth, snapped.depth);
    } else {
      EXPECT_EQ(sent.width, double(float(e.width)));
      EXPECT_EQ(sent.height, double(float(e.height)));
      EXPECT_EQ(sent.sideSlope, std::round(e.sideSlope * 128) / 128);
    }
    EXPECT_EQ(edit::checkEdit(sent), "");
  }
}

TEST(SimDisObjects, asReceivedIsAFixedPointForRandomEditsOverAHundredKilometres) {
  // Segments from 5 cm to 10 km, anywhere on a 100 km UTM database: the
  // round trip lands every point within half the grid (plus what the float
  // angles lose) and a second round trip changes no bit.
  const DisFrame frame = testFrame();
  const ObjectSender s = sender();
  std::mt19937_64 rng(43);
  std::uniform_real_distribution<double> place(0, 100000), unit(0, 1);
  double worst = 0;
  for (int k = 0; k < 1000; ++k) {
    edit::Edit e;
    if (k % 4 == 0) {
      e = crater(std::uint64_t(k + 1), place(rng), place(rng), 0.2 + 10 * unit(rng), 3600 * 5 * unit(rng));
    } else {
      std::vector<std::array<double, 2>> points = {{place(rng), place(rng)}};
      const int segments = 1 + int(rng() % 20);
      for (int j = 0; j < segments; ++j) {
        const double length = 0.05 * std::pow(200000.0, unit(rng));  // 5 cm .. 10 km, log-uniform
        const double heading = 2 * 3.141592653589793 * unit(rng);
        points.push_back({points.back()[0] + length * std::sin(heading), points.back()[1] - length * std::cos(heading)});
      }
      e = line(k % 2 ? edit::Kind::berm : edit::Kind::ditch, std::uint64_t(k + 1), points, 100 * unit(rng));
    }
    auto once = asReceived(e, frame, s);
    ASSERT_TRUE(once.ok()) << once.error();
    auto twice = asReceived(once.value(), frame, s);
    ASSERT_TRUE(twice.ok()) << twice.error();
    ASSERT_TRUE(bitIdentical(twice.value(), once.value())) << k;
    ASSERT_EQ(once->points.size(), e.points.size()) << k;
    for (std::size_t j = 0; j < e.points.size(); ++j) {
      for (int axis = 0; axis < 2; ++axis) {
        worst = std::max(worst, std::abs(once->points[j][std::size_t(axis)] - e.points[j][std::size_t(axis)]));
      }
    }
  }
  // The grid's rounding, plus what the float32 angles and length lose: about 1e-7 of a segment's length.
  EXPECT_LT(worst, kObjectGridM / 2 + 0.0015);
  std::printf("largest move of a point by the round trip: %.3f mm (half the grid is %.3f mm)\n", worst * 1000,
              kObjectGridM / 2 * 1000);
}

TEST(SimDisObjects, craterSizesSnapToTheNearestClass) {
  const std::vector<std::pair<double, edits::CraterSize>> cases = {
      {0.1, edits::kCraterSmall},  {1.0, edits::kCraterSmall},   {2.0, edits::kCraterSmall},
      {2.01, edits::kCraterMedium}, {5.25, edits::kCraterMedium}, {5.26, edits::kCraterLarge},
      {40, edits::kCraterLarge}};
  for (const auto& [radius, size] : cases) {
    edit::Edit e = crater(1, 0, 0, radius);
    snapCrater(e);
    EXPECT_EQ(e.radius, size.radius) << radius;
    EXPECT_EQ(e.depth, size.depth) << radius;
  }
  edit::Edit berm = line(edit::Kind::berm, 1, {{0, 0}, {1, 1}});
  const edit::Edit before = berm;
  snapCrater(berm);
  EXPECT_EQ(berm, before);
}

TEST(SimDisObjects, craterPduHasTheStandardsFieldsByteForByte) {
  const DisFrame frame = testFrame();
  const ObjectSender s = sender();
  // 3,723.5 s is 123.5 s past the hour: round(123.5 x 2^31 / 3600) = 73,670,620 units, shifted left.
  auto encoded = encodeEdit(crater(17, 1000.3, 2000.7, 3.4, 3723.5), frame, s);
  ASSERT_TRUE(encoded.ok()) << encoded.error();
  const std::vector<std::byte>& b = encoded->bytes;
  ASSERT_EQ(b.size(), 88u);
  expectBytes(b, 0, "07 03 2B 09 08 C8 3F B8 00 58 00 00", "header: v7, exercise 3, type 43, family 9, relative");
  expectBytes(b, 12, "00 01 00 02 00 11 00 00 00 00 00 00", "object 1:2:17, referenced none");
  expectBytes(b, 24, "00 00 00 00 01 01 03 02", "update 0, force 0, modifications 0, crater medium 1.1.3.2");
  expectBytes(b, 68, "00 00 00 00 00 00 00 00 00 01 00 02 FF FF FF FF 00 00 00 00",
              "appearance 0, requester 1:2, receiver all, padding");
  auto pdu = dis::decode(b, "test");
  ASSERT_TRUE(pdu.ok());
  // The location is the frame point on the sender's ground, through PROJ.
  auto ecef = frame.frame().toEcef({1000.3, s.ground(1000.3, 2000.7), 2000.7});
  ASSERT_TRUE(ecef.ok());
  EXPECT_EQ(pdu->pointObject->location, (dis::Vec3d{ecef->x, ecef->y, ecef->z}));
  EXPECT_EQ(objectTypeName(pdu->pointObject->type), "crater, medium");
}

TEST(SimDisObjects, ditchPduHasTheStandardsFieldsByteForByte) {
  const DisFrame frame = testFrame();
  const ObjectSender s = sender();
  edit::Edit ditch = line(edit::Kind::ditch, 70000, {{5000, 5000}, {5000, 4990}}, 3723.5);  // 10 m due north
  ditch.width = 3;
  ditch.height = 2;
  ditch.sideSlope = 0.5;
  auto encoded = encodeEdit(ditch, frame, s);
  ASSERT_TRUE(encoded.ok()) << encoded.error();
  const std::vector<std::byte>& b = encoded->bytes;
  ASSERT_EQ(b.size(), 104u);
  // Edit 70,000 = update 1, object 4,464 (0x1170).
  expectBytes(b, 0, "07 03 2C 09 08 C8 3F B8 00 68 00 00", "header: v7, exercise 3, type 44, family 9, 104 bytes");
  expectBytes(b, 12, "00 01 00 02 11 70 00 00 00 00 00 00 00 01 00 01", "object 1:2:4464, update 1, force 0, 1 segment");
  expectBytes(b, 28, "00 01 00 02 FF FF FF FF 01 01 01 00", "requester 1:2, receiver all, tank ditch 1.1.1.0");
  expectBytes(b, 40, "01 00 00 00 A0 40 00 00", "segment 1, modification 0, general 0, slope 64/128 marked 0xA");
  expectBytes(b, 84, "41 20 00 00 40 40 00 00 00 00 00 00 40 00 00 00 00 00 00 00",
              "length 10, width 3, height 0, depth 2, padding");
  auto pdu = dis::decode(b, "test");
  ASSERT_TRUE(pdu.ok());
  const dis::LinearSegment& g = pdu->linearObject->segments.at(0);
  auto anchor = frame.anchorAtFrame({5000, s.ground(5000, 4995), 4995});  // the midpoint
  ASSERT_TRUE(anchor.ok());
  EXPECT_EQ(g.location, anchor->ecef);
  EXPECT_NEAR(framePose(anchor.value(), g.location, g.orientation).headingDeg, 0, 1e-4);  // due grid north
  const edit::Edit got = encoded->edit;
  EXPECT_EQ(got.id, 70000u);
  EXPECT_EQ(got.points, (std::vector<std::array<double, 2>>{{5000, 5000}, {5000, 4990}}));
  EXPECT_EQ(got.height, 2);
  EXPECT_EQ(got.sideSlope, 0.5);
}

TEST(SimDisObjects, slopeTravelsInTheSpecificAppearanceOrDefaultsToOneInTwo) {
  EXPECT_EQ(slopeAppearance(0.5), 0xA0400000u);
  EXPECT_EQ(slopeOf(0xA0400000u), 0.5);
  EXPECT_EQ(slopeOf(slopeAppearance(0.3)), 38.0 / 128);
  EXPECT_EQ(slopeOf(slopeAppearance(100)), 4095.0 / 128);  // the most 12 bits hold
  EXPECT_EQ(slopeOf(slopeAppearance(0.001)), 1.0 / 128);    // never 0: a slope must be > 0
  EXPECT_EQ(slopeOf(0), kDefaultSideSlope);                 // a foreign sender: no marker
  EXPECT_EQ(slopeOf(0x00400000u), kDefaultSideSlope);
  EXPECT_EQ(slopeOf(0xA0000000u), kDefaultSideSlope);
}

TEST(SimDisObjects, timeIsUnwrappedIntoTheReceiversHour) {
  const double t = 7300.123456;  // 2 h and 100.123456 s
  const std::uint32_t stamp = editTimestamp(t);
  EXPECT_EQ(stamp & 1u, 0u);  // relative: simulation time
  const double back = unwrapTime(stamp, t);
  EXPECT_NEAR(back, t, 3600.0 / 2147483648.0);
  EXPECT_EQ(unwrapTime(editTimestamp(back), back), back);  // a fixed point
  EXPECT_EQ(unwrapTime(stamp, t + 1800), back);            // receiver half an hour ahead
  EXPECT_EQ(unwrapTime(stamp, t + 3539), back);
  EXPECT_EQ(unwrapTime(stamp, t - 59), back);              // receiver behind by less than the skew
  EXPECT_EQ(unwrapTime(stamp, t - 61), back - 3600);       // further behind: the hour before
  EXPECT_EQ(unwrapTime(stamp, t + 3541), back + 3600);     // 59 minutes and more ahead: the next hour
  // The last unit of an hour rounds to the next hour's start.
  EXPECT_EQ(editTimestamp(3600 - 1e-7), 0u);
  EXPECT_EQ(unwrapTime(editTimestamp(3600 - 1e-7), 3600 - 1e-7), 3600.0);
}

TEST(SimDisObjects, idsTravelAsObjectAndUpdateNumbers) {
  const DisFrame frame = testFrame();
  for (std::uint64_t id : {std::uint64_t(1), std::uint64_t(65535), std::uint64_t(65536), std::uint64_t(0xFFFFFFFF)}) {
    auto pdu = toPdu(crater(id, 10, 10, 1), frame, sender());
    ASSERT_TRUE(pdu.ok()) << pdu.error();
    EXPECT_EQ(pdu->pointObject->id.object, id & 0xFFFF);
    EXPECT_EQ(pdu->pointObject->updateNumber, id >> 16);
    auto got = asReceived(crater(id, 10, 10, 1), frame, sender());
    ASSERT_TRUE(got.ok());
    EXPECT_EQ(got->id, id);
  }
  auto tooBig = toPdu(crater(std::uint64_t(1) << 32, 10, 10, 1), frame, sender());
  ASSERT_FALSE(tooBig.ok());
  EXPECT_EQ(tooBig.message(), "toPdu: edit id 4294967296 is past 2^32 - 1, what an object number and an update number carry");
}

TEST(SimDisObjects, toPduRefusesWhatDoesNotTravel) {
  const DisFrame frame = testFrame();
  edit::Edit flatten;
  flatten.kind = edit::Kind::flatten;
  flatten.points = {{0, 0}, {10, 0}, {10, 10}};
  flatten.sideSlope = 1;
  edit::Edit bad = crater(1, 0, 0, -1);
  std::vector<std::array<double, 2>> many;
  for (int k = 0; k < 129; ++k) many.push_back({double(k), 0});
  const std::vector<std::pair<edit::Edit, std::string>> cases = {
      {flatten, "toPdu: flatten edits do not travel as DIS objects"},
      {bad, "toPdu: edit: crater: Edit::radius must be > 0 (got -1)"},
      {line(edit::Kind::berm, 1, many), "toPdu: berm: 128 segments; a Linear Object State PDU carries at most 127"},
      {line(edit::Kind::ditch, 1, {{0, 0}, {10, 0}, {10.001, 0.001}}),
       "toPdu: ditch: segment 2 is 0.001414 m long, under the 0.003906 m grid"},
  };
  for (const auto& [e, message] : cases) {
    auto pdu = toPdu(e, frame, sender());
    ASSERT_FALSE(pdu.ok()) << message;
    EXPECT_EQ(pdu.message(), message);
  }
  many.pop_back();
  EXPECT_TRUE(toPdu(line(edit::Kind::berm, 1, many), frame, sender()).ok());  // 127 segments
}

/// A linear object PDU as our sender makes it, for the hostile cases to spoil.
dis::Pdu ditchPdu() {
  auto pdu = toPdu(line(edit::Kind::ditch, 9, {{1000, 1000}, {1010, 1000}, {1010, 1020}}), testFrame(), sender());
  EXPECT_TRUE(pdu.ok()) << pdu.error();
  return pdu.value();
}

TEST(SimDisObjects, fromPduRefusesHostileObjectsNamingTheField) {
  const DisFrame frame = testFrame();
  const double nan = std::nan("");
  std::vector<std::pair<std::function<void(dis::Pdu&)>, std::string>> cases = {
      {[](dis::Pdu& p) { p.linearObject->segments.clear(); }, "fromPdu: tank ditch: no segments"},
      {[&](dis::Pdu& p) { p.linearObject->segments[1].location.x = nan; },
       "fromPdu: tank ditch: segment 2: its location, orientation or length is not finite"},
      {[&](dis::Pdu& p) { p.linearObject->segments[0].width = float(nan); },
       "fromPdu: tank ditch: segment 1: a size is not finite"},
      {[](dis::Pdu& p) { p.linearObject->segments[0].width = -1; },
       "fromPdu: tank ditch: segment 1: width -1.000000 is negative"},
      {[](dis::Pdu& p) { p.linearObject->segments[0].depth = 0; }, "fromPdu: tank ditch: segment 1 has no depth"},
      {[](dis::Pdu& p) { p.linearObject->segments[1].length = 0; }, "fromPdu: tank ditch: segment 2 has no length"},
      {[&](dis::Pdu& p) {
         auto a = frame.anchorAtEcef(p.linearObject->segments[1].location);
         ASSERT_TRUE(a.ok());
         p.linearObject->segments[1].orientation = disOrientation(a.value(), 30, 90, 0);
       },
       "fromPdu: tank ditch: segment 2 points up or down"},
      {[](dis::Pdu& p) { p.linearObject->segments[1].length += 1; },
       "fromPdu: tank ditch: segment 2 starts 0.5 m from where segment 1 ends"},
  };
  for (const auto& [spoil, message] : cases) {
    dis::Pdu pdu = ditchPdu();
    spoil(pdu);
    auto got = fromPdu(pdu, frame, 10);
    if (got.ok()) {
      ADD_FAILURE() << "taken: " << message;
      continue;
    }
    EXPECT_EQ(got.message().substr(0, message.size()), message);
  }
  auto point = toPdu(crater(1, 10, 10, 1), frame, sender());
  ASSERT_TRUE(point.ok());
  point->pointObject->location.z = std::numeric_limits<double>::infinity();
  auto got = fromPdu(point.value(), frame, 10);
  ASSERT_FALSE(got.ok());
  EXPECT_EQ(got.message(), "fromPdu: crater: the location is not finite");
  dis::Pdu entity;
  entity.header.type = 1;
  EXPECT_EQ(fromPdu(entity, frame, 10).message(), "fromPdu: PDU type 1 is not a Point or Linear Object State");
}

TEST(SimDisObjects, typesWithoutAnEditAreNamedAndMakeNone) {
  const DisFrame frame = testFrame();
  auto point = toPdu(crater(1, 10, 10, 1), frame, sender());
  ASSERT_TRUE(point.ok());
  for (const auto& [type, name] :
       std::vector<std::pair<dis::ObjectType, std::string>>{{kBuildingRubbleType, "building rubble"},
                                                            {{1, 2, 1, 4}, "vehicle defilade"},
                                                            {{1, 1, 3, 4}, "1.1.3.4"},
                                                            {{2, 1, 3, 1}, "2.1.3.1"}}) {
    dis::Pdu p = point.value();
    p.pointObject->type = type;
    auto got = fromPdu(p, frame, 10);
    ASSERT_TRUE(got.ok()) << got.error();
    EXPECT_FALSE(got.value().has_value()) << name;
    EXPECT_EQ(objectTypeName(type), name);
  }
  // An "other" linear obstacle that sinks is no berm; a berm needs height and no depth.
  dis::Pdu linear = ditchPdu();
  linear.linearObject->type = kOtherLinearType;
  auto got = fromPdu(linear, frame, 10);
  ASSERT_TRUE(got.ok());
  EXPECT_FALSE(got.value().has_value());
  for (auto& g : linear.linearObject->segments) std::swap(g.height, g.depth);
  got = fromPdu(linear, frame, 10);
  ASSERT_TRUE(got.ok());
  ASSERT_TRUE(got.value().has_value());
  EXPECT_EQ(got.value()->kind, edit::Kind::berm);
}

// ------------------------------------------------------------ the tracker

TEST(SimDisObjectTracker, tenThousandObjectsHeartbeatSpreadEvenlyOverTheInterval) {
  ObjectTracker tracker(testFrame(), sender());
  constexpr int kObjects = 10000;
  for (int k = 0; k < kObjects; ++k) {
    auto e = tracker.publish(crater(std::uint64_t(k + 1), 10.0 + (k % 100) * 20, 10.0 + (k / 100) * 20, 3), {});
    ASSERT_TRUE(e.ok()) << e.error();
  }
  std::vector<std::vector<double>> sentAt(kObjects);
  const double step = 1.0 / 60;
  std::size_t most = 0;
  int steps = 0;
  for (; steps <= 60 * 16; ++steps) {
    const double now = steps * step;
    const std::size_t n = tracker.heartbeat(now, [&](std::span<const std::byte> bytes) {
      // The object number in bytes 16-17 says which (ids 1..10,000).
      const int object = int(std::to_integer<unsigned>(bytes[16]) << 8 | std::to_integer<unsigned>(bytes[17]));
      sentAt[std::size_t(object - 1)].push_back(now);
    });
    most = std::max(most, n);
  }
  // 10,000 / 5 s at 60 Hz is 33.3 a step: 33 or 34, never a burst.
  EXPECT_LE(most, 34u);
  // 16 s is 3.2 rounds: 32,000, less one when the owed fraction ends a hair under 1.
  EXPECT_GE(tracker.counters().heartbeats, 31999u);
  EXPECT_LE(tracker.counters().heartbeats, 32000u);
  for (int k = 0; k < kObjects; ++k) {
    ASSERT_GE(sentAt[std::size_t(k)].size(), 3u) << k;
    EXPECT_LE(sentAt[std::size_t(k)].front(), 5.0 + step) << k;
    for (std::size_t j = 1; j < sentAt[std::size_t(k)].size(); ++j) {
      EXPECT_NEAR(sentAt[std::size_t(k)][j] - sentAt[std::size_t(k)][j - 1], 5.0, step + 1e-9) << k;
    }
  }
}

TEST(SimDisObjectTracker, heartbeatsAndCopiesAreDuplicatesAndANewUpdateIsANewEdit) {
  const DisFrame frame = testFrame();
  ObjectTracker a(frame, sender(1, 1)), b(frame, sender(2, 1));
  std::vector<std::vector<std::byte>> wire;
  auto send = [&](std::span<const std::byte> bytes) { wire.emplace_back(bytes.begin(), bytes.end()); };
  auto published = a.publish(crater(5, 100, 100, 1), send);
  ASSERT_TRUE(published.ok());
  EXPECT_EQ(a.publish(crater(5, 200, 200, 1), send).message(),
            "ObjectTracker::publish: edit id 5 does not follow 5 by 1 to 65,535");
  EXPECT_EQ(a.publish(crater(65541, 200, 200, 1), send).message(),
            "ObjectTracker::publish: edit id 65541 does not follow 5 by 1 to 65,535");
  auto between = a.publish(crater(60000, 200, 200, 3), send);
  ASSERT_TRUE(between.ok());
  // 5 + 65,536: object number 5 again, update 1; it follows object 60,000.
  auto wrapped = a.publish(crater(5 + 65536, 300, 300, 7), send);
  ASSERT_TRUE(wrapped.ok());
  ASSERT_EQ(wire.size(), 3u);
  auto take = [&](const std::vector<std::byte>& bytes) {
    auto pdu = dis::decode(bytes, "test");
    EXPECT_TRUE(pdu.ok());
    return b.receive(pdu.value(), 10);
  };
  // The update arrives first: it waits for the edit it follows, and comes with it.
  EXPECT_TRUE(take(wire[2]).empty());
  EXPECT_EQ(b.counters().held, 1u);
  const std::vector<edit::Edit> first = take(wire[0]);
  ASSERT_EQ(first.size(), 1u);
  EXPECT_TRUE(bitIdentical(first[0], published.value()));
  const std::vector<edit::Edit> both = take(wire[1]);
  ASSERT_EQ(both.size(), 2u);
  EXPECT_TRUE(bitIdentical(both[0], between.value()));
  EXPECT_TRUE(bitIdentical(both[1], wrapped.value()));
  EXPECT_EQ(both[1].id, 65541u);
  EXPECT_TRUE(take(wire[0]).empty());  // heartbeats
  EXPECT_TRUE(take(wire[2]).empty());
  const TrackerCounters& c = b.counters();
  EXPECT_EQ(c.received, 5u);
  EXPECT_EQ(c.edits, 3u);
  EXPECT_EQ(c.updates, 1u);
  EXPECT_EQ(c.duplicates, 2u);
  EXPECT_EQ(c.waited, 1u);
  EXPECT_EQ(c.held, 0u);
  EXPECT_EQ(b.received().size(), 3u);
  // A type without edit: counted by type once per object and update; a malformed PDU every time.
  auto rubble = dis::decode(wire[0], "test");
  rubble->pointObject->type = kBuildingRubbleType;
  rubble->pointObject->id.object = 77;
  EXPECT_TRUE(b.receive(rubble.value(), 10).empty());
  EXPECT_TRUE(b.receive(rubble.value(), 10).empty());
  EXPECT_EQ(c.withoutEdit, 1u);
  EXPECT_EQ(c.byType.at(objectTypeKey(kBuildingRubbleType)), 1u);
  EXPECT_EQ(c.duplicates, 3u);
  auto bad = dis::decode(wire[0], "test");
  bad->pointObject->id.object = 78;
  bad->pointObject->location.x = std::nan("");
  EXPECT_TRUE(b.receive(bad.value(), 10).empty());
  EXPECT_TRUE(b.receive(bad.value(), 10).empty());
  EXPECT_EQ(c.malformed, 2u);
  EXPECT_EQ(c.lastMalformed, "fromPdu: crater: the location is not finite");
  EXPECT_EQ(c.received, c.edits + c.duplicates + c.malformed + c.withoutEdit);
}

TEST(SimDisObjectTracker, oneSendersEditsAreHandedOnInItsOrderWhateverOrderTheyArrive) {
  const DisFrame frame = testFrame();
  ObjectTracker a(frame, sender(1, 1)), b(frame, sender(2, 1));
  std::vector<dis::Pdu> wire;
  auto send = [&](std::span<const std::byte> bytes) {
    auto pdu = dis::decode(bytes, "test");
    ASSERT_TRUE(pdu.ok());
    wire.push_back(pdu.value());
  };
  std::vector<edit::Edit> order;
  for (std::uint64_t id : {3, 4, 9, 65540}) {  // ids with gaps; the last is object 4 again, update 1
    auto e = a.publish(id == 9 ? line(edit::Kind::berm, id, {{0, 0}, {50, 0}}) : crater(id, 10.0 * double(id % 100), 5, 1), send);
    ASSERT_TRUE(e.ok()) << e.error();
    order.push_back(e.value());
  }
  ASSERT_EQ(wire.size(), 4u);
  EXPECT_EQ(wire[0].pointObject->referenced, (dis::ObjectId{0, 0, 0}));
  EXPECT_EQ(wire[1].pointObject->referenced, (dis::ObjectId{1, 1, 3}));
  EXPECT_EQ(wire[2].linearObject->referenced, (dis::ObjectId{1, 1, 4}));
  EXPECT_EQ(wire[3].pointObject->referenced, (dis::ObjectId{1, 1, 9}));
  EXPECT_EQ(wire[3].pointObject->id, (dis::ObjectId{1, 1, 4}));
  EXPECT_EQ(wire[3].pointObject->updateNumber, 1);
  // A foreign object (no reference) in between is handed on at once.
  dis::Pdu foreign = wire[0];
  foreign.pointObject->id = {7, 7, 1};
  EXPECT_TRUE(b.receive(wire[3], 10).empty());
  EXPECT_TRUE(b.receive(wire[1], 10).empty());
  EXPECT_EQ(b.receive(foreign, 10).size(), 1u);
  EXPECT_TRUE(b.receive(wire[2], 10).empty());
  EXPECT_EQ(b.counters().held, 3u);
  const std::vector<edit::Edit> all = b.receive(wire[0], 10);
  ASSERT_EQ(all.size(), 4u);
  for (std::size_t k = 0; k < 4; ++k) EXPECT_TRUE(bitIdentical(all[k], order[k])) << k;
  EXPECT_EQ(b.counters().waited, 3u);
  EXPECT_EQ(b.counters().held, 0u);
}

// ------------------------------------------------------------ two gateways

/// Both sides' ground as edits: published and received, by origin and id.
std::vector<edit::Edit> groundOf(const Gateway& g) {
  std::vector<edit::Edit> all = g.objects().published();
  all.insert(all.end(), g.objects().received().begin(), g.objects().received().end());
  std::sort(all.begin(), all.end(), [](const edit::Edit& x, const edit::Edit& y) {
    return std::tie(x.origin, x.id) < std::tie(y.origin, y.id);
  });
  return all;
}

/// Publishes a random edit of `kind` from gateway `g`; returns what to apply.
edit::Edit publishRandom(Gateway& g, std::mt19937_64& rng, std::uint64_t id, double now) {
  std::uniform_real_distribution<double> at(50, 1950), size(0.5, 9);
  const int kind = int(rng() % 10);
  edit::Edit e;
  if (kind < 8) {
    e = crater(id, at(rng), at(rng), size(rng), now);
  } else {
    const double x = at(rng), z = at(rng);
    std::vector<std::array<double, 2>> points = {{x, z}};
    for (int k = 0; k < 3; ++k) points.push_back({std::clamp(points.back()[0] + at(rng) / 20 - 50, 0.0, 2000.0),
                                                  std::clamp(points.back()[1] + at(rng) / 20 - 50, 0.0, 2000.0)});
    e = line(kind == 8 ? edit::Kind::berm : edit::Kind::ditch, id, points, now);
  }
  auto applied = g.publishEdit(e);
  EXPECT_TRUE(applied.ok()) << applied.error();
  return applied.ok() ? applied.value() : edit::Edit{};
}

TEST(SimDisObjectTracker, twoGatewaysWithTenPercentLossEndWithTheSameEdits) {
  TwoSims t;
  std::mt19937_64 drops(37), edits(1278);
  std::uint64_t dropped = 0, passed = 0;
  auto lossy = [&](std::vector<dis::Datagram>& batch) {
    std::vector<dis::Datagram> kept;
    for (dis::Datagram& d : batch) {
      if (std::uniform_real_distribution<double>(0, 1)(drops) < 0.1) {
        ++dropped;
      } else {
        ++passed;
        kept.push_back(std::move(d));
      }
    }
    batch = std::move(kept);
  };
  t.intoA = lossy;
  t.intoB = lossy;
  // Each side's editor in order: its own edits as published, then the remote ones as drained.
  std::vector<edit::Edit> appliedA, appliedB;
  std::uint64_t nextA = 1, nextB = 1;
  int completeA = -1, completeB = -1;  // the step from which each side held all 280
  for (int step = 0; step < 60 * 50; ++step) {
    const double now = t.a.timeS();
    // 20 s of battle: A makes an edit every 0.1 s, B every 0.25 s; then 30 s of heartbeats only.
    if (step < 60 * 20 && step % 6 == 0) appliedA.push_back(publishRandom(*t.ga, edits, nextA++, now));
    if (step < 60 * 20 && step % 15 == 0) appliedB.push_back(publishRandom(*t.gb, edits, nextB++, now));
    t.step();
    for (edit::Edit& e : t.ga->takeReceivedEdits()) appliedA.push_back(std::move(e));
    for (edit::Edit& e : t.gb->takeReceivedEdits()) appliedB.push_back(std::move(e));
    if (completeA < 0 && appliedA.size() == 280) completeA = step;
    if (completeB < 0 && appliedB.size() == 280) completeB = step;
  }
  const TrackerCounters &ca = t.ga->objects().counters(), &cb = t.gb->objects().counters();
  std::printf("datagrams passed %llu, dropped %llu; A: heartbeats %llu, edits %llu, duplicates %llu, all held at "
              "%.2f s, waited %llu; B: heartbeats %llu, edits %llu, duplicates %llu, all held at %.2f s, waited %llu\n",
              (unsigned long long)passed, (unsigned long long)dropped, (unsigned long long)ca.heartbeats,
              (unsigned long long)ca.edits, (unsigned long long)ca.duplicates, completeA / 60.0,
              (unsigned long long)ca.waited, (unsigned long long)cb.heartbeats, (unsigned long long)cb.edits,
              (unsigned long long)cb.duplicates, completeB / 60.0, (unsigned long long)cb.waited);
  EXPECT_GT(dropped, passed / 20);  // about a tenth was lost
  const std::vector<edit::Edit> a = groundOf(*t.ga), b = groundOf(*t.gb);
  ASSERT_EQ(a.size(), 200u + 80u);
  ASSERT_EQ(b.size(), a.size());
  for (std::size_t k = 0; k < a.size(); ++k) EXPECT_TRUE(bitIdentical(a[k], b[k])) << k;
  // What each editor was handed is that set, each edit once, and each sender's in the order it applied them.
  EXPECT_EQ(appliedA.size(), a.size());
  EXPECT_EQ(appliedB.size(), b.size());
  auto of = [](const std::vector<edit::Edit>& applied, edit::Origin origin) {
    std::vector<edit::Edit> out;
    for (const edit::Edit& e : applied) {
      if (e.origin == origin) out.push_back(e);
    }
    return out;
  };
  const edit::Origin siteA = 1 << 16 | 1, siteB = 2 << 16 | 1;
  EXPECT_EQ(of(appliedB, siteA), of(appliedA, siteA));
  EXPECT_EQ(of(appliedA, siteB), of(appliedB, siteB));
  EXPECT_EQ(of(appliedA, siteA).size(), 200u);
  for (const Gateway* g : {t.ga.get(), t.gb.get()}) {
    const TrackerCounters& c = g->objects().counters();
    EXPECT_EQ(c.malformed, 0u);
    EXPECT_GT(c.duplicates, 0u);
    EXPECT_EQ(c.received, c.edits + c.duplicates);
    EXPECT_EQ(c.held, 0u);
    EXPECT_EQ(g->counters().objects, c.received);
  }
  // Heartbeats made up for the losses: more edits arrived than first sends got through.
  EXPECT_GT(t.gb->objects().counters().heartbeats + t.ga->objects().counters().heartbeats, 0u);
}

TEST(SimDisObjectTracker, aWatcherThatJoinsLateConvergesAtTheNextHeartbeat) {
  TwoSims t;
  bool listening = false;
  t.intoB = [&](std::vector<dis::Datagram>& batch) {
    if (!listening) batch.clear();
  };
  std::mt19937_64 rng(5);
  for (std::uint64_t id = 1; id <= 50; ++id) publishRandom(*t.ga, rng, id, t.a.timeS());
  for (int step = 0; step < 60 * 20; ++step) t.step();
  EXPECT_TRUE(t.gb->objects().received().empty());
  listening = true;
  for (int step = 0; step < 60 * 5 + 2; ++step) t.step();
  EXPECT_EQ(t.gb->objects().received().size(), 50u);
  EXPECT_EQ(t.gb->objects().received(), t.ga->objects().published());  // in the publisher's order
  const std::vector<edit::Edit> a = groundOf(*t.ga), b = groundOf(*t.gb);
  ASSERT_EQ(a.size(), b.size());
  for (std::size_t k = 0; k < a.size(); ++k) EXPECT_TRUE(bitIdentical(a[k], b[k])) << k;
}

TEST(SimDisObjectTracker, aWatcherPublishesNoEdit) {
  sim::Simulation s(sim::test::makeWorld([](double, double) { return 0.0; }, 11, 10), {});
  GatewayOptions o;
  o.publish = false;
  std::size_t sent = 0;
  Gateway g(s, testFrame(), o, {}, [&](std::span<const std::byte>) { ++sent; });
  auto r = g.publishEdit(crater(1, 10, 10, 1));
  ASSERT_FALSE(r.ok());
  EXPECT_EQ(r.message(), "Gateway::publishEdit: publish is off (a watcher sends nothing)");
  g.afterStep();
  EXPECT_EQ(sent, 0u);
}

}  // namespace
}  // namespace sandtable::sim_dis
