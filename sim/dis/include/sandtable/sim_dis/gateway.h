#pragma once
// The simulation on a DIS network (seed VIII.C "network entity" and X;
// docs/DIS.md §11): before each step the gateway applies every PDU that
// arrived (remote entities appear, move, die and leave; remote fires fly
// as munitions; a Detonation that names a local entity kills it), and
// after each step it publishes the local entities that need a PDU and the
// step's fires and detonations.
//
// Terrain edits travel as synthetic-environment objects (object_tracker.h,
// docs/DIS.md §14): publishEdit sends a local edit now and on the
// heartbeat after, and returns the edit to apply locally (the one
// receivers make); the edits other participants publish are queued, each
// sender's in its order, for takeReceivedEdits, which the caller drains
// each step and applies in its editor, in that order. The gateway applies
// no edit itself.
//
// The transport is the caller's: `drain` hands over the datagrams that
// arrived (a dis::Receiver's, a capture's, a test's) and `send` takes one
// encoded PDU. A gateway with publish off is a stealth watcher (fly --dis).
// Remote entities are simulation entities with Controller::remote, so
// local ones collide with them, see their munitions and shoot at them.
//
// Thread safety: the gateway belongs to the thread that steps its
// simulation; its hooks run there (sim::StepHost).
#include <cstdint>
#include <functional>
#include <map>
#include <span>
#include <string>
#include <vector>

#include "sandtable/dis/datagram.h"
#include "sandtable/dis/pdu.h"
#include "sandtable/formats/dis_icons.h"
#include "sandtable/sim/simulation.h"
#include "sandtable/sim/step_host.h"
#include "sandtable/sim_dis/object_tracker.h"
#include "sandtable/sim_dis/publisher.h"
#include "sandtable/sim_dis/remote.h"

namespace sandtable::sim_dis {

struct GatewayOptions {
  std::uint8_t exercise = 1;
  std::uint16_t site = 1, application = 1;  ///< this simulation's DIS address
  bool publish = true;                      ///< false: watch only (the stealth viewer)
  /// Timestamps: absolute (UTC time past the hour, real-time runs with
  /// synchronised clocks; receivers then dead reckon from the PDU's own
  /// time) or relative (simulation time past the hour; receivers use the
  /// arrival time).
  bool absoluteTime = false;
  PublishOptions publishing;
  RemoteOptions remote;
  TrackerOptions objects;  ///< terrain edits as DIS objects: the heartbeat
};

/// Why PDUs were not applied, and what was.
struct GatewayCounters {
  std::uint64_t datagrams = 0, pdus = 0;
  std::uint64_t otherExercise = 0;  ///< ignored: another exercise
  std::uint64_t own = 0;            ///< ignored: our own site and application (a broadcast echo)
  std::uint64_t malformed = 0;      ///< refused by the decoder
  std::uint64_t unknownType = 0;    ///< a type the gateway does not apply (counted, not an error)
  std::uint64_t entityStates = 0, fires = 0, detonations = 0, removes = 0;
  std::uint64_t objects = 0;        ///< Point and Linear Object State PDUs handed to the tracker (its counters say more)
  std::uint64_t hitsTaken = 0;      ///< local entities killed by remote detonations
  std::uint64_t unknownIcons = 0;   ///< remote entities given a fallback icon (no `dis` pattern matched)
  std::uint64_t notAdded = 0;       ///< remote entities off this database
  std::uint64_t sentPdus = 0, sentBytes = 0;
  std::string lastMalformed;        ///< the decoder's last message (sender and offset)
};

/// A remote entity that left (deactivated, removed or silent): where its
/// last PDU put it.
struct Departed {
  dis::EntityId id;
  std::string marking;
  Eigen::Vector3d position = Eigen::Vector3d::Zero();  ///< frame; the last PDU's location, not dead reckoned
  const char* why = "";                                 ///< "deactivated", "removed", "timed out"
};

class Gateway {
 public:
  using Drain = std::function<void(std::vector<dis::Datagram>&)>;
  using Send = std::function<void(std::span<const std::byte>)>;

