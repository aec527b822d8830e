#include "dis_link.h"

#include <chrono>
#include <cstdio>

#include "commands.h"
#include "sandtable/geodesy/geodesy.h"

namespace sandtable::cli {

void addDisOptions(CLI::App* sub, DisArgs& a) {
  sub->add_option("--dis", a.endpoint,
                  "Join a DIS exercise: [ADDR:]PORT (broadcast by default, a 224-239 group for multicast, "
                  "else unicast; port 3000 by default; docs/DIS.md §7)");
  sub->add_option("--dis-interface", a.interface, "Network interface for --dis (e.g. eth0; default: the routing table's)");
  sub->add_option("--exercise", a.exercise, "DIS exercise id, 1-255 (default 1): PDUs of other exercises are ignored");
  sub->add_option("--site", a.site, "DIS site number of this simulation, 1-65534 (default 1)");
  sub->add_option("--application", a.application, "DIS application number of this simulation, 1-65534 (default 1)");
}

std::unique_ptr<DisLink> openDisLink(const std::string& cmd, const manifest::Manifest& m, sim::Simulation& s,
                                     const DisArgs& a) {
  if (a.exercise < 1 || a.exercise > 255) return usageError(cmd, "--exercise must be 1 to 255"), nullptr;
  if (a.site < 1 || a.site > 65534 || a.application < 1 || a.application > 65534) {
    return usageError(cmd, "--site and --application must be 1 to 65534 (0 and 65535 mean none and all in DIS)"),
           nullptr;
  }
  dis::SocketOptions base;
  base.interface = a.interface;
  auto options = dis::parseDisEndpoint(a.endpoint, base);
  if (!options) return reportProblems(cmd, options.problems()), nullptr;
  auto socket = dis::UdpSocket::open(options.value());
  if (!socket) return reportProblems(cmd, socket.problems()), nullptr;
  auto frame = geodesy::DatabaseFrame::create(m.crsWkt, m.originEasting, m.originNorthing);
  if (!frame) {
    return usageError(cmd, "--dis needs the database's coordinate system (DIS positions are geocentric): " +
                               frame.message() + "; rebuild the database with a CRS (--crs)"),
           nullptr;
  }
  auto receiver = dis::Receiver::start(std::move(socket.value()));
  if (!receiver) return reportProblems(cmd, receiver.problems()), nullptr;
  auto link = std::make_unique<DisLink>();
  link->receiver = std::move(receiver.value());
  sim_dis::GatewayOptions g;
  g.exercise = std::uint8_t(a.exercise);
  g.site = std::uint16_t(a.site);
  g.application = std::uint16_t(a.application);
  g.publish = a.publish;
  g.absoluteTime = true;  // networked runs are paced to the wall clock
  dis::Receiver* r = link->receiver.get();
  DisLink* l = link.get();
  link->gateway = std::make_unique<sim_dis::Gateway>(
      s, sim_dis::DisFrame(frame.value()), g, [r](std::vector<dis::Datagram>& out) { r->drain(out); },
      [r, l](std::span<const std::byte> bytes) {
        if (Status st = r->socket().send(bytes); !st) {
          if (l->sendErrors++ == 0) l->firstSendError = st.error();
        }
      });
  std::fprintf(stderr, "sandtable %s: DIS %s, exercise %u, site %u, application %u%s\n", cmd.c_str(),
               link->receiver->socket().endpoint().text().c_str(), a.exercise, a.site, a.application,
               a.publish ? "" : " (watching only)");
  return link;
}

std::string disPanelLine(const DisLink& link, std::pair<double, std::uint64_t>& last) {
  const sim_dis::GatewayCounters& c = link.gateway->counters();
  const dis::ReceiverCounters rc = link.receiver->counters();
  const double now = std::chrono::duration<double>(std::chrono::steady_clock::now().time_since_epoch()).count();
  static thread_local double rate = 0;
  if (last.first < 0) {
    last = {now, c.pdus};
  } else if (now - last.first >= 1.0) {
    rate = double(c.pdus - last.second) / (now - last.first);
    last = {now, c.pdus};
  }
  const std::uint64_t dropped = rc.queueDropped + rc.kernelDropped + c.malformed;
  char line[200];
  std::snprintf(line, sizeof line, "DIS %.0f PDU/S  %zu TRACKED  %llu CORRECTIONS  %llu DROPPED", rate,
                link.gateway->remotes().size(), (unsigned long long)link.gateway->remotes().counters().corrections,
                (unsigned long long)dropped);
  return line;
}

std::string disSummary(const DisLink& link) {
  const sim_dis::GatewayCounters& c = link.gateway->counters();
  const sim_dis::RemoteCounters& r = link.gateway->remotes().counters();
  const dis::ReceiverCounters rc = link.receiver->counters();
  char line[512];
  std::snprintf(line, sizeof line,
                "dis: sent %llu PDUs (%llu bytes); received %llu datagrams, %llu PDUs: %llu entity states, %llu fires, "
                "%llu detonations, %llu removes; ignored %llu own, %llu other exercise, %llu unknown type; "
                "%llu malformed; %zu remote entities tracked, %llu corrections (largest %.2f m), %llu timed out; "
                "%llu send errors\n",
                (unsigned long long)c.sentPdus, (unsigned long long)c.sentBytes, (unsigned long long)rc.datagrams,
                (unsigned long long)c.pdus, (unsigned long long)c.entityStates, (unsigned long long)c.fires,
                (unsigned long long)c.detonations, (unsigned long long)c.removes, (unsigned long long)c.own,
                (unsigned long long)c.otherExercise, (unsigned long long)c.unknownType,
                (unsigned long long)c.malformed, link.gateway->remotes().size(),
                (unsigned long long)r.corrections, r.maxCorrectionM, (unsigned long long)r.timedOut,
                (unsigned long long)link.sendErrors);
  return line;
}

}  // namespace sandtable::cli

