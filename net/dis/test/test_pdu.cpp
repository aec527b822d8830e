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
  EXPECT_FALSE(pdu->createEntity.has_value());
  EXPECT_FALSE(pdu->removeEntity.has_value());
  EXPECT_FALSE(pdu->pointObject.has_value());
  EXPECT_FALSE(pdu->linearObject.has_value());
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

// docs/DIS.md §3.3: the simulation manager 1:3:0 asks for entity 1:2:772 to be created
// (then removed), request id 0x0A0B0C0D (its bytes in order show the byte order).
CreateEntity exampleCreate() {
  CreateEntity c;
  c.originating = {1, 3, 0};
  c.receiving = {1, 2, 0x0304};
  c.requestId = 0x0A0B0C0Du;
  return c;
}
RemoveEntity exampleRemove() {
  RemoveEntity r;
  static_cast<EntityRequest&>(r) = exampleCreate();
  return r;
}

const std::vector<std::byte> kCreateGolden = bytesOf({
    // header: version 7, exercise 3, type 11 (Create Entity), family 5 (simulation management),
    // 30:00 absolute, 28 bytes
    0x07, 0x03, 0x0B, 0x05, 0x80, 0x00, 0x00, 0x01, 0x00, 0x1C, 0x00, 0x00,
    // originating 1:3:0, receiving 1:2:772
    0x00, 0x01, 0x00, 0x03, 0x00, 0x00, 0x00, 0x01, 0x00, 0x02, 0x03, 0x04,
    // request id 0x0A0B0C0D
    0x0A, 0x0B, 0x0C, 0x0D,
});

// The same body with type 12 (Remove Entity).
std::vector<std::byte> removeGolden() {
  std::vector<std::byte> b = kCreateGolden;
  b[2] = std::byte{0x0C};
  return b;
}

// docs/DIS.md §3.4: object 1:2:17, a land (domain 1) object of kind 2, category 3, subcategory
// 4, at §3's location and orientation; the appearance 0x0102030405060708 shows the byte order.
PointObjectState examplePoint() {
  PointObjectState o;
  o.id = {1, 2, 17};
  o.updateNumber = 5;
  o.force = 1;
  o.modifications = 1;  // location modified
  o.type = {1, 2, 3, 4};
  o.location = {1024.0, -2.0, 3.0};
  o.orientation = {0.5f, -1.0f, 0.25f};
  o.appearance = 0x0102030405060708u;
  o.requester = {1, 2};
  o.receiver = {0xFFFF, 0xFFFF};  // all simulations
  return o;
}

const std::vector<std::byte> kPointGolden = bytesOf({
    // header: version 7, exercise 3, type 43 (0x2B), family 9 (synthetic environment), 30:00 absolute,
    // 88 (0x58) bytes
    0x07, 0x03, 0x2B, 0x09, 0x80, 0x00, 0x00, 0x01, 0x00, 0x58, 0x00, 0x00,
    // object 1:2:17, referenced object 0:0:0
    0x00, 0x01, 0x00, 0x02, 0x00, 0x11, 0, 0, 0, 0, 0, 0,
    // update number 5, force 1, modifications 1; object type: domain 1, kind 2, category 3, subcategory 4
    0x00, 0x05, 0x01, 0x01, 0x01, 0x02, 0x03, 0x04,
    // location 1024.0, -2.0, 3.0
    0x40, 0x90, 0, 0, 0, 0, 0, 0, 0xC0, 0x00, 0, 0, 0, 0, 0, 0, 0x40, 0x08, 0, 0, 0, 0, 0, 0,
    // orientation psi 0.5f, theta -1.0f, phi 0.25f
    0x3F, 0x00, 0x00, 0x00, 0xBF, 0x80, 0x00, 0x00, 0x3E, 0x80, 0x00, 0x00,
    // appearance, 64 bits as sent
    0x01, 0x02, 0x03, 0x04, 0x05, 0x06, 0x07, 0x08,
    // requester 1:2, receiver 65535:65535, padding
    0x00, 0x01, 0x00, 0x02, 0xFF, 0xFF, 0xFF, 0xFF, 0, 0, 0, 0,
});

