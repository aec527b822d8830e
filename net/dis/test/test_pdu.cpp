// DIS PDUs (pdu.h, docs/DIS.md): golden bytes worked out by hand from the
// standard's field tables, every truncated prefix, hostile lengths and
// counts, version 6 on receive, and the timestamp.
#include <gtest/gtest.h>

#include <cstdint>
#include <string>
#include <vector>

#include "dis_example.h"
#include "sandtable/dis/pdu.h"

namespace sandtable::dis {
namespace {

using testexample::example;
using testexample::exampleHeader;

std::vector<std::byte> bytesOf(std::initializer_list<int> v) {
  std::vector<std::byte> out;
  for (int b : v) out.push_back(std::byte(b));
  return out;
}

const std::vector<std::byte> kGolden = bytesOf({
    // header: version 7, exercise 3, type 1, family 1, timestamp (half an hour: 2^30 units,
    // shifted left, absolute bit), length 176 = 144 + 2 x 16, status 0, padding
    0x07, 0x03, 0x01, 0x01, 0x80, 0x00, 0x00, 0x01, 0x00, 0xB0, 0x00, 0x00,
    // entity id 1:2:772, force 2, two records
    0x00, 0x01, 0x00, 0x02, 0x03, 0x04, 0x02, 0x02,
    // entity type 1.1.225.1.1.3.0, alternative type 0
    0x01, 0x01, 0x00, 0xE1, 0x01, 0x01, 0x03, 0x00, 0, 0, 0, 0, 0, 0, 0, 0,
    // velocity 1.0f, -0.5f, 2.5f
    0x3F, 0x80, 0x00, 0x00, 0xBF, 0x00, 0x00, 0x00, 0x40, 0x20, 0x00, 0x00,
    // location 1024.0, -2.0, 3.0
    0x40, 0x90, 0, 0, 0, 0, 0, 0, 0xC0, 0x00, 0, 0, 0, 0, 0, 0, 0x40, 0x08, 0, 0, 0, 0, 0, 0,
    // orientation psi 0.5f, theta -1.0f, phi 0.25f
    0x3F, 0x00, 0x00, 0x00, 0xBF, 0x80, 0x00, 0x00, 0x3E, 0x80, 0x00, 0x00,
    // appearance 0x18
    0x00, 0x00, 0x00, 0x18,
    // dead reckoning: algorithm 4, 15 bytes of other parameters, acceleration (0, 0, -2.0f),
    // angular velocity (0, 0.125f, 0)
    0x04, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0,
    0, 0, 0, 0, 0, 0, 0, 0, 0xC0, 0x00, 0x00, 0x00,
    0, 0, 0, 0, 0x3E, 0x00, 0x00, 0x00, 0, 0, 0, 0,
    // marking: ASCII, "T72 A" and six zeros
    0x01, 0x54, 0x37, 0x32, 0x20, 0x41, 0, 0, 0, 0, 0, 0,
    // capabilities
    0, 0, 0, 0,
    // articulated part: type 0, change 1, on the entity, 4096 + 11 (primary turret azimuth), 1.5f, padding
    0x00, 0x01, 0x00, 0x00, 0x00, 0x00, 0x10, 0x0B, 0x3F, 0xC0, 0x00, 0x00, 0, 0, 0, 0,
    // attached part: type 1, attached, on the entity, station 1, munition 2.9.225.2.1.0.0
    0x01, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0x01, 0x02, 0x09, 0x00, 0xE1, 0x02, 0x01, 0x00, 0x00,
});

TEST(DisEntityState, encodesTheGoldenBytes) {
  ASSERT_EQ(kGolden.size(), 176u);
  EXPECT_EQ(encode(exampleHeader(), example()), kGolden);
}

TEST(DisEntityState, decodesTheGoldenBytes) {
  auto pdu = decode(kGolden, "10.0.0.7:3000");
  ASSERT_TRUE(pdu.ok()) << pdu.error();
  EXPECT_EQ(pdu->header.version, 7);
  EXPECT_EQ(pdu->header.exercise, 3);
  EXPECT_EQ(pdu->header.type, 1);
  EXPECT_EQ(pdu->header.family, 1);
  EXPECT_EQ(pdu->header.length, 176);
  ASSERT_TRUE(pdu->entityState.has_value());
  EXPECT_EQ(*pdu->entityState, example());
  EXPECT_EQ(pdu->entityState->marking.text(), "T72 A");
  const auto turret = articulatedPart(pdu->entityState->parameters[0]);
  ASSERT_TRUE(turret.has_value());
  EXPECT_EQ(turret->parameterType, 4107u);
  EXPECT_EQ(turret->value, 1.5f);
  EXPECT_EQ(turret->change, 1);
  EXPECT_FALSE(attachedPart(pdu->entityState->parameters[0]).has_value());
  const auto store = attachedPart(pdu->entityState->parameters[1]);
  ASSERT_TRUE(store.has_value());
  EXPECT_EQ(store->station, 1u);
  EXPECT_EQ(store->type, (EntityType{2, 9, 225, 2, 1, 0, 0}));
}

TEST(DisEntityState, everyTruncatedPrefixIsRefusedNamingTheSenderAndTheOffset) {
  for (std::size_t n = 0; n < kGolden.size(); ++n) {
    const std::vector<std::byte> prefix(kGolden.begin(), kGolden.begin() + std::ptrdiff_t(n));
    auto pdu = decode(prefix, "10.0.0.7:3000");
    ASSERT_FALSE(pdu.ok()) << n;
    const Problem& p = pdu.problems().front();
    EXPECT_EQ(p.file, "10.0.0.7:3000");
    EXPECT_EQ(p.offset, n) << p.message;
    EXPECT_NE(p.message.find("truncated"), std::string::npos) << p.message;
  }
}

TEST(DisEntityState, version6IsTakenAndItsPaddingIgnored) {
  std::vector<std::byte> v6 = kGolden;
  v6[0] = std::byte{6};
  v6[10] = std::byte{0x5A};  // padding in version 6, not a status
  auto pdu = decode(v6, "vbs");
  ASSERT_TRUE(pdu.ok()) << pdu.error();
  EXPECT_EQ(pdu->header.version, 6);
  EXPECT_EQ(pdu->header.status, 0);
  EXPECT_EQ(*pdu->entityState, example());
  Header h = exampleHeader();
  h.version = 6;
  h.status = 0x5A;  // not written in version 6
  std::vector<std::byte> want = kGolden;
  want[0] = std::byte{6};
  EXPECT_EQ(encode(h, example()), want);
}

TEST(DisEntityState, hostileHeadersAndCountsAreRefusedWithTheirOffset) {
  const auto refusal = [](std::vector<std::byte> b) {
    auto pdu = decode(b, "s");
    EXPECT_FALSE(pdu.ok());
    return pdu.ok() ? Problem{} : pdu.problems().front();
  };
  std::vector<std::byte> b = kGolden;
  b[0] = std::byte{5};
  EXPECT_EQ(refusal(b).offset, 0u);
  b = kGolden;
  b[8] = std::byte{0xFF};  // length 65,456
  EXPECT_EQ(refusal(b).offset, 8u);
  b = kGolden;
  b[8] = std::byte{0};
  b[9] = std::byte{11};  // shorter than a header
  EXPECT_EQ(refusal(b).offset, 8u);
  b = kGolden;
  b[19] = std::byte{255};  // 255 records claimed in 176 bytes
  const Problem p = refusal(b);
  EXPECT_EQ(p.offset, 19u);
  EXPECT_NE(p.message.find("4224"), std::string::npos) << p.message;
  b = kGolden;
  b[19] = std::byte{1};  // one record, 32 bytes of them
  EXPECT_EQ(refusal(b).offset, 19u);
  b = std::vector<std::byte>(kGolden.begin(), kGolden.begin() + 140);
  b[8] = std::byte{0};
  b[9] = std::byte{140};  // a whole PDU by its length, too short for an Entity State PDU
  EXPECT_EQ(refusal(b).offset, 8u);
}

TEST(DisPdu, otherTypesDecodeTheirHeaderOnly) {
  std::vector<std::byte> data = kGolden;
  data[2] = std::byte{20};  // a Data PDU: not decoded, counted by the receiver
  data[3] = std::byte{5};
  auto pdu = decode(data, "s");
  ASSERT_TRUE(pdu.ok()) << pdu.error();
  EXPECT_EQ(pdu->header.type, 20);
  EXPECT_FALSE(pdu->entityState.has_value());
  EXPECT_FALSE(pdu->fire.has_value());
  EXPECT_FALSE(pdu->detonation.has_value());
}

// docs/DIS.md §3.1: a round 1:2:9 fired by 1:2:3 at 1:2:4, and its detonation on the target.
MunitionDescriptor exampleDescriptor() { return {{2, 9, 225, 2, 1, 0, 0}, 1000, 1000, 1, 0}; }

Fire exampleFire() {
  Fire f;
  f.firing = {1, 2, 3};
  f.target = {1, 2, 4};
  f.event = {1, 2, 9};
  f.location = {1024.0, -2.0, 3.0};
  f.descriptor = exampleDescriptor();
  f.velocity = {1.0f, -0.5f, 2.5f};
  f.range = 2.0f;
  return f;
}

Detonation exampleDetonation() {
  Detonation d;
  d.firing = {1, 2, 3};
  d.target = {1, 2, 4};
  d.event = {1, 2, 9};
  d.velocity = {1.0f, -0.5f, 2.5f};
  d.location = {1024.0, -2.0, 3.0};
  d.descriptor = exampleDescriptor();
  d.entityLocation = {0.5f, -1.0f, 0.25f};
  d.result = 1;  // entity impact
  d.parameters.push_back(toParameter(ArticulatedPart{0, 0, 4096 + 11, 1.5f}));
  return d;
}

const std::vector<std::byte> kFireGolden = bytesOf({
    // header: version 7, exercise 3, type 2 (Fire), family 2 (warfare), 30:00 absolute, 96 bytes
    0x07, 0x03, 0x02, 0x02, 0x80, 0x00, 0x00, 0x01, 0x00, 0x60, 0x00, 0x00,
    // firing 1:2:3, target 1:2:4, munition 0:0:0 (none tracked), event 1:2:9
    0x00, 0x01, 0x00, 0x02, 0x00, 0x03, 0x00, 0x01, 0x00, 0x02, 0x00, 0x04, 0, 0, 0, 0, 0, 0,
    0x00, 0x01, 0x00, 0x02, 0x00, 0x09,
    // fire mission index 0
    0, 0, 0, 0,
    // location 1024.0, -2.0, 3.0
    0x40, 0x90, 0, 0, 0, 0, 0, 0, 0xC0, 0x00, 0, 0, 0, 0, 0, 0, 0x40, 0x08, 0, 0, 0, 0, 0, 0,
    // descriptor: munition 2.9.225.2.1.0.0, warhead 1000, fuse 1000, quantity 1, rate 0
    0x02, 0x09, 0x00, 0xE1, 0x02, 0x01, 0x00, 0x00, 0x03, 0xE8, 0x03, 0xE8, 0x00, 0x01, 0x00, 0x00,
    // velocity 1.0f, -0.5f, 2.5f; range 2.0f
    0x3F, 0x80, 0x00, 0x00, 0xBF, 0x00, 0x00, 0x00, 0x40, 0x20, 0x00, 0x00, 0x40, 0x00, 0x00, 0x00,
});

const std::vector<std::byte> kDetonationGolden = bytesOf({
    // header: version 7, exercise 3, type 3 (Detonation), family 2, 30:00 absolute, 120 = 104 + 16 bytes
    0x07, 0x03, 0x03, 0x02, 0x80, 0x00, 0x00, 0x01, 0x00, 0x78, 0x00, 0x00,
    // firing 1:2:3, target 1:2:4, munition 0:0:0, event 1:2:9
    0x00, 0x01, 0x00, 0x02, 0x00, 0x03, 0x00, 0x01, 0x00, 0x02, 0x00, 0x04, 0, 0, 0, 0, 0, 0,
    0x00, 0x01, 0x00, 0x02, 0x00, 0x09,
    // velocity 1.0f, -0.5f, 2.5f
    0x3F, 0x80, 0x00, 0x00, 0xBF, 0x00, 0x00, 0x00, 0x40, 0x20, 0x00, 0x00,
    // location 1024.0, -2.0, 3.0
    0x40, 0x90, 0, 0, 0, 0, 0, 0, 0xC0, 0x00, 0, 0, 0, 0, 0, 0, 0x40, 0x08, 0, 0, 0, 0, 0, 0,
    // descriptor as in the Fire PDU
    0x02, 0x09, 0x00, 0xE1, 0x02, 0x01, 0x00, 0x00, 0x03, 0xE8, 0x03, 0xE8, 0x00, 0x01, 0x00, 0x00,
    // location in the target's axes 0.5f, -1.0f, 0.25f
    0x3F, 0x00, 0x00, 0x00, 0xBF, 0x80, 0x00, 0x00, 0x3E, 0x80, 0x00, 0x00,
    // result 1 (entity impact), one record, padding
    0x01, 0x01, 0x00, 0x00,
    // articulated part: change 0, on the entity, 4107, 1.5f
    0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0x10, 0x0B, 0x3F, 0xC0, 0x00, 0x00, 0, 0, 0, 0,
});

TEST(DisFire, encodesAndDecodesTheGoldenBytes) {
  ASSERT_EQ(kFireGolden.size(), 96u);
  EXPECT_EQ(encode(exampleHeader(), exampleFire()), kFireGolden);
  auto pdu = decode(kFireGolden, "s");
  ASSERT_TRUE(pdu.ok()) << pdu.error();
  ASSERT_TRUE(pdu->fire.has_value());
  EXPECT_EQ(*pdu->fire, exampleFire());
  EXPECT_FALSE(pdu->entityState.has_value());
}

TEST(DisDetonation, encodesAndDecodesTheGoldenBytes) {
  ASSERT_EQ(kDetonationGolden.size(), 120u);
  EXPECT_EQ(encode(exampleHeader(), exampleDetonation()), kDetonationGolden);
  auto pdu = decode(kDetonationGolden, "s");
  ASSERT_TRUE(pdu.ok()) << pdu.error();
  ASSERT_TRUE(pdu->detonation.has_value());
  EXPECT_EQ(*pdu->detonation, exampleDetonation());
}

TEST(DisFire, truncatedAndHostileFireAndDetonationPdusAreRefused) {
  for (const auto* golden : {&kFireGolden, &kDetonationGolden}) {
    for (std::size_t n = 0; n < golden->size(); ++n) {
      auto pdu = decode(std::span(*golden).first(n), "s");
      ASSERT_FALSE(pdu.ok()) << n;
      EXPECT_EQ(pdu.problems().front().offset, n);
    }
  }
  std::vector<std::byte> b = kFireGolden;
  b.resize(100);
  b[9] = std::byte{100};  // a Fire PDU of 100 bytes
  auto pdu = decode(b, "s");
  ASSERT_FALSE(pdu.ok());
  EXPECT_EQ(pdu.problems().front().offset, 8u);
  b = kDetonationGolden;
  b[101] = std::byte{200};  // 200 records in 120 bytes
  pdu = decode(b, "s");
  ASSERT_FALSE(pdu.ok());
  EXPECT_EQ(pdu.problems().front().offset, 101u);
  b = std::vector<std::byte>(kDetonationGolden.begin(), kDetonationGolden.begin() + 100);
  b[9] = std::byte{100};
  pdu = decode(b, "s");
  ASSERT_FALSE(pdu.ok());
  EXPECT_EQ(pdu.problems().front().offset, 8u);
}

TEST(DisPdu, aDatagramOfTwoPdusDecodesTheFirstAndSaysWhereTheNextStarts) {
  std::vector<std::byte> two = kGolden;
  two.insert(two.end(), kGolden.begin(), kGolden.end());
  auto first = decode(two, "s");
  ASSERT_TRUE(first.ok()) << first.error();
  EXPECT_EQ(first->header.length, 176);
  auto second = decode(std::span(two).subspan(first->header.length), "s");
  ASSERT_TRUE(second.ok()) << second.error();
  EXPECT_EQ(*second->entityState, example());
}

TEST(DisTimestamp, unitsOfTwoToTheThirtyOnePerHourWithTheAbsoluteBit) {
  EXPECT_EQ(timestamp(0.0, false), 0u);
  EXPECT_EQ(timestamp(0.0, true), 1u);
  EXPECT_EQ(timestamp(1800.0, false), 0x80000000u);
  EXPECT_EQ(timestamp(900.0, true), 0x40000001u);
  EXPECT_EQ(timestamp(3600.0 + 900.0, true), 0x40000001u);  // modulo the hour
  EXPECT_EQ(timestamp(-900.0, false), timestamp(2700.0, false));
  EXPECT_EQ(timestamp(3599.9999999, false) >> 1, 0x7fffffffu);
  EXPECT_TRUE(timestampAbsolute(timestamp(12.0, true)));
  EXPECT_FALSE(timestampAbsolute(timestamp(12.0, false)));
  for (double s : {0.0, 0.001, 1.5, 59.25, 1234.567, 3599.0}) {
    EXPECT_NEAR(timestampSeconds(timestamp(s, true)), s, 3600.0 / 2147483648.0) << s;
  }
}

TEST(DisMarking, isElevenCharactersZeroPadded) {
  EXPECT_EQ(Marking::ascii("ABCDEFGHIJKLMNOP").text(), "ABCDEFGHIJK");
  EXPECT_EQ(Marking::ascii("").text(), "");
  EXPECT_EQ(Marking::ascii("T72").chars[3], '\0');
}

}  // namespace
}  // namespace sandtable::dis
