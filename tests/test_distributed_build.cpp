// Issue 38, part A: a build split into tasks and merged is byte-identical to
// the one-machine build of the same inputs, on real data (Bayreuth with its
// OSM across the N49/N50 tile edge; a 2 x 2 mosaic of Danish DTED1 cells),
// here and through a real Slurm cluster (tools/slurm-local.sh, started by
// .ci/run); a resumed build after scancel, and the faults the merge refuses.
#include <gtest/gtest.h>
#include <sys/wait.h>
#include <unistd.h>

#include <chrono>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <thread>

#include <nlohmann/json.hpp>

#include "sandtable/testing/nginx.h"
#include "sandtable/testing/require.h"
#include "test_support.h"

namespace sandtable::test {
namespace {

namespace fs = std::filesystem;
using nlohmann::json;

std::vector<std::string> bayreuthArgs() {
  return {"build", "--elevation", data("elevation/srtm/N49E011.hgt.zip"), data("elevation/srtm/N50E011.hgt.zip"),
          "--culture",   data("culture/osm/north-bayreuth.osm.gz"), "--extent", "11.52", "49.94", "11.62", "50.03",
          "--spacing",   "30"};
}

/// Four DTED1 cells meeting at 10 E 56 N (Jutland, around Skanderborg).
std::vector<std::string> dtedArgs() {
  return {"build", "--elevation", data("elevation/dted/denmark-dhm/e009/n55.dt1"), data("elevation/dted/denmark-dhm/e009/n56.dt1"),
          data("elevation/dted/denmark-dhm/e010/n55.dt1"), data("elevation/dted/denmark-dhm/e010/n56.dt1"),
          "--extent", "9.80", "55.90", "10.20", "56.10", "--spacing", "30"};
}

std::vector<std::string> with(std::vector<std::string> a, const std::vector<std::string>& more) {
  a.insert(a.end(), more.begin(), more.end());
  return a;
}

/// The manifest without the keys that hold timings (written out here, not
/// taken from the library, so a key that should not differ makes this fail).
json stableManifest(const std::string& db) {
  json m = json::parse(slurpFile(db + "/manifest.json"));
  for (const char* p : {"/checksum", "/created_utc", "/build/seconds", "/build/resample_seconds",
                        "/build/posts_per_second", "/build/modules/seconds", "/build/modules/modules_per_second",
                        "/build/modules/stage_cpu_seconds", "/build/culture/load_seconds"}) {
    const json::json_pointer ptr(p);
    if (m.contains(ptr)) m[ptr.parent_pointer()].erase(ptr.back());
  }
  return m;
}

/// Every file of the two databases, byte for byte (as cmp would).
void expectSameDatabase(const std::string& a, const std::string& b) {
  std::vector<std::string> names;
  for (const auto& e : fs::directory_iterator(a)) names.push_back(e.path().filename().string());
  std::size_t others = 0;
  for (const auto& e : fs::directory_iterator(b)) others += e.path().filename() != "" ? 1 : 0;
  EXPECT_EQ(names.size(), others) << "the databases hold different files";
  for (const auto& n : names) {
    if (n == "manifest.json") continue;
    const std::string x = slurpFile(a + "/" + n), y = slurpFile(b + "/" + n);
    EXPECT_GT(x.size(), 0u) << n;
    EXPECT_TRUE(x == y) << n << " differs (" << x.size() << " and " << y.size() << " bytes)";
  }
  EXPECT_EQ(stableManifest(a), stableManifest(b)) << "manifest.json differs beyond its timings";
  for (const char* n : {"grid.stg", "modules.pack", "modules.idx", "icons.pack", "materials.txt"}) {
    EXPECT_TRUE(fs::exists(a + "/" + n)) << n;
  }
}

TEST(DistributedBuild, bayreuthWithOsmMergesByteIdenticalToTheOneMachineBuild) {
  SANDTABLE_REQUIRE_DATA();
  TempDir tmp("dist-bay");
  const auto one = runCli(with(bayreuthArgs(), {"-o", tmp / "one"}));
  ASSERT_EQ(one.exitCode, 0) << one.err;
  const auto dist = runCli(with(bayreuthArgs(), {"-o", tmp / "dist", "--executor", "local", "--tasks", "3"}));
  ASSERT_EQ(dist.exitCode, 0) << dist.err;
  EXPECT_NE(dist.err.find("3 tasks, 3 to build"), std::string::npos) << dist.err;
  expectSameDatabase(tmp / "one", tmp / "dist");
  // The culture really was there: the check above compared towns, not fields.
  EXPECT_GT(stableManifest(tmp / "one")["build"]["culture"]["features_landed"].get<int>(), 1000);
  // A rerun finds every part whole and only merges again.
  const auto again = runCli(with(bayreuthArgs(), {"-o", tmp / "dist", "--force", "--executor", "local", "--tasks", "3"}));
  ASSERT_EQ(again.exitCode, 0) << again.err;
  EXPECT_NE(again.err.find("0 to build (3 already built)"), std::string::npos) << again.err;
  expectSameDatabase(tmp / "one", tmp / "dist");
}

TEST(DistributedBuild, dtedMosaicPlanTasksAndMergeByHandAreByteIdentical) {
  SANDTABLE_REQUIRE_DATA();
  TempDir tmp("dist-dted");
  const auto one = runCli(with(dtedArgs(), {"-o", tmp / "one"}));
  ASSERT_EQ(one.exitCode, 0) << one.err;
  const auto plan = runCli(with(dtedArgs(), {"-o", tmp / "dist", "--plan", tmp / "plan.json", "--tasks", "4"}));
  ASSERT_EQ(plan.exitCode, 0) << plan.err;
  const json p = json::parse(slurpFile(tmp / "plan.json"));
  ASSERT_EQ(p["tasks"].size(), 4u);
  EXPECT_EQ(p["inputs"].size(), 4u);
  // Tasks in any order, one twice (idempotent).
  for (const char* t : {"2", "0", "3", "1", "2"}) {
    const auto r = runCli({"build", "--task", tmp / "plan.json", t});
    ASSERT_EQ(r.exitCode, 0) << r.err;
  }
  const auto merged = runCli({"build", "--merge", tmp / "plan.json"});
  ASSERT_EQ(merged.exitCode, 0) << merged.err;
  expectSameDatabase(tmp / "one", tmp / "dist");
}

/// A planned DTED build with its parts built, for the fault tests.
struct Planned {
  TempDir tmp{"dist-fault"};
  std::string plan = tmp / "plan.json";
  void build(const std::vector<std::string>& extra = {}) {
    auto r = runCli(with(with(dtedArgs(), {"-o", tmp / "db", "--plan", plan, "--tasks", "3"}), extra));
    ASSERT_EQ(r.exitCode, 0) << r.err;
    for (const char* t : {"0", "1", "2"}) {
      r = runCli({"build", "--task", plan, t});
      ASSERT_EQ(r.exitCode, 0) << r.err;
    }
  }
  std::string part(int t) const {
    char n[32];
    std::snprintf(n, sizeof n, "part-%05d.stp", t);
    return tmp / ("db.parts/" + std::string(n));
  }
};

TEST(DistributedBuild, aPartWithAFlippedByteIsRefusedNamingTheTaskAndTheFile) {
  SANDTABLE_REQUIRE_DATA();
  Planned p;
  p.build();
  std::string bytes = slurpFile(p.part(1));
  ASSERT_GT(bytes.size(), 100000u);
  bytes[bytes.size() / 2] = char(bytes[bytes.size() / 2] ^ 0x10);
  spit(p.part(1), bytes);
  const auto r = runCli({"build", "--merge", p.plan});
  EXPECT_NE(r.exitCode, 0);
  EXPECT_NE(r.err.find("task 1"), std::string::npos) << r.err;
  EXPECT_NE(r.err.find("part-00001.stp"), std::string::npos) << r.err;
  EXPECT_NE(r.err.find("checksum"), std::string::npos) << r.err;
  EXPECT_FALSE(fs::exists(p.tmp / "db")) << "nothing may be published";
  // The task is built again (its part is bad), and the merge then succeeds.
  const auto t = runCli({"build", "--task", p.plan, "1"});
  ASSERT_EQ(t.exitCode, 0) << t.err;
  EXPECT_EQ(t.out.find("already built"), std::string::npos) << t.out;
  EXPECT_EQ(runCli({"build", "--merge", p.plan}).exitCode, 0);
}

TEST(DistributedBuild, aPartOfAnotherPlanIsRefused) {
  SANDTABLE_REQUIRE_DATA();
  Planned a, b;
  a.build();
  b.build({"--zstd-level", "3"});  // the same rows, another plan
  fs::copy_file(b.part(2), a.part(2), fs::copy_options::overwrite_existing);
  const auto r = runCli({"build", "--merge", a.plan});
  EXPECT_NE(r.exitCode, 0);
  EXPECT_NE(r.err.find("another plan"), std::string::npos) << r.err;
  EXPECT_NE(r.err.find("part-00002.stp"), std::string::npos) << r.err;
  EXPECT_NE(r.err.find("task 2"), std::string::npos) << r.err;
}

TEST(DistributedBuild, aPlanWhoseInputsChangedIsRefused) {
  SANDTABLE_REQUIRE_DATA();
  TempDir tmp("dist-inputs");
  const std::string culture = tmp / "roads.geojson";
  spit(culture, R"({"type":"FeatureCollection","features":[{"type":"Feature","properties":{"highway":"primary"},
    "geometry":{"type":"LineString","coordinates":[[9.9,55.95],[10.1,56.05]]}}]})");
  auto r = runCli(with(dtedArgs(), {"--culture", culture, "-o", tmp / "db", "--plan", tmp / "plan.json", "--tasks", "2"}));
  ASSERT_EQ(r.exitCode, 0) << r.err;
  ASSERT_EQ(runCli({"build", "--task", tmp / "plan.json", "0"}).exitCode, 0);
  spit(culture, slurpFile(culture) + " ");
  r = runCli({"build", "--task", tmp / "plan.json", "1"});
  EXPECT_NE(r.exitCode, 0);
  EXPECT_NE(r.err.find("roads.geojson"), std::string::npos) << r.err;
  EXPECT_NE(r.err.find("changed since the plan"), std::string::npos) << r.err;
  r = runCli({"build", "--merge", tmp / "plan.json"});
  EXPECT_NE(r.exitCode, 0);
}

