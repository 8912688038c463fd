// core::LockstepRoster and core::LockstepGate: the Simulator's lockstep participants, which
// steps wait for them, the stepping thread's wait for their answers, and the ones dropped for a
// missed step (until they answer again).
#include <gtest/gtest.h>

#include <atomic>
#include <chrono>
#include <string>
#include <thread>
#include <vector>

#include "pedicle_drilling/core/sim/lockstep_roster.hpp"

namespace pc = pedicle_drilling::core;

namespace {
constexpr std::uint64_t kMs = 1000000ULL;  // 1 ms in ns
}  // namespace

TEST(LockstepRoster, EveryStepWaitsUntilAParticipantJoins) {
  pc::LockstepRoster roster;
  EXPECT_EQ(roster.size(), 0u);
  EXPECT_TRUE(roster.wantsStep(1 * kMs));
  EXPECT_TRUE(roster.allAnswered(1 * kMs));  // nobody to wait for
  roster.answer("planner", 1 * kMs, 5 * kMs);
  EXPECT_EQ(roster.size(), 1u);
  EXPECT_FALSE(roster.wantsStep(2 * kMs));
  EXPECT_FALSE(roster.wantsStep(4 * kMs));
  EXPECT_TRUE(roster.wantsStep(5 * kMs));  // its next step
  EXPECT_TRUE(roster.wantsStep(6 * kMs));  // ... or any after it
}

TEST(LockstepRoster, ANextStepOfZeroWantsEveryStep) {
  pc::LockstepRoster roster;
  roster.answer("planner", 1 * kMs, 50 * kMs);
  roster.answer("monitor", 1 * kMs, 0);
  EXPECT_TRUE(roster.wantsStep(2 * kMs));
  roster.answer("monitor", 2 * kMs, 40 * kMs);
  EXPECT_FALSE(roster.wantsStep(3 * kMs));
  EXPECT_TRUE(roster.wantsStep(40 * kMs));
}

TEST(LockstepRoster, AllAnsweredNeedsEachParticipantAtTheStep) {
  pc::LockstepRoster roster;
  roster.answer("a", 3 * kMs, 0);
  roster.answer("b", 2 * kMs, 0);
  EXPECT_TRUE(roster.allAnswered(2 * kMs));
  EXPECT_FALSE(roster.allAnswered(3 * kMs));
  roster.answer("b", 3 * kMs, 0);
  EXPECT_TRUE(roster.allAnswered(3 * kMs));
}

TEST(LockstepRoster, AnOlderAnswerIsIgnored) {
  pc::LockstepRoster roster;
  roster.answer("a", 5 * kMs, 9 * kMs);
  roster.answer("a", 4 * kMs, 0);  // arrives late: neither its step nor its next step count
  EXPECT_TRUE(roster.allAnswered(5 * kMs));
  EXPECT_FALSE(roster.wantsStep(6 * kMs));
  EXPECT_TRUE(roster.wantsStep(9 * kMs));
}

TEST(LockstepRoster, TheSilentAreDroppedUntilTheyAnswerAgain) {
  pc::LockstepRoster roster;
  roster.answer("a", 7 * kMs, 0);
  roster.answer("b", 6 * kMs, 0);
  roster.answer("c", 5 * kMs, 0);
  const std::vector<std::string> dropped = roster.dropSilent(7 * kMs);
  EXPECT_EQ(dropped, (std::vector<std::string>{"b", "c"}));
  EXPECT_EQ(roster.size(), 1u);
  EXPECT_TRUE(roster.allAnswered(7 * kMs));
  EXPECT_TRUE(roster.dropSilent(7 * kMs).empty());
  roster.answer("b", 8 * kMs, 0);  // joins again
  EXPECT_EQ(roster.size(), 2u);
  EXPECT_FALSE(roster.allAnswered(8 * kMs));
}

TEST(LockstepGate, TheWaitEndsWithTheLastAnswer) {
  pc::LockstepGate gate(10.0);
  gate.answer("a", 1 * kMs, 0);
  gate.answer("b", 1 * kMs, 0);
  std::thread answers([&gate] {
    std::this_thread::sleep_for(std::chrono::milliseconds(20));
    gate.answer("a", 2 * kMs, 10 * kMs);
    std::this_thread::sleep_for(std::chrono::milliseconds(20));
    gate.answer("b", 2 * kMs, 10 * kMs);
  });
  const auto start = std::chrono::steady_clock::now();
  const pc::LockstepGate::WaitResult r = gate.wait(2 * kMs, [] { return true; });
  const double waited =
      std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  answers.join();
  EXPECT_FALSE(r.timed_out);
  EXPECT_TRUE(r.dropped.empty());
  EXPECT_LT(waited, 5.0);                 // woken by the answer, not by the 10 s deadline
  EXPECT_FALSE(gate.wantsStep(3 * kMs));  // both asked for the step at 10 ms next
  EXPECT_TRUE(gate.wantsStep(10 * kMs));
}

TEST(LockstepGate, ASilentParticipantIsDroppedAtTheDeadline) {
  pc::LockstepGate gate(0.2);
  gate.answer("a", 1 * kMs, 0);
  gate.answer("b", 1 * kMs, 0);
  gate.answer("a", 2 * kMs, 0);
  const auto start = std::chrono::steady_clock::now();
  const pc::LockstepGate::WaitResult r = gate.wait(2 * kMs, [] { return true; });
  EXPECT_GE(std::chrono::steady_clock::now() - start, std::chrono::milliseconds(200));
  EXPECT_TRUE(r.timed_out);
  EXPECT_EQ(r.dropped, std::vector<std::string>{"b"});
  // The next step waits only for the one left.
  std::thread answer([&gate] { gate.answer("a", 3 * kMs, 0); });
  EXPECT_FALSE(gate.wait(3 * kMs, [] { return true; }).timed_out);
  answer.join();
}

TEST(LockstepGate, AShutdownEndsTheWaitDroppingNobody) {
  pc::LockstepGate gate(30.0);
  gate.answer("a", 1 * kMs, 0);
  std::atomic<bool> running{true};
  std::thread stop([&gate, &running] {
    std::this_thread::sleep_for(std::chrono::milliseconds(30));
    running = false;
    gate.wake();
  });
  const pc::LockstepGate::WaitResult r = gate.wait(2 * kMs, [&running] { return running.load(); });
  stop.join();
  EXPECT_FALSE(r.timed_out);
  EXPECT_TRUE(r.dropped.empty());
}
