// libFuzzer target: the edit journal (FORMAT.md §14) on arbitrary bytes,
// decoded twice: as they are (the torn-tail and damage rules see the
// checksums fail), then with the header's and every record's CRCs resealed
// so that the bytes reach the field checks. What decodes must keep the
// journal's promises, or the target traps:
// - the whole-record prefix it reports (validBytes) decodes again to the
//   same edits with no warning: cutting a torn tail leaves a sound journal;
// - every edit it gives back encodes (the writer accepts what the reader
//   accepted), and that encoding decodes and encodes to the same bytes.
// Build with clang: -DSANDTABLE_FUZZ=ON; run by tools/fuzz.sh with the
// golden journal of FORMAT.md §14.6 as the seed.
#include <cstddef>
#include <cstdint>
#include <span>
#include <vector>

#include "sandtable/formats/bytes.h"
#include "sandtable/formats/edit_journal.h"

namespace {

using namespace sandtable;
using namespace sandtable::journal;

void reseal(std::vector<std::byte>& b) {
  if (b.size() < kHeaderBytes) return;
  storeLE<std::uint32_t>(b.data() + headerField::headerCrc, crc32(std::span(b).first(headerField::headerCrc)));
  std::size_t off = kHeaderBytes;
  while (off + kRecordHeadBytes <= b.size()) {
    std::byte* r = b.data() + off;
    const std::uint32_t n = loadLE<std::uint32_t>(r + headField::payloadBytes);
    const bool fits = n <= kMaxPayloadBytes && n <= b.size() - off - kRecordHeadBytes;
    if (fits) storeLE<std::uint32_t>(r + headField::payloadCrc, crc32(std::span(r + kRecordHeadBytes, n)));
    storeLE<std::uint32_t>(r + headField::headCrc, crc32(std::span(r, headField::headCrc)));
    if (!fits) break;
    off += kRecordHeadBytes + n;
  }
}

std::vector<std::byte> encodeAll(const std::vector<edit::Edit>& edits) {
  std::vector<std::byte> out = encodeHeader();
  for (const edit::Edit& e : edits) {
    if (!encodeRecord(e, kHeaderBytes, out)) __builtin_trap();  // the reader accepted what the writer refuses
  }
  return out;
}

void check(std::span<const std::byte> bytes) {
  if (bytes.size() >= kHeaderBytes) (void)decodeRecord(bytes.subspan(kHeaderBytes), "fuzz", kHeaderBytes);
  const auto j = decodeJournal(bytes, "fuzz");
  if (!j) return;
  if (j->validBytes < kHeaderBytes || j->validBytes > bytes.size() || j->warnings.size() > 1) __builtin_trap();
  if (j->warnings.empty() != (j->validBytes == bytes.size())) __builtin_trap();
  const auto cut = decodeJournal(bytes.first(j->validBytes), "fuzz");
  const auto once = encodeAll(j->edits);
  if (!cut || !cut->warnings.empty() || encodeAll(cut->edits) != once) __builtin_trap();
  const auto again = decodeJournal(once, "fuzz");
  if (!again || !again->warnings.empty() || again->edits.size() != j->edits.size()) __builtin_trap();
  if (encodeAll(again->edits) != once) __builtin_trap();
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  std::vector<std::byte> b(reinterpret_cast<const std::byte*>(data), reinterpret_cast<const std::byte*>(data) + size);
  check(b);
  reseal(b);
  check(b);
  return 0;
}
