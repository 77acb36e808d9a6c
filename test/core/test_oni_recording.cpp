// The .oni checks the driver runs before OpenNI2 opens a recording (core/oni_recording.h), on
// recordings written by the sim library's writer and then damaged as a disk, a copy or a user
// would: deleted, truncated, overwritten, replaced by another kind of file.
#include "tabletop_shapes/core/oni_recording.h"

#include "small_recording.h"

#include <gtest/gtest.h>

#include <cstdio>
#include <fstream>
#include <iterator>
#include <string>
#include <unistd.h>
#include <vector>

namespace tabletop_shapes {
namespace {

class OniRecordingTest : public ::testing::Test {
 protected:
  void SetUp() override { ASSERT_GT(bytes_.size(), 3000u); }
  testing_support::SmallRecordingFile recording_{"test_oni_recording"};
  const std::string& path_ = recording_.path;
  std::string bytes_ = recording_.bytes;  // a copy the tests damage
};

TEST_F(OniRecordingTest, AWholeRecordingHasNoProblem) { EXPECT_EQ(oniRecordingProblem(path_), ""); }

TEST_F(OniRecordingTest, ADeletedRecordingIsNamed) {
  std::remove(path_.c_str());
  EXPECT_EQ(oniRecordingProblem(path_), "recording " + path_ + " does not exist or cannot be read");
}

TEST_F(OniRecordingTest, ATruncatedRecordingSaysWhereItEnds) {
  recording_.write(bytes_.substr(0, 3000));
  const std::string problem = oniRecordingProblem(path_);
  EXPECT_EQ(
      problem.rfind("recording " + path_ + " is truncated: it ends at byte 3000 inside record ", 0),
      0u)
      << problem;
}

TEST_F(OniRecordingTest, ARecordingWithoutItsEndRecordIsTruncated) {
  // The last record is END (28 bytes, no payload): a copy stopped just before it.
  recording_.write(bytes_.substr(0, bytes_.size() - 28));
  EXPECT_NE(oniRecordingProblem(path_).find("is truncated"), std::string::npos);
}

TEST_F(OniRecordingTest, AnOverwrittenRecordIsDamagedAtItsOffset) {
  bytes_.replace(24, 4, "JUNK");  // the first record's magic, right after the 24-byte header
  recording_.write(bytes_);
  EXPECT_EQ(oniRecordingProblem(path_),
            "recording " + path_ + " is damaged: no valid record at byte 24");
}

TEST_F(OniRecordingTest, ARecordingReplacedByAnotherFileIsNotAnOni) {
  recording_.write("# .PCD v0.7\nVERSION 0.7\nFIELDS x y z\n");
  EXPECT_EQ(oniRecordingProblem(path_),
            "recording " + path_ + " is not an .oni file (37 bytes, no NI10 header)");
  recording_.write("");
  EXPECT_EQ(oniRecordingProblem(path_),
            "recording " + path_ + " is not an .oni file (0 bytes, no NI10 header)");
}

TEST_F(OniRecordingTest, ARecordingReplacedByAWholeOneIsFineAgain) {
  recording_.write(bytes_.substr(0, 100));
  EXPECT_NE(oniRecordingProblem(path_), "");
  recording_.write(bytes_);
  EXPECT_EQ(oniRecordingProblem(path_), "");
}

TEST_F(OniRecordingTest, AnUnendingChainOfRecordsIsWalkedInBoundedSteps) {
  // Record headers that claim a header size below 28 bytes would never advance.
  bytes_.replace(24 + 12, 4, std::string("\x04\x00\x00\x00", 4));
  recording_.write(bytes_);
  EXPECT_NE(oniRecordingProblem(path_).find("is damaged: no valid record at byte 24"),
            std::string::npos);
}

TEST(LooksLikeRecording, ByItsSuffixInAnyCase) {
  EXPECT_TRUE(looksLikeRecording("/data/scene.oni"));
  EXPECT_TRUE(looksLikeRecording("scene.ONI"));
  EXPECT_FALSE(looksLikeRecording(".oni"));  // a suffix alone names no file
  EXPECT_FALSE(looksLikeRecording("#1"));
  EXPECT_FALSE(looksLikeRecording("1d27/0601@2/5"));
  EXPECT_FALSE(looksLikeRecording(""));
}

}  // namespace
}  // namespace tabletop_shapes
