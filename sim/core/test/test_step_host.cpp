// The one fixed-step runner: hooks in order once per step, pacing on an
// injected clock (no sleeps), cancellation within one step, and one rule
// for how many steps a duration is.
#include <gtest/gtest.h>

#include <cmath>
#include <limits>
#include <string>
#include <vector>

#include "sandtable/sim/simulation.h"
#include "sandtable/sim/step_host.h"
#include "sim_fixture.h"

namespace sandtable::sim {
namespace {

/// A clock that jumps where a real one would sleep, and counts.
class FakeClock final : public PaceClock {
 public:
  double nowS() override {
    ++reads;
    return now;
  }
  void sleepUntilS(double s) override {
    sleeps.push_back(s);
    if (s > now) now = s;
    if (onSleep) onSleep();
  }
  double now = 100;  // an arbitrary origin
  int reads = 0;
  std::vector<double> sleeps;
  std::function<void()> onSleep;
};

Simulation flatSimulation() {
  Simulation sim(test::makeWorld([](double, double) { return 20.0; }));
  Entity e;
  e.name = "tank";
  e.position = {1000, 0, 1000};
  e.speedMs = 5;
  e.autopilot = true;
  EXPECT_TRUE(sim.add(e));
  return sim;
}

TEST(StepHost, hooksRunInTheOrderAddedOncePerStepAroundIt) {
  Simulation sim = flatSimulation();
  StepHost host(sim);
  std::vector<std::string> log;
  auto hook = [&](const char* name) {
    return [&log, name](Simulation& s) { log.push_back(std::string(name) + std::to_string(s.steps())); };
  };
  host.addBeforeStep(hook("b1@"));
  host.addBeforeStep(hook("b2@"));
  host.addAfterStep(hook("a1@"));
  host.addAfterStep(hook("a2@"));
  const StepRun run = host.runToStep(3);
  EXPECT_EQ(run.steps, 3u);
  EXPECT_FALSE(run.cancelled);
  // Before-hooks see the step's start (k steps taken), after-hooks its end.
  const std::vector<std::string> want = {"b1@0", "b2@0", "a1@1", "a2@1", "b1@1", "b2@1",
                                         "a1@2", "a2@2", "b1@2", "b2@2", "a1@3", "a2@3"};
  EXPECT_EQ(log, want);
  host.step();  // one step by hand goes through the hooks too
  EXPECT_EQ(log.size(), want.size() + 4);
  EXPECT_EQ(host.runToStep(2).steps, 0u);  // already past: nothing
  EXPECT_EQ(sim.steps(), 4u);
}

TEST(StepHost, asFastAsPossibleNeverReadsTheClock) {
  Simulation sim = flatSimulation();
  FakeClock clock;
  StepHost host(sim);
  host.setPacing(Pacing::asFastAsPossible, &clock);
  EXPECT_EQ(host.runFor(1).steps, 60u);
  EXPECT_EQ(clock.reads, 0);
  EXPECT_TRUE(clock.sleeps.empty());
}

TEST(StepHost, realTimeTakesStepKAtItsEndTimeAndCatchesUpWithoutWaiting) {
  Simulation sim = flatSimulation();
  FakeClock clock;
  StepHost host(sim);
  host.setPacing(Pacing::realTime, &clock);
  const double dt = sim.options().stepS;
  std::vector<double> takenAt;
  host.addBeforeStep([&](Simulation&) { takenAt.push_back(clock.now); });
  // Step 2 takes 0.51 s of wall time (30.6 steps): the next steps are
  // late and run at once until the run is back on time.
  host.addAfterStep([&](Simulation& s) {
    if (s.steps() == 3) clock.now += 0.51;
  });
  const StepRun run = host.runFor(1);
  ASSERT_EQ(run.steps, 60u);
  ASSERT_EQ(takenAt.size(), 60u);
  const double start = 100;
  const double late = start + 3 * dt + 0.51;  // the clock when step 2 ended: 33.6 dt
  for (std::size_t k = 0; k < takenAt.size(); ++k) {
    const double due = start + double(k + 1) * dt;  // hand-worked: step k ends at (k + 1) dt
    if (k < 3) {
      EXPECT_DOUBLE_EQ(takenAt[k], due) << k;
    } else if (due <= late) {
      EXPECT_DOUBLE_EQ(takenAt[k], late) << k;  // behind: no wait
    } else {
      EXPECT_DOUBLE_EQ(takenAt[k], due) << k;
    }
  }
  // It waited only for the steps not yet due: 0, 1, 2, then 33..59 (step
  // k ends at (k + 1) dt; steps 3..32 end before 33.6 dt and ran at once).
  EXPECT_EQ(clock.sleeps.size(), 3u + 27u);
  EXPECT_DOUBLE_EQ(clock.now, start + 60 * dt);
}

TEST(StepHost, aCancelSetInAHookStopsTheRunBeforeTheNextStep) {
  Simulation sim = flatSimulation();
  StepHost host(sim);
  std::atomic<bool> cancel{false};
  host.setCancel(&cancel);
  host.addAfterStep([&](Simulation& s) {
    if (s.steps() == 5) cancel = true;
  });
  const StepRun run = host.runFor(10);
  EXPECT_TRUE(run.cancelled);
  EXPECT_EQ(run.steps, 5u);
  EXPECT_EQ(sim.steps(), 5u);
  // Set before a run starts: no step at all.
  const StepRun again = host.runFor(10);
  EXPECT_TRUE(again.cancelled);
  EXPECT_EQ(again.steps, 0u);
  cancel = false;
  EXPECT_EQ(host.runFor(0.5).steps, 30u);
}

TEST(StepHost, aCancelWhilePacedWaitingTakesNoFurtherStep) {
  Simulation sim = flatSimulation();
  FakeClock clock;
  std::atomic<bool> cancel{false};
  clock.onSleep = [&] {
    if (clock.sleeps.size() == 4) cancel = true;  // Ctrl-C during the fourth wait
  };
  StepHost host(sim);
  host.setPacing(Pacing::realTime, &clock);
  host.setCancel(&cancel);
  const StepRun run = host.runFor(10);
  EXPECT_TRUE(run.cancelled);
  EXPECT_EQ(run.steps, 3u);
  EXPECT_EQ(sim.steps(), 3u);
}

TEST(StepHost, aDurationIsRoundSecondsOverTheStep) {
  Simulation sim = flatSimulation();
  StepHost host(sim);
  EXPECT_EQ(host.stepsFor(120), 7200u);
  EXPECT_EQ(host.stepsFor(1.01), 61u);  // 60.6 steps
  EXPECT_EQ(host.stepsFor(1.0 / 120.0), 1u);  // half a step rounds up
  EXPECT_EQ(host.stepsFor(0), 0u);
  EXPECT_EQ(host.stepsFor(-3), 0u);
  EXPECT_EQ(host.stepsFor(std::numeric_limits<double>::quiet_NaN()), 0u);
  EXPECT_EQ(host.stepsFor(std::numeric_limits<double>::infinity()), 0u);
  // Simulation::runFor is the host without hooks.
  sim.runFor(1.01);
  EXPECT_EQ(sim.steps(), 61u);
}

}  // namespace
}  // namespace sandtable::sim
