// sandtable dis: the network monitor and the data logger (docs/DIS.md §7;
// seed XI.B.2, NPSStealth's "when, who, how often, and what types of
// packets"). `inspect` reads a capture, `monitor` watches a port live,
// `record` writes what arrives to a pcap, `play` sends a capture again at
// its recorded pace, `to-script` / `from-script` convert between a capture
// and a seed Figure 71 script. The monitor itself is net/dis's Monitor and
// the conversions are sim_dis/script_pcap.h; this file parses flags,
// converts coordinates for printing (geodesy) and prints.
#include <unistd.h>

#include <algorithm>
#include <atomic>
#include <chrono>
#include <cmath>
#include <csignal>
#include <cstdio>
#include <limits>
#include <map>
#include <optional>
#include <string>
#include <thread>
#include <vector>

#include <nlohmann/json.hpp>

#include "commands.h"
#include "db_util.h"
#include "sandtable/dis/monitor.h"
#include "sandtable/dis/orientation.h"
#include "sandtable/dis/pcap.h"
#include "sandtable/dis/socket.h"
#include "sandtable/formats/bytes.h"
#include "sandtable/formats/dis_icons.h"
#include "sandtable/geodesy/geodesy.h"
#include "sandtable/sim/sim_world.h"
#include "sandtable/sim_dis/script_pcap.h"

