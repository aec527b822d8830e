#include "sandtable/sim_dis/script_pcap.h"

#include <algorithm>
#include <cmath>
#include <unordered_map>
#include <unordered_set>

#include "sandtable/formats/dis_icons.h"
#include "sandtable/sim/entity.h"
#include "sandtable/sim/units.h"
#include "sandtable/sim_dis/remote.h"

namespace sandtable::sim_dis {
namespace {

constexpr const char* kProblemFile = "script-pcap";

/// Two times closer than this are one (the script's resolution).
constexpr double kSameTimeS = 1e-9;

dis::EntityType patternType(const iconpack::DisPattern& p) {
  // The icon's pattern with its wildcards as 0 ("other"), as the gateway sends it.
  auto field = [&](int k, auto v) { return (p.wild >> k) & 1 ? decltype(v){0} : v; };
  const iconpack::DisType& d = p.type;
  return {field(0, d.kind),        field(1, d.domain),   field(2, d.country), field(3, d.category),
          field(4, d.subcategory), field(5, d.specific), field(6, d.extra)};
}

/// A bearing in [0, 360) that the writer's "%f" does not print as
/// 360.000000 (a hair under 360 is north).
double bearing(double deg) {
  const double b = sim::wrapDeg(deg);
  return b >= 360.0 - 5e-7 ? 0.0 : b;
}

dis::Header headerAt(std::uint8_t exercise, double t) {
  dis::Header h;
  h.exercise = exercise;
  h.timestamp = dis::timestamp(std::fmod(std::max(0.0, t), 3600.0), false);
  return h;
}

// ------------------------------------------------------------ from

struct Outgoing {
  EntityMapping map;
  sim::Entity entity;  ///< the state offered to the publisher
  Identity who;
  sim::ScriptLine last;  ///< the line applied last
  bool started = false, dead = false;
};

class ScriptPublisher {
 public:
  ScriptPublisher(const DisFrame& frame, std::span<const iconpack::Icon> icons, const FromScriptOptions& o)
      : frame_(frame), icons_(icons), o_(o), publisher_(frame, o.publishing) {}

  Result<FromScriptResult> run(const std::vector<sim::ScriptLine>& lines);

 private:
  void addEntities(const sim::ScriptPlayer& player);
  void place(Outgoing& out, double t);
  void offer(Outgoing& out, double t, bool force);
  void fire(Outgoing& out, double t);
  void retire(Outgoing& out, double t);
  void send(std::vector<std::byte> bytes, double t);

