#include "sandtable/sim_dis/object_tracker.h"

#include <algorithm>

namespace sandtable::sim_dis {
namespace {

std::uint64_t objectKey(const dis::ObjectId& id) {
  return std::uint64_t(id.site) << 32 | std::uint64_t(id.application) << 16 | id.object;
}

}  // namespace

ObjectTracker::ObjectTracker(DisFrame frame, ObjectSender self, TrackerOptions options)
    : frame_(std::move(frame)), self_(std::move(self)), options_(options) {}

Result<edit::Edit> ObjectTracker::publish(const edit::Edit& e, const Send& send) {
  if (publishedIds_.count(e.id) != 0) {
    return Problem{"", 0, "ObjectTracker::publish: edit id " + std::to_string(e.id) + " was published already"};
  }
  auto encoded = encodeEdit(e, frame_, self_);
  if (!encoded) return encoded.problems();
  publishedIds_.insert(e.id);
  if (send) send(encoded->bytes);
  published_.push_back(encoded->edit);
  bytes_.push_back(std::move(encoded->bytes));
  ++counters_.published;
  return published_.back();
}

std::size_t ObjectTracker::heartbeat(double nowS, const Send& send) {
  const double dt = lastS_ ? nowS - *lastS_ : 0.0;
  lastS_ = nowS;
  const std::size_t n = bytes_.size();
  if (n == 0 || !(dt > 0)) return 0;
  // n objects a heartbeat interval: n * dt / interval owed now; a long
  // pause owes each object once, not a backlog.
  credit_ = std::min(credit_ + double(n) * dt / options_.heartbeatS, double(n));
  std::size_t sent = 0;
  for (; credit_ >= 1; credit_ -= 1, ++sent) {
    if (cursor_ >= n) cursor_ = 0;
    if (send) send(bytes_[cursor_]);
    ++cursor_;
  }
  counters_.heartbeats += sent;
  return sent;
}

std::optional<edit::Edit> ObjectTracker::receive(const dis::Pdu& pdu, double nowS) {
  const dis::ObjectId* id = pdu.pointObject ? &pdu.pointObject->id : pdu.linearObject ? &pdu.linearObject->id : nullptr;
  if (!id) return std::nullopt;
  ++counters_.received;
  const std::uint16_t update = pdu.pointObject ? pdu.pointObject->updateNumber : pdu.linearObject->updateNumber;
  const std::uint64_t key = objectKey(*id) << 16 | update;
  if (seen_.count(key) != 0) {
    ++counters_.duplicates;
    return std::nullopt;
  }
  auto got = fromPdu(pdu, frame_, nowS);
  if (!got) {
    // Not remembered: a later good PDU of the same id and update still counts.
    ++counters_.malformed;
    counters_.lastMalformed = got.error();
    return std::nullopt;
  }
  seen_.insert(key);
  const bool known = !objects_.insert(objectKey(*id)).second;
  if (!got.value()) {
    ++counters_.withoutEdit;
    ++counters_.byType[objectTypeKey(pdu.pointObject ? pdu.pointObject->type : pdu.linearObject->type)];
    return std::nullopt;
  }
  ++counters_.edits;
  if (known) ++counters_.updates;
  received_.push_back(*got.value());
  return received_.back();
}

}  // namespace sandtable::sim_dis
