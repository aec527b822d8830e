#pragma once
// Shared by the sim_dis tests: the test frame, the receiver's view of a
// PDU, and two simulations on one world joined by gateways through queues
// (TwoSims), with a hook on what B drains for fault injection.
#include <gtest/gtest.h>

#include <deque>
#include <functional>
#include <memory>
#include <vector>

#include "../../core/test/sim_fixture.h"
#include "sandtable/dis/pdu.h"
#include "sandtable/sim/simulation.h"
#include "sandtable/sim/step_host.h"
#include "sandtable/sim_dis/gateway.h"

namespace sandtable::sim_dis::test {

// UTM 33N, north-west corner at E 300 km, N 5,600 km (about 12.2 E, 50.5 N).
inline DisFrame testFrame() {
  auto f = geodesy::DatabaseFrame::create("EPSG:32633", 300000.0, 5600000.0);
  EXPECT_TRUE(f.ok()) << f.error();
  return DisFrame(f.value());
}

inline double horizontal(const Eigen::Vector3d& a, const Eigen::Vector3d& b) {
  return Eigen::Vector2d(a.x() - b.x(), a.z() - b.z()).norm();
}

/// The PDU as a receiver gets it: encoded and decoded (floats rounded).
inline dis::EntityState overTheWire(const dis::EntityState& s) {
  auto pdu = dis::decode(dis::encode(dis::Header{}, s), "test");
  EXPECT_TRUE(pdu.ok()) << pdu.error();
  return *pdu->entityState;
}

/// Two simulations on one flat world (2 km square at 100 m), joined by a
/// queue per direction. A publishes as site 1, B as site 2; both snap
/// corrections (no smoothing) so a receiver shows exactly its dead reckoning.
struct TwoSims {
  /// What B drains, in arrival order, before B applies it: a test drops,
  /// reorders, holds back or adds datagrams here.
  using Filter = std::function<void(std::vector<dis::Datagram>&)>;

  std::shared_ptr<sim::SimWorld> world = sim::test::makeWorld([](double, double) { return 100.0; }, 201, 10);
  sim::Simulation a, b;
  std::deque<dis::Datagram> toA, toB;
  Filter intoB;
  Filter intoA;  ///< the same for what A drains
  std::unique_ptr<Gateway> ga, gb;
  sim::StepHost ha{a}, hb{b};

  explicit TwoSims(sim::SimOptions options = {}) : a(world, options), b(world, options) {
    GatewayOptions oa, ob;
    oa.site = 1;
    ob.site = 2;
    oa.remote.blendLandS = ob.remote.blendLandS = 0;
    ga = std::make_unique<Gateway>(a, testFrame(), oa, drainer(toA, &intoA), sender(toB));
    gb = std::make_unique<Gateway>(b, testFrame(), ob, drainer(toB, &intoB), sender(toA));
    ga->attach(ha);
    gb->attach(hb);
  }
  TwoSims(const TwoSims&) = delete;
  TwoSims& operator=(const TwoSims&) = delete;

  static Gateway::Drain drainer(std::deque<dis::Datagram>& q, const Filter* filter) {
    return [&q, filter](std::vector<dis::Datagram>& out) {
      out.assign(q.begin(), q.end());
      q.clear();
      if (filter && *filter) (*filter)(out);
    };
  }
  static Gateway::Send sender(std::deque<dis::Datagram>& q, dis::Address from = {0x7f000001, 3000}) {
    return [&q, from](std::span<const std::byte> bytes) {
      dis::Datagram d;
      d.sender = from;
      d.bytes.assign(bytes.begin(), bytes.end());
      q.push_back(std::move(d));
    };
  }
  void step() {
    ha.step();
    hb.step();
  }
};

}  // namespace sandtable::sim_dis::test
