// A database on a web server (issue 38 part B; docs/HTTP.md): nginx on
// loopback serves a database built from real SRTM and OSM, and the CLI
// opens it by URL. `fly` draws byte-identical frames from the URL and from
// the directory; `info` says the same; `validate` passes over HTTP and
// names the file when the server's copy is damaged; a pack record altered
// on the server is refused by its CRC (after one fetch again), and the
// viewer flies on what it has; a second open fetches only the manifest and
// the pack's header; grid.stg is read by range, block by block, each
// checked by its table CRC; a grid on the server that is not the
// manifest's is refused, named by its URL, and a damaged block is named.
#include <gtest/gtest.h>
#include <signal.h>
#include <sys/wait.h>
#include <unistd.h>

#include <chrono>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <thread>

#include <nlohmann/json.hpp>

#include "sandtable/paging/pager.h"
#include "sandtable/paging/world.h"
#include "sandtable/render/renderer.h"
#include "sandtable/testing/nginx.h"
#include "sandtable/testing/require.h"
#include "test_support.h"

namespace sandtable::test {
namespace {

namespace fs = std::filesystem;

class HttpDatabase : public ::testing::Test {
 protected:
  static void SetUpTestSuite() {
    if (!haveData()) return;
    dir_ = new TempDir("httpdb");
    fs::create_directories(*dir_ / "www");
    const auto b = runCli({"build", "--elevation", data("elevation/srtm/N49E011.hgt.zip"), "--culture",
                           data("culture/osm/north-bayreuth.osm.gz"), "--extent", "11.56", "49.96", "11.60", "49.99",
                           "--spacing", "30", "-o", *dir_ / "www/db"});
    ASSERT_EQ(b.exitCode, 0) << b.err;
  }
  static void TearDownTestSuite() {
    delete dir_;
    dir_ = nullptr;
  }
  void SetUp() override {
    SANDTABLE_REQUIRE_DATA();
    ASSERT_NE(dir_, nullptr);
    std::string why;
    nginx_ = testsupport::Nginx::start(*dir_ / "www", 0, why);
    SANDTABLE_REQUIRE(nginx_ != nullptr, "nginx: " << why);
    // The mirror in the test's own directory, not the user's cache.
    ::setenv("SANDTABLE_CACHE", (*dir_ / "cache").c_str(), 1);
  }
  static std::string local() { return *dir_ / "www/db"; }
  std::string url(const std::string& name = "db") const { return nginx_->url() + "/" + name; }