  const DisFrame& frame_;
  std::span<const iconpack::Icon> icons_;
  const FromScriptOptions& o_;
  Publisher publisher_;
  std::vector<Outgoing> out_;
  std::unordered_map<std::uint32_t, std::size_t> index_;  ///< script entity -> out_
  FromScriptResult result_;
  std::uint16_t events_ = 0;
  std::uint32_t requests_ = 0;
};

void ScriptPublisher::addEntities(const sim::ScriptPlayer& player) {
  const auto entities = player.entities();
  const bool direct = std::all_of(entities.begin(), entities.end(),
                                  [](const sim::ScriptEntity& e) { return e.entity >= 1 && e.entity <= 65534; });
  for (std::size_t k = 0; k < entities.size(); ++k) {
    const sim::ScriptEntity& se = entities[k];
    Outgoing out;
    EntityMapping& m = out.map;
    m.scriptEntity = se.entity;
    m.scriptType = se.type;
    m.id = {o_.site, o_.application, std::uint16_t(direct ? se.entity : k + 1)};
    const iconpack::Icon* icon = se.type < icons_.size() ? &icons_[se.type] : nullptr;
    if (icon) m.icon = icon->name;
    if (auto it = o_.types.find(se.type); it != o_.types.end()) {
      m.type = it->second;
      m.typeByIcon = false;
    } else if (icon && !icon->dis.empty()) {
      m.type = patternType(icon->dis.front());
    } else {
      m.type = {1, 1, 0, 0, 0, 0, 0};  // a land platform of no known kind
      m.typeByIcon = false;
      m.fallback = true;
    }
    m.marking = std::to_string(se.entity).substr(0, 11);
    out.who = {m.id, m.type, 0};
    sim::Entity& e = out.entity;
    e.id = std::uint32_t(k);
    e.name = m.marking;
    e.domain = domainOf(m.type);
    // Turret and gun go out when the icon has them or the script turns them.
    e.armed = icon && icon->armed;
    for (const sim::ScriptLine& l : player.lines()) {
      if (l.entity == se.entity && (l.viewDirectionDeg != 0 || l.gunElevation != 0)) e.armed = true;
    }
    index_[se.entity] = out_.size();
    out_.push_back(std::move(out));
  }
}

void ScriptPublisher::place(Outgoing& out, double t) {
  const sim::ScriptLine& l = out.last;
  // A dead entity stays where its last line put it (the simulator stops it).
  const Eigen::Vector2d p = out.dead ? Eigen::Vector2d(l.x, l.z) : sim::deadReckon(l, t);
  double y = l.y;
  if (y == 0 && o_.groundAt) y = o_.groundAt(p.x(), p.y()).value_or(0.0);
  sim::Entity& e = out.entity;
  e.position = {p.x(), y, p.y()};
  e.headingDeg = sim::wrapDeg(l.directionDeg);
  e.speedMs = out.dead ? 0.0 : l.speed;
  e.velocity = sim::headingVector(e.headingDeg) * e.speedMs;
  e.alive = !out.dead;
  e.gunAzimuthDeg = l.viewDirectionDeg;
  e.gunElevationDeg = l.gunElevation * sim::kRadToDeg;  // the script's unit is the simulator's: radians
}

void ScriptPublisher::send(std::vector<std::byte> bytes, double t) {
  if (bytes.empty()) return;
  dis::Datagram d;
  d.timeS = o_.startUnixS + t;
  d.sender = o_.sender;
  d.destination = o_.destination;
  d.bytes = std::move(bytes);
  result_.datagrams.push_back(std::move(d));
}

void ScriptPublisher::offer(Outgoing& out, double t, bool force) {
  place(out, t);  // a turned turret or gun goes out by the publisher's angle threshold
  const std::uint64_t unplaceable = publisher_.unplaceable();
  if (auto s = publisher_.offer(out.entity, out.who, t, force)) {
    send(dis::encode(headerAt(o_.exercise, t), *s), t);
    ++out.map.entityStates;
    ++result_.entityStates;
  }
  result_.unplaceable += publisher_.unplaceable() - unplaceable;
}

void ScriptPublisher::fire(Outgoing& out, double t) {
  auto anchor = frame_.anchorAtFrame(out.entity.position);
  if (!anchor) {
    ++result_.unplaceable;
    return;
  }
  dis::Fire f;
  f.firing = out.who.id;
  f.event = {o_.site, o_.application, ++events_};
  f.location = anchor->ecef;
  // The script says that it fired, not what: a ballistic round (docs/DIS.md
  // §11), its velocity and range unknown (0).
  f.descriptor.munition = {2, 1, 225, 2, 0, 0, 0};
  f.descriptor.quantity = 1;
  send(dis::encode(headerAt(o_.exercise, t), f), t);
  ++result_.fires;
}

void ScriptPublisher::retire(Outgoing& out, double t) {
  // The deactivating PDU carries where the entity really is (Gateway::retire).
  place(out, t);
  static_cast<void>(publisher_.offer(out.entity, out.who, t, true));
  if (auto s = publisher_.retire(out.entity.id, t)) {
    send(dis::encode(headerAt(o_.exercise, t), *s), t);
    ++out.map.entityStates;
    ++result_.entityStates;
  }
  dis::RemoveEntity r;
  r.originating = {o_.site, o_.application, 0};
  r.receiving = out.who.id;
  r.requestId = ++requests_;
  send(dis::encode(headerAt(o_.exercise, t), r), t);
  ++result_.removes;
}

Result<FromScriptResult> ScriptPublisher::run(const std::vector<sim::ScriptLine>& lines) {
  sim::ScriptPlayer player(lines);
  addEntities(player);
  const double dt = 1.0 / o_.rateHz;
  const double end = player.lines().back().timeS;
  result_.endS = end;
  auto isAlive = [&](std::uint32_t n) { return !out_[index_.at(n)].dead; };
  std::uint64_t k = 0;
  for (;;) {
    const double grid = double(k) * dt;
    if (!player.finished() && player.nextTimeS() <= grid + kSameTimeS) {
      // Lines at their own time: the publisher sees each change when it happens.
      const double t = player.nextTimeS();
      player.advance(t, isAlive, [&](const sim::ScriptLine& l) {
        Outgoing& out = out_[index_.at(l.entity)];
        const bool first = !out.started;
        out.started = true;
        out.last = l;
        if (!l.alive) out.dead = true;
        ++out.map.lines;
        offer(out, t, first);
        if (l.fire) fire(out, t);
      });
      continue;
    }
    if (grid > end + kSameTimeS) break;
    for (Outgoing& out : out_) {
      if (out.started) offer(out, grid, false);
    }
    ++k;
  }
  for (Outgoing& out : out_) {
    if (out.started) retire(out, end);
  }
  for (Outgoing& out : out_) result_.entities.push_back(out.map);
  return std::move(result_);
}

// -------------------------------------------------------------- to

struct Incoming {
  EntityMapping map;
  dis::EntityId id;
  sim::Domain domain = sim::Domain::land;
  sim::ScriptRecorder recorder;
  bool active = false;  ///< tracked now (between its first PDU and its leaving)
  bool firing = false;  ///< a Fire PDU arrived: the next sample has Fire_Flag 1
  double lastS = -1;    ///< the last sample offered
};

class ScriptLogger {
 public:
  ScriptLogger(const DisFrame& frame, std::span<const iconpack::Icon> icons, const ToScriptOptions& o)
      : icons_(icons), iconMap_(icons), o_(o), remotes_(frame, remoteOptions(o)) {}

