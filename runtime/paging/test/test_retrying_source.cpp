// RetryingSource (retrying_source.h): a failed module's generation is
// bumped once its pause has passed, so the pager reloads it; the pause
// doubles while it keeps failing; a read that succeeds forgets it; a
// missing module is never tried again.
#include <gtest/gtest.h>

#include <atomic>
#include <chrono>
#include <thread>

#include "sandtable/paging/retrying_source.h"

namespace sandtable::paging {
namespace {

/// Fails every read while `down`; module (9, 9) is missing.
class FlakySource final : public ModuleSource {
 public:
  const pack::IndexHeader& header() const override { return header_; }
  ModuleInfo info(std::uint32_t, std::uint32_t) const override { return {}; }
  std::uint64_t generation(std::uint32_t, std::uint32_t) const override { return 0; }
  Result<std::uint64_t> read(std::uint32_t kx, std::uint32_t kz, module::Module&) const override {
    if (down || missing(kx, kz)) return Problem{"flaky", 0, "down"};
    return std::uint64_t{0};
  }
  bool missing(std::uint32_t kx, std::uint32_t kz) const override { return kx == 9 && kz == 9; }
  std::uint64_t changes() const override { return 0; }
  std::uint64_t changedSince(std::uint64_t since, std::vector<ModuleKey>&) const override { return since; }
  std::atomic<bool> down{true};

 private:
  pack::IndexHeader header_;
};

void sleepSeconds(double s) { std::this_thread::sleep_for(std::chrono::duration<double>(s)); }

TEST(RetryingSource, aFailedModuleComesDueAfterItsPauseAndIsReadAgainWhenTheSourceIsBack) {
  auto inner = std::make_shared<FlakySource>();
  RetryingSource src(inner, {.firstPauseSeconds = 0.3, .maxPauseSeconds = 1.2});
  module::Module m;
  EXPECT_FALSE(src.read(1, 2, m).ok());
  EXPECT_FALSE(src.readCoarse(9, 9, m).ok());  // missing: not retried
  EXPECT_EQ(src.failing(), 1u);
  EXPECT_EQ(src.changes(), 0u) << "due before its pause";
  EXPECT_EQ(src.generation(1, 2), 0u);
  sleepSeconds(0.35);
  EXPECT_EQ(src.changes(), 1u);
  std::vector<ModuleKey> changed;
  EXPECT_EQ(src.changedSince(0, changed), 1u);
  ASSERT_EQ(changed.size(), 1u);
  EXPECT_EQ(changed[0], (ModuleKey{1, 2}));
  EXPECT_EQ(src.generation(1, 2), 1u);
  EXPECT_EQ(src.generation(9, 9), 0u);
  EXPECT_EQ(src.changes(), 1u) << "promoted once per pause";

  // Still down: the retry fails, and the next pause is twice as long.
  EXPECT_FALSE(src.read(1, 2, m).ok());
  sleepSeconds(0.35);
  EXPECT_EQ(src.changes(), 1u) << "the second pause is 0.6 s";
  sleepSeconds(0.35);
  EXPECT_EQ(src.changes(), 2u);
  EXPECT_EQ(src.generation(1, 2), 2u);

  // Back: the read returns the module's generation now, and it is forgotten.
  inner->down = false;
  auto r = src.read(1, 2, m);
  ASSERT_TRUE(r.ok()) << r.error();
  EXPECT_EQ(r.value(), 2u);
  EXPECT_EQ(src.failing(), 0u);
  sleepSeconds(1.3);
  EXPECT_EQ(src.changes(), 2u) << "a module read well is not bumped again";
  changed.clear();
  EXPECT_EQ(src.changedSince(1, changed), 2u);
  EXPECT_EQ(changed.size(), 1u);
}

}  // namespace
}  // namespace sandtable::paging