  static TempDir* dir_;
  std::unique_ptr<testsupport::Nginx> nginx_;
};
TempDir* HttpDatabase::dir_ = nullptr;

std::vector<std::string> flyArgs(const std::string& db, const std::string& out) {
  return {"fly", db, "--headless", "--frames", "12", "--at", "11.575", "49.965", "--height", "120", "--pitch", "-20",
          "--heading", "20", "--pager-sync", "--lod", "rings", "--no-hud", "--size", "320x200", "--png", out};
}

TEST_F(HttpDatabase, flyDrawsTheSameFramesFromTheUrlAsFromTheDirectory) {
  std::string why;
  SANDTABLE_REQUIRE(render::headlessGlAvailable(why), "headless GL (EGL, Mesa): " << why);
  const auto a = runCli(flyArgs(local(), *dir_ / "frames-local"));
  ASSERT_EQ(a.exitCode, 0) << a.err;
  const std::uint64_t before = nginx_->requests();
  const auto b = runCli(flyArgs(url(), *dir_ / "frames-http"));
  ASSERT_EQ(b.exitCode, 0) << b.err;
  EXPECT_GT(nginx_->requests(), before + 5) << "the modules did not come from the server";
  // grid.stg is read by range (its header, its table, then runs of
  // blocks), never fetched whole. (This grid is 4 blocks: the flight reads
  // them all. bench/http_paging.py measures a larger one.)
  std::this_thread::sleep_for(std::chrono::milliseconds(200));  // nginx logs after it answers
  const auto grid = nginx_->served("/db/grid.stg");
  EXPECT_GE(grid.ranges, 3u);
  EXPECT_EQ(grid.whole, 0u) << "grid.stg came whole";
  EXPECT_LE(grid.bytes, fs::file_size(local() + "/grid.stg"));
  int frames = 0;
  for (const auto& e : fs::directory_iterator(*dir_ / "frames-local")) {
    if (e.path().extension() != ".png") continue;
    ++frames;
    const std::string other = *dir_ / ("frames-http/" + e.path().filename().string());
    EXPECT_EQ(slurpFile(e.path().string()), slurpFile(other)) << e.path().filename();
  }
  EXPECT_EQ(frames, 12);
}

/// tools/delay_proxy.py in front of a server: every byte RTT/2 late each way
/// (this kernel has no sch_netem, so no `tc netem` in a namespace).
class DelayProxy {
 public:
  DelayProxy(std::uint16_t upstream, int rttMs) {
    int fds[2];
    if (::pipe(fds) != 0) return;
    pid_ = ::fork();
    if (pid_ == 0) {
      ::dup2(fds[1], 1);
      ::close(fds[0]);
      const std::string script = std::string(SANDTABLE_SOURCE_DIR) + "/tools/delay_proxy.py";
      const std::string up = std::to_string(upstream), rtt = std::to_string(rttMs);
      ::execlp("python3", "python3", script.c_str(), "0", "127.0.0.1", up.c_str(), rtt.c_str(), "--seconds", "600",
               nullptr);
      ::_exit(127);
    }
    ::close(fds[1]);
    FILE* f = ::fdopen(fds[0], "r");
    char line[64] = {};
    if (f && std::fgets(line, sizeof line, f)) port_ = std::atoi(line + std::strlen("listening "));
    if (f) std::fclose(f);
  }
  ~DelayProxy() {
    if (pid_ > 0) {
      ::kill(pid_, SIGTERM);
      ::waitpid(pid_, nullptr, 0);
    }
  }
  std::uint16_t port() const { return std::uint16_t(port_); }

