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
    uint32_t last_row;  // the last image row that added to it
  };
  // Open-addressing hash from voxel key to the voxel's running sum; reused between frames.
  class VoxelTable {
   public:
    void clear();  // keeps the last frame's size, so that a frame like it does not grow
    uint32_t voxelOf(uint64_t key);     // inserts a voxel with an empty sum when new
    uint32_t find(uint64_t key) const;  // of a key in the table
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
  // A band of image rows, keyed and summed by one thread into its own table.
  struct Band {
    int first_row = 0, end_row = 0;
    VoxelTable table;                  // band 0's becomes the whole frame's
    std::vector<uint32_t> row_voxels;  // the voxels of the last two rows' points
    std::vector<uint32_t> merged;      // per voxel of the band: its voxel in band 0's table
    std::vector<char> met_before;      // per voxel of the band: also in an earlier band
  };

  template <typename PointT>
  void applyImpl(const pcl::PointCloud<PointT>& in, Cloud& out, ViewBounds* view);
  // keys_[i] for the rows of band `band`: input point i's voxel key (0 without a voxel grid),
  // kEmpty when it is dropped (not finite, flying pixel, beyond the range); the image is
  // width x height points. With a voxel grid, each row's points are then added to the band's
  // table; with `view`, the valid pixels to the band's view bounds.
  template <typename PointT>
  void passBand(const pcl::PointCloud<PointT>& in, int width, bool drop_flying, Band& band,
                ViewBoundsGatherer::Band* view);
  // Band `b`'s voxels into band 0's table, in the band's order; a voxel also met in an earlier
  // band gets the band's points added one by one, in image order, as one pass would add them.
  template <typename PointT>
  void mergeBand(const pcl::PointCloud<PointT>& in, int width, Band& band);
  void releaseOversizedBuffers(size_t input_points);

  PreprocessParams params_;
  std::vector<Band> bands_;
  std::vector<uint64_t> keys_;  // per input point; reused between frames
  ViewBoundsGatherer view_;
};

}  // namespace tabletop_shapes
