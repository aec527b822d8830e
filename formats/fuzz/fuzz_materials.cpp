// libFuzzer target: the material table reader (materials.txt, FORMAT.md)
// on arbitrary text. What parse accepts must come back the same through
// format: parse(format(t)) == t is the table's documented round trip, so a
// table that does not traps. Build with clang: -DSANDTABLE_FUZZ=ON; run by
// tools/fuzz.sh with samples/materials.txt as the seed.
#include <cstddef>
#include <cstdint>
#include <span>

#include "sandtable/formats/materials.h"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  using namespace sandtable;
  const auto table = materials::parse(std::as_bytes(std::span(data, size)), "fuzz");
  if (!table.ok()) return 0;
  const std::string text = materials::format(table.value());
  const auto again = materials::parse(std::as_bytes(std::span(text.data(), text.size())), "fuzz");
  if (!again.ok() || !(again.value() == table.value())) __builtin_trap();
  return 0;
}
