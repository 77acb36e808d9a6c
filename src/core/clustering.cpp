// §2.5 Euclidean cluster extraction with a k-d tree.
#include "tabletop_shapes/core/clustering.h"

#include "tabletop_shapes/core/cluster_join.h"
#include "tabletop_shapes/core/cluster_split.h"

#include <pcl/search/kdtree.h>
#include <pcl/segmentation/extract_clusters.h>

#include <algorithm>

namespace tabletop_shapes {

std::vector<CloudPtr> extractClusters(const CloudConstPtr& cloud, const ClusteringParams& params,
                                      const Plane* table) {
  std::vector<CloudPtr> clusters;
  if (!cloud || cloud->empty() || !(params.tolerance > 0.0f)) return clusters;
  // The k-d tree needs finite points; the stages before hand over dense clouds, but be safe.
  CloudConstPtr input = cloud;
  if (!cloud->is_dense) {
    auto finite = std::make_shared<Cloud>();
    finite->header = cloud->header;
    for (const auto& p : cloud->points) {
      if (p.getVector3fMap().allFinite()) finite->push_back(p);
    }
    input = finite;
  }
  if (input->empty()) return clusters;

  // Unsorted radius results: the clustering does not need them ordered by distance.
  auto tree = std::make_shared<pcl::search::KdTree<Point>>(false);
  tree->setInputCloud(input);
  std::vector<pcl::PointIndices> cluster_indices;
  pcl::EuclideanClusterExtraction<Point> extraction;
  extraction.setClusterTolerance(params.tolerance);
  extraction.setMinClusterSize(std::max(1, params.min_size));
  extraction.setMaxClusterSize(std::max(1, params.max_size));
  extraction.setSearchMethod(tree);
  extraction.setInputCloud(input);
  extraction.extract(cluster_indices);

  for (const auto& indices : cluster_indices) {
    auto cluster = std::make_shared<Cloud>(*input, indices.indices);
    cluster->header = input->header;
    cluster->is_dense = true;
    if (!table) {
      clusters.push_back(cluster);
      continue;
    }
    for (const CloudPtr& part : splitAtConcaveSeams(cluster, *table, params)) {
      clusters.push_back(part);
    }
  }
  if (table) {
    const Eigen::Vector3f viewpoint = cloud->sensor_origin_.head<3>();
    return joinPartsHiddenInTheMiddle(joinInsidesSeenOverRims(clusters, *table, viewpoint), *table,
                                      viewpoint);
  }
  std::stable_sort(clusters.begin(), clusters.end(),
                   [](const CloudPtr& a, const CloudPtr& b) { return a->size() > b->size(); });
  return clusters;
}

}  // namespace tabletop_shapes
