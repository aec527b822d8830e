// The network monitor (monitor.h, docs/DIS.md §7).
#include "sandtable/dis/monitor.h"

#include <algorithm>
#include <array>
#include <cctype>
#include <cstring>

namespace sandtable::dis {

namespace {

// SISO-REF-010's PDU type names, 0-72 (the same list as Open-DIS's enumeration).
constexpr std::array<std::string_view, 73> kTypeNames = {
    "Other", "Entity State", "Fire", "Detonation", "Collision", "Service Request", "Resupply Offer",
    "Resupply Received", "Resupply Cancel", "Repair Complete", "Repair Response", "Create Entity", "Remove Entity",
    "Start/Resume", "Stop/Freeze", "Acknowledge", "Action Request", "Action Response", "Data Query", "Set Data",
    "Data", "Event Report", "Comment", "Electromagnetic Emission", "Designator", "Transmitter", "Signal", "Receiver",
    "IFF", "Underwater Acoustic", "Supplemental Emission / Entity State", "Intercom Signal", "Intercom Control",
    "Aggregate State", "IsGroupOf", "Transfer Ownership", "IsPartOf", "Minefield State", "Minefield Query",
    "Minefield Data", "Minefield Response NACK", "Environmental Process", "Gridded Data", "Point Object State",
    "Linear Object State", "Areal Object State", "TSPI", "Appearance", "Articulated Parts", "LE Fire",
    "LE Detonation", "Create Entity-R", "Remove Entity-R", "Start/Resume-R", "Stop/Freeze-R", "Acknowledge-R",
    "Action Request-R", "Action Response-R", "Data Query-R", "Set Data-R", "Data-R", "Event Report-R", "Comment-R",
    "Record-R", "Set Record-R", "Record Query-R", "Collision-Elastic", "Entity State Update",
    "Directed Energy Fire", "Entity Damage Status", "Information Operations Action",
    "Information Operations Report", "Attribute"};

/// Types decode() gives a body for; the rest are counted as unknown.
bool decoded(std::uint8_t type) {
  return type == std::uint8_t(PduType::entityState) || type == std::uint8_t(PduType::fire) ||
         type == std::uint8_t(PduType::detonation);
}

/// The length a PDU's header gives when it can be trusted to find the next
/// PDU: a readable header of a known version, within what arrived.
std::size_t usableLength(std::span<const std::byte> rest) {
  if (rest.size() < kHeaderBytes) return 0;
  const auto version = std::to_integer<std::uint8_t>(rest[0]);
  if (version != kVersion6 && version != kVersion7) return 0;
  const std::size_t length = (std::size_t(std::to_integer<std::uint8_t>(rest[8])) << 8) |
                             std::to_integer<std::uint8_t>(rest[9]);
  return length >= kHeaderBytes && length <= rest.size() ? length : 0;
}

/// A reason to count by: the decoder's message without its stage prefix,
/// every run of digits as N ("length N is outside N..N bytes").
std::string reasonOf(const std::string& message) {
  std::string_view m = message;
  if (m.starts_with("dis: ")) m.remove_prefix(5);
  std::string out;
  for (std::size_t k = 0; k < m.size(); ++k) {
    if (std::isdigit(static_cast<unsigned char>(m[k]))) {
      while (k + 1 < m.size() && std::isdigit(static_cast<unsigned char>(m[k + 1]))) ++k;
      out += 'N';
    } else {
      out += m[k];
    }
  }
  return out;
}

Vec3d turn(const Matrix3& r, const Vec3d& v) {
  return {r[0][0] * v.x + r[0][1] * v.y + r[0][2] * v.z, r[1][0] * v.x + r[1][1] * v.y + r[1][2] * v.z,
          r[2][0] * v.x + r[2][1] * v.y + r[2][2] * v.z};
}

}  // namespace

std::string_view pduTypeName(std::uint8_t type) { return type < kTypeNames.size() ? kTypeNames[type] : ""; }

Monitor::Monitor(MonitorOptions options) : options_(std::move(options)) {}

std::optional<double> Monitor::firstTime() const { return firstS_; }

Monitor::Sender* Monitor::sender(const SenderKey& key, double timeS) {
  auto it = senders_.find(key);
  if (it == senders_.end()) {
    if (senders_.size() >= options_.maxSenders) {
      ++capped_.senders;
      return nullptr;
    }
    it = senders_.emplace(key, Sender{}).first;
    it->second.firstS = it->second.lastS = timeS;
  }
  return &it->second;
}

void Monitor::touch(Sender& s, double timeS) {
  s.largestGapS = std::max(s.largestGapS, timeS - s.lastS);  // 0 for a new sender: lastS is its first time
  s.lastS = std::max(s.lastS, timeS);
}

void Monitor::countPdu(Sender& s, std::uint8_t type, double timeS) {
  touch(s, timeS);
  ++s.pdus;
  ++s.types[type];
  if (!decoded(type)) ++s.unknownTypes;
}

void Monitor::add(const Datagram& d) {
  if (!firstS_) firstS_ = d.timeS;
  lastS_ = std::max(lastS_, d.timeS);
  ++datagrams_;
  const std::span<const std::byte> bytes(d.bytes);
  const std::string from = d.sender.text();
  std::size_t offset = 0;
  do {
    const auto rest = bytes.subspan(offset);
    // The exercise filter looks only at byte 1, so another exercise's
    // traffic, malformed or not, never reaches the counts.
    if (options_.exercise && rest.size() >= 2 && std::to_integer<std::uint8_t>(rest[1]) != *options_.exercise) {
      ++otherExercise_;
      const std::size_t length = usableLength(rest);
      if (length == 0) return;
      offset += length;
      continue;
    }
    auto pdu = decode(rest, from);
    if (!pdu.ok()) {
      malformed(d, offset, pdu.problems().front());
      const std::size_t length = usableLength(rest);
      if (length == 0) return;
      offset += length;
      continue;
    }
    apply(d, pdu.value());
    offset += pdu->header.length;
  } while (offset < bytes.size());
}

void Monitor::malformed(const Datagram& d, std::size_t offset, const Problem& problem) {
  ++malformed_;
  if (Sender* s = sender({d.sender, false, 0, 0}, d.timeS)) {
    touch(*s, d.timeS);
    ++s->malformed;
  }
  const std::string reason = reasonOf(problem.message);
  auto it = reasons_.find(reason);
  if (it == reasons_.end()) {
    if (reasons_.size() >= options_.maxReasons) {
      ++capped_.reasons;
      return;
    }
    it = reasons_.emplace(reason, Reason{}).first;
  }
  Reason& r = it->second;
  ++r.count;
  if (r.examples.size() < options_.examplesPerReason) {
    r.examples.push_back({datagrams_, d.timeS, d.sender, offset + std::size_t(problem.offset), problem.message});
  }
}

void Monitor::apply(const Datagram& d, const Pdu& pdu) {
  ++pdus_;
  const std::uint8_t type = pdu.header.type;
  SenderKey key{d.sender, false, 0, 0};
  auto bySite = [&](std::uint16_t site, std::uint16_t application) {
    key.hasSite = true;
    key.site = site;
    key.application = application;
  };
  if (pdu.entityState) bySite(pdu.entityState->id.site, pdu.entityState->id.application);
  if (pdu.fire) bySite(pdu.fire->firing.site, pdu.fire->firing.application);
  if (pdu.detonation) bySite(pdu.detonation->firing.site, pdu.detonation->firing.application);
  if (!decoded(type)) ++unknownTypes_;
  Sender* s = sender(key, d.timeS);
  if (s) countPdu(*s, type, d.timeS);
  if (pdu.fire) {
    ++fires_;
    if (s) ++s->fires;
  }
  if (pdu.detonation) {
    ++detonations_;
    if (s) ++s->detonations;
  }
  if (pdu.entityState) applyEntityState(d, pdu.header.exercise, *pdu.entityState);
}

void Monitor::applyEntityState(const Datagram& d, std::uint8_t exercise, const EntityState& es) {
  const EntityKey key{exercise, es.id.site, es.id.application, es.id.entity};
  auto it = entities_.find(key);
  if (it == entities_.end()) {
    if (entities_.size() >= options_.maxEntities) {
      ++capped_.entities;
      return;
    }
    Entity e;
    e.owner = d.sender;
    e.latest = es;
    e.latestS = e.firstS = d.timeS;
    it = entities_.emplace(key, std::move(e)).first;
  } else if (it->second.owner != d.sender) {
    // A second address claims the id: counted and listed; the first
    // owner's track is kept, so one rogue sender cannot move the entity.
    ++conflictPdus_;
    const ConflictKey ck{key, d.sender};
    auto c = conflicts_.find(ck);
    if (c != conflicts_.end()) {
      ++c->second;
    } else if (conflicts_.size() < options_.maxConflictsListed) {
      conflicts_.emplace(ck, 1);
    } else {
      ++capped_.conflicts;
    }
    return;
  } else {
    Entity& e = it->second;
    e.largestGapS = std::max(e.largestGapS, d.timeS - e.latestS);
    if (d.timeS >= e.latestS) {
      e.previous = std::move(e.latest);
      e.previousS = e.latestS;
      e.latest = es;
      e.latestS = d.timeS;
    }
  }
  Entity& e = it->second;
  ++e.updates;
  const std::uint8_t a = es.deadReckoning.algorithm;
  e.algorithms[a / 64] |= std::uint64_t(1) << (a % 64);
}

EntityStateAt Monitor::reckon(const EntityState& es, double pduTimeS, double atS) {
  EntityStateAt out;
  out.pduTimeS = pduTimeS;
  out.atS = atS;
  out.motion = advance(motionOf(es), atS - pduTimeS);
  out.location = out.motion.position;
  const auto angles = rotationAngles(out.motion.orientation);
  out.orientation = {float(angles[0]), float(angles[1]), float(angles[2])};
  const std::uint8_t a = out.motion.algorithm;
  out.worldVelocity = a >= 6 && a <= 9 ? turn(out.motion.orientation, out.motion.velocity) : out.motion.velocity;
  return out;
}

std::optional<EntityStateAt> Monitor::state(std::uint8_t exercise, EntityId id, double atS) const {
  const auto it = entities_.find({exercise, id.site, id.application, id.entity});
  if (it == entities_.end()) return std::nullopt;
  const Entity& e = it->second;
  if (atS >= e.latestS) return reckon(e.latest, e.latestS, atS);
  if (e.previous && atS >= e.previousS) return reckon(*e.previous, e.previousS, atS);
  return std::nullopt;
}

std::optional<EntityStateAt> Monitor::state(EntityId id, double atS) const {
  for (unsigned x = 0; x < 256; ++x) {
    if (entities_.contains({std::uint8_t(x), id.site, id.application, id.entity})) {
      return state(std::uint8_t(x), id, atS);
    }
  }
  return std::nullopt;
}

Report Monitor::report() const { return build(lastS_); }
Report Monitor::report(double nowS) const { return build(nowS); }

Report Monitor::build(double nowS) const {
  Report r;
  r.firstS = firstS_.value_or(nowS);
  r.lastS = nowS;
  r.windowS = std::max(0.0, r.lastS - r.firstS);
  const auto rate = [&](std::uint64_t n) { return r.windowS > 0 ? double(n) / r.windowS : 0.0; };
  r.datagrams = datagrams_;
  r.pdus = pdus_;
  r.otherExercise = otherExercise_;
  r.unknownTypes = unknownTypes_;
  r.fires = fires_;
  r.detonations = detonations_;
  r.malformed = malformed_;
  r.conflictPdus = conflictPdus_;
  r.capped = capped_;

  for (const auto& [reason, v] : reasons_) r.reasons.push_back({reason, v.count, v.examples});
  std::stable_sort(r.reasons.begin(), r.reasons.end(),
                   [](const ReasonReport& a, const ReasonReport& b) { return a.count > b.count; });

  for (const auto& [key, e] : entities_) {
    EntityReport x;
    x.exercise = key.exercise;
    x.id = {key.site, key.application, key.entity};
    x.sender = e.owner;
    const EntityState& s = e.latest;
    x.type = s.type;
    x.force = s.force;
    x.marking = s.marking.text();
    x.appearance = s.appearance;
    for (const VariableParameter& p : s.parameters) {
      if (auto a = articulatedPart(p)) x.articulated.push_back(*a);
      else if (auto b = attachedPart(p)) x.attached.push_back(*b);
      else ++x.otherRecords;
    }
    for (unsigned a = 0; a < 256; ++a) {
      if ((e.algorithms[a / 64] >> (a % 64)) & 1u) x.algorithms.push_back(std::uint8_t(a));
    }
    x.algorithm = s.deadReckoning.algorithm;
    x.updates = e.updates;
    x.firstS = e.firstS;
    x.lastS = e.latestS;
    x.largestGapS = e.largestGapS;
    x.location = s.location;
    x.orientation = s.orientation;
    x.velocity = s.velocity;
    r.entities.push_back(std::move(x));
  }

  // Each sender's entities and their largest heartbeat gap, in one pass.
  std::map<SenderKey, std::pair<std::uint64_t, double>> published;
  for (const EntityReport& e : r.entities) {
    auto& [n, gap] = published[{e.sender, true, e.id.site, e.id.application}];
    ++n;
    gap = std::max(gap, e.largestGapS);
  }
  for (const auto& [key, s] : senders_) {
    SenderReport x;
    x.address = key.address;
    x.hasSiteApplication = key.hasSite;
    x.site = key.site;
    x.application = key.application;
    x.pdus = s.pdus;
    x.ratePerS = rate(s.pdus);
    for (const auto& [type, n] : s.types) x.types.push_back({type, n, rate(n)});
    x.unknownTypes = s.unknownTypes;
    x.malformed = s.malformed;
    x.fires = s.fires;
    x.detonations = s.detonations;
    x.firstS = s.firstS;
    x.lastS = s.lastS;
    x.largestGapS = s.largestGapS;
    if (const auto it = published.find(key); it != published.end()) {
      x.entities = it->second.first;
      x.largestHeartbeatGapS = it->second.second;
    }
    r.senders.push_back(std::move(x));
  }

  for (const auto& [key, n] : conflicts_) {
    const Entity& owner = entities_.at(key.entity);
    r.conflicts.push_back({key.entity.exercise,
                           {key.entity.site, key.entity.application, key.entity.entity},
                           owner.owner,
                           key.other,
                           n});
  }
  return r;
}

}  // namespace sandtable::dis
