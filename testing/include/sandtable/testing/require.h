#pragma once
// What a test needs from the machine (../shared/data, headless GL, Xvfb,
// ffmpeg), asked for in one place. On a developer's machine a missing need
// skips the test, so a checkout without the data still runs everything
// else. Under CI (.ci/run exports SANDTABLE_REQUIRE_ALL=1) the same test
// FAILS, naming what is missing: a test there can never pass by not running.
// Every test that would skip goes through SANDTABLE_REQUIRE; `git grep
// GTEST_SKIP` finds only this file.
//
// Thread safety: reads the environment; call from the test's thread.
#include <gtest/gtest.h>

#include <cstdlib>
#include <string_view>

namespace sandtable::testsupport {

/// True when SANDTABLE_REQUIRE_ALL is "1": a missing need fails the test.
inline bool requireAll() {
  const char* v = std::getenv("SANDTABLE_REQUIRE_ALL");
  return v != nullptr && std::string_view(v) == "1";
}

}  // namespace sandtable::testsupport

/// Skips the test (or, under SANDTABLE_REQUIRE_ALL=1, fails it) unless
/// `cond` holds. `what` is streamed into the message: what is missing and
/// where, e.g. "headless GL: " << why. Returns from the calling function, as
/// GTEST_SKIP and GTEST_FAIL do: use it in a test body or SetUp.
#define SANDTABLE_REQUIRE(cond, what)                                                                  \
  do {                                                                                                 \
    if (!(cond)) {                                                                                     \
      if (::sandtable::testsupport::requireAll()) {                                                    \
        GTEST_FAIL() << "required but missing: " << what                                               \
                     << " (SANDTABLE_REQUIRE_ALL=1: every test must run here; install it or unset it)"; \
      }                                                                                                \
      GTEST_SKIP() << "missing: " << what << " (set SANDTABLE_REQUIRE_ALL=1 to fail instead)";         \
    }                                                                                                  \
  } while (0)
