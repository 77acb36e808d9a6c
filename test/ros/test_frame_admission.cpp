// Preprocess's admission bookkeeping (ros/frame_admission.h), without a master: admit while
// fewer than the limit are in flight, free a place per answer, give up on a frame after the
// timeout, and match answers by stamp also when stamps repeat or go back.
#include "tabletop_shapes/ros/frame_admission.h"

#include <gtest/gtest.h>

namespace {

using tabletop_shapes::bridge::FrameAdmission;
using Clock = FrameAdmission::Clock;
using std::chrono::milliseconds;

const Clock::time_point t0 = Clock::time_point() + std::chrono::hours(1);

TEST(FrameAdmission, AdmitsUpToTheLimitAndRefusesTheRestUntilOneIsAnswered) {
  FrameAdmission admission(2, 2.0);
  EXPECT_TRUE(admission.admit(1000, t0).admitted);
  const FrameAdmission::Decision second = admission.admit(2000, t0 + milliseconds(33));
  EXPECT_TRUE(second.admitted);
  EXPECT_EQ(second.in_flight, 1u);
  const FrameAdmission::Decision third = admission.admit(3000, t0 + milliseconds(66));
  EXPECT_FALSE(third.admitted);
  EXPECT_EQ(third.in_flight, 2u);
  EXPECT_TRUE(third.timed_out_stamps_us.empty());
  EXPECT_EQ(admission.inFlight(), 2u);

  EXPECT_TRUE(admission.answered(1000));
  EXPECT_EQ(admission.inFlight(), 1u);
  EXPECT_TRUE(admission.admit(4000, t0 + milliseconds(100)).admitted);
  EXPECT_FALSE(admission.admit(5000, t0 + milliseconds(133)).admitted);
}

TEST(FrameAdmission, AnswersToFramesNeverAdmittedChangeNothing) {
  FrameAdmission admission(1, 2.0);
  ASSERT_TRUE(admission.admit(1000, t0).admitted);
  ASSERT_FALSE(admission.admit(2000, t0 + milliseconds(33)).admitted);
  // The refused frame's own "chain busy" answer comes back on `objects`: not the admitted one.
  EXPECT_FALSE(admission.answered(2000));
  EXPECT_EQ(admission.inFlight(), 1u);
  EXPECT_TRUE(admission.answered(1000));
  EXPECT_FALSE(admission.answered(1000)) << "answered twice";
  EXPECT_EQ(admission.inFlight(), 0u);
}

TEST(FrameAdmission, AFrameNeverAnsweredIsGivenUpAfterTheTimeout) {
  FrameAdmission admission(1, 0.5);
  ASSERT_TRUE(admission.admit(1000, t0).admitted);
  // Within the timeout the chain is busy.
  EXPECT_FALSE(admission.admit(2000, t0 + milliseconds(499)).admitted);
  const FrameAdmission::Decision late = admission.admit(3000, t0 + milliseconds(501));
  EXPECT_TRUE(late.admitted);
  EXPECT_EQ(late.in_flight, 0u);
  ASSERT_EQ(late.timed_out_stamps_us.size(), 1u);
  EXPECT_EQ(late.timed_out_stamps_us[0], 1000u);
  // An answer after the give-up frees nothing: the place went to frame 3000.
  EXPECT_FALSE(admission.answered(1000));
  EXPECT_EQ(admission.inFlight(), 1u);
}

TEST(FrameAdmission, OnlyTheFramesOlderThanTheTimeoutAreGivenUp) {
  FrameAdmission admission(3, 1.0);
  ASSERT_TRUE(admission.admit(1000, t0).admitted);
  ASSERT_TRUE(admission.admit(2000, t0 + milliseconds(300)).admitted);
  ASSERT_TRUE(admission.admit(3000, t0 + milliseconds(600)).admitted);
  const FrameAdmission::Decision decision = admission.admit(4000, t0 + milliseconds(1400));
  EXPECT_EQ(decision.timed_out_stamps_us, (std::vector<uint64_t>{1000, 2000}));
  EXPECT_TRUE(decision.admitted);
  EXPECT_EQ(admission.inFlight(), 2u);  // 3000 and 4000
  EXPECT_TRUE(admission.answered(3000));
  EXPECT_TRUE(admission.answered(4000));
}

TEST(FrameAdmission, RepeatedStampsAreAnsweredOneByOne) {
  FrameAdmission admission(2, 2.0);
  ASSERT_TRUE(admission.admit(7000, t0).admitted);
  ASSERT_TRUE(admission.admit(7000, t0 + milliseconds(33)).admitted);
  EXPECT_TRUE(admission.answered(7000));
  EXPECT_EQ(admission.inFlight(), 1u);
  EXPECT_TRUE(admission.answered(7000));
  EXPECT_FALSE(admission.answered(7000));
}

TEST(FrameAdmission, StampsGoingBackAreMatchedAsAnyOther) {
  // A bag played in a loop: the stamps jump back 30 s between two frames in flight.
  FrameAdmission admission(2, 2.0);
  ASSERT_TRUE(admission.admit(40'000'000, t0).admitted);
  ASSERT_TRUE(admission.admit(10'000'000, t0 + milliseconds(33)).admitted);
  EXPECT_TRUE(admission.answered(10'000'000));
  EXPECT_TRUE(admission.answered(40'000'000));
  EXPECT_EQ(admission.inFlight(), 0u);
}

TEST(FrameAdmission, NoLimitAdmitsEveryFrameAndTracksNone) {
  FrameAdmission admission(0, 0.1);
  for (int i = 0; i < 100; ++i) {
    const FrameAdmission::Decision decision = admission.admit(i, t0 + milliseconds(33 * i));
    EXPECT_TRUE(decision.admitted);
    EXPECT_TRUE(decision.timed_out_stamps_us.empty());
  }
  EXPECT_EQ(admission.inFlight(), 0u);
}

TEST(FrameAdmission, ALowerLimitTakesEffectWhenPlacesAreFreed) {
  FrameAdmission admission(3, 2.0);
  ASSERT_TRUE(admission.admit(1000, t0).admitted);
  ASSERT_TRUE(admission.admit(2000, t0).admitted);
  admission.setLimits(1, 2.0);
  EXPECT_FALSE(admission.admit(3000, t0).admitted);
  EXPECT_TRUE(admission.answered(1000));
  EXPECT_FALSE(admission.admit(4000, t0).admitted) << "2000 still in flight, limit 1";
  EXPECT_TRUE(admission.answered(2000));
  EXPECT_TRUE(admission.admit(5000, t0).admitted);
}

TEST(FrameAdmission, StampsAreMatchedInWholeMicroseconds) {
  // The input's stamp in ns; the later stages' PCL headers carry whole microseconds.
  EXPECT_EQ(FrameAdmission::stampMicroseconds(1'700'000'000'123'456'789ull),
            1'700'000'000'123'456ull);
}

TEST(FrameAdmission, TheBusyReasonNamesTheFramesInFlight) {
  using tabletop_shapes::bridge::chainBusyReason;
  using tabletop_shapes::bridge::isChainBusyReason;
  EXPECT_EQ(chainBusyReason(1), "skipped: chain busy (1 frame in flight)");
  EXPECT_EQ(chainBusyReason(2), "skipped: chain busy (2 frames in flight)");
  EXPECT_TRUE(isChainBusyReason(chainBusyReason(3)));
  EXPECT_FALSE(isChainBusyReason("no table: no plane"));
  EXPECT_FALSE(isChainBusyReason(""));
}

// A stage in the manager frees the place before publishing; the same answer heard on the topic
// afterwards must not free a second frame with the same stamp (a looped bag repeats stamps).
TEST(FrameAdmission, AnAnswerCountedInProcessIsNotCountedAgainOnTheTopic) {
  FrameAdmission admission(2, 2.0);
  ASSERT_TRUE(admission.admit(7000, t0).admitted);
  ASSERT_TRUE(admission.admit(7000, t0 + milliseconds(33)).admitted);
  EXPECT_TRUE(admission.answeredInProcess(7000));
  EXPECT_EQ(admission.inFlight(), 1u);
  EXPECT_FALSE(admission.answered(7000)) << "the topic copy of the answer already counted";
  EXPECT_EQ(admission.inFlight(), 1u);
  EXPECT_TRUE(admission.answered(7000)) << "the second frame's own answer, heard on the topic";
  EXPECT_EQ(admission.inFlight(), 0u);
  // An in-process answer to a frame never admitted is no answer to count later either.
  EXPECT_FALSE(admission.answeredInProcess(8000));
  ASSERT_TRUE(admission.admit(8000, t0 + milliseconds(66)).admitted);
  EXPECT_TRUE(admission.answered(8000));
}

TEST(FrameAdmission, TheRegistryFreesThePlaceOfAdmissionsOnTheAnswersTopicOnly) {
  using tabletop_shapes::bridge::frameAnsweredInProcess;
  using tabletop_shapes::bridge::registerAdmission;
  using tabletop_shapes::bridge::unregisterAdmission;
  FrameAdmission chain(1, 2.0), other_chain(1, 2.0);
  registerAdmission("/tabletop_shapes/objects", &chain);
  registerAdmission("/other/objects", &other_chain);
  ASSERT_TRUE(chain.admit(1000, t0).admitted);
  ASSERT_TRUE(other_chain.admit(1000, t0).admitted);
  frameAnsweredInProcess("/tabletop_shapes/objects", 1000);
  EXPECT_EQ(chain.inFlight(), 0u);
  EXPECT_EQ(other_chain.inFlight(), 1u) << "another chain's answers topic";
  EXPECT_TRUE(chain.admit(2000, t0 + milliseconds(33)).admitted) << "the next frame at once";
  unregisterAdmission("/tabletop_shapes/objects", &chain);
  frameAnsweredInProcess("/tabletop_shapes/objects", 2000);
  EXPECT_EQ(chain.inFlight(), 1u) << "unregistered: answers reach it by the topic only";
  unregisterAdmission("/other/objects", &other_chain);
}

}  // namespace
