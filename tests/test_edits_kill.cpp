// Kill -9 during a burst of edits (issue 37): a child process applies
// craters through the editor with its journal, batches of four made
// durable, until the parent kills it with SIGKILL mid-burst. Then
// `sandtable edits list` reads the journal to the last whole record (at most
// a warning), and the ground replayed from it (`export --journal --grid`,
// read through GDAL) equals, post for post and byte for byte, the ground of
// a fresh journal written from exactly the records listed. The same holds
// with the last record torn by hand (a crash inside a write), which is cut
// with a warning.
#include <gdal_priv.h>
#include <gtest/gtest.h>
#include <signal.h>
#include <sys/wait.h>
#include <unistd.h>

#include <chrono>
#include <cstring>
#include <filesystem>
#include <thread>

#include <nlohmann/json.hpp>

#include "sandtable/edits/editor.h"
#include "sandtable/formats/edit_journal.h"
#include "sandtable/paging/world.h"
#include "test_support.h"

namespace sandtable::test {
namespace {

namespace fs = std::filesystem;

constexpr int kBurst = 100000;  // far more than the child lives to make

/// The k-th crater of the burst: spread over the database (68 x 71 posts
/// at 30 m), positions on a 1/8 m lattice so the JSON's decimals are exact.
edit::Edit burstCrater(int k) {
  edit::Edit e;
  e.id = std::uint64_t(k);
  e.time = k * 0.5;
  e.kind = edit::Kind::crater;
  e.points = {{100 + (k * 37 % 1800) + 0.125, 100 + (k * 53 % 1900) + 0.375}};
  e.radius = 2 + k % 5;
  e.depth = 0.5 + 0.25 * (k % 4);
  return e;
}

/// The child: applies the burst and never returns.
[[noreturn]] void burst(const std::string& db, const std::string& journal) {
  auto world = paging::World::open(db);
  if (!world) ::_exit(3);
  edits::EditorOptions o;
  o.journal = journal;
  o.meshModules = false;
  o.journalOptions.batchRecords = 4;
  auto ed = edits::Editor::open(world.value(), o);
  if (!ed) ::_exit(4);
  for (int k = 1; k <= kBurst; ++k) {
    if (!ed.value()->apply(burstCrater(k))) ::_exit(5);
    if (!ed.value()->tick()) ::_exit(6);
  }
  ::_exit(0);
}

/// An edit from `edits list --json`'s fields.
edit::Edit fromJson(const nlohmann::json& j) {
  edit::Edit e;
  e.id = j["id"].get<std::uint64_t>();
  e.time = j["time_s"].get<double>();
  e.origin = j["origin"].get<edit::Origin>();
  EXPECT_EQ(j["kind"], "crater");
  e.kind = edit::Kind::crater;
  for (const auto& p : j["points_xz"]) e.points.push_back({p[0].get<double>(), p[1].get<double>()});
  e.radius = j["radius_m"].get<double>();
  e.depth = j["depth_m"].get<double>();
  return e;
}

/// Writes `edits` into a new journal at `path`.
void writeJournal(const std::string& path, const std::vector<edit::Edit>& edits) {
  auto w = journal::JournalWriter::open(path);
  ASSERT_TRUE(w) << w.error();
  for (const edit::Edit& e : edits) ASSERT_TRUE(w.value()->append(e));
  ASSERT_TRUE(w.value()->close());
}

std::vector<float> readGrid(const std::string& path) {
  GDALAllRegister();
  std::vector<float> px;
  auto* ds = static_cast<GDALDataset*>(GDALOpen(path.c_str(), GA_ReadOnly));
  if (!ds) return px;
  const int w = ds->GetRasterXSize(), h = ds->GetRasterYSize();
  px.resize(std::size_t(w) * std::size_t(h));
  if (ds->GetRasterBand(1)->RasterIO(GF_Read, 0, 0, w, h, px.data(), w, h, GDT_Float32, 0, 0) != CE_None) px.clear();
  GDALClose(ds);
  return px;
}

/// `edits list J --json`: the edits, and what it said on stderr.
std::vector<edit::Edit> list(const std::string& journal, std::string& err) {
  const auto r = runCli({"edits", "list", journal, "--json"});
  EXPECT_EQ(r.exitCode, 0) << r.err;
  err = r.err;
  std::vector<edit::Edit> out;
  if (r.exitCode != 0) return out;
  const auto parsed = nlohmann::json::parse(r.out);
  for (const auto& e : parsed["edits"]) out.push_back(fromJson(e));
  return out;
}

/// The export of the ground over `journal`, checked equal to the export
/// over a fresh journal of `records`, post for post and byte for byte.
void expectSameGround(const TempDir& t, const std::string& db, const std::string& journal,
                      const std::vector<edit::Edit>& records, const std::string& tag) {
  const std::string fresh = t / (tag + "-fresh.journal");
  writeJournal(fresh, records);
  const std::string a = t / (tag + "-replayed.tif"), b = t / (tag + "-fresh.tif");
  for (const auto& [j, out] : {std::pair{journal, a}, std::pair{fresh, b}}) {
    const auto r = runCli({"export", db, "--journal", j, "--grid", "-o", out});
    ASSERT_EQ(r.exitCode, 0) << r.err;
  }
  const std::vector<float> pa = readGrid(a), pb = readGrid(b);
  ASSERT_FALSE(pa.empty());
  ASSERT_EQ(pa.size(), pb.size());
  std::size_t differ = 0;
  for (std::size_t k = 0; k < pa.size(); ++k) differ += std::memcmp(&pa[k], &pb[k], sizeof(float)) != 0;
  EXPECT_EQ(differ, 0u) << tag;
  EXPECT_EQ(slurpFile(a), slurpFile(b)) << tag;
}

TEST(EditsKill, aJournalKilledMidBurstReplaysToItsLastWholeRecord) {
  SANDTABLE_REQUIRE_DATA();
  TempDir t("editskill");
  const std::string db = t / "db";
  const auto b = runCli({"build", "--elevation", data("elevation/srtm/N49E011.hgt.zip"), "--extent", "11.57", "49.95",
                         "11.60", "49.97", "--spacing", "30", "--no-modules", "-o", db});
  ASSERT_EQ(b.exitCode, 0) << b.err;
  const std::string journal = t / "burst.journal";

  const pid_t child = ::fork();
  ASSERT_GE(child, 0);
  if (child == 0) burst(db, journal);
  // Kill it once a few batches are on disk (bounded wait: 60 s).
  const std::uintmax_t enough = journal::kHeaderBytes + 40 * 137;
  bool killed = false;
  for (int k = 0; k < 60000 && !killed; ++k) {
    std::error_code ec;
    if (fs::exists(journal, ec) && fs::file_size(journal, ec) >= enough) {
      ::kill(child, SIGKILL);
      killed = true;
    } else {
      std::this_thread::sleep_for(std::chrono::milliseconds(1));
    }
  }
  if (!killed) ::kill(child, SIGKILL);
  int status = 0;
  ASSERT_EQ(::waitpid(child, &status, 0), child);
  ASSERT_TRUE(killed) << "the journal never grew to " << enough << " bytes";
  ASSERT_TRUE(WIFSIGNALED(status) && WTERMSIG(status) == SIGKILL) << "the child ended by itself: " << status;

  // Replayed to the last whole record: a prefix of the burst, in order.
  std::string err;
  const std::vector<edit::Edit> listed = list(journal, err);
  ASSERT_GE(listed.size(), 40u) << fs::file_size(journal) << " bytes; " << err;
  ASSERT_LT(listed.size(), std::size_t(kBurst));
  EXPECT_TRUE(err.empty() || err.find("warning") != std::string::npos) << err;
  for (std::size_t k = 0; k < listed.size(); ++k) ASSERT_EQ(listed[k], burstCrater(int(k) + 1)) << k;
  expectSameGround(t, db, journal, listed, "killed");

  // A crash inside a write: the last record torn 7 bytes short is cut,
  // with a warning, and the ground is that of the records before it.
  const std::string torn = t / "torn.journal";
  fs::copy_file(journal, torn);
  fs::resize_file(torn, fs::file_size(journal) - 7);
  const std::vector<edit::Edit> whole = list(torn, err);
  EXPECT_NE(err.find("warning"), std::string::npos) << err;
  ASSERT_EQ(whole.size(), listed.size() - 1);
  expectSameGround(t, db, torn, whole, "torn");
}

}  // namespace
}  // namespace sandtable::test
