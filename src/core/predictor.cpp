#include "tabletop_shapes/core/predictor.h"

#include "tabletop_shapes/core/grid_search.h"

#include <algorithm>

namespace tabletop_shapes {
namespace {

constexpr float kNeighbourCell = 0.01f;  // GridSearch cell [m]

}  // namespace

Prediction predictShape(const NormalCloud& object, const PredictorParams& params) {
  Prediction prediction;
  const int k = std::max(1, params.k);
  const int n = static_cast<int>(object.size());
  if (n < k + 1) return prediction;  // Unknown: not enough points for eq. 1

  // The k nearest of 5 mm voxel centroids lie within a centimetre for small k.
  GridSearch<pcl::PointNormal> tree(kNeighbourCell);
  tree.setInputCloud(object.makeShared());

  // Eq. 1: d(p0) = sum over the k nearest neighbours of ||n_i - n_0||.
  // (Points in no particular order: the values are sorted below.)
  std::vector<float> variation;
  variation.reserve(n);
  tree.forEachNearestKIndices(k + 1, [&](int i, const pcl::Indices& neighbours) {
    const Eigen::Vector3f n0 = object[i].getNormalVector3fMap();
    float sum = 0.0f;
    int used = 0;
    for (size_t j = 0; j < neighbours.size() && used < k; ++j) {
      if (neighbours[j] == i) continue;  // the query point itself
      sum += (object[neighbours[j]].getNormalVector3fMap() - n0).norm();
      ++used;
    }
    if (used == k) variation.push_back(sum);
  });
  if (variation.empty()) return prediction;

  // Edge points have unstable normals and neighbours on the adjacent face: average only the
  // representative middle section of the sorted values.
  std::sort(variation.begin(), variation.end());
  const float low = std::clamp(params.section_low, 0.0f, 1.0f);
  const float high = std::clamp(params.section_high, low, 1.0f);
  const size_t size = variation.size();
  const size_t begin = std::min(size - 1, static_cast<size_t>(low * size));
  const size_t end = std::clamp(static_cast<size_t>(high * size), begin + 1, size);
  double total = 0.0;
  for (size_t i = begin; i < end; ++i) total += variation[i];
  prediction.score = static_cast<float>(total / static_cast<double>(end - begin));
  prediction.guess = prediction.score > params.threshold ? ShapeType::Cylinder : ShapeType::Cube;
  return prediction;
}

}  // namespace tabletop_shapes
