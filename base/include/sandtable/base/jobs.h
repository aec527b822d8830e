#pragma once
// The job system: every parallel build stage runs through here, on oneTBB.
// There are no hand-written thread pools in the build. (The pager's four
// directional loaders are dedicated threads by design, seed §7, and are
// not jobs.)
//
// Thread safety: any thread may call these; `body` runs concurrently on up
// to threadCount(threads) workers and must be safe for that. Calls may
// nest: an inner parallelFor shares the outer one's workers.
#include <atomic>
#include <cstddef>
#include <functional>

namespace sandtable::jobs {

/// The number of workers a stage asks for: `requested` when positive,
/// else every hardware thread (at least 1).
int threadCount(int requested);

/// Runs body(i) for every i in [0, n) on up to threadCount(threads)
/// workers, one index per task (build stages have few, heavy items) and
/// returns when all have run. Once `cancel` reads true, indices not yet
/// started are skipped; those already running finish.
void parallelFor(std::size_t n, int threads, const std::function<void(std::size_t)>& body,
                 const std::atomic<bool>* cancel = nullptr);

/// As parallelFor, but hands each worker a contiguous range [begin, end)
/// of about `grain` indices: for many light items (rows, posts).
void parallelRanges(std::size_t n, int threads, std::size_t grain,
                    const std::function<void(std::size_t begin, std::size_t end)>& body,
                    const std::atomic<bool>* cancel = nullptr);

}  // namespace sandtable::jobs