// docs/DIS.md §3.5: object 1:2:18 (domain 1, kind 5, category 2, subcategory 1) in two segments.
LinearObjectState exampleLinear() {
  LinearObjectState o;
  o.id = {1, 2, 18};
  o.updateNumber = 1;
  o.force = 2;
  o.requester = {1, 2};
  o.receiver = {0xFFFF, 0xFFFF};
  o.type = {1, 5, 2, 1};
  LinearSegment a;
  a.number = 1;
  a.generalAppearance = 0x1234;
  a.specificAppearance = 0x89ABCDEFu;
  a.location = {1024.0, -2.0, 3.0};
  a.orientation = {0.5f, -1.0f, 0.25f};
  a.length = 100.0f;
  a.width = 4.0f;
  a.height = 2.5f;
  a.depth = 0.5f;
  LinearSegment b;
  b.number = 2;
  b.modification = 1;
  b.location = {2048.0, -2.0, 3.0};
  b.length = 50.0f;
  b.width = 4.0f;
  o.segments = {a, b};
  return o;
}

const std::vector<std::byte> kLinearGolden = bytesOf({
    // header: version 7, exercise 3, type 44 (0x2C), family 9, 30:00 absolute, 168 = 40 + 2 x 64 (0xA8) bytes
    0x07, 0x03, 0x2C, 0x09, 0x80, 0x00, 0x00, 0x01, 0x00, 0xA8, 0x00, 0x00,
    // object 1:2:18, referenced object 0:0:0
    0x00, 0x01, 0x00, 0x02, 0x00, 0x12, 0, 0, 0, 0, 0, 0,
    // update number 1, force 2, two segments
    0x00, 0x01, 0x02, 0x02,
    // requester 1:2, receiver 65535:65535, object type 1.5.2.1
    0x00, 0x01, 0x00, 0x02, 0xFF, 0xFF, 0xFF, 0xFF, 0x01, 0x05, 0x02, 0x01,
    // segment 1: number 1, modification 0, general appearance 0x1234, specific 0x89ABCDEF
    0x01, 0x00, 0x12, 0x34, 0x89, 0xAB, 0xCD, 0xEF,
    // location 1024.0, -2.0, 3.0; orientation 0.5f, -1.0f, 0.25f
    0x40, 0x90, 0, 0, 0, 0, 0, 0, 0xC0, 0x00, 0, 0, 0, 0, 0, 0, 0x40, 0x08, 0, 0, 0, 0, 0, 0,
    0x3F, 0x00, 0x00, 0x00, 0xBF, 0x80, 0x00, 0x00, 0x3E, 0x80, 0x00, 0x00,
    // length 100.0f (1.5625 x 2^6: 0x42C8...), width 4.0f, height 2.5f, depth 0.5f, padding
    0x42, 0xC8, 0x00, 0x00, 0x40, 0x80, 0x00, 0x00, 0x40, 0x20, 0x00, 0x00, 0x3F, 0x00, 0x00, 0x00, 0, 0, 0, 0,
    // segment 2: number 2, modification 1, appearances 0
    0x02, 0x01, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00,
    // location 2048.0 (2^11: exponent 0x40A), -2.0, 3.0; orientation 0, 0, 0
    0x40, 0xA0, 0, 0, 0, 0, 0, 0, 0xC0, 0x00, 0, 0, 0, 0, 0, 0, 0x40, 0x08, 0, 0, 0, 0, 0, 0,
    0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0,
    // length 50.0f (1.5625 x 2^5: 0x4248...), width 4.0f, height 0, depth 0, padding
    0x42, 0x48, 0x00, 0x00, 0x40, 0x80, 0x00, 0x00, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0,
});

