#include "sandtable/sim_dis/object_tracker.h"

#include <algorithm>

namespace sandtable::sim_dis {
namespace {

std::uint64_t objectKey(const dis::ObjectId& id) {
  return std::uint64_t(id.site) << 32 | std::uint64_t(id.application) << 16 | id.object;
}

/// The key of the object `id` (update `update`) follows, or nullopt when it
/// follows none of its sender's: the referenced object with the update
/// number that makes its edit id the latest below this one's.
std::optional<std::uint64_t> followedKey(const dis::ObjectId& id, std::uint16_t update, const dis::ObjectId& ref) {
  if (ref.site != id.site || ref.application != id.application) return std::nullopt;
  if (ref.object < id.object) return objectKey(ref) << 16 | update;
  if (update == 0) return std::nullopt;  // no earlier id has that object number
  return objectKey(ref) << 16 | std::uint16_t(update - 1);
}

}  // namespace

ObjectTracker::ObjectTracker(DisFrame frame, ObjectSender self, TrackerOptions options)
    : frame_(std::move(frame)), self_(std::move(self)), options_(options) {}

Result<edit::Edit> ObjectTracker::publish(const edit::Edit& e, const Send& send) {
  // Receivers find the edit this one follows from its object number alone (followedKey).
  if (lastId_ && (e.id <= *lastId_ || e.id - *lastId_ >= 0x10000)) {
    return Problem{"", 0, "ObjectTracker::publish: edit id " + std::to_string(e.id) + " does not follow " +
                              std::to_string(*lastId_) + " by 1 to 65,535"};
  }
  auto encoded = encodeEdit(e, frame_, self_, previous_.value_or(dis::ObjectId{}));
  if (!encoded) return encoded.problems();
  previous_ = dis::ObjectId{self_.site, self_.application, std::uint16_t(e.id & 0xFFFF)};
  lastId_ = e.id;
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

std::vector<edit::Edit> ObjectTracker::receive(const dis::Pdu& pdu, double nowS) {
  std::vector<edit::Edit> out;
  const dis::ObjectId* id = pdu.pointObject ? &pdu.pointObject->id : pdu.linearObject ? &pdu.linearObject->id : nullptr;
  if (!id) return out;
  ++counters_.received;
  const std::uint16_t update = pdu.pointObject ? pdu.pointObject->updateNumber : pdu.linearObject->updateNumber;
  const dis::ObjectId& ref = pdu.pointObject ? pdu.pointObject->referenced : pdu.linearObject->referenced;
  const std::uint64_t key = objectKey(*id) << 16 | update;
  if (seen_.count(key) != 0) {
    ++counters_.duplicates;
    return out;
  }
  auto got = fromPdu(pdu, frame_, nowS);
  if (!got) {
    // Not remembered: a later good PDU of the same id and update still counts.
    ++counters_.malformed;
    counters_.lastMalformed = got.error();
    return out;
  }
  seen_.insert(key);
  const bool known = !objects_.insert(objectKey(*id)).second;
  if (!got.value()) {
    ++counters_.withoutEdit;
    ++counters_.byType[objectTypeKey(pdu.pointObject ? pdu.pointObject->type : pdu.linearObject->type)];
  } else {
    ++counters_.edits;
    if (known) ++counters_.updates;
  }
  const std::optional<std::uint64_t> after = followedKey(*id, update, ref);
  if (after && done_.count(*after) == 0) {
    ++counters_.waited;
    ++counters_.held;
    waiting_[*after].push_back({key, std::move(got.value())});
    return out;
  }
  handOn(key, std::move(got.value()), out);
  return out;
}

void ObjectTracker::handOn(std::uint64_t key, std::optional<edit::Edit> e, std::vector<edit::Edit>& out) {
  // Iterative: a late receiver may release thousands of one sender's edits at once.
  std::vector<Held> ready = {{key, std::move(e)}};
  while (!ready.empty()) {
    Held h = std::move(ready.back());
    ready.pop_back();
    done_.insert(h.key);
    if (h.edit) {
      received_.push_back(*h.edit);
      out.push_back(std::move(*h.edit));
    }
    auto it = waiting_.find(h.key);
    if (it == waiting_.end()) continue;
    // In reverse onto the stack, so they come off in arrival order.
    counters_.held -= it->second.size();
    for (auto w = it->second.rbegin(); w != it->second.rend(); ++w) ready.push_back(std::move(*w));
    waiting_.erase(it);
  }
}

}  // namespace sandtable::sim_dis
