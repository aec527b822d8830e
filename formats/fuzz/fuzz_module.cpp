// libFuzzer target: module::decode (versions 1 to 6) on arbitrary bytes.
// The CRCs would stop almost every input at the header, so the fuzzer's
// bytes are re-sealed first (both CRCs recomputed) and reach the level
// checks. Build with clang: -DSANDTABLE_FUZZ=ON (formats/CMakeLists.txt);
// run build/formats/sandtable_fuzz_module -max_len=4096.
#include <cstddef>
#include <cstdint>
#include <vector>

#include "sandtable/formats/bytes.h"
#include "sandtable/formats/module.h"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  using namespace sandtable;
  std::vector<std::byte> b(reinterpret_cast<const std::byte*>(data), reinterpret_cast<const std::byte*>(data) + size);
  if (b.size() >= module::kHeaderBytes) {
    storeLE<std::uint64_t>(b.data() + module::field::totalBytes, b.size());
    storeLE<std::uint32_t>(b.data() + module::field::payloadCrc, crc32(std::span(b).subspan(module::kHeaderBytes)));
    storeLE<std::uint32_t>(b.data() + module::field::headerCrc, crc32(std::span(b).first(module::field::headerCrc)));
  }
  module::Module m;
  (void)module::decodeInto(b, "fuzz", 0, m);
  return 0;
}
