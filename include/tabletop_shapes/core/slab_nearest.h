// Exact nearest-point queries bounded by a distance, for the closest pair of two clusters
// (cluster_join): the points sorted along x, held one array per coordinate in blocks of four;
// a query scans only the slab of points whose x lies within the bound, four at a time. The
// squared distances are the floats pcl::KdTreeFLANN computes ((q - p)^2 summed over x, y, z in
// that order), so the nearest distance is the same; with a single nearest point, so is its index.
#pragma once

#include "tabletop_shapes/core/plane_support.h"

#include <vector>

namespace tabletop_shapes {

class SlabNearest {
 public:
  explicit SlabNearest(const Cloud& cloud);

  struct Hit {
    float squared = 0.0f;  // squared distance to the nearest point
    int index = -1;        // its index in the cloud (the first in the cloud's order if tied)
    bool tied = false;     // another point lies at exactly the same distance
  };
  // The point of the cloud nearest `query` among those within squared distance `bound`
  // (inclusive); false when there is none.
  bool nearest(const Eigen::Vector3f& query, float bound, Hit& hit) const;

 private:
  std::vector<float> sorted_x_;  // ascending
  std::vector<int> order_;       // cloud index of each sorted position
  VectorBlocks blocks_;          // the points in sorted order
};

}  // namespace tabletop_shapes
