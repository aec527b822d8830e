// libFuzzer target: manifest::decode (manifest.json, FORMAT.md §5) on
// arbitrary bytes. A checksum mismatch is reported but the schema is still
// read, so the fuzzer reaches every field check without resealing. Build
// with clang: -DSANDTABLE_FUZZ=ON; run by tools/fuzz.sh with a built
// database's manifest.json as the seed.
#include <cstddef>
#include <cstdint>
#include <span>

#include "sandtable/formats/manifest.h"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  using namespace sandtable;
  (void)manifest::decode(std::as_bytes(std::span(data, size)), "fuzz");
  return 0;
}
