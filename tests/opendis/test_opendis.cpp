// Sandtable's DIS PDUs against Open-DIS for JavaScript (npm open-dis 1.3.6,
// from the seed's school; docs/DIS.md §10), an implementation nobody here
// wrote, in both of its builds (DIS 6 and DIS 7), both ways:
// - Open-DIS builds Entity State, Fire and Detonation PDUs (write_pdus.js);
//   sandtable::dis::decode reads every field as set, and encoding what it
//   decoded gives Open-DIS's bytes back;
// - sandtable::dis::encode writes them; Open-DIS decodes them (read_pdus.js)
//   and every field, floats exactly, is what was encoded;
// - Node sends Open-DIS's PDUs over UDP on loopback (send_pdus.js) to a
//   dis::Receiver, and what it queues decodes to every field as set.
// The package is installed into the build tree by the CTest fixture
// OpenDis.npmInstall (tests/opendis/CMakeLists.txt). A missing node or
// package fails these tests; they never skip.
//
// Thread safety: the tests run node one process at a time.
#include <gtest/gtest.h>

#include <array>
#include <bit>
#include <cstdint>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include <arpa/inet.h>
#include <netinet/in.h>
#include <nlohmann/json.hpp>
#include <sys/socket.h>
#include <sys/wait.h>
#include <unistd.h>

#include "sandtable/testing/process.h"
#include "sandtable/dis/pdu.h"
#include "sandtable/dis/socket.h"
#include "opendis_support.h"