// A task reads whole (for its CRC) only the sources under its rows: a cell
// changed in place after the plan is refused by the task over it, naming
// the file; the task over the other end of the mosaic need not read it.
TEST(DistributedBuild, anElevationCellChangedAfterThePlanIsRefusedByTheTaskOverIt) {
  SANDTABLE_REQUIRE_DATA();
  TempDir tmp("dist-cell");
  const std::string south = tmp / "n55.dt1", north = tmp / "n56.dt1";
  fs::copy_file(data("elevation/dted/denmark-dhm/e010/n55.dt1"), south);
  fs::copy_file(data("elevation/dted/denmark-dhm/e010/n56.dt1"), north);
  const std::vector<std::string> args = {"build", "--elevation", south, north, "--extent", "10.30", "55.80", "10.60",
                                         "56.20", "--spacing", "60", "-o", tmp / "db"};
  auto r = runCli(with(args, {"--plan", tmp / "plan.json", "--tasks", "2"}));
  ASSERT_EQ(r.exitCode, 0) << r.err;
  // The same size, another byte in the middle of the northern cell's posts.
  std::string bytes = slurpFile(north);
  bytes[bytes.size() / 2] = char(bytes[bytes.size() / 2] ^ 0x01);
  spit(north, bytes);
  r = runCli({"build", "--task", tmp / "plan.json", "0"});  // the northern rows
  EXPECT_NE(r.exitCode, 0);
  EXPECT_NE(r.err.find("n56.dt1"), std::string::npos) << r.err;
  EXPECT_NE(r.err.find("another CRC-32"), std::string::npos) << r.err;
  EXPECT_NE(r.err.find("changed since the plan"), std::string::npos) << r.err;
}