 private:
  pid_t pid_ = -1;
  int port_ = 0;
};

// The round trips, 20 and 100 ms, added by a proxy the test starts:
// the frames are still those drawn from the local copy (the viewer waits for
// its loads, --pager-sync, so a slow link may only make it slower).
TEST_F(HttpDatabase, flyOverTwentyAndAHundredMillisecondRoundTripsDrawsTheLocalFrames) {
  std::string why;
  SANDTABLE_REQUIRE(render::headlessGlAvailable(why), "headless GL (EGL, Mesa): " << why);
  const auto a = runCli(flyArgs(local(), *dir_ / "frames-rtt-local"));
  ASSERT_EQ(a.exitCode, 0) << a.err;
  for (const int rtt : {20, 100}) {
    SCOPED_TRACE(std::to_string(rtt) + " ms");
    DelayProxy proxy(nginx_->port(), rtt);
    ASSERT_NE(proxy.port(), 0) << "tools/delay_proxy.py did not start";
    ::setenv("SANDTABLE_CACHE", (*dir_ / ("cache-rtt" + std::to_string(rtt))).c_str(), 1);
    const std::string out = *dir_ / ("frames-rtt" + std::to_string(rtt));
    const auto b = runCli(flyArgs("http://127.0.0.1:" + std::to_string(proxy.port()) + "/db", out));
    ASSERT_EQ(b.exitCode, 0) << b.err;
    int frames = 0;
    for (const auto& e : fs::directory_iterator(*dir_ / "frames-rtt-local")) {
      if (e.path().extension() != ".png") continue;
      ++frames;
      EXPECT_EQ(slurpFile(e.path().string()), slurpFile(out + "/" + e.path().filename().string()))
          << e.path().filename();
    }
    EXPECT_EQ(frames, 12);
  }
}

/// Modules in the pager's window: resident real ones, placeholders, holes.
struct WindowCount {
  int real = 0, placeholders = 0, holes = 0;
};
WindowCount countWindow(const paging::Pager& p) {
  WindowCount c;
  const paging::ModuleRect w = p.window();
  for (std::int64_t kz = w.z0; kz < w.z1; ++kz) {
    for (std::int64_t kx = w.x0; kx < w.x1; ++kx) {
      const auto r = p.resident(std::uint32_t(kx), std::uint32_t(kz), p.levels() - 1);
      if (!r) ++c.holes;
      else if (r.placeholder()) ++c.placeholders;
      else ++c.real;
    }
  }
  return c;
}

// The server stops while a viewer pages from it: the loads fail and are
// counted, coarse placeholders (from the mirrored grid) stand in, nothing
// crashes; when the server returns, the placeholders are read again
// (paging/retrying_source.h) and every module in view is real again.
TEST_F(HttpDatabase, theServerStoppingMidFlightLeavesPlaceholdersThatReloadWhenItComesBack) {
  ::setenv("SANDTABLE_CACHE", (*dir_ / "cache-stop").c_str(), 1);
  auto world = paging::World::open(url());  // the manifest, the mirror and the pack's header
  ASSERT_TRUE(world.ok()) << world.error();
  nginx_->stop();
  paging::PagerOptions po;
  po.viewDistance = 1500;
  auto pager = paging::Pager::open(*world.value(), po);
  ASSERT_TRUE(pager.ok()) << pager.error();
  paging::Pager& p = *pager.value();
  const auto start = std::chrono::steady_clock::now();
  auto t = [&] { return std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count(); };
  const double x = 1500, z = 1500;
  for (int i = 0; i < 40; ++i) {
    p.update(x, z, 0, 0, t());
    std::this_thread::sleep_for(std::chrono::milliseconds(25));
  }
  ASSERT_TRUE(p.waitIdle(10));
  const WindowCount down = countWindow(p);
  EXPECT_GT(down.placeholders, 0) << "no load failed with the server stopped";
  // (Those whose records came in the block the pack's header was read with are real.)
  EXPECT_GT(p.metrics().corruptModules + p.metrics().missingModules, 0u) << "the failed loads were not counted";
  std::string why;
  ASSERT_TRUE(nginx_->restart(why)) << why;
  WindowCount up;
  for (int i = 0; i < 600 && (up.real == 0 || up.placeholders > 0 || up.holes > 0); ++i) {  // at most 15 s
    p.update(x, z, 0, 0, t());
    std::this_thread::sleep_for(std::chrono::milliseconds(25));
    up = countWindow(p);
  }
  EXPECT_EQ(up.placeholders, 0) << "placeholders left after the server came back";
  EXPECT_EQ(up.holes, 0);
  EXPECT_EQ(up.real, down.placeholders + down.real + down.holes);
  p.stop();
}

// The pack's records are kept on disk beside the mirror (paging/disk_cache.h):
// a second flight over the same ground asks nginx for no record, and draws
// the same frames; a cached block damaged on disk fails its record's CRC,
// is dropped and fetched again, and the frames are still the same.
TEST_F(HttpDatabase, aSecondFlightReadsTheRecordsFromTheDiskCache) {
  std::string why;
  SANDTABLE_REQUIRE(render::headlessGlAvailable(why), "headless GL (EGL, Mesa): " << why);
  const std::string cache = *dir_ / "cache-disk";
  ::setenv("SANDTABLE_CACHE", cache.c_str(), 1);
  const auto first = runCli(flyArgs(url(), *dir_ / "frames-disk1"));
  ASSERT_EQ(first.exitCode, 0) << first.err;
  std::this_thread::sleep_for(std::chrono::milliseconds(200));
  const std::uint64_t r1 = nginx_->requests();
  const auto second = runCli(flyArgs(url(), *dir_ / "frames-disk2"));
  ASSERT_EQ(second.exitCode, 0) << second.err;
  std::this_thread::sleep_for(std::chrono::milliseconds(200));
  // The manifest and the HEADs of the pack and the grid: not the pack's
  // header, the grid's table, any record or any grid block.
  EXPECT_EQ(nginx_->requests() - r1, 3u);
  std::vector<std::string> cacheFiles;
  for (const auto& e : fs::recursive_directory_iterator(cache)) {
    if (e.path().extension() == ".cache") cacheFiles.push_back(e.path().string());
  }
  ASSERT_EQ(cacheFiles.size(), 2u) << "no modules.pack.*.cache and grid.stg.*.cache under " << cache;
  // Damage every cached byte that is not a hole: each record and grid
  // block read from them fails its CRC.
  for (const std::string& cacheFile : cacheFiles) {
    std::string bytes = slurpFile(cacheFile);
    std::size_t flipped = 0;
    for (std::size_t k = 0; k < bytes.size(); k += 997) {
      if (bytes[k] != 0) bytes[k] = char(bytes[k] ^ 0x21), ++flipped;
    }
    ASSERT_GT(flipped, 10u) << cacheFile;
    spit(cacheFile, bytes);
  }
  const auto third = runCli(flyArgs(url(), *dir_ / "frames-disk3"));
  ASSERT_EQ(third.exitCode, 0) << third.err;
  for (const char* out : {"frames-disk2", "frames-disk3"}) {
    for (const auto& e : fs::directory_iterator(*dir_ / "frames-disk1")) {
      if (e.path().extension() != ".png") continue;
      EXPECT_EQ(slurpFile(e.path().string()), slurpFile(*dir_ / (std::string(out) + "/" + e.path().filename().string())))
          << out << "/" << e.path().filename();
    }
  }
  EXPECT_EQ(third.err.find("checksum mismatch"), std::string::npos) << "a damaged cached block is fetched again, "
                                                                       "not reported as a damaged module:\n"
                                                                    << third.err;
}

TEST_F(HttpDatabase, infoAndValidateReadTheUrl) {
  const auto a = runCli({"info", local(), "--json"});
  const auto b = runCli({"info", url(), "--json"});
  ASSERT_EQ(a.exitCode, 0) << a.err;
  ASSERT_EQ(b.exitCode, 0) << b.err;
  auto ja = nlohmann::json::parse(a.out), jb = nlohmann::json::parse(b.out);
  ja.erase("database");
  jb.erase("database");
  EXPECT_EQ(ja, jb);
  const auto v = runCli({"validate", url()});
  EXPECT_EQ(v.exitCode, 0) << v.out << v.err;
  EXPECT_NE(v.out.find(": ok"), std::string::npos) << v.out;
}

TEST_F(HttpDatabase, aDamagedCopyOnTheServerIsNamedAndAlteredRecordsAreRefused) {
  // A copy served beside the good one, one byte of a module record flipped.
  const std::string bad = *dir_ / "www/bad";
  fs::remove_all(bad);
  fs::copy(local(), bad, fs::copy_options::recursive);
  std::string pack = slurpFile(bad + "/modules.pack");
  ASSERT_GT(pack.size(), 5000u);
  pack[pack.size() / 2] = char(pack[pack.size() / 2] ^ 0x5a);
  spit(bad + "/modules.pack", pack);
  // validate fetches every file and checks it against the manifest.
  const auto v = runCli({"validate", url("bad")});
  EXPECT_EQ(v.exitCode, 1) << v.out << v.err;
  EXPECT_NE(v.err.find(url("bad") + "/modules.pack"), std::string::npos) << v.err;
  EXPECT_NE(v.err.find("damaged"), std::string::npos) << v.err;
  // The viewer pages the damaged pack by range: the altered record fails
  // its CRC (fetched twice), is counted, and the frames still come.
  std::string why;
  SANDTABLE_REQUIRE(render::headlessGlAvailable(why), "headless GL (EGL, Mesa): " << why);
  const auto f = runCli({"fly", url("bad"), "--headless", "--frames", "3", "--lod", "full", "--pager-sync", "--size",
                         "160x100", "--png", *dir_ / "frames-bad"});
  ASSERT_EQ(f.exitCode, 0) << f.err;
  EXPECT_NE(f.err.find("checksum mismatch"), std::string::npos) << f.err;
  EXPECT_TRUE(fs::exists(*dir_ / "frames-bad/frame_00002.png"));
}

TEST_F(HttpDatabase, theMirrorIsKeptAndADamagedGridOnTheServerIsNamed) {
  // A fresh mirror: info fetches the manifest and every small file.
  ::setenv("SANDTABLE_CACHE", (*dir_ / "cache-mirror").c_str(), 1);
  const std::uint64_t r0 = nginx_->requests();
  const auto first = runCli({"info", url()});
  ASSERT_EQ(first.exitCode, 0) << first.err;
  std::this_thread::sleep_for(std::chrono::milliseconds(200));  // nginx logs after it answers
  const std::uint64_t r1 = nginx_->requests();
  EXPECT_GE(r1 - r0, 3u);  // the manifest, modules.idx, grid.stg's header and table, ...
  // Again: the copies match the manifest, the pack's header is in the
  // disk cache (checked against the index) and the grid's header and table
  // in its local copy (checked against the manifest's CRC), so only the
  // manifest and the HEADs of the pack and the grid are asked for.
  const auto second = runCli({"info", url()});
  ASSERT_EQ(second.exitCode, 0) << second.err;
  std::this_thread::sleep_for(std::chrono::milliseconds(200));
  EXPECT_EQ(nginx_->requests() - r1, 3u);
  // A grid on the server whose block table is not the manifest's is
  // refused at open, by URL.
  const std::string bad = *dir_ / "www/badgrid";
  fs::remove_all(bad);
  fs::copy(local(), bad, fs::copy_options::recursive);
  const std::string good = slurpFile(bad + "/grid.stg");
  ASSERT_GT(good.size(), 3 * 4096u);
  std::string grid = good;
  grid[4096 + 20] = char(grid[4096 + 20] ^ 0x01);  // the second block's minimum elevation, in the table
  spit(bad + "/grid.stg", grid);
  const auto r = runCli({"info", url("badgrid")});
  EXPECT_NE(r.exitCode, 0);
  EXPECT_NE(r.err.find(url("badgrid") + "/grid.stg"), std::string::npos) << r.err;
  EXPECT_NE(r.err.find("damaged"), std::string::npos) << r.err;
  // A byte of the last block flipped: the table is sound, so the database
  // opens; the block fails its CRC when read (twice), the viewer names it
  // and flies on over a flat stand-in, and validate names the file.
  grid = good;
  grid[grid.size() - 100] = char(grid[grid.size() - 100] ^ 0x01);
  spit(bad + "/grid.stg", grid);
  const auto v = runCli({"validate", url("badgrid")});
  EXPECT_EQ(v.exitCode, 1) << v.out << v.err;
  EXPECT_NE(v.err.find(url("badgrid") + "/grid.stg"), std::string::npos) << v.err;
  std::string why;
  SANDTABLE_REQUIRE(render::headlessGlAvailable(why), "headless GL (EGL, Mesa): " << why);
  ::setenv("SANDTABLE_CACHE", (*dir_ / "cache-badgrid").c_str(), 1);
  const auto f = runCli({"fly", url("badgrid"), "--headless", "--frames", "3", "--lod", "full", "--pager-sync", "--size",
                         "160x100", "--png", *dir_ / "frames-badgrid"});
  ASSERT_EQ(f.exitCode, 0) << f.err;
  EXPECT_NE(f.err.find(url("badgrid") + "/grid.stg"), std::string::npos) << f.err;
  EXPECT_NE(f.err.find("failed its checksum twice"), std::string::npos) << f.err;
  EXPECT_TRUE(fs::exists(*dir_ / "frames-badgrid/frame_00002.png"));
}

TEST_F(HttpDatabase, aMissingDatabaseIsAClearError) {
  const auto r = runCli({"info", url("nothing-here")});
  EXPECT_NE(r.exitCode, 0);
  EXPECT_NE(r.err.find(url("nothing-here") + "/manifest.json"), std::string::npos) << r.err;
  EXPECT_NE(r.err.find("404"), std::string::npos) << r.err;
}

}  // namespace
}  // namespace sandtable::test
