// `sandtable build` on the hostile inputs of issue 9: culture lines whose
// exact widening used to take minutes (they must now build and validate),
// SIGTERM and SIGINT during long stages (the build must stop promptly and
// leave neither the database nor its partial directory), and culture that
// misses the terrain (an error) or lands only in part (counted).
#include <fcntl.h>
#include <signal.h>
#include <spawn.h>
#include <sys/wait.h>
#include <unistd.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <fstream>
#include <random>
#include <sstream>
#include <thread>

#include <nlohmann/json.hpp>

#include "test_support.h"

extern char** environ;

namespace sandtable::test {
namespace {

namespace fs = std::filesystem;

// The small SRTM crop every build here uses (3.6 x 3.3 km).
const std::vector<std::string> kCrop = {"--extent", "11.50", "49.50", "11.55", "49.53", "--spacing", "30"};
constexpr double kLon0 = 11.525, kLat0 = 49.515;

/// A GeoJSON FeatureCollection of lines, in lon/lat; each line given in
/// metres east/north of (kLon0, kLat0).
std::string writeLines(const std::string& path, const std::vector<std::vector<std::array<double, 2>>>& lines,
                       const std::string& props) {
  const double mLat = 111320.0, mLon = 111320.0 * std::cos(kLat0 * M_PI / 180);
  std::ofstream out(path);
  out.precision(10);
  out << "{\"type\":\"FeatureCollection\",\"features\":[";
  for (std::size_t l = 0; l < lines.size(); ++l) {
    out << (l ? ",\n" : "") << "{\"type\":\"Feature\",\"properties\":{" << props
        << "},\"geometry\":{\"type\":\"LineString\",\"coordinates\":[";
    for (std::size_t k = 0; k < lines[l].size(); ++k) {
      out << (k ? "," : "") << "[" << kLon0 + lines[l][k][0] / mLon << "," << kLat0 + lines[l][k][1] / mLat << "]";
    }
    out << "]}}";
  }
  out << "]}\n";
  return path;
}

std::vector<std::string> buildArgs(const std::string& culture, const std::string& db, bool json = true) {
  std::vector<std::string> a = {"build", "--elevation", data("elevation/srtm/N49E011.hgt.zip")};
  a.insert(a.end(), kCrop.begin(), kCrop.end());
  a.insert(a.end(), {"--culture", culture, "-o", db});
  if (json) a.push_back("--json");
  return a;
}

void expectValid(const std::string& db) {
  const auto v = runCli({"validate", db, "--json"});
  EXPECT_EQ(v.exitCode, 0) << v.out << v.err;
  EXPECT_TRUE(nlohmann::json::parse(v.out)["ok"].get<bool>()) << v.out;
}

TEST(BuildHostile, zigzagAndTenThousandVertexRoadsBuildAndValidate) {
  SANDTABLE_REQUIRE_DATA();
  TempDir tmp("hostile");
  // 2,000 vertices 0.33 m apart, +-55 m, 900 m wide: over 5 minutes before.
  std::vector<std::array<double, 2>> zigzag, smooth;
  for (int k = 0; k < 2000; ++k) zigzag.push_back({-330 + 0.33 * k, k % 2 ? 55.0 : -55.0});
  // 10,000 vertices 0.3 m apart on a gentle curve: 16 s before.
  for (int k = 0; k < 10000; ++k) smooth.push_back({-1500 + 0.3 * k, 200 * std::sin(k / 1500.0)});
  struct Case {
    const char* name;
    std::vector<std::array<double, 2>> line;
    const char* width;
    bool coarsened;
  };
  for (const Case& c : {Case{"zigzag", zigzag, "900", true}, Case{"smooth", smooth, "9", false}}) {
    SCOPED_TRACE(c.name);
    const std::string culture = writeLines(tmp / (std::string(c.name) + ".geojson"), {c.line},
                                           "\"highway\":\"primary\",\"width\":\"" + std::string(c.width) + "\"");
    const std::string db = tmp / c.name;
    const auto b = runCli(buildArgs(culture, db));
    ASSERT_EQ(b.exitCode, 0) << b.err;
    const auto j = nlohmann::json::parse(b.out);
    EXPECT_EQ(j["culture"]["features_landed"], 1);
    EXPECT_EQ(j["culture"]["lines_coarsened"], c.coarsened ? 1 : 0);
    EXPECT_LT(j["culture"]["line_vertices_kept"].get<int>(), 1000);
    EXPECT_GT(j["culture"]["classes"]["primary"]["length_km"].get<double>(), c.coarsened ? 0.1 : 2.9);
    // The estimate's sizes are exact: what was built.
    ASSERT_TRUE(j.contains("estimate"));
    EXPECT_EQ(j["estimate"]["posts"], j["posts"]);
    EXPECT_EQ(j["estimate"]["modules"], j["modules"]["count"]);
    EXPECT_EQ(j["estimate"]["grid_bytes"].get<std::uintmax_t>(), fs::file_size(db + "/grid.stg"));
    EXPECT_GT(j["estimate"]["peak_bytes"].get<double>(), 0.0);
    expectValid(db);
  }
}

// ------------------------------------------------------------ signals

/// A running `sandtable build`, its stderr going to a file.
class Running {
 public:
  Running(const std::vector<std::string>& args, const std::string& errPath) : err_(errPath) {
    std::vector<std::string> all = {SANDTABLE_CLI};
    all.insert(all.end(), args.begin(), args.end());
    std::vector<char*> argv;
    for (auto& a : all) argv.push_back(a.data());
    argv.push_back(nullptr);
    posix_spawn_file_actions_t fa;
    posix_spawn_file_actions_init(&fa);
    posix_spawn_file_actions_addopen(&fa, 0, "/dev/null", O_RDONLY, 0);
    posix_spawn_file_actions_addopen(&fa, 1, "/dev/null", O_WRONLY, 0);
    posix_spawn_file_actions_addopen(&fa, 2, errPath.c_str(), O_WRONLY | O_CREAT | O_TRUNC, 0644);
    // The test runner may block or ignore signals; the child starts clean.
    posix_spawnattr_t at;
    posix_spawnattr_init(&at);
    sigset_t none, all_;
    sigemptyset(&none);
    sigfillset(&all_);
    posix_spawnattr_setsigmask(&at, &none);
    posix_spawnattr_setsigdefault(&at, &all_);
    posix_spawnattr_setflags(&at, POSIX_SPAWN_SETSIGMASK | POSIX_SPAWN_SETSIGDEF);
    spawned_ = posix_spawn(&pid_, argv[0], &fa, &at, argv.data(), environ) == 0;
    posix_spawn_file_actions_destroy(&fa);
    posix_spawnattr_destroy(&at);
  }
  ~Running() {
    if (spawned_ && !exited_) {
      ::kill(pid_, SIGKILL);
      ::waitpid(pid_, nullptr, 0);
    }
  }
  bool spawned() const { return spawned_; }
  /// Waits until stderr holds `marker` (true) or the process ends (false).
  bool waitFor(const std::string& marker, double seconds) {
    const auto end = std::chrono::steady_clock::now() + std::chrono::duration<double>(seconds);
    while (std::chrono::steady_clock::now() < end) {
      if (slurpFile(err_).find(marker) != std::string::npos) return true;
      if (poll()) return false;
      std::this_thread::sleep_for(std::chrono::milliseconds(20));
    }
    return false;
  }
  /// Sends `sig` and returns the seconds until the process ended (or
  /// `limit` + 1 if it did not; it is then killed).
  double stopWith(int sig, double limit) {
    const auto t0 = std::chrono::steady_clock::now();
    ::kill(pid_, sig);
    for (;;) {
      const double s = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
      if (poll()) return s;
      if (s > limit) return limit + 1;
      std::this_thread::sleep_for(std::chrono::milliseconds(10));
    }
  }
  int status() const { return status_; }
  std::string err() const { return slurpFile(err_); }