// Sources on a web server, read through GDAL's /vsicurl/, so workers need no
// copy: the same bytes as a build from local copies, and a cell changed on
// the server after the plan is refused by the task over it, by its path.
TEST(DistributedBuild, sourcesOnAWebServerBuildTheSameBytesAndAChangedOneIsRefused) {
  SANDTABLE_REQUIRE_DATA();
  TempDir tmp("dist-vsicurl");
  fs::create_directories(tmp / "www");
  const std::string south = tmp / "www/n55.dt1", north = tmp / "www/n56.dt1";
  fs::copy_file(data("elevation/dted/denmark-dhm/e010/n55.dt1"), south);
  fs::copy_file(data("elevation/dted/denmark-dhm/e010/n56.dt1"), north);
  std::string why;
  auto nginx = testsupport::Nginx::start(tmp / "www", 0, why);
  SANDTABLE_REQUIRE(nginx != nullptr, "nginx: " << why);
  const std::string url = "/vsicurl/" + nginx->url();
  const std::vector<std::string> extent = {"--extent", "10.02", "55.90", "10.20", "56.10", "--spacing", "60"};  // inland: no voids
  auto r = runCli(with(with({"build", "--elevation", south, north}, extent), {"-o", tmp / "one"}));
  ASSERT_EQ(r.exitCode, 0) << r.err;
  const std::vector<std::string> remote = with({"build", "--elevation", url + "/n55.dt1", url + "/n56.dt1"}, extent);
  r = runCli(with(remote, {"-o", tmp / "dist", "--executor", "local", "--tasks", "2"}));
  ASSERT_EQ(r.exitCode, 0) << r.err;
  for (const char* n : {"grid.stg", "modules.pack", "modules.idx", "icons.pack", "materials.txt"}) {
    EXPECT_TRUE(slurpFile(tmp / "one" + "/" + n) == slurpFile(tmp / "dist" + "/" + n)) << n;
  }
  EXPECT_GT(nginx->served("/n56.dt1").requests, 0u) << "the sources did not come from the server";
  // The manifest names the sources as given.
  EXPECT_NE(slurpFile(tmp / "dist/manifest.json").find(url + "/n56.dt1"), std::string::npos);
  r = runCli(with(remote, {"-o", tmp / "db", "--plan", tmp / "plan.json", "--tasks", "2"}));
  ASSERT_EQ(r.exitCode, 0) << r.err;
  std::string bytes = slurpFile(north);
  bytes[bytes.size() / 2] = char(bytes[bytes.size() / 2] ^ 0x01);
  spit(north, bytes);
  r = runCli({"build", "--task", tmp / "plan.json", "0"});  // the northern rows
  EXPECT_NE(r.exitCode, 0);
  EXPECT_NE(r.err.find(url + "/n56.dt1"), std::string::npos) << r.err;
  EXPECT_NE(r.err.find("another CRC-32"), std::string::npos) << r.err;
}

