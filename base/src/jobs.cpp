#include "sandtable/base/jobs.h"

#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>
#include <tbb/task_arena.h>

#include <algorithm>
#include <thread>

namespace sandtable::jobs {

int threadCount(int requested) {
  if (requested > 0) return requested;
  return std::max(1, static_cast<int>(std::thread::hardware_concurrency()));
}

namespace {

bool stopped(const std::atomic<bool>* cancel) {
  return cancel && cancel->load(std::memory_order_relaxed);
}

/// A worker limit means an arena of that size; the default arena when the
/// caller wants every core, so nested calls do not oversubscribe.
template <typename F>
void inArena(int threads, F&& f) {
  const int n = threadCount(threads);
  if (n >= tbb::this_task_arena::max_concurrency()) {
    f();
    return;
  }
  tbb::task_arena arena(n);
  arena.execute(f);
}

}  // namespace

void parallelFor(std::size_t n, int threads, const std::function<void(std::size_t)>& body,
                 const std::atomic<bool>* cancel) {
  if (n == 0) return;
  inArena(threads, [&] {
    tbb::parallel_for(
        tbb::blocked_range<std::size_t>(0, n, 1),
        [&](const tbb::blocked_range<std::size_t>& r) {
          for (std::size_t i = r.begin(); i != r.end(); ++i) {
            if (stopped(cancel)) return;
            body(i);
          }
        },
        tbb::simple_partitioner());
  });
}

void parallelRanges(std::size_t n, int threads, std::size_t grain,
                    const std::function<void(std::size_t, std::size_t)>& body,
                    const std::atomic<bool>* cancel) {
  if (n == 0) return;
  inArena(threads, [&] {
    tbb::parallel_for(
        tbb::blocked_range<std::size_t>(0, n, std::max<std::size_t>(1, grain)),
        [&](const tbb::blocked_range<std::size_t>& r) {
          if (!stopped(cancel)) body(r.begin(), r.end());
        },
        tbb::simple_partitioner());
  });
}

}  // namespace sandtable::jobs
