// §2.1 preprocessing: flying pixels of organised clouds and the maximum range, then a voxel grid
// whose voxels become their centroid.
#pragma once

#include "tabletop_shapes/core/types.h"

namespace tabletop_shapes {

// Reusable: keeps its buffers between frames, so a per-frame call does not reallocate.
class Preprocessor {
 public:
  explicit Preprocessor(const PreprocessParams& params = {}) : params_(params) {}
  void setParams(const PreprocessParams& params) { params_ = params; }
  const PreprocessParams& params() const { return params_; }

  // Organised or not; NaN / inf points are skipped without copying the input.
  // `out` is unorganised (height 1), dense, keeps the input's header.
  void apply(const pcl::PointCloud<pcl::PointXYZ>& in, Cloud& out);
  void apply(const pcl::PointCloud<pcl::PointXYZRGB>& in, Cloud& out);
  void apply(const pcl::PointCloud<pcl::PointXYZRGBA>& in, Cloud& out);

  // Bytes held between frames. A frame far larger than the current one (a burst of millions
  // of points) does not leave its buffers behind: they shrink on the next normal frame.
  size_t bufferBytes() const;

 private:
  template <typename PointT>
  void applyImpl(const pcl::PointCloud<PointT>& in, Cloud& out);
  template <typename PointT>
  void markFlyingPixels(const pcl::PointCloud<PointT>& in);
  void releaseOversizedBuffers(size_t input_points);

  PreprocessParams params_;
  // Open-addressing hash from voxel key to the voxel's running sum; reused between frames.
  struct VoxelSlot {
    uint64_t key;
    uint32_t voxel;  // index into sums_
  };
  struct VoxelSum {
    uint64_t key;
    double x, y, z;
    uint32_t count;
  };
  std::vector<VoxelSlot> slots_;
  std::vector<VoxelSum> sums_;   // in order of first appearance: deterministic output
  std::vector<uint8_t> flying_;  // per input pixel: 1 = flying pixel; reused between frames
};

}  // namespace tabletop_shapes