TEST(DistributedBuild, aKilledTaskLeavesNoPartAndTheRerunBuildsOnlyIt) {
  SANDTABLE_REQUIRE_DATA();
  TempDir tmp("dist-kill");
  auto r = runCli(with(bayreuthArgs(), {"-o", tmp / "db", "--plan", tmp / "plan.json", "--tasks", "2"}));
  ASSERT_EQ(r.exitCode, 0) << r.err;
  ASSERT_EQ(runCli({"build", "--task", tmp / "plan.json", "0"}).exitCode, 0);
  const pid_t pid = ::fork();
  ASSERT_GE(pid, 0);
  if (pid == 0) {
    ::execl(SANDTABLE_CLI, SANDTABLE_CLI, "build", "--task", (tmp / "plan.json").c_str(), "1", nullptr);
    ::_exit(127);
  }
  // Killed while it works (it loads the culture, resamples and meshes for
  // over a second; a task that finished first would make the check moot).
  std::this_thread::sleep_for(std::chrono::milliseconds(400));
  ::kill(pid, SIGKILL);
  int status = 0;
  ::waitpid(pid, &status, 0);
  ASSERT_TRUE(WIFSIGNALED(status)) << "the task ended before it was killed; make it longer";
  EXPECT_FALSE(fs::exists(tmp / "db.parts/part-00001.stp")) << "a killed task left a part";
  r = runCli(with(bayreuthArgs(), {"-o", tmp / "db", "--executor", "local", "--tasks", "2"}));
  ASSERT_EQ(r.exitCode, 0) << r.err;
  EXPECT_NE(r.err.find("1 to build (1 already built)"), std::string::npos) << r.err;
}

// ---- the real cluster (tools/slurm-local.sh start; .ci/run starts it) ----

bool haveSlurm() {
  return std::getenv("SLURM_CONF") != nullptr && std::system("sinfo -h >/dev/null 2>&1") == 0;
}
#define REQUIRE_SLURM()                                                                                      \
  SANDTABLE_REQUIRE(haveSlurm(), "a Slurm cluster: eval \"$(tools/slurm-local.sh start)\" (sets SLURM_CONF)")

std::string shellQuote(const std::string& s) {
  std::string q = "'";
  for (char c : s) {
    if (c == '\'') q.append("'\\''");
    else q.push_back(c);
  }
  q.push_back('\'');
  return q;
}

std::string commandOut(const std::string& cmd) {
  std::string out;
  if (FILE* p = ::popen(cmd.c_str(), "r")) {
    char buf[256];
    while (std::fgets(buf, sizeof buf, p)) out += buf;
    ::pclose(p);
  }
  return out;
}

