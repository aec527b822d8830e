// libFuzzer target: iconpack::decode on arbitrary bytes. The size and CRC
// checks would stop almost every input at the header, so the fuzzer's bytes
// are re-sealed first (body size and both CRCs recomputed) and reach the
// body's checks. What decode accepts must encode back to the same bytes (the
// format has one encoding of each pack), so a pack that decodes but that
// encode refuses, or writes differently, traps. A version 1 pack (still
// read) is written as version 2: that must decode to the same pack. Seeds:
// tools/fuzz.sh (the built sample packs). Build with clang:
// -DSANDTABLE_FUZZ=ON (formats/CMakeLists.txt); run
// build/formats/sandtable_fuzz_icon_pack -max_len=4096.
#include <cstddef>
#include <cstdint>
#include <vector>

#include "sandtable/formats/bytes.h"
#include "sandtable/formats/icon_pack.h"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  using namespace sandtable;
  std::vector<std::byte> b(reinterpret_cast<const std::byte*>(data), reinterpret_cast<const std::byte*>(data) + size);
  if (b.size() >= iconpack::kHeaderBytes) {
    storeLE<std::uint64_t>(b.data() + 24, b.size() - iconpack::kHeaderBytes);                    // body_bytes
    storeLE<std::uint32_t>(b.data() + 32, crc32(std::span(b).subspan(iconpack::kHeaderBytes)));  // body_crc
    storeLE<std::uint32_t>(b.data() + 36, crc32(std::span(b).first(36)));                        // header_crc
  }
  const auto pack = iconpack::decode(b, "fuzz");
  if (pack.ok()) {
    const auto again = iconpack::encode(pack.value());
    if (!again.ok()) {
      __builtin_trap();
    }
    if (loadLE<std::uint32_t>(b.data() + 8) == iconpack::kVersion) {
      if (again.value() != b) {
        __builtin_trap();
      }
    } else {
      const auto twice = iconpack::decode(again.value(), "fuzz");
      if (!twice.ok() || !(twice.value() == pack.value())) {
        __builtin_trap();
      }
    }
  }
  return 0;
}
