// libFuzzer target: a build part (FORMAT.md §15) on arbitrary bytes, read
// as the merge reads it: PartReader::open (header, trailer, sizes), verify
// (the file CRC and the structure), then every block (up to 8) and every
// module (up to 64) in order, whether verify passed or not. The header CRC
// and the trailer's CRC are resealed first, so the fuzzer's bytes reach the
// size and structure checks instead of stopping at a checksum. The reader
// works on a file (pread), so the bytes go through a scratch file. Build
// with clang: -DSANDTABLE_FUZZ=ON; run by tools/fuzz.sh.
#include <stdlib.h>

#include <cstddef>
#include <cstdint>
#include <cstdlib>
#include <fstream>
#include <string>
#include <vector>

#include "sandtable/formats/bytes.h"
#include "sandtable/formats/part.h"

namespace {

/// One file per fuzzing process, rewritten for every input.
const std::string& scratchFile() {
  static const std::string path = [] {
    const char* tmp = std::getenv("TMPDIR");  // tools/fuzz.sh points it into its build directory
    std::string dir = std::string(tmp && *tmp ? tmp : "/tmp") + "/sandtable-fuzz-part-XXXXXX";
    if (!::mkdtemp(dir.data())) __builtin_trap();
    return dir + "/task.part";
  }();
  return path;
}

void reseal(std::vector<std::byte>& b) {
  using namespace sandtable;
  using namespace sandtable::part;
  if (b.size() >= kHeaderBytes) {
    storeLE<std::uint32_t>(b.data() + field::headerCrc, crc32(std::span(b).first(field::headerCrc)));
  }
  if (b.size() >= kHeaderBytes + kTrailerBytes) {
    storeLE<std::uint32_t>(b.data() + b.size() - 4, crc32(std::span(b).first(b.size() - 4)));
  }
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
  auto opened = part::PartReader::open(scratchFile());
  if (!opened.ok()) return 0;
  part::PartReader& r = *opened.value();
  if (r.report().size() > part::kMaxReportBytes) __builtin_trap();  // open must cap the report
  (void)r.verify();
  std::vector<std::byte> block(grid::kBlockBytes);
  const std::uint64_t blocks = r.header().blockCount();
  for (std::uint64_t k = 0; k < blocks && k < 8; ++k) {
    if (!r.nextBlock(block).ok()) return 0;
  }
  if (blocks > 8) return 0;
  for (int k = 0; k < 64; ++k) {
    auto m = r.nextModule();
    if (!m.ok()) break;
    if (m.value().coarse.size() != m.value().entry.compressedBytes) __builtin_trap();
  }
  return 0;
}
