// The plane each object rests on: see support.h.
#include "tabletop_shapes/core/support.h"

#include "tabletop_shapes/core/convex_polygon.h"

#include <algorithm>

namespace tabletop_shapes {
namespace {

// A cluster whose bottom lies this far above the table may rest on another object [m]: more
// than the table's noise band (table.min_height 8 mm) and the voxel grid.
constexpr float kMinLift = 0.03f;
// The bottom is the height below which this share of the cluster's points lie: a few stray
// points of the object beneath do not set it. Small, because the split gives the lowest rows of
// an object lying on another to the one beneath (at the concave seam): a box lying across two
// (test_support) kept 1/20 of its lowest 1 cm, and 3 % put its bottom 9 mm high.
constexpr float kBottomQuantile = 0.01f;
// The object beneath reaches up to the bottom: its top lies within this below it or above
// it (an object lying across a lower one's edge dips into its top face's noise) [m].
constexpr float kTopBelowBottom = 0.03f;
constexpr float kTopAboveBottom = 0.02f;
// The object lies over the footprints of the objects beneath: this share of its points, seen
// from above, within kFootprintReach of them. A box lying across a thin standing one overhangs
// it (learn24: an eighth over it); an object whose lower part is hidden behind one in front is
// seen behind that one's footprint, not over it.
constexpr float kMinSupportedShare = 0.1f;
// Noise blurs the footprints' edges; an upper box flush with the lower one's front has its front
// face on the footprint's edge [m].
constexpr float kFootprintReach = 0.01f;
// An object whose lower part a neighbour in front hides shows its bottom edge just behind that
// neighbour: a point of the bottom edge within kFootprintReach outside a footprint, with the
// footprint this far from it towards the camera, stands behind it [m]. On a covered table objects
// stand 5-10 mm apart: the visible bottom of one hidden below lies just over its front
// neighbour's top and its front face within the reach of that neighbour's footprint, as an object
// lying on it would.
constexpr float kBehindStep = 0.02f;
// The bottom edge: the points up to this far above the cluster's bottom [m].
constexpr float kBottomEdge = 0.01f;
// A cluster with at least this share of its bottom edge behind the footprints beneath it, and its
// centre (its points seen from above) more than kHiddenCentreOutside outside all of them, is hidden
// below, not lying there: an object resting on others has its centre over them, and the visible
// part of one hidden below lies behind its front neighbour. Measured (session 11, rendered clutter
// of seed 2012, 8 scenes per kind, and the 45 OSD scenes): the 17 clusters of the covered and
// touching tables this keeps on the table have bottom-edge shares 0.33-0.97 and centres 1.8-14 cm
// outside; objects lying on others in the stacked clutter and OSD shares 0-0.15; OSD learn21's
// top box, standing on a box seen only in front of it, share 0.76 with its centre 1.1 cm outside
// that box's footprint. The centre margin is thin on both sides: a flat box lying on one seen
// only in front of it shows little front face, and its centre lies further back.
constexpr float kMinHiddenBottomShare = 0.25f;
constexpr float kHiddenCentreOutside = 0.015f;

// The split cuts a pile at its concave seam, which noise blurs upwards: the lower object's
// cluster keeps the upper one's lowest rows (rendered stacked clutter of seed 2012: boxes lying on
// boxes got their bottoms 2-13 mm high, 20-25 % too short). The top face of the object beneath,
// a dense band of equal heights next to the upper one, tells the real bottom: the points of
// the objects beneath within kTopFaceReach of the upper one's footprint, in the window of
// kTopFaceWindow with the most of them (at least kMinTopFacePoints), whose median lies below the
// upper one's bottom, lower its support to that median. Side faces spread their points over
// their height (a few per window), a flat top face gathers them within the noise.
constexpr float kTopFaceReach = 0.02f;
constexpr float kTopFaceWindow = 0.006f;
constexpr size_t kMinTopFacePoints = 20;

struct Extent {
  float bottom = 0.0f, top = 0.0f;
  std::vector<Eigen::Vector2f> footprint;            // convex hull on the table, (u, v)
  std::vector<Eigen::Vector2f> projected;            // the points on the table, (u, v)
  std::vector<float> heights;                        // the points' heights above the table
  Eigen::Vector2f centre = Eigen::Vector2f::Zero();  // mean of `projected`
};

// True when `upper` is an object whose lower part the clusters `beneath` hide from `eye_foot`
// (the camera seen from above): see kMinHiddenBottomShare.
bool hiddenBelow(const Extent& upper, const std::vector<const Extent*>& beneath,
                 const Eigen::Vector2f& eye_foot) {
  for (const Extent* lower : beneath) {
    if (insideDistance(lower->footprint, upper.centre) > -kHiddenCentreOutside) return false;
  }
  // On a footprint's blurred edge, outside it, and behind it as the camera sees it.
  auto behind = [&](const Extent& lower, const Eigen::Vector2f& q) {
    const float inside = insideDistance(lower.footprint, q);
    if (!(inside <= 0.0f && inside > -kFootprintReach)) return false;
    const Eigen::Vector2f towards_eye = (eye_foot - q).normalized();
    return insideDistance(lower.footprint, q + kBehindStep * towards_eye) > 0.0f;
  };
  size_t bottom_edge = 0, hidden = 0;
  for (size_t i = 0; i < upper.projected.size(); ++i) {
    if (upper.heights[i] > upper.bottom + kBottomEdge) continue;
    ++bottom_edge;
    hidden += std::any_of(beneath.begin(), beneath.end(),
                          [&](const Extent* lower) { return behind(*lower, upper.projected[i]); });
  }
  return bottom_edge > 0 &&
         static_cast<float>(hidden) >= kMinHiddenBottomShare * static_cast<float>(bottom_edge);
}

// The height of the top face beneath `upper` (see kTopFaceReach), or upper.bottom when the
// objects beneath show none lower than it.
float supportHeight(const Extent& upper, const std::vector<const Extent*>& beneath) {
  std::vector<float> heights;
  for (const Extent* lower : beneath) {
    for (size_t i = 0; i < lower->heights.size(); ++i) {
      const float h = lower->heights[i];
      if (h >= upper.bottom - kTopBelowBottom && h <= upper.bottom + kTopAboveBottom &&
          insideDistance(upper.footprint, lower->projected[i]) > -kTopFaceReach) {
        heights.push_back(h);
      }
    }
  }
  if (heights.size() < kMinTopFacePoints) return upper.bottom;
  std::sort(heights.begin(), heights.end());
  size_t best_first = 0, best_count = 0;
  for (size_t first = 0, last = 0; first < heights.size(); ++first) {
    while (last < heights.size() && heights[last] <= heights[first] + kTopFaceWindow) ++last;
    if (last - first > best_count) best_count = last - first, best_first = first;
  }
  if (best_count < kMinTopFacePoints) return upper.bottom;
  return std::min(upper.bottom, heights[best_first + best_count / 2]);
}

}  // namespace

std::vector<Plane> supportPlanes(const std::vector<CloudPtr>& clusters, const Plane& table,
                                 const Eigen::Vector3f& eye) {
  const Eigen::Vector3f u = table.normal.unitOrthogonal(), v = table.normal.cross(u);
  const Eigen::Vector2f eye_foot(u.dot(eye), v.dot(eye));
  std::vector<Extent> extents(clusters.size());
  for (size_t c = 0; c < clusters.size(); ++c) {
    const Cloud& cluster = *clusters[c];
    if (cluster.empty()) continue;
    std::vector<float>& heights = extents[c].heights;
    std::vector<Eigen::Vector2f> projected;
    heights.reserve(cluster.size());
    projected.reserve(cluster.size());
    for (const auto& point : cluster) {
      const Eigen::Vector3f p = point.getVector3fMap();
      heights.push_back(table.signedDistance(p));
      projected.emplace_back(u.dot(p), v.dot(p));
    }
    Extent& e = extents[c];
    e.top = *std::max_element(heights.begin(), heights.end());
    std::vector<float> sorted = heights;
    const size_t k = static_cast<size_t>(kBottomQuantile * static_cast<float>(sorted.size()));
    std::nth_element(sorted.begin(), sorted.begin() + k, sorted.end());
    e.bottom = sorted[k];
    e.footprint = convexHull2d(projected);
    for (const Eigen::Vector2f& q : projected) e.centre += q;
    e.centre /= static_cast<float>(projected.size());
    e.projected = std::move(projected);
  }

  std::vector<Plane> planes(clusters.size(), table);
  for (size_t c = 0; c < clusters.size(); ++c) {
    const Extent& upper = extents[c];
    if (!(upper.bottom > kMinLift) || upper.projected.empty()) continue;
    std::vector<const Extent*> beneath;  // the clusters whose top reaches up to its bottom
    for (size_t d = 0; d < clusters.size(); ++d) {
      const Extent& lower = extents[d];
      if (d != c && lower.top >= upper.bottom - kTopBelowBottom &&
          lower.top <= upper.bottom + kTopAboveBottom && lower.footprint.size() >= 3) {
        beneath.push_back(&lower);
      }
    }
    const size_t supported = std::count_if(
        upper.projected.begin(), upper.projected.end(), [&](const Eigen::Vector2f& q) {
          return std::any_of(beneath.begin(), beneath.end(), [&](const Extent* lower) {
            return insideDistance(lower->footprint, q) > -kFootprintReach;
          });
        });
    if (supported >= kMinSupportedShare * static_cast<float>(upper.projected.size()) &&
        !hiddenBelow(upper, beneath, eye_foot)) {
      planes[c].d -= supportHeight(upper, beneath);  // the table's plane lifted to its bottom
    }
  }
  return planes;
}

}  // namespace tabletop_shapes
