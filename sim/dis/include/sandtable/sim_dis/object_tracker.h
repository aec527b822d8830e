#pragma once
// The terrain objects of one DIS participant (issue 37; docs/DIS.md §14):
// the edits it published, re-sent on a heartbeat so that a receiver that
// joins late or lost a datagram converges to the same ground, and the
// edits it received from others, each applied once.
//
// Publishing: the object's PDU is sent at once and then once per
// heartbeatS (the seed's 5 s) in a round robin over every published
// object, spread evenly over the interval: n objects go out at n /
// heartbeatS a second (10,000 at 60 Hz is 34 a step), never in a burst.
// A heartbeat is the same bytes as the first PDU, its timestamp included,
// so a late receiver reconstructs the same edit time (objects.h).
//
// Receiving: an object is known by its id and update number. A pair seen
// before (a heartbeat, a copy) yields nothing. A pair not seen before
// yields its edit; when the object id was known with another update
// number (a sender that extended a berm, or one whose object numbers
// wrapped), the new state is a NEW edit with its own id (update << 16 |
// object), applied on top of the old one and counted in `updates`: edits
// are never undone here.
//
// Order: overlapping edits applied in another order give other floats,
// so a receiver must apply one sender's edits in the order the sender
// applied them, whatever order loss and heartbeats bring them in. Each
// published object references (the referenced object id) the object its
// sender published before it; a received edit whose referenced object is
// of the same sender and not yet handed on is held until it is, then
// handed on with every edit that waited behind it. A referenced object of
// another sender, or none (0:0:0, the first; foreign senders), holds
// nothing. The referenced object's update number is the one that makes
// its id the latest below this object's, which is exact because publish
// takes only ids that grow by 1 to 65,535. Edits of different senders are
// handed on in arrival order.
//
// Thread safety: one thread owns a tracker (the gateway's).
#include <cstdint>
#include <functional>
#include <map>
#include <optional>
#include <span>
#include <string>
#include <unordered_map>
#include <unordered_set>
#include <vector>

#include "sandtable/base/result.h"
#include "sandtable/dis/pdu.h"
#include "sandtable/formats/edit.h"
#include "sandtable/sim_dis/frame.h"
#include "sandtable/sim_dis/objects.h"

namespace sandtable::sim_dis {

struct TrackerOptions {
  double heartbeatS = 5;  ///< every published object is re-sent once per this (seed: 5 s)
};

struct TrackerCounters {
  std::uint64_t published = 0;   ///< local edits published
  std::uint64_t heartbeats = 0;  ///< PDUs re-sent by heartbeat
  std::uint64_t received = 0;    ///< object PDUs received (each counted once below, or malformed)
  std::uint64_t edits = 0;       ///< of those, new edits handed on (updates included)
  std::uint64_t updates = 0;     ///< of the edits, known objects with a new update number
  std::uint64_t duplicates = 0;  ///< an object id and update number seen before: nothing to do
  std::uint64_t malformed = 0;   ///< refused by fromPdu (lastMalformed says why)
  std::uint64_t withoutEdit = 0; ///< objects of a type that makes no edit (byType says which)
  std::uint64_t waited = 0;      ///< edits (and objects without edit) that arrived before the one they follow
  std::uint64_t held = 0;        ///< of those, still waiting now
  /// Objects that make no edit, by objectTypeKey (name: objectTypeName),
  /// once per object id and update number: unknown types, and the
  /// recognised ones Sandtable does not apply (building rubble, vehicle defilade).
  std::map<std::uint32_t, std::uint64_t> byType;
  std::string lastMalformed;
};

class ObjectTracker {
 public:
  using Send = std::function<void(std::span<const std::byte>)>;

  ObjectTracker(DisFrame frame, ObjectSender self, TrackerOptions options = {});

  /// Publishes local edit `e` (crater sizes snapped, snapCrater): its PDU
  /// goes to `send` now and on every heartbeat after. Returns the edit as
  /// every receiver makes it (asReceived, from the very bytes sent): the
  /// caller applies that one, not `e`. Refuses what toPdu refuses, and an
  /// id that does not follow the last one published by 1 to 65,535 (so
  /// receivers can tell which object each follows).
  Result<edit::Edit> publish(const edit::Edit& e, const Send& send);
  /// Sends the heartbeats due by `nowS` (seconds, the caller's clock; the
  /// first call only starts the clock) and returns how many.
  std::size_t heartbeat(double nowS, const Send& send);
  /// A decoded Point or Linear Object State PDU from another participant,
  /// read with the receiver's clock `nowS`: the edits it makes ready, in
  /// their senders' order (its own, and those that waited behind it), or
  /// none (counted: a duplicate, malformed, a type without edit, or held).
  std::vector<edit::Edit> receive(const dis::Pdu& pdu, double nowS);

  /// The local edits published (as received), in order.
  const std::vector<edit::Edit>& published() const { return published_; }
  /// The remote edits handed on, in the order receive() handed them on.
  const std::vector<edit::Edit>& received() const { return received_; }
  const TrackerCounters& counters() const { return counters_; }
  const TrackerOptions& options() const { return options_; }

 private:
  DisFrame frame_;
  ObjectSender self_;
  TrackerOptions options_;
  TrackerCounters counters_;
  std::vector<edit::Edit> published_;
  std::vector<std::vector<std::byte>> bytes_;  ///< each published object's PDU, as first sent
  std::optional<std::uint64_t> lastId_;  ///< the last edit id published
  std::size_t cursor_ = 0;      ///< the next object a heartbeat sends
  double credit_ = 0;           ///< heartbeats owed, fractional
  std::optional<double> lastS_;
  /// An object received before the one it follows.
  struct Held {
    std::uint64_t key = 0;
    std::optional<edit::Edit> edit;  ///< none: a type without edit
  };
  void handOn(std::uint64_t key, std::optional<edit::Edit> e, std::vector<edit::Edit>& out);

  std::optional<dis::ObjectId> previous_;      ///< the last object published
  std::unordered_set<std::uint64_t> seen_;     ///< keys (site, application, object, update) received
  std::unordered_set<std::uint64_t> done_;     ///< keys handed on (or without edit)
  std::unordered_set<std::uint64_t> objects_;  ///< site, application, object
  std::unordered_map<std::uint64_t, std::vector<Held>> waiting_;  ///< by the key they follow
  std::vector<edit::Edit> received_;
};

}  // namespace sandtable::sim_dis
