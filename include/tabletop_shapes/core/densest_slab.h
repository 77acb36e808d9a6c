// The densest slab of a set of plane distances: the most values within `width` of each other.
// The table stage asks it of every plane's 50-100k inlier distances (twice per plane for its
// surface slab, once for its surface contrast); sorting them all took 5 % of a 4-object frame.
#pragma once

#include <cstddef>
#include <vector>

namespace tabletop_shapes {

struct DensestSlab {
  size_t count = 0;   // values in the slab
  float low = 0.0f;   // its smallest value
  float high = 0.0f;  // its largest value
};

// What sorting `values` ascending (-0 before +0) and taking the longest run [begin, end) with
// values[end - 1] <= values[begin] + width (the first such run on ties) gives: count = end -
// begin, low = values[begin], high = values[end - 1]; {0, 0, 0} for no values. The same floats,
// without sorting them all: the values are counted in bins of width / 256; only the bins that can
// start a run as long as the longest one some bin surely starts are sorted and searched.
DensestSlab densestSlab(const std::vector<float>& values, float width);

}  // namespace tabletop_shapes