namespace sandtable::cli {

namespace {

std::string idText(const dis::EntityId& id) {
  return std::to_string(id.site) + ":" + std::to_string(id.application) + ":" + std::to_string(id.entity);
}

nlohmann::json xyz(const Eigen::Vector3d& p) { return {p.x(), p.y(), p.z()}; }

/// Adds lon, lat (WGS-84 degrees) and height (metres above the ellipsoid)
/// of a frame position to `j`, so a report can be checked against a
/// sender's geodetic positions without this database's frame; nothing
/// when PROJ cannot convert it.
void addGeodetic(nlohmann::json& j, const geodesy::DatabaseFrame& frame, const Eigen::Vector3d& p) {
  const auto g = frame.toLonLatHeight({p.x(), p.y(), p.z()});
  if (!g) return;
  j["lon"] = g->lon;
  j["lat"] = g->lat;
  j["height"] = g->height;
}

}  // namespace

nlohmann::json disJson(const DisLink& link, const sim::Simulation& s) {
  const sim_dis::GatewayCounters& c = link.gateway->counters();
  const sim_dis::RemoteCounters& r = link.gateway->remotes().counters();
  const dis::ReceiverCounters rc = link.receiver->counters();
  const geodesy::DatabaseFrame& frame = link.gateway->remotes().frame().frame();
  nlohmann::json remotes = nlohmann::json::array();
  for (const auto& [key, e] : link.gateway->remotes().all()) {
    const sim::Entity* shown = e.simId == UINT32_MAX ? nullptr : s.find(e.simId);
    nlohmann::json j = {{"id", idText(e.id)},
                        {"marking", e.last.marking.text()},
                        {"sender", e.sender.text()},
                        {"updates", e.updates},
                        {"sim_id", e.simId == UINT32_MAX ? nlohmann::json(nullptr) : nlohmann::json(e.simId)}};
    if (shown) {
      j["position"] = xyz(shown->position);  // as this simulation shows it at its last step
      addGeodetic(j, frame, shown->position);
      j["heading_deg"] = shown->headingDeg;
      j["alive"] = shown->alive;
      j["icon"] = shown->icon;
    }
    remotes.push_back(std::move(j));
  }
  nlohmann::json departed = nlohmann::json::array();
  for (const sim_dis::Departed& d : link.gateway->departed()) {
    nlohmann::json j = {{"id", idText(d.id)}, {"marking", d.marking}, {"why", d.why}, {"position", xyz(d.position)}};
    addGeodetic(j, frame, d.position);
    departed.push_back(std::move(j));
  }
  nlohmann::json local = nlohmann::json::array();
  for (const sim::Entity& e : s.entities()) {
    if (e.controller == sim::Controller::remote || e.domain == sim::Domain::munition) continue;
    local.push_back({{"id", idText(link.gateway->disId(e.id))}, {"name", e.name}, {"position", xyz(e.position)}});
  }
  // The wall clock now, just after the last step: a sender on this host
  // can tell where its entities were at the moment the positions show.
  const double unixS = std::chrono::duration<double>(std::chrono::system_clock::now().time_since_epoch()).count();
  return {{"unix_time_s", unixS},
          {"sent_pdus", c.sentPdus},
          {"sent_bytes", c.sentBytes},
          {"send_errors", link.sendErrors},
          {"datagrams", rc.datagrams},
          {"queue_dropped", rc.queueDropped},
          {"kernel_dropped", rc.kernelDropped},
          {"pdus", c.pdus},
          {"entity_states", c.entityStates},
          {"fires", c.fires},
          {"detonations", c.detonations},
          {"removes", c.removes},
          {"own", c.own},
          {"other_exercise", c.otherExercise},
          {"unknown_type", c.unknownType},
          {"malformed", c.malformed},
          {"last_malformed", c.lastMalformed},
          {"hits_taken", c.hitsTaken},
          {"unknown_icons", c.unknownIcons},
          {"corrections", r.corrections},
          {"largest_correction_m", r.maxCorrectionM},
          {"timed_out", r.timedOut},
          {"conflicts", r.conflicts},
          {"stale", r.stale},
          {"duplicates", r.duplicates},
          {"non_finite", r.nonFinite},
          {"remote_entities", remotes},
          {"departed", departed},
          {"local_entities", local}};
}

}  // namespace sandtable::cli
