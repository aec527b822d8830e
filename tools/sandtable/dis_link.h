#pragma once
// What `sim --dis` and `fly --dis` share: the socket and its receive
// thread, the database frame from the manifest, and the simulation's DIS
// gateway on them (docs/DIS.md §11). Problems are printed; nullptr means
// exit 2.
#include <cstdint>
#include <memory>
#include <string>

#include <CLI/CLI.hpp>
#include <nlohmann/json.hpp>

#include "sandtable/dis/socket.h"
#include "sandtable/formats/manifest.h"
#include "sandtable/sim/simulation.h"
#include "sandtable/sim_dis/gateway.h"

namespace sandtable::cli {

struct DisArgs {
  std::string endpoint;   ///< --dis [ADDR:]PORT; empty: not networked
  std::string interface;  ///< --dis-interface
  unsigned exercise = 1, site = 1, application = 1;
  bool publish = true;    ///< false: the stealth viewer watches only
};

struct DisLink {
  std::unique_ptr<dis::Receiver> receiver;
  std::unique_ptr<sim_dis::Gateway> gateway;
  std::uint64_t sendErrors = 0;
  std::string firstSendError;
};

/// Adds --dis, --dis-interface, --exercise, --site and --application to `sub`.
void addDisOptions(CLI::App* sub, DisArgs& a);
std::unique_ptr<DisLink> openDisLink(const std::string& cmd, const manifest::Manifest& m, sim::Simulation& s,
                                     const DisArgs& a);
/// One line on what the gateway did, for the summary.
std::string disSummary(const DisLink& link);
/// The panel's line: "DIS 31 PDU/S  40 TRACKED  12 CORRECTIONS  0 DROPPED";
/// `last` keeps (wall seconds, PDUs) of the previous call for the rate.
std::string disPanelLine(const DisLink& link, std::pair<double, std::uint64_t>& last);
/// The same as JSON, with every remote entity tracked at the end (frame
/// position and WGS-84 lon, lat, height), those that left, this
/// simulation's own entities where they are now, and the wall clock
/// (unix_time_s) when it was made.
nlohmann::json disJson(const DisLink& link, const sim::Simulation& s);

}  // namespace sandtable::cli