TEST(DisEntityRequest, createAndRemoveEncodeAndDecodeTheGoldenBytes) {
  ASSERT_EQ(kCreateGolden.size(), 28u);
  EXPECT_EQ(encode(exampleHeader(), exampleCreate()), kCreateGolden);
  EXPECT_EQ(encode(exampleHeader(), exampleRemove()), removeGolden());
  auto pdu = decode(kCreateGolden, "s");
  ASSERT_TRUE(pdu.ok()) << pdu.error();
  EXPECT_EQ(pdu->header.family, 5);
  ASSERT_TRUE(pdu->createEntity.has_value());
  EXPECT_EQ(*pdu->createEntity, exampleCreate());
  EXPECT_FALSE(pdu->removeEntity.has_value());
  pdu = decode(removeGolden(), "s");
  ASSERT_TRUE(pdu.ok()) << pdu.error();
  ASSERT_TRUE(pdu->removeEntity.has_value());
  EXPECT_EQ(*pdu->removeEntity, exampleRemove());
  EXPECT_FALSE(pdu->createEntity.has_value());
  EXPECT_EQ(pdu->removeEntity->receiving, (EntityId{1, 2, 772}));
}

TEST(DisEntityRequest, version6IsDecodedToo) {
  // 1278.1a-1998 lays both out alike: VBS's Remove Entity must remove the entity.
  for (std::vector<std::byte> b : {kCreateGolden, removeGolden()}) {
    b[0] = std::byte{6};
    b[10] = std::byte{0x5A};  // padding in version 6
    auto pdu = decode(b, "vbs");
    ASSERT_TRUE(pdu.ok()) << pdu.error();
    EXPECT_EQ(pdu->header.status, 0);
    EXPECT_TRUE(pdu->createEntity.has_value() || pdu->removeEntity.has_value());
    const EntityRequest& r = pdu->createEntity ? static_cast<const EntityRequest&>(*pdu->createEntity)
                                               : static_cast<const EntityRequest&>(*pdu->removeEntity);
    EXPECT_EQ(r, static_cast<const EntityRequest&>(exampleCreate()));
    Header h = exampleHeader();
    h.version = 6;
    b[10] = std::byte{0};
    EXPECT_EQ(pdu->createEntity ? encode(h, *pdu->createEntity) : encode(h, *pdu->removeEntity), b);
  }
}

TEST(DisObjectState, pointAndLinearEncodeAndDecodeTheGoldenBytes) {
  ASSERT_EQ(kPointGolden.size(), 88u);
  ASSERT_EQ(kLinearGolden.size(), 168u);
  EXPECT_EQ(encode(exampleHeader(), examplePoint()), kPointGolden);
  EXPECT_EQ(encode(exampleHeader(), exampleLinear()), kLinearGolden);
  auto pdu = decode(kPointGolden, "s");
  ASSERT_TRUE(pdu.ok()) << pdu.error();
  ASSERT_TRUE(pdu->pointObject.has_value());
  EXPECT_EQ(*pdu->pointObject, examplePoint());
  EXPECT_FALSE(pdu->linearObject.has_value());
  pdu = decode(kLinearGolden, "s");
  ASSERT_TRUE(pdu.ok()) << pdu.error();
  ASSERT_TRUE(pdu->linearObject.has_value());
  EXPECT_EQ(*pdu->linearObject, exampleLinear());
  EXPECT_EQ(pdu->linearObject->segments[0].length, 100.0f);
}

TEST(DisObjectState, version6ObjectPdusDecodeTheirHeaderOnly) {
  // Version 6's layout differs (a 6-byte object type, 16-bit segment sizes): counted, not read.
  for (std::vector<std::byte> b : {kPointGolden, kLinearGolden}) {
    b[0] = std::byte{6};
    auto pdu = decode(b, "s");
    ASSERT_TRUE(pdu.ok()) << pdu.error();
    EXPECT_FALSE(pdu->pointObject.has_value());
    EXPECT_FALSE(pdu->linearObject.has_value());
  }
}

TEST(DisNewPdus, everyTruncatedPrefixIsRefusedAtItsLength) {
  for (const auto& golden : {kCreateGolden, removeGolden(), kPointGolden, kLinearGolden}) {
    for (std::size_t n = 0; n < golden.size(); ++n) {
      auto pdu = decode(std::span(golden).first(n), "10.0.0.7:3000");
      ASSERT_FALSE(pdu.ok()) << n;
      const Problem& p = pdu.problems().front();
      EXPECT_EQ(p.file, "10.0.0.7:3000");
      EXPECT_EQ(p.offset, n) << p.message;
      EXPECT_NE(p.message.find("truncated"), std::string::npos) << p.message;
    }
  }
}

