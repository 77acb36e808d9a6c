// A bounded PCD reader for the three encodings PCL writes (ascii, binary, binary_compressed
// with LZF). PCL's own reader trusts the header: a compressed file declaring more points than
// it holds made it read past its buffer, a corrupted size field made it allocate gigabytes, and
// float64 x y z or garbage ASCII lines gave silently wrong clouds. This reader checks every
// declared size against the bytes present before it allocates anything, caps the points, and
// refuses whatever it cannot read exactly, naming the problem.
#pragma once

#include <pcl/point_cloud.h>
#include <pcl/point_types.h>

#include <cstddef>
#include <cstdint>
#include <stdexcept>
#include <string>

namespace tabletop_shapes {

// 3x SXGA (1280 x 1024): far more than any single RGB-D frame, far less than a memory bomb.
constexpr uint64_t kDefaultMaxPoints = 4000000;

struct PcdReadOptions {
  uint64_t max_points = kDefaultMaxPoints;
};

// Why a file was refused; what() names the problem (no path: callers add it).
struct PcdError : std::runtime_error {
  using std::runtime_error::runtime_error;
};

// x y z of a PCD held in memory (float32 or float64; other fields are checked and skipped).
// The cloud keeps WIDTH x HEIGHT; is_dense is false when any point is not finite.
pcl::PointCloud<pcl::PointXYZ> parsePcd(const uint8_t* data, size_t size,
                                        const PcdReadOptions& options = {});

// The same for a file (mapped, not copied: the cap bounds what is allocated).
pcl::PointCloud<pcl::PointXYZ> readPcdFile(const std::string& path,
                                           const PcdReadOptions& options = {});

// LZF (liblzf's format, as PCL writes it): decompresses exactly `out_size` bytes into `out`.
// False when the input is malformed, references outside the output or yields another size.
bool lzfDecompressExact(const uint8_t* in, size_t in_size, uint8_t* out, size_t out_size);

}  // namespace tabletop_shapes
