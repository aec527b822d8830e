#include "sandtable/viewer/sim_session.h"

#include <algorithm>
#include <cctype>
#include <cmath>
#include <cstdio>
#include <iterator>

#include <nlohmann/json.hpp>

#include "sandtable/sim/motion.h"
#include "sandtable/sim/report.h"

namespace sandtable::viewer {
namespace {

constexpr double kMsToKmh = 3.6;
/// A ship drawn sits this fraction of its length deep in the water (a
/// 25 m patrol boat: 1.5 m), within 0.3 .. 3 m.
constexpr double kDraftPerLength = 0.06;
constexpr double kRadToDeg = 180.0 / 3.14159265358979323846;

scene::ObjectLook lookOf(sim::ObjectState s) {
  switch (s) {
    case sim::ObjectState::standing: return scene::ObjectLook::standing;
    case sim::ObjectState::knockedOver: return scene::ObjectLook::knockedOver;
    case sim::ObjectState::stump: return scene::ObjectLook::stump;
    case sim::ObjectState::ruins: return scene::ObjectLook::ruins;
    case sim::ObjectState::destroyed: return scene::ObjectLook::destroyed;
  }
  return scene::ObjectLook::standing;
}

std::string upper(std::string s) {
  for (char& c : s) c = char(std::toupper(static_cast<unsigned char>(c)));
  return s;
}

std::string forceWord(std::uint8_t force) { return upper(sim::forceName(force)); }

long headingRounded(double deg) { return std::lround(sim::wrapDeg(deg)) % 360; }

}  // namespace

const char* viewModeName(ViewMode m) {
  switch (m) {
    case ViewMode::stealth: return "stealth";
    case ViewMode::attached: return "attached";
    case ViewMode::driving: return "driving";
  }
  return "?";
}

const char* viewerKeyName(ViewerKey k) {
  switch (k) {
    case ViewerKey::nextEntity: return "NextEntity";
    case ViewerKey::previousEntity: return "PreviousEntity";
    case ViewerKey::stealth: return "Stealth";
    case ViewerKey::drive: return "Drive";
    case ViewerKey::allStop: return "AllStop";
  }
  return "?";
}

SimSession::SimSession(std::unique_ptr<sim::Simulation> simulation, SimSessionOptions options)
    : sim_(std::move(simulation)),
      host_(*sim_),
      options_(std::move(options)),
      heightRatio_(options_.tether.heightRatio) {
  // Driving: the keys' controls advance and feed the commands before each step.
  host_.addBeforeStep([this](sim::Simulation&) {
    if (mode_ != ViewMode::driving || !driveKeys_) return;
    driveKeys_->advance(stepS());
    applyDrive();
  });
  // Objects changed before the first frame (a test, a restored state).
  const auto& objects = sim_->world().objects();
  for (std::uint32_t k = 0; k < objects.size(); ++k) {
    if (objects[k].state != sim::ObjectState::standing) changedObjects_.insert(k);
  }
  eventsSeen_ = sim_->events().size();
}

Result<std::unique_ptr<SimSession>> SimSession::create(std::unique_ptr<sim::Simulation> simulation,
                                                       SimSessionOptions options) {
  if (!simulation) return Problem{"--scenario", 0, "no simulation to show"};
  if (!(options.startS >= 0) || !std::isfinite(options.startS)) {
    return Problem{"--sim-start", 0, "--sim-start must be a number of seconds, 0 or more"};
  }
  std::unique_ptr<SimSession> s(new SimSession(std::move(simulation), std::move(options)));
  const auto entities = s->sim_->entities();
  std::optional<std::uint32_t> named;
  if (!s->options_.attach.empty()) {
    named = s->named(s->options_.attach);
    if (!named && !s->options_.attachWhenSeen) {
      std::string some;
      std::size_t k = 0;
      for (auto it = entities.begin(); it != entities.end() && k < 8; ++it, ++k) some += (k ? ", " : "") + it->name;
      if (entities.size() > 8) some += ", ...";
      std::string msg = "--attach ";
      msg += s->options_.attach;
      msg += ": no entity of that name in the scenario";
      msg += entities.empty() ? std::string(" (it has none)") : " (it has " + some + ")";
      return Problem{"--attach", 0, msg};
    }
  }
  if (s->options_.drive) {
    const std::optional<std::uint32_t> who = named ? named : s->sim_->driven;
    if (!who) {
      return Problem{"--drive", 0,
                     "--drive: the scenario marks no entity `driven`; mark one in the scenario or name it "
                     "with --attach NAME"};
    }
    const sim::Entity* e = s->sim_->find(*who);
    if (!e) return Problem{"--drive", 0, "--drive: the scenario's driven entity is not in the simulation"};
    if (e->domain == sim::Domain::munition) {
      return Problem{"--drive", 0, "--drive: " + e->name + " is a munition and cannot be driven"};
    }
    s->drive(*who);
  } else if (named) {
    s->attach(*named);
  }
  s->startSteps_ = s->host_.stepsFor(s->options_.startS);
  s->advanceToStep(s->startSteps_);
  s->sample();
  return s;
}

// ---------------------------------------------------------------- time

void SimSession::advanceToStep(std::uint64_t steps) { host_.runToStep(steps); }

void SimSession::advanceToFlightTime(double t) { advanceToStep(startSteps_ + host_.stepsFor(t)); }

void SimSession::setDrawn(std::shared_ptr<const scene::DrawnLevels> drawn) {
  sim_->world().setDrawnLevel([drawn = std::move(drawn)](double x, double z) {
    return drawn->at(x, z).value_or(world::DrawnLevel{});
  });
}

void SimSession::step() { host_.step(); }

std::optional<std::uint32_t> SimSession::named(const std::string& text) const {
  std::optional<std::uint32_t> found;
  for (const sim::Entity& e : sim_->entities()) {
    if (e.name == text) found = e.id;
  }
  if (!found && options_.findEntity) found = options_.findEntity(text);
  if (found && !sim_->find(*found)) found.reset();
  return found;
}

void SimSession::attachAwaited() {
  if (!options_.attachWhenSeen || options_.attach.empty() || attachedOnce_) return;
  if (auto id = named(options_.attach)) {
    attach(*id);
    attachedOnce_ = true;
  }
}

std::vector<EntityLabel> SimSession::labels(const Eigen::Vector3d& eye) const {
  std::vector<std::pair<double, EntityLabel>> near;
  if (!options_.labels) return {};
  for (const sim::Entity& e : sim_->entities()) {
    if (e.domain == sim::Domain::munition || e.name.empty()) continue;
    const double d = (e.position - eye).norm();
    if (d > options_.labelRangeM) continue;
    EntityLabel l;
    l.position = e.position + Eigen::Vector3d(0, std::max(2.0, e.height) + 1.5, 0);
    l.text = upper(e.name);
    l.force = e.force;
    l.alive = e.alive;
    near.emplace_back(d, std::move(l));
  }
  std::sort(near.begin(), near.end(), [](const auto& a, const auto& b) { return a.first < b.first; });
  std::vector<EntityLabel> out;
  out.reserve(near.size());
  for (auto& [d, l] : near) out.push_back(std::move(l));
  return out;
}

void SimSession::sample() {
  attachAwaited();
  const double now = sim_->timeS();
  // The attached entity may have been removed (Simulation::remove, from a
  // step hook): back to the stealth eye.
  if (attached_ && !sim_->find(*attached_)) detach();
  const auto entities = sim_->entities();
  if (aimed_.size() < sim_->nextId()) aimed_.resize(sim_->nextId(), false);
  const auto& events = sim_->events();
  for (; eventsSeen_ < events.size(); ++eventsSeen_) {
    const sim::Event& ev = events[eventsSeen_];
    if (ev.object != UINT32_MAX) changedObjects_.insert(ev.object);
    if (ev.kind == sim::EventKind::fire && ev.other < aimed_.size()) aimed_[ev.other] = true;
    if (ev.kind != sim::EventKind::detonation) continue;
    const sim::Entity* munition = sim_->find(ev.entity);
    const bool guided = munition && munition->mobility == sim::Mobility::guided;
    scene::Flash f;
    f.x = ev.position.x();
    f.y = ev.position.y();
    f.z = ev.position.z();
    f.durationS = float(options_.flashS);
    f.radiusM = guided ? 7.0f : 4.5f;
    flashes_.push_back({f, ev.timeS});
    // The trail ends where the munition went off.
    auto it = trails_.find(ev.entity);
    if (it != trails_.end()) it->second.points.push_back({ev.position, ev.timeS});
  }
  for (const sim::Entity& e : entities) {
    // Scripts write View_Direction 0 on most lines (demo.script): 0 stays "not aimed" for them too.
    if (e.gunAzimuthDeg != 0) aimed_[e.id] = true;
    if (e.domain != sim::Domain::munition || !e.alive) continue;
    TrailPoints& t = trails_[e.id];
    // Missiles leave white smoke; rounds an amber tracer.
    if (t.points.empty() && e.mobility != sim::Mobility::guided) t.rgb = {255, 196, 96};
    if (!t.points.empty() && t.points.back().timeS >= now) continue;
    t.points.push_back({e.position, now});
  }
  // Forget what has faded.
  const double trailCut = now - options_.trailS;
  for (auto it = trails_.begin(); it != trails_.end();) {
    auto& pts = it->second.points;
    pts.erase(pts.begin(), std::find_if(pts.begin(), pts.end(), [&](const Passed& p) { return p.timeS > trailCut; }));
    const sim::Entity* m = sim_->find(it->first);
    const bool flying = m && m->alive;
    it = pts.empty() && !flying ? trails_.erase(it) : std::next(it);
  }
  std::erase_if(flashes_, [&](const Detonation& d) { return now - d.timeS >= double(d.flash.durationS); });
}

// ---------------------------------------------------------------- frames

float SimSession::turretOf(const sim::Entity& e) const {
  // gunAzimuthDeg is a world azimuth and reads 0 until something aims the
  // gun: an entity that never aimed keeps its turret forward.
  if (e.id >= aimed_.size() || !aimed_[e.id]) return 0;
  return float(sim::turnBetween(e.headingDeg, e.gunAzimuthDeg));
}

float SimSession::gunOf(const sim::Entity& e) {
  // Unlike the azimuth, the elevation is relative to the hull and its 0 is
  // the gun's rest (level): no "aimed" guard is needed, an entity that
  // never set it shows its gun level. A non-finite value (a hostile PDU's
  // float) draws level rather than poisoning the vertex stage.
  return std::isfinite(e.gunElevationDeg) ? float(e.gunElevationDeg) : 0.0f;
}

void SimSession::fill(scene::DynamicScene& out) const {
  out.clear();
  const double now = sim_->timeS();
  const auto& icons = sim_->world().icons().icons;
  for (const sim::Entity& e : sim_->entities()) {
    if (e.domain == sim::Domain::munition && !e.alive) continue;
    if (e.icon >= icons.size()) continue;
    scene::DynamicInstance d;
    d.icon = e.icon;
    d.dead = !e.alive;
    d.onSurface = e.domain == sim::Domain::land || e.domain == sim::Domain::sea;
    d.shadow = e.domain == sim::Domain::land;
    d.x = e.position.x();
    d.y = e.position.y();
    d.z = e.position.z();
    if (e.domain == sim::Domain::sea) {
      // The simulator keeps a ship's keel (the icon's y = 0) at the datum;
      // drawn, it sits in the water drawn there, down to its draft.
      const auto& b = icons[e.icon].bounds;
      const double draft = std::clamp(kDraftPerLength * double(b[5] - b[2]), 0.3, 3.0);
      d.y = std::min(d.y, sim_->world().groundAt(d.x, d.z).value_or(d.y)) - draft;
    }
    const Eigen::Quaterniond q = e.orientation().normalized();
    d.orientation = {float(q.x()), float(q.y()), float(q.z()), float(q.w())};
    d.turretAzimuthDeg = turretOf(e);
    d.gunElevationDeg = gunOf(e);
    d.force = e.force;
    out.instances.push_back(d);
  }
  for (const auto& [id, t] : trails_) {
    if (t.points.size() < 2) continue;
    scene::Trail trail;
    trail.rgb = t.rgb;
    trail.lifeS = float(options_.trailS);
    for (const Passed& p : t.points) {
      trail.points.push_back({p.position.x(), p.position.y(), p.position.z(), float(now - p.timeS)});
    }
    out.trails.push_back(std::move(trail));
  }
  for (const Detonation& d : flashes_) {
    scene::Flash f = d.flash;
    f.ageS = float(now - d.timeS);
    out.flashes.push_back(f);
  }
  const auto& objects = sim_->world().objects();
  for (const std::uint32_t changed : changedObjects_) {
    // A re-meshed module (dynamic terrain) holds the object at a new index.
    const std::uint32_t k = sim_->world().currentIndex(changed);
    if (k >= objects.size()) continue;
    const sim::StaticObject& o = objects[k];
    if (o.state == sim::ObjectState::standing) continue;
    out.objectOverrides.push_back({o.moduleX, o.moduleZ, o.index, lookOf(o.state)});
  }
  std::sort(out.objectOverrides.begin(), out.objectOverrides.end());
  const auto same = [](const scene::ObjectOverride& a, const scene::ObjectOverride& b) { return a.key() == b.key(); };
  out.objectOverrides.erase(std::unique(out.objectOverrides.begin(), out.objectOverrides.end(), same),
                            out.objectOverrides.end());
}

std::vector<render::MapMark> SimSession::mapMarks() const {
  std::vector<render::MapMark> marks;
  if (options_.extraMarks) marks = options_.extraMarks();
  for (const sim::Entity& e : sim_->entities()) {
    if (!isTarget(e)) continue;
    render::MapMark m;
    m.x = e.position.x(), m.z = e.position.z();
    m.headingDeg = e.headingDeg;
    m.force = e.force;
    m.alive = e.alive;
    m.selected = attached_ == e.id;
    marks.push_back(m);
  }
  return marks;
}

std::optional<std::uint32_t> SimSession::focus() const { return attached_ ? attached_ : sim_->driven; }

std::vector<std::string> SimSession::panelLines() const {
  std::vector<std::string> lines;
  const sim::Census n = sim::census(*sim_);
  const std::uint32_t alive = n.alive, total = n.total, flying = n.munitionsInFlight;
  char buf[160];
  std::snprintf(buf, sizeof buf, "SIM %.1f S  ENTITIES %u/%u ALIVE", sim_->timeS(), alive, total);
  lines.emplace_back(buf);
  if (flying > 0) lines.back() += "  MUNITIONS " + std::to_string(flying);
  if (options_.extraPanel) {
    for (std::string& l : options_.extraPanel()) lines.push_back(std::move(l));
  }
  std::string view = mode_ == ViewMode::stealth    ? "VIEW STEALTH"
                     : mode_ == ViewMode::attached ? "VIEW ATTACHED TO "
                                                   : "DRIVING ";
  if (const sim::Entity* a = attached_ ? sim_->find(*attached_) : nullptr) view += upper(a->name);
  lines.push_back(view);
  const auto who = focus();
  const sim::Entity* focused = who ? sim_->find(*who) : nullptr;
  if (!focused) return lines;
  const sim::Entity& e = *focused;
  lines.push_back(upper(e.name) + "  " + upper(e.iconName) + "  " + forceWord(e.force) + "  " +
                  (e.alive ? "ALIVE" : "DEAD"));
  std::snprintf(buf, sizeof buf, "SPD %.0f KM/H  HDG %03ld\xC2\xB0  FUEL %.0f%%", std::abs(e.speedMs) * kMsToKmh,
                headingRounded(e.headingDeg), std::clamp(e.fuel, 0.0, 1.0) * 100.0);
  lines.emplace_back(buf);
  if (e.domain == sim::Domain::air) {
    std::snprintf(buf, sizeof buf, "ALT %.0f M  AGL %.0f M  PITCH %.0f\xC2\xB0  ROLL %.0f\xC2\xB0", e.position.y(),
                  e.heightAgl, e.pitchDeg, e.rollDeg);
    lines.emplace_back(buf);
  }
  if (mode_ == ViewMode::driving && attached_ == who) {
    const sim::Commands& c = e.commands;
    std::snprintf(buf, sizeof buf, "CMD %.0f KM/H  %03ld\xC2\xB0", c.speedMs * kMsToKmh, headingRounded(c.headingDeg));
    lines.emplace_back(buf);
    if (e.domain == sim::Domain::air) lines.back() += "  ALT " + std::to_string(std::lround(c.altitudeM)) + " M";
  }
  return lines;
}

std::string SimSession::frameJson() const {
  const sim::Census n = sim::census(*sim_);
  const std::uint32_t alive = n.alive, total = n.total, flying = n.munitionsInFlight;
  nlohmann::json j = {{"time_s", sim_->timeS()},
                      {"steps", sim_->steps()},
                      {"entities", total},
                      {"alive", alive},
                      {"munitions_in_flight", flying},
                      {"trails", trails_.size()},
                      {"flashes", flashes_.size()},
                      {"objects_changed", changedObjects_.size()},
                      {"view", viewModeName(mode_)}};
  j["attached"] = nameJson(attached_);
  if (const sim::Entity* focused = focus() ? sim_->find(*focus()) : nullptr) {
    const sim::Entity& e = *focused;
    const auto who = focus();
    j["focus"] = {{"name", e.name},          {"alive", e.alive},
                  {"speed_kmh", std::abs(e.speedMs) * kMsToKmh},
                  {"heading", e.headingDeg}, {"fuel", e.fuel},
                  {"x", e.position.x()},     {"y", e.position.y()},
                  {"z", e.position.z()}};
    if (mode_ == ViewMode::driving && attached_ == who) {
      j["focus"]["command_speed_kmh"] = e.commands.speedMs * kMsToKmh;
      j["focus"]["command_heading"] = e.commands.headingDeg;
    }
  }
  return j.dump();
}

nlohmann::json SimSession::nameJson(std::optional<std::uint32_t> id) const {
  const std::string* name = id ? sim_->nameOf(*id) : nullptr;
  return name ? nlohmann::json(*name) : nlohmann::json(nullptr);
}

std::string SimSession::summaryJson() const {
  nlohmann::json j = sim::summaryJson(*sim_);
  j["seed"] = sim_->options().seed;
  j["scenario"] = options_.scenario;
  j["view"] = viewModeName(mode_);
  j["attached"] = nameJson(attached_);
  j["driven"] = nameJson(sim_->driven);
  return j.dump();
}

std::string SimSession::summaryLine() const {
  std::uint32_t alive = 0, total = 0;
  for (const sim::Entity& e : sim_->entities()) {
    if (!isTarget(e)) continue;
    ++total;
    alive += e.alive;
  }
  const sim::SimCounters& c = sim_->counters();
  char buf[200];
  std::snprintf(buf, sizeof buf, "%.1f s simulated, %u/%u entities alive, %llu fired, %llu detonations, %zu objects changed",
                sim_->timeS(), alive, total, static_cast<unsigned long long>(c.fired),
                static_cast<unsigned long long>(c.detonations), changedObjects_.size());
  return buf;
}

// ---------------------------------------------------------------- the view

void SimSession::attach(std::uint32_t id) {
  if (!sim_->find(id)) return;
  if (attached_ != id) {
    tetherHeading_.reset();
    tetherTime_.reset();
    orbitDeg_ = 0;
  }
  attached_ = id;
  mode_ = ViewMode::attached;
  driveKeys_.reset();
}

void SimSession::detach() {
  attached_.reset();
  mode_ = ViewMode::stealth;
  driveKeys_.reset();
}

void SimSession::seedDrive(const sim::Entity& e) {
  world::ViewerState s;
  s.headingDeg = e.commands.headingDeg;
  s.speedMs = e.commands.speedMs;
  s.groundFollowing = false;
  s.eyeElevation = e.domain == sim::Domain::air ? e.commands.altitudeM : 0;
  world::ControllerSettings cs;
  cs.speedStepMs = options_.driving.speedStepMs;
  cs.maxSpeedMs = std::max(e.vehicle.maxSpeedMs, 1.0);
  cs.minSpeedMs = e.domain == sim::Domain::air ? 0 : -options_.driving.reverseFraction * cs.maxSpeedMs;
  cs.turnStepDeg = options_.driving.turnStepDeg;
  cs.turnRateDegS = options_.driving.turnRateDegS;
  cs.climbStepM = options_.driving.climbStepM;
  cs.climbRateMS = options_.driving.climbRateMS;
  cs.minHeightAglM = 0;
  driveKeys_.emplace(s, world::GroundElevationFn{}, cs);
}

void SimSession::drive(std::uint32_t id) {
  sim::Entity* found = sim_->find(id);
  if (!found || !isTarget(*found)) return;
  attach(id);
  mode_ = ViewMode::driving;
  sim::Entity& e = *found;
  e.controller = sim::Controller::driven;
  // Land dynamics need the autopilot to turn commands into track forces;
  // simple and ship mobility read the commands themselves.
  e.autopilot = true;
  sim_->driven = id;
  seedDrive(e);
}

void SimSession::stopDriving() {
  if (mode_ != ViewMode::driving) return;
  mode_ = ViewMode::attached;
  driveKeys_.reset();
}

void SimSession::applyDrive() {
  sim::Entity* driven = attached_ && driveKeys_ ? sim_->find(*attached_) : nullptr;
  if (!driven || !driven->alive) return;
  sim::Entity& e = *driven;
  const world::ViewerState& s = driveKeys_->state();
  e.commands.speedMs = s.speedMs;
  e.commands.headingDeg = s.headingDeg;
  if (e.domain == sim::Domain::air) e.commands.altitudeM = s.eyeElevation;
  e.autopilot = true;
}

std::optional<std::pair<double, double>> SimSession::driveCommands() const {
  if (mode_ != ViewMode::driving || !driveKeys_) return std::nullopt;
  return std::pair{driveKeys_->state().speedMs, driveKeys_->state().headingDeg};
}

void SimSession::allStop() {
  std::optional<std::uint32_t> who = attached_ ? attached_ : sim_->driven;
  sim::Entity* found = who ? sim_->find(*who) : nullptr;
  if (!found) return;
  sim::Entity& e = *found;
  sim::allStop(e);
  if (mode_ == ViewMode::driving && attached_ == who) seedDrive(e);
}

void SimSession::handle(ViewerKey k) {
  const auto entities = sim_->entities();
  switch (k) {
    case ViewerKey::nextEntity:
    case ViewerKey::previousEntity: {
      std::vector<std::uint32_t> ids;
      for (const sim::Entity& e : entities) {
        if (isTarget(e)) ids.push_back(e.id);
      }
      if (ids.empty()) return;
      const std::optional<std::uint32_t> from = attached_ ? attached_ : focus();
      std::size_t at = 0;
      if (from) {
        const auto it = std::find(ids.begin(), ids.end(), *from);
        const std::size_t here = it == ids.end() ? 0 : std::size_t(it - ids.begin());
        // From the stealth eye the first press attaches to the focus itself.
        const std::size_t step = attached_ ? 1 : 0;
        at = k == ViewerKey::nextEntity ? (here + step) % ids.size() : (here + ids.size() - step) % ids.size();
      }
      attach(ids[at]);
      break;
    }
    case ViewerKey::stealth: detach(); break;
    case ViewerKey::drive:
      if (mode_ == ViewMode::driving) {
        stopDriving();
      } else if (const auto who = attached_ ? attached_ : sim_->driven) {
        drive(*who);
      } else {
        for (const sim::Entity& e : entities) {
          if (e.domain == sim::Domain::land) {
            drive(e.id);
            break;
          }
        }
      }
      break;
    case ViewerKey::allStop: allStop(); break;
  }
}

bool SimSession::steers(world::Key k) const {
  if (mode_ == ViewMode::stealth) return false;
  return k == world::Key::up || k == world::Key::down || k == world::Key::left || k == world::Key::right || k == world::Key::pageUp ||
         k == world::Key::pageDown;
}

void SimSession::handle(const world::KeyEvent& e) {
  if (!steers(e.key)) return;
  const sim::Entity* a = attached_ ? sim_->find(*attached_) : nullptr;
  const bool air = a && a->domain == sim::Domain::air;
  const bool pages = e.key == world::Key::pageUp || e.key == world::Key::pageDown;
  if (mode_ == ViewMode::driving && driveKeys_ && (!pages || air)) {
    driveKeys_->handle(e);
    return;
  }
  if (!e.pressed) return;
  switch (e.key) {
    case world::Key::up: zoom_ = std::max(0.25, zoom_ / 1.25); break;
    case world::Key::down: zoom_ = std::min(8.0, zoom_ * 1.25); break;
    case world::Key::left: orbitDeg_ = sim::wrapDeg(orbitDeg_ - 15); break;
    case world::Key::right: orbitDeg_ = sim::wrapDeg(orbitDeg_ + 15); break;
    case world::Key::pageUp: heightRatio_ = std::min(2.0, heightRatio_ + 0.1); break;
    case world::Key::pageDown: heightRatio_ = std::max(0.05, heightRatio_ - 0.1); break;
    default: break;
  }
}

world::Pose SimSession::tetherPose(world::GroundClamp& ground) {
  const sim::Entity* attached = attached_ ? sim_->find(*attached_) : nullptr;
  if (!attached) return world::Pose{};
  const sim::Entity& e = *attached;
  const TetherSettings& t = options_.tether;
  const double now = sim_->timeS();
  const double target = sim::wrapDeg(e.headingDeg + orbitDeg_);
  if (!tetherHeading_ || !tetherTime_) {
    tetherHeading_ = target;
  } else {
    const double dt = std::max(0.0, now - *tetherTime_);
    const double k = t.headingLagS > 0 ? 1.0 - std::exp(-dt / t.headingLagS) : 1.0;
    tetherHeading_ = sim::wrapDeg(*tetherHeading_ + sim::turnBetween(*tetherHeading_, target) * k);
  }
  tetherTime_ = now;
  const double size = std::max({e.halfLength, e.halfWidth, e.radius, e.height, 2.0});
  const double distance = std::clamp(t.sizeFactor * size, t.minDistanceM, t.maxDistanceM) * zoom_;
  const Eigen::Vector3d back = sim::headingVector(*tetherHeading_);
  const Eigen::Vector3d eye = e.position - back * distance + Eigen::Vector3d(0, heightRatio_ * distance, 0);
  const double originE = sim_->world().originEasting(), originN = sim_->world().originNorthing();
  world::Pose p;
  p.easting = originE + eye.x();
  p.northing = originN - eye.z();
  const double g = ground.groundEN(p.easting, p.northing);
  // Behind an entity going downhill the ground rises towards the eye: it
  // stays a quarter of the distance above that ground, looking down more.
  const double altitude = std::max(eye.y(), g + std::max(t.minAglM, 0.25 * distance));
  const double lookY = e.position.y() + 0.5 * e.height;
  p.headingDeg = *tetherHeading_;
  p.pitchDeg = std::clamp(std::atan2(lookY - altitude, distance) * kRadToDeg + t.pitchBiasDeg, -89.0, 89.0);
  p.altitude = altitude;
  p.heightAgl = altitude - g;
  p.speedKmh = std::abs(e.speedMs) * kMsToKmh;
  return p;
}

}  // namespace sandtable::viewer
