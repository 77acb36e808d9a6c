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
  // keys_[i]: input point i's voxel key (0 without a voxel grid), kEmpty when it is dropped
  // (not finite, flying pixel, beyond the range). The image is width x height points.
  template <typename PointT>
  void keyPixels(const pcl::PointCloud<PointT>& in, int width, int height, bool drop_flying);
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
  std::vector<VoxelSum> sums_;        // in order of first appearance: deterministic output
  std::vector<uint64_t> keys_;        // per input point (keyPixels); reused between frames
  std::vector<uint32_t> row_voxels_;  // the voxels of the last two image rows' points
};

}  // namespace tabletop_shapes
