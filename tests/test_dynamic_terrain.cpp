// Dynamic terrain on real data, against independent computations (issue 37,
// "Tests on real data"; docs/DYNAMIC.md):
//  - Monaco's SRTM at 30 m: a crater on the steepest slope GDAL finds; the
//    edited ground at its centre is the profile's depth under the source
//    warped by GDAL; the volume removed over the posts of two exported
//    GeoTIFFs (read by GDAL) is the numerically integrated profile's; a
//    tank driven through it stays on the edited ground `sample --journal`
//    reads and pitches by that ground's slope;
//  - Bayreuth with its OSM, a crater on a module corner: four modules
//    re-meshed at every level, no magenta shows through the baked database
//    at full, rings and sse, and validate passes on the baked database;
//  - two `sim --dis` processes through a relay that drops 10 % of the
//    datagrams end with the same edits and the same heights hash.
#include <gtest/gtest.h>

#include <algorithm>
#include <array>
#include <atomic>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <memory>
#include <random>
#include <thread>

#include <arpa/inet.h>
#include <netinet/in.h>
#include <poll.h>
#include <sys/socket.h>
#include <unistd.h>

#include <gdal.h>
#include <gdal_utils.h>
#include <nlohmann/json.hpp>
#include <ogr_api.h>
#include <ogr_spatialref.h>
#include <ogrsf_frmts.h>

#include "sandtable/converters/crs.h"
#include "sandtable/edits/editor.h"
#include "sandtable/paging/world.h"
#include "sandtable/render/renderer.h"
#include "sandtable/sim/sim_world.h"
#include "sandtable/sim/simulation.h"
#include "sandtable/sim/units.h"
#include "test_support.h"
#include "viewer_support.h"

namespace sandtable::test {
namespace {

constexpr double kPi = 3.14159265358979323846;

// ---------------------------------------------------------------- GDAL side

/// A single-band raster read through GDAL, with its georeferencing.
struct Raster {
  int w = 0, h = 0;
  double gt[6] = {};
  std::string wkt;
  std::vector<float> v;
  float at(int i, int j) const { return v[std::size_t(j) * w + i]; }
  /// Easting and northing of pixel (i, j)'s centre: post (i, j).
  std::array<double, 2> post(int i, int j) const {
    return {gt[0] + (i + 0.5) * gt[1], gt[3] + (j + 0.5) * gt[5]};
  }
};

Raster readRaster(GDALDatasetH ds) {
  Raster r;
  r.w = GDALGetRasterXSize(ds), r.h = GDALGetRasterYSize(ds);
  GDALGetGeoTransform(ds, r.gt);
  r.wkt = GDALGetProjectionRef(ds);
  r.v.resize(std::size_t(r.w) * r.h);
  EXPECT_EQ(GDALRasterIO(GDALGetRasterBand(ds, 1), GF_Read, 0, 0, r.w, r.h, r.v.data(), r.w, r.h, GDT_Float32, 0, 0),
            CE_None);
  return r;
}

Raster readTif(const std::string& path) {
  GDALDatasetH ds = GDALOpen(path.c_str(), GA_ReadOnly);
  EXPECT_NE(ds, nullptr) << path;
  if (!ds) return {};
  Raster r = readRaster(ds);
  GDALClose(ds);
  return r;
}

constexpr float kVoid = -32768;

/// The SRTM sources warped by GDAL (bilinear, exact transforms) onto
/// `like`'s pixels, as `gdalwarp -r bilinear -et 0` would: the ground as
/// the source has it, independent of the builder.
Raster warpSourcesOnto(const Raster& like, const std::vector<std::string>& hgtZips) {
  GDALDatasetH mem = GDALCreate(GDALGetDriverByName("MEM"), "", like.w, like.h, 1, GDT_Float32, nullptr);
  GDALSetGeoTransform(mem, const_cast<double*>(like.gt));
  GDALSetProjection(mem, like.wkt.c_str());
  GDALFillRaster(GDALGetRasterBand(mem, 1), kVoid, 0);
  std::vector<GDALDatasetH> srcs;
  for (const std::string& zip : hgtZips) {
    const std::string name = std::filesystem::path(zip).stem().string();  // N43E007.hgt
    const std::string path = "/vsizip/" + zip + "/" + name;
    srcs.push_back(GDALOpen(path.c_str(), GA_ReadOnly));
    EXPECT_NE(srcs.back(), nullptr) << path;
  }
  const char* argv[] = {"-r", "bilinear", "-et", "0", "-srcnodata", "-32768", "-dstnodata", "-32768", nullptr};
  GDALWarpAppOptions* o = GDALWarpAppOptionsNew(const_cast<char**>(argv), nullptr);
  int usage = 0;
  EXPECT_NE(GDALWarp(nullptr, mem, int(srcs.size()), srcs.data(), o, &usage), nullptr);
  GDALWarpAppOptionsFree(o);
  for (GDALDatasetH s : srcs) GDALClose(s);
  Raster r = readRaster(mem);
  GDALClose(mem);
  return r;
}

/// The database CRS <-> WGS 84 lon/lat through OGR (not the product's geodesy).
class LonLat {
 public:
  explicit LonLat(const std::string& wkt) {
    wgs_.SetWellKnownGeogCS("WGS84");
    wgs_.SetAxisMappingStrategy(OAMS_TRADITIONAL_GIS_ORDER);
    EXPECT_EQ(frame_.importFromWkt(wkt.c_str()), OGRERR_NONE);
    frame_.SetAxisMappingStrategy(OAMS_TRADITIONAL_GIS_ORDER);
    toGeo_.reset(OGRCreateCoordinateTransformation(&frame_, &wgs_));
    toFrame_.reset(OGRCreateCoordinateTransformation(&wgs_, &frame_));
  }
  std::array<double, 2> lonLat(double e, double n) const {
    toGeo_->Transform(1, &e, &n);
    return {e, n};
  }
  std::array<double, 2> eastNorth(double lon, double lat) const {
    toFrame_->Transform(1, &lon, &lat);
    return {lon, lat};
  }

