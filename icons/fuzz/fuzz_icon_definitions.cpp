// libFuzzer target: icon definition files (docs/ICONS.md §1) on arbitrary
// text. Only the parse: model files named in the text are not opened.
// Build with clang: -DSANDTABLE_FUZZ=ON; run by tools/fuzz.sh with
// samples/icons*.txt as the seeds.
#include <cstddef>
#include <cstdint>
#include <span>

#include "sandtable/icons/definitions.h"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  (void)sandtable::icons::parseDefinitions(std::as_bytes(std::span(data, size)), "fuzz", "/nonexistent");
  return 0;
}