TEST(DisNewPdus, hostileLengthsAndCountsAreRefusedWithTheirOffset) {
  const auto refusal = [](const std::vector<std::byte>& b) {
    auto pdu = decode(b, "s");
    EXPECT_FALSE(pdu.ok());
    return pdu.ok() ? Problem{} : pdu.problems().front();
  };
  // Create and Remove Entity of 32 bytes (four bytes past the request id).
  for (std::vector<std::byte> b : {kCreateGolden, removeGolden()}) {
    b.resize(32);
    b[9] = std::byte{32};
    const Problem p = refusal(b);
    EXPECT_EQ(p.offset, 8u);
    EXPECT_NE(p.message.find("28 bytes"), std::string::npos) << p.message;
  }
  // A Point Object State PDU cut to 80 bytes by its own length.
  std::vector<std::byte> b(kPointGolden.begin(), kPointGolden.begin() + 80);
  b[9] = std::byte{80};
  EXPECT_EQ(refusal(b).offset, 8u);
  // Linear: 255 segments claimed in 168 bytes (they would need 16,360), one segment in two's
  // bytes, and a PDU too short for the fixed part.
  b = kLinearGolden;
  b[27] = std::byte{255};
  Problem p = refusal(b);
  EXPECT_EQ(p.offset, 27u);
  EXPECT_NE(p.message.find("16360"), std::string::npos) << p.message;
  b[27] = std::byte{1};
  EXPECT_EQ(refusal(b).offset, 27u);
  b[27] = std::byte{0};
  EXPECT_EQ(refusal(b).offset, 27u);
  b = std::vector<std::byte>(kLinearGolden.begin(), kLinearGolden.begin() + 36);
  b[9] = std::byte{36};
  EXPECT_EQ(refusal(b).offset, 8u);
  // A count that matches its length but not what arrived: truncated, nothing allocated.
  b = kLinearGolden;
  b[27] = std::byte{127};
  b[8] = std::byte{0x1F};  // 8168 = 40 + 127 x 64 = 0x1FE8
  b[9] = std::byte{0xE8};
  p = refusal(b);
  EXPECT_EQ(p.offset, kLinearGolden.size());
  EXPECT_NE(p.message.find("truncated"), std::string::npos) << p.message;
}

TEST(DisNewPdus, roundTripsAndTheLargestLinearObject) {
  LinearObjectState o = exampleLinear();
  o.segments.assign(kMaxSegments, o.segments[0]);
  for (std::size_t k = 0; k < o.segments.size(); ++k) o.segments[k].number = std::uint8_t(k);
  const auto bytes = encode(exampleHeader(), o);
  ASSERT_EQ(bytes.size(), 40u + 64u * 127u);
  auto pdu = decode(bytes, "s");
  ASSERT_TRUE(pdu.ok()) << pdu.error();
  EXPECT_EQ(*pdu->linearObject, o);
  o.segments.push_back(o.segments[0]);  // 128 segments: past 8,192 bytes
  EXPECT_TRUE(encode(exampleHeader(), o).empty());
  o.segments.clear();
  pdu = decode(encode(exampleHeader(), o), "s");
  ASSERT_TRUE(pdu.ok()) << pdu.error();
  EXPECT_EQ(*pdu->linearObject, o);
  PointObjectState point = examplePoint();
  point.appearance = 0xFFFFFFFFFFFFFFFFu;  // every bit survives (no float reading)
  pdu = decode(encode(exampleHeader(), point), "s");
  ASSERT_TRUE(pdu.ok()) << pdu.error();
  EXPECT_EQ(*pdu->pointObject, point);
  RemoveEntity r;
  r.originating = {0xFFFF, 0xFFFF, 0xFFFF};
  r.requestId = 0xFFFFFFFFu;
  pdu = decode(encode(exampleHeader(), r), "s");
  ASSERT_TRUE(pdu.ok()) << pdu.error();
  EXPECT_EQ(*pdu->removeEntity, r);
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
