// §2.5 Euclidean cluster extraction, neighbours from a GridSearch.
#include "tabletop_shapes/core/clustering.h"

#include "tabletop_shapes/core/cluster_join.h"
#include "tabletop_shapes/core/cluster_split.h"
#include "tabletop_shapes/core/grid_search.h"
#include "tabletop_shapes/core/parallel.h"

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

  // The connected components of the points closer than the tolerance, from a grid with cells
  // of the tolerance (each point's neighbours lie in 27 cells): the clusters of
  // pcl::EuclideanClusterExtraction, filtered and ordered (largest first) as it does.
  GridSearch<Point> grid(params.tolerance, false);
  grid.setInputCloud(input);
  const size_t min_size = static_cast<size_t>(std::max(1, params.min_size));
  const size_t max_size = static_cast<size_t>(std::max(1, params.max_size));
  std::vector<pcl::PointIndices> cluster_indices;
  for (pcl::Indices& component : grid.connectedComponents(params.tolerance, freeWorkerThreads())) {
    if (component.size() < min_size || component.size() > max_size) continue;
    cluster_indices.emplace_back();
    cluster_indices.back().header = input->header;
    cluster_indices.back().indices = std::move(component);
  }
  std::sort(cluster_indices.rbegin(), cluster_indices.rend(), pcl::comparePointClusters);

  // Clusters are split independently: one per core at a time, largest first (PCL's order).
  std::vector<std::vector<CloudPtr>> parts(cluster_indices.size());
  std::vector<std::vector<int>> side_by_side(cluster_indices.size());
  parallelFor(cluster_indices.size(), [&](size_t i) {
    auto cluster = std::make_shared<Cloud>(*input, cluster_indices[i].indices);
    cluster->header = input->header;
    cluster->is_dense = true;
    parts[i] = table ? splitAtConcaveSeams(cluster, *table, params, &side_by_side[i], input)
                     : std::vector<CloudPtr>{cluster};
  });
  // Side-by-side groups numbered over all clusters.
  std::vector<int> groups;
  int first_group = 0;
  for (size_t i = 0; i < parts.size(); ++i) {
    clusters.insert(clusters.end(), parts[i].begin(), parts[i].end());
    int last = -1;
    for (size_t p = 0; p < parts[i].size(); ++p) {
      const int group = p < side_by_side[i].size() ? side_by_side[i][p] : -1;
      // A cluster left whole is in no group: no part of it is kept apart from another's.
      groups.push_back(group < 0 || parts[i].size() < 2 ? -1 : first_group + group);
      last = std::max(last, group);
    }
    first_group += last + 1;
  }
  if (table) {
    const Eigen::Vector3f viewpoint = cloud->sensor_origin_.head<3>();
    std::vector<CloudPtr> joined = joinInsidesSeenOverRims(clusters, *table, viewpoint, &groups);
    return joinPartsHiddenInTheMiddle(std::move(joined), *table, viewpoint, &groups);
  }
  std::stable_sort(clusters.begin(), clusters.end(),
                   [](const CloudPtr& a, const CloudPtr& b) { return a->size() > b->size(); });
  return clusters;
}

}  // namespace tabletop_shapes
