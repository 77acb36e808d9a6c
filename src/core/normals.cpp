#include "tabletop_shapes/core/normals.h"

#include <pcl/search/kdtree.h>
#include <pcl/surface/mls.h>

namespace tabletop_shapes {
namespace {

// MLS smooths the points (projection on the local polynomial) and gives the normal of the
// local tangent plane; PCL leaves out points with fewer than 3 neighbours.
void smoothWithNormals(const CloudConstPtr& cluster, const NormalParams& params,
                       NormalCloud& smoothed) {
  // The k-d tree must not see NaN / inf points (an organised cluster may hold some).
  CloudConstPtr finite = cluster;
  if (!cluster->is_dense) {
    auto copy = std::make_shared<Cloud>();
    copy->header = cluster->header;
    for (const auto& p : cluster->points) {
      if (std::isfinite(p.x) && std::isfinite(p.y) && std::isfinite(p.z)) copy->push_back(p);
    }
    if (copy->empty()) return;
    finite = copy;
  }
  pcl::MovingLeastSquares<Point, pcl::PointNormal> mls;
  mls.setInputCloud(finite);
  mls.setSearchMethod(std::make_shared<pcl::search::KdTree<Point>>());
  mls.setComputeNormals(true);
  mls.setPolynomialOrder(std::max(0, params.polynomial_order));
  mls.setSearchRadius(params.search_radius);
  mls.process(smoothed);
}

}  // namespace

void estimateNormalsMLS(const CloudConstPtr& cluster, const NormalParams& params,
                        NormalCloud& out) {
  out.clear();
  NormalCloud smoothed;
  if (cluster && !cluster->empty() && params.search_radius > 0.0f) {
    smoothWithNormals(cluster, params, smoothed);
  }

  // The cloud is in the camera frame: orient every normal towards the origin so that normals
  // of one face agree in sign (the predictor and the box fit compare normals directly).
  out.reserve(smoothed.size());
  for (const auto& p : smoothed.points) {
    if (!std::isfinite(p.x) || !std::isfinite(p.y) || !std::isfinite(p.z) ||
        !std::isfinite(p.normal_x) || !std::isfinite(p.normal_y) || !std::isfinite(p.normal_z)) {
      continue;
    }
    pcl::PointNormal q = p;
    Eigen::Vector3f normal = q.getNormalVector3fMap();
    const float norm = normal.norm();
    if (norm < 1e-6f) continue;
    normal /= norm;
    if (normal.dot(-q.getVector3fMap()) < 0.0f) normal = -normal;
    q.getNormalVector3fMap() = normal;
    out.push_back(q);
  }
  if (cluster) out.header = cluster->header;
  out.width = static_cast<uint32_t>(out.size());
  out.height = 1;
  out.is_dense = true;
}

}  // namespace tabletop_shapes
