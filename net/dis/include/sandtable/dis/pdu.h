#pragma once
// DIS protocol data units on the wire (IEEE 1278.1-2012, DIS version 7;
// version 6, IEEE 1278.1a-1998, accepted on receive), as docs/DIS.md lays
// them out byte by byte. Every field is big-endian ("network order") at the
// offset the standard gives; the offsets are pinned with static_asserts in
// pdu.cpp and golden bytes in test/test_pdu.cpp.
//
// Built: the PDU header, the timestamp, the Entity State PDU (type 1) with
// its variable parameter records (articulated and attached parts), the Fire
// PDU (2), the Detonation PDU (3), Create Entity (11) and Remove Entity
// (12), and the synthetic environment's Point Object State (43) and Linear
// Object State (44). Other PDU types decode their header and are reported as
// such (no body), so a receiver can count them.
//
// Decoding never trusts the bytes: the header's length, the record count
// and every fixed part are checked against what arrived before anything is
// read or sized, and a problem names the sender and the byte offset.
//
// Thread safety: pure functions over values; call from any thread.
#include <array>
#include <cstddef>
#include <cstdint>
#include <optional>
#include <span>
#include <string>
#include <string_view>
#include <vector>

#include "sandtable/base/result.h"

namespace sandtable::dis {

inline constexpr std::size_t kHeaderBytes = 12;
inline constexpr std::size_t kEntityStateBytes = 144;  ///< without variable parameter records
inline constexpr std::size_t kParameterBytes = 16;     ///< one variable parameter record
inline constexpr std::size_t kFireBytes = 96;
inline constexpr std::size_t kDetonationBytes = 104;   ///< without variable parameter records
inline constexpr std::size_t kEntityRequestBytes = 28; ///< Create Entity and Remove Entity
inline constexpr std::size_t kPointObjectBytes = 88;
inline constexpr std::size_t kLinearObjectBytes = 40;  ///< without segment records
inline constexpr std::size_t kSegmentBytes = 64;       ///< one linear segment parameter record
/// The largest PDU the standard allows (IEEE 1278.2: 8,192 bytes); a
/// header claiming more is refused.
inline constexpr std::size_t kMaxPduBytes = 8192;

inline constexpr std::uint8_t kVersion6 = 6;  ///< IEEE 1278.1a-1998
inline constexpr std::uint8_t kVersion7 = 7;  ///< IEEE 1278.1-2012

/// PDU types this library knows by name (the standard's enumeration).
enum class PduType : std::uint8_t {
  entityState = 1,
  fire = 2,
  detonation = 3,
  createEntity = 11,
  removeEntity = 12,
  pointObjectState = 43,
  linearObjectState = 44,
};

/// The most linear segments a Linear Object State PDU can carry within
/// kMaxPduBytes: (8192 - 40) / 64.
inline constexpr std::size_t kMaxSegments = (kMaxPduBytes - kLinearObjectBytes) / kSegmentBytes;

/// Protocol families of those types.
enum class Family : std::uint8_t {
  entityInformation = 1,
  warfare = 2,
  simulationManagement = 5,
  syntheticEnvironment = 9,
};

/// The 12-byte header every PDU starts with.
struct Header {
  std::uint8_t version = kVersion7;
  std::uint8_t exercise = 1;
  std::uint8_t type = 0;
  std::uint8_t family = 0;
  std::uint32_t timestamp = 0;  ///< see timestamp() below
  std::uint16_t length = 0;     ///< bytes of the whole PDU, header included
  std::uint8_t status = 0;      ///< version 7's PDU status; version 6 has padding here
  bool operator==(const Header&) const = default;
};

/// Site, application, entity: unique within an exercise.
struct EntityId {
  std::uint16_t site = 0, application = 0, entity = 0;
  bool operator==(const EntityId&) const = default;
};

/// Kind, domain, country, category, subcategory, specific, extra (SISO-REF-010).
struct EntityType {
  std::uint8_t kind = 0, domain = 0;
  std::uint16_t country = 0;
  std::uint8_t category = 0, subcategory = 0, specific = 0, extra = 0;
  bool operator==(const EntityType&) const = default;
};

struct Vec3f {
  float x = 0, y = 0, z = 0;
  bool operator==(const Vec3f&) const = default;
};
struct Vec3d {
  double x = 0, y = 0, z = 0;
  bool operator==(const Vec3d&) const = default;
};

/// Euler angles psi, theta, phi in radians, relative to the geocentric
/// (WGS-84 ECEF) frame, as the standard defines them.
struct Euler {
  float psi = 0, theta = 0, phi = 0;
  bool operator==(const Euler&) const = default;
};

/// The 40-byte dead reckoning parameters record.
struct DeadReckoning {
  std::uint8_t algorithm = 1;                ///< 1 static ... 9 FVB (IEEE 1278.1 Annex E)
  std::array<std::uint8_t, 15> other{};      ///< "other parameters", kept as sent
  Vec3f acceleration;                        ///< m/s^2 (world or body axes by algorithm)
  Vec3f angularVelocity;                     ///< rad/s, body axes
  bool operator==(const DeadReckoning&) const = default;
};

/// The entity marking: a character set and 11 characters (zero-padded).
struct Marking {
  std::uint8_t characterSet = 1;  ///< 1: ASCII
  std::array<char, 11> chars{};
  /// The characters up to the first zero.
  std::string text() const;
  /// ASCII marking of `s`, cut to 11 characters.
  static Marking ascii(std::string_view s);
  bool operator==(const Marking&) const = default;
};

/// One 16-byte variable parameter record (version 6: articulation
/// parameter): its type and the 15 bytes after it, kept as sent.
struct VariableParameter {
  std::uint8_t recordType = 0;  ///< 0 articulated part, 1 attached part (others kept, not read)
  std::array<std::uint8_t, 15> data{};
  bool operator==(const VariableParameter&) const = default;
};

/// Record type 0: one articulated part (a turret's azimuth, a gun's
/// elevation): parameterType is the part class times 32 plus the metric
/// (SISO-REF-010: 4096 + 11 is the primary turret's azimuth).
struct ArticulatedPart {
  std::uint8_t change = 0;      ///< change indicator, bumped by the sender on each change
  std::uint16_t attachedTo = 0; ///< 0: the entity itself, else another part's record number
  std::uint32_t parameterType = 0;
  float value = 0;              ///< radians, metres or m/s by metric
  bool operator==(const ArticulatedPart&) const = default;
};

/// Record type 1: an attached part (a store on a station).
struct AttachedPart {
  std::uint8_t detached = 0;    ///< 0 attached, 1 detached
  std::uint16_t attachedTo = 0;
  std::uint32_t station = 0;    ///< attached part parameter type (station)
  EntityType type;
  bool operator==(const AttachedPart&) const = default;
};

VariableParameter toParameter(const ArticulatedPart& p);
VariableParameter toParameter(const AttachedPart& p);
/// The record as an articulated (attached) part; empty for other types.
std::optional<ArticulatedPart> articulatedPart(const VariableParameter& v);
std::optional<AttachedPart> attachedPart(const VariableParameter& v);

/// The Entity State PDU's body (type 1, family 1).
struct EntityState {
  EntityId id;
  std::uint8_t force = 0;  ///< 0 other, 1 friendly, 2 opposing, 3 neutral
  EntityType type, alternativeType;
  Vec3f velocity;          ///< m/s (world axes for algorithms 1-5, body for 6-9)
  Vec3d location;          ///< metres, WGS-84 geocentric
  Euler orientation;
  std::uint32_t appearance = 0;
  DeadReckoning deadReckoning;
  Marking marking;
  std::uint32_t capabilities = 0;
  std::vector<VariableParameter> parameters;  ///< at most 255
  bool operator==(const EntityState&) const = default;
};

/// Site, application and a number the firing simulation counts up: ties a
/// Detonation to its Fire.
struct EventId {
  std::uint16_t site = 0, application = 0, event = 0;
  bool operator==(const EventId&) const = default;
};

/// The munition descriptor (version 6: burst descriptor), 16 bytes.
struct MunitionDescriptor {
  EntityType munition;
  std::uint16_t warhead = 0, fuse = 0, quantity = 0, rate = 0;
  bool operator==(const MunitionDescriptor&) const = default;
};

/// The Fire PDU's body (type 2, family 2): 96 bytes in all.
struct Fire {
  EntityId firing, target, munition;  ///< target and munition 0:0:0 when none
  EventId event;
  std::uint32_t fireMissionIndex = 0;
  Vec3d location;                     ///< where it was fired, ECEF metres
  MunitionDescriptor descriptor;
  Vec3f velocity;                     ///< the round's, ECEF m/s
  float range = 0;                    ///< metres, 0 when unknown
  bool operator==(const Fire&) const = default;
};

/// The Detonation PDU's body (type 3, family 2): 104 bytes plus 16 per record.
struct Detonation {
  EntityId firing, target, munition;
  EventId event;
  Vec3f velocity;                     ///< the round's at impact, ECEF m/s
  Vec3d location;                     ///< ECEF metres
  MunitionDescriptor descriptor;
  Vec3f entityLocation;               ///< in the target's body axes, metres
  std::uint8_t result = 0;            ///< 1 entity impact, 3 ground impact, 5 detonation, ... (SISO-REF-010)
  std::vector<VariableParameter> parameters;  ///< at most 255
  bool operator==(const Detonation&) const = default;
};

/// The body of a Create Entity PDU (type 11) or a Remove Entity PDU (12),
/// family 5 (simulation management): 28 bytes in all, the same in version 6
/// and 7. The receiving id names the entity to create or remove.
struct EntityRequest {
  EntityId originating, receiving;
  std::uint32_t requestId = 0;  ///< the sender's, echoed by the Acknowledge PDU
  bool operator==(const EntityRequest&) const = default;
};
struct CreateEntity : EntityRequest {
  bool operator==(const CreateEntity&) const = default;
};
struct RemoveEntity : EntityRequest {
  bool operator==(const RemoveEntity&) const = default;
};

/// A synthetic environment object's id: site, application, object number.
struct ObjectId {
  std::uint16_t site = 0, application = 0, object = 0;
  bool operator==(const ObjectId&) const = default;
};

/// Site and application (the simulation address record).
struct SimulationAddress {
  std::uint16_t site = 0, application = 0;
  bool operator==(const SimulationAddress&) const = default;
};

/// The object type record of IEEE 1278.1-2012 (4 bytes, in this order;
/// SISO-REF-010 section 12 names the values).
struct ObjectType {
  std::uint8_t domain = 0, kind = 0, category = 0, subcategory = 0;
  bool operator==(const ObjectType&) const = default;
};

/// The Point Object State PDU's body (type 43, family 9): 88 bytes in all.
struct PointObjectState {
  ObjectId id;
  ObjectId referenced;             ///< the object this one is placed relative to; 0:0:0 when none
  std::uint16_t updateNumber = 0;  ///< counts up with each change
  std::uint8_t force = 0;
  std::uint8_t modifications = 0;  ///< bit 0 location, bit 1 orientation modified
  ObjectType type;
  Vec3d location;                  ///< ECEF metres
  Euler orientation;
  std::uint64_t appearance = 0;    ///< the 64-bit object appearance field, kept as sent (docs/DIS.md §3.4)
  SimulationAddress requester, receiver;
  bool operator==(const PointObjectState&) const = default;
};

/// One linear segment parameter record: 64 bytes.
struct LinearSegment {
  std::uint8_t number = 0;
  std::uint8_t modification = 0;
  std::uint16_t generalAppearance = 0;
  std::uint32_t specificAppearance = 0;
  Vec3d location;                  ///< ECEF metres
  Euler orientation;
  float length = 0, width = 0, height = 0, depth = 0;  ///< metres
  bool operator==(const LinearSegment&) const = default;
};

/// The Linear Object State PDU's body (type 44, family 9): 40 bytes plus
/// 64 per segment, at most kMaxSegments.
struct LinearObjectState {
  ObjectId id, referenced;
  std::uint16_t updateNumber = 0;
  std::uint8_t force = 0;
  SimulationAddress requester, receiver;
  ObjectType type;
  std::vector<LinearSegment> segments;
  bool operator==(const LinearObjectState&) const = default;
};

/// The timestamp field: time past the hour in units of 3600 s / 2^31 in
/// bits 31..1, and bit 0 set for absolute time (a clock synchronised to
/// UTC), clear for relative. `secondsPastHour` is taken modulo 3600.
std::uint32_t timestamp(double secondsPastHour, bool absolute);
double timestampSeconds(std::uint32_t stamp);
inline bool timestampAbsolute(std::uint32_t stamp) { return (stamp & 1u) != 0; }

/// An Entity State PDU: `header`'s version, exercise, timestamp and status
/// are written as given, its type, family and length as the PDU needs.
/// Empty when there are more than 255 parameters.
std::vector<std::byte> encode(const Header& header, const EntityState& state);

/// A Fire PDU (96 bytes), and a Detonation PDU (empty past 255 records);
/// as for the Entity State PDU, the header's type, family and length are
/// written as the PDU needs.
std::vector<std::byte> encode(const Header& header, const Fire& fire);
std::vector<std::byte> encode(const Header& header, const Detonation& detonation);

/// Create Entity and Remove Entity PDUs (28 bytes), a Point Object State
/// PDU (88 bytes) and a Linear Object State PDU (empty past kMaxSegments
/// segments); the header's type, family and length as the PDU needs.
std::vector<std::byte> encode(const Header& header, const CreateEntity& create);
std::vector<std::byte> encode(const Header& header, const RemoveEntity& remove);
std::vector<std::byte> encode(const Header& header, const PointObjectState& object);
std::vector<std::byte> encode(const Header& header, const LinearObjectState& object);

/// One decoded PDU: the header, and the body when the type is one this
/// library decodes (Entity State 1, Fire 2, Detonation 3, Create Entity
/// 11, Remove Entity 12 in version 6 or 7; Point Object State 43 and
/// Linear Object State 44 in version 7 only, their version 6 layout being
/// another); otherwise only the header, which a receiver counts as an
/// unknown type, not an error. At most one body is set.
struct Pdu {
  Header header;
  std::optional<EntityState> entityState;
  std::optional<Fire> fire;
  std::optional<Detonation> detonation;
  std::optional<CreateEntity> createEntity;
  std::optional<RemoveEntity> removeEntity;
  std::optional<PointObjectState> pointObject;
  std::optional<LinearObjectState> linearObject;
};

/// Decodes the PDU at the start of `bytes` (a datagram may carry more than
/// one: header.length says where the next starts). Refuses, naming
/// `sender` and the offset: fewer than 12 bytes; a version other than 6 or
/// 7; a length under 12, over kMaxPduBytes or over what arrived; for an
/// Entity State PDU, a length other than 144 + 16 per record its count
/// names; for a Fire PDU, a length other than 96; for a Detonation PDU, a
/// length other than 104 + 16 per record; for Create and Remove Entity, a
/// length other than 28; for a version 7 Point Object State PDU, a length
/// other than 88; for a version 7 Linear Object State PDU, a length other
/// than 40 + 64 per segment its count names. Reads nothing past
/// header.length.
Result<Pdu> decode(std::span<const std::byte> bytes, const std::string& sender);

}  // namespace sandtable::dis
