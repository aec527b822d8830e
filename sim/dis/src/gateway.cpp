#include "sandtable/sim_dis/gateway.h"

#include <chrono>
#include <cmath>
#include <optional>

#include "sandtable/sim/motion.h"
#include "sandtable/sim/sim_world.h"
#include "sandtable/sim/units.h"

namespace sandtable::sim_dis {
namespace {

constexpr double kGravity = 9.81;
constexpr double kRoundLifeS = 60;  ///< a remote round whose Detonation never comes

std::uint64_t eventKey(const dis::EventId& e) {
  return (std::uint64_t(e.site) << 32) | (std::uint64_t(e.application) << 16) | e.event;
}

double systemSecondsPastHour() {
  const auto now = std::chrono::system_clock::now().time_since_epoch();
  return std::fmod(std::chrono::duration<double>(now).count(), 3600.0);
}

std::uint8_t disDomain(sim::Domain d) {
  switch (d) {
    case sim::Domain::land: return 1;
    case sim::Domain::air: return 2;
    case sim::Domain::sea: return 3;
    case sim::Domain::munition: return 0;
  }
  return 0;
}

/// The munition type a Fire PDU names for the simulator's rounds: kind 2
/// (munition), domain 1 (anti-land), USA, guided or ballistic.
dis::EntityType munitionType(bool guided) { return {2, 1, 225, std::uint8_t(guided ? 1 : 2), 1, 0, 0}; }

dis::Vec3f toFloat(const dis::Vec3d& v) { return {float(v.x), float(v.y), float(v.z)}; }
dis::Vec3d toDouble(const dis::Vec3f& v) { return {v.x, v.y, v.z}; }

}  // namespace

Gateway::Gateway(sim::Simulation& simulation, DisFrame frame, GatewayOptions options, Drain drain, Send send)
    : sim_(simulation),
      options_(options),
      drain_(std::move(drain)),
      send_(std::move(send)),
      remotes_(frame, options.remote),
      publisher_(frame, options.publishing),
      frame_(std::move(frame)),
      objects_(frame_,
               {options.exercise, options.site, options.application,
                [&world = simulation.world()](double x, double z) { return world.groundAt(x, z).value_or(0.0); }},
               options.objects),
      wall_(systemSecondsPastHour),
      icons_(simulation.world().icons()) {}

void Gateway::attach(sim::StepHost& host) {
  host.addBeforeStep([this](sim::Simulation&) { beforeStep(); });
  host.addAfterStep([this](sim::Simulation&) { afterStep(); });
}

void Gateway::beforeStep() {
  if (drain_) drain_(inbox_);
  apply(inbox_);
  inbox_.clear();
  flyRemoteMunitions();
  syncRemotes();
}

void Gateway::afterStep() {
  if (!options_.publish) {
    eventCursor_ = sim_.events().size();
    return;
  }
  publishEntities();
  publishEvents();
  objects_.heartbeat(sim_.timeS(), [this](std::span<const std::byte> bytes) { sendPdu(bytes); });
}

void Gateway::apply(const std::vector<dis::Datagram>& datagrams) {
  // The sender's words are only for a refusal: a good PDU is decoded
  // without them, a bad one again with them (decode is a pure function, so
  // the message is the same), which spares a string per PDU (bench dis).
  static const std::string kUnnamed;
  for (const dis::Datagram& d : datagrams) {
    ++counters_.datagrams;
    std::span<const std::byte> rest(d.bytes);
    while (!rest.empty()) {
      auto pdu = dis::decode(rest, kUnnamed);
      if (!pdu) pdu = dis::decode(rest, d.sender.text());
      if (!pdu) {
        ++counters_.malformed;
        counters_.lastMalformed = pdu.error();
        break;  // the rest of the datagram cannot be framed
      }
      applyPdu(pdu.value(), d.sender);
      rest = rest.subspan(std::min<std::size_t>(pdu->header.length, rest.size()));
    }
  }
}

void Gateway::applyPdu(const dis::Pdu& pdu, const dis::Address& sender) {
  ++counters_.pdus;
  if (pdu.header.exercise != options_.exercise) {
    ++counters_.otherExercise;
    return;
  }
  auto ours = [&](const dis::EntityId& id) { return id.site == options_.site && id.application == options_.application; };
  if (pdu.entityState) {
    if (ours(pdu.entityState->id)) {
      ++counters_.own;
      return;
    }
    applyEntityState(pdu, sender);
  } else if (pdu.fire) {
    if (ours(pdu.fire->firing)) {
      ++counters_.own;
      return;
    }
    applyFire(*pdu.fire);
  } else if (pdu.detonation) {
    if (ours(pdu.detonation->firing)) {
      ++counters_.own;
      return;
    }
    applyDetonation(*pdu.detonation);
  } else if (pdu.removeEntity) {
    applyRemove(pdu.removeEntity->receiving);
  } else if (pdu.pointObject || pdu.linearObject) {
    const dis::ObjectId& id = pdu.pointObject ? pdu.pointObject->id : pdu.linearObject->id;
    if (id.site == options_.site && id.application == options_.application) {
      ++counters_.own;
      return;
    }
    ++counters_.objects;
    for (edit::Edit& e : objects_.receive(pdu, sim_.timeS())) receivedEdits_.push_back(std::move(e));
  } else {
    ++counters_.unknownType;
  }
}

double Gateway::pduTime(const dis::Header& h) const {
  const double now = sim_.timeS();
  if (!options_.absoluteTime || !dis::timestampAbsolute(h.timestamp)) return now;
  double age = wall_() - dis::timestampSeconds(h.timestamp);
  age -= 3600 * std::floor((age + 1800) / 3600);  // into [-1800, 1800): the hour may have turned
  return now - std::clamp(age, 0.0, options_.remote.timeoutS);
}

void Gateway::applyEntityState(const dis::Pdu& pdu, const dis::Address& sender) {
  ++counters_.entityStates;
  const dis::EntityState& s = *pdu.entityState;
  const RemoteEntity* known = remotes_.find(s.id);
  const std::uint32_t hadSim = known ? known->simId : UINT32_MAX;
  // A copy for depart(): update() erases the entity when the PDU deactivates it.
  std::optional<RemoteEntity> leaving;
  if (known && (s.appearance & kAppearanceDeactivated) != 0) leaving = *known;
  // Null: deactivated, or its location cannot be placed. A stale or
  // duplicate deactivation comes back as the entity, which stays.
  if (remotes_.update(s, sender, pduTime(pdu.header), sim_.timeS(), pdu.header.timestamp)) return;
  if (leaving) depart(*leaving, s, "deactivated");
  if (hadSim != UINT32_MAX) sim_.remove(hadSim);
}

void Gateway::depart(const RemoteEntity& r, const dis::EntityState& last, const char* why) {
  Departed d;
  d.id = r.id;
  d.marking = last.marking.text();
  d.position = frameOf(r.anchor, last.location);
  if (auto a = frame_.anchorAtEcef(last.location)) d.position = a->frame;
  d.why = why;
  if (departed_.size() == kDepartedKept) departed_.erase(departed_.begin());
  departed_.push_back(std::move(d));
}

void Gateway::applyRemove(const dis::EntityId& id) {
  ++counters_.removes;
  if (id.site == options_.site && id.application == options_.application) {
    // A simulation manager asks us to remove one of ours (IEEE 1278.1 5.6.5.3).
    if (id.entity != 0) sim_.remove(std::uint32_t(id.entity) - 1);
    return;
  }
  const RemoteEntity* r = remotes_.find(id);
  if (!r) return;
  depart(*r, r->last, "removed");
  const std::uint32_t simId = r->simId;
  remotes_.remove(id);
  if (simId != UINT32_MAX) sim_.remove(simId);
}

void Gateway::syncRemotes() {
  for (const RemoteEntity& gone : remotes_.expire(sim_.timeS())) {
    depart(gone, gone.last, "timed out");
    if (gone.simId != UINT32_MAX) sim_.remove(gone.simId);
  }
  for (auto& [key, r] : remotes_.all()) placeRemote(r);
}

std::uint16_t Gateway::iconFor(const dis::EntityType& t) {
  const iconpack::DisMatch m =
      icons_.lookup({t.kind, t.domain, t.country, t.category, t.subcategory, t.specific, t.extra});
  if (m.fallback()) ++counters_.unknownIcons;
  return m.icon == iconpack::kNoIcon ? 0 : std::uint16_t(m.icon);
}

void Gateway::placeRemote(RemoteEntity& r) {
  auto state = remotes_.stateAt(r, sim_.timeS());
  if (!state) return;
  const RemoteState& s = state.value();
  sim::Entity* e = r.simId == UINT32_MAX ? nullptr : sim_.find(r.simId);
  if (!e) {
    if (r.offDatabase) return;
    sim::Entity fresh;
    fresh.controller = sim::Controller::remote;
    fresh.domain = r.domain;
    fresh.icon = iconFor(r.last.type);
    fresh.name = r.last.marking.text();
    fresh.force = r.last.force;
    fresh.position = s.pose.position;
    fresh.headingDeg = s.pose.headingDeg;
    auto id = sim_.add(fresh);
    if (!id) {
      r.offDatabase = true;
      ++counters_.notAdded;
      return;
    }
    r.simId = id.value();
    e = sim_.find(r.simId);
  }
  e->position = s.pose.position;
  e->headingDeg = s.pose.headingDeg;
  e->pitchDeg = s.pose.pitchDeg;
  e->rollDeg = s.pose.rollDeg;
  e->velocity = s.velocity;
  e->speedMs = Eigen::Vector2d(s.velocity.x(), s.velocity.z()).norm();
  e->alive = s.alive;
  e->name = r.last.marking.text();
  if (r.domain == sim::Domain::land && options_.publishing.alignToGround) {
    // Align to ground (seed X.C): the drawn ground's height and slope.
    if (auto g = sim_.world().groundAt(e->position.x(), e->position.z())) e->position.y() = *g;
    if (auto a = sim::projectedPointAttitude(sim_.world(), e->position.x(), e->position.z(), e->headingDeg,
                                             e->halfLength, e->halfWidth)) {
      e->pitchDeg = a->pitchDeg;
      e->rollDeg = a->rollDeg;
    }
  }
  for (const dis::VariableParameter& v : r.last.parameters) {
    const auto part = dis::articulatedPart(v);
    if (!part) continue;
    if (part->parameterType == kTurretAzimuth) e->gunAzimuthDeg = sim::wrapDeg(e->headingDeg + part->value * sim::kRadToDeg);
    if (part->parameterType == kGunElevation) e->gunElevationDeg = part->value * sim::kRadToDeg;
  }
}

void Gateway::applyFire(const dis::Fire& f) {
  ++counters_.fires;
  auto anchor = frame_.anchorAtEcef(f.location);
  if (!anchor) return;
  sim::Entity m;
  m.controller = sim::Controller::remote;
  m.domain = sim::Domain::munition;
  m.name = "remote round";
  m.position = anchor->frame;
  m.velocity = frameVector(anchor.value(), toDouble(f.velocity));
  m.speedMs = m.velocity.norm();
  m.headingDeg = sim::headingOf(m.velocity.x(), m.velocity.z());
  m.launcher = simIdOf(f.firing);
  auto id = sim_.add(m);
  if (!id) return;
  remoteRounds_[eventKey(f.event)] = id.value();
  roundLaunchedS_[id.value()] = sim_.timeS();
  sim_.addEvent({0, sim::EventKind::fire, id.value(), m.launcher, UINT32_MAX, m.position, "remote", {}});
}

void Gateway::flyRemoteMunitions() {
  const double dt = sim_.options().stepS;
  for (auto it = remoteRounds_.begin(); it != remoteRounds_.end();) {
    sim::Entity* m = sim_.find(it->second);
    const double age = m ? sim_.timeS() - roundLaunchedS_[it->second] : kRoundLifeS;
    const bool gone = !m || age >= kRoundLifeS || !sim_.world().onGrid(m->position.x(), m->position.z()) ||
                      m->position.y() < sim_.world().groundAt(m->position.x(), m->position.z()).value_or(-1e9);
    if (gone) {
      if (m) sim_.remove(it->second);
      roundLaunchedS_.erase(it->second);
      it = remoteRounds_.erase(it);
      continue;
    }
    m->velocity.y() -= kGravity * dt;
    m->position += m->velocity * dt;
    m->headingDeg = sim::headingOf(m->velocity.x(), m->velocity.z());
    ++it;
  }
}

void Gateway::applyDetonation(const dis::Detonation& d) {
  ++counters_.detonations;
  if (auto it = remoteRounds_.find(eventKey(d.event)); it != remoteRounds_.end()) {
    sim_.remove(it->second);
    roundLaunchedS_.erase(it->second);
    remoteRounds_.erase(it);
  }
  auto anchor = frame_.anchorAtEcef(d.location);
  const Eigen::Vector3d at = anchor ? anchor->frame : Eigen::Vector3d::Zero();
  const std::uint32_t shooter = simIdOf(d.firing);
  const bool ourTarget = d.target.site == options_.site && d.target.application == options_.application;
  const std::uint32_t target = simIdOf(d.target);
  if (anchor) {
    sim_.addEvent({0, sim::EventKind::detonation, UINT32_MAX, target, UINT32_MAX, at, "remote",
                   d.result == 1 ? "entity" : d.result == 3 ? "terrain" : "air"});
  }
  // Result 1 is an entity impact, 2 an entity proximate detonation (SISO-REF-010).
  if (ourTarget && target != UINT32_MAX && (d.result == 1 || d.result == 2)) {
    if (sim_.destroy(target, shooter, "munition")) ++counters_.hitsTaken;
  }
}

dis::EntityId Gateway::disId(std::uint32_t simId) const {
  const sim::Entity* e = sim_.find(simId);
  if (e && e->controller == sim::Controller::remote) {
    for (const auto& [key, r] : remotes_.all()) {
      if (r.simId == simId) return r.id;
    }
  }
  return {options_.site, options_.application, std::uint16_t(simId + 1)};
}

std::uint32_t Gateway::simIdOf(const dis::EntityId& id) const {
  if (id.site == options_.site && id.application == options_.application) {
    return id.entity == 0 ? UINT32_MAX : std::uint32_t(id.entity) - 1;
  }
  auto it = remotes_.all().find(RemoteEntities::key(id));
  return it == remotes_.all().end() ? UINT32_MAX : it->second.simId;
}

Identity Gateway::identityOf(const sim::Entity& e) const {
  Identity who;
  who.id = disId(e.id);
  who.force = e.force;
  const auto& icons = sim_.world().icons().icons;
  if (e.icon < icons.size() && !icons[e.icon].dis.empty()) {
    // The icon's first pattern, its wildcards sent as 0 ("other").
    const iconpack::DisPattern& p = icons[e.icon].dis.front();
    const iconpack::DisType d = p.type;
    auto field = [&](int k, auto v) { return (p.wild >> k) & 1 ? decltype(v){0} : v; };
    who.type = {field(0, d.kind),     field(1, d.domain),      field(2, d.country), field(3, d.category),
                field(4, d.subcategory), field(5, d.specific), field(6, d.extra)};
  } else {
    who.type = {1, disDomain(e.domain), 0, 0, 0, 0, 0};
  }
  return who;
}

dis::Header Gateway::header() const {
  dis::Header h;
  h.exercise = options_.exercise;
  h.timestamp = options_.absoluteTime ? dis::timestamp(wall_(), true)
                                      : dis::timestamp(std::fmod(sim_.timeS(), 3600.0), false);
  return h;
}

void Gateway::sendPdu(std::span<const std::byte> bytes) {
  if (bytes.empty() || !send_) return;
  send_(bytes);
  ++counters_.sentPdus;
  counters_.sentBytes += bytes.size();
}

void Gateway::publishEntities() {
  const double now = sim_.timeS();
  for (const sim::Entity& e : sim_.entities()) {
    if (e.controller == sim::Controller::remote || e.domain == sim::Domain::munition) continue;
    const bool first = published_.emplace(e.id, true).second;
    if (auto s = publisher_.offer(e, identityOf(e), now, first)) sendPdu(dis::encode(header(), *s));
  }
  for (auto it = published_.begin(); it != published_.end();) {
    if (sim_.find(it->first)) {
      ++it;
      continue;
    }
    retire(it->first);
    it = published_.erase(it);
  }
}

void Gateway::retire(std::uint32_t simId) {
  const dis::EntityId id = disId(simId);
  if (const sim::Entity* e = sim_.find(simId)) {
    // Still here (the end of a run): the last PDU says where it really is.
    static_cast<void>(publisher_.offer(*e, identityOf(*e), sim_.timeS(), true));
  }
  if (auto s = publisher_.retire(simId, sim_.timeS())) sendPdu(dis::encode(header(), *s));
  dis::RemoveEntity r;
  r.originating = {options_.site, options_.application, 0};
  r.receiving = id;
  r.requestId = ++requests_;
  sendPdu(dis::encode(header(), r));
}

Result<edit::Edit> Gateway::publishEdit(const edit::Edit& e) {
  if (!options_.publish) return Problem{"", 0, "Gateway::publishEdit: publish is off (a watcher sends nothing)"};
  return objects_.publish(e, [this](std::span<const std::byte> bytes) { sendPdu(bytes); });
}

std::vector<edit::Edit> Gateway::takeReceivedEdits() {
  std::vector<edit::Edit> out;
  out.swap(receivedEdits_);
  return out;
}

void Gateway::retireAll() {
  for (const auto& [id, _] : published_) retire(id);
  published_.clear();
}

void Gateway::publishEvents() {
  const auto& events = sim_.events();
  for (; eventCursor_ < events.size(); ++eventCursor_) {
    const sim::Event& ev = events[eventCursor_];
    if (ev.kind != sim::EventKind::fire && ev.kind != sim::EventKind::detonation) continue;
    const sim::Entity* round = sim_.find(ev.entity);
    if (!round || round->controller == sim::Controller::remote) continue;
    auto anchor = frame_.anchorAtFrame(ev.position);
    if (!anchor) continue;
    const std::uint32_t launcher = round->launcher;
    const dis::EventId event{options_.site, options_.application, std::uint16_t(ev.entity + 1)};
    const bool guided = round->munitionType < sim_.munitions().size() && sim_.munitions()[round->munitionType].guided;
    dis::MunitionDescriptor descriptor{munitionType(guided), 1000, 1000, 1, 0};
    const dis::Vec3f velocity = toFloat(ecefVector(anchor.value(), round->velocity));
    if (ev.kind == sim::EventKind::fire) {
      dis::Fire f;
      f.firing = disId(launcher);
      if (round->target != UINT32_MAX) f.target = disId(round->target);
      f.munition = disId(ev.entity);
      f.event = event;
      f.location = anchor->ecef;
      f.descriptor = descriptor;
      f.velocity = velocity;
      sendPdu(dis::encode(header(), f));
    } else {
      dis::Detonation d;
      d.firing = disId(launcher);
      if (ev.other != UINT32_MAX) d.target = disId(ev.other);
      d.munition = disId(ev.entity);
      d.event = event;
      d.velocity = velocity;
      d.location = anchor->ecef;
      d.descriptor = descriptor;
      d.result = ev.other != UINT32_MAX ? 1 : ev.detail == "terrain" ? 3 : 5;
      sendPdu(dis::encode(header(), d));
    }
  }
}

}  // namespace sandtable::sim_dis