  Result<ToScriptResult> run(std::span<const dis::Datagram> datagrams);

 private:
  static RemoteOptions remoteOptions(const ToScriptOptions& o) {
    RemoteOptions r;
    // The script follows each PDU's truth: corrections snap, no smooth-back.
    r.blendLandS = r.blendSeaS = r.blendAirS = r.blendMunitionS = 0;
    r.timeoutS = o.timeoutS;
    return r;
  }
  void sampleUntil(double t);
  void sample(Incoming& in, double t);
  /// A last line where the entity stops (speed 0), and no more.
  void stop(Incoming& in, const sim::ScriptLine& at);
  void expire(double t);
  void applyPdu(const dis::Pdu& pdu, const dis::Address& sender, double t);
  void applyEntityState(const dis::EntityState& s, const dis::Address& sender, double t);
  Incoming& incoming(const dis::EntityState& s);
  sim::ScriptLine lineOf(const Incoming& in, const RemoteState& st, const dis::EntityState& last, double t) const;
  void finish();

  std::span<const iconpack::Icon> icons_;
  iconpack::DisIconMap iconMap_;
  const ToScriptOptions& o_;
  RemoteEntities remotes_;
  std::vector<Incoming> in_;
  std::unordered_map<std::uint64_t, std::size_t> index_;  ///< RemoteEntities::key -> in_
  std::optional<std::uint8_t> exercise_;
  std::uint64_t grid_ = 0;  ///< the next sample time, in steps of 1 / rate
  ToScriptResult result_;
};

Incoming& ScriptLogger::incoming(const dis::EntityState& s) {
  const std::uint64_t key = RemoteEntities::key(s.id);
  if (auto it = index_.find(key); it != index_.end()) return in_[it->second];
  Incoming in{.map = {}, .id = s.id, .domain = domainOf(s.type), .recorder = sim::ScriptRecorder(o_.recorder)};
  in.map.id = s.id;
  in.map.type = s.type;
  in.map.marking = s.marking.text();
  const iconpack::DisMatch m =
      iconMap_.match({s.type.kind, s.type.domain, s.type.country, s.type.category, s.type.subcategory,
                      s.type.specific, s.type.extra});
  in.map.scriptType = m.icon == iconpack::kNoIcon ? 0 : m.icon;
  if (m.icon < icons_.size()) in.map.icon = icons_[m.icon].name;
  in.map.fallback = m.fallback();
  index_[key] = in_.size();
  in_.push_back(std::move(in));
  return in_.back();
}

sim::ScriptLine ScriptLogger::lineOf(const Incoming& in, const RemoteState& st, const dis::EntityState& last,
                                     double t) const {
  sim::ScriptLine l;
  l.setTime(t);
  l.entity = std::uint32_t(&in - in_.data());  // renumbered in finish()
  l.type = in.map.scriptType;
  const Eigen::Vector3d& p = st.pose.position;
  l.x = p.x();
  l.z = p.z();
  const bool onGround = in.domain == sim::Domain::land || in.domain == sim::Domain::sea;
  l.y = onGround ? 0.0 : p.y();
  if (!onGround && o_.groundAt) {
    if (auto g = o_.groundAt(p.x(), p.z())) l.aboveGroundLevel = p.y() - *g;
  }
  l.directionDeg = bearing(st.pose.headingDeg);
  const Eigen::Vector2d v(st.velocity.x(), st.velocity.z());
  const Eigen::Vector3d ahead = sim::headingVector(l.directionDeg);
  l.speed = v.norm() * (v.dot(Eigen::Vector2d(ahead.x(), ahead.z())) < 0 ? -1 : 1);
  for (const dis::VariableParameter& vp : last.parameters) {
    const auto part = dis::articulatedPart(vp);
    if (!part || part->attachedTo != 0) continue;
    if (part->parameterType == kTurretAzimuth) {
      l.viewDirectionDeg = bearing(l.directionDeg + part->value * sim::kRadToDeg);
    } else if (part->parameterType == kGunElevation) {
      l.gunElevation = part->value;
    }
  }
  l.alive = st.alive;
  l.fire = in.firing;
  return l;
}

void ScriptLogger::sample(Incoming& in, double t) {
  RemoteEntity* r = remotes_.find(in.id);
  // A grid sample at the time of a PDU's own sample adds nothing (and would
  // take back a Fire_Flag at the very time it was set).
  if (!r || t < in.lastS || (t <= in.lastS + kSameTimeS && !in.firing)) return;
  auto st = remotes_.stateAt(*r, t);
  if (!st) {
    ++result_.unplaceable;
    return;
  }
  in.recorder.record(lineOf(in, st.value(), r->last, t));
  in.lastS = t;
  in.firing = false;
}

void ScriptLogger::stop(Incoming& in, const sim::ScriptLine& at) {
  sim::ScriptLine l = at;
  l.speed = 0;
  l.fire = false;
  in.recorder.record(l);
  in.recorder.finish();
  in.active = false;
}

void ScriptLogger::expire(double t) {
  for (const RemoteEntity& gone : remotes_.expire(t)) {
    auto it = index_.find(RemoteEntities::key(gone.id));
    if (it == index_.end()) continue;
    Incoming& in = in_[it->second];
    ++result_.timedOut;
    // Where the network lost it: its dead reckoning at the timeout.
    RemoteEntity copy = gone;
    if (auto st = remotes_.stateAt(copy, t)) stop(in, lineOf(in, st.value(), copy.last, t));
    else in.active = false;
  }
}

void ScriptLogger::sampleUntil(double t) {
  const double dt = 1.0 / o_.rateHz;
  for (double g = double(grid_) * dt; g < t - kSameTimeS; g = double(++grid_) * dt) {
    expire(g);
    for (Incoming& in : in_) {
      if (in.active) sample(in, g);
    }
  }
}

void ScriptLogger::applyEntityState(const dis::EntityState& s, const dis::Address& sender, double t) {
  ++result_.entityStates;
  Incoming& in = incoming(s);
  ++in.map.entityStates;
  if ((s.appearance & kAppearanceDeactivated) != 0) {
    // It leaves where this PDU puts it (the publisher's true final state).
    if (in.active) {
      RemoteEntity* r = remotes_.find(s.id);
      if (r) {
        dis::EntityState still = s;
        still.velocity = {};
        still.deadReckoning.algorithm = 1;
        still.appearance &= ~kAppearanceDeactivated;
        r = remotes_.update(still, sender, t, t);
      }
      if (r) {
        if (auto st = remotes_.stateAt(*r, t)) stop(in, lineOf(in, st.value(), s, t));
      }
      in.active = false;
    }
    remotes_.update(s, sender, t, t);  // drops it
    return;
  }
  if (!remotes_.update(s, sender, t, t)) {
    ++result_.unplaceable;
    return;
  }
  in.domain = domainOf(s.type);
  in.active = true;
  sample(in, t);
}

void ScriptLogger::applyPdu(const dis::Pdu& pdu, const dis::Address& sender, double t) {
  ++result_.pdus;
  if (!exercise_ && pdu.entityState) exercise_ = pdu.header.exercise;
  if (!exercise_ || pdu.header.exercise != *exercise_) {
    // Before the first Entity State PDU no exercise is chosen: only its PDUs count.
    if (exercise_ || pdu.entityState) ++result_.otherExercise;
    else ++result_.otherTypes;
    return;
  }
  if (pdu.entityState) {
    applyEntityState(*pdu.entityState, sender, t);
  } else if (pdu.fire) {
    ++result_.fires;
    auto it = index_.find(RemoteEntities::key(pdu.fire->firing));
    if (it != index_.end() && in_[it->second].active) {
      in_[it->second].firing = true;
      sample(in_[it->second], t);
    }
  } else if (pdu.removeEntity) {
    ++result_.removes;
    auto it = index_.find(RemoteEntities::key(pdu.removeEntity->receiving));
    if (it != index_.end() && in_[it->second].active) {
      Incoming& in = in_[it->second];
      RemoteEntity* r = remotes_.find(in.id);
      if (r) {
        if (auto st = remotes_.stateAt(*r, t)) stop(in, lineOf(in, st.value(), r->last, t));
      }
      in.active = false;
      remotes_.remove(in.id);
    }
  } else {
    ++result_.otherTypes;
  }
}

void ScriptLogger::finish() {
  for (Incoming& in : in_) in.recorder.finish();
  // Entity numbers: the DIS entity field when no two ids share one.
  std::unordered_set<std::uint16_t> fields;
  for (const Incoming& in : in_) {
    if (in.id.entity == 0 || !fields.insert(in.id.entity).second) result_.renumbered = true;
  }
  for (std::size_t k = 0; k < in_.size(); ++k) {
    Incoming& in = in_[k];
    in.map.scriptEntity = result_.renumbered ? std::uint32_t(k + 1) : in.id.entity;
    for (sim::ScriptLine l : in.recorder.lines()) {
      l.entity = in.map.scriptEntity;
      result_.lines.push_back(l);
      ++in.map.lines;
    }
    result_.entities.push_back(in.map);
  }
  std::stable_sort(result_.lines.begin(), result_.lines.end(),
                   [](const sim::ScriptLine& a, const sim::ScriptLine& b) { return a.timeS < b.timeS; });
}

Result<ToScriptResult> ScriptLogger::run(std::span<const dis::Datagram> datagrams) {
  exercise_ = o_.exercise;
  const double origin = o_.originUnixS.value_or(datagrams.empty() ? 0.0 : datagrams.front().timeS);
  for (const dis::Datagram& d : datagrams) {
    ++result_.datagrams;
    const double t = d.timeS - origin;
    if (t < -kSameTimeS) {
      ++result_.beforeOrigin;
      continue;
    }
    sampleUntil(t);
    std::span<const std::byte> rest(d.bytes);
    while (!rest.empty()) {
      auto pdu = dis::decode(rest, d.sender.text());
      if (!pdu) {
        if (result_.malformed++ == 0) result_.firstMalformed = pdu.error();
        break;  // the rest of the datagram cannot be framed
      }
      applyPdu(pdu.value(), d.sender, std::max(0.0, t));
      rest = rest.subspan(std::min<std::size_t>(pdu->header.length, rest.size()));
    }
  }
  result_.exercise = exercise_.value_or(0);
  finish();
  return std::move(result_);
}

}  // namespace

Result<FromScriptResult> fromScript(const std::vector<sim::ScriptLine>& lines, const DisFrame& frame,
                                    std::span<const iconpack::Icon> icons, const FromScriptOptions& options) {
  if (!(options.rateHz > 0 && std::isfinite(options.rateHz))) {
    return Problem{kProblemFile, 0, "the sampling rate must be above 0 Hz"};
  }
  if (lines.empty()) return Problem{kProblemFile, 0, "the script has no lines: nothing to publish"};
  ScriptPublisher p(frame, icons, options);
  return p.run(lines);
}

Result<ToScriptResult> toScript(std::span<const dis::Datagram> datagrams, const DisFrame& frame,
                                std::span<const iconpack::Icon> icons, const ToScriptOptions& options) {
  if (!(options.rateHz > 0 && std::isfinite(options.rateHz))) {
    return Problem{kProblemFile, 0, "the sampling rate must be above 0 Hz"};
  }
  ScriptLogger logger(frame, icons, options);
  return logger.run(datagrams);
}

std::optional<Eigen::Vector2d> scriptPosition(const std::vector<sim::ScriptLine>& lines, std::uint32_t entity,
                                              double timeS) {
  const sim::ScriptLine* last = nullptr;
  for (const sim::ScriptLine& l : lines) {
    if (l.timeS > timeS + sim::kScriptTimeResolutionS / 2) break;
    if (l.entity != entity) continue;
    if (last && !last->alive) break;  // dead: its later lines are skipped
    last = &l;
  }
  if (!last) return std::nullopt;
  if (!last->alive) return Eigen::Vector2d(last->x, last->z);
  return sim::deadReckon(*last, timeS);
}

}  // namespace sandtable::sim_dis
