// A grid read by block from a remote source (GridFile::openRemote): the
// posts equal the local file's, the local copy is reused and checked, a
// damaged response is fetched again, a block that cannot be had stands in
// flat and comes back, and the copy stays within its bound.
#include <gtest/gtest.h>
#include <sys/stat.h>
#include <unistd.h>
#include <zlib.h>

#include <atomic>
#include <filesystem>
#include <fstream>
#include <thread>

#include "sandtable/formats/bytes.h"
#include "sandtable/formats/grid.h"

namespace sandtable::grid {
namespace {

namespace fs = std::filesystem;

std::string tempPath(const std::string& name) {
  return (fs::temp_directory_path() / (name + "." + std::to_string(::getpid()))).string();
}

/// Posts that differ everywhere: elevation 10 i + j / 8, material (i + 2 j) % 5.
std::vector<std::byte> gridBytes(std::uint32_t nx, std::uint32_t nz) {
  const std::string path = tempPath("remote-src.stg");
  auto w = GridWriter::create(path, makeHeader(nx, nz, 25.0, 600000.0, 5000000.0));
  EXPECT_TRUE(w.ok()) << w.error();
  const Header& h = w.value()->header();
  auto b = std::make_unique<BlockData>();
  for (std::uint32_t bz = 0; bz < h.blocksZ; ++bz) {
    for (std::uint32_t bx = 0; bx < h.blocksX; ++bx) {
      for (std::uint32_t k = 0; k < kPostsPerBlock; ++k) {
        const std::uint32_t i = std::min(nx - 1, bx * kBlockPosts + k % kBlockPosts);
        const std::uint32_t j = std::min(nz - 1, bz * kBlockPosts + k / kBlockPosts);
        b->elevation[k] = float(10 * i) + float(j) / 8;
        b->normalX[k] = toSnorm(0.6f);
        b->normalY[k] = toSnorm(0.8f);
        b->normalZ[k] = 0;
        b->material[k] = std::uint8_t((i + 2 * j) % 5);
      }
      EXPECT_EQ(w.value()->writeBlock(bx, bz, *b).message(), "");
    }
  }
  EXPECT_EQ(w.value()->finish().message(), "");
  std::ifstream in(path, std::ios::binary);
  std::vector<char> c((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
  fs::remove(path);
  std::vector<std::byte> out(c.size());
  std::memcpy(out.data(), c.data(), c.size());
  return out;
}

std::uint32_t zlibCrc(std::span<const std::byte> b) {
  return static_cast<std::uint32_t>(::crc32(0L, reinterpret_cast<const Bytef*>(b.data()), static_cast<uInt>(b.size())));
}

/// A server in memory: counts reads; may alter the next `alter` responses
/// past the header, or fail every read while `down`.
class MemorySource final : public RangeSource {
 public:
  explicit MemorySource(std::vector<std::byte> bytes) : bytes_(std::move(bytes)) {}
  const std::string& name() const override { return name_; }
  std::uint64_t size() const override { return bytes_.size(); }
  Status read(std::uint64_t off, std::span<std::byte> out) const override {
    ++reads;
    readBytes += out.size();
    if (delayMs > 0) std::this_thread::sleep_for(std::chrono::milliseconds(delayMs));
    if (down) return Problem{name_, off, "http: connection refused"};
    if (off + out.size() > bytes_.size()) return Problem{name_, off, "past the end"};
    std::copy_n(bytes_.begin() + std::ptrdiff_t(off), out.size(), out.begin());
    if (off >= kPageBytes && alter > 0) {
      --alter;
      out[out.size() / 2] ^= std::byte{0x40};
    }
    return {};
  }
  void refresh(std::uint64_t, std::uint64_t) const override { ++refreshes; }
  mutable std::atomic<int> reads{0}, refreshes{0}, alter{0};
  mutable std::atomic<std::uint64_t> readBytes{0};
  std::atomic<bool> down{false};
  int delayMs = 0;  ///< a slow link: readers of a block being fetched wait for it

 private:
  std::string name_ = "http://example.org/db/grid.stg";
  std::vector<std::byte> bytes_;
};

struct Fixture {
  std::vector<std::byte> bytes;
  std::shared_ptr<const GridFile> local;
  std::string localPath, copyPath;
  std::uint32_t crc = 0;

  Fixture(std::uint32_t nx, std::uint32_t nz, const std::string& tag) : bytes(gridBytes(nx, nz)) {
    localPath = tempPath("remote-local-" + tag + ".stg");
    copyPath = tempPath("remote-copy-" + tag + ".cache");
    fs::remove(copyPath);
    std::ofstream(localPath, std::ios::binary).write(reinterpret_cast<const char*>(bytes.data()), std::streamsize(bytes.size()));
    local = GridFile::open(localPath).value();
    crc = zlibCrc(bytes);
  }
  ~Fixture() {
    local.reset();
    fs::remove(localPath);
    fs::remove(copyPath);
  }
};

/// Every post of `g` equals the local file's (a sample of them, the last
/// row and column included, so every block is read).
void expectSamePosts(const GridFile& g, const GridFile& local) {
  auto next = [](std::uint32_t v, std::uint32_t step, std::uint32_t n) { return v + 1 == n ? n : std::min(v + step, n - 1); };
  for (std::uint32_t j = 0; j < local.postsZ(); j = next(j, 3, local.postsZ())) {
    for (std::uint32_t i = 0; i < local.postsX(); i = next(i, 5, local.postsX())) {
      ASSERT_EQ(g.elevation(i, j), local.elevation(i, j)) << i << "," << j;
      ASSERT_EQ(g.material(i, j), local.material(i, j)) << i << "," << j;
      ASSERT_EQ(g.normal(i, j), local.normal(i, j)) << i << "," << j;
    }
  }
}

TEST(GridRemote, postsEqualTheFileAndTheCopyIsReused) {
  Fixture f(300, 200, "reuse");  // 5 x 4 blocks
  auto src = std::make_shared<MemorySource>(f.bytes);
  {
    auto g = GridFile::openRemote(src, f.copyPath, f.crc);
    ASSERT_TRUE(g.ok()) << g.error();
    EXPECT_TRUE(g.value()->remote());
    EXPECT_EQ(src->reads, 2);  // the header page, then the table
    expectSamePosts(*g.value(), *f.local);
    const RemoteGridStats s = g.value()->remoteStats();
    EXPECT_EQ(s.fetchedBlocks, 20u);
    EXPECT_EQ(s.diskBlocks, 0u);
    // Readahead: a row of 5 blocks is at most 2 requests (1 + 4 after it).
    EXPECT_LE(s.requests, 8u);
    EXPECT_EQ(g.value()->bytes().size(), f.bytes.size());
    EXPECT_TRUE(std::equal(f.bytes.begin(), f.bytes.end(), g.value()->bytes().begin()));
  }
  // A second open asks the server for nothing: the copy's header and table
  // combine to the manifest's CRC, and every block comes from the copy,
  // checked.
  const int before = src->reads;
  auto again = GridFile::openRemote(src, f.copyPath, f.crc);
  ASSERT_TRUE(again.ok()) << again.error();
  expectSamePosts(*again.value(), *f.local);
  EXPECT_EQ(src->reads - before, 0);
  EXPECT_EQ(again.value()->remoteStats().diskBlocks, 20u);
  EXPECT_EQ(again.value()->remoteStats().fetchedBlocks, 0u);
}

TEST(GridRemote, aTableThatDoesNotCombineToTheManifestCrcIsRefused) {
  Fixture f(130, 70, "crc");
  auto g = GridFile::openRemote(std::make_shared<MemorySource>(f.bytes), f.copyPath, f.crc ^ 1);
  ASSERT_FALSE(g.ok());
  EXPECT_EQ(g.problems().front().file, "http://example.org/db/grid.stg");
  EXPECT_NE(g.error().find("damaged or from another build"), std::string::npos) << g.error();
  // A block's CRC changed in the table (and the table CRC with it): the
  // combined CRC no longer matches the manifest's.
  std::vector<std::byte> b = f.bytes;
  Header h = decodeHeader(std::span(b).first(kPageBytes), "x", b.size()).value();
  b[h.blockTableOffset] ^= std::byte{1};
  h.tableCrc = zlibCrc(std::span(b).subspan(h.blockTableOffset, h.blockCount() * kBlockEntryBytes));
  const auto page = encodeHeader(h);
  std::copy(page.begin(), page.end(), b.begin());
  auto g2 = GridFile::openRemote(std::make_shared<MemorySource>(b), f.copyPath, f.crc);
  ASSERT_FALSE(g2.ok());
  EXPECT_NE(g2.error().find("manifest says"), std::string::npos) << g2.error();
  // A short file: refused before anything past the header is read.
  std::vector<std::byte> cut(f.bytes.begin(), f.bytes.begin() + 5000);
  auto g3 = GridFile::openRemote(std::make_shared<MemorySource>(cut), f.copyPath, f.crc);
  ASSERT_FALSE(g3.ok());
  EXPECT_NE(g3.error().find("truncated"), std::string::npos) << g3.error();
}

TEST(GridRemote, aDamagedResponseIsFetchedAgainAndADamagedCopyToo) {
  Fixture f(130, 70, "damage");
  auto src = std::make_shared<MemorySource>(f.bytes);
  {
    auto g = GridFile::openRemote(src, f.copyPath, f.crc);
    ASSERT_TRUE(g.ok()) << g.error();
    src->alter = 1;
    expectSamePosts(*g.value(), *f.local);
    EXPECT_EQ(src->refreshes, 1);
    EXPECT_EQ(g.value()->remoteStats().refetches, 1u);
    EXPECT_TRUE(g.value()->takeRemoteProblems().empty());
  }
  // One byte of a block flipped in the local copy: that block is fetched
  // again, the others come from the copy.
  const Header h = f.local->header();
  {
    std::fstream io(f.copyPath, std::ios::in | std::ios::out | std::ios::binary);
    io.seekp(std::streamoff(h.dataOffset + kBlockBytes + 77));
    io.put('\x5a');
  }
  const int before = src->reads;
  auto g = GridFile::openRemote(src, f.copyPath, f.crc);
  ASSERT_TRUE(g.ok()) << g.error();
  expectSamePosts(*g.value(), *f.local);
  EXPECT_EQ(g.value()->remoteStats().fetchedBlocks, 1u);
  EXPECT_EQ(g.value()->remoteStats().diskBlocks, 5u);  // the other five
  EXPECT_EQ(src->reads - before, 1);
  // The copy's block table damaged: its head no longer checks, so the
  // server's is fetched again (two reads), and the posts are still right.
  {
    std::fstream io(f.copyPath, std::ios::in | std::ios::out | std::ios::binary);
    io.seekp(std::streamoff(h.blockTableOffset + 3));
    io.put('\x11');
  }
  const int before2 = src->reads;
  auto g2 = GridFile::openRemote(src, f.copyPath, f.crc);
  ASSERT_TRUE(g2.ok()) << g2.error();
  EXPECT_EQ(src->reads - before2, 2);
  expectSamePosts(*g2.value(), *f.local);
}

TEST(GridRemote, aBlockThatCannotBeHadStandsInFlatAndComesBack) {
  Fixture f(130, 70, "down");
  auto src = std::make_shared<MemorySource>(f.bytes);
  RemoteGridOptions o;
  o.retryFirstSeconds = 0.2;
  auto g = GridFile::openRemote(src, f.copyPath, f.crc, o);
  ASSERT_TRUE(g.ok()) << g.error();
  src->down = true;
  // Block (1, 0): posts 64..127 east. Its stand-in is flat at the middle of
  // its table entry's range, normals up.
  const BlockEntry e = f.local->blockEntry(1, 0);
  EXPECT_EQ(g.value()->elevation(70, 10), 0.5f * (e.minElevation + e.maxElevation));
  EXPECT_EQ(g.value()->normal(70, 10), (std::array<float, 3>{0, 1, 0}));
  const int afterFirst = src->reads;
  EXPECT_EQ(g.value()->elevation(71, 11), 0.5f * (e.minElevation + e.maxElevation));
  EXPECT_EQ(src->reads, afterFirst);  // not asked again before the pause
  const Status st = g.value()->fetchBlocks(0, 0, 2, 1);
  ASSERT_FALSE(st.ok());
  EXPECT_EQ(st.problems().front().file, "http://example.org/db/grid.stg");
  const auto problems = g.value()->takeRemoteProblems();
  ASSERT_FALSE(problems.empty());
  EXPECT_EQ(problems.front().offset, f.local->header().dataOffset + kBlockBytes);
  EXPECT_NE(problems.front().message.find("connection refused"), std::string::npos);
  EXPECT_GT(g.value()->remoteStats().standIns, 0u);
  // The server is back; after the pause the real posts come.
  src->down = false;
  std::this_thread::sleep_for(std::chrono::milliseconds(300));
  expectSamePosts(*g.value(), *f.local);
  EXPECT_EQ(g.value()->remoteStats().standIns, 0u);
}

TEST(GridRemote, aBlockDamagedOnTheServerIsNamed) {
  Fixture f(130, 70, "bad");
  std::vector<std::byte> b = f.bytes;
  const Header h = f.local->header();
  b[h.dataOffset + 2 * kBlockBytes + 9] ^= std::byte{0x10};  // block (2, 0)
  auto g = GridFile::openRemote(std::make_shared<MemorySource>(b), f.copyPath, f.crc);
  ASSERT_TRUE(g.ok()) << g.error();  // header and table are sound
  EXPECT_EQ(g.value()->elevation(10, 10), f.local->elevation(10, 10));
  (void)g.value()->elevation(129, 10);
  const auto problems = g.value()->takeRemoteProblems();
  ASSERT_EQ(problems.size(), 1u);
  EXPECT_EQ(problems.front().offset, h.dataOffset + 2 * kBlockBytes);
  EXPECT_NE(problems.front().message.find("failed its checksum twice"), std::string::npos) << problems.front().message;
}

// Threads reading at once over a slow source: a block being fetched is
// waited for (not fetched twice, not read half-written), a fetch holds no
// lock other blocks' readers need, and every post is right.
TEST(GridRemote, readersOnManyThreadsSeeOnlyWholeBlocks) {
  Fixture f(64 * 8, 64 * 6, "threads");  // 48 blocks
  auto src = std::make_shared<MemorySource>(f.bytes);
  src->delayMs = 3;
  auto g = GridFile::openRemote(src, f.copyPath, f.crc);
  ASSERT_TRUE(g.ok()) << g.error();
  std::atomic<int> wrong{0};
  std::vector<std::thread> threads;
  for (std::uint32_t t = 0; t < 6; ++t) {
    threads.emplace_back([&, t] {
      for (std::uint32_t k = 0; k < 3000; ++k) {
        const std::uint32_t i = (k * 7919u + t * 104729u) % f.local->postsX();
        const std::uint32_t j = (k * 6271u + t * 15485863u) % f.local->postsZ();
        if (g.value()->elevation(i, j) != f.local->elevation(i, j) || g.value()->material(i, j) != f.local->material(i, j)) {
          ++wrong;
        }
      }
    });
  }
  // A prefetch of the whole grid from another thread at the same time.
  threads.emplace_back([&] { EXPECT_TRUE(g.value()->fetchBlocks(0, 0, 7, 5).ok()); });
  for (auto& t : threads) t.join();
  EXPECT_EQ(wrong.load(), 0);
  EXPECT_EQ(g.value()->remoteStats().fetchedBlocks, 48u) << "a block was fetched twice";
}

TEST(GridRemote, theCopyStaysWithinItsBound) {
  Fixture f(64 * 12, 64 * 4, "bound");  // 48 blocks, 2.1 MB
  auto src = std::make_shared<MemorySource>(f.bytes);
  RemoteGridOptions o;
  o.maxBytes = 10 * kBlockBytes;
  o.evictAfterSeconds = 0;
  auto g = GridFile::openRemote(src, f.copyPath, f.crc, o);
  ASSERT_TRUE(g.ok()) << g.error();
  expectSamePosts(*g.value(), *f.local);
  struct stat st {};
  ASSERT_EQ(::stat(f.copyPath.c_str(), &st), 0);
  // The bound plus the header, the table and one fetch's blocks.
  EXPECT_LE(std::uint64_t(st.st_blocks) * 512, o.maxBytes + 2 * kPageBytes + 5 * kBlockBytes);
  EXPECT_GT(g.value()->remoteStats().evictedBlocks, 0u);
  // Evicted blocks are fetched again when read.
  expectSamePosts(*g.value(), *f.local);
}

}  // namespace
}  // namespace sandtable::grid