TEST(DistributedBuildSlurm, aJobArrayBuildsTheSameBytes) {
  SANDTABLE_REQUIRE_DATA();
  REQUIRE_SLURM();
  TempDir tmp("dist-slurm");
  ASSERT_EQ(runCli(with(dtedArgs(), {"-o", tmp / "one"})).exitCode, 0);
  const auto r = runCli(with(dtedArgs(), {"-o", tmp / "dist", "--executor", "slurm", "--tasks", "3"}));
  ASSERT_EQ(r.exitCode, 0) << r.err;
  EXPECT_NE(r.err.find("sbatch --parsable --wait --array=0-2"), std::string::npos) << r.err;
  expectSameDatabase(tmp / "one", tmp / "dist");
  EXPECT_TRUE(fs::exists(tmp / "dist.parts/logs/task-0.out"));
  // --emit-sbatch prints the script a user would submit.
  const auto e = runCli(with(dtedArgs(), {"-o", tmp / "x", "--emit-sbatch", "--tasks", "3", "--partition", "debug"}));
  ASSERT_EQ(e.exitCode, 0) << e.err;
  EXPECT_NE(e.out.find("#SBATCH --array=0-2"), std::string::npos) << e.out;
  EXPECT_NE(e.out.find("#SBATCH --partition=debug"), std::string::npos) << e.out;
  EXPECT_NE(e.out.find("build --task"), std::string::npos) << e.out;
}

TEST(DistributedBuildSlurm, aResumedBuildAfterScancelBuildsOnlyWhatIsMissing) {
  SANDTABLE_REQUIRE_DATA();
  REQUIRE_SLURM();
  TempDir tmp("dist-scancel");
  ASSERT_EQ(runCli(with(bayreuthArgs(), {"-o", tmp / "one"})).exitCode, 0);
  std::string cmd = shellQuote(SANDTABLE_CLI);
  for (const auto& a : with(bayreuthArgs(), {"-o", tmp / "dist", "--executor", "slurm", "--tasks", "4"})) {
    cmd.push_back(' ');
    cmd.append(shellQuote(a));
  }
  std::string background = "(";
  background.append(cmd).append(" >").append(shellQuote(tmp / "log")).append(" 2>&1; echo $? >");
  background.append(shellQuote(tmp / "rc")).append(") &");
  ASSERT_EQ(std::system(background.c_str()), 0);
  // Cancel the first array task seen running (bounded wait).
  std::string cancelled;
  for (int i = 0; i < 1200 && cancelled.empty() && !fs::exists(tmp / "rc"); ++i) {
    std::this_thread::sleep_for(std::chrono::milliseconds(50));
    const std::string q = commandOut("squeue -h -r -n sandtable-build -t RUNNING -o %i");
    if (!q.empty()) cancelled = q.substr(0, q.find('\n'));
  }
  ASSERT_FALSE(cancelled.empty()) << "no array task was seen running; log:\n" << slurpFile(tmp / "log");
  std::string scancel = "scancel ";
  scancel.append(cancelled);
  ASSERT_EQ(std::system(scancel.c_str()), 0);
  for (int i = 0; i < 2400 && !fs::exists(tmp / "rc"); ++i) std::this_thread::sleep_for(std::chrono::milliseconds(100));
  ASSERT_TRUE(fs::exists(tmp / "rc")) << "the build did not end";
  std::this_thread::sleep_for(std::chrono::milliseconds(100));
  EXPECT_NE(std::atoi(slurpFile(tmp / "rc").c_str()), 0) << slurpFile(tmp / "log");
  const std::string log = slurpFile(tmp / "log");
  EXPECT_NE(log.find("tasks unbuilt"), std::string::npos) << log;
  EXPECT_FALSE(fs::exists(tmp / "dist")) << "a build with a cancelled task published a database";
  // The rerun submits only what is missing, and the result is the same bytes.
  const auto r = runCli(with(bayreuthArgs(), {"-o", tmp / "dist", "--executor", "slurm", "--tasks", "4"}));
  ASSERT_EQ(r.exitCode, 0) << r.err;
  EXPECT_NE(r.err.find("already built"), std::string::npos) << r.err;
  EXPECT_EQ(r.err.find("0 already built"), std::string::npos) << "the rerun built every task again:\n" << r.err;
  expectSameDatabase(tmp / "one", tmp / "dist");
}

}  // namespace
}  // namespace sandtable::test
