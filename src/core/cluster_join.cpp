// Joining the inside of an open object (bowl, pot, cup) to its outer wall: see cluster_join.h.
#include "tabletop_shapes/core/cluster_join.h"
#include "tabletop_shapes/core/cluster_split.h"

#include "tabletop_shapes/core/convex_polygon.h"
#include "tabletop_shapes/core/slab_nearest.h"

#include <pcl/kdtree/kdtree_flann.h>

#include <Eigen/Geometry>

#include <algorithm>
#include <functional>
#include <cmath>
#include <limits>
#include <memory>
#include <numeric>

namespace tabletop_shapes {
namespace {

// The inside reaches up to the rim: its top lies within this of the outer wall's top [m] (as
// parts of one object in cluster_split; a stacked object rises further).
constexpr float kRimStep = 0.02f;
// Only points this far below the rim tell: the line of sight to a point at the rim's height
// crosses that height at the point itself [m].
constexpr float kBelowRim = 0.01f;
// A line of sight counts as passing through the opening when it crosses the rim's height this
// far inside the outer wall's footprint: lines of sight grazing a solid object's top edge cross
// its footprint's edge, blurred by the 5 mm voxel grid and the noise [m].
constexpr float kOpeningInset = 0.005f;
// Share of the inside's points seen through the opening. The footprint of the visible outer wall
// covers only the near half of the opening, so the far inside wall's lines of sight cross the
// rim's height beyond it: on OSD's bowls 20 % pass; beside solid objects under 1 %.
constexpr float kMinSeenThroughFraction = 0.1f;
// Room for the float rounding of the crossings in the bound that spares their computation [m].
constexpr float kCrossingRounding = 0.001f;

// Parts of one object hidden in the middle: their tops lie within this of each other [m] (the
// top face or rim of one solid, seen on both sides of the occluder; a stacked object rises
// further, see kRimStep).
constexpr float kSameTop = 0.015f;
// The gap between the parts is sampled every kGapStep along the shortest segment between them,
// leaving out kGapEnd at each end [m]: the occluder's silhouette loses up to 2 cm there to the
// flying-pixel filter and the voxel grid (learn28: the 2 samples nearest one end unexplained,
// the 8 others hidden). Separate objects show a wider run of table or background (learn15: 5 cm
// at one end, the 12 other samples hidden). Gaps longer than kMaxGap are not one object's
// hidden middle (boxes and cans on a table: up to 25 cm wide behind one).
constexpr float kGapStep = 0.01f;
constexpr float kGapEnd = 0.025f;
constexpr float kMaxGap = 0.3f;
// A gap sample is hidden when a point of the occluder lies within this angle of its line of
// sight (twice the voxel grid's 5 mm at 1 m) and at least kOccluderInFront nearer the camera.
constexpr float kSightAngle = 0.01f;       // [rad]
constexpr float kOccluderInFront = 0.02f;  // [m]
// Rounding room of the angle bounds that spare the search for an occluding point [rad]: the
// float test of an angle of kSightAngle errs by ~1e-5.
constexpr double kAngleSlack = 1e-3;

// Clusters nearer than this touch [m]: the split (cluster_split.h) parted them at a concave
// seam, as two objects side by side, and they are not joined again as the parts of an object
// hidden in the middle, which are separate Euclidean clusters, at least clustering.tolerance
// (2 cm) apart.
constexpr float kTouching = 0.01f;

// A point farther than this beyond a polygon's bounding box shrunk by an inset is surely less
// than the inset inside the polygon, whatever the float rounding of the exact distance [m].
constexpr float kSurelyShallower = 1e-5f;

struct Footprint {
  float top = 0.0f;                   // highest point above the table [m]
  std::vector<Eigen::Vector2f> hull;  // convex hull of the rim on the table, in (u, v)
  Eigen::AlignedBox2f box;            // the hull's bounding box
};

// Whether cluster c was parted under a level top face of its own (cluster_split.h).
bool underOwnTop(const std::vector<int>* side_by_side, size_t c) {
  return side_by_side && c < side_by_side->size() && (*side_by_side)[c] >= 0;
}

bool keptApart(const std::vector<int>* side_by_side, size_t a, size_t b) {
  return side_by_side && a < side_by_side->size() && b < side_by_side->size() &&
         (*side_by_side)[a] >= 0 && (*side_by_side)[a] == (*side_by_side)[b];
}

int root(std::vector<int>& parent, int i) {
  while (parent[i] != i) i = parent[i] = parent[parent[i]];
  return i;
}

// The clusters merged by the union-find forest `parent`, largest first; the caller's clouds are
// not changed. `side_by_side` (when not empty) follows the merged clusters: a merged cluster
// keeps the largest number of its members.
std::vector<CloudPtr> mergeGroups(const std::vector<CloudPtr>& clusters, std::vector<int>& parent,
                                  std::vector<int>* side_by_side) {
  std::vector<std::pair<CloudPtr, int>> joined;
  std::vector<bool> copied;
  std::vector<int> joined_index(clusters.size(), -1);
  const bool grouped = side_by_side && side_by_side->size() == clusters.size();
  for (size_t c = 0; c < clusters.size(); ++c) {
    const int r = root(parent, static_cast<int>(c));
    const int group = grouped ? (*side_by_side)[c] : -1;
    if (joined_index[r] < 0) {
      joined_index[r] = static_cast<int>(joined.size());
      joined.emplace_back(clusters[c], group);
      copied.push_back(false);
      continue;
    }
    const int j = joined_index[r];
    auto& [cloud, joined_group] = joined[j];
    if (!copied[j]) cloud = std::make_shared<Cloud>(*cloud), copied[j] = true;
    *cloud += *clusters[c];
    joined_group = std::max(joined_group, group);
  }
  return largestFirst(std::move(joined), grouped ? side_by_side : nullptr);
}

}  // namespace

std::vector<CloudPtr> joinInsidesSeenOverRims(std::vector<CloudPtr> clusters, const Plane& table,
                                              const Eigen::Vector3f& viewpoint,
                                              std::vector<int>* side_by_side) {
  if (clusters.size() < 2) return clusters;
  const Eigen::Vector3f u = table.normal.unitOrthogonal(), v = table.normal.cross(u);
  const float eye_height = table.signedDistance(viewpoint);
  // The opening is what the rim surrounds: the footprint of the points within kBelowRim of the
  // top. A closed object's topmost points are solid (a bottle's cap over its shoulder): the
  // camera sees nothing through them, while lines of sight to an object behind it crossed the
  // cap's height over the shoulder, within the whole footprint (issue 12: a box cut by the image
  // border behind a flattened bottle was joined to it as its inside).
  auto footprintOf = [&](const std::vector<size_t>& members) {
    float top = -std::numeric_limits<float>::max();
    std::vector<float> heights;
    size_t points = 0;
    for (size_t c : members) points += clusters[c]->size();
    heights.reserve(points);
    for (size_t c : members) {
      for (const auto& point : *clusters[c]) {
        heights.push_back(table.signedDistance(point.getVector3fMap()));
        top = std::max(top, heights.back());
      }
    }
    std::vector<Eigen::Vector2f> rim;
    size_t i = 0;
    for (size_t c : members) {
      for (const auto& point : *clusters[c]) {
        const Eigen::Vector3f p = point.getVector3fMap();
        if (heights[i++] >= top - kBelowRim) rim.emplace_back(u.dot(p), v.dot(p));
      }
    }
    Footprint footprint{top, convexHull2d(std::move(rim)), {}};
    for (const Eigen::Vector2f& corner : footprint.hull) footprint.box.extend(corner);
    return footprint;
  };
  std::vector<Footprint> footprints(clusters.size());
  for (size_t c = 0; c < clusters.size(); ++c) footprints[c] = footprintOf({c});

  // Each cluster's footprint's bounding box and lowest point, for the bound below.
  const Eigen::Vector2f eye_on_table(u.dot(viewpoint), v.dot(viewpoint));
  std::vector<Eigen::AlignedBox2f> boxes(clusters.size());
  std::vector<float> bottoms(clusters.size(), std::numeric_limits<float>::max());
  for (size_t c = 0; c < clusters.size(); ++c) {
    for (const auto& point : *clusters[c]) {
      const Eigen::Vector3f p = point.getVector3fMap();
      boxes[c].extend(Eigen::Vector2f(u.dot(p), v.dot(p)));
      bottoms[c] = std::min(bottoms[c], table.signedDistance(p));
    }
  }
  // Is cluster `inside` seen through the opening whose rim is `rim`? `reaching_rim`: its top must
  // also come within kRimStep of the rim (else it only must not rise above it).
  auto seenThroughOpening = [&](size_t inside, const Footprint& rim, bool reaching_rim) {
    const float rise = footprints[inside].top - rim.top;
    if (rim.hull.size() < 3 || rise > kRimStep || (reaching_rim && rise < -kRimStep) ||
        !(eye_height > rim.top) || clusters[inside]->empty()) {
      return false;
    }
    // A point of a convex polygon within the inset of its bounding box's side is within the
    // inset of its boundary: the box test spares the exact distance to most crossings.
    const Eigen::Vector2f shrink = Eigen::Vector2f::Constant(kOpeningInset - kSurelyShallower);
    const Eigen::AlignedBox2f deep_enough(rim.box.min() + shrink, rim.box.max() - shrink);
    // A crossing's footprint is the eye's moved toward the point's by the share s = (eye - rim)
    // / (eye - point) of the way (heights), s growing with the point's height: every crossing
    // lies in the box of the footprint box's corners moved by the least and the largest share.
    // When that box (a millimetre wider, for rounding) misses the opening, none passes.
    const float lowest = std::min(bottoms[inside], rim.top - kBelowRim);
    Eigen::AlignedBox2f crossings;
    for (const float share : {(eye_height - rim.top) / (eye_height - lowest),
                              (eye_height - rim.top) / (eye_height - (rim.top - kBelowRim))}) {
      for (const auto corner : {Eigen::AlignedBox2f::BottomLeft, Eigen::AlignedBox2f::BottomRight,
                                Eigen::AlignedBox2f::TopLeft, Eigen::AlignedBox2f::TopRight}) {
        crossings.extend(eye_on_table + (boxes[inside].corner(corner) - eye_on_table) * share);
      }
    }
    crossings.extend(crossings.min() - Eigen::Vector2f::Constant(kCrossingRounding));
    crossings.extend(crossings.max() + Eigen::Vector2f::Constant(kCrossingRounding));
    if (!crossings.intersects(deep_enough)) return false;
    size_t through = 0;
    for (const auto& point : *clusters[inside]) {
      const Eigen::Vector3f p = point.getVector3fMap();
      const float height = table.signedDistance(p);
      if (height > rim.top - kBelowRim) continue;
      // Where the line of sight viewpoint -> p crosses the rim's height.
      const Eigen::Vector3f crossing =
          viewpoint + (p - viewpoint) * ((eye_height - rim.top) / (eye_height - height));
      const Eigen::Vector2f on_table(u.dot(crossing), v.dot(crossing));
      through +=
          deep_enough.contains(on_table) && insideDistance(rim.hull, on_table) >= kOpeningInset;
    }
    return through >= kMinSeenThroughFraction * clusters[inside]->size();
  };

  std::vector<int> parent(clusters.size());
  std::iota(parent.begin(), parent.end(), 0);
  std::vector<bool> open(clusters.size(), false);  // an inside reaching the rim was seen in it
  for (size_t inside = 0; inside < clusters.size(); ++inside) {
    for (size_t outer = 0; outer < clusters.size(); ++outer) {
      if (outer != inside && !keptApart(side_by_side, inside, outer) &&
          seenThroughOpening(inside, footprints[outer], true)) {
        open[outer] = true;
        parent[root(parent, static_cast<int>(inside))] = root(parent, static_cast<int>(outer));
      }
    }
  }
  // The split may cut a bowl's concave inside into pieces, and which pieces varies from run to
  // run on the same cloud (seen in one process; cause not found); a piece that ends well below
  // the rim (the bottom) joins an object known to be open when it is seen through that object's
  // opening, the hull of the whole object so far. Only then: a box under a box is below the
  // upper top too.
  std::vector<std::vector<size_t>> groups(clusters.size());
  for (size_t c = 0; c < clusters.size(); ++c) {
    groups[root(parent, static_cast<int>(c))].push_back(c);
  }
  for (size_t outer = 0; outer < clusters.size(); ++outer) {
    if (!open[outer]) continue;
    const int group = root(parent, static_cast<int>(outer));
    const Footprint rim = footprintOf(groups[group]);
    for (size_t piece = 0; piece < clusters.size(); ++piece) {
      if (groups[piece].size() == 1 && !keptApart(side_by_side, piece, outer) &&
          root(parent, static_cast<int>(piece)) == static_cast<int>(piece) &&
          seenThroughOpening(piece, rim, false)) {
        parent[piece] = group;
      }
    }
  }
  return mergeGroups(clusters, parent, side_by_side);
}

std::vector<CloudPtr> joinPartsHiddenInTheMiddle(std::vector<CloudPtr> clusters, const Plane& table,
                                                 const Eigen::Vector3f& viewpoint,
                                                 std::vector<int>* side_by_side) {
  if (clusters.size() < 3) return clusters;  // two parts and an occluder
  std::vector<float> top(clusters.size(), -std::numeric_limits<float>::max());
  for (size_t c = 0; c < clusters.size(); ++c) {
    for (const auto& p : *clusters[c])
      top[c] = std::max(top[c], table.signedDistance(p.getVector3fMap()));
  }
  // Each cluster's nearest range from the viewpoint and the cone of its lines of sight (axis:
  // the sight to its centroid, half-angle: the widest to a point), made at the first sample it
  // is asked about, so that the gap samples skip the clusters that cannot hide them without a
  // look at their points.
  struct SightCone {
    bool made = false;
    float nearest = std::numeric_limits<float>::max();
    Eigen::Vector3d axis = Eigen::Vector3d::Zero();
    double half_angle = 0.0;  // [rad]
  };
  std::vector<SightCone> cones(clusters.size());
  auto coneOf = [&](size_t c) -> const SightCone& {
    SightCone& cone = cones[c];
    if (cone.made) return cone;
    cone.made = true;
    Eigen::Vector3d sum = Eigen::Vector3d::Zero();
    for (const auto& p : *clusters[c]) {
      const Eigen::Vector3f to = p.getVector3fMap() - viewpoint;
      cone.nearest = std::min(cone.nearest, to.norm());
      sum += to.cast<double>();
    }
    cone.axis = sum.normalized();
    double least_cosine = 1.0;
    for (const auto& p : *clusters[c]) {
      const Eigen::Vector3d to = (p.getVector3fMap() - viewpoint).cast<double>();
      least_cosine = std::min(least_cosine, to.dot(cone.axis) / to.norm());
    }
    cone.half_angle = std::acos(std::clamp(least_cosine, -1.0, 1.0));
    return cone;
  };
  // Is the point `sample` hidden from the viewpoint by cluster `occluder`?
  auto hiddenBy = [&](const Eigen::Vector3f& sample, size_t occluder) {
    const Eigen::Vector3f sight = sample - viewpoint;
    const float range = sight.norm();
    const SightCone& cone = coneOf(occluder);
    // No point near enough, or the sight's angle to every point exceeds kSightAngle (angles
    // add up: to the axis <= to a point + the point's to the axis), with room for rounding.
    if (!(cone.nearest < range - kOccluderInFront)) return false;
    const double off_axis =
        std::acos(std::clamp(sight.cast<double>().normalized().dot(cone.axis), -1.0, 1.0));
    if (off_axis > cone.half_angle + kSightAngle + kAngleSlack) return false;
    const float min_cos = std::cos(kSightAngle);
    for (const auto& point : *clusters[occluder]) {
      const Eigen::Vector3f to = point.getVector3fMap() - viewpoint;
      const float r = to.norm();
      if (r < range - kOccluderInFront && to.dot(sight) >= min_cos * r * range) return true;
    }
    return false;
  };
  // The closest pair of points of clusters a and b (squared distance), as a scan over a's
  // points with a nearest-neighbour search in b finds it (the first of a's points at the least
  // distance), without searching for the points of a that cannot come nearer than the best so
  // far: a's points are visited in the order of their distance to b's bounding box, and the
  // scan stops where that distance exceeds the best. Bounds are taken slightly below the
  // squared distance to a box, so that float rounding never skips a point that the search's
  // distance would tie with. Each search looks only within the best so far (SlabNearest, one per
  // cluster, built once); where two points of b tie for nearest, a k-d tree picks as it did.
  constexpr float kBoundSlack = 0.9999f;
  std::vector<Eigen::AlignedBox3f> boxes(clusters.size());
  for (size_t c = 0; c < clusters.size(); ++c) {
    for (const auto& p : *clusters[c]) boxes[c].extend(p.getVector3fMap());
  }
  std::vector<std::unique_ptr<SlabNearest>> slabs(clusters.size());
  std::vector<std::unique_ptr<pcl::KdTreeFLANN<Point>>> trees(clusters.size());
  auto closestPair = [&](size_t a, size_t b, float& squared_distance, Eigen::Vector3f& from,
                         Eigen::Vector3f& to) {
    if (clusters[a]->empty() || clusters[b]->empty()) return false;
    std::vector<std::pair<float, int>> order;
    order.reserve(clusters[a]->size());
    for (size_t i = 0; i < clusters[a]->size(); ++i) {
      const float bound = boxes[b].squaredExteriorDistance((*clusters[a])[i].getVector3fMap());
      order.emplace_back(kBoundSlack * bound, static_cast<int>(i));
    }
    // A heap gives the points in the sorted order, and the scan stops after a few of them: a
    // full sort cost more than the scan.
    const auto later = std::greater<std::pair<float, int>>();
    std::make_heap(order.begin(), order.end(), later);
    if (!slabs[b]) slabs[b] = std::make_unique<SlabNearest>(*clusters[b]);
    float best = std::numeric_limits<float>::max();
    int best_a = -1, best_b = -1;
    for (auto end = order.end(); end != order.begin(); --end) {
      std::pop_heap(order.begin(), end, later);
      const auto [bound, i] = *(end - 1);
      if (bound > best) break;
      SlabNearest::Hit hit;
      if (!slabs[b]->nearest((*clusters[a])[i].getVector3fMap(), best, hit) ||
          !(hit.squared < best || (hit.squared == best && i < best_a))) {
        continue;
      }
      if (hit.tied) {
        if (!trees[b]) {
          trees[b] = std::make_unique<pcl::KdTreeFLANN<Point>>();
          trees[b]->setInputCloud(clusters[b]);
        }
        std::vector<int> nearest(1);
        std::vector<float> squared(1);
        trees[b]->nearestKSearch((*clusters[a])[i], 1, nearest, squared);
        hit.index = nearest[0];
      }
      best = hit.squared, best_a = i, best_b = hit.index;
    }
    if (best_a < 0) return false;
    squared_distance = best;
    from = (*clusters[a])[best_a].getVector3fMap();
    to = (*clusters[b])[best_b].getVector3fMap();
    return true;
  };
  // Whether clusters a and b touch, computed once per pair when asked.
  std::vector<int8_t> touching(clusters.size() * clusters.size(), -1);
  auto touch = [&](size_t a, size_t b) {
    int8_t& known = touching[std::min(a, b) * clusters.size() + std::max(a, b)];
    if (known < 0) {
      float squared = 0.0f;
      Eigen::Vector3f from, to;
      known = boxes[a].squaredExteriorDistance(boxes[b]) < kTouching * kTouching &&
              closestPair(a, b, squared, from, to) && squared < kTouching * kTouching;
    }
    return known > 0;
  };
  // Two objects with a third touching both between them (a block of touching objects, split
  // apart) are not the two sides of one object: its middle would be that third object.
  auto bridged = [&](size_t a, size_t b) {
    for (size_t c = 0; c < clusters.size(); ++c) {
      if (c != a && c != b && touch(a, c) && touch(b, c)) return true;
    }
    return false;
  };
  std::vector<int> parent(clusters.size());
  std::iota(parent.begin(), parent.end(), 0);
  // A cluster under a level top face of its own (split from a cluster, cluster_split.h) is a
  // whole object, not one side of an object hidden in the middle (issue 15): low objects behind
  // a row of taller ones fall into Euclidean clusters of their own, one per gap, and were joined;
  // a small cluster left whole between parts of a touching block chained six of them into one
  // (rendered scene 1065472284); the legs of a box lying across two joined a neighbouring pile's
  // lower box. The halves of an occluded object are clusters left whole (OSD 25-32).
  for (size_t a = 0; a < clusters.size(); ++a) {
    for (size_t b = a + 1; b < clusters.size(); ++b) {
      if (std::abs(top[a] - top[b]) > kSameTop || root(parent, a) == root(parent, b) ||
          underOwnTop(side_by_side, a) || underOwnTop(side_by_side, b))
        continue;
      if (kBoundSlack * boxes[a].squaredExteriorDistance(boxes[b]) > kMaxGap * kMaxGap) continue;
      // The shortest segment between the two parts.
      float shortest = 0.0f;
      Eigen::Vector3f from = Eigen::Vector3f::Zero(), to = from;
      if (!closestPair(a, b, shortest, from, to)) continue;
      const float gap = std::sqrt(shortest);
      if (gap > kMaxGap || gap < kTouching || bridged(a, b)) continue;
      // Samples every kGapStep at least kGapEnd from both ends; the midpoint of a shorter gap.
      const float first = std::min(kGapEnd, gap / 2), last = std::max(gap - kGapEnd, gap / 2);
      bool explained = true;
      for (float t = first; t <= last && explained; t += kGapStep) {
        const Eigen::Vector3f sample = from + (to - from) * (t / gap);
        bool hidden = false;
        for (size_t c = 0; c < clusters.size() && !hidden; ++c) {
          hidden = c != a && c != b && hiddenBy(sample, c);
        }
        explained = hidden;
      }
      if (explained) parent[root(parent, a)] = root(parent, b);
    }
  }
  return mergeGroups(clusters, parent, side_by_side);
}

}  // namespace tabletop_shapes