 private:
  bool poll() {
    if (exited_) return true;
    exited_ = ::waitpid(pid_, &status_, WNOHANG) == pid_;
    return exited_;
  }
  std::string err_;
  pid_t pid_ = -1;
  bool spawned_ = false, exited_ = false;
  int status_ = 0;
};

/// Heavy culture: 100 wiggly roads of 2,500 vertices (5 m steps) across the
/// crop. Widening them takes about a minute on two cores.
std::string heavyCulture(const TempDir& tmp) {
  std::mt19937 rng(9);
  std::uniform_real_distribution<double> turn(-0.6, 0.6);
  std::vector<std::vector<std::array<double, 2>>> lines;
  for (int l = 0; l < 100; ++l) {
    std::vector<std::array<double, 2>> p;
    double x = -1500, z = -1500 + 30.0 * l, a = 0;
    for (int k = 0; k < 2500; ++k) {
      p.push_back({x, z});
      a = std::clamp(a + turn(rng), -1.0, 1.0);
      x += 5 * std::cos(a), z += 5 * std::sin(a) * 0.2;
      if (x > 1500) x = -1500 + (x - 1500);
    }
    lines.push_back(std::move(p));
  }
  return writeLines(tmp / "heavy.geojson", lines, "\"highway\":\"residential\"");
}

/// Nothing named like the output, finished or partial.
void expectNothingLeft(const TempDir& tmp) {
  for (const auto& e : fs::directory_iterator(tmp.path())) {
    EXPECT_NE(e.path().filename().string().rfind("db", 0), 0u) << "left behind: " << e.path();
  }
}

// A stop is a behaviour, not a benchmark, and tests hold no timing
// thresholds: promptness is checked by what the build printed after the
// signal (it never finished the stage it was in, nor began another). This
// limit only keeps a build that ignores the signal from hanging the test;
// the seconds taken are printed.
constexpr double kStopLimit = 60.0;

/// The progress lines (`stage: NN% (Ts)`, non-TTY form) of `text`.
std::vector<std::string> progressLines(const std::string& text) {
  std::vector<std::string> out;
  std::istringstream in(text);
  for (std::string l; std::getline(in, l);) {
    const auto pct = l.find("% (");
    if (pct != std::string::npos && l.find(": ") < pct && l.back() == ')') out.push_back(l);
  }
  return out;
}

struct SignalCase {
  const char* name;
  int sig;
  bool culture;        ///< heavy culture (else none)
  const char* marker;  ///< stderr text of the stage to interrupt
};

void PrintTo(const SignalCase& c, std::ostream* os) { *os << c.name; }

class BuildSignal : public ::testing::TestWithParam<SignalCase> {};

TEST_P(BuildSignal, stopsPromptlyAndLeavesNothing) {
  SANDTABLE_REQUIRE_DATA();
  const SignalCase& c = GetParam();
  TempDir tmp("signal");
  const std::string db = tmp / "db";
  std::vector<std::string> args;
  if (c.culture) {
    args = buildArgs(heavyCulture(tmp), db, false);  // no --json: progress lines on stderr
  } else {
    // A whole SRTM cell at 30 m: seconds of resampling.
    args = {"build", "--elevation", data("elevation/srtm/N49E011.hgt.zip"), "--spacing", "30", "-o", db};
  }
  Running run(args, tmp / "stderr.txt");
  ASSERT_TRUE(run.spawned());
  ASSERT_TRUE(run.waitFor(c.marker, 120)) << run.err();
  const std::size_t before = run.err().size();
  const double s = run.stopWith(c.sig, kStopLimit);
  ASSERT_LE(s, kStopLimit) << "the build did not stop: " << run.err();
  for (const std::string& l : progressLines(run.err().substr(before))) {
    EXPECT_NE(l.find(c.marker), std::string::npos) << "a later stage began after the signal: " << l;
    EXPECT_EQ(l.find("100%"), std::string::npos) << "the stage ran to its end after the signal: " << l;
  }
  EXPECT_TRUE(WIFEXITED(run.status())) << run.err();
  EXPECT_EQ(WEXITSTATUS(run.status()), 128 + c.sig) << run.err();
  EXPECT_NE(run.err().find("cancelled"), std::string::npos) << run.err();
  expectNothingLeft(tmp);
  std::printf("[          ] %s: stopped %.2f s after the signal\n", c.name, s);
}

INSTANTIATE_TEST_SUITE_P(
    Stages, BuildSignal,
    ::testing::Values(SignalCase{"sigtermWhileWideningCulture", SIGTERM, true, "widening lines"},
                      SignalCase{"sigintWhileReadingCulture", SIGINT, true, "reading culture"},
                      SignalCase{"sigtermWhileResampling", SIGTERM, false, "resampling"},
                      SignalCase{"sigintWhileBuildingModules", SIGINT, false, "modules:"}),
    [](const auto& p) { return std::string(p.param.name); });

// ------------------------------------------------------------ culture off the terrain

TEST(BuildHostile, cultureThatMissesTheTerrainIsAnError) {
  SANDTABLE_REQUIRE_DATA();
  TempDir tmp("miss");
  // Monaco's OSM over a Danish DTED cell.
  const std::string monaco = data("culture/osm/monaco.osm.gz");
  const auto b = runCli({"build", "--elevation", data("elevation/dted/denmark-dhm/e010/n55.dt1"), "--culture", monaco,
                         "--extent", "10.0", "55.0", "10.1", "55.05", "-o", tmp / "db"});
  EXPECT_EQ(b.exitCode, 2) << b.err;
  EXPECT_NE(b.err.find(monaco), std::string::npos) << b.err;
  EXPECT_NE(b.err.find("lies on the terrain"), std::string::npos) << b.err;
  EXPECT_NE(b.err.find("the culture covers lon 7."), std::string::npos) << b.err;
  EXPECT_NE(b.err.find("the database lon 10."), std::string::npos) << b.err;
  expectNothingLeft(tmp);
}

TEST(BuildHostile, cultureLandingInPartCountsWhatLanded) {
  SANDTABLE_REQUIRE_DATA();
  TempDir tmp("part");
  // A corner of Monaco: most of the extract lies outside.
  const auto b = runCli({"build", "--elevation", data("elevation/srtm/N43E007.hgt.zip"), "--culture",
                         data("culture/osm/monaco.osm.gz"), "--extent", "7.41", "43.72", "7.425", "43.735",
                         "--spacing", "30", "--json", "-o", tmp / "db"});
  ASSERT_EQ(b.exitCode, 0) << b.err;
  const auto c = nlohmann::json::parse(b.out)["culture"];
  const auto read = c["features_read"].get<std::uint64_t>(), landed = c["features_landed"].get<std::uint64_t>(),
             outside = c["features_outside"].get<std::uint64_t>();
  EXPECT_GT(landed, 0u);
  EXPECT_GT(outside, 0u);
  EXPECT_LE(landed + outside, read);
  // The text summary says the same.
  const auto t = runCli({"build", "--elevation", data("elevation/srtm/N43E007.hgt.zip"), "--culture",
                         data("culture/osm/monaco.osm.gz"), "--extent", "7.41", "43.72", "7.425", "43.735",
                         "--spacing", "30", "-o", tmp / "db2"});
  ASSERT_EQ(t.exitCode, 0) << t.err;
  EXPECT_NE(t.out.find(std::to_string(landed) + " features on the terrain (" + std::to_string(read) + " read, " +
                       std::to_string(outside) + " outside)"),
            std::string::npos)
      << t.out;
  EXPECT_NE(t.err.find("estimate: "), std::string::npos) << t.err;
  // Culture loading shows progress (plain lines: stderr is not a TTY).
  EXPECT_NE(t.err.find("reading culture:"), std::string::npos) << t.err;
  EXPECT_NE(t.err.find("widening lines:"), std::string::npos) << t.err;
}

}  // namespace
}  // namespace sandtable::test