namespace sandtable::cli {
namespace {

constexpr double kPi = 3.14159265358979323846;
constexpr double kDeg = 180.0 / kPi;

std::atomic<bool> gStop{false};
void onSignal(int) { gStop.store(true); }
void stopOnSignals() {
  gStop.store(false);
  std::signal(SIGINT, onSignal);
  std::signal(SIGTERM, onSignal);
}

// ------------------------------------------------------------ words

std::string idText(const dis::EntityId& id) {
  return std::to_string(id.site) + ":" + std::to_string(id.application) + ":" + std::to_string(id.entity);
}

std::string typeText(const dis::EntityType& t) {
  return std::to_string(t.kind) + "." + std::to_string(t.domain) + "." + std::to_string(t.country) + "." +
         std::to_string(t.category) + "." + std::to_string(t.subcategory) + "." + std::to_string(t.specific) + "." +
         std::to_string(t.extra);
}

const char* forceName(std::uint8_t f) {
  switch (f) {
    case 0: return "other";
    case 1: return "friendly";
    case 2: return "opposing";
    case 3: return "neutral";
    default: return "?";
  }
}

/// DIS dead-reckoning algorithm names (IEEE 1278.1 Annex E).
std::string algorithmName(std::uint8_t a) {
  static const char* const kNames[] = {"Other", "Static", "FPW", "RPW", "RVW", "FVW", "FPB", "RPB", "RVB", "FVB"};
  return a < 10 ? kNames[a] : std::to_string(a);
}

std::string typeName(std::uint8_t type) {
  const auto n = dis::pduTypeName(type);
  return n.empty() ? "type " + std::to_string(type) : std::string(n);
}

std::string fixed(double v, int decimals) {
  if (std::fabs(v) < 0.5 * std::pow(10.0, -decimals)) v = 0;  // no "-0.0"
  char b[64];
  std::snprintf(b, sizeof b, "%.*f", decimals, v);
  return b;
}

// ------------------------------------------------------ coordinates

/// Where an entity is and how it is turned, in the words a user reads:
/// WGS-84 lon/lat/height and local heading, pitch and roll (true north).
struct Placed {
  std::optional<geodesy::LonLatHeight> geodetic;
  std::optional<dis::Attitude> attitude;  // radians
};

Placed place(const dis::Vec3d& ecef, const dis::Euler& e) {
  Placed p;
  auto g = geodesy::fromEcef({ecef.x, ecef.y, ecef.z});
  if (!g.ok()) return p;
  p.geodetic = g.value();
  p.attitude = dis::toAttitude(dis::trueAxes(g->lat / kDeg, g->lon / kDeg), e);
  return p;
}

double headingDeg(double radians) {
  double h = std::fmod(radians * kDeg, 360.0);
  if (h < 0) h += 360.0;
  // -0 and a hair under 360 (a rounding of north) both read as 0.
  return h >= 360.0 - 1e-9 ? 0.0 : h + 0.0;
}

nlohmann::json vecJson(double x, double y, double z) { return {{"x", x}, {"y", y}, {"z", z}}; }

/// location (ECEF as the PDU carries it), geodetic, orientation (the PDU's
/// psi, theta, phi in radians) and attitude (degrees).
void placeJson(nlohmann::json& j, const dis::Vec3d& ecef, const dis::Euler& e) {
  j["location"] = vecJson(ecef.x, ecef.y, ecef.z);
  j["orientation"] = {{"psi", e.psi}, {"theta", e.theta}, {"phi", e.phi}};
  const Placed p = place(ecef, e);
  if (p.geodetic) {
    j["geodetic"] = {{"lon_deg", p.geodetic->lon}, {"lat_deg", p.geodetic->lat}, {"height_m", p.geodetic->height}};
  }
  if (p.attitude) {
    j["attitude"] = {{"heading_deg", headingDeg(p.attitude->heading)},
                     {"pitch_deg", p.attitude->pitch * kDeg},
                     {"roll_deg", p.attitude->roll * kDeg}};
  }
}

// ------------------------------------------------------------- JSON

/// The states of every entity at one time (`inspect --at`).
struct StatesAt {
  double atS = 0;  ///< seconds after the first packet
  std::map<std::pair<std::uint8_t, std::uint64_t>, dis::EntityStateAt> states;
};

std::uint64_t idKey(const dis::EntityId& id) {
  return (std::uint64_t(id.site) << 32) | (std::uint64_t(id.application) << 16) | id.entity;
}

StatesAt statesAt(const dis::Monitor& m, double atS) {
  StatesAt out;
  out.atS = atS;
  const double t0 = m.firstTime().value_or(0.0);
  for (const dis::EntityReport& e : m.report().entities) {
    if (auto s = m.state(e.exercise, e.id, t0 + atS)) out.states.emplace(std::pair(e.exercise, idKey(e.id)), *s);
  }
  return out;
}

nlohmann::json entityJson(const dis::EntityReport& e, double t0, const StatesAt* at) {
  nlohmann::json j = {{"exercise", e.exercise},
                      {"id", idText(e.id)},
                      {"site", e.id.site},
                      {"application", e.id.application},
                      {"entity", e.id.entity},
                      {"sender", e.sender.text()},
                      {"type", typeText(e.type)},
                      {"force", e.force},
                      {"force_name", forceName(e.force)},
                      {"marking", e.marking},
                      {"appearance", e.appearance},
                      {"dr_algorithm", e.algorithm},
                      {"dr_algorithm_name", algorithmName(e.algorithm)},
                      {"dr_algorithms", e.algorithms},
                      {"updates", e.updates},
                      {"first_s", e.firstS - t0},
                      {"last_s", e.lastS - t0},
                      {"largest_gap_s", e.largestGapS},
                      {"velocity", vecJson(e.velocity.x, e.velocity.y, e.velocity.z)}};
  placeJson(j, e.location, e.orientation);
  nlohmann::json parts = nlohmann::json::array();
  for (const dis::ArticulatedPart& p : e.articulated) {
    parts.push_back({{"parameter_type", p.parameterType},
                     {"part_class", p.parameterType / 32 * 32},
                     {"metric", p.parameterType % 32},
                     {"value", p.value},
                     {"change", p.change},
                     {"attached_to", p.attachedTo}});
  }
  j["articulated"] = parts;
  nlohmann::json stores = nlohmann::json::array();
  for (const dis::AttachedPart& p : e.attached) {
    stores.push_back({{"station", p.station},
                      {"type", typeText(p.type)},
                      {"detached", p.detached != 0},
                      {"attached_to", p.attachedTo}});
  }
  j["attached"] = stores;
  j["other_records"] = e.otherRecords;
  if (at) {
    const auto it = at->states.find({e.exercise, idKey(e.id)});
    if (it != at->states.end()) {
      const dis::EntityStateAt& s = it->second;
      nlohmann::json a = {{"time_s", at->atS},
                          {"pdu_time_s", s.pduTimeS - t0},
                          {"dt_s", s.atS - s.pduTimeS},
                          {"velocity", vecJson(s.worldVelocity.x, s.worldVelocity.y, s.worldVelocity.z)}};
      placeJson(a, s.location, s.orientation);
      j["at"] = a;
    }
  }
  return j;
}

nlohmann::json reportJson(const dis::Report& r, const StatesAt* at) {
  const double t0 = r.firstS;
  nlohmann::json senders = nlohmann::json::array();
  for (const dis::SenderReport& s : r.senders) {
    nlohmann::json types = nlohmann::json::array();
    for (const dis::TypeCount& t : s.types) {
      types.push_back({{"type", t.type}, {"name", typeName(t.type)}, {"count", t.count}, {"rate_per_s", t.ratePerS}});
    }
    senders.push_back({{"address", s.address.text()},
                       {"site_application", s.hasSiteApplication ? std::to_string(s.site) + ":" +
                                                                        std::to_string(s.application)
                                                                  : std::string()},
                       {"pdus", s.pdus},
                       {"rate_per_s", s.ratePerS},
                       {"types", types},
                       {"unknown_types", s.unknownTypes},
                       {"malformed", s.malformed},
                       {"fires", s.fires},
                       {"detonations", s.detonations},
                       {"entities", s.entities},
                       {"first_s", s.firstS - t0},
                       {"last_s", s.lastS - t0},
                       {"largest_gap_s", s.largestGapS},
                       {"largest_heartbeat_gap_s", s.largestHeartbeatGapS}});
  }
  nlohmann::json entities = nlohmann::json::array();
  for (const dis::EntityReport& e : r.entities) entities.push_back(entityJson(e, t0, at));
  nlohmann::json reasons = nlohmann::json::array();
  for (const dis::ReasonReport& x : r.reasons) {
    nlohmann::json examples = nlohmann::json::array();
    for (const dis::MalformedExample& m : x.examples) {
      examples.push_back({{"datagram", m.datagram},
                          {"time_s", m.timeS - t0},
                          {"sender", m.sender.text()},
                          {"offset", m.offset},
                          {"message", m.message}});
    }
    reasons.push_back({{"reason", x.reason}, {"count", x.count}, {"examples", examples}});
  }
  nlohmann::json conflicts = nlohmann::json::array();
  for (const dis::ConflictReport& c : r.conflicts) {
    conflicts.push_back({{"exercise", c.exercise},
                         {"id", idText(c.id)},
                         {"owner", c.owner.text()},
                         {"other", c.other.text()},
                         {"pdus", c.pdus}});
  }
  nlohmann::json j = {{"start_time_s", t0},
                      {"window_s", r.windowS},
                      {"datagrams", r.datagrams},
                      {"pdus", r.pdus},
                      {"other_exercise", r.otherExercise},
                      {"unknown_types", r.unknownTypes},
                      {"fires", r.fires},
                      {"detonations", r.detonations},
                      {"malformed", {{"count", r.malformed}, {"reasons", reasons}}},
                      {"senders", senders},
                      {"entities", entities},
                      {"conflicts", {{"pdus", r.conflictPdus}, {"ids", conflicts}}},
                      {"capped",
                       {{"senders", r.capped.senders},
                        {"entities", r.capped.entities},
                        {"reasons", r.capped.reasons},
                        {"conflicts", r.capped.conflicts}}}};
  if (at) j["at_s"] = at->atS;
  return j;
}

// ------------------------------------------------------------ tables

/// Prints rows as left-aligned columns two spaces apart, the first row a header.
void printTable(std::FILE* out, const std::vector<std::vector<std::string>>& rows, const std::string& indent = "  ") {
  if (rows.size() <= 1) {
    std::fprintf(out, "%s(none)\n", indent.c_str());
    return;
  }
  std::vector<std::size_t> width;
  for (const auto& row : rows) {
    width.resize(std::max(width.size(), row.size()), 0);
    for (std::size_t k = 0; k < row.size(); ++k) width[k] = std::max(width[k], row[k].size());
  }
  for (const auto& row : rows) {
    std::string line = indent;
    for (std::size_t k = 0; k < row.size(); ++k) {
      line += row[k];
      if (k + 1 < row.size()) line += std::string(width[k] - row[k].size() + 2, ' ');
    }
    std::fprintf(out, "%s\n", line.c_str());
  }
}

/// "ES 12  Fire 1  Comment 1": the short names of the common types.
std::string typesText(const dis::SenderReport& s) {
  std::string out;
  for (const dis::TypeCount& t : s.types) {
    std::string name = t.type == 1 ? "ES" : t.type == 2 ? "Fire" : t.type == 3 ? "Det" : typeName(t.type);
    if (!out.empty()) out += "  ";
    out += name + " " + std::to_string(t.count);
  }
  return out.empty() ? "-" : out;
}

std::string partsText(const dis::EntityReport& e) {
  std::string out;
  for (const dis::ArticulatedPart& p : e.articulated) {
    if (!out.empty()) out += " ";
    // SISO-REF-010's metrics 11-16 are azimuth, elevation and rotation and
    // their rates (radians, rad/s): shown in degrees; 1-10 are metres and m/s.
    const std::uint32_t metric = p.parameterType % 32;
    const bool angle = metric >= 11 && metric <= 16;
    const std::string unit = angle ? (metric % 2 == 0 ? "deg/s" : "deg") : "";
    out += std::to_string(p.parameterType) + "=" + (angle ? fixed(p.value * kDeg, 1) : fixed(p.value, 2)) + unit;
  }
  for (const dis::AttachedPart& p : e.attached) {
    if (!out.empty()) out += " ";
    out += "st" + std::to_string(p.station) + ":" + typeText(p.type) + (p.detached ? "(off)" : "");
  }
  return out.empty() ? "-" : out;
}

/// `maxEntities` bounds the entity rows (the live table, redrawn each second).
void printReport(std::FILE* out, const dis::Report& r, const StatesAt* at,
                 std::size_t maxEntities = std::numeric_limits<std::size_t>::max()) {
  const double t0 = r.firstS;
  std::fprintf(out, "%s s, %llu datagrams, %llu PDUs (%llu Fire, %llu Detonation, %llu of undecoded types), "
                    "%llu malformed, %llu of other exercises\n",
               fixed(r.windowS, 1).c_str(), (unsigned long long)r.datagrams, (unsigned long long)r.pdus,
               (unsigned long long)r.fires, (unsigned long long)r.detonations, (unsigned long long)r.unknownTypes,
               (unsigned long long)r.malformed, (unsigned long long)r.otherExercise);
  std::vector<std::vector<std::string>> rows = {
      {"SENDER", "SITE:APP", "PDUS", "PER S", "ENTITIES", "MAX GAP S", "MAX HEARTBEAT S", "BAD", "TYPES"}};
  for (const dis::SenderReport& s : r.senders) {
    rows.push_back({s.address.text(),
                    s.hasSiteApplication ? std::to_string(s.site) + ":" + std::to_string(s.application) : "-",
                    std::to_string(s.pdus), fixed(s.ratePerS, 2), std::to_string(s.entities),
                    fixed(s.largestGapS, 2), fixed(s.largestHeartbeatGapS, 2), std::to_string(s.malformed),
                    typesText(s)});
  }
  std::fprintf(out, "senders\n");
  printTable(out, rows);

  rows = {{"ENTITY", "MARKING", "TYPE", "FORCE", "DR", "UPDATES", "MAX GAP S", "LAST S", "LON", "LAT", "HEIGHT M",
           "HEADING", "PITCH", "ROLL", "PARTS"}};
  std::size_t unlisted = 0;
  for (const dis::EntityReport& e : r.entities) {
    if (rows.size() > maxEntities) {
      ++unlisted;
      continue;
    }
    dis::Vec3d location = e.location;
    dis::Euler orientation = e.orientation;
    if (at) {
      const auto it = at->states.find({e.exercise, idKey(e.id)});
      if (it == at->states.end()) continue;  // not yet heard at that time
      location = it->second.location;
      orientation = it->second.orientation;
    }
    std::string algorithms;
    for (std::uint8_t a : e.algorithms) algorithms += (algorithms.empty() ? "" : ",") + algorithmName(a);
    const Placed p = place(location, orientation);
    rows.push_back({idText(e.id), e.marking.empty() ? "-" : e.marking, typeText(e.type), forceName(e.force),
                    algorithms, std::to_string(e.updates), fixed(e.largestGapS, 2), fixed(e.lastS - t0, 2),
                    p.geodetic ? fixed(p.geodetic->lon, 6) : "?", p.geodetic ? fixed(p.geodetic->lat, 6) : "?",
                    p.geodetic ? fixed(p.geodetic->height, 1) : "?",
                    p.attitude ? fixed(headingDeg(p.attitude->heading), 1) : "?",
                    p.attitude ? fixed(p.attitude->pitch * kDeg, 1) : "?",
                    p.attitude ? fixed(p.attitude->roll * kDeg, 1) : "?", partsText(e)});
  }
  if (at) std::fprintf(out, "entities at %s s (dead reckoned from the last PDU before)\n", fixed(at->atS, 3).c_str());
  else std::fprintf(out, "entities (as their last PDU has them)\n");
  printTable(out, rows);
  if (unlisted > 0) std::fprintf(out, "  ... and %zu more entities (--json lists every one)\n", unlisted);

  if (r.malformed > 0) {
    std::fprintf(out, "malformed PDUs: %llu\n", (unsigned long long)r.malformed);
    rows = {{"COUNT", "REASON", "FIRST", "SENDER", "DATAGRAM", "OFFSET"}};
    for (const dis::ReasonReport& x : r.reasons) {
      const dis::MalformedExample* m = x.examples.empty() ? nullptr : &x.examples.front();
      rows.push_back({std::to_string(x.count), x.reason, m ? fixed(m->timeS - t0, 3) + " s" : "-",
                      m ? m->sender.text() : "-", m ? std::to_string(m->datagram) : "-",
                      m ? std::to_string(m->offset) : "-"});
    }
    printTable(out, rows);
  }
  if (r.conflictPdus > 0) {
    std::fprintf(out, "entity ids claimed by two addresses: %llu PDUs\n", (unsigned long long)r.conflictPdus);
    rows = {{"ID", "OWNER", "OTHER", "PDUS"}};
    for (const dis::ConflictReport& c : r.conflicts) {
      rows.push_back({idText(c.id), c.owner.text(), c.other.text(), std::to_string(c.pdus)});
    }
    printTable(out, rows);
  }
  const dis::CapCounts& c = r.capped;
  if (c.senders + c.entities + c.reasons + c.conflicts > 0) {
    std::fprintf(out, "past the monitor's caps (counted, not kept): %llu PDUs of senders, %llu of entities, "
                      "%llu malformed of other reasons, %llu conflicting ids\n",
                 (unsigned long long)c.senders, (unsigned long long)c.entities, (unsigned long long)c.reasons,
                 (unsigned long long)c.conflicts);
  }
}

// ----------------------------------------------------------- inspect

struct InspectArgs {
  std::string file;
  std::optional<double> at;
  std::optional<int> exercise;
  int port = 0;
  bool json = false;
};

std::optional<std::string> monitorOptions(std::optional<int> exercise, dis::MonitorOptions& o) {
  if (exercise) {
    if (*exercise < 0 || *exercise > 255) return "--exercise must be 0..255";
    o.exercise = std::uint8_t(*exercise);
  }
  return std::nullopt;
}

int runInspect(const InspectArgs& a) {
  const std::string cmd = "dis inspect";
  dis::MonitorOptions options;
  if (auto bad = monitorOptions(a.exercise, options)) return usageError(cmd, *bad);
  if (a.at && !(*a.at >= 0 && std::isfinite(*a.at))) return usageError(cmd, "--at must be seconds >= 0");
  if (a.port < 0 || a.port > 65535) return usageError(cmd, "--port must be 0..65535");
  dis::PcapReadOptions readOptions;
  readOptions.port = std::uint16_t(a.port);
  auto reader = dis::PcapReader::open(a.file, readOptions);
  if (!reader) return reportProblems(cmd, reader.problems());
  dis::Monitor monitor(options);
  Warnings warnings;
  dis::Datagram d;
  std::optional<StatesAt> at;
  while (reader->next(d, &warnings)) {
    // --at: take every entity's state when the capture passes the time, in
    // the same pass (the monitor then holds each entity's last PDU before).
    if (a.at && !at && monitor.firstTime() && d.timeS > *monitor.firstTime() + *a.at) {
      at = statesAt(monitor, *a.at);
    }
    monitor.add(d);
  }
  if (a.at && !at) at = statesAt(monitor, *a.at);
  for (const Problem& w : warnings) std::fprintf(stderr, "sandtable %s: warning: %s\n", cmd.c_str(), w.str().c_str());
  const dis::Report r = monitor.report();
  const StatesAt* states = at ? &*at : nullptr;
  if (a.json) {
    nlohmann::json j = reportJson(r, states);
    j["file"] = a.file;
    j["packets"] = reader->packets();
    j["packets_skipped"] = reader->skips().total();
    std::printf("%s\n", j.dump(1).c_str());
  } else {
    std::printf("%s: %llu packets (%llu not DIS/UDP, skipped)\n", a.file.c_str(),
                (unsigned long long)reader->packets(), (unsigned long long)reader->skips().total());
    printReport(stdout, r, states);
  }
  return kOk;
}

void registerInspect(CLI::App& dis, Commands& c) {
  auto a = std::make_shared<InspectArgs>();
  auto* sub = dis.add_subcommand("inspect", "Report on a capture file: who sent what, how often, and what was wrong");
  sub->footer(
      "Per sender (address and site:application): PDU types and rates, gaps, entities, malformed PDUs with\n"
      "the reason and offset, ids claimed by two addresses (docs/DIS.md, 'The network monitor').\n"
      "Examples:\n"
      "  sandtable dis inspect exercise.pcap\n"
      "  sandtable dis inspect exercise.pcap --at 30 --exercise 1 --json");
  sub->add_option("FILE", a->file, "Capture file (pcap or pcapng)")->required();
  sub->add_option("--at", a->at, "Dead reckon every entity to this many seconds after the first packet");
  sub->add_option("--exercise", a->exercise, "Only this exercise's PDUs (0..255); others are counted, not read");
  sub->add_option("--port", a->port, "Only UDP datagrams to this port (default: every port)");
  sub->add_flag("--json", a->json, "Print the report as JSON");
  c.add(sub, [a] { return runInspect(*a); });
}

// -------------------------------------------------------------- live

/// Problems of the socket layer: each names its option field in the
/// message, which withFlags turns into the flag; exit 2.
int socketProblems(const std::string& cmd, const std::vector<Problem>& problems) {
  for (const Problem& p : problems) usageError(cmd, p.message);
  return kUsage;
}

/// The socket for `--dis [ADDR:]PORT` and `--interface`.
Result<dis::UdpSocket> openSocket(const std::string& endpoint, const std::string& interface) {
  dis::SocketOptions base;
  base.interface = interface;
  auto o = dis::parseDisEndpoint(endpoint, base);
  if (!o) return o.problems();
  return dis::UdpSocket::open(o.value());
}

double steadyNow() {
  return std::chrono::duration<double>(std::chrono::steady_clock::now().time_since_epoch()).count();
}

bool validSeconds(std::optional<double> s) { return !s || (*s > 0 && std::isfinite(*s)); }

struct LiveArgs {
  std::string dis = "3000", interface, output;
  std::optional<double> seconds;
  std::optional<int> exercise;
  bool json = false;
};

nlohmann::json receiverJson(const dis::ReceiverCounters& c) {
  return {{"datagrams", c.datagrams},
          {"bytes", c.bytes},
          {"queue_dropped", c.queueDropped},
          {"kernel_dropped", c.kernelDropped},
          {"errors", c.errors}};
}

int runMonitor(const LiveArgs& a) {
  const std::string cmd = "dis monitor";
  dis::MonitorOptions options;
  if (auto bad = monitorOptions(a.exercise, options)) return usageError(cmd, *bad);
  if (!validSeconds(a.seconds)) return usageError(cmd, "--seconds must be above 0");
  auto socket = openSocket(a.dis, a.interface);
  if (!socket) return socketProblems(cmd, socket.problems());
  const std::string where = socket->endpoint().text();
  auto receiver = dis::Receiver::start(std::move(socket.value()));
  if (!receiver) return socketProblems(cmd, receiver.problems());
  dis::Receiver& rx = *receiver.value();
  stopOnSignals();
  const bool tty = !a.json && ::isatty(STDOUT_FILENO) == 1;
  std::fprintf(stderr, "sandtable %s: listening (%s); Ctrl-C stops\n", cmd.c_str(), where.c_str());
  dis::Monitor monitor(options);
  std::vector<dis::Datagram> batch;
  const double start = steadyNow();
  double nextTick = start + 1.0;
  std::uint64_t lastPdus = 0, lastDatagrams = 0;
  while (!gStop.load()) {
    const double now = steadyNow();
    if (a.seconds && now - start >= *a.seconds) break;
    rx.waitPending(100);
    rx.drain(batch);
    for (const dis::Datagram& d : batch) monitor.add(d);
    if (steadyNow() < nextTick) continue;
    nextTick += 1.0;
    if (a.json) continue;
    const dis::Report r = monitor.report(steadyNow());
    const auto c = rx.counters();
    if (tty) {
      std::printf("\x1b[H\x1b[2J");  // home and clear: the table is redrawn in place
      std::printf("%s  %.0f s  last second: %llu datagrams, %llu PDUs  (dropped: %llu queue, %llu kernel)\n",
                  where.c_str(), steadyNow() - start, (unsigned long long)(r.datagrams - lastDatagrams),
                  (unsigned long long)(r.pdus - lastPdus), (unsigned long long)c.queueDropped,
                  (unsigned long long)c.kernelDropped);
      printReport(stdout, r, nullptr, 40);
    } else {
      std::printf("%.0f s  datagrams %llu (+%llu)  PDUs %llu (+%llu)  senders %zu  entities %zu  malformed %llu  "
                  "other exercise %llu  dropped %llu\n",
                  steadyNow() - start, (unsigned long long)r.datagrams, (unsigned long long)(r.datagrams - lastDatagrams),
                  (unsigned long long)r.pdus, (unsigned long long)(r.pdus - lastPdus), r.senders.size(),
                  r.entities.size(), (unsigned long long)r.malformed, (unsigned long long)r.otherExercise,
                  (unsigned long long)(c.queueDropped + c.kernelDropped));
    }
    std::fflush(stdout);
    lastPdus = r.pdus;
    lastDatagrams = r.datagrams;
  }
  rx.drain(batch);
  for (const dis::Datagram& d : batch) monitor.add(d);
  const dis::Report r = monitor.report(steadyNow());
  const auto c = rx.counters();
  if (a.json) {
    nlohmann::json j = reportJson(r, nullptr);
    j["listening"] = where;
    j["receiver"] = receiverJson(c);
    std::printf("%s\n", j.dump(1).c_str());
  } else {
    std::printf("final report (%s; receiver dropped %llu in its queue, %llu in the kernel)\n", where.c_str(),
                (unsigned long long)c.queueDropped, (unsigned long long)c.kernelDropped);
    printReport(stdout, r, nullptr);
  }
  return kOk;
}

int runRecord(const LiveArgs& a) {
  const std::string cmd = "dis record";
  if (!validSeconds(a.seconds)) return usageError(cmd, "--seconds must be above 0");
  auto socket = openSocket(a.dis, a.interface);
  if (!socket) return socketProblems(cmd, socket.problems());
  const std::string where = socket->endpoint().text();
  auto writer = dis::PcapWriter::create(a.output);
  if (!writer) return reportProblems(cmd, writer.problems());
  auto receiver = dis::Receiver::start(std::move(socket.value()));
  if (!receiver) return socketProblems(cmd, receiver.problems());
  dis::Receiver& rx = *receiver.value();
  stopOnSignals();
  // Received datagrams carry the steady clock; a pcap wants seconds since
  // 1970: one offset, taken now, keeps the recorded intervals exact.
  const double toUnix =
      std::chrono::duration<double>(std::chrono::system_clock::now().time_since_epoch()).count() - steadyNow();
  std::fprintf(stderr, "sandtable %s: recording (%s) to %s; Ctrl-C stops\n", cmd.c_str(), where.c_str(),
               a.output.c_str());
  const bool tty = ::isatty(STDERR_FILENO) == 1;
  std::vector<dis::Datagram> batch;
  const double start = steadyNow();
  double nextTick = start + 1.0;
  std::uint64_t bytes = 0;
  auto writeBatch = [&]() -> Status {
    for (dis::Datagram& d : batch) {
      d.timeS += toUnix;
      bytes += d.bytes.size();
      if (Status st = writer->write(d); !st) return st;
    }
    return {};
  };
  while (!gStop.load()) {
    if (a.seconds && steadyNow() - start >= *a.seconds) break;
    rx.waitPending(100);
    rx.drain(batch);
    if (Status st = writeBatch(); !st) return reportProblems(cmd, st.problems());
    if (steadyNow() >= nextTick) {
      nextTick += 1.0;
      std::fprintf(stderr, tty ? "\r%.0f s  %llu datagrams  %llu bytes   " : "%.0f s  %llu datagrams  %llu bytes\n",
                   steadyNow() - start, (unsigned long long)writer->count(), (unsigned long long)bytes);
    }
  }
  rx.drain(batch);
  if (Status st = writeBatch(); !st) return reportProblems(cmd, st.problems());
  if (tty) std::fprintf(stderr, "\n");
  const auto c = rx.counters();
  const std::uint64_t n = writer->count();
  if (Status st = writer->close(); !st) return reportProblems(cmd, st.problems());
  if (a.json) {
    nlohmann::json j = {{"file", a.output}, {"listening", where}, {"datagrams", n}, {"bytes", bytes},
                        {"seconds", steadyNow() - start}, {"receiver", receiverJson(c)}};
    std::printf("%s\n", j.dump(1).c_str());
  } else {
    std::printf("recorded %llu datagrams (%llu bytes) in %.1f s to %s; dropped %llu in the queue, %llu in the "
                "kernel\n",
                (unsigned long long)n, (unsigned long long)bytes, steadyNow() - start, a.output.c_str(),
                (unsigned long long)c.queueDropped, (unsigned long long)c.kernelDropped);
  }
  return kOk;
}

struct PlayArgs {
  std::string file, dis = "3000", interface;
  double speed = 1.0;
  bool loop = false, json = false;
};

/// Sleeps until `when` (steady seconds) or a stop; false on a stop.
bool sleepUntil(double when) {
  while (!gStop.load()) {
    const double left = when - steadyNow();
    if (left <= 0) return true;
    std::this_thread::sleep_for(std::chrono::duration<double>(std::min(left, 0.1)));
  }
  return false;
}

int runPlay(const PlayArgs& a) {
  const std::string cmd = "dis play";
  if (!(a.speed > 0 && std::isfinite(a.speed))) return usageError(cmd, "--speed must be above 0 (1: recorded pace)");
  Warnings warnings;
  auto capture = dis::readPcap(a.file, &warnings);
  if (!capture) return reportProblems(cmd, capture.problems());
  for (const Problem& w : warnings) std::fprintf(stderr, "sandtable %s: warning: %s\n", cmd.c_str(), w.str().c_str());
  if (capture->empty()) return usageError(cmd, a.file + " holds no UDP datagrams to play");
  auto socket = openSocket(a.dis, a.interface);
  if (!socket) return socketProblems(cmd, socket.problems());
  const std::string where = socket->endpoint().text();
  stopOnSignals();
  std::fprintf(stderr, "sandtable %s: %zu datagrams from %s (%s) at %gx%s; Ctrl-C stops\n", cmd.c_str(),
               capture->size(), a.file.c_str(), where.c_str(), a.speed, a.loop ? ", looping" : "");
  const double t0 = capture->front().timeS;
  const double started = steadyNow();
  std::uint64_t sent = 0, failed = 0, passes = 0;
  std::string firstFailure;
  do {
    // Each pass keeps the capture's intervals (divided by --speed) from
    // its own start, so a long loop does not drift.
    const double passStart = steadyNow();
    for (const dis::Datagram& d : capture.value()) {
      if (!sleepUntil(passStart + std::max(0.0, d.timeS - t0) / a.speed)) break;
      if (Status st = socket->send(d.bytes); st) {
        ++sent;
      } else if (failed++ == 0) {
        firstFailure = st.error();
      }
    }
    if (!gStop.load()) ++passes;
  } while (a.loop && !gStop.load());
  const double wall = steadyNow() - started;
  if (!firstFailure.empty()) {
    std::fprintf(stderr, "sandtable %s: %llu datagrams not sent; the first: %s\n", cmd.c_str(),
                 (unsigned long long)failed, firstFailure.c_str());
  }
  if (a.json) {
    nlohmann::json j = {{"file", a.file}, {"sending", where}, {"datagrams_sent", sent}, {"send_failures", failed},
                        {"passes", passes}, {"seconds", wall}, {"speed", a.speed}};
    std::printf("%s\n", j.dump(1).c_str());
  } else {
    std::printf("sent %llu datagrams (%llu complete passes) in %.1f s (%s)\n", (unsigned long long)sent,
                (unsigned long long)passes, wall, where.c_str());
  }
  return failed > 0 && sent == 0 ? kProblems : kOk;
}

void addLiveOptions(CLI::App* sub, LiveArgs& a) {
  sub->add_option("--dis", a.dis, "[ADDR:]PORT to listen on: 3000, 239.1.2.3:3000 (multicast), ... (default 3000)");
  sub->add_option("--interface", a.interface, "Network interface (default: the routing table's choice)");
  sub->add_option("--seconds", a.seconds, "Stop after this many seconds (default: at Ctrl-C)");
  sub->add_flag("--json", a.json, "Print the final report as JSON");
}

void registerLive(CLI::App& dis, Commands& c) {
  auto m = std::make_shared<LiveArgs>();
  auto* sub = dis.add_subcommand("monitor", "Watch a DIS port live: who sends what, how often, and what is wrong");
  sub->footer(
      "On a terminal the report is redrawn every second; otherwise one line a second. Ctrl-C (or --seconds)\n"
      "stops with a final report (docs/DIS.md, 'The network monitor').\n"
      "Examples:\n"
      "  sandtable dis monitor --dis 3000\n"
      "  sandtable dis monitor --dis 239.1.2.3:3000 --exercise 1 --seconds 60 --json > exercise.json");
  addLiveOptions(sub, *m);
  sub->add_option("--exercise", m->exercise, "Only this exercise's PDUs (0..255); others are counted, not read");
  c.add(sub, [m] { return runMonitor(*m); });

  auto r = std::make_shared<LiveArgs>();
  sub = dis.add_subcommand("record", "Record a DIS port to a pcap file that Wireshark opens (the data logger)");
  sub->footer(
      "Every UDP datagram that arrives, with its sender, destination and arrival time; the file appears when\n"
      "recording stops (Ctrl-C or --seconds).\n"
      "Example:\n"
      "  sandtable dis record --dis 3000 -o exercise.pcap --seconds 600");
  addLiveOptions(sub, *r);
  sub->add_option("-o,--output", r->output, "The pcap file to write")->required();
  c.add(sub, [r] { return runRecord(*r); });

  auto p = std::make_shared<PlayArgs>();
  sub = dis.add_subcommand("play", "Send a capture's datagrams to a DIS port again, at the recorded pace");
  sub->footer(
      "Every UDP datagram of the capture, its payload as recorded, to --dis (the recorded destination is not\n"
      "used). --speed 2 plays twice as fast; --loop starts again at the end until Ctrl-C.\n"
      "Example:\n"
      "  sandtable dis play exercise.pcap --dis 3000 --speed 2 --loop");
  sub->add_option("FILE", p->file, "Capture file (pcap or pcapng)")->required();
  sub->add_option("--dis", p->dis, "[ADDR:]PORT to send to (default 3000: the default broadcast)");
  sub->add_option("--interface", p->interface, "Network interface (default: the routing table's choice)");
  sub->add_option("--speed", p->speed, "Pace: 1 as recorded, 2 twice as fast (default 1)");
  sub->add_flag("--loop", p->loop, "Start again at the end, until Ctrl-C");
  sub->add_flag("--json", p->json, "Print the summary as JSON");
  c.add(sub, [p] { return runPlay(*p); });
}

// ------------------------------------------------- scripts <-> captures

/// What both conversions take from the database: its frame (the CRS and
/// the grid's north-west corner), its icons and its drawn ground.
struct ScriptDb {
  std::shared_ptr<const paging::World> world;
  std::shared_ptr<sim::SimWorld> sim;
  std::optional<sim_dis::DisFrame> frame;
  std::span<const iconpack::Icon> icons() const {
    return world->icons() ? std::span<const iconpack::Icon>(world->icons()->icons) : std::span<const iconpack::Icon>();
  }
  sim_dis::GroundFn ground() const {
    auto w = sim;
    return [w](double x, double z) { return w->groundAt(x, z); };
  }
};

std::optional<ScriptDb> openScriptDb(const std::string& cmd, const std::string& dir) {
  ScriptDb db;
  db.world = openWorldOrReport(cmd, dir);
  if (!db.world) return std::nullopt;
  const manifest::Manifest& m = db.world->manifest();
  auto frame = geodesy::DatabaseFrame::create(m.crsWkt, m.originEasting, m.originNorthing);
  if (!frame) {
    usageError(cmd, "DB " + dir + " has no usable coordinate system (scripts are in its frame, DIS is geocentric): " +
                        frame.message() + "; rebuild the database with a CRS (--crs)");
    return std::nullopt;
  }
  db.frame.emplace(frame.value());
  auto simWorld = sim::SimWorld::open(*db.world);
  if (!simWorld) {
    reportProblems(cmd, simWorld.problems());
    return std::nullopt;
  }
  db.sim = simWorld.value();
  return db;
}

bool validRate(double hz) { return hz > 0 && hz <= 10000 && std::isfinite(hz); }

std::string iconText(const sim_dis::EntityMapping& e) { return e.icon.empty() ? "-" : e.icon; }

struct ToScriptArgs {
  std::string file, db, output;
  std::optional<int> exercise;
  std::optional<double> origin;
  int port = 0;
  double rate = 60;
  bool json = false;
};

int runToScript(const ToScriptArgs& a) {
  const std::string cmd = "dis to-script";
  sim_dis::ToScriptOptions o;
  if (a.exercise) {
    if (*a.exercise < 0 || *a.exercise > 255) return usageError(cmd, "--exercise must be 0..255");
    o.exercise = std::uint8_t(*a.exercise);
  }
  if (!validRate(a.rate)) return usageError(cmd, "--rate must be above 0 and at most 10000 (samples per second)");
  if (a.origin && !std::isfinite(*a.origin)) return usageError(cmd, "--origin must be seconds since 1970");
  if (a.port < 0 || a.port > 65535) return usageError(cmd, "--port must be 0..65535");
  o.rateHz = a.rate;
  o.originUnixS = a.origin;
  dis::PcapReadOptions readOptions;
  readOptions.port = std::uint16_t(a.port);
  Warnings warnings;
  auto capture = dis::readPcap(a.file, &warnings, readOptions);
  if (!capture) return reportProblems(cmd, capture.problems());
  for (const Problem& w : warnings) std::fprintf(stderr, "sandtable %s: warning: %s\n", cmd.c_str(), w.str().c_str());
  auto db = openScriptDb(cmd, a.db);
  if (!db) return kUsage;
  o.groundAt = db->ground();
  auto result = sim_dis::toScript(capture.value(), *db->frame, db->icons(), o);
  if (!result) return reportProblems(cmd, result.problems());
  const sim_dis::ToScriptResult& r = result.value();
  if (r.lines.empty()) {
    return usageError(cmd, a.file + " holds no Entity State PDU" +
                               (a.exercise ? " of exercise " + std::to_string(*a.exercise) : std::string()) +
                               " to make a script of");
  }
  const std::string text = "# sandtable dis to-script " + a.file + " (docs/DIS.md §9; format docs/SCRIPTS.md)\n" +
                           sim::formatScript(r.lines);
  if (Status st = writeFileAtomic(a.output, std::as_bytes(std::span(text.data(), text.size()))); !st) {
    return reportProblems(cmd, st.problems());
  }
  if (r.malformed > 0) {
    std::fprintf(stderr, "sandtable %s: warning: %llu malformed PDUs skipped; the first: %s\n", cmd.c_str(),
                 (unsigned long long)r.malformed, r.firstMalformed.c_str());
  }
  if (a.json) {
    nlohmann::json entities = nlohmann::json::array();
    for (const sim_dis::EntityMapping& e : r.entities) {
      entities.push_back({{"id", idText(e.id)}, {"marking", e.marking}, {"type", typeText(e.type)},
                          {"script_entity", e.scriptEntity}, {"script_type", e.scriptType}, {"icon", e.icon},
                          {"icon_fallback", e.fallback}, {"entity_states", e.entityStates}, {"lines", e.lines}});
    }
    nlohmann::json j = {{"file", a.file}, {"database", a.db}, {"output", a.output}, {"exercise", r.exercise},
                        {"datagrams", r.datagrams}, {"pdus", r.pdus}, {"entity_states", r.entityStates},
                        {"fires", r.fires}, {"removes", r.removes}, {"other_exercise", r.otherExercise},
                        {"other_types", r.otherTypes}, {"malformed", r.malformed},
                        {"before_origin", r.beforeOrigin}, {"unplaceable", r.unplaceable},
                        {"timed_out", r.timedOut}, {"renumbered", r.renumbered}, {"lines", r.lines.size()},
                        {"rate_hz", a.rate}, {"entities", entities}};
    std::printf("%s\n", j.dump(1).c_str());
    return kOk;
  }
  std::printf("%s: %llu datagrams, %llu PDUs: %llu Entity State (exercise %u), %llu Fire, %llu Remove Entity; "
              "skipped %llu of other exercises, %llu of other types, %llu malformed, %llu before --origin\n",
              a.file.c_str(), (unsigned long long)r.datagrams, (unsigned long long)r.pdus,
              (unsigned long long)r.entityStates, unsigned(r.exercise), (unsigned long long)r.fires,
              (unsigned long long)r.removes, (unsigned long long)r.otherExercise, (unsigned long long)r.otherTypes,
              (unsigned long long)r.malformed, (unsigned long long)r.beforeOrigin);
  std::printf("wrote %s: %zu lines, %zu entities (sampled at %g Hz; %llu timed out)%s\n", a.output.c_str(),
              r.lines.size(), r.entities.size(), a.rate, (unsigned long long)r.timedOut,
              r.renumbered ? "; entity numbers 1, 2, ... (two DIS ids share an entity field)" : "");
  std::vector<std::vector<std::string>> rows = {
      {"DIS ID", "MARKING", "DIS TYPE", "ENTITY_NUMBER", "ENTITY_TYPE", "ICON", "PDUS", "LINES"}};
  for (const sim_dis::EntityMapping& e : r.entities) {
    rows.push_back({idText(e.id), e.marking.empty() ? "-" : e.marking, typeText(e.type),
                    std::to_string(e.scriptEntity), std::to_string(e.scriptType),
                    iconText(e) + (e.fallback ? " (fallback)" : ""), std::to_string(e.entityStates),
                    std::to_string(e.lines)});
  }
  printTable(stdout, rows);
  return kOk;
}

struct FromScriptArgs {
  std::string file, db, output;
  int exercise = 1, site = 1, application = 1;
  double rate = 60, start = 0;
  std::vector<std::string> types;
  bool json = false;
};

/// --type N=K.D.C.CAT.SUB.SPEC.EXTRA, omitted fields and `*` sent as 0.
std::optional<std::string> parseTypeFlag(const std::string& text, std::map<std::uint32_t, dis::EntityType>& out) {
  const auto eq = text.find('=');
  const std::string bad = "--type \"" + text + "\" must be ENTITY_TYPE=KIND.DOMAIN.COUNTRY.CATEGORY.SUBCATEGORY."
                          "SPECIFIC.EXTRA, such as 2=1.1.225.1.1.3.0";
  if (eq == std::string::npos || eq == 0) return bad;
  std::uint32_t n = 0;
  for (char c : text.substr(0, eq)) {
    if (c < '0' || c > '9' || n > 429496729u) return bad;
    n = n * 10 + std::uint32_t(c - '0');
  }
  std::string why;
  auto p = iconpack::parseDisPattern(text.substr(eq + 1), why);
  if (!p) return bad + ": " + why;
  auto field = [&](int k, auto v) { return (p->wild >> k) & 1 ? decltype(v){0} : v; };
  const iconpack::DisType& d = p->type;
  out[n] = {field(0, d.kind),        field(1, d.domain),   field(2, d.country), field(3, d.category),
            field(4, d.subcategory), field(5, d.specific), field(6, d.extra)};
  return std::nullopt;
}

int runFromScript(const FromScriptArgs& a) {
  const std::string cmd = "dis from-script";
  sim_dis::FromScriptOptions o;
  if (a.exercise < 1 || a.exercise > 255) return usageError(cmd, "--exercise must be 1 to 255");
  if (a.site < 1 || a.site > 65534 || a.application < 1 || a.application > 65534) {
    return usageError(cmd, "--site and --application must be 1 to 65534 (0 and 65535 mean none and all in DIS)");
  }
  if (!validRate(a.rate)) return usageError(cmd, "--rate must be above 0 and at most 10000 (samples per second)");
  if (!(a.start >= 0 && a.start < 4e9)) return usageError(cmd, "--start must be seconds since 1970, 0 or more");
  for (const std::string& t : a.types) {
    if (auto bad = parseTypeFlag(t, o.types)) return usageError(cmd, *bad);
  }
  o.exercise = std::uint8_t(a.exercise);
  o.site = std::uint16_t(a.site);
  o.application = std::uint16_t(a.application);
  o.rateHz = a.rate;
  o.startUnixS = a.start;
  auto lines = sim::readScriptFile(a.file);
  if (!lines) return reportProblems(cmd, lines.problems());
  if (lines->empty()) return usageError(cmd, a.file + " has no script lines to publish");
  auto db = openScriptDb(cmd, a.db);
  if (!db) return kUsage;
  o.groundAt = db->ground();
  auto result = sim_dis::fromScript(lines.value(), *db->frame, db->icons(), o);
  if (!result) return reportProblems(cmd, result.problems());
  const sim_dis::FromScriptResult& r = result.value();
  auto writer = dis::PcapWriter::create(a.output);
  if (!writer) return reportProblems(cmd, writer.problems());
  for (const dis::Datagram& d : r.datagrams) {
    if (Status st = writer->write(d); !st) return reportProblems(cmd, st.problems());
  }
  if (Status st = writer->close(); !st) return reportProblems(cmd, st.problems());
  for (const sim_dis::EntityMapping& e : r.entities) {
    if (e.fallback) {
      std::fprintf(stderr,
                   "sandtable %s: warning: Entity_Type %u has no DIS type (no --type, and icon %u %s): entity %u "
                   "goes out as 1.1.0.0.0.0.0 (a land platform)\n",
                   cmd.c_str(), e.scriptType, e.scriptType,
                   e.icon.empty() ? "is not in the database" : ("\"" + e.icon + "\" has no dis pattern").c_str(),
                   e.scriptEntity);
    }
  }
  auto typeFrom = [](const sim_dis::EntityMapping& e) {
    return e.fallback ? "default" : e.typeByIcon ? "icon" : "--type";
  };
  if (a.json) {
    nlohmann::json entities = nlohmann::json::array();
    for (const sim_dis::EntityMapping& e : r.entities) {
      entities.push_back({{"script_entity", e.scriptEntity}, {"script_type", e.scriptType}, {"id", idText(e.id)},
                          {"type", typeText(e.type)}, {"type_from", typeFrom(e)}, {"icon", e.icon},
                          {"marking", e.marking}, {"lines", e.lines}, {"entity_states", e.entityStates}});
    }
    nlohmann::json j = {{"file", a.file}, {"database", a.db}, {"output", a.output},
                        {"datagrams", r.datagrams.size()}, {"entity_states", r.entityStates}, {"fires", r.fires},
                        {"removes", r.removes}, {"unplaceable", r.unplaceable}, {"end_s", r.endS},
                        {"rate_hz", a.rate}, {"exercise", a.exercise}, {"entities", entities}};
    std::printf("%s\n", j.dump(1).c_str());
    return kOk;
  }
  std::printf("%s: %zu lines, %zu entities, 0 to %s s\n", a.file.c_str(), lines->size(), r.entities.size(),
              fixed(r.endS, 3).c_str());
  std::printf("wrote %s: %zu datagrams (%llu Entity State, %llu Fire, %llu Remove Entity PDUs), exercise %d, "
              "from %s to %s; %llu states off the frame\n",
              a.output.c_str(), r.datagrams.size(), (unsigned long long)r.entityStates,
              (unsigned long long)r.fires, (unsigned long long)r.removes, a.exercise, o.sender.text().c_str(),
              o.destination.text().c_str(), (unsigned long long)r.unplaceable);
  std::vector<std::vector<std::string>> rows = {
      {"ENTITY_NUMBER", "ENTITY_TYPE", "DIS ID", "DIS TYPE", "FROM", "ICON", "LINES", "PDUS"}};
  for (const sim_dis::EntityMapping& e : r.entities) {
    rows.push_back({std::to_string(e.scriptEntity), std::to_string(e.scriptType), idText(e.id), typeText(e.type),
                    typeFrom(e), iconText(e), std::to_string(e.lines), std::to_string(e.entityStates)});
  }
  printTable(stdout, rows);
  return kOk;
}

void registerScripts(CLI::App& dis, Commands& c) {
  auto t = std::make_shared<ToScriptArgs>();
  auto* sub = dis.add_subcommand("to-script", "Convert a capture's Entity State PDUs into a script (seed Figure 71)");
  sub->footer(
      "Each entity is dead reckoned between its PDUs and sampled at --rate; a script line is kept by the script\n"
      "recorder's rule. Positions are in DB's frame (x east, z south of its north-west corner); Entity_Number is\n"
      "the DIS entity field, Entity_Type the icon DB draws the DIS type with (docs/DIS.md §9).\n"
      "Examples:\n"
      "  sandtable dis to-script exercise.pcap db -o exercise.script\n"
      "  sandtable dis to-script exercise.pcap db -o exercise.script --exercise 3 --json");
  sub->add_option("FILE", t->file, "Capture file (pcap or pcapng)")->required();
  sub->add_option("DB", t->db, "Database directory (its CRS and origin set the script's frame)")->required();
  sub->add_option("-o,--output", t->output, "The script to write")->required();
  sub->add_option("--exercise", t->exercise, "Only this exercise (0..255; default: the first Entity State PDU's)");
  sub->add_option("--port", t->port, "Only UDP datagrams to this port (default: every port)");
  sub->add_option("--rate", t->rate, "Samples per second between PDUs (default 60)");
  sub->add_option("--origin", t->origin,
                  "Capture time (seconds since 1970) of script time 0 (default: the first packet's)");
  sub->add_flag("--json", t->json, "Print the summary and the id and type mapping as JSON");
  c.add(sub, [t] { return runToScript(*t); });

  auto f = std::make_shared<FromScriptArgs>();
  sub = dis.add_subcommand("from-script", "Convert a script (seed Figure 71) into a capture of Entity State PDUs");
  sub->footer(
      "The script is played at --rate and each entity published as `sim --dis` would: an Entity State PDU when\n"
      "its dead-reckoned copy passes 1 m or 3 degrees, at least every 5 s; a Fire PDU per Fire_Flag; a\n"
      "deactivating PDU and a Remove Entity PDU per entity at the script's end. One PDU per datagram from\n"
      "127.0.0.1:3000 to 127.255.255.255:3000, stamped --start + the script's time (docs/DIS.md §9).\n"
      "Examples:\n"
      "  sandtable dis from-script samples/demo.script db -o demo.pcap\n"
      "  sandtable dis from-script run.script db -o run.pcap --type 2=1.1.225.1.1.3.0 --site 5");
  sub->add_option("FILE", f->file, "Script file (docs/SCRIPTS.md)")->required();
  sub->add_option("DB", f->db, "Database directory (its CRS and origin place the script's frame)")->required();
  sub->add_option("-o,--output", f->output, "The pcap file to write")->required();
  sub->add_option("--exercise", f->exercise, "DIS exercise id, 1-255 (default 1)");
  sub->add_option("--site", f->site, "DIS site number, 1-65534 (default 1)");
  sub->add_option("--application", f->application, "DIS application number, 1-65534 (default 1)");
  sub->add_option("--rate", f->rate, "Samples per second the publisher is offered (default 60)");
  sub->add_option("--start", f->start, "Capture time of script time 0, seconds since 1970 (default 0)");
  sub->add_option("--type", f->types,
                  "ENTITY_TYPE=K.D.C.CAT.SUB.SPEC.EXTRA: the DIS type of a script Entity_Type (default: the DB "
                  "icon's first dis pattern); repeatable");
  sub->add_flag("--json", f->json, "Print the summary and the id and type mapping as JSON");
  c.add(sub, [f] { return runFromScript(*f); });
}

}  // namespace

void registerDis(CLI::App& root, Commands& c) {
  auto* dis = root.add_subcommand("dis", "DIS network tools: the monitor and the data logger");
  dis->require_subcommand(1);
  registerInspect(*dis, c);
  registerLive(*dis, c);
  registerScripts(*dis, c);
}

}  // namespace sandtable::cli
