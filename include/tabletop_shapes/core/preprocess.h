// §2.1 preprocessing: maximum range, then a voxel grid whose voxels become their centroid.
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

 private:
  template <typename PointT>
  void applyImpl(const pcl::PointCloud<PointT>& in, Cloud& out);

  PreprocessParams params_;
  struct VoxelEntry;
  std::vector<VoxelEntry> voxels_;                      // valid points' voxels, reused
  std::vector<std::pair<uint64_t, uint32_t>> keyed_;    // (voxel key, point index), reused
  std::vector<std::pair<uint64_t, uint32_t>> scratch_;  // radix sort buffer, reused
};

}  // namespace tabletop_shapes
