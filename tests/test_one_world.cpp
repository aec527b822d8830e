// One world (issue 34 item 4): `sandtable sim` and `sandtable fly
// --scenario` open their database once. The CLI runs as its own process,
// so the opens are counted from outside: inotify reports every open of the
// database's manifest.json, which openDatabase reads once per call and
// nothing else in these two commands reads. (Opens and closes are both
// watched, so two opens in a row never coalesce into one event.) The
// library path is counted in-process with databaseOpens().
#include <gtest/gtest.h>
#include <sys/inotify.h>
#include <unistd.h>

#include <nlohmann/json.hpp>

#include "sandtable/formats/database.h"
#include "sandtable/formats/manifest.h"
#include "sandtable/paging/world.h"
#include "sandtable/render/renderer.h"
#include "sandtable/sim/sim_world.h"
#include "sandtable/testing/require.h"
#include "test_support.h"

namespace sandtable::test {
namespace {

/// Counts the opens of one file in a directory while `run` runs.
class OpenCounter {
 public:
  OpenCounter(const std::string& dir, std::string name) : name_(std::move(name)) {
    fd_ = inotify_init1(IN_NONBLOCK | IN_CLOEXEC);
    EXPECT_GE(fd_, 0);
    EXPECT_GE(inotify_add_watch(fd_, dir.c_str(), IN_OPEN | IN_CLOSE_NOWRITE | IN_CLOSE_WRITE), 0);
  }
  ~OpenCounter() {
    if (fd_ >= 0) ::close(fd_);
  }
  /// Opens of the file since the last call.
  int take() {
    int opens = 0;
    alignas(inotify_event) char buf[1 << 16];
    for (;;) {
      const ssize_t n = ::read(fd_, buf, sizeof buf);
      if (n <= 0) break;
      for (ssize_t k = 0; k < n;) {
        const auto* e = reinterpret_cast<const inotify_event*>(buf + k);
        if ((e->mask & IN_OPEN) && e->len > 0 && name_ == e->name) ++opens;
        k += ssize_t(sizeof(inotify_event) + e->len);
      }
    }
    return opens;
  }

 private:
  std::string name_;
  int fd_ = -1;
};

class OneWorld : public ::testing::Test {
 protected:
  static void SetUpTestSuite() {
    tmp_ = new TempDir("one-world");
    const auto synth = runCli({"synth", "-o", *tmp_ / "inputs", "--size-km", "2"});
    ASSERT_EQ(synth.exitCode, 0) << synth.err;
    const auto j = nlohmann::json::parse(slurpFile(*tmp_ / "inputs/synth.json"));
    const auto& b = j["bounds"];
    const double west = b["west"].get<double>(), south = b["south"].get<double>();
    const double east = b["east"].get<double>(), north = b["north"].get<double>();
    const auto build = runCli({"build", "--elevation", *tmp_ / "inputs/dem.tif", "--culture",
                               *tmp_ / "inputs/culture.gpkg", "--spacing", "31.25", "--icons",
                               std::string(SANDTABLE_SOURCE_DIR) + "/samples/icons.txt", "-o", *tmp_ / "db"});
    ASSERT_EQ(build.exitCode, 0) << build.err;
    char at[96];
    std::snprintf(at, sizeof at, "%.6f,%.6f", (west + east) / 2, (south + north) / 2);
    spit(*tmp_ / "one.scenario", std::string("sandtable-scenario 1\nframe lonlat\n") +
                                     "entity t1 icon=tank force=blue mobility=tracked at=" + at +
                                     " heading=0 speed=10\n");
  }
  static void TearDownTestSuite() {
    delete tmp_;
    tmp_ = nullptr;
  }
  static std::string db() { return *tmp_ / "db"; }
  static TempDir* tmp_;
};
TempDir* OneWorld::tmp_ = nullptr;

TEST_F(OneWorld, simOpensTheDatabaseOnce) {
  OpenCounter opens(db(), manifest::kFileName);
  const auto r = runCli({"sim", db(), "--scenario", *tmp_ / "one.scenario", "--duration", "2", "--json"});
  ASSERT_EQ(r.exitCode, 0) << r.err;
  EXPECT_EQ(opens.take(), 1);
}

TEST_F(OneWorld, flyWithAScenarioOpensTheDatabaseOnce) {
  std::string why;
  SANDTABLE_REQUIRE(render::headlessGlAvailable(why), "headless GL (EGL, Mesa): " << why);
  OpenCounter opens(db(), manifest::kFileName);
  const auto r = runCli({"fly", db(), "--scenario", *tmp_ / "one.scenario", "--png", *tmp_ / "frames", "--frames",
                         "2", "--size", "160x120", "--no-hud"});
  ASSERT_EQ(r.exitCode, 0) << r.err;
  EXPECT_EQ(opens.take(), 1);
}

TEST_F(OneWorld, theCounterSeesOneOpenForAWorldAndNoneForTheSimulatorOnIt) {
  OpenCounter fileOpens(db(), manifest::kFileName);
  const std::uint64_t before = databaseOpens();
  auto world = paging::World::open(db());
  ASSERT_TRUE(world) << world.error();
  auto sim = sim::SimWorld::open(*world.value());
  ASSERT_TRUE(sim) << sim.error();
  EXPECT_FALSE(sim.value()->objects().empty());  // its modules were read, through the world's source
  EXPECT_EQ(databaseOpens(), before + 1);
  EXPECT_EQ(fileOpens.take(), 1);  // the counter and the file agree
}

}  // namespace
}  // namespace sandtable::test
