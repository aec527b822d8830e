// DiskCachedRange (disk_cache.h): bytes read once come from the local file
// after; the bound holds; refresh() drops blocks; a new build's cache starts
// empty and removes the old files.
#include <gtest/gtest.h>
#include <unistd.h>

#include <atomic>
#include <filesystem>
#include <vector>

#include "sandtable/paging/disk_cache.h"

namespace sandtable::paging {
namespace {

namespace fs = std::filesystem;

/// Bytes in memory, counting what is read.
class MemoryRange final : public RangeSource {
 public:
  explicit MemoryRange(std::size_t n) : bytes_(n) {
    for (std::size_t k = 0; k < n; ++k) bytes_[k] = std::byte(k * 7 + k / 251);
  }
  const std::string& name() const override { return name_; }
  std::uint64_t size() const override { return bytes_.size(); }
  Status read(std::uint64_t offset, std::span<std::byte> out) const override {
    if (offset > bytes_.size() || out.size() > bytes_.size() - offset) return Problem{name_, offset, "past the end"};
    std::copy_n(bytes_.begin() + std::ptrdiff_t(offset), out.size(), out.begin());
    readBytes += out.size();
    return {};
  }
  std::vector<std::byte> bytes_;
  mutable std::atomic<std::uint64_t> readBytes{0};

 private:
  std::string name_ = "memory";
};

std::string tempDir() {
  const fs::path p = fs::temp_directory_path() / ("sandtable-disk-cache." + std::to_string(::getpid()));
  fs::remove_all(p);
  return p.string();
}

TEST(DiskCachedRange, readsOnceThenFromDiskWithinItsBound) {
  const std::string dir = tempDir();
  auto mem = std::make_shared<MemoryRange>(100'000);
  const DiskCacheOptions o{.maxBytes = 3 * 4096, .blockBytes = 4096};
  {
    auto c = DiskCachedRange::open(mem, dir, "modules.pack", 0x1234, o);
    ASSERT_TRUE(c.ok()) << c.error();
    std::vector<std::byte> out(5000);
    ASSERT_TRUE(c.value()->read(1000, out).ok());
    EXPECT_TRUE(std::equal(out.begin(), out.end(), mem->bytes_.begin() + 1000));
    EXPECT_EQ(mem->readBytes.load(), 8192u);  // blocks 0 and 1, in one read
    ASSERT_TRUE(c.value()->read(2000, out).ok());
    EXPECT_EQ(mem->readBytes.load(), 8192u) << "a second read of cached blocks asked the source";
    EXPECT_TRUE(std::equal(out.begin(), out.end(), mem->bytes_.begin() + 2000));
    // Past the bound (3 blocks): older blocks are evicted.
    ASSERT_TRUE(c.value()->read(50'000, out).ok());
    ASSERT_TRUE(c.value()->read(90'000, out).ok());
    EXPECT_LE(c.value()->stats().residentBlocks, 3u);
    EXPECT_GT(c.value()->stats().evictedBlocks, 0u);
    // refresh() drops the blocks: the next read asks the source again.
    const std::uint64_t before = mem->readBytes.load();
    c.value()->refresh(90'000, 10);
    ASSERT_TRUE(c.value()->read(90'000, out).ok());
    EXPECT_GT(mem->readBytes.load(), before);
    EXPECT_TRUE(std::equal(out.begin(), out.end(), mem->bytes_.begin() + 90'000));
  }
  {
    // Reopened: what is on disk is still there (another process, a later run).
    mem->readBytes = 0;
    auto c = DiskCachedRange::open(mem, dir, "modules.pack", 0x1234, o);
    ASSERT_TRUE(c.ok());
    std::vector<std::byte> out(100);
    ASSERT_TRUE(c.value()->read(90'000, out).ok());
    EXPECT_EQ(mem->readBytes.load(), 0u);
  }
  {
    // Another build (another CRC): an empty cache; the old files are gone.
    auto c = DiskCachedRange::open(mem, dir, "modules.pack", 0x9999, o);
    ASSERT_TRUE(c.ok());
    EXPECT_EQ(c.value()->stats().residentBlocks, 0u);
    int files = 0;
    for (const auto& e : fs::directory_iterator(dir)) files += e.path().string().find("1234") == std::string::npos;
    EXPECT_EQ(files, 2);
    for (const auto& e : fs::directory_iterator(dir)) EXPECT_EQ(e.path().string().find("00001234"), std::string::npos);
  }
  fs::remove_all(dir);
}

}  // namespace
}  // namespace sandtable::paging
