// DIS PDU encoding and decoding (pdu.h, docs/DIS.md). Big-endian by the
// standard; every offset below is the standard's, pinned by static_asserts
// so that a slip in one field moves no other.
#include "sandtable/dis/pdu.h"

#include <bit>
#include <cmath>
#include <cstring>

namespace sandtable::dis {

namespace {

// ------------------------------------------------- big-endian scalars

template <typename T>
T loadBE(const std::byte* p) {
  using U = std::conditional_t<sizeof(T) == 1, std::uint8_t,
                               std::conditional_t<sizeof(T) == 2, std::uint16_t,
                                                  std::conditional_t<sizeof(T) == 4, std::uint32_t, std::uint64_t>>>;
  U u = 0;
  for (std::size_t k = 0; k < sizeof(T); ++k) u = U((u << 8) | U(std::to_integer<std::uint8_t>(p[k])));
  return std::bit_cast<T>(u);
}

template <typename T>
void storeBE(std::byte* p, T value) {
  using U = std::conditional_t<sizeof(T) == 1, std::uint8_t,
                               std::conditional_t<sizeof(T) == 2, std::uint16_t,
                                                  std::conditional_t<sizeof(T) == 4, std::uint32_t, std::uint64_t>>>;
  U u = std::bit_cast<U>(value);
  for (std::size_t k = sizeof(T); k-- > 0;) {
    p[k] = std::byte(u & 0xff);
    u = U(u >> 8);
  }
}

// ------------------------------------------------------------ offsets

namespace header {
constexpr std::size_t version = 0, exercise = 1, type = 2, family = 3, timestamp = 4, length = 8, status = 10;
}
static_assert(header::status + 2 == kHeaderBytes);  // byte 11: padding

// Entity State PDU (IEEE 1278.1-2012 7.2.2; the same bytes in 1278.1a-1998 5.3.3.1).
namespace es {
constexpr std::size_t id = 12, force = 18, parameterCount = 19, type = 20, alternativeType = 28, velocity = 36,
                      location = 48, orientation = 72, appearance = 84, deadReckoning = 88, marking = 128,
                      capabilities = 140, parameters = 144;
}
static_assert(es::force == es::id + 6 && es::type == es::parameterCount + 1);
static_assert(es::alternativeType == es::type + 8 && es::velocity == es::alternativeType + 8);
static_assert(es::location == es::velocity + 12 && es::orientation == es::location + 24);
static_assert(es::appearance == es::orientation + 12 && es::deadReckoning == es::appearance + 4);
static_assert(es::marking == es::deadReckoning + 40 && es::capabilities == es::marking + 12);
static_assert(es::parameters == es::capabilities + 4 && es::parameters == kEntityStateBytes);

// Fire PDU (IEEE 1278.1-2012 7.3.2; 1278.1a-1998 5.3.4.1).
namespace fire {
constexpr std::size_t firing = 12, target = 18, munition = 24, event = 30, missionIndex = 36, location = 40,
                      descriptor = 64, velocity = 80, range = 92;
}
static_assert(fire::target == fire::firing + 6 && fire::munition == fire::target + 6 && fire::event == fire::munition + 6);
static_assert(fire::missionIndex == fire::event + 6 && fire::location == fire::missionIndex + 4);
static_assert(fire::descriptor == fire::location + 24 && fire::velocity == fire::descriptor + 16);
static_assert(fire::range == fire::velocity + 12 && fire::range + 4 == kFireBytes);

// Detonation PDU (IEEE 1278.1-2012 7.3.3; 1278.1a-1998 5.3.4.2).
namespace det {
constexpr std::size_t firing = 12, target = 18, munition = 24, event = 30, velocity = 36, location = 48,
                      descriptor = 72, entityLocation = 88, result = 100, parameterCount = 101, padding = 102,
                      parameters = 104;
}
static_assert(det::velocity == det::event + 6 && det::location == det::velocity + 12);
static_assert(det::descriptor == det::location + 24 && det::entityLocation == det::descriptor + 16);
static_assert(det::result == det::entityLocation + 12 && det::parameters == det::padding + 2);
static_assert(det::parameters == kDetonationBytes);
// Both warfare PDUs open with the same four ids at the same offsets.
static_assert(det::firing == fire::firing && det::target == fire::target && det::munition == fire::munition &&
              det::event == fire::event);

// Create Entity and Remove Entity PDUs (IEEE 1278.1-2012 7.5.2, 7.5.3;
// 1278.1a-1998 5.3.6.1, 5.3.6.2: the same bytes).
namespace req {
constexpr std::size_t originating = 12, receiving = 18, requestId = 24;
}
static_assert(req::receiving == req::originating + 6 && req::requestId == req::receiving + 6);
static_assert(req::requestId + 4 == kEntityRequestBytes);

// Point Object State PDU (IEEE 1278.1-2012 7.10.4).
namespace po {
constexpr std::size_t id = 12, referenced = 18, updateNumber = 24, force = 26, modifications = 27, type = 28,
                      location = 32, orientation = 56, appearance = 68, requester = 76, receiver = 80, padding = 84;
}
static_assert(po::referenced == po::id + 6 && po::updateNumber == po::referenced + 6);
static_assert(po::force == po::updateNumber + 2 && po::modifications == po::force + 1 && po::type == po::modifications + 1);
static_assert(po::location == po::type + 4 && po::orientation == po::location + 24);
static_assert(po::appearance == po::orientation + 12 && po::requester == po::appearance + 8);
static_assert(po::receiver == po::requester + 4 && po::padding == po::receiver + 4 && po::padding + 4 == kPointObjectBytes);

// Linear Object State PDU (IEEE 1278.1-2012 7.10.5) and its 64-byte linear
// segment parameter records (6.2.52).
namespace lo {
constexpr std::size_t id = 12, referenced = 18, updateNumber = 24, force = 26, segmentCount = 27, requester = 28,
                      receiver = 32, type = 36, segments = 40;
}
static_assert(lo::referenced == lo::id + 6 && lo::updateNumber == lo::referenced + 6 && lo::force == lo::updateNumber + 2);
static_assert(lo::segmentCount == lo::force + 1 && lo::requester == lo::segmentCount + 1);
static_assert(lo::receiver == lo::requester + 4 && lo::type == lo::receiver + 4 && lo::segments == lo::type + 4);
static_assert(lo::segments == kLinearObjectBytes);
// Both object PDUs open with the same ids, update number and force.
static_assert(lo::id == po::id && lo::referenced == po::referenced && lo::updateNumber == po::updateNumber &&
              lo::force == po::force);
namespace seg {
constexpr std::size_t number = 0, modification = 1, generalAppearance = 2, specificAppearance = 4, location = 8,
                      orientation = 32, length = 44, width = 48, height = 52, depth = 56, padding = 60;
}
static_assert(seg::specificAppearance == seg::generalAppearance + 2 && seg::location == seg::specificAppearance + 4);
static_assert(seg::orientation == seg::location + 24 && seg::length == seg::orientation + 12);
static_assert(seg::width == seg::length + 4 && seg::height == seg::width + 4 && seg::depth == seg::height + 4);
static_assert(seg::padding == seg::depth + 4 && seg::padding + 4 == kSegmentBytes);
static_assert(kLinearObjectBytes + kSegmentBytes * kMaxSegments <= kMaxPduBytes &&
              kLinearObjectBytes + kSegmentBytes * (kMaxSegments + 1) > kMaxPduBytes);

// Dead reckoning parameters, within their 40 bytes.
namespace dr {
constexpr std::size_t algorithm = 0, other = 1, acceleration = 16, angularVelocity = 28, bytes = 40;
}
static_assert(dr::acceleration == dr::other + 15 && dr::bytes == dr::angularVelocity + 12);

// ------------------------------------------------------------ records

void putType(std::byte* p, const EntityType& t) {
  storeBE(p + 0, t.kind);
  storeBE(p + 1, t.domain);
  storeBE(p + 2, t.country);
  storeBE(p + 4, t.category);
  storeBE(p + 5, t.subcategory);
  storeBE(p + 6, t.specific);
  storeBE(p + 7, t.extra);
}

EntityType getType(const std::byte* p) {
  return {loadBE<std::uint8_t>(p), loadBE<std::uint8_t>(p + 1), loadBE<std::uint16_t>(p + 2),
          loadBE<std::uint8_t>(p + 4), loadBE<std::uint8_t>(p + 5), loadBE<std::uint8_t>(p + 6),
          loadBE<std::uint8_t>(p + 7)};
}

void putVec(std::byte* p, const Vec3f& v) {
  storeBE(p, v.x);
  storeBE(p + 4, v.y);
  storeBE(p + 8, v.z);
}
Vec3f getVecF(const std::byte* p) { return {loadBE<float>(p), loadBE<float>(p + 4), loadBE<float>(p + 8)}; }

void putVec(std::byte* p, const Vec3d& v) {
  storeBE(p, v.x);
  storeBE(p + 8, v.y);
  storeBE(p + 16, v.z);
}
Vec3d getVecD(const std::byte* p) { return {loadBE<double>(p), loadBE<double>(p + 8), loadBE<double>(p + 16)}; }

/// Entity ids and event ids: three 16-bit numbers.
void putTriple(std::byte* p, std::uint16_t a, std::uint16_t b, std::uint16_t c) {
  storeBE(p, a);
  storeBE(p + 2, b);
  storeBE(p + 4, c);
}
void putId(std::byte* p, const EntityId& id) { putTriple(p, id.site, id.application, id.entity); }
/// An EntityId or an EventId.
template <typename Triple>
Triple getTriple(const std::byte* p) {
  return {loadBE<std::uint16_t>(p), loadBE<std::uint16_t>(p + 2), loadBE<std::uint16_t>(p + 4)};
}
EntityId getId(const std::byte* p) { return getTriple<EntityId>(p); }

void putDescriptor(std::byte* p, const MunitionDescriptor& d) {
  putType(p, d.munition);
  storeBE(p + 8, d.warhead);
  storeBE(p + 10, d.fuse);
  storeBE(p + 12, d.quantity);
  storeBE(p + 14, d.rate);
}
MunitionDescriptor getDescriptor(const std::byte* p) {
  return {getType(p), loadBE<std::uint16_t>(p + 8), loadBE<std::uint16_t>(p + 10), loadBE<std::uint16_t>(p + 12),
          loadBE<std::uint16_t>(p + 14)};
}

void putEuler(std::byte* p, const Euler& e) {
  storeBE(p, e.psi);
  storeBE(p + 4, e.theta);
  storeBE(p + 8, e.phi);
}
Euler getEuler(const std::byte* p) { return {loadBE<float>(p), loadBE<float>(p + 4), loadBE<float>(p + 8)}; }

void putAddress(std::byte* p, const SimulationAddress& a) {
  storeBE(p, a.site);
  storeBE(p + 2, a.application);
}
SimulationAddress getAddress(const std::byte* p) { return {loadBE<std::uint16_t>(p), loadBE<std::uint16_t>(p + 2)}; }

void putObjectType(std::byte* p, const ObjectType& t) {
  storeBE(p, t.domain);
  storeBE(p + 1, t.kind);
  storeBE(p + 2, t.category);
  storeBE(p + 3, t.subcategory);
}
ObjectType getObjectType(const std::byte* p) {
  return {loadBE<std::uint8_t>(p), loadBE<std::uint8_t>(p + 1), loadBE<std::uint8_t>(p + 2),
          loadBE<std::uint8_t>(p + 3)};
}

void putBytes(std::byte* p, std::span<const std::uint8_t> b) {
  for (std::size_t k = 0; k < b.size(); ++k) p[k] = std::byte(b[k]);
}
template <std::size_t N>
std::array<std::uint8_t, N> getBytes(const std::byte* p) {
  std::array<std::uint8_t, N> a{};
  for (std::size_t k = 0; k < N; ++k) a[k] = std::to_integer<std::uint8_t>(p[k]);
  return a;
}

void putHeader(std::byte* p, const Header& h) {
  storeBE(p + header::version, h.version);
  storeBE(p + header::exercise, h.exercise);
  storeBE(p + header::type, h.type);
  storeBE(p + header::family, h.family);
  storeBE(p + header::timestamp, h.timestamp);
  storeBE(p + header::length, h.length);
  // Version 6 has 16 bits of padding where version 7 has the status.
  storeBE(p + header::status, h.version >= kVersion7 ? h.status : std::uint8_t(0));
}

Header getHeader(const std::byte* p) {
  Header h;
  h.version = loadBE<std::uint8_t>(p + header::version);
  h.exercise = loadBE<std::uint8_t>(p + header::exercise);
  h.type = loadBE<std::uint8_t>(p + header::type);
  h.family = loadBE<std::uint8_t>(p + header::family);
  h.timestamp = loadBE<std::uint32_t>(p + header::timestamp);
  h.length = loadBE<std::uint16_t>(p + header::length);
  h.status = h.version >= kVersion7 ? loadBE<std::uint8_t>(p + header::status) : std::uint8_t(0);
  return h;
}

/// `count` variable parameter records (<= 255; their bytes checked by the caller).
std::vector<VariableParameter> getRecords(const std::byte* p, std::size_t count) {
  std::vector<VariableParameter> out(count);
  for (std::size_t k = 0; k < count; ++k) {
    const std::byte* r = p + k * kParameterBytes;
    out[k].recordType = loadBE<std::uint8_t>(r);
    out[k].data = getBytes<15>(r + 1);
  }
  return out;
}

/// The firing, target and munition ids and the event id of a Fire or
/// Detonation PDU (the same offsets in both).
template <typename Warfare>
void getWarfareIds(const std::byte* p, Warfare& w) {
  w.firing = getId(p + fire::firing);
  w.target = getId(p + fire::target);
  w.munition = getId(p + fire::munition);
  w.event = getTriple<EventId>(p + fire::event);
}

Fire getFire(const std::byte* p) {
  Fire f;
  getWarfareIds(p, f);
  f.fireMissionIndex = loadBE<std::uint32_t>(p + fire::missionIndex);
  f.location = getVecD(p + fire::location);
  f.descriptor = getDescriptor(p + fire::descriptor);
  f.velocity = getVecF(p + fire::velocity);
  f.range = loadBE<float>(p + fire::range);
  return f;
}

Detonation getDetonation(const std::byte* p, std::size_t count) {
  Detonation d;
  getWarfareIds(p, d);
  d.velocity = getVecF(p + det::velocity);
  d.location = getVecD(p + det::location);
  d.descriptor = getDescriptor(p + det::descriptor);
  d.entityLocation = getVecF(p + det::entityLocation);
  d.result = loadBE<std::uint8_t>(p + det::result);
  d.parameters = getRecords(p + det::parameters, count);
  return d;
}

EntityState getEntityState(const std::byte* p, std::size_t count) {
  EntityState e;
  e.id = getId(p + es::id);
  e.force = loadBE<std::uint8_t>(p + es::force);
  e.type = getType(p + es::type);
  e.alternativeType = getType(p + es::alternativeType);
  e.velocity = getVecF(p + es::velocity);
  e.location = getVecD(p + es::location);
  e.orientation = getEuler(p + es::orientation);
  e.appearance = loadBE<std::uint32_t>(p + es::appearance);
  const std::byte* d = p + es::deadReckoning;
  e.deadReckoning.algorithm = loadBE<std::uint8_t>(d + dr::algorithm);
  e.deadReckoning.other = getBytes<15>(d + dr::other);
  e.deadReckoning.acceleration = getVecF(d + dr::acceleration);
  e.deadReckoning.angularVelocity = getVecF(d + dr::angularVelocity);
  e.marking.characterSet = loadBE<std::uint8_t>(p + es::marking);
  for (std::size_t k = 0; k < e.marking.chars.size(); ++k) {
    e.marking.chars[k] = char(std::to_integer<std::uint8_t>(p[es::marking + 1 + k]));
  }
  e.capabilities = loadBE<std::uint32_t>(p + es::capabilities);
  e.parameters = getRecords(p + es::parameters, count);
  return e;
}

template <typename Request>
Request getRequest(const std::byte* p) {
  Request r;
  r.originating = getId(p + req::originating);
  r.receiving = getId(p + req::receiving);
  r.requestId = loadBE<std::uint32_t>(p + req::requestId);
  return r;
}

PointObjectState getPointObject(const std::byte* p) {
  PointObjectState o;
  o.id = getTriple<ObjectId>(p + po::id);
  o.referenced = getTriple<ObjectId>(p + po::referenced);
  o.updateNumber = loadBE<std::uint16_t>(p + po::updateNumber);
  o.force = loadBE<std::uint8_t>(p + po::force);
  o.modifications = loadBE<std::uint8_t>(p + po::modifications);
  o.type = getObjectType(p + po::type);
  o.location = getVecD(p + po::location);
  o.orientation = getEuler(p + po::orientation);
  o.appearance = loadBE<std::uint64_t>(p + po::appearance);
  o.requester = getAddress(p + po::requester);
  o.receiver = getAddress(p + po::receiver);
  return o;
}

LinearSegment getSegment(const std::byte* r) {
  LinearSegment s;
  s.number = loadBE<std::uint8_t>(r + seg::number);
  s.modification = loadBE<std::uint8_t>(r + seg::modification);
  s.generalAppearance = loadBE<std::uint16_t>(r + seg::generalAppearance);
  s.specificAppearance = loadBE<std::uint32_t>(r + seg::specificAppearance);
  s.location = getVecD(r + seg::location);
  s.orientation = getEuler(r + seg::orientation);
  s.length = loadBE<float>(r + seg::length);
  s.width = loadBE<float>(r + seg::width);
  s.height = loadBE<float>(r + seg::height);
  s.depth = loadBE<float>(r + seg::depth);
  return s;
}

/// `count` segments (<= kMaxSegments; their bytes checked by the caller).
LinearObjectState getLinearObject(const std::byte* p, std::size_t count) {
  LinearObjectState o;
  o.id = getTriple<ObjectId>(p + lo::id);
  o.referenced = getTriple<ObjectId>(p + lo::referenced);
  o.updateNumber = loadBE<std::uint16_t>(p + lo::updateNumber);
  o.force = loadBE<std::uint8_t>(p + lo::force);
  o.requester = getAddress(p + lo::requester);
  o.receiver = getAddress(p + lo::receiver);
  o.type = getObjectType(p + lo::type);
  o.segments.reserve(count);
  for (std::size_t k = 0; k < count; ++k) o.segments.push_back(getSegment(p + lo::segments + k * kSegmentBytes));
  return o;
}

std::string str(std::uint64_t v) { return std::to_string(v); }

}  // namespace

std::string Marking::text() const {
  std::size_t n = 0;
  while (n < chars.size() && chars[n] != '\0') ++n;
  return std::string(chars.data(), n);
}

Marking Marking::ascii(std::string_view s) {
  Marking m;
  for (std::size_t k = 0; k < m.chars.size() && k < s.size(); ++k) m.chars[k] = s[k];
  return m;
}

namespace {
// Both part records: byte 0 the record type, then one byte, a 16-bit
// part-attached-to, a 32-bit type, and 8 bytes of value (articulated: a
// 32-bit float and 32 bits of padding; attached: an entity type).
template <typename FillValue>
VariableParameter partRecord(std::uint8_t recordType, std::uint8_t flag, std::uint16_t attachedTo, std::uint32_t type,
                             FillValue fillValue) {
  std::array<std::byte, kParameterBytes> b{};
  storeBE(b.data() + 1, flag);
  storeBE(b.data() + 2, attachedTo);
  storeBE(b.data() + 4, type);
  fillValue(b.data() + 8);
  return {recordType, getBytes<15>(b.data() + 1)};
}
}  // namespace

VariableParameter toParameter(const ArticulatedPart& p) {
  return partRecord(0, p.change, p.attachedTo, p.parameterType, [&](std::byte* q) { storeBE(q, p.value); });
}

VariableParameter toParameter(const AttachedPart& p) {
  return partRecord(1, p.detached, p.attachedTo, p.station, [&](std::byte* q) { putType(q, p.type); });
}

namespace {
std::array<std::byte, kParameterBytes> recordBytes(const VariableParameter& v) {
  std::array<std::byte, kParameterBytes> b{};
  b[0] = std::byte(v.recordType);
  putBytes(b.data() + 1, v.data);
  return b;
}
void putRecords(std::byte* p, const std::vector<VariableParameter>& records) {
  for (std::size_t k = 0; k < records.size(); ++k) {
    const auto r = recordBytes(records[k]);
    std::memcpy(p + k * kParameterBytes, r.data(), r.size());
  }
}

template <typename Warfare>
void putWarfareIds(std::byte* p, const Warfare& w) {
  putId(p + fire::firing, w.firing);
  putId(p + fire::target, w.target);
  putId(p + fire::munition, w.munition);
  putTriple(p + fire::event, w.event.site, w.event.application, w.event.event);
}

Header typed(const Header& header, PduType type, Family family, std::size_t bytes) {
  Header h = header;
  h.type = std::uint8_t(type);
  h.family = std::uint8_t(family);
  h.length = std::uint16_t(bytes);
  return h;
}
}  // namespace

std::optional<ArticulatedPart> articulatedPart(const VariableParameter& v) {
  if (v.recordType != 0) return std::nullopt;
  const auto b = recordBytes(v);
  return ArticulatedPart{loadBE<std::uint8_t>(b.data() + 1), loadBE<std::uint16_t>(b.data() + 2),
                         loadBE<std::uint32_t>(b.data() + 4), loadBE<float>(b.data() + 8)};
}

std::optional<AttachedPart> attachedPart(const VariableParameter& v) {
  if (v.recordType != 1) return std::nullopt;
  const auto b = recordBytes(v);
  return AttachedPart{loadBE<std::uint8_t>(b.data() + 1), loadBE<std::uint16_t>(b.data() + 2),
                      loadBE<std::uint32_t>(b.data() + 4), getType(b.data() + 8)};
}

std::uint32_t timestamp(double secondsPastHour, bool absolute) {
  double s = std::fmod(secondsPastHour, 3600.0);
  if (!(s >= 0)) s = std::isfinite(s) ? s + 3600.0 : 0.0;
  // 2^31 units per hour, rounded down; an hour's last fraction stays in range.
  const auto units = std::min<std::uint64_t>(std::uint64_t(s * (2147483648.0 / 3600.0)), 0x7fffffffu);
  return std::uint32_t(units << 1) | (absolute ? 1u : 0u);
}

double timestampSeconds(std::uint32_t stamp) { return double(stamp >> 1) * (3600.0 / 2147483648.0); }

std::vector<std::byte> encode(const Header& header, const EntityState& e) {
  if (e.parameters.size() > 255) return {};
  const std::size_t bytes = kEntityStateBytes + kParameterBytes * e.parameters.size();
  std::vector<std::byte> out(bytes, std::byte{0});
  std::byte* p = out.data();
  putHeader(p, typed(header, PduType::entityState, Family::entityInformation, bytes));
  putId(p + es::id, e.id);
  storeBE(p + es::force, e.force);
  storeBE(p + es::parameterCount, std::uint8_t(e.parameters.size()));
  putType(p + es::type, e.type);
  putType(p + es::alternativeType, e.alternativeType);
  putVec(p + es::velocity, e.velocity);
  putVec(p + es::location, e.location);
  putEuler(p + es::orientation, e.orientation);
  storeBE(p + es::appearance, e.appearance);
  std::byte* d = p + es::deadReckoning;
  storeBE(d + dr::algorithm, e.deadReckoning.algorithm);
  putBytes(d + dr::other, e.deadReckoning.other);
  putVec(d + dr::acceleration, e.deadReckoning.acceleration);
  putVec(d + dr::angularVelocity, e.deadReckoning.angularVelocity);
  storeBE(p + es::marking, e.marking.characterSet);
  for (std::size_t k = 0; k < e.marking.chars.size(); ++k) p[es::marking + 1 + k] = std::byte(e.marking.chars[k]);
  storeBE(p + es::capabilities, e.capabilities);
  putRecords(p + es::parameters, e.parameters);
  return out;
}

std::vector<std::byte> encode(const Header& header, const Fire& f) {
  std::vector<std::byte> out(kFireBytes, std::byte{0});
  std::byte* p = out.data();
  putHeader(p, typed(header, PduType::fire, Family::warfare, kFireBytes));
  putWarfareIds(p, f);
  storeBE(p + fire::missionIndex, f.fireMissionIndex);
  putVec(p + fire::location, f.location);
  putDescriptor(p + fire::descriptor, f.descriptor);
  putVec(p + fire::velocity, f.velocity);
  storeBE(p + fire::range, f.range);
  return out;
}

std::vector<std::byte> encode(const Header& header, const Detonation& d) {
  if (d.parameters.size() > 255) return {};
  const std::size_t bytes = kDetonationBytes + kParameterBytes * d.parameters.size();
  std::vector<std::byte> out(bytes, std::byte{0});
  std::byte* p = out.data();
  putHeader(p, typed(header, PduType::detonation, Family::warfare, bytes));
  putWarfareIds(p, d);
  putVec(p + det::velocity, d.velocity);
  putVec(p + det::location, d.location);
  putDescriptor(p + det::descriptor, d.descriptor);
  putVec(p + det::entityLocation, d.entityLocation);
  storeBE(p + det::result, d.result);
  storeBE(p + det::parameterCount, std::uint8_t(d.parameters.size()));
  putRecords(p + det::parameters, d.parameters);
  return out;
}

namespace {
std::vector<std::byte> encodeRequest(const Header& header, PduType type, const EntityRequest& r) {
  std::vector<std::byte> out(kEntityRequestBytes, std::byte{0});
  std::byte* p = out.data();
  putHeader(p, typed(header, type, Family::simulationManagement, kEntityRequestBytes));
  putId(p + req::originating, r.originating);
  putId(p + req::receiving, r.receiving);
  storeBE(p + req::requestId, r.requestId);
  return out;
}

void putObjectId(std::byte* p, const ObjectId& id) { putTriple(p, id.site, id.application, id.object); }

void putSegment(std::byte* r, const LinearSegment& s) {
  storeBE(r + seg::number, s.number);
  storeBE(r + seg::modification, s.modification);
  storeBE(r + seg::generalAppearance, s.generalAppearance);
  storeBE(r + seg::specificAppearance, s.specificAppearance);
  putVec(r + seg::location, s.location);
  putEuler(r + seg::orientation, s.orientation);
  storeBE(r + seg::length, s.length);
  storeBE(r + seg::width, s.width);
  storeBE(r + seg::height, s.height);
  storeBE(r + seg::depth, s.depth);
}
}  // namespace

std::vector<std::byte> encode(const Header& header, const CreateEntity& c) {
  return encodeRequest(header, PduType::createEntity, c);
}

std::vector<std::byte> encode(const Header& header, const RemoveEntity& r) {
  return encodeRequest(header, PduType::removeEntity, r);
}

std::vector<std::byte> encode(const Header& header, const PointObjectState& o) {
  std::vector<std::byte> out(kPointObjectBytes, std::byte{0});
  std::byte* p = out.data();
  putHeader(p, typed(header, PduType::pointObjectState, Family::syntheticEnvironment, kPointObjectBytes));
  putObjectId(p + po::id, o.id);
  putObjectId(p + po::referenced, o.referenced);
  storeBE(p + po::updateNumber, o.updateNumber);
  storeBE(p + po::force, o.force);
  storeBE(p + po::modifications, o.modifications);
  putObjectType(p + po::type, o.type);
  putVec(p + po::location, o.location);
  putEuler(p + po::orientation, o.orientation);
  storeBE(p + po::appearance, o.appearance);
  putAddress(p + po::requester, o.requester);
  putAddress(p + po::receiver, o.receiver);
  return out;
}

std::vector<std::byte> encode(const Header& header, const LinearObjectState& o) {
  if (o.segments.size() > kMaxSegments) return {};
  const std::size_t bytes = kLinearObjectBytes + kSegmentBytes * o.segments.size();
  std::vector<std::byte> out(bytes, std::byte{0});
  std::byte* p = out.data();
  putHeader(p, typed(header, PduType::linearObjectState, Family::syntheticEnvironment, bytes));
  putObjectId(p + lo::id, o.id);
  putObjectId(p + lo::referenced, o.referenced);
  storeBE(p + lo::updateNumber, o.updateNumber);
  storeBE(p + lo::force, o.force);
  storeBE(p + lo::segmentCount, std::uint8_t(o.segments.size()));
  putAddress(p + lo::requester, o.requester);
  putAddress(p + lo::receiver, o.receiver);
  putObjectType(p + lo::type, o.type);
  for (std::size_t k = 0; k < o.segments.size(); ++k) putSegment(p + lo::segments + k * kSegmentBytes, o.segments[k]);
  return out;
}

Result<Pdu> decode(std::span<const std::byte> bytes, const std::string& sender) {
  auto fail = [&](std::size_t offset, const std::string& message) {
    return Problem{sender, offset, "dis: " + message};
  };
  if (bytes.size() < kHeaderBytes) {
    return fail(bytes.size(), "truncated: a PDU header needs 12 bytes, " + str(bytes.size()) + " arrived");
  }
  Pdu pdu;
  pdu.header = getHeader(bytes.data());
  const Header& h = pdu.header;
  if (h.version != kVersion6 && h.version != kVersion7) {
    return fail(header::version, "protocol version " + str(h.version) + " is not supported (6 or 7)");
  }
  if (h.length < kHeaderBytes || h.length > kMaxPduBytes) {
    return fail(header::length, "length " + str(h.length) + " is outside 12.." + str(kMaxPduBytes) + " bytes");
  }
  if (h.length > bytes.size()) {
    return fail(bytes.size(), "truncated: the header gives " + str(h.length) + " bytes, " + str(bytes.size()) +
                                  " arrived");
  }
  if (h.type == std::uint8_t(PduType::createEntity) || h.type == std::uint8_t(PduType::removeEntity)) {
    // Versions 6 and 7 lay both out alike (1278.1a-1998 5.3.6.1-2): decoded in either.
    if (h.length != kEntityRequestBytes) {
      return fail(header::length, std::string(h.type == std::uint8_t(PduType::createEntity) ? "a Create" : "a Remove") +
                                      " Entity PDU is 28 bytes; the length is " + str(h.length));
    }
    if (h.type == std::uint8_t(PduType::createEntity)) pdu.createEntity = getRequest<CreateEntity>(bytes.data());
    else pdu.removeEntity = getRequest<RemoveEntity>(bytes.data());
    return pdu;
  }
  // Version 6's object PDUs have another layout (a 6-byte object type, other
  // segment records): their header only, counted like an unknown type.
  if (h.type == std::uint8_t(PduType::pointObjectState) && h.version == kVersion7) {
    if (h.length != kPointObjectBytes) {
      return fail(header::length, "a Point Object State PDU is 88 bytes; the length is " + str(h.length));
    }
    pdu.pointObject = getPointObject(bytes.data());
    return pdu;
  }
  if (h.type == std::uint8_t(PduType::linearObjectState) && h.version == kVersion7) {
    if (h.length < kLinearObjectBytes) {
      return fail(header::length, "a Linear Object State PDU needs at least 40 bytes; the length is " + str(h.length));
    }
    // The count is one byte (255 at most) and must match the length, which is
    // at most kMaxPduBytes: at most kMaxSegments are read and allocated.
    const std::size_t n = std::to_integer<std::uint8_t>(bytes[lo::segmentCount]);
    if (h.length != kLinearObjectBytes + kSegmentBytes * n) {
      return fail(lo::segmentCount, str(n) + " linear segments need a length of " +
                                        str(kLinearObjectBytes + kSegmentBytes * n) + " bytes; the header gives " +
                                        str(h.length));
    }
    pdu.linearObject = getLinearObject(bytes.data(), n);
    return pdu;
  }
  if (h.type == std::uint8_t(PduType::fire)) {
    if (h.length != kFireBytes) return fail(header::length, "a Fire PDU is 96 bytes; the length is " + str(h.length));
    pdu.fire = getFire(bytes.data());
    return pdu;
  }
  if (h.type == std::uint8_t(PduType::detonation)) {
    if (h.length < kDetonationBytes) {
      return fail(header::length, "a Detonation PDU needs at least 104 bytes; the length is " + str(h.length));
    }
    const std::size_t n = std::to_integer<std::uint8_t>(bytes[det::parameterCount]);
    if (h.length != kDetonationBytes + kParameterBytes * n) {
      return fail(det::parameterCount, str(n) + " variable parameter records need a length of " +
                                           str(kDetonationBytes + kParameterBytes * n) + " bytes; the header gives " +
                                           str(h.length));
    }
    pdu.detonation = getDetonation(bytes.data(), n);
    return pdu;
  }
  if (h.type != std::uint8_t(PduType::entityState)) return pdu;  // counted by the receiver, not an error
  if (h.length < kEntityStateBytes) {
    return fail(header::length, "an Entity State PDU needs at least 144 bytes; the length is " + str(h.length));
  }
  const std::size_t count = std::to_integer<std::uint8_t>(bytes[es::parameterCount]);
  const std::size_t want = kEntityStateBytes + kParameterBytes * count;
  if (h.length != want) {
    return fail(es::parameterCount, str(count) + " variable parameter records need a length of " + str(want) +
                                        " bytes; the header gives " + str(h.length));
  }
  pdu.entityState = getEntityState(bytes.data(), count);
  return pdu;
}

}  // namespace sandtable::dis