 private:
  OGRSpatialReference wgs_, frame_;
  std::unique_ptr<OGRCoordinateTransformation> toGeo_, toFrame_;
};

// ------------------------------------------------------------ CLI helpers

/// `sandtable sample DB [--journal J] --points FILE --json` at eastings and
/// northings (written as lon/lat through OGR): elevations in order.
std::vector<double> sampleAt(const std::string& db, const std::string& journal, const LonLat& ll,
                             const std::vector<std::array<double, 2>>& en, const std::string& scratch) {
  std::string lines;
  char buf[96];
  for (const auto& p : en) {
    const auto g = ll.lonLat(p[0], p[1]);
    std::snprintf(buf, sizeof buf, "%.12f %.12f\n", g[0], g[1]);
    lines += buf;
  }
  spit(scratch, lines);
  std::vector<std::string> args = {"sample", db, "--points", scratch, "--json"};
  if (!journal.empty()) args.insert(args.end(), {"--journal", journal});
  const auto s = runCli(args);
  EXPECT_EQ(s.exitCode, 0) << s.err;
  std::vector<double> out;
  if (s.exitCode != 0) return out;
  for (const auto& p : nlohmann::json::parse(s.out)) out.push_back(p["elevation"].get<double>());
  EXPECT_EQ(out.size(), en.size());
  return out;
}

double sampleOne(const std::string& db, const std::string& journal, double e, double n) {
  std::vector<std::string> args = {"sample", db, "--xy", std::to_string(e), std::to_string(n), "--json"};
  if (!journal.empty()) args.insert(args.end(), {"--journal", journal});
  const auto s = runCli(args);
  EXPECT_EQ(s.exitCode, 0) << s.err;
  return s.exitCode == 0 ? nlohmann::json::parse(s.out)["elevation"].get<double>() : NAN;
}

/// `export DB [--journal J] --grid -o PATH`, read back through GDAL.
Raster exportGrid(const std::string& db, const std::string& journal, const std::string& path) {
  std::vector<std::string> args = {"export", db, "--grid", "-o", path};
  if (!journal.empty()) args.insert(args.end(), {"--journal", journal});
  const auto r = runCli(args);
  EXPECT_EQ(r.exitCode, 0) << r.err;
  return readTif(path);
}

// ----------------------------------------------- the crater, independently

/// docs/DYNAMIC.md "Crater": the change at distance r, written out here from
/// the formula (not the product's profile code).
double craterDelta(double r, double R, double d) {
  const double rho = d / 4;
  if (r <= R) return -d + (d + rho) * (r / R) * (r / R);
  if (r < 2 * R) return rho * ((2 * R - r) / R) * ((2 * R - r) / R);
  return 0;
}

/// Volume below the ground before, by Simpson's rule over rings 2 pi r dr.
double craterVolumeRemovedNumerically(double R, double d) {
  const int n = 20000;  // even
  const double h = 2 * R / n;
  double s = 0;
  for (int k = 0; k <= n; ++k) {
    const double r = k * h;
    const double f = std::max(0.0, -craterDelta(r, R, d)) * 2 * kPi * r;
    s += f * (k == 0 || k == n ? 1 : (k % 2 ? 4 : 2));
  }
  return s * h / 3;
}

// ================================================================ Monaco

class DynamicMonaco : public ::testing::Test {
 protected:
  static void SetUpTestSuite() {
    if (!haveData()) return;
    convert::initGdal();
    tmp_ = new TempDir("dyn-monaco");
    // Bilinear point samples (no triangle fit): the posts are what GDAL's
    // bilinear warp of the source gives, which the test checks first.
    const auto b = runCli({"build", "--elevation", data("elevation/srtm/N43E007.hgt.zip"), "--extent", "7.39", "43.72",
                           "7.44", "43.76", "--spacing", "30", "--resample", "bilinear", "--fit", "posts", "--icons",
                           std::string(SANDTABLE_SOURCE_DIR) + "/samples/icons.txt", "-o", *tmp_ / "db"});
    ASSERT_EQ(b.exitCode, 0) << b.err;
  }
  static void TearDownTestSuite() {
    delete tmp_;
    tmp_ = nullptr;
  }
  void SetUp() override { SANDTABLE_REQUIRE_DATA(); }
  static std::string db() { return *tmp_ / "db"; }
  static inline TempDir* tmp_ = nullptr;
};

/// The steepest post GDAL's warp of the source shows, at most `maxSlope`
/// (rise over run, central differences), with `margin` posts of valid
/// ground round it.
std::array<int, 2> steepestPost(const Raster& g, int margin, double maxSlope, double& slope) {
  std::array<int, 2> best = {-1, -1};
  slope = 0;
  const double sx = g.gt[1], sz = -g.gt[5];
  for (int j = margin; j < g.h - margin; ++j) {
    for (int i = margin; i < g.w - margin; ++i) {
      bool valid = true;
      for (int b = -margin; b <= margin && valid; ++b) {
        for (int a = -margin; a <= margin && valid; ++a) valid = g.at(i + a, j + b) != kVoid;
      }
      if (!valid) continue;
      const double gx = (g.at(i + 1, j) - g.at(i - 1, j)) / (2 * sx);
      const double gz = (g.at(i, j + 1) - g.at(i, j - 1)) / (2 * sz);
      const double s = std::hypot(gx, gz);
      if (s <= maxSlope && s > slope) slope = s, best = {i, j};
    }
  }
  return best;
}

/// A tracked tank on autopilot (4 m/s) driven across the crater along the
/// slope's contour through its centre, on the edited world (the editor
/// replaying the journal, as `sim --journal` opens it). Every 10 steps: its
/// height is the edited ground `sample --journal` reads under it (1 cm),
/// and its pitch is that ground's slope from its origin to the point
/// half its length ahead (SIM.md §4), read by `sample` too.
void driveATankThroughTheCrater(const std::string& db, const std::string& journal, const Raster& g,
                                std::array<int, 2> c, double R, double depth, const TempDir& t) {
  auto base = paging::World::open(db);
  ASSERT_TRUE(base.ok()) << base.error();
  edits::EditorOptions eo;
  eo.journal = journal;
  eo.readOnly = true;
  eo.background = false;
  auto ed = edits::Editor::open(base.value(), eo);
  ASSERT_TRUE(ed.ok()) << ed.error();
  auto world = sim::SimWorld::open(*ed.value()->world());
  ASSERT_TRUE(world.ok()) << world.error();
  const double oe = world.value()->originEasting(), on = world.value()->originNorthing();
  sim::SimOptions so;
  so.collisions = false;
  sim::Simulation s(world.value(), so);

  // The contour at the centre (GDAL's ground): across the gradient.
  const double gx = g.at(c[0] + 1, c[1]) - g.at(c[0] - 1, c[1]), gz = g.at(c[0], c[1] + 1) - g.at(c[0], c[1] - 1);
  const double dirX = -gz / std::hypot(gx, gz), dirZ = gx / std::hypot(gx, gz);  // world x east, z south
  const double heading = std::atan2(dirX, -dirZ) * sim::kRadToDeg;
  const auto centre = g.post(c[0], c[1]);
  const double cx = centre[0] - oe, cz = on - centre[1];
  sim::Entity tank;
  tank.name = "tank";
  tank.icon = *world.value()->iconIndex("tank");
  tank.mobility = sim::Mobility::tracked;
  tank.position = {cx - 2.2 * R * dirX, 0, cz - 2.2 * R * dirZ};
  tank.headingDeg = tank.commands.headingDeg = heading;
  tank.speedMs = tank.commands.speedMs = 4;
  tank.autopilot = true;
  ASSERT_TRUE(s.add(tank));

  struct Pose { double x, y, z, pitch, heading, halfLength; };
  std::vector<Pose> poses;
  for (int k = 0; k < 60 * 300; ++k) {
    s.step();
    const sim::Entity& e = s.entity(0);
    if (k % 10 == 0) poses.push_back({e.position.x(), e.position.y(), e.position.z(), e.pitchDeg, e.headingDeg,
                                      e.halfLength});
    if (std::hypot(e.position.x() - cx, e.position.z() - cz) > 2.2 * R && k > 60 * 60) break;
  }
  ASSERT_GT(poses.size(), 100u);
  std::vector<std::array<double, 2>> at, front;
  for (const Pose& p : poses) {
    const Eigen::Vector3d f = sim::headingVector(p.heading);
    at.push_back({p.x + oe, on - p.z});
    front.push_back({p.x + f.x() * p.halfLength + oe, on - (p.z + f.z() * p.halfLength)});
  }
  const LonLat ll(base.value()->manifest().crsWkt);
  const auto hAt = sampleAt(db, journal, ll, at, t / "at.txt");
  const auto hFront = sampleAt(db, journal, ll, front, t / "front.txt");
  ASSERT_EQ(hAt.size(), poses.size());
  ASSERT_EQ(hFront.size(), poses.size());
  double worstY = 0, worstPitch = 0, steepest = 0, closest = 1e9, lowest = 1e9;
  for (std::size_t k = 0; k < poses.size(); ++k) {
    const Pose& p = poses[k];
    worstY = std::max(worstY, std::abs(p.y - hAt[k]));
    const double measured = std::atan2(hFront[k] - hAt[k], p.halfLength) * sim::kRadToDeg;
    worstPitch = std::max(worstPitch, std::abs(p.pitch - measured));
    const double r = std::hypot(p.x - cx, p.z - cz);
    if (r < R) steepest = std::max(steepest, std::abs(p.pitch));
    closest = std::min(closest, r);
    lowest = std::min(lowest, p.y);
  }
  // The wall's steepest slope along a line through the centre, from the
  // formula: d(delta)/dr at r = R is 2 (d + d/4) / R (the ground's own slope
  // along the contour is about 0). The drawn wall is the parabola's chords
  // between posts 30 m apart, crossed obliquely, so less steep than its
  // tangent at the crest: the pitch lies between 60 % of it and it.
  const double wall = std::atan(2 * 1.25 * depth / R) * sim::kRadToDeg;
  EXPECT_LT(worstY, 0.01);
  EXPECT_LT(worstPitch, 0.1);
  EXPECT_LT(closest, 5.0);
  EXPECT_GT(steepest, 0.6 * wall);
  EXPECT_LT(steepest, wall + 0.5);
  std::printf("[ monaco tank ] %zu poses, heading %.1f deg, passed %.2f m from the centre, lowest %.2f m: "
              "|y - sample --journal| <= %.2g m, |pitch - measured slope| <= %.3f deg; steepest pitch in the bowl "
              "%.2f deg vs the wall's %.2f deg\n",
              poses.size(), heading, closest, lowest, worstY, worstPitch, steepest, wall);
}

TEST_F(DynamicMonaco, aCraterOnASteepSlopeHasItsDepthItsVolumeAndATankFollowsIt) {
  TempDir t("dyn-crater");
  // The database's unedited grid, checked against GDAL's own warp of the
  // source onto the same pixels: equal, so either is "the original ground".
  const Raster before = exportGrid(db(), "", t / "before.tif");
  ASSERT_GT(before.w, 0);
  const Raster source = warpSourcesOnto(before, {data("elevation/srtm/N43E007.hgt.zip")});
  double worstWarp = 0;
  std::size_t compared = 0;
  for (std::size_t k = 0; k < before.v.size(); ++k) {
    if (source.v[k] == kVoid) continue;
    worstWarp = std::max(worstWarp, double(std::abs(before.v[k] - source.v[k])));
    ++compared;
  }
  EXPECT_GT(compared, before.v.size() * 9 / 10);
  EXPECT_LT(worstWarp, 2e-3);  // the build's bilinear in doubles, GDAL's in floats

  // A crater of radius 5 posts (the posts resolve it: refineCells gives 0)
  // centred on the steepest post with slope <= 0.35 (19 degrees, so a tank
  // still climbs out) and 11 posts of valid ground round it.
  const double spacing = before.gt[1], R = 150, depth = 10;
  double slope = 0;
  const auto [ci, cj] = steepestPost(source, 11, 0.35, slope);
  ASSERT_GE(ci, 0);
  const auto centre = source.post(ci, cj);
  const double ground = source.at(ci, cj);
  const std::string journal = t / "edits.journal";
  const auto a = runCli({"edits", "apply", "crater", db(), "--journal", journal, "--xy", std::to_string(centre[0]),
                         std::to_string(centre[1]), "--radius", "150", "--depth", "10", "--json"});
  ASSERT_EQ(a.exitCode, 0) << a.err;

  // Depth: at the centre, d below the source's ground (the warps' 2 mm).
  const double atCentre = sampleOne(db(), journal, centre[0], centre[1]);
  EXPECT_NEAR(atCentre, ground - depth, 2e-3);

  // Volume: the posts' differences of two GDAL-read exports, against the
  // profile integrated numerically.
  const Raster after = exportGrid(db(), journal, t / "after.tif");
  ASSERT_EQ(after.v.size(), before.v.size());
  double removed = 0, added = 0;
  for (std::size_t k = 0; k < after.v.size(); ++k) {
    const double dh = double(after.v[k]) - double(before.v[k]);
    (dh < 0 ? removed : added) += std::abs(dh) * spacing * spacing;
  }
  const double expected = craterVolumeRemovedNumerically(R, depth);
  EXPECT_NEAR(expected, 0.4 * kPi * R * R * depth, 1e-6 * expected);  // DYNAMIC.md's closed form, as a check
  EXPECT_NEAR(removed / expected, 1.0, 0.01);
  std::printf("[ monaco crater ] post (%d, %d) slope %.3f (%.1f deg), ground %.2f m; sample at centre %.3f m "
              "(ground - d = %.3f); source warp vs export max %.2g m over %zu posts; removed %.0f m3 over posts vs "
              "%.0f m3 integrated (%+.3f %%); added %.0f m3\n",
              ci, cj, slope, std::atan(slope) * sim::kRadToDeg, ground, atCentre, ground - depth, worstWarp, compared,
              removed, expected, 100 * (removed / expected - 1), added);

  driveATankThroughTheCrater(db(), journal, source, {ci, cj}, R, depth, t);
}

// ============================================================== Bayreuth

/// North of Bayreuth from SRTM with its OSM (roads, forests, a town) at
/// 30 m and the sample icons, as tests/test_dis_sim.cpp builds it.
class DynamicBayreuth : public ::testing::Test {
 protected:
  static void SetUpTestSuite() {
    if (!haveData()) return;
    convert::initGdal();
    tmp_ = new TempDir("dyn-bayreuth");
    const auto b = runCli({"build", "--elevation", data("elevation/srtm/N49E011.hgt.zip"), "--extent", "11.55", "49.94",
                           "11.62", "49.99", "--spacing", "30", "--culture", data("culture/osm/north-bayreuth.osm.gz"),
                           "--icons", std::string(SANDTABLE_SOURCE_DIR) + "/samples/icons.txt", "-o", *tmp_ / "db"});
    ASSERT_EQ(b.exitCode, 0) << b.err;
  }
  static void TearDownTestSuite() {
    delete tmp_;
    tmp_ = nullptr;
  }
  void SetUp() override { SANDTABLE_REQUIRE_DATA(); }
  static std::string db() { return *tmp_ / "db"; }
  static inline TempDir* tmp_ = nullptr;
};

// ----------------------------------------------- two processes, 10 % loss

/// A UDP socket on 127.0.0.1:port sharing the port (SO_REUSEADDR) with the
/// `sim --dis 127.0.0.1:port` that binds 0.0.0.0:port: the kernel hands a
/// datagram sent to 127.0.0.1:port to the socket bound to that address
/// rather than the wildcard, so the relay, not the sim, reads what the sim
/// sends, and a datagram the relay sends to 127.0.0.2:port reaches only the
/// sim.
int relaySocket(std::uint16_t port) {
  const int fd = ::socket(AF_INET, SOCK_DGRAM | SOCK_CLOEXEC, 0);
  const int one = 1;
  ::setsockopt(fd, SOL_SOCKET, SO_REUSEADDR, &one, sizeof one);
  sockaddr_in a{};
  a.sin_family = AF_INET;
  a.sin_port = htons(port);
  a.sin_addr.s_addr = htonl(INADDR_LOOPBACK);
  EXPECT_EQ(::bind(fd, reinterpret_cast<sockaddr*>(&a), sizeof a), 0) << "relay bind 127.0.0.1:" << port;
  return fd;
}

/// Forwards every datagram sim A sends (to 127.0.0.1:portA) to sim B
/// (127.0.0.2:portB) and back, dropping each with probability 10 %
/// (a fixed-seed generator): the lossy link, where the kernel has
/// no netem for `tc` to add loss with (`unshare -rn` + `tc qdisc add dev lo
/// root netem loss 10%`: "Specified qdisc kind is unknown"). The first
/// crater PDU each way is always dropped, so a heartbeat must bring it.
class LossyRelay {
 public:
  LossyRelay(std::uint16_t portA, std::uint16_t portB) : ports_{portA, portB} {
    fds_[0] = relaySocket(portA), fds_[1] = relaySocket(portB);
    thread_ = std::thread([this] { run(); });
  }
  ~LossyRelay() {
    stop_ = true;
    thread_.join();
    ::close(fds_[0]), ::close(fds_[1]);
  }
  std::uint64_t forwarded(int from) const { return forwarded_[from]; }
  std::uint64_t dropped(int from) const { return dropped_[from]; }
  std::uint64_t droppedObjects(int from) const { return droppedObjects_[from]; }

