// libFuzzer target: the grid file (FORMAT.md §3) on arbitrary bytes, read
// as a database reads it: GridFile::open (header and sizes), a few posts
// through the mapping, then validateGrid (every block). Then as a web
// server's grid (GridFile::openRemote, docs/HTTP.md) from memory, with the
// bytes' own CRC as the manifest's: its posts must be the mapped file's
// wherever the block came whole. The header CRC,
// the file size field and the block table's CRC are resealed first, so
// the fuzzer's bytes reach the layout and block checks instead of stopping
// at a checksum. The bytes go through a file because the grid is only ever
// memory-mapped. Build with clang: -DSANDTABLE_FUZZ=ON; run by
// tools/fuzz.sh with a small database's grid.stg as the seed.
#include <stdlib.h>
#include <unistd.h>

#include <algorithm>
#include <cstddef>
#include <cstdlib>
#include <cstdint>
#include <fstream>
#include <memory>
#include <span>
#include <string>
#include <vector>

#include "sandtable/formats/bytes.h"
#include "sandtable/formats/grid.h"

namespace {

/// One file per fuzzing process, rewritten for every input.
const std::string& scratchFile() {
  static const std::string path = [] {
    const char* tmp = std::getenv("TMPDIR");  // tools/fuzz.sh points it into its build directory
    std::string dir = std::string(tmp && *tmp ? tmp : "/tmp") + "/sandtable-fuzz-grid-XXXXXX";
    if (!::mkdtemp(dir.data())) __builtin_trap();
    return dir + "/grid.bin";
  }();
  return path;
}

/// The bytes as a server would send them.
class MemorySource final : public sandtable::RangeSource {
 public:
  explicit MemorySource(const std::vector<std::byte>& b) : b_(b) {}
  const std::string& name() const override { return name_; }
  std::uint64_t size() const override { return b_.size(); }
  sandtable::Status read(std::uint64_t off, std::span<std::byte> out) const override {
    if (off > b_.size() || out.size() > b_.size() - off) return sandtable::Problem{name_, off, "past the end"};
    std::copy_n(b_.begin() + std::ptrdiff_t(off), out.size(), out.begin());
    return {};
  }

 private:
  const std::vector<std::byte>& b_;
  std::string name_ = "http://fuzz/grid.stg";
};

void reseal(std::vector<std::byte>& b) {
  using namespace sandtable;
  using namespace sandtable::grid;
  if (b.size() < kPageBytes) return;
  storeLE<std::uint64_t>(b.data() + field::fileBytes, b.size());
  const auto table = loadLE<std::uint64_t>(b.data() + field::blockTableOffset);
  const std::uint64_t blocks =
      std::uint64_t(loadLE<std::uint32_t>(b.data() + field::blocksX)) * loadLE<std::uint32_t>(b.data() + field::blocksZ);
  if (table <= b.size() && blocks <= (b.size() - table) / kBlockEntryBytes) {
    const auto crc = crc32(std::span(b).subspan(table, blocks * kBlockEntryBytes));
    storeLE<std::uint32_t>(b.data() + field::tableCrc, crc);
  }
  storeLE<std::uint32_t>(b.data() + field::headerCrc, crc32(std::span(b).first(field::headerCrc)));
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  using namespace sandtable;
  std::vector<std::byte> b(reinterpret_cast<const std::byte*>(data), reinterpret_cast<const std::byte*>(data) + size);
  reseal(b);
  {
    std::ofstream out(scratchFile(), std::ios::binary | std::ios::trunc);
    out.write(reinterpret_cast<const char*>(b.data()), static_cast<std::streamsize>(b.size()));
  }
  const auto grid = grid::GridFile::open(scratchFile());
  if (!grid.ok()) return 0;
  const grid::GridFile& g = *grid.value();
  if (g.postsX() == 0 || g.postsZ() == 0) __builtin_trap();  // open must refuse a grid without posts
  // The corners and the middle: every plane of the posts the header says exist.
  for (const auto& [i, j] : {std::pair{0u, 0u}, std::pair{g.postsX() - 1, g.postsZ() - 1},
                             std::pair{g.postsX() / 2, g.postsZ() / 2}}) {
    (void)g.elevation(i, j);
    (void)g.normal(i, j);
    (void)g.material(i, j);
  }
  (void)grid::validateGrid(scratchFile());

  const std::string copy = scratchFile() + ".copy";
  ::unlink(copy.c_str());
  grid::RemoteGridOptions o;
  o.retryFirstSeconds = 1e9;  // a failed block is not asked again within one input
  const auto remote = grid::GridFile::openRemote(std::make_shared<MemorySource>(b), copy, crc32(b), o);
  if (!remote.ok()) return 0;
  const grid::GridFile& r = *remote.value();
  if (r.header().blockCount() != g.header().blockCount()) __builtin_trap();
  for (std::uint32_t bz = 0; bz < g.header().blocksZ; ++bz) {
    for (std::uint32_t bx = 0; bx < g.header().blocksX; ++bx) {
      const bool whole = crc32(g.blockBytes(bx, bz)) == g.blockEntry(bx, bz).crc;
      const auto got = r.blockBytes(bx, bz);
      // A whole block is the file's; any other stands in, never half-read.
      if (whole && !std::equal(got.begin(), got.end(), g.blockBytes(bx, bz).begin())) __builtin_trap();
    }
  }
  return 0;
}
