// validatePack (pack.h): every byte of modules.idx and modules.pack, with
// at most a few problems of each kind in the report.
#include <algorithm>
#include <map>

#include "pack_internal.h"
#include "sandtable/base/capped_problems.h"
#include "sandtable/formats/bytes.h"

namespace sandtable::pack {
using namespace detail;

namespace {

/// The pack's problems, at most `kPerKind` of each kind listed, so a badly
/// damaged pack gives a readable report.
class Report : public CappedProblems<> {
 public:
  Report() : CappedProblems(kPerKind) {}
  Status take() { return CappedProblems::take("pack"); }

 private:
  static constexpr int kPerKind = 20;
};

struct Placed {
  Extent entry;  ///< the record's extent
  std::uint32_t kx = 0, kz = 0;
  Part part = Part::coarse;
};

}  // namespace

Status validatePack(const std::string& directory, const Work& work) {
  const std::string indexPath = join(directory, kIndexFileName);
  const std::string packPath = join(directory, kPackFileName);
  Report r;
  MappedFile index;
  IndexHeader h;
  bool haveHeader = false;
  if (const Status mapped = index.open(indexPath); !mapped) {
    r.add("index", Problem{indexPath, 0, "pack index: " + mapped.message()});
  } else if (auto dh = decodeIndexHeader(index.bytes(), indexPath, index.size()); !dh) {
    r.add("index", Status(dh.problems()));
  } else {
    h = dh.value();
    haveHeader = true;
  }
  Status packProblems;
  FdGuard pack{openPack(packPath, haveHeader ? &h : nullptr, packProblems)};
  r.add("pack", packProblems);
  if (!haveHeader) return r.take();

  const auto all = index.bytes();
  for (std::size_t k = kIndexHeaderFieldBytes; k < kIndexHeaderBytes; ++k) {
    if (all[k] != std::byte{0}) {
      r.add("index", Problem{indexPath, k, "pack index: header padding is not zero"});
      break;
    }
  }
  r.add("index", checkTableCrc(h, all, indexPath));
  // Reserved header bytes: the CRCs cover them, so only a writer that
  // resealed the CRC can put anything there; v1 and v2 write zeros.
  const std::size_t reservedFrom = h.version >= kVersion2 ? indexField::reservedV2 : indexField::reserved;
  for (std::size_t k = reservedFrom; k < indexField::headerCrc; ++k) {
    if (all[k] != std::byte{0}) {
      r.add("index", Problem{indexPath, k, "pack index: header reserved bytes " + str(reservedFrom) +
                                               "..123 are not zero"});
      break;
    }
  }
  if (pack.fd >= 0) {
    std::array<std::byte, kPackHeaderBytes> head{};
    if (preadAll(pack.fd, head.data(), head.size(), 0)) {
      for (std::size_t k = packField::reserved; k < packField::headerCrc; ++k) {
        if (head[k] != std::byte{0}) {
          r.add("pack", Problem{packPath, k, "pack: header reserved bytes 24..59 are not zero"});
          break;
        }
      }
    }
  }

  // Entries: each on its own, then their placement in the pack.
  std::vector<Placed> placed;
  for (std::uint32_t kz = 0; kz < h.modulesZ; ++kz) {
    for (std::uint32_t kx = 0; kx < h.modulesX; ++kx) {
      const Entry e = decodeEntry(all.subspan(entryOffset(h, kx, kz), h.entryBytes()), h.version);
      bool ok = false;
      r.add("entry", checkEntry(h, e, kx, kz, indexPath, &ok));
      if (h.version >= kVersion2) {
        const std::uint64_t at = entryOffset(h, kx, kz) + entryFieldV2::reserved;
        if (loadLE<std::uint64_t>(all.data() + at) != 0) {
          r.add("entry", Problem{indexPath, at, "pack index: the entry of " + moduleName(kx, kz) +
                                                    " has reserved bytes 56..63 that are not zero"});
        }
      }
      if (!ok) continue;
      placed.push_back({e.coarse(), kx, kz, Part::coarse});
      if (partLevels(h, Part::fine) > 0) placed.push_back({e.fine, kx, kz, Part::fine});
    }
  }
  std::sort(placed.begin(), placed.end(),
            [](const Placed& a, const Placed& b) { return a.entry.offset < b.entry.offset; });
  std::uint64_t covered = kPackHeaderBytes;  // end of the furthest record so far
  const Placed* last = nullptr;
  for (const Placed& p : placed) {
    const std::uint64_t begin = p.entry.offset, end = begin + p.entry.compressedBytes;
    if (begin < covered && last) {
      r.add("overlap",
            Problem{indexPath, entryOffset(h, p.kx, p.kz),
                    "pack index: the record of " + partName(p.kx, p.kz, p.part) + " (bytes " +
                        str(begin) + ".." + str(end - 1) + ") overlaps the record of " +
                        partName(last->kx, last->kz, last->part) + " (bytes " + str(last->entry.offset) +
                        ".." + str(last->entry.offset + last->entry.compressedBytes - 1) + ")"});
    } else if (begin > covered) {
      r.add("gap", Problem{packPath, covered,
                           "pack: bytes " + str(covered) + ".." + str(begin - 1) +
                               " are in no module's record"});
    }
    if (end > covered) {
      covered = end;
      last = &p;
    }
  }
  if (covered < h.packBytes) {
    r.add("gap", Problem{packPath, covered,
                         "pack: bytes " + str(covered) + ".." + str(h.packBytes - 1) +
                             " are in no module's record"});
  }

  // Records, in pack order (sequential reads).
  if (pack.fd < 0) return r.take();
  std::vector<std::byte> record;
  std::size_t done = 0;
  for (const Placed& p : placed) {
    if (done++ % 64 == 0) {
      work.report(double(done - 1) / double(placed.size()), "checking pack");
      if (work.cancelled()) {
        auto out = r.take();
        out.add({packPath, 0, kCancelledMessage});
        return out;
      }
    }
    record.resize(p.entry.compressedBytes);
    if (const Status read = preadAll(pack.fd, record.data(), record.size(), p.entry.offset); !read) {
      r.add("record",
            Problem{packPath, p.entry.offset,
                    "pack: cannot read the record of " + partName(p.kx, p.kz, p.part) + ": " + read.message()});
      continue;
    }
    auto raw = unpackRecord(p.entry, p.kx, p.kz, p.part, record, packPath, true);
    if (!raw) {
      r.add("record", Status(raw.problems()));
      continue;
    }
    auto m = decodeRecord(h, p.entry, p.kx, p.kz, p.part, raw.value(), packPath);
    if (!m) r.add("module", Status(m.problems()));
  }
  work.report(1.0, "checking pack");
  return r.take();
}

}  // namespace sandtable::pack
