// §2.1 preprocessing: flying pixels of organised clouds and the maximum range, then a voxel grid
// whose voxels become their centroid.
#pragma once

#include "tabletop_shapes/core/types.h"
#include "tabletop_shapes/core/view_bounds.h"

namespace tabletop_shapes {

// Reusable: keeps its buffers between frames, so a per-frame call does not reallocate.
class Preprocessor {
 public:
  explicit Preprocessor(const PreprocessParams& params = {}) : params_(params) {}
  void setParams(const PreprocessParams& params) { params_ = params; }
  const PreprocessParams& params() const { return params_; }

  // Organised or not; NaN / inf points are skipped without copying the input.
  // `out` is unorganised (height 1), dense, keeps the input's header. With `view`, also the
  // input's view bounds, as viewBoundsOf gives them, from the same pass over the pixels.
  void apply(const pcl::PointCloud<pcl::PointXYZ>& in, Cloud& out, ViewBounds* view = nullptr);
  void apply(const pcl::PointCloud<pcl::PointXYZRGB>& in, Cloud& out, ViewBounds* view = nullptr);
  void apply(const pcl::PointCloud<pcl::PointXYZRGBA>& in, Cloud& out, ViewBounds* view = nullptr);

  // Bytes held between frames. A frame far larger than the current one (a burst of millions
  // of points) does not leave its buffers behind: they shrink on the next normal frame.
  size_t bufferBytes() const;

 private:
  struct VoxelSum {
    uint64_t key;
    double x, y, z;
    uint32_t count;
  };
  // Open-addressing hash from voxel key to the voxel's running sum; reused between frames.
  class VoxelTable {
   public:
    void clear();  // keeps the last frame's size, so that a frame like it does not grow
    uint32_t voxelOf(uint64_t key);  // inserts a voxel with an empty sum when new
    size_t bytes() const;
    void release();              // gives back a table far larger than its voxels need
    std::vector<VoxelSum> sums;  // in order of first appearance: deterministic output

   private:
    struct Slot {
      uint64_t key;
      uint32_t voxel;  // index into sums
    };
    void grow();
    std::vector<Slot> slots_;
  };
  template <typename PointT>
  void applyImpl(const pcl::PointCloud<PointT>& in, Cloud& out, ViewBounds* view);
  // keys_[i] for rows [first_row, end_row): input point i's voxel key (0 without a voxel grid),
  // kEmpty when it is dropped (not finite, flying pixel, beyond the range); the image is
  // width x (keys_.size() / width) points. With `view`, the valid pixels go to its bounds.
  template <typename PointT>
  void keyRows(const pcl::PointCloud<PointT>& in, int width, bool drop_flying, int first_row,
               int end_row, ViewBoundsGatherer::Band* view);
  // Every kept point of the width x height image added to its voxel's sum, in image order.
  template <typename PointT>
  void sumVoxels(const pcl::PointCloud<PointT>& in, int width, int height);
  void releaseOversizedBuffers(size_t input_points);

  PreprocessParams params_;
  VoxelTable table_;
  std::vector<uint64_t> keys_;        // per input point; reused between frames
  std::vector<uint32_t> row_voxels_;  // the voxels of the last two image rows' points
  ViewBoundsGatherer view_;
};

}  // namespace tabletop_shapes
