// Splitting touching or stacked objects at concave seams: supervoxels joined by local convexity
// (LCCP). Small parts rejoin the neighbour they touch most, so a handle or a noisy patch does not
// become an object.
#include "tabletop_shapes/core/cluster_split.h"

#include <pcl/search/kdtree.h>
#include <pcl/segmentation/lccp_segmentation.h>
#include <pcl/segmentation/supervoxel_clustering.h>

#include <algorithm>
#include <map>

namespace tabletop_shapes {
namespace {

// Part label of every point; 0 for points no supervoxel holds.
std::vector<uint32_t> convexPartLabels(const CloudConstPtr& cluster,
                                       const ClusteringParams& params) {
  // Voxels a little coarser than the preprocessing grid (5 mm), so neighbouring surface
  // samples are adjacent voxels.
  const float voxel = std::max(0.006f, params.split_patch_size / 4);
  pcl::SupervoxelClustering<Point> supervoxel(voxel, params.split_patch_size);
  supervoxel.setUseSingleCameraTransform(false);
  supervoxel.setColorImportance(0.0f);
  supervoxel.setSpatialImportance(1.0f);
  supervoxel.setNormalImportance(4.0f);
  supervoxel.setInputCloud(cluster);
  std::map<uint32_t, pcl::Supervoxel<Point>::Ptr> patches;
  supervoxel.extract(patches);
  std::multimap<uint32_t, uint32_t> adjacency;
  supervoxel.getSupervoxelAdjacency(adjacency);

  pcl::LCCPSegmentation<Point> lccp;
  lccp.setConcavityToleranceThreshold(params.split_concavity_deg);
  // Extended convexity (k = 1): a seam is concave only when the patches around it agree, which
  // keeps noisy box faces together; the sanity and smoothness checks over-split real boxes.
  lccp.setKFactor(1);
  lccp.setMinSegmentSize(3);
  lccp.setInputSupervoxels(patches, adjacency);
  lccp.segment();
  pcl::PointCloud<pcl::PointXYZL>::Ptr labelled = supervoxel.getLabeledCloud();
  lccp.relabelCloud(*labelled);
  std::vector<uint32_t> labels(cluster->size(), 0);
  for (size_t i = 0; i < labels.size() && i < labelled->size(); ++i)
    labels[i] = (*labelled)[i].label;
  return labels;
}

// Points of other parts among the k nearest neighbours of `part`'s points, per part.
std::map<uint32_t, int> neighbourVotes(const Cloud& cluster, pcl::search::KdTree<Point>& tree,
                                       const std::vector<uint32_t>& labels, uint32_t part) {
  std::map<uint32_t, int> votes;
  std::vector<int> neighbours;
  std::vector<float> distances;
  for (size_t i = 0; i < labels.size(); ++i) {
    if (labels[i] != part) continue;
    tree.nearestKSearch(cluster[i], 16, neighbours, distances);
    for (int j : neighbours) {
      if (labels[j] != part && labels[j] != 0) ++votes[labels[j]];
    }
  }
  return votes;
}

void relabel(std::vector<uint32_t>& labels, uint32_t from, uint32_t to) {
  std::replace(labels.begin(), labels.end(), from, to);
}

// Unlabelled points (0) and parts below min_points join the neighbouring part they touch most,
// smallest first.
void mergeSmallParts(const Cloud& cluster, pcl::search::KdTree<Point>& tree, int min_points,
                     std::vector<uint32_t>& labels) {
  for (;;) {
    std::map<uint32_t, int> size;
    for (uint32_t l : labels) ++size[l];
    if (size.size() < 2) return;
    uint32_t smallest = 0;
    if (!size.count(0)) {
      smallest = std::min_element(size.begin(), size.end(), [](auto& a, auto& b) {
                   return a.second < b.second;
                 })->first;
      if (size[smallest] >= min_points) return;
    }
    const std::map<uint32_t, int> votes = neighbourVotes(cluster, tree, labels, smallest);
    uint32_t target = 0;
    for (const auto& [label, n] : votes) {
      if (target == 0 || n > votes.at(target)) target = label;
    }
    if (target == 0) {  // touches no other part: join the largest
      for (const auto& [label, n] : size) {
        if (label != smallest && label != 0 && (target == 0 || n > size[target])) target = label;
      }
    }
    relabel(labels, smallest, target);
  }
}

// Neighbouring parts whose tops lie within kStackStep of each other rejoin: on a table a
// concave seam between objects that matters here is one object standing or leaning on
// another, whose top then rises above the lower one's. Parts of one object cut apart by noise
// or by the concave inside of a cup or bowl end at the same top (rim) and are joined again.
// (Touching objects of equal height therefore stay one cluster.)
constexpr float kStackStep = 0.02f;  // [m]

void mergePartsOfEqualTop(const Cloud& cluster, pcl::search::KdTree<Point>& tree,
                          const Plane& table, std::vector<uint32_t>& labels) {
  for (bool merged = true; merged;) {
    merged = false;
    std::map<uint32_t, float> top;
    for (size_t i = 0; i < labels.size(); ++i) {
      const float h = table.signedDistance(cluster[i].getVector3fMap());
      auto it = top.find(labels[i]);
      if (it == top.end())
        top[labels[i]] = h;
      else
        it->second = std::max(it->second, h);
    }
    for (const auto& [part, part_top] : top) {
      for (const auto& [other, n] : neighbourVotes(cluster, tree, labels, part)) {
        if (std::abs(top[other] - part_top) <= kStackStep) {
          relabel(labels, part, other);
          merged = true;
          break;
        }
      }
      if (merged) break;
    }
  }
}

}  // namespace

std::vector<CloudPtr> splitAtConcaveSeams(const CloudPtr& cluster, const Plane& table,
                                          const ClusteringParams& params) {
  const int min_points = std::max(1, params.split_min_points);
  if (!cluster || !(params.split_concavity_deg > 0.0f) || !(params.split_patch_size > 0.0f) ||
      static_cast<int>(cluster->size()) < 2 * min_points) {
    return {cluster};
  }
  std::vector<uint32_t> labels = convexPartLabels(cluster, params);
  pcl::search::KdTree<Point> tree(false);
  tree.setInputCloud(cluster);
  mergeSmallParts(*cluster, tree, min_points, labels);
  mergePartsOfEqualTop(*cluster, tree, table, labels);

  std::map<uint32_t, std::vector<int>> parts;
  for (size_t i = 0; i < labels.size(); ++i) parts[labels[i]].push_back(static_cast<int>(i));
  if (parts.size() < 2) return {cluster};
  std::vector<CloudPtr> out;
  for (const auto& [label, indices] : parts) {
    auto part = std::make_shared<Cloud>(*cluster, indices);
    part->header = cluster->header;
    part->is_dense = true;
    out.push_back(part);
  }
  std::stable_sort(out.begin(), out.end(),
                   [](const CloudPtr& a, const CloudPtr& b) { return a->size() > b->size(); });
  return out;
}

}  // namespace tabletop_shapes
