// Clouds a stage fills one frame after the other (a driver's published cloud, a PointCloud2
// as it is read): the last one again when nobody holds it any more (the usual case: the next
// stage is done with a frame before the next one is filled), which saves a VGA frame its
// allocation, page faults and construction (5-10 MB); else a new one. A cloud far larger
// than the frame (after a burst) is not kept.
#pragma once

#include <boost/make_shared.hpp>
#include <boost/shared_ptr.hpp>
#include <pcl/point_cloud.h>

namespace tabletop_shapes {
namespace bridge {

template <typename PointT>
class CloudPool {
 public:
  boost::shared_ptr<pcl::PointCloud<PointT>> next(size_t points) {
    // use_count 1: only the pool holds it, and only the pool hands it out.
    if (!last_ || last_.use_count() > 1 || last_->points.capacity() > 2 * points) {
      last_ = boost::make_shared<pcl::PointCloud<PointT>>();
    }
    return last_;
  }

 private:
  boost::shared_ptr<pcl::PointCloud<PointT>> last_;
};

}  // namespace bridge
}  // namespace tabletop_shapes
