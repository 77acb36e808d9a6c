// The bounds of an organised cloud's valid pixels (ViewBounds), gathered on bands of rows that
// may run on different threads: viewBoundsOf uses it, and so does the preprocessing, which
// gathers them in its own pass over the pixels instead of a second pass over the input.
#pragma once

#include "tabletop_shapes/core/types.h"

#include <algorithm>
#include <limits>
#include <vector>

namespace tabletop_shapes {

class ViewBoundsGatherer {
 public:
  // The pixels of one band of rows, added by one thread, row by row.
  class Band {
   public:
    // A finite point at `column` of the current row; points at z <= 0 are not valid pixels.
    void add(int column, float x, float y, float z) {
      if (z <= 0.0f) return;
      const float tan_x = x / z, tan_y = y / z;
      min_x_ = std::min(min_x_, tan_x);
      max_x_ = std::max(max_x_, tan_x);
      min_y_ = std::min(min_y_, tan_y);
      min_z_ = std::min(min_z_, z);
      max_y_ = std::max(max_y_, tan_y);
      if (first_ < 0) first_ = column, first_tan_ = tan_x;
      last_ = column, last_tan_ = tan_x;
    }

    // Extremes of valid pixels gathered elsewhere (columns: through add).
    void addExtremes(float min_tan_x, float max_tan_x, float min_tan_y, float max_tan_y,
                     float min_z) {
      min_x_ = std::min(min_x_, min_tan_x);
      max_x_ = std::max(max_x_, max_tan_x);
      min_y_ = std::min(min_y_, min_tan_y);
      max_y_ = std::max(max_y_, max_tan_y);
      min_z_ = std::min(min_z_, min_z);
    }

   private:
    friend class ViewBoundsGatherer;
    float min_x_ = std::numeric_limits<float>::max(), max_x_ = -min_x_;
    float min_y_ = min_x_, max_y_ = -min_x_, min_z_ = min_x_;
    int first_ = -1, last_ = -1;  // the current row's first and last valid column
    float first_tan_ = 0.0f, last_tan_ = 0.0f;
  };

  // Ready for a cloud of `rows` rows gathered on `bands` bands.
  void reset(size_t bands, size_t rows);
  // The current row of a band (a thread's own Band, a local: no cache line shared with another
  // thread's) is complete: its pixel size (tan x grows by 1 / fx per column) is kept when it
  // holds two valid points.
  void endRow(Band& band, size_t row) {
    row_has_pixel_[row] = band.last_ > band.first_;
    if (band.last_ > band.first_) {
      row_pixel_[row] = (band.last_tan_ - band.first_tan_) / (band.last_ - band.first_);
    }
    band.first_ = band.last_ = -1;
  }
  // A band's rows are all done.
  void setBand(size_t index, const Band& band) { bands_[index] = band; }
  ViewBounds bounds() const;

 private:
  std::vector<Band> bands_;
  std::vector<double> row_pixel_;
  std::vector<char> row_has_pixel_;
};

}  // namespace tabletop_shapes