  Gateway(sim::Simulation& simulation, DisFrame frame, GatewayOptions options, Drain drain, Send send);

  /// Adds the gateway's hooks to `host`: beforeStep, afterStep.
  void attach(sim::StepHost& host);
  void beforeStep();
  void afterStep();
  /// Applies datagrams now (what beforeStep does with the drained ones).
  void apply(const std::vector<dis::Datagram>& datagrams);
  /// Retires every local entity published (the end of a run): a
  /// deactivating Entity State PDU and a Remove Entity PDU each.
  void retireAll();

  /// Publishes local terrain edit `e` (a crater, berm or ditch; its time
  /// the simulation's): its object PDU goes out now and on every heartbeat
  /// after (afterStep). Returns the edit as receivers make it
  /// (asReceived): apply that one, not `e`, so that both ends hold the
  /// same ground. Refuses what ObjectTracker::publish refuses, and any
  /// edit when publish is off.
  Result<edit::Edit> publishEdit(const edit::Edit& e);
  /// The remote edits that arrived since the last call (each object id and
  /// update number once), each sender's in the order it applied them
  /// (ObjectTracker: a later one waits for an earlier one lost); the caller
  /// applies them in this order.
  std::vector<edit::Edit> takeReceivedEdits();
  const ObjectTracker& objects() const { return objects_; }

  /// The wall clock in seconds past the hour (absolute timestamps); tests
  /// replace it.
  void setWallClock(std::function<double()> secondsPastHour) { wall_ = std::move(secondsPastHour); }

  const GatewayCounters& counters() const { return counters_; }
  const RemoteEntities& remotes() const { return remotes_; }
  RemoteEntities& remotes() { return remotes_; }
  const Publisher& publisher() const { return publisher_; }
  /// The last kDepartedKept remote entities that left, oldest first.
  const std::vector<Departed>& departed() const { return departed_; }
  static constexpr std::size_t kDepartedKept = 4096;
  /// The DIS id of a local entity, and the simulation id behind a DIS id
  /// (local or remote; UINT32_MAX when none).
  dis::EntityId disId(std::uint32_t simId) const;
  std::uint32_t simIdOf(const dis::EntityId& id) const;

 private:
  void applyPdu(const dis::Pdu& pdu, const dis::Address& sender);
  void applyEntityState(const dis::Pdu& pdu, const dis::Address& sender);
  void applyFire(const dis::Fire& f);
  void applyDetonation(const dis::Detonation& d);
  void applyRemove(const dis::EntityId& id);
  void depart(const RemoteEntity& r, const dis::EntityState& last, const char* why);
  /// A deactivating Entity State PDU and a Remove Entity PDU for a local entity.
  void retire(std::uint32_t simId);
  void syncRemotes();
  void placeRemote(RemoteEntity& r);
  void flyRemoteMunitions();
  void publishEntities();
  void publishEvents();
  void sendPdu(std::span<const std::byte> bytes);
  dis::Header header() const;
  double pduTime(const dis::Header& h) const;
  Identity identityOf(const sim::Entity& e) const;
  std::uint16_t iconFor(const dis::EntityType& t);

  sim::Simulation& sim_;
  GatewayOptions options_;
  Drain drain_;
  Send send_;
  RemoteEntities remotes_;
  Publisher publisher_;
  DisFrame frame_;
  ObjectTracker objects_;
  std::vector<edit::Edit> receivedEdits_;
  GatewayCounters counters_;
  std::function<double()> wall_;
  iconpack::DisIconMap icons_;
  std::vector<dis::Datagram> inbox_;
  std::size_t eventCursor_ = 0;
  std::uint32_t requests_ = 0;
  /// Remote munitions in flight, by their Fire's event id.
  std::map<std::uint64_t, std::uint32_t> remoteRounds_;
  std::map<std::uint32_t, double> roundLaunchedS_;
  /// Local entities published, to retire the ones removed.
  std::map<std::uint32_t, bool> published_;
  std::vector<Departed> departed_;
};

}  // namespace sandtable::sim_dis
