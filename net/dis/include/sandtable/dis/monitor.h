#pragma once
// The network monitor (seed XI.B.2: NPSStealth in Zealous Pursuit found
// "when, who, how often, and what types of packets" broke an exercise):
// fed datagrams, it keeps per sender the PDU counts by type and their
// rates, unknown types, malformed PDUs with the decoder's reason and byte
// offset, the entities each sender publishes (type, force, marking,
// articulated and attached parts, dead-reckoning algorithms, heartbeat
// gaps), entity ids claimed by two sender addresses, and Fire and
// Detonation counts; and it dead reckons any entity to a given time.
//
// A sender is the datagram's source address together with the site and
// application its PDUs carry (the entity id of an Entity State PDU, the
// firing entity's of a Fire or Detonation PDU). PDUs that carry no id this
// library reads (types it does not decode, and malformed PDUs) go to the
// address's row without a site:application.
//
// Times are the datagrams' (Datagram::timeS: the capture's clock or the
// receiver's), not the PDUs' timestamps, which senders set from clocks of
// their own; gaps, rates and dead reckoning all use arrival times.
//
// Memory is bounded: senders, entities, malformed reasons, the examples of
// each reason and the listed id conflicts are capped (MonitorOptions);
// what passes a cap is counted, never stored. Per entity the monitor keeps
// the latest Entity State PDU and the one before it, enough for state() at
// any time from the earlier one on; to dead reckon at a time long past, feed
// the datagrams up to that time and ask then (`sandtable dis inspect --at`
// does so in one pass over the capture).
//
// Thread safety: a Monitor is a plain object; one thread at a time (the
// live monitor feeds it from the receive loop and reports from the same
// thread). Report values are plain structs.
#include <array>
#include <cstddef>
#include <cstdint>
#include <map>
#include <optional>
#include <string>
#include <string_view>
#include <vector>

#include "sandtable/dis/datagram.h"
#include "sandtable/dis/dead_reckoning.h"
#include "sandtable/dis/pdu.h"

namespace sandtable::dis {

struct MonitorOptions {
  std::optional<std::uint8_t> exercise;  ///< only this exercise's PDUs; others are counted as ignored
  std::size_t maxSenders = 1024;
  std::size_t maxEntities = 100000;
  std::size_t maxReasons = 64;          ///< distinct malformed reasons kept
  std::size_t examplesPerReason = 3;
  std::size_t maxConflictsListed = 64;  ///< entity ids claimed by two addresses, listed
};

/// The standard's name of a PDU type (SISO-REF-010, 1-72), "" past it.
std::string_view pduTypeName(std::uint8_t type);

/// One PDU type's count from one sender.
struct TypeCount {
  std::uint8_t type = 0;
  std::uint64_t count = 0;
  double ratePerS = 0;  ///< count over the report's window
};

struct SenderReport {
  Address address;
  bool hasSiteApplication = false;  ///< false: the row of PDUs without ids (unknown types, malformed)
  std::uint16_t site = 0, application = 0;
  std::uint64_t pdus = 0;           ///< decoded PDUs (malformed ones apart)
  double ratePerS = 0;              ///< pdus over the report's window
  std::vector<TypeCount> types;     ///< by type number
  std::uint64_t unknownTypes = 0;   ///< PDUs of types this library does not decode (not 1, 2, 3)
  std::uint64_t malformed = 0;
  std::uint64_t fires = 0, detonations = 0;
  std::uint64_t entities = 0;       ///< entities this sender publishes (tracked ones)
  double firstS = 0, lastS = 0;
  double largestGapS = 0;           ///< between consecutive PDUs of this sender
  double largestHeartbeatGapS = 0;  ///< the largest of its entities' gaps
};

struct EntityReport {
  std::uint8_t exercise = 0;
  EntityId id;
  Address sender;                   ///< the address that first claimed the id
  EntityType type;
  std::uint8_t force = 0;
  std::string marking;
  std::uint32_t appearance = 0;
  std::vector<ArticulatedPart> articulated;  ///< as last seen
  std::vector<AttachedPart> attached;        ///< as last seen
  std::uint64_t otherRecords = 0;            ///< variable parameter records of other types, last seen
  std::vector<std::uint8_t> algorithms;      ///< dead-reckoning algorithms used, ascending
  std::uint8_t algorithm = 0;                ///< the last PDU's
  std::uint64_t updates = 0;                 ///< Entity State PDUs
  double firstS = 0, lastS = 0;
  double largestGapS = 0;                    ///< the largest heartbeat gap
  // The last PDU's kinematics, as sent.
  Vec3d location;
  Euler orientation;
  Vec3f velocity;
};

struct MalformedExample {
  std::uint64_t datagram = 0;  ///< 1-based number of the datagram fed
  double timeS = 0;
  Address sender;
  std::size_t offset = 0;      ///< byte offset of the problem in the datagram
  std::string message;         ///< the decoder's words
};

struct ReasonReport {
  std::string reason;          ///< the decoder's message with every number as N
  std::uint64_t count = 0;
  std::vector<MalformedExample> examples;
};

/// An entity id claimed by a second sender address.
struct ConflictReport {
  std::uint8_t exercise = 0;
  EntityId id;
  Address owner, other;
  std::uint64_t pdus = 0;      ///< the other address's Entity State PDUs for the id
};

/// What passed a cap: counted, not stored.
struct CapCounts {
  std::uint64_t senders = 0;    ///< PDUs from senders past maxSenders
  std::uint64_t entities = 0;   ///< Entity State PDUs of entities past maxEntities
  std::uint64_t reasons = 0;    ///< malformed PDUs whose reason came past maxReasons
  std::uint64_t conflicts = 0;  ///< conflicting ids past maxConflictsListed
};

struct Report {
  double firstS = 0, lastS = 0;    ///< first datagram, and the report's time
  double windowS = 0;              ///< lastS - firstS: what rates divide by
  std::uint64_t datagrams = 0;
  std::uint64_t pdus = 0;          ///< decoded PDUs (malformed ones apart)
  std::uint64_t otherExercise = 0; ///< PDUs ignored by the exercise filter
  std::uint64_t unknownTypes = 0, fires = 0, detonations = 0;
  std::uint64_t malformed = 0;
  std::vector<ReasonReport> reasons;     ///< most frequent first
  std::vector<SenderReport> senders;     ///< by address, then site:application
  std::vector<EntityReport> entities;    ///< by exercise, then id
  std::uint64_t conflictPdus = 0;        ///< Entity State PDUs for an id another address owns
  std::vector<ConflictReport> conflicts;
  CapCounts capped;
};

/// An entity dead reckoned to a time.
struct EntityStateAt {
  double pduTimeS = 0;    ///< arrival of the PDU it is reckoned from
  double atS = 0;
  Motion motion;          ///< at atS
  Vec3d location;         ///< ECEF metres
  Euler orientation;      ///< psi, theta, phi of motion.orientation
  Vec3d worldVelocity;    ///< ECEF m/s (body-axis velocities turned into the world)
};

class Monitor {
 public:
  explicit Monitor(MonitorOptions options = {});