 private:
  void run() {
    std::mt19937_64 rng(37);
    std::uniform_real_distribution<double> u(0, 1);
    std::vector<char> buf(65536);
    while (!stop_) {
      pollfd p[2] = {{fds_[0], POLLIN, 0}, {fds_[1], POLLIN, 0}};
      if (::poll(p, 2, 50) <= 0) continue;
      for (int from = 0; from < 2; ++from) {
        if (!(p[from].revents & POLLIN)) continue;
        const ssize_t n = ::recv(fds_[from], buf.data(), buf.size(), MSG_DONTWAIT);
        if (n <= 0) continue;
        // DIS PDU header byte 2 is the PDU type: 43 Point Object State (a crater).
        const bool object = n > 2 && static_cast<unsigned char>(buf[2]) == 43;
        const bool firstObject = object && !droppedObject_[from];
        if (u(rng) < 0.10 || firstObject) {
          ++dropped_[from];
          if (object) ++droppedObjects_[from], droppedObject_[from] = true;
          continue;
        }
        sockaddr_in to{};
        to.sin_family = AF_INET;
        to.sin_port = htons(ports_[1 - from]);
        to.sin_addr.s_addr = htonl(0x7f000002);  // 127.0.0.2: the sim's wildcard socket, not the relay's
        ::sendto(fds_[1 - from], buf.data(), std::size_t(n), 0, reinterpret_cast<sockaddr*>(&to), sizeof to);
        ++forwarded_[from];
      }
    }
  }
  std::array<std::uint16_t, 2> ports_;
  std::array<int, 2> fds_{};
  std::array<std::atomic<std::uint64_t>, 2> forwarded_{}, dropped_{}, droppedObjects_{};
  std::array<bool, 2> droppedObject_{};
  std::atomic<bool> stop_{false};
  std::thread thread_;
};

/// A scripted tank at (x, z) firing eight rounds 0.08 below level round the
/// compass from 1.5 s to 8.5 s: those that meet the ground make craters.
std::string firingScript(int entity, double x, double z) {
  char line[160];
  std::snprintf(line, sizeof line, "00 00 00 %d 2 %.1f 0.0 %.1f 90.0 90.0 0.0 0.0 0.0 0 1\n", entity, x, z);
  std::string out = line;
  for (int k = 0; k < 8; ++k) {
    std::snprintf(line, sizeof line, "00 00 %02d.5 %d 2 %.1f 0.0 %.1f 90.0 %.1f -0.08 0.0 0.0 1 1\n", k + 1, entity, x,
                  z, 20.0 + 40 * k);
    out += line;
  }
  return out;
}

TEST_F(DynamicBayreuth, twoSimProcessesFiringOverALinkLosingTenPercentEndWithTheSameGround) {
  TempDir t("dyn-dis");
  for (const auto& [name, x, z] : {std::tuple{"a", 2000.0, 2000.0}, std::tuple{"b", 3000.0, 3200.0}}) {
    spit(t / (std::string(name) + ".script"), firingScript(1, x, z));
    spit(t / (std::string(name) + ".scenario"), "sandtable-scenario 1\nentity gun icon=tank force=blue script=" +
                                                    (t / (std::string(name) + ".script")) + " script-entity=1\n");
  }
  const std::uint16_t portA = std::uint16_t(40000 + ::getpid() % 10000 * 2), portB = std::uint16_t(portA + 1);
  CommandResult a, b;
  std::uint64_t forwarded[2], dropped[2], droppedObjects[2];
  {
    LossyRelay relay(portA, portB);
    // 22 s: the last crater comes at 8.5 s; a lost object PDU comes back
    // on the 5 s heartbeat (DIS.md §14.4), so each is sent at least 3
    // times before the end (lost every time: 1 in 1,000).
    auto run = [&](const std::string& name, std::uint16_t port, const char* site, CommandResult& out) {
      out = runCli({"sim", db(), "--scenario", t / (name + ".scenario"), "--dis", "127.0.0.1:" + std::to_string(port),
                    "--site", site, "--duration", "22", "--journal", "none", "--json"});
    };
    std::thread ta([&] { run("a", portA, "1", a); });
    std::thread tb([&] { run("b", portB, "2", b); });
    ta.join(), tb.join();
    for (int k = 0; k < 2; ++k) forwarded[k] = relay.forwarded(k), dropped[k] = relay.dropped(k),
                                    droppedObjects[k] = relay.droppedObjects(k);
  }
  ASSERT_EQ(a.exitCode, 0) << a.err;
  ASSERT_EQ(b.exitCode, 0) << b.err;
  const auto ja = nlohmann::json::parse(a.out)["terrain"], jb = nlohmann::json::parse(b.out)["terrain"];
  const std::uint64_t localA = ja["local"], localB = jb["local"];
  EXPECT_GE(localA, 2u);
  EXPECT_GE(localB, 2u);
  EXPECT_EQ(ja["received"], localB);
  EXPECT_EQ(jb["received"], localA);
  EXPECT_EQ(ja["edits"], localA + localB);
  EXPECT_EQ(jb["edits"], localA + localB);
  EXPECT_EQ(ja["refused"], 0);
  EXPECT_EQ(jb["refused"], 0);
  EXPECT_EQ(ja["content_hash"], jb["content_hash"]);
  // Crater PDUs were lost each way, and came back on heartbeats.
  for (int k = 0; k < 2; ++k) EXPECT_GE(droppedObjects[k], 1u);
  std::printf("[ dis 10 %% loss ] A made %llu craters, B %llu; A holds %s edits (hash %s, %s duplicates), B %s (hash "
              "%s, %s duplicates); relay A->B %llu forwarded %llu dropped (%llu crater PDUs), B->A %llu forwarded %llu dropped (%llu)\n",
              (unsigned long long)localA, (unsigned long long)localB, ja["edits"].dump().c_str(),
              ja["content_hash"].get<std::string>().c_str(), ja["duplicates"].dump().c_str(), jb["edits"].dump().c_str(),
              jb["content_hash"].get<std::string>().c_str(), jb["duplicates"].dump().c_str(),
              (unsigned long long)forwarded[0], (unsigned long long)dropped[0], (unsigned long long)droppedObjects[0],
              (unsigned long long)forwarded[1], (unsigned long long)dropped[1], (unsigned long long)droppedObjects[1]);
}

// ------------------------------------------------- a crater on a corner

/// Module (kx, kz)'s vertices at `level` that lie more than `drop` metres
/// lower in `after` than in `before` (same vertex index).
std::size_t lowered(const module::Module& before, const module::Module& after, std::size_t level, double drop) {
  const auto& b = before.levels[level].vertices;
  const auto& a = after.levels[level].vertices;
  std::size_t n = 0;
  for (std::size_t k = 0; k < std::min(a.size(), b.size()); ++k) n += double(b[k].y) - double(a[k].y) > drop;
  return n;
}

/// The corner post shared by modules (kx-1..kx, kz-1..kz), in the database's
/// CRS, and the journal holding a crater (R 90 m, 12 m deep) on it.
struct CornerCrater {
  std::uint32_t kx = 2, kz = 2;
  double easting = 0, northing = 0;
  std::string journal;
};

CornerCrater cornerCrater(const paging::World& w, const TempDir& t, const std::string& db) {
  CornerCrater c;
  const pack::IndexHeader& h = w.modules()->header();
  EXPECT_GE(h.modulesX, 3u);
  EXPECT_GE(h.modulesZ, 3u);
  const double spacing = h.moduleSize / h.moduleSquares;
  c.easting = w.manifest().originEasting + c.kx * h.moduleSquares * spacing;
  c.northing = w.manifest().originNorthing - c.kz * h.moduleSquares * spacing;
  c.journal = t / "corner.journal";
  const auto a = runCli({"edits", "apply", "crater", db, "--journal", c.journal, "--xy", std::to_string(c.easting),
                         std::to_string(c.northing), "--radius", "90", "--depth", "12", "--json"});
  EXPECT_EQ(a.exitCode, 0) << a.err;
  if (a.exitCode == 0) {
    EXPECT_EQ(nlohmann::json::parse(a.out)["modules_remeshed"], 4) << a.out;
  }
  return c;
}

TEST_F(DynamicBayreuth, aCraterOnAModuleCornerRemeshesFourModulesAtEveryLevelAndLeavesNoHole) {
  std::string why;
  SANDTABLE_REQUIRE(render::headlessGlAvailable(why), "headless GL (EGL, Mesa): " << why);
  TempDir t("dyn-corner");
  auto base = paging::World::open(db());
  ASSERT_TRUE(base.ok()) << base.error();
  const CornerCrater c = cornerCrater(*base.value(), t, db());

  // The editor replaying the journal: the four modules round the corner
  // get new generations, and at every level the corner post (a lattice
  // post of every level) is lower, as the grid says: d below.
  edits::EditorOptions eo;
  eo.journal = c.journal;
  eo.readOnly = true;
  eo.background = false;
  auto ed = edits::Editor::open(base.value(), eo);
  ASSERT_TRUE(ed.ok()) << ed.error();
  const auto& edited = *ed.value()->modules();
  const auto& built = *base.value()->modules();
  for (std::uint32_t z = c.kz - 1; z <= c.kz; ++z) {
    for (std::uint32_t x = c.kx - 1; x <= c.kx; ++x) {
      SCOPED_TRACE("module " + std::to_string(x) + "," + std::to_string(z));
      EXPECT_GT(edited.generation(x, z), 0u);
      module::Module before, after;
      ASSERT_TRUE(built.read(x, z, before).ok());
      ASSERT_TRUE(edited.read(x, z, after).ok());
      ASSERT_EQ(after.levels.size(), before.levels.size());
      for (std::size_t level = 0; level < after.levels.size(); ++level) {
        EXPECT_GE(lowered(before, after, level, 11.0), 1u) << "level " << level;  // the corner post, 12 m down
      }
    }
  }
  EXPECT_EQ(edited.generation(0, 0), 0u);
  EXPECT_EQ(edited.generation(c.kx + 1, c.kz), 0u);

  // Baked; drawn from 150 m up and 150 m south, looking at it 45 degrees
  // down, against magenta with no sky: no pixel of the clear colour below
  // the silhouette at any selection rule.
  const auto bk = runCli({"edits", "bake", db(), c.journal, "-o", t / "baked"});
  ASSERT_EQ(bk.exitCode, 0) << bk.err;
  const LonLat ll(base.value()->manifest().crsWkt);
  const auto eye = ll.lonLat(c.easting, c.northing - 150);
  for (const char* lod : {"full", "rings", "sse"}) {
    const std::string dir = t / (std::string("png-") + lod);
    std::filesystem::create_directories(dir);
    const auto f = runCli({"fly", t / "baked", "--headless", "--png", dir, "--frames", "2", "--at",
                           std::to_string(eye[0]), std::to_string(eye[1]), "--height", "150", "--pitch", "-45",
                           "--heading", "0", "--no-sky", "--no-fog", "--no-hud", "--lod", lod, "--pager-sync", "--mode",
                           "modules", "--size", "480x320"});
    ASSERT_EQ(f.exitCode, 0) << f.err;
    const render::Image img = readPng(dir + "/frame_00001.png");
    ASSERT_GT(img.width, 0u);
    const std::uint64_t holes = holesBelowTheSilhouette(img);
    EXPECT_EQ(holes, 0u) << lod;
    std::printf("[ corner crater ] --lod %s: %llu magenta pixels below the silhouette\n", lod,
                (unsigned long long)holes);
    if (const char* keep = std::getenv("SANDTABLE_KEEP_PNG")) {
      std::filesystem::copy_file(dir + "/frame_00001.png", std::string(keep) + "/corner-" + lod + ".png",
                                 std::filesystem::copy_options::overwrite_existing);
    }
  }
}

// Every geometric check of validate passes on the baked corner crater.
TEST_F(DynamicBayreuth, aBakedCraterOnAModuleCornerValidates) {
  TempDir t("dyn-corner-validate");
  auto base = paging::World::open(db());
  ASSERT_TRUE(base.ok()) << base.error();
  const CornerCrater c = cornerCrater(*base.value(), t, db());
  const auto bk = runCli({"edits", "bake", db(), c.journal, "-o", t / "baked"});
  ASSERT_EQ(bk.exitCode, 0) << bk.err;
  const auto v = runCli({"validate", t / "baked"});
  EXPECT_EQ(v.exitCode, 0) << v.out << v.err;
}

}  // namespace
}  // namespace sandtable::test
