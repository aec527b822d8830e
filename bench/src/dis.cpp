// bench dis: the DIS figures of issue 36, each beside a baseline measured
// in the same run (see the header for the parts).
#include "sandtable/bench/dis.h"

#include <arpa/inet.h>
#include <netinet/in.h>
#include <sys/socket.h>
#include <sys/uio.h>
#include <time.h>
#include <unistd.h>

#include <algorithm>
#include <atomic>
#include <chrono>
#include <cmath>
#include <limits>
#include <memory>
#include <string>
#include <thread>

#include "sandtable/base/stats.h"
#include "sandtable/dis/socket.h"
#include "sandtable/sim/simulation.h"
#include "sandtable/sim/step_host.h"
#include "sandtable/sim_dis/gateway.h"
#include "synthetic_world.h"

namespace sandtable::bench {
namespace {

constexpr double kSquareM = 125;
constexpr double kSizeKm = 50;
constexpr std::uint16_t kSite = 2, kApplication = 3;  ///< the remote sender's DIS address
constexpr double kRoundS = 1;                          ///< between an entity's PDUs in the streams
constexpr double kGoalMemory = 1e6, kGoalLoopback = 2e5;
constexpr double kPacedHz = 20000;                     ///< the latency run's rate
constexpr double kStepS = 1.0 / 60;
const dis::Address kSender{0x7f000001, 3001};

double seconds() { return std::chrono::duration<double>(std::chrono::steady_clock::now().time_since_epoch()).count(); }

/// This thread's CPU time: the one-core parts are timed with it, so that a
/// machine shared with other work (this one runs CI) charges them only for
/// the time they ran, not for the time they waited for a core.
double cpuSeconds() {
  timespec t{};
  clock_gettime(CLOCK_THREAD_CPUTIME_ID, &t);
  return double(t.tv_sec) + 1e-9 * double(t.tv_nsec);
}

dis::Vec3f toFloat(const dis::Vec3d& v) { return {float(v.x), float(v.y), float(v.z)}; }

/// Keeps a value from being optimised away.
template <class T>
void keep(const T& v) {
  asm volatile("" : : "g"(&v) : "memory");
}

/// One remote entity of the streams: a straight run at constant speed,
/// land (FPW) or, one in five, air (RVW) 1 km above the hills.
struct Mover {
  sim_dis::Anchor anchor;
  Eigen::Vector3d start, velocity;
  double headingDeg = 0;
  bool air = false;
};

dis::EntityId moverId(std::uint32_t k) {
  // Entity numbers are 16 bits: 65,535 per application.
  return {kSite, std::uint16_t(kApplication + k / 65535), std::uint16_t(k % 65535 + 1)};
}

Result<std::vector<Mover>> makeMovers(const sim_dis::DisFrame& frame, const sim::SimWorld& w, std::uint32_t n,
                                      std::uint64_t seed) {
  std::vector<Mover> out;
  out.reserve(n);
  const double margin = 2000;
  for (std::uint32_t k = 0; k < n; ++k) {
    Mover m;
    m.air = k % 5 == 0;
    const double x = margin + unitRandom(seed ^ 0xd1, 4 * k) * (w.widthM() - 2 * margin);
    const double z = margin + unitRandom(seed ^ 0xd1, 4 * k + 1) * (w.depthM() - 2 * margin);
    m.headingDeg = 360 * unitRandom(seed ^ 0xd1, 4 * k + 2);
    const double speed = m.air ? 100 + 100 * unitRandom(seed ^ 0xd1, 4 * k + 3) : 3 + 12 * unitRandom(seed ^ 0xd1, 4 * k + 3);
    m.start = {x, hillsAt(x, z) + (m.air ? 1000 : 0), z};
    m.velocity = sim::headingVector(m.headingDeg) * speed;
    auto a = frame.anchorAtFrame(m.start);
    if (!a) return a.problems();
    m.anchor = a.value();
    out.push_back(m);
  }
  return out;
}

/// Mover k's Entity State at `t` seconds after its start: what a tank or an
/// aircraft with a turret and a gun (two articulated parts) sends.
dis::EntityState stateOf(const Mover& m, std::uint32_t k, double t) {
  dis::EntityState s;
  s.id = moverId(k);
  s.force = std::uint8_t(1 + k % 2);
  s.type = m.air ? dis::EntityType{1, 2, 225, 1, 1, 0, 0} : dis::EntityType{1, 1, 225, 1, 1, 3, 0};
  s.location = sim_dis::ecefOf(m.anchor, m.start + m.velocity * t);
  s.orientation = sim_dis::disOrientation(m.anchor, m.headingDeg, 0, 0);
  s.velocity = toFloat(sim_dis::ecefVector(m.anchor, m.velocity));
  s.deadReckoning.algorithm = m.air ? 4 : 2;
  std::string mark = m.air ? "A" : "T";
  mark += std::to_string(k);
  s.marking = dis::Marking::ascii(mark);
  s.parameters.push_back(dis::toParameter(dis::ArticulatedPart{0, 0, sim_dis::kTurretAzimuth, float(0.01 * (k % 100))}));
  s.parameters.push_back(dis::toParameter(dis::ArticulatedPart{0, 0, sim_dis::kGunElevation, 0.05f}));
  return s;
}

/// rounds[r][k]: entity k's r-th PDU, one per datagram.
using Stream = std::vector<std::vector<dis::Datagram>>;

Stream makeStream(const std::vector<Mover>& movers, std::uint32_t rounds) {
  Stream out(rounds);
  dis::Header h;
  h.exercise = 1;
  for (std::uint32_t r = 0; r < rounds; ++r) {
    out[r].reserve(movers.size());
    for (std::uint32_t k = 0; k < movers.size(); ++k) {
      dis::Datagram d;
      d.sender = kSender;
      d.destination = {0x7f000001, dis::kDisPort};
      d.bytes = dis::encode(h, stateOf(movers[k], k, r * kRoundS));
      out[r].push_back(std::move(d));
    }
  }
  return out;
}

sim_dis::GatewayOptions watcherOptions() {
  sim_dis::GatewayOptions o;
  o.publish = false;  // the stealth viewer's gateway
  return o;
}

Result<sim_dis::DisFrame> hillsFrame() {
  auto f = geodesy::DatabaseFrame::create(kHillsCrs, kHillsEasting, kHillsNorthing);
  if (!f) return f.problems();
  return sim_dis::DisFrame(f.value());
}

nlohmann::json rateJson(const std::vector<double>& rates, std::uint64_t count) {
  nlohmann::json list = nlohmann::json::array();
  for (double r : rates) list.push_back(r);
  return {{"per_s", stats::median(rates)}, {"runs_per_s", list}, {"count", count}};
}

// ---- 1. From memory -------------------------------------------------------

struct MemoryRun {
  double decodePerS = 0, createPerS = 0, applyPerS = 0;
};

Result<MemoryRun> memoryOnce(const std::shared_ptr<sim::SimWorld>& world, const sim_dis::DisFrame& frame,
                             const Stream& stream) {
  MemoryRun out;
  // Baseline: decode every PDU of the stream, nothing else.
  std::uint64_t decoded = 0, total = 0;
  const std::string sender = kSender.text();
  double t0 = cpuSeconds();
  for (const auto& round : stream) {
    for (const dis::Datagram& d : round) {
      auto pdu = dis::decode(d.bytes, sender);
      decoded += pdu && pdu->entityState ? 1 : 0;
      keep(pdu);
    }
    total += round.size();
  }
  out.decodePerS = double(total) / (cpuSeconds() - t0);
  if (decoded != total) return Problem{"", 0, "bench dis: the stream did not decode (a bug)"};

  sim::Simulation s(world);
  sim_dis::Gateway g(s, frame, watcherOptions(), nullptr, nullptr);
  t0 = cpuSeconds();
  g.apply(stream.front());
  out.createPerS = double(stream.front().size()) / (cpuSeconds() - t0);
  double applyS = 0;
  std::uint64_t applied = 0;
  for (std::size_t r = 1; r < stream.size(); ++r) {
    s.runFor(kRoundS);  // untimed: the clock moves on to the round's time (no entities in it yet)
    t0 = cpuSeconds();
    g.apply(stream[r]);
    applyS += cpuSeconds() - t0;
    applied += stream[r].size();
  }
  out.applyPerS = double(applied) / applyS;
  if (g.counters().entityStates != total || g.remotes().size() != stream.front().size()) {
    return Problem{"", 0, "bench dis: the gateway did not apply every PDU (a bug)"};
  }
  return out;
}

// ---- 2. Loopback ----------------------------------------------------------

/// A free UDP port on 127.0.0.1 (the kernel's pick, released at once).
Result<std::uint16_t> freePort() {
  const int fd = ::socket(AF_INET, SOCK_DGRAM, 0);
  if (fd < 0) return Problem{"", 0, "bench dis: cannot open a UDP socket"};
  sockaddr_in a{};
  a.sin_family = AF_INET;
  a.sin_addr.s_addr = htonl(INADDR_LOOPBACK);
  socklen_t len = sizeof a;
  const bool ok = ::bind(fd, reinterpret_cast<sockaddr*>(&a), sizeof a) == 0 &&
                  ::getsockname(fd, reinterpret_cast<sockaddr*>(&a), &len) == 0;
  ::close(fd);
  if (!ok) return Problem{"", 0, "bench dis: no free UDP port on 127.0.0.1"};
  return ntohs(a.sin_port);
}

std::uint32_t sequenceOf(const std::vector<std::byte>& b) {
  std::uint32_t v = 0;
  for (int i = 4; i < 8; ++i) v = (v << 8) | std::to_integer<std::uint32_t>(b[i]);
  return v >> 1;
}

struct LoopbackRun {
  std::uint64_t sent = 0, received = 0, kernelDrops = 0, queueDrops = 0, applied = 0;
  double sentPerS = 0, receivedPerS = 0;
  std::vector<double> readLatencyMs, appliedLatencyMs;
};

/// Sends `count` PDUs of `stream` (cycled; the sequence number in the
/// relative timestamp field) from a plain socket to a Receiver's socket,
/// paced at `hz` (0: as fast as the socket takes them); this thread drains
/// and, when `apply`, applies them.
Result<LoopbackRun> loopbackOnce(const std::shared_ptr<sim::SimWorld>& world, const sim_dis::DisFrame& frame,
                                 const Stream& stream, std::uint64_t count, bool apply, double hz) {
  auto rp = freePort();
  if (!rp) return rp.problems();
  dis::SocketOptions ro;
  ro.address = "127.0.0.1";
  ro.port = rp.value();
  ro.receiveBufferBytes = 4 << 20;
  auto rsock = dis::UdpSocket::open(ro);
  if (!rsock) return rsock.problems();
  auto receiver = dis::Receiver::start(std::move(rsock.value()), {});
  if (!receiver) return receiver.problems();
  // The load generator: a plain socket connected to the receiver, writing
  // batches with sendmmsg, so that the sender is not what limits the rate.
  const int sfd = ::socket(AF_INET, SOCK_DGRAM, 0);
  if (sfd < 0) return Problem{"", 0, "bench dis: cannot open the sender's UDP socket"};
  sockaddr_in dst{};
  dst.sin_family = AF_INET;
  dst.sin_addr.s_addr = htonl(INADDR_LOOPBACK);
  dst.sin_port = htons(rp.value());
  const int sndbuf = 4 << 20;
  ::setsockopt(sfd, SOL_SOCKET, SO_SNDBUF, &sndbuf, sizeof sndbuf);
  if (::connect(sfd, reinterpret_cast<sockaddr*>(&dst), sizeof dst) != 0) {
    ::close(sfd);
    return Problem{"", 0, "bench dis: cannot connect the sender to 127.0.0.1"};
  }

  sim::Simulation s(world);
  sim_dis::Gateway g(s, frame, watcherOptions(), nullptr, nullptr);
  std::vector<double> sentAt(count, 0.0);
  std::atomic<bool> done{false};
  std::atomic<std::uint64_t> sendErrors{0};
  double sendStart = 0, sendEnd = 0;
  const std::size_t perRound = stream.front().size();
  std::thread sender([&] {
    constexpr std::size_t kBatch = 32;
    std::vector<std::vector<std::byte>> bufs(kBatch);
    std::vector<iovec> iov(kBatch);
    std::vector<mmsghdr> msgs(kBatch);
    sendStart = seconds();
    for (std::uint64_t i = 0; i < count;) {
      if (hz > 0) {
        const double due = sendStart + double(i) / hz;
        while (seconds() < due) std::this_thread::sleep_for(std::chrono::microseconds(50));
      }
      const std::size_t n = std::size_t(std::min<std::uint64_t>(hz > 0 ? 16 : kBatch, count - i));
      const double now = seconds();
      for (std::size_t b = 0; b < n; ++b) {
        const std::uint64_t q = i + b;
        const auto& src = stream[(q / perRound) % stream.size()][q % perRound].bytes;
        bufs[b].assign(src.begin(), src.end());
        const std::uint32_t stamp = std::uint32_t(q) << 1;  // relative: the gateway does not read it
        for (int k = 0; k < 4; ++k) bufs[b][4 + k] = std::byte(stamp >> (24 - 8 * k));
        iov[b] = {bufs[b].data(), bufs[b].size()};
        msgs[b] = {};
        msgs[b].msg_hdr.msg_iov = &iov[b];
        msgs[b].msg_hdr.msg_iovlen = 1;
        sentAt[q] = now;
      }
      std::size_t off = 0;
      while (off < n) {
        const int k = ::sendmmsg(sfd, msgs.data() + off, unsigned(n - off), 0);
        if (k <= 0) {
          sendErrors.fetch_add(n - off);
          break;
        }
        off += std::size_t(k);
      }
      i += n;
    }
    sendEnd = seconds();
    done.store(true);
  });

  LoopbackRun out;
  std::vector<std::pair<std::uint32_t, double>> reads, applies;  // sequence, time
  reads.reserve(count);
  if (apply) applies.reserve(count);
  std::vector<dis::Datagram> batch;
  double lastS = seconds(), quietSince = 0;
  for (;;) {
    if (!receiver.value()->waitPending(5)) {
      if (!done.load()) continue;
      const auto c = receiver.value()->counters();
      if (c.datagrams + c.kernelDropped >= count) break;
      if (quietSince == 0) quietSince = seconds();
      if (seconds() - quietSince > 0.3) break;  // the rest were lost without a count
      continue;
    }
    quietSince = 0;
    receiver.value()->drain(batch);
    for (const dis::Datagram& d : batch) reads.emplace_back(sequenceOf(d.bytes), d.timeS);
    if (apply) {
      g.apply(batch);
      const double t = seconds();
      for (const dis::Datagram& d : batch) applies.emplace_back(sequenceOf(d.bytes), t);
    }
    lastS = seconds();
  }
  sender.join();
  ::close(sfd);
  const auto c = receiver.value()->counters();
  out.sent = count - sendErrors.load();
  out.received = reads.size();
  out.applied = apply ? g.counters().entityStates : 0;
  out.kernelDrops = c.kernelDropped;
  out.queueDrops = c.queueDropped;
  out.sentPerS = double(count) / std::max(1e-9, sendEnd - sendStart);
  out.receivedPerS = double(out.received) / std::max(1e-9, lastS - sendStart);
  for (const auto& [seq, t] : reads) {
    if (seq < count) out.readLatencyMs.push_back(1000 * (t - sentAt[seq]));
  }
  for (const auto& [seq, t] : applies) {
    if (seq < count) out.appliedLatencyMs.push_back(1000 * (t - sentAt[seq]));
  }
  return out;
}

nlohmann::json latencyJson(const std::vector<double>& ms) {
  return {{"p50_ms", stats::percentile(ms, 0.5)}, {"p99_ms", stats::percentile(ms, 0.99)},
          {"max_ms", ms.empty() ? 0.0 : *std::max_element(ms.begin(), ms.end())}, {"samples", ms.size()}};
}

// ---- 3 and 5. Tracking N entities ------------------------------------------

struct TrackRun {
  double stateAtPerS = 0, advancePerS = 0, beforeStepMs = 0, stepMs = 0;
};

/// A watcher tracking `n` entities: created from one round of PDUs and put
/// into its simulation by a first pre-step.
struct Watcher {
  std::unique_ptr<sim::Simulation> sim;
  std::unique_ptr<sim_dis::Gateway> gateway;
};

Result<Watcher> makeWatcher(const std::shared_ptr<sim::SimWorld>& world, const sim_dis::DisFrame& frame,
                            const std::vector<Mover>& movers) {
  Watcher w;
  w.sim = std::make_unique<sim::Simulation>(world);
  w.gateway = std::make_unique<sim_dis::Gateway>(*w.sim, frame, watcherOptions(), nullptr, nullptr);
  const Stream one = makeStream(movers, 1);
  w.gateway->apply(one.front());
  w.gateway->beforeStep();
  if (w.gateway->remotes().size() != movers.size() || w.sim->entities().size() != movers.size()) {
    return Problem{"", 0, "bench dis: the watcher did not take every entity (a bug)"};
  }
  return w;
}

TrackRun trackOnce(Watcher& w, int steps) {
  TrackRun out;
  sim_dis::RemoteEntities& remotes = w.gateway->remotes();
  const double n = double(remotes.size());
  const double t0 = w.sim->timeS();
  // Baseline: the closed-form motion alone.
  double sink = 0;
  double c0 = cpuSeconds();
  for (int k = 0; k < steps; ++k) {
    const double t = t0 + k * kStepS;
    for (const auto& [key, r] : remotes.all()) sink += dis::advance(r.motion, t - r.motionS).position.x;
  }
  out.advancePerS = n * steps / (cpuSeconds() - c0);
  c0 = cpuSeconds();
  for (int k = 0; k < steps; ++k) {
    const double t = t0 + k * kStepS;
    for (auto& [key, r] : remotes.all()) {
      auto st = remotes.stateAt(r, t);
      if (st) sink += st->pose.position.x();
    }
  }
  out.stateAtPerS = n * steps / (cpuSeconds() - c0);
  keep(sink);
  // The gateway's pre-step work (no PDUs: placing every entity), then the
  // simulation's own step, each on its own.
  double before = 0, step = 0;
  for (int k = 0; k < steps; ++k) {
    c0 = cpuSeconds();
    w.gateway->beforeStep();
    const double c1 = cpuSeconds();
    w.sim->step();
    step += cpuSeconds() - c1;
    before += c1 - c0;
  }
  out.beforeStepMs = 1000 * before / steps;
  out.stepMs = 1000 * step / steps;
  return out;
}

// ---- 4. Table 9 --------------------------------------------------------------

struct Channel {
  std::string name;
  bool timeBased = false;
  double thresholdM = 0, intervalS = 0;
  std::uint8_t airAlgorithm = 2;
  std::unique_ptr<sim_dis::Publisher> publisher;
  std::unique_ptr<sim_dis::RemoteEntities> remotes;
  std::uint64_t pdus = 0, bytes = 0;
  struct Error {
    double sum = 0, max = 0;
    std::uint64_t n = 0;
    void add(double e) {
      sum += e;
      max = std::max(max, e);
      ++n;
    }
    nlohmann::json json() const { return {{"mean_m", n ? sum / double(n) : 0.0}, {"max_m", max}, {"samples", n}}; }
  } land, air, all;
};

sim::Entity exerciseEntity(const sim::SimWorld& w, std::uint64_t seed, std::uint32_t k) {
  sim::Entity e = zigzagEntity(w, seed, k);
  if (k % 5 == 0) {  // one in five an aircraft: 100-200 m/s, 1.5 km up, turning at 6 deg/s
    e.domain = sim::Domain::air;
    e.mobility = sim::Mobility::simple;
    e.position.y() = 1500;
    e.speedMs = 100 + 100 * unitRandom(seed ^ 0xa1, k);
    e.vehicle.maxSpeedMs = 250;
    e.vehicle.turnRateDegS = 6;
  }
  return e;
}

Result<nlohmann::json> table9Once(const std::shared_ptr<sim::SimWorld>& world, const sim_dis::DisFrame& frame,
                                  std::uint32_t entities, double seconds_, std::uint64_t seed) {
  sim::SimOptions so;
  so.seed = seed;
  sim::Simulation s(world, so);
  for (std::uint32_t k = 0; k < entities; ++k) {
    auto id = s.add(exerciseEntity(s.world(), seed, k));
    if (!id) return id.problems();
  }
  std::vector<Channel> channels;
  auto addChannel = [&](Channel c, sim::UpdateThresholds t) {
    sim_dis::PublishOptions po;
    po.thresholds = t;
    po.airAlgorithm = c.airAlgorithm;
    c.publisher = std::make_unique<sim_dis::Publisher>(frame, po);
    c.remotes = std::make_unique<sim_dis::RemoteEntities>(frame);
    channels.push_back(std::move(c));
  };
  const double inf = std::numeric_limits<double>::infinity();
  for (double m : {0.5, 1.0, 2.0, 5.0}) {
    for (int alg : {2, 4, 5}) {
      Channel c;
      c.thresholdM = m;
      c.airAlgorithm = std::uint8_t(alg);
      addChannel(std::move(c), {m, 3.0, 5.0});
    }
  }
  for (double i : {1.0 / 15, 1.0, 5.0}) {  // the seed's Table 9 intervals, FPW
    Channel c;
    c.timeBased = true;
    c.intervalS = i;
    addChannel(std::move(c), {inf, inf, i});
  }
  const dis::Header header;
  const std::uint64_t steps = std::uint64_t(std::llround(seconds_ / kStepS));
  for (std::uint64_t k = 0; k <= steps; ++k) {
    if (k > 0) s.step();
    const double t = s.timeS();
    const bool sample = k % 6 == 0;  // errors at 10 Hz
    for (const sim::Entity& e : s.entities()) {
      if (e.domain == sim::Domain::munition) continue;
      sim_dis::Identity who;
      who.id = {1, 1, std::uint16_t(e.id + 1)};
      who.force = e.force;
      who.type = e.domain == sim::Domain::air ? dis::EntityType{1, 2, 225, 1, 1, 0, 0}
                                              : dis::EntityType{1, 1, 225, 1, 1, 3, 0};
      for (Channel& c : channels) {
        if (auto st = c.publisher->offer(e, who, t, k == 0)) {
          const auto bytes = dis::encode(header, *st);
          ++c.pdus;
          c.bytes += bytes.size();
          auto pdu = dis::decode(bytes, "table9");
          if (!pdu || !pdu->entityState) return Problem{"", 0, "bench dis: a Table 9 PDU did not decode (a bug)"};
          c.remotes->update(*pdu->entityState, kSender, t, t);
        }
        if (!sample) continue;
        sim_dis::RemoteEntity* r = c.remotes->find(who.id);
        if (!r) continue;
        auto shown = c.remotes->stateAt(*r, t);
        if (!shown) continue;
        Eigen::Vector3d d = shown->pose.position - e.position;
        const bool air = e.domain == sim::Domain::air;
        if (!air) d.y() = 0;  // land: receivers align it to their ground
        (air ? c.air : c.land).add(d.norm());
        c.all.add(d.norm());
      }
    }
  }
  nlohmann::json errorBased = nlohmann::json::array(), timeBased = nlohmann::json::array();
  const double span = double(steps) * kStepS;
  const Channel* oneMetre = nullptr;
  for (const Channel& c : channels) {
    if (!c.timeBased && c.thresholdM == 1.0 && c.airAlgorithm == 2) oneMetre = &c;
  }
  for (const Channel& c : channels) {
    nlohmann::json j = {{"pdus", c.pdus},
                        {"pdus_per_s", double(c.pdus) / span},
                        {"pdus_per_entity_s", double(c.pdus) / span / entities},
                        {"bytes_per_s", double(c.bytes) / span},
                        {"error", c.all.json()},
                        {"land_error", c.land.json()},
                        {"air_error", c.air.json()}};
    if (c.timeBased) {
      j["interval_s"] = c.intervalS;
      j["algorithm"] = 2;
      j["pdus_over_threshold_1m"] = double(c.pdus) / double(std::max<std::uint64_t>(1, oneMetre->pdus));
      j["mean_error_over_threshold_1m"] =
          c.all.sum / double(std::max<std::uint64_t>(1, c.all.n)) /
          std::max(1e-12, oneMetre->all.sum / double(std::max<std::uint64_t>(1, oneMetre->all.n)));
      timeBased.push_back(std::move(j));
    } else {
      j["threshold_m"] = c.thresholdM;
      j["land_algorithm"] = 2;
      j["air_algorithm"] = c.airAlgorithm;
      errorBased.push_back(std::move(j));
    }
  }
  std::uint64_t air = 0;
  for (const sim::Entity& e : s.entities()) air += e.domain == sim::Domain::air ? 1 : 0;
  return nlohmann::json{{"entities", entities},
                        {"air_entities", air},
                        {"seconds", span},
                        {"error_sampled_hz", 10},
                        // Collisions stop an entity within a step: the truth jumps, and the
                        // receivers' smooth-back (0.5 s for aircraft) shows that as the largest errors.
                        {"entity_collisions", s.counters().collisions.entities},
                        {"object_collisions", s.counters().collisions.objects},
                        {"error_based", errorBased},
                        {"time_based", timeBased}};
}

Status check(const DisBenchOptions& o) {
  auto bad = [](const std::string& m) { return Status(Problem{"", 0, "bench dis: " + m}); };
  if (o.entities < 1 || o.entities > 1000000) return bad("DisBenchOptions::entities must be 1..1000000");
  if (o.pdusPerEntity < 2 || o.pdusPerEntity > 100) return bad("DisBenchOptions::pdusPerEntity must be 2..100");
  if (o.loopbackPdus < 1000 || o.loopbackPdus > 10000000) {
    return bad("DisBenchOptions::loopbackPdus must be 1000..10000000");
  }
  for (std::uint32_t n : o.trackedCounts) {
    if (n < 1 || n > 1000000) return bad("DisBenchOptions::trackedCounts must be 1..1000000 each");
  }
  for (std::uint32_t n : o.exerciseCounts) {
    if (n < 1 || n > 100000) return bad("DisBenchOptions::exerciseCounts must be 1..100000 each");
  }
  if (!(o.exerciseSeconds >= 1 && o.exerciseSeconds <= 3600)) {
    return bad("DisBenchOptions::exerciseSeconds must be 1..3600");
  }
  if (o.repeat < 1 || o.repeat > 100) return bad("DisBenchOptions::repeat must be 1..100");
  return {};
}

}  // namespace

DisBenchOptions quickDisBenchOptions() {
  DisBenchOptions o;
  o.entities = 2000;
  o.pdusPerEntity = 3;
  o.loopbackPdus = 20000;
  o.trackedCounts = {1000};
  o.exerciseCounts = {100};
  o.exerciseSeconds = 5;
  return o;
}

Result<DisBenchReport> runDisBench(const DisBenchOptions& o, const Notes& notes) {
  if (Status st = check(o); !st) return st.problems();
  auto grid = makeHillsGrid(kSizeKm, kSquareM, "dis");
  if (!grid) return grid.problems();
  auto world = std::make_shared<sim::SimWorld>(grid.value(), 0, 1);
  auto frame = hillsFrame();
  if (!frame) return frame.problems();
  char line[300];
  nlohmann::json j;
  j["options"] = {{"entities", o.entities},           {"pdus_per_entity", o.pdusPerEntity},
                  {"loopback_pdus", o.loopbackPdus},  {"tracked", o.trackedCounts},
                  {"exercises", o.exerciseCounts},    {"exercise_seconds", o.exerciseSeconds},
                  {"repeat", o.repeat},               {"seed", o.seed},
                  {"hardware_threads", std::thread::hardware_concurrency()}};

  // 1. From memory.
  notes.say("building the stream: " + std::to_string(o.entities) + " entities x " + std::to_string(o.pdusPerEntity) +
            " Entity State PDUs");
  auto movers = makeMovers(frame.value(), *world, o.entities, o.seed);
  if (!movers) return movers.problems();
  const Stream stream = makeStream(movers.value(), o.pdusPerEntity);
  {
    std::vector<double> decode, create, apply;
    for (int r = 0; r < o.repeat; ++r) {
      auto m = memoryOnce(world, frame.value(), stream);
      if (!m) return m.problems();
      decode.push_back(m->decodePerS);
      create.push_back(m->createPerS);
      apply.push_back(m->applyPerS);
      std::snprintf(line, sizeof line, "memory, run %d: decode %.0f/s, apply %.0f/s (create %.0f/s)", r + 1,
                    m->decodePerS, m->applyPerS, m->createPerS);
      notes.say(line);
    }
    const double a = stats::median(apply), d = stats::median(decode);
    j["memory"] = {{"pdu_bytes", stream.front().front().bytes.size()},
                   {"decode", rateJson(decode, std::uint64_t(o.entities) * o.pdusPerEntity)},
                   {"apply", rateJson(apply, std::uint64_t(o.entities) * (o.pdusPerEntity - 1))},
                   {"create", rateJson(create, o.entities)},
                   {"apply_over_decode", a / d},
                   {"goal_pdus_per_s", kGoalMemory},
                   {"meets_goal", a >= kGoalMemory}};
  }

  // 2. Loopback.
  {
    std::vector<double> recv, applied, sent;
    std::uint64_t kernel = 0, queue = 0, lost = 0, maxLost = 0;
    std::vector<double> readLat, appliedLat;
    for (int r = 0; r < o.repeat; ++r) {
      auto b = loopbackOnce(world, frame.value(), stream, o.loopbackPdus, false, 0);
      if (!b) return b.problems();
      auto a = loopbackOnce(world, frame.value(), stream, o.loopbackPdus, true, 0);
      if (!a) return a.problems();
      recv.push_back(b->receivedPerS);
      applied.push_back(a->receivedPerS);
      sent.push_back(a->sentPerS);
      kernel += a->kernelDrops;
      queue += a->queueDrops;
      lost = a->sent - a->received;
      maxLost = std::max(maxLost, lost);
      readLat.insert(readLat.end(), a->readLatencyMs.begin(), a->readLatencyMs.end());
      appliedLat.insert(appliedLat.end(), a->appliedLatencyMs.begin(), a->appliedLatencyMs.end());
      std::snprintf(line, sizeof line,
                    "loopback, run %d: received %.0f/s (drain only) and %.0f/s (applied), sent %.0f/s, "
                    "%llu of %llu lost (kernel %llu, queue %llu)",
                    r + 1, b->receivedPerS, a->receivedPerS, a->sentPerS, (unsigned long long)lost,
                    (unsigned long long)a->sent, (unsigned long long)a->kernelDrops, (unsigned long long)a->queueDrops);
      notes.say(line);
    }
    // Latency without a backlog: the same path paced at kPacedHz.
    const std::uint64_t pacedCount = std::min<std::uint64_t>(o.loopbackPdus, std::uint64_t(kPacedHz));
    std::vector<double> pacedRead, pacedApplied;
    for (int r = 0; r < o.repeat; ++r) {
      auto p = loopbackOnce(world, frame.value(), stream, pacedCount, true, kPacedHz);
      if (!p) return p.problems();
      pacedRead.insert(pacedRead.end(), p->readLatencyMs.begin(), p->readLatencyMs.end());
      pacedApplied.insert(pacedApplied.end(), p->appliedLatencyMs.begin(), p->appliedLatencyMs.end());
    }
    const double a = stats::median(applied);
    j["loopback"] = {{"pdus_per_run", o.loopbackPdus},
                     {"receive", rateJson(recv, o.loopbackPdus)},
                     {"apply", rateJson(applied, o.loopbackPdus)},
                     {"sent_per_s", stats::median(sent)},
                     {"apply_over_receive", a / stats::median(recv)},
                     {"apply_over_memory", a / j["memory"]["apply"]["per_s"].get<double>()},
                     {"drops", {{"kernel", kernel}, {"queue", queue}, {"max_lost_per_run", maxLost}}},
                     {"latency_blast", {{"read", latencyJson(readLat)}, {"applied", latencyJson(appliedLat)}}},
                     {"latency_paced", {{"rate_per_s", kPacedHz},
                                        {"read", latencyJson(pacedRead)},
                                        {"applied", latencyJson(pacedApplied)}}},
                     {"goal_pdus_per_s", kGoalLoopback},
                     {"meets_goal", a >= kGoalLoopback},
                     // Everything sent arrived and was applied about as fast as it was sent:
                     // the sender (and the kernel's loopback delivery it pays for) set the
                     // rate, so the receiving side's figure is a lower bound.
                     {"sender_limited", maxLost == 0 && a >= 0.9 * stats::median(sent)}};
  }

  // 3 and 5. Tracking 1,000 to 100,000 entities.
  nlohmann::json dr = nlohmann::json::array(), watch = nlohmann::json::array();
  for (std::uint32_t n : o.trackedCounts) {
    notes.say("tracking " + std::to_string(n) + " entities: creating them");
    auto mv = makeMovers(frame.value(), *world, n, o.seed ^ 0x77);
    if (!mv) return mv.problems();
    auto w = makeWatcher(world, frame.value(), mv.value());
    if (!w) return w.problems();
    const int steps = n >= 100000 ? 20 : 60;
    std::vector<double> stateAt, advance, before, step;
    for (int r = 0; r < o.repeat; ++r) {
      const TrackRun t = trackOnce(w.value(), steps);
      stateAt.push_back(t.stateAtPerS);
      advance.push_back(t.advancePerS);
      before.push_back(t.beforeStepMs);
      step.push_back(t.stepMs);
      std::snprintf(line, sizeof line,
                    "tracking %u, run %d: stateAt %.0f/s, advance %.0f/s; pre-step %.2f ms, step %.2f ms", n, r + 1,
                    t.stateAtPerS, t.advancePerS, t.beforeStepMs, t.stepMs);
      notes.say(line);
    }
    const double sa = stats::median(stateAt), ad = stats::median(advance);
    const double drStepMs = 1000.0 * n / sa;
    dr.push_back({{"entities", n},
                  {"steps_per_run", steps},
                  {"state_at", rateJson(stateAt, std::uint64_t(n) * steps)},
                  {"advance", rateJson(advance, std::uint64_t(n) * steps)},
                  {"state_at_over_advance", ad / sa},
                  {"step_ms", drStepMs},
                  {"fits_60hz", drStepMs <= 1000.0 / 60}});
    const double b = stats::median(before), s = stats::median(step);
    watch.push_back({{"entities", n},
                     {"before_step_ms", b},
                     {"sim_step_ms", s},
                     {"frame_ms", b + s},
                     {"fits_30fps", b + s <= 1000.0 / 30}});
  }
  j["dead_reckoning"] = dr;
  j["watch"] = watch;
  j["viewer_measured"] = false;

  // 4. Table 9.
  nlohmann::json exercises = nlohmann::json::array();
  for (std::uint32_t n : o.exerciseCounts) {
    notes.say("Table 9: " + std::to_string(n) + " entities for " + std::to_string(int(o.exerciseSeconds)) + " s");
    auto t = table9Once(world, frame.value(), n, o.exerciseSeconds, o.seed);
    if (!t) return t.problems();
    exercises.push_back(std::move(t.value()));
  }
  j["table9"] = {{"exercises", exercises}};
  j["notes"] = {
      "memory: one PDU per datagram; apply is the update rounds (entities known), create the first round",
      "loopback: sender, receiver thread and consumer share this machine's cores; latency one-way on one steady clock",
      "watch: the gateway's pre-step and the simulation's step with N remote entities, no rendering; the viewer's "
      "frame rate with N tracked entities is measured with fly --dis beside a publishing sim --dis (docs/DIS.md 13)",
      "table9: errors are horizontal for land entities (receivers align them to the ground), 3-D for aircraft"};
  DisBenchReport rep;
  rep.json = std::move(j);
  return rep;
}

}  // namespace sandtable::bench
