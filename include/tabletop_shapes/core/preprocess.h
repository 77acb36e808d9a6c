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
    uint32_t first_pixel;  // the input index of the voxel's first point: its place in the output
  };
  // Open-addressing hash from voxel key to the voxel's running sum; reused between frames.
  class VoxelTable {
   public:
    void clear();  // keeps the last frame's size, so that a frame like it does not grow
    // Inserts a voxel with an empty sum, first met at `pixel`, when new.
    uint32_t voxelOf(uint64_t key, uint32_t pixel);
    // Starts loading the slot where key's probe begins: a lookup a few pixels on then finds it
    // in the cache (the table is larger than L2).
    void prefetch(uint64_t key) const;
    size_t bytes() const;
    void release();              // gives back a table far larger than its voxels need
    std::vector<VoxelSum> sums;  // in order of first appearance: deterministic output

   private:
    struct Slot {
      uint64_t key;
      uint32_t voxel;  // index into sums
      uint32_t frame;  // the slot is in use when it is the table's frame_
    };
    // A new voxel, after the table grew: voxelOf's insert would make it more than half full.
    uint32_t insertGrowing(uint64_t key, uint32_t pixel);
    void grow();
    std::vector<Slot> slots_;
    // Counts clear()s: a frame's clear only moves it on, not 2-4 MB of slots written again.
    uint32_t frame_ = 0;
  };
  template <typename PointT>
  void applyImpl(const pcl::PointCloud<PointT>& in, Cloud& out, ViewBounds* view);
  // keys_[i] for rows [first_row, end_row): input point i's voxel key (0 without a voxel grid),
  // kEmpty when it is dropped (not finite, flying pixel, beyond the range); the image is
  // width x (keys_.size() / width) points. With `view`, the valid pixels go to its bounds.
  template <typename PointT>
  void keyRows(const pcl::PointCloud<PointT>& in, int width, bool drop_flying, int first_row,
               int end_row, ViewBoundsGatherer::Band* view);
  // The voxels of one owner (one thread's share of the voxel space) and the voxels of the last
  // two image rows' points it summed. Aligned: owners' vectors grow on different threads.
  struct alignas(64) VoxelOwner {
    VoxelTable table;
    std::vector<uint32_t> row_voxels;
  };
  // Every kept point of the width x height image whose voxel `owner` of `owners` owns added to
  // its voxel's sum, in image order.
  template <typename PointT>
  void sumOwnedVoxels(const pcl::PointCloud<PointT>& in, int width, int height, size_t owner,
                      size_t owners);
  // The owners' voxels' centroids into `out` in the order their voxels are first met, on
  // `threads` threads in `pieces` pieces.
  void writeCentroids(size_t owners, size_t pixels, size_t pieces, unsigned threads, Cloud& out);
  void releaseOversizedBuffers(size_t input_points);

  PreprocessParams params_;
  std::vector<VoxelOwner> owners_;  // reused between frames
  std::vector<uint64_t> keys_;      // per input point; reused between frames
  ViewBoundsGatherer view_;
};

}  // namespace tabletop_shapes
