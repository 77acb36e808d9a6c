// The bounded PCD reader: PCL's own files in every encoding read back exactly, and every defect
// of issue 16 (a compressed file declaring more or fewer points than it holds, corrupted size
// fields, huge POINTS, float64 x y z, garbage ASCII lines, truncation) is refused with its
// reason instead of a heap overread, a memory bomb or a silently wrong cloud.
#include "tabletop_shapes/core/pcd_reader.h"

#include <gtest/gtest.h>
#include <pcl/io/pcd_io.h>

#include <cmath>
#include <cstdio>
#include <cstring>
#include <fstream>
#include <iterator>
#include <random>
#include <string>
#include <unistd.h>

namespace tabletop_shapes {
namespace {

// A 40 x 30 organised XYZRGB cloud with a few NaN points; distinct coordinates per point.
pcl::PointCloud<pcl::PointXYZRGB> sampleCloud() {
  pcl::PointCloud<pcl::PointXYZRGB> cloud(40, 30);
  for (size_t i = 0; i < cloud.size(); ++i) {
    pcl::PointXYZRGB& p = cloud.points[i];
    p.x = 0.001f * i - 0.5f;
    p.y = 0.25f - 0.0005f * i;
    p.z = 1.0f + 0.0001f * i;
    p.r = static_cast<uint8_t>(i);
    if (i % 97 == 5) p.x = p.y = p.z = NAN;
  }
  cloud.is_dense = false;
  return cloud;
}

// `cloud` written by PCL in `encoding` (0 ascii, 1 binary, 2 binary_compressed), as bytes.
std::string pclFile(const pcl::PointCloud<pcl::PointXYZRGB>& cloud, int encoding) {
  char name[] = "/tmp/test_pcd_readerXXXXXX";
  const int fd = mkstemp(name);
  close(fd);
  pcl::PCDWriter writer;
  if (encoding == 0) writer.writeASCII(name, cloud, 8);
  if (encoding == 1) writer.writeBinary(name, cloud);
  if (encoding == 2) writer.writeBinaryCompressed(name, cloud);
  std::ifstream in(name, std::ios::binary);
  std::string bytes((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
  std::remove(name);
  return bytes;
}

pcl::PointCloud<pcl::PointXYZ> parse(const std::string& bytes, PcdReadOptions options = {}) {
  return parsePcd(reinterpret_cast<const uint8_t*>(bytes.data()), bytes.size(), options);
}

// The reason parse() refuses `bytes` with ("" when it reads them).
std::string refusal(const std::string& bytes, PcdReadOptions options = {}) {
  try {
    parse(bytes, options);
  } catch (const PcdError& e) {
    return e.what();
  }
  return "";
}

size_t bodyOffset(const std::string& bytes) {
  const size_t data = bytes.find("\nDATA ");
  return bytes.find('\n', data + 1) + 1;
}

std::string replaceLine(std::string bytes, const std::string& keyword, const std::string& line) {
  const size_t start = bytes.find("\n" + keyword + " ") + 1;
  const size_t end = bytes.find('\n', start);
  return bytes.replace(start, end - start, line);
}

void expectSameXyz(const pcl::PointCloud<pcl::PointXYZRGB>& want,
                   const pcl::PointCloud<pcl::PointXYZ>& got) {
  ASSERT_EQ(got.size(), want.size());
  EXPECT_EQ(got.width, want.width);
  EXPECT_EQ(got.height, want.height);
  EXPECT_FALSE(got.is_dense);
  for (size_t i = 0; i < want.size(); ++i) {
    for (int a = 0; a < 3; ++a) {
      if (std::isnan(want.points[i].data[a])) {
        EXPECT_TRUE(std::isnan(got.points[i].data[a])) << i;
      } else {
        EXPECT_NEAR(got.points[i].data[a], want.points[i].data[a], 1e-6) << "point " << i;
      }
    }
  }
}

TEST(PcdReader, ReadsPclFilesInEveryEncoding) {
  const auto cloud = sampleCloud();
  for (int encoding = 0; encoding < 3; ++encoding) {
    SCOPED_TRACE(encoding);
    expectSameXyz(cloud, parse(pclFile(cloud, encoding)));
  }
}

TEST(PcdReader, ReadsTheBundledScenes) {
  const auto cloud = readPcdFile(std::string(TABLETOP_SHAPES_TEST_DATA) + "/learn0.pcd");
  EXPECT_EQ(cloud.width, 640u);
  EXPECT_EQ(cloud.height, 480u);
  // PCL's reader gives the same points.
  pcl::PointCloud<pcl::PointXYZ> reference;
  ASSERT_EQ(pcl::io::loadPCDFile(std::string(TABLETOP_SHAPES_TEST_DATA) + "/learn0.pcd", reference),
            0);
  ASSERT_EQ(cloud.size(), reference.size());
  size_t finite = 0;
  for (size_t i = 0; i < cloud.size(); ++i) {
    if (!std::isfinite(reference.points[i].z)) continue;
    ++finite;
    ASSERT_EQ(cloud.points[i].getVector3fMap(), reference.points[i].getVector3fMap()) << i;
  }
  EXPECT_GT(finite, 150000u);  // 182,292 of its 307,200 pixels
}

// Finding 1: POINTS doubled in a compressed file made PCL read past its buffer (valgrind:
// 3025 invalid reads, then SIGSEGV, or exit 0 with garbage objects).
TEST(PcdReader, CompressedFileDeclaringMorePointsIsRefused) {
  const auto cloud = sampleCloud();
  std::string bytes = pclFile(cloud, 2);
  bytes = replaceLine(bytes, "HEIGHT", "HEIGHT 60");
  bytes = replaceLine(bytes, "POINTS", "POINTS 2400");
  EXPECT_NE(refusal(bytes).find("decompresses to 19200 bytes, but POINTS 2400"), std::string::npos)
      << refusal(bytes);
}

// Finding 4: fewer points declared than the block holds gave "no table" and exit 0.
TEST(PcdReader, CompressedFileDeclaringFewerPointsIsRefused) {
  std::string bytes = pclFile(sampleCloud(), 2);
  bytes = replaceLine(bytes, "HEIGHT", "HEIGHT 15");
  bytes = replaceLine(bytes, "POINTS", "POINTS 600");
  EXPECT_NE(refusal(bytes).find("decompresses to 19200 bytes, but POINTS 600"), std::string::npos)
      << refusal(bytes);
}

// Finding 2: 9 corrupted bytes in the compressed-size field made PCL allocate 8.2 GB.
TEST(PcdReader, CorruptedCompressedSizeFieldsAreRefusedBeforeAllocating) {
  const std::string bytes = pclFile(sampleCloud(), 2);
  const size_t body = bodyOffset(bytes);
  std::string huge_compressed = bytes;
  std::memset(&huge_compressed[body], 0xff, 4);
  EXPECT_NE(refusal(huge_compressed).find("(truncated)"), std::string::npos)
      << refusal(huge_compressed);
  std::string huge_uncompressed = bytes;
  std::memset(&huge_uncompressed[body + 4], 0xff, 4);
  EXPECT_NE(refusal(huge_uncompressed).find("decompresses to 4294967295 bytes"), std::string::npos);
  std::string corrupt_lzf = bytes;  // a back reference before the start of the output
  corrupt_lzf[body + 8] = static_cast<char>(0xff);
  corrupt_lzf[body + 9] = static_cast<char>(0xff);
  EXPECT_NE(refusal(corrupt_lzf).find("compressed block is corrupt"), std::string::npos)
      << refusal(corrupt_lzf);
  EXPECT_NE(refusal(bytes.substr(0, bytes.size() - 10)).find("truncated"), std::string::npos);
}

// Finding 2: POINTS 99,999,999 cost PCL 3.6 GB (compressed) and 1.24 GB (ascii).
TEST(PcdReader, PointsAboveTheCapAreRefused) {
  for (int encoding = 0; encoding < 3; ++encoding) {
    std::string bytes = pclFile(sampleCloud(), encoding);
    bytes = replaceLine(bytes, "WIDTH", "WIDTH 99999999");
    bytes = replaceLine(bytes, "HEIGHT", "HEIGHT 1");
    bytes = replaceLine(bytes, "POINTS", "POINTS 99999999");
    EXPECT_NE(refusal(bytes).find("POINTS 99999999 is above the limit of 4000000"),
              std::string::npos)
        << refusal(bytes);
  }
  // A lower cap refuses the 1200-point sample; the default reads it.
  const std::string bytes = pclFile(sampleCloud(), 1);
  EXPECT_NE(refusal(bytes, PcdReadOptions{1000}).find("above the limit of 1000"),
            std::string::npos);
  EXPECT_EQ(refusal(bytes), "");
  // Raised past the default, the cap lets through what the data holds, and no more.
  std::string declared = replaceLine(bytes, "WIDTH", "WIDTH 5000000");
  declared = replaceLine(declared, "HEIGHT", "HEIGHT 1");
  declared = replaceLine(declared, "POINTS", "POINTS 5000000");
  EXPECT_NE(refusal(declared, PcdReadOptions{10000000}).find("(truncated)"), std::string::npos);
}

TEST(PcdReader, Float64CoordinatesAreConverted) {
  std::string text =
      "VERSION 0.7\nFIELDS x y z\nSIZE 8 8 8\nTYPE F F F\nCOUNT 1 1 1\nWIDTH 2\nHEIGHT 1\n"
      "POINTS 2\nDATA binary\n";
  const double values[6] = {0.125, -0.5, 1.75, 1e-3, 2.0, 3.5};
  text.append(reinterpret_cast<const char*>(values), sizeof values);
  const auto cloud = parse(text);
  ASSERT_EQ(cloud.size(), 2u);
  EXPECT_FLOAT_EQ(cloud.points[0].x, 0.125f);
  EXPECT_FLOAT_EQ(cloud.points[0].z, 1.75f);
  EXPECT_FLOAT_EQ(cloud.points[1].x, 1e-3f);
  EXPECT_FLOAT_EQ(cloud.points[1].z, 3.5f);
  EXPECT_TRUE(cloud.is_dense);
}

TEST(PcdReader, IntegerCoordinatesAreRefused) {
  const std::string text =
      "FIELDS x y z\nSIZE 2 2 2\nTYPE U U U\nWIDTH 1\nPOINTS 1\nDATA ascii\n1 2 3\n";
  EXPECT_NE(refusal(text).find("field 'x' is not one float (TYPE U, SIZE 2"), std::string::npos)
      << refusal(text);
}

TEST(PcdReader, AsciiGarbageIsRefusedNamingTheLine) {
  const std::string head = "FIELDS x y z\nSIZE 4 4 4\nTYPE F F F\nWIDTH 3\nPOINTS 3\nDATA ascii\n";
  EXPECT_EQ(refusal(head + "0 0 1\n0.5 0 1\n1 0 1\n"), "");
  EXPECT_EQ(refusal(head + "0 0 1\n0.5 0 1\n1 0 1"), "") << "no final newline";
  EXPECT_EQ(refusal(head + "0 0 1\n0.5 zero 1\n1 0 1\n"), "data line 2: 'zero' is not a number");
  EXPECT_EQ(refusal(head + "0 0 1\n0.5 0\n1 0 1\n"), "data line 2: 2 values, a point has 3");
  EXPECT_EQ(refusal(head + "0 0 1\n0.5 0 1 7\n1 0 1\n"),
            "data line 2: more than the 3 values a point has");
  EXPECT_EQ(refusal(head + "0 0 1\n0.5 0 1\n1 0 1\n2 0 1\n"), "more points than POINTS 3 declares");
  EXPECT_EQ(refusal(head + "0 0 1\n0.5 0 1\n\n\n\n"), "POINTS 3 declared, the data holds 2");
}

TEST(PcdReader, HeaderDefectsAreNamed) {
  const std::string ok =
      "FIELDS x y z\nSIZE 4 4 4\nTYPE F F F\nWIDTH 2\nHEIGHT 1\nPOINTS 2\nDATA ascii\n"
      "0 0 1\n0 1 1\n";
  EXPECT_EQ(refusal(ok), "");
  EXPECT_EQ(refusal(replaceLine(ok, "POINTS", "POINTS 3")), "WIDTH 2 x HEIGHT 1 is not POINTS 3");
  EXPECT_EQ(refusal(replaceLine(ok, "SIZE", "SIZE 4 4")), "SIZE has 2 values for 3 fields");
  EXPECT_EQ(refusal(replaceLine(ok, "SIZE", "SIZE 4 4 3")),
            "SIZE of field 'z' is 3, not 1, 2, 4 or 8");
  EXPECT_EQ(refusal(replaceLine(ok, "WIDTH", "WIDTH -2")),
            "WIDTH '-2' is not a non-negative integer");
  EXPECT_EQ(refusal(replaceLine(ok, "FIELDS", "FIELDS x y w")), "no 'z' field");
  EXPECT_EQ(refusal(replaceLine(ok, "DATA", "DATA binary_lz4")),
            "DATA 'binary_lz4' is not ascii, binary or binary_compressed");
  EXPECT_EQ(refusal("\x89PNG\r\n\x1a\nrest"),
            "not a PCD header (binary bytes before the DATA line)");
  EXPECT_EQ(refusal(""), "not a PCD header (no DATA line)");
}

TEST(PcdReader, BinaryBodyMustMatchTheDeclaredSize) {
  const std::string bytes = pclFile(sampleCloud(), 1);
  EXPECT_NE(refusal(bytes.substr(0, bytes.size() - 1)).find("(truncated)"), std::string::npos);
  EXPECT_NE(refusal(bytes + "extra").find("binary data of 19205 bytes, but POINTS 1200"),
            std::string::npos)
      << refusal(bytes + "extra");
}

TEST(PcdReader, FileErrorsAreNamed) {
  try {
    readPcdFile("/nonexistent/cloud.pcd");
    FAIL();
  } catch (const PcdError& e) {
    EXPECT_STREQ(e.what(), "No such file or directory");
  }
  EXPECT_THROW(readPcdFile("/tmp"), PcdError);
}

TEST(PcdReader, LzfRoundTripAndBounds) {
  // A literal run of 3 bytes, then a back reference copying them twice (overlapping).
  const uint8_t in[] = {2, 'a', 'b', 'c', (4 << 5), 2};
  uint8_t out[9];
  ASSERT_TRUE(lzfDecompressExact(in, sizeof in, out, sizeof out));
  EXPECT_EQ(std::string(reinterpret_cast<char*>(out), 9), "abcabcabc");
  uint8_t small[8];
  EXPECT_FALSE(lzfDecompressExact(in, sizeof in, small, sizeof small)) << "output too small";
  uint8_t large[10];
  EXPECT_FALSE(lzfDecompressExact(in, sizeof in, large, sizeof large)) << "output not filled";
  EXPECT_FALSE(lzfDecompressExact(in, 5, out, sizeof out)) << "reference cut off";
  const uint8_t before_start[] = {0, 'a', (1 << 5), 5};
  EXPECT_FALSE(lzfDecompressExact(before_start, sizeof before_start, out, 4));
}

// Random byte flips of valid files: each is read or refused, never a crash (ASan in
// make test-sanitize turns an overread into a failure).
TEST(PcdReader, RandomCorruptionIsReadOrRefused) {
  std::mt19937 random(16);
  int refused = 0, read = 0;
  for (int encoding = 0; encoding < 3; ++encoding) {
    const std::string bytes = pclFile(sampleCloud(), encoding);
    for (int trial = 0; trial < 300; ++trial) {
      std::string corrupt = bytes;
      const int flips = 1 + trial % 8;
      for (int k = 0; k < flips; ++k) {
        corrupt[random() % corrupt.size()] = static_cast<char>(random());
      }
      try {
        const auto cloud = parse(corrupt);
        EXPECT_LE(cloud.size(), kDefaultMaxPoints);
        ++read;
      } catch (const PcdError&) {
        ++refused;
      }
    }
  }
  EXPECT_EQ(read + refused, 900);
  EXPECT_GT(refused, 100);
}

}  // namespace
}  // namespace tabletop_shapes
