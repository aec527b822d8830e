// libFuzzer target: the pack index (modules.idx) and the pack
// (modules.pack), FORMAT.md §10, read as a database reads them:
// PackReader::open, every module (up to 64) read and decoded, then
// validatePack. Input: a 4-byte little-endian length of the index, the
// index, then the pack. The index header CRC, its table CRC, the pack
// header CRC (in both files) and the pack size are resealed first so the
// fuzzer's bytes reach the entry and record checks. The reader works on
// files (mmap and pread), so the bytes go through a scratch directory.
// Build with clang: -DSANDTABLE_FUZZ=ON; run by tools/fuzz.sh with a small
// database's index and pack as the seed.
#include <stdlib.h>

#include <algorithm>
#include <cstddef>
#include <cstdlib>
#include <cstdint>
#include <fstream>
#include <span>
#include <string>
#include <vector>

#include "sandtable/formats/bytes.h"
#include "sandtable/formats/pack.h"

namespace {

const std::string& scratchDir() {
  static const std::string dir = [] {
    const char* tmp = std::getenv("TMPDIR");  // tools/fuzz.sh points it into its build directory
    std::string d = std::string(tmp && *tmp ? tmp : "/tmp") + "/sandtable-fuzz-pack-XXXXXX";
    if (!::mkdtemp(d.data())) __builtin_trap();
    return d;
  }();
  return dir;
}

void write(const std::string& path, std::span<const std::byte> bytes) {
  std::ofstream out(path, std::ios::binary | std::ios::trunc);
  out.write(reinterpret_cast<const char*>(bytes.data()), static_cast<std::streamsize>(bytes.size()));
}

void reseal(std::vector<std::byte>& index, std::vector<std::byte>& pack) {
  using namespace sandtable;
  using namespace sandtable::pack;
  std::uint32_t packHeaderCrc = 0;
  if (pack.size() >= kPackHeaderBytes) {
    packHeaderCrc = crc32(std::span(pack).first(packField::headerCrc));
    storeLE<std::uint32_t>(pack.data() + packField::headerCrc, packHeaderCrc);
  }
  if (index.size() < kIndexHeaderBytes) return;
  storeLE<std::uint64_t>(index.data() + indexField::packBytes, pack.size());
  storeLE<std::uint32_t>(index.data() + indexField::packHeaderCrc, packHeaderCrc);
  storeLE<std::uint32_t>(index.data() + indexField::tableCrc, crc32(std::span(index).subspan(kIndexHeaderBytes)));
  storeLE<std::uint32_t>(index.data() + indexField::headerCrc, crc32(std::span(index).first(indexField::headerCrc)));
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  using namespace sandtable;
  if (size < 4) return 0;
  const auto* bytes = reinterpret_cast<const std::byte*>(data);
  const std::size_t indexBytes = std::min<std::size_t>(loadLE<std::uint32_t>(bytes), size - 4);
  std::vector<std::byte> index(bytes + 4, bytes + 4 + indexBytes), pack(bytes + 4 + indexBytes, bytes + size);
  reseal(index, pack);
  write(scratchDir() + "/" + pack::kIndexFileName, index);
  write(scratchDir() + "/" + pack::kPackFileName, pack);
  const auto reader = pack::PackReader::open(scratchDir());
  if (reader.ok()) {
    const pack::IndexHeader& h = reader.value()->header();
    int tries = 0;
    for (std::uint32_t kz = 0; kz < h.modulesZ && tries < 64; ++kz) {
      for (std::uint32_t kx = 0; kx < h.modulesX && tries < 64; ++kx, ++tries) {
        (void)reader.value()->read(kx, kz);
      }
    }
  }
  (void)pack::validatePack(scratchDir());
  return 0;
}