namespace sandtable::dis {
namespace {

using namespace opendis_test;  // kScripts, kModules, node(), haveOpenDis(), ...

std::vector<std::byte> readBytes(const fs::path& path) {
  std::ifstream in(path, std::ios::binary);
  std::vector<char> c((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
  std::vector<std::byte> out(c.size());
  for (std::size_t k = 0; k < c.size(); ++k) out[k] = std::byte(static_cast<unsigned char>(c[k]));
  return out;
}

/// Bytes as hex, for a readable failure message.
std::string hex(const std::vector<std::byte>& bytes) {
  static constexpr char kDigits[] = "0123456789abcdef";
  std::string out;
  for (std::size_t k = 0; k < bytes.size(); ++k) {
    if (k > 0) out += k % 16 == 0 ? '\n' : ' ';
    const auto b = std::to_integer<unsigned>(bytes[k]);
    out += kDigits[b >> 4];
    out += kDigits[b & 15];
  }
  return out;
}

void writeBytes(const fs::path& path, const std::vector<std::byte>& bytes) {
  std::ofstream(path, std::ios::binary)
      .write(reinterpret_cast<const char*>(bytes.data()), std::streamsize(bytes.size()));
}

// ------------------------------------------------ field by field checks
//
// One JSON layout both ways (write_pdus.js and read_pdus.js print it):
// arrays for ids, types and vectors, floats as the exact values of their
// float32 or float64. A float is compared as a double, so a JSON value that
// is not the float32 fails too.

void expectF(const json& j, float v, const std::string& what) { EXPECT_EQ(j.get<double>(), double(v)) << what; }
void expectD(const json& j, double v, const std::string& what) { EXPECT_EQ(j.get<double>(), v) << what; }

template <typename Int>
void expectU(const json& j, Int v, const std::string& what) {
  EXPECT_EQ(j.get<std::int64_t>(), std::int64_t(v)) << what;
}

void expectVec(const json& j, const Vec3f& v, const std::string& what) {
  ASSERT_EQ(j.size(), 3u) << what;
  expectF(j[0], v.x, what + ".x");
  expectF(j[1], v.y, what + ".y");
  expectF(j[2], v.z, what + ".z");
}
void expectVec(const json& j, const Vec3d& v, const std::string& what) {
  ASSERT_EQ(j.size(), 3u) << what;
  expectD(j[0], v.x, what + ".x");
  expectD(j[1], v.y, what + ".y");
  expectD(j[2], v.z, what + ".z");
}
template <typename Triple>
void expectTriple(const json& j, const Triple& t, std::uint16_t third, const std::string& what) {
  ASSERT_EQ(j.size(), 3u) << what;
  expectU(j[0], t.site, what + ".site");
  expectU(j[1], t.application, what + ".application");
  expectU(j[2], third, what + ".third");
}
void expectId(const json& j, const EntityId& id, const std::string& what) { expectTriple(j, id, id.entity, what); }
void expectType(const json& j, const EntityType& t, const std::string& what) {
  ASSERT_EQ(j.size(), 7u) << what;
  expectU(j[0], t.kind, what + ".kind");
  expectU(j[1], t.domain, what + ".domain");
  expectU(j[2], t.country, what + ".country");
  expectU(j[3], t.category, what + ".category");
  expectU(j[4], t.subcategory, what + ".subcategory");
  expectU(j[5], t.specific, what + ".specific");
  expectU(j[6], t.extra, what + ".extra");
}

void expectHeader(const json& j, const Header& h) {
  expectU(j["version"], h.version, "header.version");
  expectU(j["exercise"], h.exercise, "header.exercise");
  expectU(j["type"], h.type, "header.type");
  expectU(j["family"], h.family, "header.family");
  expectU(j["timestamp"], h.timestamp, "header.timestamp");
  expectU(j["length"], h.length, "header.length");
  expectU(j["status"], h.status, "header.status");
}

/// The float32 a standard reader finds in the first 4 bytes of a float64:
/// what Open-DIS 6's value `d` reads as (docs/DIS.md §10).
float highHalfAsFloat(double d) { return std::bit_cast<float>(std::uint32_t(std::bit_cast<std::uint64_t>(d) >> 32)); }

void expectRecords(const json& j, const std::vector<VariableParameter>& records, const std::string& what) {
  ASSERT_EQ(j.size(), records.size()) << what;
  for (std::size_t k = 0; k < records.size(); ++k) {
    const json& r = j[k];
    const std::string at = what + "[" + std::to_string(k) + "]";
    expectU(r["recordType"], records[k].recordType, at + ".recordType");
    if (const auto a = articulatedPart(records[k])) {
      expectU(r["change"], a->change, at + ".change");
      expectU(r["attachedTo"], a->attachedTo, at + ".attachedTo");
      expectU(r["parameterType"], a->parameterType, at + ".parameterType");
      if (r.value("writtenAs", "") == "opendis6-float64") {
        // Open-DIS 6 puts a float64 where the standard has a float32 and
        // padding: the receiver reads the double's first half.
        const double sent = r["value"].get<double>();
        EXPECT_EQ(a->value, highHalfAsFloat(sent)) << at << ": Open-DIS 6's float64 " << sent;
        EXPECT_NE(double(a->value), sent) << at;
        continue;
      }
      expectF(r["value"], a->value, at + ".value");
      // The standard's 32 bits of padding after the value.
      for (std::size_t b = 11; b < 15; ++b) EXPECT_EQ(records[k].data[b], 0) << at << " padding byte " << b + 1;
      if (r.contains("padding")) expectU(r["padding"], 0u, at + ".padding");
    } else if (const auto t = attachedPart(records[k])) {
      expectU(r["detached"], t->detached, at + ".detached");
      expectU(r["attachedTo"], t->attachedTo, at + ".attachedTo");
      expectU(r["station"], t->station, at + ".station");
      expectType(r["type"], t->type, at + ".type");
    } else {
      ADD_FAILURE() << at << ": record type " << int(records[k].recordType) << " is not one this check sets";
    }
  }
}

void expectDescriptor(const json& j, const MunitionDescriptor& d, const std::string& what) {
  expectType(j["munition"], d.munition, what + ".munition");
  expectU(j["warhead"], d.warhead, what + ".warhead");
  expectU(j["fuse"], d.fuse, what + ".fuse");
  expectU(j["quantity"], d.quantity, what + ".quantity");
  expectU(j["rate"], d.rate, what + ".rate");
}

void expectEntityState(const json& j, const EntityState& e) {
  expectId(j["id"], e.id, "id");
  expectU(j["force"], e.force, "force");
  expectType(j["type"], e.type, "type");
  expectType(j["alternativeType"], e.alternativeType, "alternativeType");
  expectVec(j["velocity"], e.velocity, "velocity");
  expectVec(j["location"], e.location, "location");
  ASSERT_EQ(j["orientation"].size(), 3u);
  expectF(j["orientation"][0], e.orientation.psi, "psi");
  expectF(j["orientation"][1], e.orientation.theta, "theta");
  expectF(j["orientation"][2], e.orientation.phi, "phi");
  expectU(j["appearance"], e.appearance, "appearance");
  const json& dr = j["deadReckoning"];
  expectU(dr["algorithm"], e.deadReckoning.algorithm, "deadReckoning.algorithm");
  ASSERT_EQ(dr["other"].size(), 15u);
  for (std::size_t k = 0; k < 15; ++k) expectU(dr["other"][k], e.deadReckoning.other[k], "deadReckoning.other");
  expectVec(dr["acceleration"], e.deadReckoning.acceleration, "deadReckoning.acceleration");
  expectVec(dr["angularVelocity"], e.deadReckoning.angularVelocity, "deadReckoning.angularVelocity");
  expectU(j["marking"]["characterSet"], e.marking.characterSet, "marking.characterSet");
  ASSERT_EQ(j["marking"]["chars"].size(), 11u);
  for (std::size_t k = 0; k < 11; ++k) {
    expectU(j["marking"]["chars"][k], std::uint8_t(e.marking.chars[k]), "marking.chars[" + std::to_string(k) + "]");
  }
  expectU(j["capabilities"], e.capabilities, "capabilities");
  expectRecords(j["parameters"], e.parameters, "parameters");
}

template <typename Warfare>
void expectWarfareIds(const json& j, const Warfare& w) {
  expectId(j["firing"], w.firing, "firing");
  expectId(j["target"], w.target, "target");
  expectId(j["munition"], w.munition, "munition");
  expectTriple(j["event"], w.event, w.event.event, "event");
}

void expectFire(const json& j, const Fire& f) {
  expectWarfareIds(j, f);
  expectU(j["fireMissionIndex"], f.fireMissionIndex, "fireMissionIndex");
  expectVec(j["location"], f.location, "location");
  expectDescriptor(j["descriptor"], f.descriptor, "descriptor");
  expectVec(j["velocity"], f.velocity, "velocity");
  expectF(j["range"], f.range, "range");
}

void expectDetonation(const json& j, const Detonation& d) {
  expectWarfareIds(j, d);
  expectVec(j["velocity"], d.velocity, "velocity");
  expectVec(j["location"], d.location, "location");
  expectDescriptor(j["descriptor"], d.descriptor, "descriptor");
  expectVec(j["entityLocation"], d.entityLocation, "entityLocation");
  expectU(j["result"], d.result, "result");
  expectRecords(j["parameters"], d.parameters, "parameters");
}

// ------------------------------------------- Open-DIS -> Sandtable

/// The body of a decoded PDU against the JSON of what Open-DIS set.
void expectBody(const json& p, const Pdu& pdu) {
  if (p.contains("entityState")) {
    ASSERT_TRUE(pdu.entityState);
    expectEntityState(p["entityState"], *pdu.entityState);
  } else if (p.contains("fire")) {
    ASSERT_TRUE(pdu.fire);
    expectFire(p["fire"], *pdu.fire);
  } else {
    ASSERT_TRUE(pdu.detonation);
    expectDetonation(p["detonation"], *pdu.detonation);
  }
}

/// write_pdus.js builds the three PDUs in `version`; decode reads every
/// field as set, and encoding the result gives Open-DIS's bytes back.
void checkOpenDisBuilds(int version) {
  ASSERT_TRUE(haveOpenDis());
  const fs::path dir = scratchDir("write" + std::to_string(version));
  const auto set = node("write_pdus.js", std::to_string(version) + " " + shellQuoted(dir));
  ASSERT_TRUE(set);
  ASSERT_EQ((*set)["pdus"].size(), 3u);
  for (const json& p : (*set)["pdus"]) {
    const std::string file = p["file"].get<std::string>();
    SCOPED_TRACE(file);
    const auto bytes = readBytes(file);
    const auto pdu = decode(bytes, file);
    ASSERT_TRUE(pdu.ok()) << pdu.error();
    expectHeader(p["header"], pdu->header);
    EXPECT_EQ(pdu->header.length, bytes.size());
    expectBody(p, pdu.value());
    const std::vector<std::byte> again = pdu->entityState ? encode(pdu->header, *pdu->entityState)
                                         : pdu->fire      ? encode(pdu->header, *pdu->fire)
                                         : pdu->detonation ? encode(pdu->header, *pdu->detonation)
                                                           : std::vector<std::byte>{};
    EXPECT_EQ(hex(again), hex(bytes)) << "our encoding of what we decoded differs from Open-DIS's bytes";
  }
  fs::remove_all(dir);
}

TEST(OpenDis, sandtableDecodesEveryFieldOpenDis7Sets) { checkOpenDisBuilds(7); }
TEST(OpenDis, sandtableDecodesEveryFieldOpenDis6Sets) { checkOpenDisBuilds(6); }

/// Node sends Open-DIS's three PDUs over UDP to 127.0.0.1; a Receiver on
/// that port queues them, and each decodes to every field as set.
void checkOpenDisSendsOverUdp(int version) {
  ASSERT_TRUE(haveOpenDis());
  const fs::path dir = scratchDir("udp" + std::to_string(version));
  const auto set = node("write_pdus.js", std::to_string(version) + " " + shellQuoted(dir));
  ASSERT_TRUE(set);
  const json& pdus = (*set)["pdus"];
  ASSERT_EQ(pdus.size(), 3u);
  SocketOptions o;
  o.address = "127.0.0.1";
  o.port = fixtures::freeUdpPort();
  auto socket = UdpSocket::open(o);
  ASSERT_TRUE(socket.ok()) << socket.error();
  auto receiver = Receiver::start(std::move(socket.value()));
  ASSERT_TRUE(receiver.ok()) << receiver.error();
  std::string command = "node ";
  command += shellQuoted(kScripts / "send_pdus.js");
  command += " 127.0.0.1 ";
  command += std::to_string(o.port);
  for (const json& p : pdus) {
    command += ' ';
    command += shellQuoted(p["file"].get<std::string>());
  }
  const auto [out, ok] = capture(command + " 2>&1");
  ASSERT_TRUE(ok) << out;
  std::vector<Datagram> got, batch;
  for (int wait = 0; wait < 50 && got.size() < pdus.size(); ++wait) {
    if (receiver.value()->waitPending(100)) {
      receiver.value()->drain(batch);
      got.insert(got.end(), batch.begin(), batch.end());
    }
  }
  ASSERT_EQ(got.size(), pdus.size()) << "datagrams received from node on 127.0.0.1:" << o.port;
  // Loopback keeps the order one sender sent in.
  for (std::size_t k = 0; k < got.size(); ++k) {
    SCOPED_TRACE(pdus[k]["file"].get<std::string>());
    EXPECT_EQ(got[k].sender.ip, 0x7f000001u) << got[k].sender.text();
    EXPECT_EQ(got[k].bytes, readBytes(pdus[k]["file"].get<std::string>()));
    const auto pdu = decode(got[k].bytes, got[k].sender.text());
    ASSERT_TRUE(pdu.ok()) << pdu.error();
    expectHeader(pdus[k]["header"], pdu->header);
    expectBody(pdus[k], pdu.value());
  }
  EXPECT_EQ(receiver.value()->counters().queueDropped, 0u);
  fs::remove_all(dir);
}

TEST(OpenDis, receiverDecodesOpenDis7PdusSentOverUdp) { checkOpenDisSendsOverUdp(7); }
TEST(OpenDis, receiverDecodesOpenDis6PdusSentOverUdp) { checkOpenDisSendsOverUdp(6); }

// ------------------------------------------- Sandtable -> Open-DIS

Header headerOf(int version) {
  Header h;
  h.version = std::uint8_t(version);
  h.exercise = 21;
  h.timestamp = timestamp(2345.678, false);
  h.status = version == 7 ? 0x04 : 0;
  return h;
}

EntityState ourEntityState() {
  EntityState e;
  e.id = {7, 3, 40001};
  e.force = 1;
  e.type = {1, 2, 225, 1, 11, 2, 0};
  e.alternativeType = {1, 2, 222, 1, 3, 0, 0};
  e.velocity = {101.25f, -37.0625f, 0.0078125f};
  e.location = {4027893.2581, 306998.7777, 4919499.4142};
  e.orientation = {0.7853982f, -0.2617994f, 3.1f};
  e.appearance = 0x90000008;  // bit 31 set
  e.deadReckoning.algorithm = 9;
  e.deadReckoning.other = {2, 0xaa, 0x55, 0x80, 0x7f, 0xff, 0, 1, 2, 3, 4, 5, 6, 7, 0xf0};
  e.deadReckoning.acceleration = {-0.25f, 4.5f, -9.8f};
  e.deadReckoning.angularVelocity = {0.0625f, -0.03125f, 1.0e-3f};
  e.marking = Marking::ascii("SANDTABLE 1");
  e.capabilities = 0xc0000001;
  e.parameters.push_back(toParameter(ArticulatedPart{9, 0, 4096 + 11, -2.75f}));      // turret azimuth
  e.parameters.push_back(toParameter(ArticulatedPart{4, 1, 4416 + 13, 0.3490659f}));  // gun elevation
  e.parameters.push_back(toParameter(AttachedPart{1, 0, 3, {2, 9, 225, 2, 14, 2, 0}}));
  return e;
}

Fire ourFire() {
  Fire f;
  f.firing = {7, 3, 40001};
  f.target = {8, 4, 123};
  f.munition = {7, 3, 40999};
  f.event = {7, 3, 65535};
  f.fireMissionIndex = 0xfedcba98;
  f.location = {4027890.125, 306990.5, 4919501.75};
  f.descriptor = {{2, 2, 225, 2, 1, 0, 0}, 5000, 1100, 3, 900};
  f.velocity = {-610.5f, 20.25f, 15.125f};
  f.range = 3000.75f;
  return f;
}

Detonation ourDetonation() {
  Detonation d;
  d.firing = {7, 3, 40001};
  d.target = {8, 4, 123};
  d.munition = {7, 3, 40999};
  d.event = {7, 3, 65535};
  d.velocity = {-600.0f, 19.5f, -40.0625f};
  d.location = {4026100.0625, 307100.25, 4920700.5};
  d.descriptor = {{2, 2, 225, 2, 1, 0, 0}, 5000, 1100, 1, 0};
  d.entityLocation = {-2.5f, 0.125f, -1.0f};
  d.result = 5;
  d.parameters.push_back(toParameter(ArticulatedPart{2, 0, 4096 + 11, 1.25f}));
  d.parameters.push_back(toParameter(AttachedPart{0, 0, 2, {2, 9, 225, 2, 14, 2, 0}}));
  return d;
}

/// The 8 bytes at `offset` of a record (the bytes after its type byte are `data`).
std::uint64_t recordBytes(const VariableParameter& v, std::size_t offset, std::size_t n) {
  std::uint64_t u = 0;
  for (std::size_t k = 0; k < n; ++k) u = (u << 8) | (offset + k == 0 ? v.recordType : v.data[offset + k - 1]);
  return u;
}

/// Open-DIS's own values of the fields it reads otherwise than the standard.
void expectRaw(const json& raw, int version, const std::vector<VariableParameter>& records) {
  ASSERT_EQ(raw["records"].size(), records.size());
  expectU(raw["recordCount"], records.size(), "recordCount");
  for (std::size_t k = 0; k < records.size(); ++k) {
    const json& r = raw["records"][k];
    const std::string at = "raw.records[" + std::to_string(k) + "]";
    if (version == 6) {
      // One float64 over the value field: a float32 and its padding read
      // as a double (1.25 comes out as 0.03125; docs/DIS.md §10).
      expectD(r["parameterValue"], std::bit_cast<double>(recordBytes(records[k], 8, 8)), at + ".parameterValue");
      if (records[k].recordType == 0) {
        EXPECT_NE(r["parameterValue"].get<double>(), double(articulatedPart(records[k])->value)) << at;
      }
    } else {
      // The generic record: a float64 over bytes 1-8, a u32, a u16, a u8;
      // and ArticulatedParts' 64-bit value as a signed decimal string.
      expectD(r["variableParameterFields1"], std::bit_cast<double>(recordBytes(records[k], 1, 8)), at + ".fields1");
      expectU(r["variableParameterFields2"], recordBytes(records[k], 9, 4), at + ".fields2");
      expectU(r["variableParameterFields3"], recordBytes(records[k], 13, 2), at + ".fields3");
      expectU(r["variableParameterFields4"], recordBytes(records[k], 15, 1), at + ".fields4");
      EXPECT_EQ(r["parameterValue"].get<std::string>(), std::to_string(std::int64_t(recordBytes(records[k], 8, 8))))
          << at;
    }
  }
}

/// Open-DIS reads every field of what encode writes in `version`.
void checkOpenDisReads(int version) {
  ASSERT_TRUE(haveOpenDis());
  const fs::path dir = scratchDir("read" + std::to_string(version));
  const Header h = headerOf(version);
  const EntityState es = ourEntityState();
  const Fire fire = ourFire();
  const Detonation det = ourDetonation();
  const std::vector<std::vector<std::byte>> pdus = {encode(h, es), encode(h, fire), encode(h, det)};
  std::string args = std::to_string(version);
  for (std::size_t k = 0; k < pdus.size(); ++k) {
    const fs::path file = dir / std::string("sandtable").append(std::to_string(version)).append("_")
                                    .append(std::to_string(k)).append(".bin");
    writeBytes(file, pdus[k]);
    args += ' ';
    args += shellQuoted(file);
  }
  const auto read = node("read_pdus.js", args);
  ASSERT_TRUE(read);
  const json& got = (*read)["pdus"];
  ASSERT_EQ(got.size(), 3u);
  for (std::size_t k = 0; k < 3; ++k) {
    SCOPED_TRACE(got[k]["file"].get<std::string>());
    const auto ours = decode(pdus[k], "self");
    ASSERT_TRUE(ours.ok()) << ours.error();
    expectHeader(got[k]["header"], ours->header);
    EXPECT_EQ(got[k]["raw"]["padding"].get<int>(), 0);
  }
  expectEntityState(got[0]["entityState"], es);
  expectFire(got[1]["fire"], fire);
  expectDetonation(got[2]["detonation"], det);
  // The marking as a string: Open-DIS 7 stops at the first zero, Open-DIS 6
  // gives all 11 characters, zeros included.
  const std::string text = version == 7 ? es.marking.text() : std::string(es.marking.chars.data(), 11);
  EXPECT_EQ(got[0]["entityState"]["marking"]["text"].get<std::string>(), text);
  // Open-DIS 6 reads the appearance, the capabilities and the fire mission
  // index as signed 32-bit integers; Open-DIS 7 as unsigned.
  const auto raw32 = [&](std::uint32_t v) { return version == 6 ? std::int64_t(std::int32_t(v)) : std::int64_t(v); };
  EXPECT_EQ(got[0]["raw"]["appearance"].get<std::int64_t>(), raw32(es.appearance));
  EXPECT_EQ(got[0]["raw"]["capabilities"].get<std::int64_t>(), raw32(es.capabilities));
  EXPECT_EQ(got[1]["raw"]["fireMissionIndex"].get<std::int64_t>(), raw32(fire.fireMissionIndex));
  expectRaw(got[0]["raw"], version, es.parameters);
  expectRaw(got[2]["raw"], version, det.parameters);
  fs::remove_all(dir);
}

TEST(OpenDis, openDis7ReadsEveryFieldSandtableEncodes) { checkOpenDisReads(7); }
TEST(OpenDis, openDis6ReadsEveryFieldSandtableEncodes) { checkOpenDisReads(6); }

}  // namespace
}  // namespace sandtable::dis