  /// Counts and applies every PDU in `d` (back to back; each header's
  /// length says where the next starts). After a malformed PDU whose
  /// header still gives a usable length the next PDU is read; otherwise
  /// the rest of the datagram is dropped with it.
  void add(const Datagram& d);

  /// The report at the last datagram's time, or at `nowS` (live: rates
  /// over the time up to now).
  Report report() const;
  Report report(double nowS) const;

  /// Entity `id` of `exercise` dead reckoned to `atS` from the latest kept
  /// Entity State PDU that arrived at or before atS; empty for an unknown
  /// entity or when atS is before every kept PDU.
  std::optional<EntityStateAt> state(std::uint8_t exercise, EntityId id, double atS) const;
  /// The same in the first exercise (lowest number) that has the id.
  std::optional<EntityStateAt> state(EntityId id, double atS) const;

  /// The time of the first datagram fed, empty before one.
  std::optional<double> firstTime() const;

 private:
  struct SenderKey {
    Address address;
    bool hasSite = false;
    std::uint16_t site = 0, application = 0;
    auto operator<=>(const SenderKey&) const = default;
  };
  struct Sender {
    std::map<std::uint8_t, std::uint64_t> types;
    std::uint64_t pdus = 0, unknownTypes = 0, malformed = 0, fires = 0, detonations = 0;
    double firstS = 0, lastS = 0, largestGapS = 0;
  };
  struct EntityKey {
    std::uint8_t exercise = 0;
    std::uint16_t site = 0, application = 0, entity = 0;
    auto operator<=>(const EntityKey&) const = default;
  };
  struct Entity {
    Address owner;
    EntityState latest;
    double latestS = 0;
    std::optional<EntityState> previous;
    double previousS = 0;
    std::uint64_t updates = 0;
    double firstS = 0, largestGapS = 0;
    std::array<std::uint64_t, 4> algorithms{};  // a 256-bit set
  };
  struct Reason {
    std::uint64_t count = 0;
    std::vector<MalformedExample> examples;
  };
  struct ConflictKey {
    EntityKey entity;
    Address other;
    auto operator<=>(const ConflictKey&) const = default;
  };

  /// The sender's counters, or null past the cap (counted).
  Sender* sender(const SenderKey& key, double timeS);
  static void touch(Sender& s, double timeS);
  void countPdu(Sender& s, std::uint8_t type, double timeS);
  void malformed(const Datagram& d, std::size_t offset, const Problem& problem);
  void apply(const Datagram& d, const Pdu& pdu);
  void applyEntityState(const Datagram& d, std::uint8_t exercise, const EntityState& es);
  static EntityStateAt reckon(const EntityState& es, double pduTimeS, double atS);
  Report build(double nowS) const;

  MonitorOptions options_;
  std::optional<double> firstS_;
  double lastS_ = 0;
  std::uint64_t datagrams_ = 0, pdus_ = 0, otherExercise_ = 0, unknownTypes_ = 0, fires_ = 0, detonations_ = 0,
                malformed_ = 0, conflictPdus_ = 0;
  CapCounts capped_;
  std::map<SenderKey, Sender> senders_;
  std::map<EntityKey, Entity> entities_;
  std::map<std::string, Reason> reasons_;
  std::map<ConflictKey, std::uint64_t> conflicts_;
};

}  // namespace sandtable::dis
