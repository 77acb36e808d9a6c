// Splitting touching or stacked objects at concave seams: supervoxels joined by local convexity
// (LCCP). Small parts rejoin a neighbour they do not meet at a concave seam, so a handle or a
// noisy patch does not become an object.
#include "tabletop_shapes/core/cluster_split.h"

#include "tabletop_shapes/core/convex_polygon.h"
#include "tabletop_shapes/core/grid_neighbours.h"
#include "tabletop_shapes/core/grid_search.h"
#include "tabletop_shapes/core/parallel.h"
#include "tabletop_shapes/core/top_step_split.h"
#include "tabletop_shapes/core/voxel_key.h"

#include <pcl/segmentation/lccp_segmentation.h>
#include <pcl/segmentation/supervoxel_clustering.h>

#include <Eigen/Geometry>

#include <algorithm>
#include <cmath>
#include <functional>
#include <limits>
#include <map>
#include <optional>
#include <numeric>
#include <set>
#include <unordered_map>

namespace tabletop_shapes {
namespace {

constexpr float kVoteSearchCell = 0.01f;  // GridSearch cell of the neighbour votes [m]
// LCCP segments of at most this many supervoxels join a neighbour (LCCP's min segment size).
constexpr size_t kMaxSmallSegment = 3;
// Parts whose tops lie within this of each other are one object (see mergeUnseparatedParts).
constexpr float kStackStep = 0.02f;  // [m]

// One supervoxel adjacency between two LCCP parts, and whether LCCP found it convex.
struct Seam {
  uint32_t a, b;
  bool convex;
};

struct ConvexParts {
  std::vector<uint32_t> labels;  // part label of every point; 0 for points no supervoxel holds
  std::vector<Seam> seams;       // supervoxel adjacencies between different parts
};

// A point's coordinates in the table plane (its footprint).
class TableProjection {
 public:
  explicit TableProjection(const Plane& table)
      : u_(table.normal.unitOrthogonal()), v_(table.normal.cross(u_)) {}
  Eigen::Vector2f operator()(const Point& p) const {
    return {u_.dot(p.getVector3fMap()), v_.dot(p.getVector3fMap())};
  }

 private:
  Eigen::Vector3f u_, v_;
};

// How far depth noise smears a vertical face sideways at `range` [m]; a lower object may stick
// out from under a wider one by only a centimetre (a box lying across two): the floor stays
// below that.
float sidewaysSmear(float range, const ClusteringParams& params) {
  return std::max(0.005f, 2.0f * params.split_depth_step * range * range);
}

// The height above the table of the cloud's highest point.
float topOf(const Cloud& cloud, const Plane& table) {
  float top = -std::numeric_limits<float>::infinity();
  for (const auto& p : cloud) top = std::max(top, table.signedDistance(p.getVector3fMap()));
  return top;
}

// Points beside or over another part that show a stack: the lower part of a stack needs
// split_min_points, a tenth of them beyond the smear is plenty of evidence.
int stackEvidencePoints(const ClusteringParams& params) {
  return std::max(10, params.split_min_points / 10);
}

Eigen::Vector3f centroidOf(const Cloud& cloud) {
  Eigen::Vector3f centroid = Eigen::Vector3f::Zero();
  for (const auto& p : cloud) centroid += p.getVector3fMap();
  return centroid / static_cast<float>(std::max<size_t>(cloud.size(), 1));
}

// Supervoxel edge length for a cluster at `range` from the camera. Beyond ~1.5 m the depth
// steps of a disparity camera (growing with range^2) cut a surface into terraces farther apart
// than 6 mm voxels; non-adjacent voxels leave a disconnected supervoxel graph, and its pieces
// became objects of their own. Voxels 1.5 steps long keep neighbouring terraces adjacent.
float supervoxelResolution(float range, const ClusteringParams& params) {
  // A little coarser than the preprocessing grid (5 mm), so neighbouring surface samples are
  // adjacent voxels.
  const float base = std::max(0.006f, params.split_patch_size / 4);
  return std::max(base, 1.5f * params.split_depth_step * range * range);
}

// LCCP's merge of small segments (pcl::LCCPSegmentation::mergeSmallSegments), with the
// supervoxels visited in label order: a segment of at most `max_supervoxels` supervoxels joins
// its largest neighbouring segment (the last of equal ones), unless that one joined another
// before; repeated while any joins.
void mergeSmallSegments(const std::multimap<uint32_t, uint32_t>& adjacency, size_t max_supervoxels,
                        std::map<uint32_t, uint32_t>& part_of_supervoxel) {
  std::set<uint32_t> joined;
  for (bool merged = true; merged;) {
    merged = false;
    std::map<uint32_t, size_t> size;
    std::map<uint32_t, std::set<uint32_t>> neighbours;
    for (const auto& [supervoxel, part] : part_of_supervoxel) ++size[part];
    for (const auto& [a, b] : adjacency) {
      const uint32_t part_a = part_of_supervoxel[a], part_b = part_of_supervoxel[b];
      if (part_a != part_b) neighbours[part_a].insert(part_b), neighbours[part_b].insert(part_a);
    }
    for (auto& [supervoxel, part] : part_of_supervoxel) {
      if (size[part] > max_supervoxels) continue;
      uint32_t largest = part;
      for (const uint32_t other : neighbours[part]) {
        if (size[other] >= size[largest]) largest = other;
      }
      if (largest == part || joined.count(largest)) continue;
      // The rest of `part` follows (its size stays as it was until the next round).
      if (joined.insert(part).second) size[largest] += size[part];
      part = largest;
      merged = true;
    }
  }
}

ConvexParts convexParts(const CloudConstPtr& cluster, const ClusteringParams& params) {
  const float voxel = supervoxelResolution(centroidOf(*cluster).norm(), params);
  pcl::SupervoxelClustering<Point> supervoxel(voxel, std::max(params.split_patch_size, 2 * voxel));
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
  // PCL's graph keeps its supervoxels in the order of their heap addresses (boost setS), and
  // LCCP visits them in that order when it numbers its segments and when it merges the small
  // ones, whose outcome depends on the order. The addresses change with the threads'
  // allocations, and so did the objects from run to run. So LCCP only groups (the groups do not
  // depend on the order), and the segments are numbered and merged here in supervoxel order.
  lccp.setMinSegmentSize(0);
  lccp.setInputSupervoxels(patches, adjacency);
  lccp.segment();
  std::map<uint32_t, uint32_t> part_of_supervoxel;
  lccp.getSupervoxelToSegmentMap(part_of_supervoxel);
  std::map<uint32_t, uint32_t> numbered;  // LCCP's segment label -> ours
  for (auto& [supervoxel, part] : part_of_supervoxel)
    part = numbered.emplace(part, static_cast<uint32_t>(numbered.size() + 1)).first->second;
  mergeSmallSegments(adjacency, kMaxSmallSegment, part_of_supervoxel);

  pcl::PointCloud<pcl::PointXYZL>::Ptr labelled = supervoxel.getLabeledCloud();
  ConvexParts parts;
  parts.labels.assign(cluster->size(), 0);
  for (size_t i = 0; i < parts.labels.size() && i < labelled->size(); ++i) {
    const auto part = part_of_supervoxel.find((*labelled)[i].label);
    if (part != part_of_supervoxel.end()) parts.labels[i] = part->second;
  }

  pcl::LCCPSegmentation<Point>::SupervoxelAdjacencyList graph;
  lccp.getSVAdjacencyList(graph);
  for (auto [edge, end] = boost::edges(graph); edge != end; ++edge) {
    const uint32_t a = part_of_supervoxel[graph[boost::source(*edge, graph)]];
    const uint32_t b = part_of_supervoxel[graph[boost::target(*edge, graph)]];
    if (a != b) parts.seams.push_back({a, b, graph[*edge].is_convex});
  }
  return parts;
}

// The kVoters nearest points of every point of a cluster (itself among them), found at once
// (GridSearch::forEachNearestKIndices: the lists of one nearestKSearch per point): the merges
// below count them again for every part at every round.
constexpr int kVoters = 16;
class NearestOfEach {
 public:
  explicit NearestOfEach(const CloudConstPtr& cluster)
      : count_(cluster->size(), 0), nearest_(cluster->size() * kVoters) {
    // The 16 nearest of 5 mm voxel centroids lie within about a centimetre.
    GridSearch<Point> search(kVoteSearchCell, false);
    search.setInputCloud(cluster);
    // Each point's slots are its own: the threads write different ones. A single cluster to
    // split (one pile on the table) gets every core.
    search.forEachNearestKIndices(
        kVoters,
        [&](int i, const pcl::Indices& nearest) {
          count_[i] = static_cast<int>(nearest.size());
          std::copy(nearest.begin(), nearest.end(), nearest_.begin() + i * kVoters);
        },
        freeWorkerThreads());
  }
  template <typename Visit>
  void forEachOf(size_t i, Visit&& visit) const {
    for (int k = 0; k < count_[i]; ++k) visit(nearest_[i * kVoters + k]);
  }

 private:
  std::vector<int> count_;    // per point: how many it has (fewer only in a tiny cluster)
  std::vector<int> nearest_;  // kVoters slots per point
};

// Points of other parts among the kVoters nearest neighbours of `part`'s points, per part.
std::map<uint32_t, int> neighbourVotes(const NearestOfEach& nearest,
                                       const std::vector<uint32_t>& labels, uint32_t part) {
  std::map<uint32_t, int> votes;
  for (size_t i = 0; i < labels.size(); ++i) {
    if (labels[i] != part) continue;
    nearest.forEachOf(i, [&](int j) {
      if (labels[j] != part && labels[j] != 0) ++votes[labels[j]];
    });
  }
  return votes;
}

void relabel(ConvexParts& parts, uint32_t from, uint32_t to) {
  std::replace(parts.labels.begin(), parts.labels.end(), from, to);
  for (Seam& seam : parts.seams) {
    if (seam.a == from) seam.a = to;
    if (seam.b == from) seam.b = to;
  }
}

// How two parts meet: 2 along a (mostly) convex seam, 1 without a supervoxel seam (they only
// lie close), 0 along a mostly concave seam.
int seamRank(const std::vector<Seam>& seams, uint32_t part, uint32_t other) {
  int convex = 0, concave = 0;
  for (const Seam& seam : seams) {
    if ((seam.a == part && seam.b == other) || (seam.a == other && seam.b == part))
      ++(seam.convex ? convex : concave);
  }
  if (convex + concave == 0) return 1;
  return convex >= concave ? 2 : 0;
}

// The neighbour `part` joins: the one it touches most among those it continues convexly, else
// among those it only lies close to, else among those it meets at a concave seam.
uint32_t bestNeighbour(const std::map<uint32_t, int>& votes, const std::vector<Seam>& seams,
                       uint32_t part) {
  uint32_t best = 0;
  int rank = -1;
  for (const auto& [label, n] : votes) {
    const int r = seamRank(seams, part, label);
    if (r > rank || (r == rank && n > votes.at(best))) {
      best = label;
      rank = r;
    }
  }
  return best;
}

// Unlabelled points (0) and parts below min_points join the neighbouring part chosen by
// bestNeighbour, smallest first: across a concave seam only when they touch nothing else (a
// handle). A thin strip of a lower box's top face around a box standing on it touches the
// upper box most, but meets it at the concave seam.
void mergeSmallParts(const NearestOfEach& nearest, int min_points, ConvexParts& parts) {
  std::vector<uint32_t>& labels = parts.labels;
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
    uint32_t target =
        bestNeighbour(neighbourVotes(nearest, labels, smallest), parts.seams, smallest);
    if (target == 0) {  // touches no other part: join the largest
      for (const auto& [label, n] : size) {
        if (label != smallest && label != 0 && (target == 0 || n > size[target])) target = label;
      }
    }
    relabel(parts, smallest, target);
  }
}

// Whether two parts stand one over the other rather than side by side: most points of the
// smaller lie over the footprint of the larger (within `smear`). The inside of a cup lies within
// its rim, a box face cut off by noise along the edge of the face next to it; two objects
// touching side by side cover different parts of the table.
bool footprintsOverlap(const Cloud& cluster, const std::vector<uint32_t>& labels, uint32_t a,
                       uint32_t b, const TableProjection& onTable, float smear) {
  std::vector<Eigen::Vector2f> footprint_a, footprint_b;
  for (size_t i = 0; i < labels.size(); ++i) {
    if (labels[i] == a) footprint_a.push_back(onTable(cluster[i]));
    if (labels[i] == b) footprint_b.push_back(onTable(cluster[i]));
  }
  if (footprint_a.size() > footprint_b.size()) std::swap(footprint_a, footprint_b);
  const std::vector<Eigen::Vector2f> hull = convexHull2d(footprint_b);
  if (hull.size() < 3) return true;  // a degenerate larger part: no footprint to judge by
  const PolygonEdges edges(hull);
  const auto over = std::count_if(footprint_a.begin(), footprint_a.end(),
                                  [&](const auto& q) { return edges.insideDistance(q) >= -smear; });
  return 2 * static_cast<size_t>(over) >= footprint_a.size();
}

// Cells of the footprint grid in hasFlatTop [m]: two voxels of the preprocessing grid.
constexpr float kFootprintCell = 0.01f;
// A top face: the points within kTopBand of a part's highest point (kStackStep: the highest
// point is a noisy one) covering at least kFlatTopCover of its footprint cells, and at least
// kMinTopCells cells (20 cm^2: a can 5 cm across; a mug's handle, 1-2 cm wide, is smaller).
constexpr float kTopBand = kStackStep;
constexpr float kFlatTopCover = 0.5f;
constexpr size_t kMinTopCells = 20;
// Side by side, tops at least this far apart [m]: the halves of one cup's rim or one box's top
// cut apart by noise end at the same height within a few millimetres.
constexpr float kTopStep = 0.01f;
// The two halves of one top cut by an object lying across it end within this of each other [m]
// (learn19 / learn21: 3-4 mm apart); at kTopStep two boxes of a block meeting at a corner,
// tops 8-9 mm apart, a taller neighbour over the corner, were joined.
constexpr float kOneTopFace = 0.006f;

// Whether the part has a top face of its own covering most of its footprint, as the top of a
// box or can does (its sides project onto the top's edge). A bowl's or mug's rim is a thin ring
// around the inside seen within it; a piece of it cut off by noise is not flat.
bool hasFlatTop(const Cloud& cluster, const std::vector<uint32_t>& labels, uint32_t part,
                float part_top, const Plane& table, const TableProjection& onTable) {
  std::set<uint64_t> footprint, top_face;
  for (size_t i = 0; i < labels.size(); ++i) {
    if (labels[i] != part) continue;
    const Eigen::Vector2f q = onTable(cluster[i]) / kFootprintCell;
    const uint64_t cell =
        voxel_key::pack(voxel_key::floorToInt(q.x()), voxel_key::floorToInt(q.y()), 0);
    footprint.insert(cell);
    if (table.signedDistance(cluster[i].getVector3fMap()) >= part_top - kTopBand)
      top_face.insert(cell);
  }
  return top_face.size() >= kMinTopCells && top_face.size() >= kFlatTopCover * footprint.size();
}

// Neighbouring parts rejoin when no concave seam parts them, or when their tops lie within
// kStackStep of each other, unless they stand side by side. On a table a concave seam between
// objects that matters here is one object standing or leaning on another, whose top then rises
// above the lower one's, or two objects touching side by side, each over its own part of the
// table under its own flat top (a block of boxes and cans; issue 15). Parts of one object cut
// apart by noise or by the concave inside of a cup or bowl end at the same top (rim) and are
// joined again. Parts that touch without any supervoxel seam between them were cut apart by a
// gap in the samples (an edge lost to the camera's near range, depth steps), not by a seam,
// unless side by side: then the gap is the depth jump from one object's top edge to the one
// behind it. (Touching objects whose tops lie within kTopStep of each other, or meet without
// a concave seam, stay one cluster.)
void mergeUnseparatedParts(const Cloud& cluster, const NearestOfEach& nearest, const Plane& table,
                           float smear, ConvexParts& parts) {
  const TableProjection onTable(table);
  std::vector<uint32_t>& labels = parts.labels;
  auto sideBySide = [&](uint32_t a, float a_top, uint32_t b, float b_top) {
    return std::abs(a_top - b_top) >= kTopStep &&
           !footprintsOverlap(cluster, labels, a, b, onTable, smear) &&
           hasFlatTop(cluster, labels, a, a_top, table, onTable) &&
           hasFlatTop(cluster, labels, b, b_top, table, onTable);
  };
  for (bool merged = true; merged;) {
    merged = false;
    std::map<uint32_t, float> top, bottom;
    for (size_t i = 0; i < labels.size(); ++i) {
      const float h = table.signedDistance(cluster[i].getVector3fMap());
      auto it = top.find(labels[i]);
      if (it == top.end()) {
        top[labels[i]] = bottom[labels[i]] = h;
      } else {
        it->second = std::max(it->second, h);
        bottom[labels[i]] = std::min(bottom[labels[i]], h);
      }
    }
    // The higher of two parts rests on the lower's flat top: its lowest point lies no deeper
    // than kStackStep under it (a can lying on a box: the contact line under the can is hidden,
    // so no supervoxel seam joins them). A depth-step terrace of one face has no flat top.
    auto restsOnTop = [&](uint32_t a, uint32_t b) {
      const uint32_t higher = top[a] > top[b] ? a : b, lower = higher == a ? b : a;
      return bottom[higher] >= top[lower] - kStackStep &&
             hasFlatTop(cluster, labels, lower, top[lower], table, onTable);
    };
    for (const auto& [part, part_top] : top) {
      for (const auto& [other, n] : neighbourVotes(nearest, labels, part)) {
        const bool same_top = std::abs(top[other] - part_top) <= kStackStep;
        if ((same_top || (seamRank(parts.seams, part, other) == 1 && !restsOnTop(part, other))) &&
            !sideBySide(part, part_top, other, top[other])) {
          relabel(parts, part, other);
          merged = true;
          break;
        }
      }
      if (merged) break;
    }
  }
}

// ---- side by side under their own tops (issue 15) ----
// Touching objects whose tops lie within kTopStep of each other, or whose front faces form one
// plane, meet at no concave seam that parts them; what tells them apart is the top: each
// object's points lie under its own level top face, and one solid has one. Heights on a
// footprint grid (kFootprintCell), each cell its highest point: cells of one top face differ by
// less than kTopFaceStep from their neighbours (Kinect depth steps at 1.3 m are ~5 mm, about
// 3 mm along up seen 40-55 deg down), the tops of touching neighbours mostly by more.
constexpr float kTopFaceStep = 0.006f;  // [m]
// A cell of a top face spreads over at most this [m]: depth noise at 1.3 m spreads a 1 cm
// cell's points over up to 1 cm along up.
constexpr float kNoisyTopSpread = 2.0f * kTopFaceStep;
// A top face is level: its cells' heights spread over less than this [m] (a lying can's or a
// cone's side chains cells down its slope).
constexpr float kTopFaceSpread = 0.02f;
// A top face covers at least this share of its outline (a box top or can lid does; a mug's
// rim or a bottle's shoulder is a ring).
constexpr float kTopFaceFill = 0.6f;
// A top face is at least this wide [cells]: a strip down a lying can's side is 1-2 cells wide.
constexpr float kTopFaceWidth = 3.0f;

// The width of a convex polygon: its smallest extent across, over its edges' directions.
float widthOf(const std::vector<Eigen::Vector2f>& hull) {
  float width = std::numeric_limits<float>::infinity();
  for (size_t i = 0; i < hull.size(); ++i) {
    const Eigen::Vector2f edge = hull[(i + 1) % hull.size()] - hull[i];
    const Eigen::Vector2f across = Eigen::Vector2f(-edge.y(), edge.x()).normalized();
    float extent = 0.0f;
    for (const Eigen::Vector2f& corner : hull)
      extent = std::max(extent, across.dot(corner - hull[i]));
    width = std::min(width, extent);
  }
  return width;
}

struct FootprintCell {
  int64_t x, y;
  float height;     // of its highest point above the table
  float low;        // of its lowest point
  int region = -1;  // cells joined by kTopFaceStep steps; -1 in a steep cell
  int id = -1;      // 0, 1, ... in the order the cells were first met: an index for flat arrays
  // A vertical face (or an edge) projects onto the cell: it joins no top face, or the faces of
  // a box behind a lower one would chain both tops into one region.
  bool steep() const { return height - low > kTopFaceStep; }
  // Steep by depth noise only: a vertical face or an edge spreads over centimetres.
  bool noisyTop() const { return height - low <= kNoisyTopSpread; }
};

struct TopFace {
  std::vector<Eigen::Vector2f> outline;  // convex hull of its points' footprints
  float height;                          // its highest cell
  int parted_by_a_gap = -1;              // faces cut from one region along gaps share a number >= 0
};

// The area of a counter-clockwise polygon.
float areaOf(const std::vector<Eigen::Vector2f>& hull) {
  float area = 0.0f;
  for (size_t i = 0; i < hull.size(); ++i) {
    const Eigen::Vector2f &a = hull[i], &b = hull[(i + 1) % hull.size()];
    area += 0.5f * (a.x() * b.y() - b.x() * a.y());
  }
  return area;
}

// The cells a filled convex region of this outline (cell centres) holds: its area, half its
// boundary cells, 1.
float filledCells(const std::vector<Eigen::Vector2f>& hull) {
  float perimeter = 0.0f;
  for (size_t i = 0; i < hull.size(); ++i)
    perimeter += (hull[(i + 1) % hull.size()] - hull[i]).norm();
  return areaOf(hull) + 0.5f * perimeter + 1.0f;
}

// ---- one region, several objects of the same height: split at the necks of its outline ----
// Neighbours whose tops lie within kTopFaceStep form one region. Where one rectangle or circle
// cannot explain its outline (a can beside a box, two cans side by side), the outline narrows
// between them: the depth of its cells (distance to the nearest cell outside, in cells) has a
// peak in each object and a saddle at the neck between. Two peaks stay apart when the saddle
// is below kNeckRatio of the smaller peak, and the smaller peak is at least kMinPeakDepth (an
// object 5 cm across: noise along an outline makes shallow dents, not objects). A single box or
// can has one peak or a ridge (no neck); an L-shaped outline peaks at its corner.
constexpr float kNeckRatio = 0.7f;
constexpr float kMinPeakDepth = 2.5f;  // [cells]
// A can beside a box of its own height meets it along a short tangent that 1 cm cells fill in:
// saddle / peak 0.73 in the unit test, above kNeckRatio; 0.8 for every region cut OSD learn1's
// box and learn43's can at noisy dents. A region whole at kNeckRatio is parted at up to
// kLidNeckRatio only into a can's lid (its outline fills at least kLidFill of the circle across
// it; 0.84-0.87 in the test) and a box's top (at least kBoxTopFill of the smallest rectangle
// around it; 0.96-0.99): a piece cut off a lid is no whole circle, a piece of a box top none.
constexpr float kLidNeckRatio = 0.8f;
constexpr float kLidFill = 0.75f;
constexpr float kBoxTopFill = 0.9f;
// An outside cell with at least this many of its 8 neighbours in the region is a hole in the
// face (a noisy cell), not its edge.
constexpr int kHoleNeighbours = 6;
// Only regions filling this share of their outline are split (see topFaces).
constexpr float kNeckSplitFill = 0.8f;

std::unordered_map<uint64_t, int> indexOfCells(const std::vector<const FootprintCell*>& region) {
  std::unordered_map<uint64_t, int> index_of;
  for (size_t i = 0; i < region.size(); ++i)
    index_of.emplace(voxel_key::pack(region[i]->x, region[i]->y, 0), static_cast<int>(i));
  return index_of;
}

// Calls visit(j) for the region's cells j among the 8 neighbours of its cell i.
template <typename Visit>
void forNeighboursInRegion(const std::vector<const FootprintCell*>& region,
                           const std::unordered_map<uint64_t, int>& index_of, int i,
                           Visit&& visit) {
  forGridNeighbours(index_of, region[i]->x, region[i]->y, [&](uint64_t, int j) { visit(j); });
}

// Each cell's distance to the nearest cell outside its region, in cells.
std::vector<float> depthsInRegion(const std::vector<const FootprintCell*>& region,
                                  const std::unordered_map<uint64_t, int>& index_of) {
  std::unordered_map<uint64_t, Eigen::Vector2f> outside;
  auto inRegion = [&](int64_t x, int64_t y) {
    return index_of.count(voxel_key::pack(x, y, 0)) > 0;
  };
  for (const FootprintCell* cell : region) {
    for (int64_t dx = -1; dx <= 1; ++dx) {
      for (int64_t dy = -1; dy <= 1; ++dy) {
        const int64_t x = cell->x + dx, y = cell->y + dy;
        if (inRegion(x, y) || outside.count(voxel_key::pack(x, y, 0))) continue;
        int neighbours_in = 0;
        for (int64_t ex = -1; ex <= 1; ++ex) {
          for (int64_t ey = -1; ey <= 1; ++ey) neighbours_in += inRegion(x + ex, y + ey);
        }
        if (neighbours_in < kHoleNeighbours)
          outside.emplace(voxel_key::pack(x, y, 0), Eigen::Vector2f(x, y));
      }
    }
  }
  std::vector<float> depth(region.size(), std::numeric_limits<float>::infinity());
  for (size_t i = 0; i < region.size(); ++i) {
    const Eigen::Vector2f at(region[i]->x, region[i]->y);
    for (const auto& [key, edge] : outside) depth[i] = std::min(depth[i], (edge - at).norm());
  }
  return depth;
}

// The share of the smallest rectangle around the convex outline `hull` that it fills, over the
// rectangles along its edges: 1 for a rectangle at any angle, pi / 4 for a circle.
float rectangleFill(const std::vector<Eigen::Vector2f>& hull) {
  float smallest = std::numeric_limits<float>::infinity();
  for (size_t i = 0; i < hull.size(); ++i) {
    const Eigen::Vector2f along = (hull[(i + 1) % hull.size()] - hull[i]).normalized();
    const Eigen::Vector2f across(-along.y(), along.x());
    float low = 0.0f, high = 0.0f, width = 0.0f;
    for (const Eigen::Vector2f& corner : hull) {
      low = std::min(low, along.dot(corner - hull[i]));
      high = std::max(high, along.dot(corner - hull[i]));
      width = std::max(width, std::abs(across.dot(corner - hull[i])));
    }
    smallest = std::min(smallest, (high - low) * width);
  }
  return areaOf(hull) / smallest;
}

// The share of the circle across the convex outline's widest extent that it fills: 1 for a
// circle, 0.64 for a square.
float discFill(const std::vector<Eigen::Vector2f>& hull) {
  float diameter = 0.0f;
  for (const Eigen::Vector2f& a : hull) {
    for (const Eigen::Vector2f& b : hull) diameter = std::max(diameter, (a - b).norm());
  }
  return areaOf(hull) / (static_cast<float>(kPi) / 4.0f * diameter * diameter);
}

// The region's objects: its cells grouped by the peak they drain to (highest first, a
// watershed on the depths), peaks parted by a neck kept apart; groups below kMinTopCells join
// the neighbouring group they touch most.
std::vector<std::vector<const FootprintCell*>> splitAtNecks(
    const std::vector<const FootprintCell*>& region, float neck_ratio) {
  if (region.size() < 2 * kMinTopCells) return {region};
  const std::unordered_map<uint64_t, int> index_of = indexOfCells(region);
  const std::vector<float> depth = depthsInRegion(region, index_of);
  std::vector<int> order(region.size());
  std::iota(order.begin(), order.end(), 0);
  std::stable_sort(order.begin(), order.end(), [&](int a, int b) { return depth[a] > depth[b]; });
  // Union-find over cells: each group's root holds its peak.
  std::vector<int> parent(region.size(), -1);  // -1: not reached yet
  std::vector<float> peak(region.size(), 0.0f);
  auto root = [&](int i) {
    while (parent[i] != i) i = parent[i] = parent[parent[i]];
    return i;
  };
  auto forNeighbours = [&](int i, auto&& visit) {
    forNeighboursInRegion(region, index_of, i, visit);
  };
  std::vector<int> roots;
  for (int i : order) {
    roots.clear();
    int uphill = -1;  // the deepest neighbour reached: the cell drains to its peak
    forNeighbours(i, [&](int j) {
      if (parent[j] < 0) return;
      roots.push_back(root(j));
      if (uphill < 0 || depth[j] > depth[uphill]) uphill = j;
    });
    if (roots.empty()) {
      parent[i] = i;
      peak[i] = depth[i];
      continue;
    }
    std::sort(roots.begin(), roots.end(),
              [&](int a, int b) { return peak[a] != peak[b] ? peak[a] > peak[b] : a < b; });
    roots.erase(std::unique(roots.begin(), roots.end()), roots.end());
    for (size_t k = 1; k < roots.size(); ++k) {
      const float smaller_peak = peak[roots[k]];
      if (smaller_peak < kMinPeakDepth || depth[i] >= neck_ratio * smaller_peak)
        parent[roots[k]] = roots[0];
    }
    parent[i] = root(uphill);
  }
  std::map<int, std::vector<int>> groups;
  for (size_t i = 0; i < region.size(); ++i) groups[root(static_cast<int>(i))].push_back(i);
  while (groups.size() > 1) {
    auto smallest = std::min_element(groups.begin(), groups.end(), [](auto& a, auto& b) {
      return a.second.size() < b.second.size();
    });
    if (smallest->second.size() >= kMinTopCells) break;
    std::map<int, int> touching;
    for (int i : smallest->second) {
      forNeighbours(i, [&](int j) {
        if (root(j) != smallest->first) ++touching[root(j)];
      });
    }
    const int into = touching.empty()
                         ? -1
                         : std::max_element(touching.begin(), touching.end(), [](auto& a, auto& b) {
                             return a.second < b.second;
                           })->first;
    if (into < 0) {  // an island: no group to join, it stays apart and fails kMinTopCells
      break;
    }
    for (int i : smallest->second) {
      parent[i] = into;
      groups[into].push_back(i);
    }
    parent[smallest->first] = into;
    groups.erase(smallest);
  }
  std::vector<std::vector<const FootprintCell*>> objects;
  for (const auto& [group_root, members] : groups) {
    objects.emplace_back();
    for (int i : members) objects.back().push_back(region[i]);
  }
  return objects;
}

// The convex outline of the cells' centres.
std::vector<Eigen::Vector2f> outlineOf(const std::vector<const FootprintCell*>& cells) {
  std::vector<Eigen::Vector2f> centres;
  for (const FootprintCell* cell : cells) centres.emplace_back(cell->x + 0.5f, cell->y + 0.5f);
  return convexHull2d(std::move(centres));
}

// The region's objects side by side: parted at its necks, or into a can's lid and a box's top
// at a shallower one (kLidNeckRatio).
std::vector<std::vector<const FootprintCell*>> splitSideBySide(
    const std::vector<const FootprintCell*>& region) {
  std::vector<std::vector<const FootprintCell*>> objects = splitAtNecks(region, kNeckRatio);
  if (objects.size() > 1) return objects;
  std::vector<std::vector<const FootprintCell*>> lid_and_box = splitAtNecks(region, kLidNeckRatio);
  if (lid_and_box.size() != 2) return objects;
  auto lid = [](const std::vector<Eigen::Vector2f>& hull) {
    return hull.size() >= 3 && discFill(hull) >= kLidFill;
  };
  auto boxTop = [](const std::vector<Eigen::Vector2f>& hull) {
    return hull.size() >= 3 && rectangleFill(hull) >= kBoxTopFill;
  };
  const std::vector<Eigen::Vector2f> a = outlineOf(lid_and_box[0]), b = outlineOf(lid_and_box[1]);
  return (lid(a) && boxTop(b)) || (lid(b) && boxTop(a)) ? lid_and_box : objects;
}

// The region's cells under each top it holds: the flood fill chains the tops of touching
// objects of nearly one height (top_step_split.h).
std::vector<std::vector<const FootprintCell*>> topsOf(
    const std::vector<const FootprintCell*>& region) {
  std::vector<HeightCell> heights;
  for (const FootprintCell* cell : region) heights.push_back({cell->x, cell->y, cell->height});
  std::vector<std::vector<const FootprintCell*>> tops;
  for (const std::vector<int>& top : splitAtTopSteps(heights, kMinTopCells)) {
    tops.emplace_back();
    for (int i : top) tops.back().push_back(region[i]);
  }
  return tops;
}

// ---- one region, several objects of the same height: split along the gap between them ----
// Objects 5-10 mm apart whose tops lie within kTopFaceStep form one level region; when their
// tops meet along a straight side (two boxes side by side) the outline has no neck. What parts
// them is the gap: a straight corridor across the region in which no point of the top lies
// (the camera sees into the gap, or the farther object's face below its top), while a top's
// own points leave no such corridor. Projected onto the corridor's normal, in kGapBin bins,
// the top's points leave an empty run of at least kMinTopGap that is kGapContrast times the
// widest other empty run of that projection (1 cm or more away): the 5 mm voxel grid leaves
// empty runs up to ~5 mm at regular steps in the directions of its rows, a gap one.
constexpr float kGapBin = 0.001f;      // [m]
constexpr float kMinTopGap = 0.0035f;  // [m]
constexpr float kGapContrast = 2.0f;   // widest empty run / the next widest elsewhere
constexpr int kGapDirections = 90;     // corridor directions tried, 2 deg apart
constexpr int kMaxGapSplits = 3;       // a region parts into at most 2^3 objects
constexpr int kGapTextureCells = 5;    // cells beside a run that counts as texture (not an end)

// The region's cells parted along the best gap (see above), or the region itself.
std::vector<std::vector<const FootprintCell*>> splitAlongAGap(
    const std::vector<const FootprintCell*>& region, const std::vector<Eigen::Vector2f>& level) {
  if (region.size() < 2 * kMinTopCells || level.size() < 2 * kMinTopCells) return {region};
  float best_gap = 0.0f, best_cut = 0.0f;
  Eigen::Vector2f best_normal = Eigen::Vector2f::Zero();
  // Per bin: the lowest and highest projection of a point in it (none: lowest > highest), and the
  // region's cells up to it (cell centres), for the cells on each side of a run.
  std::vector<float> first_in_bin, last_in_bin;
  std::vector<int> cells_up_to_bin;
  for (int d = 0; d < kGapDirections; ++d) {
    const float angle = static_cast<float>(kPi) * d / kGapDirections;
    const Eigen::Vector2f normal(std::cos(angle), std::sin(angle));
    float low = std::numeric_limits<float>::infinity(), high = -low;
    for (const Eigen::Vector2f& q : level) {
      low = std::min(low, normal.dot(q));
      high = std::max(high, normal.dot(q));
    }
    const int bins = static_cast<int>((high - low) / kGapBin) + 1;
    first_in_bin.assign(bins, std::numeric_limits<float>::infinity());
    last_in_bin.assign(bins, -std::numeric_limits<float>::infinity());
    cells_up_to_bin.assign(bins + 1, 0);
    for (const Eigen::Vector2f& q : level) {
      const float at = normal.dot(q);
      const int b = std::min(bins - 1, static_cast<int>((at - low) / kGapBin));
      first_in_bin[b] = std::min(first_in_bin[b], at);
      last_in_bin[b] = std::max(last_in_bin[b], at);
    }
    for (const FootprintCell* cell : region) {
      const float at = normal.dot(Eigen::Vector2f(cell->x + 0.5f, cell->y + 0.5f) * kFootprintCell);
      ++cells_up_to_bin[std::clamp(static_cast<int>((at - low) / kGapBin) + 1, 0, bins)];
    }
    for (int b = 1; b <= bins; ++b) cells_up_to_bin[b] += cells_up_to_bin[b - 1];
    // The gaps between consecutive points, at least a bin wide, with kGapTextureCells cells of
    // the region on each side (the texture of the points, not the ragged ends); a cut needs
    // kMinTopCells on each side.
    float widest = 0.0f, widest_at = 0.0f;
    std::vector<std::pair<float, float>> runs;  // width, middle [m along normal]
    for (int b = 1; b < bins; ++b) {
      if (last_in_bin[b - 1] < first_in_bin[b - 1] || !(first_in_bin[b] > last_in_bin[b])) continue;
      int end = b;  // bin b - 1 holds points, b does not: the run ends at the next bin with one
      while (end < bins && first_in_bin[end] > last_in_bin[end]) ++end;
      if (end == bins) break;
      const int middle = (b + end) / 2;
      const int before = cells_up_to_bin[middle];
      const int after = static_cast<int>(region.size()) - before;
      if (std::min(before, after) >= kGapTextureCells) {
        const float from = last_in_bin[b - 1], to = first_in_bin[end];
        runs.emplace_back(to - from, 0.5f * (from + to));
        if (std::min(before, after) >= static_cast<int>(kMinTopCells) && runs.back().first > widest)
          std::tie(widest, widest_at) = runs.back();
      }
      b = end;
    }
    float next = 0.0f;
    for (const auto& [width, at] : runs) {
      if (std::abs(at - widest_at) >= kFootprintCell) next = std::max(next, width);
    }
    if (widest < kMinTopGap || widest <= best_gap) continue;
    if (widest < kGapContrast * next) continue;
    best_gap = widest;
    best_cut = widest_at;
    best_normal = normal;
  }
  if (best_gap == 0.0f) return {region};
  std::vector<std::vector<const FootprintCell*>> sides(2);
  for (const FootprintCell* cell : region) {
    const float at =
        best_normal.dot(Eigen::Vector2f(cell->x + 0.5f, cell->y + 0.5f) * kFootprintCell);
    sides[at < best_cut ? 0 : 1].push_back(cell);
  }
  for (const auto& side : sides) {
    if (side.size() < kMinTopCells || widthOf(outlineOf(side)) + 1.0f < kTopFaceWidth)
      return {region};
  }
  return sides;
}

// The cells within `outline` (cell centres) whose highest point lies at the level of a face
// from `bottom` to `top` (within kTopFaceStep): the face's own cells and the noisy ones of it
// that depth noise made steep (at 1.1-1.3 m a third of a box top's 1 cm cells spread over more
// than kTopFaceStep; issue 15). Only the cells of the outline's bounding box are looked up: a
// block of touching objects holds many faces, each a small part of its cells.
size_t levelCellsWithin(const std::vector<Eigen::Vector2f>& outline, float bottom, float top,
                        const std::unordered_map<uint64_t, FootprintCell>& cells) {
  Eigen::Vector2f low = outline.front(), high = outline.front();
  for (const Eigen::Vector2f& corner : outline)
    low = low.cwiseMin(corner), high = high.cwiseMax(corner);
  size_t level = 0;
  for (int64_t x = voxel_key::floorToInt(low.x()) - 1; x <= voxel_key::floorToInt(high.x()); ++x) {
    for (int64_t y = voxel_key::floorToInt(low.y()) - 1; y <= voxel_key::floorToInt(high.y());
         ++y) {
      const auto it = cells.find(voxel_key::pack(x, y, 0));
      if (it == cells.end()) continue;
      const FootprintCell& cell = it->second;
      level += cell.height >= bottom - kTopFaceStep && cell.height <= top + kTopFaceStep &&
               insideDistance(outline, {cell.x + 0.5f, cell.y + 0.5f}) >= 0.0f;
    }
  }
  return level;
}

// The level top faces of the cluster's objects: regions of the height grid of at least
// kMinTopCells cells, level and filled, not lying within the outline of a higher region (the
// inside of a cup or bowl seen within its rim).
std::vector<TopFace> topFaces(const Cloud& cluster, const std::vector<float>& heights,
                              const std::vector<Eigen::Vector2f>& footprints,
                              std::unordered_map<uint64_t, FootprintCell>& cells) {
  // Each point's cell (the map's elements stay where they are), and the points of each cell in
  // ascending order as one flat array (cell id -> range): one hash lookup per point in all.
  std::vector<FootprintCell*> cell_of_point(cluster.size());
  for (size_t i = 0; i < cluster.size(); ++i) {
    const Eigen::Vector2f q = footprints[i] / kFootprintCell;
    const int64_t x = voxel_key::floorToInt(q.x()), y = voxel_key::floorToInt(q.y());
    auto [it, added] =
        cells.try_emplace(voxel_key::pack(x, y, 0), FootprintCell{x, y, heights[i], heights[i]});
    FootprintCell& cell = it->second;
    if (added) {
      cell.id = static_cast<int>(cells.size()) - 1;
    } else {
      cell.height = std::max(cell.height, heights[i]);
      cell.low = std::min(cell.low, heights[i]);
    }
    cell_of_point[i] = &cell;
  }
  std::vector<int> first_point_of_cell(cells.size() + 1, 0), points_by_cell(cluster.size());
  for (const FootprintCell* cell : cell_of_point) ++first_point_of_cell[cell->id + 1];
  std::partial_sum(first_point_of_cell.begin(), first_point_of_cell.end(),
                   first_point_of_cell.begin());
  {
    std::vector<int> next = first_point_of_cell;
    for (size_t i = 0; i < cluster.size(); ++i)
      points_by_cell[next[cell_of_point[i]->id]++] = static_cast<int>(i);
  }
  // Regions: flood fill over the 8 neighbours within kTopFaceStep, steep cells left out. A steep
  // cell whose highest point lies at the level of the cell beside it is a noisy cell of the same
  // top (a third of a box top's cells at 1.1-1.3 m): the fill goes on across it, else pieces of
  // one top cut apart by noisy cells would be faces of their own.
  std::vector<std::vector<const FootprintCell*>> regions;
  std::vector<uint64_t> stack;
  auto forNeighbourCells = [&](const FootprintCell& cell, auto&& visit) {
    forGridNeighbours(cells, cell.x, cell.y, visit);
  };
  for (auto& [key, seed] : cells) {
    if (seed.region >= 0 || seed.steep()) continue;
    seed.region = static_cast<int>(regions.size());
    regions.emplace_back(1, &seed);
    stack.assign(1, key);
    auto reach = [&](float from_height, uint64_t next_key, FootprintCell& next) {
      if (next.region >= 0 || next.steep() || std::abs(next.height - from_height) > kTopFaceStep)
        return;
      next.region = seed.region;
      regions.back().push_back(&next);
      stack.push_back(next_key);
    };
    while (!stack.empty()) {
      const FootprintCell& cell = cells.at(stack.back());
      stack.pop_back();
      forNeighbourCells(cell, [&](uint64_t next_key, FootprintCell& next) {
        if (!next.steep()) return reach(cell.height, next_key, next);
        if (!next.noisyTop() || std::abs(next.height - cell.height) > kTopFaceStep) return;
        forNeighbourCells(next, [&](uint64_t across_key, FootprintCell& across) {
          reach(next.height, across_key, across);
        });
      });
    }
  }
  // Regions of several objects of the same height parted at their necks, when they nearly fill
  // their outline (two objects side by side); not a top face with a bite out of it: the top of
  // a lower box seen around one standing on it narrows around the upper box's corner (OSD
  // learn20, learn22).
  auto nearlyConvex = [](const std::vector<const FootprintCell*>& region) {
    std::vector<Eigen::Vector2f> centres;
    for (const FootprintCell* cell : region) centres.emplace_back(cell->x + 0.5f, cell->y + 0.5f);
    const std::vector<Eigen::Vector2f> hull = convexHull2d(std::move(centres));
    return hull.size() >= 3 && region.size() >= kNeckSplitFill * filledCells(hull);
  };
  // The points at a region's level: those of its cells and of the steep cells around them (its
  // edges), from a step under its lowest cell to half a step over its highest.
  std::vector<int> taken_in_call(cells.size(), -1);  // per cell id: the last call that took it
  int calls = 0;
  auto levelPoints = [&](const std::vector<const FootprintCell*>& region) {
    float low = std::numeric_limits<float>::infinity(), high = -low;
    for (const FootprintCell* cell : region)
      low = std::min(low, cell->height), high = std::max(high, cell->height);
    std::vector<Eigen::Vector2f> level;
    const int call = calls++;
    auto take = [&](const FootprintCell& cell) {
      if (taken_in_call[cell.id] == call) return;
      taken_in_call[cell.id] = call;
      for (int k = first_point_of_cell[cell.id]; k < first_point_of_cell[cell.id + 1]; ++k) {
        const int i = points_by_cell[k];
        if (heights[i] >= low - kTopFaceStep && heights[i] <= high + 0.5f * kTopFaceStep)
          level.push_back(footprints[i]);
      }
    };
    for (const FootprintCell* cell : region) {
      take(*cell);
      forNeighbourCells(*cell, [&](uint64_t, const FootprintCell& next) {
        if (next.steep()) take(next);
      });
    }
    return level;
  };
  // Objects of one level along straight gaps (up to kMaxGapSplits rounds).
  auto splitAlongGaps = [&](std::vector<const FootprintCell*> region) {
    std::vector<std::vector<const FootprintCell*>> pieces{std::move(region)}, next;
    for (int round = 0; round < kMaxGapSplits; ++round) {
      next.clear();
      for (const auto& piece : pieces) {
        for (auto& part : splitAlongAGap(piece, levelPoints(piece)))
          next.push_back(std::move(part));
      }
      if (next.size() == pieces.size()) break;
      pieces.swap(next);
    }
    return pieces;
  };
  std::vector<std::vector<const FootprintCell*>> objects;
  std::vector<int> parted_by_a_gap;  // per object: its region's number when cut along gaps
  for (const auto& chained : regions) {
    for (const auto& region : topsOf(chained)) {
      const bool two_side_by_side = region.size() >= 2 * kMinTopCells && nearlyConvex(region);
      for (auto& side : two_side_by_side ? splitSideBySide(region)
                                         : std::vector<std::vector<const FootprintCell*>>{region}) {
        std::vector<std::vector<const FootprintCell*>> pieces = splitAlongGaps(std::move(side));
        const int gap_group = pieces.size() > 1 ? static_cast<int>(objects.size()) : -1;
        for (auto& object : pieces) {
          for (const FootprintCell* cell : object)
            cells.at(voxel_key::pack(cell->x, cell->y, 0)).region =
                static_cast<int>(objects.size());
          objects.push_back(std::move(object));
          parted_by_a_gap.push_back(gap_group);
        }
      }
    }
  }
  regions = std::move(objects);
  // Outlines of the larger regions (cell centres), for the fill and the nesting tests.
  std::vector<std::vector<Eigen::Vector2f>> outlines(regions.size());
  std::vector<float> top(regions.size()), bottom(regions.size());
  for (size_t r = 0; r < regions.size(); ++r) {
    top[r] = -std::numeric_limits<float>::infinity();
    bottom[r] = std::numeric_limits<float>::infinity();
    std::vector<Eigen::Vector2f> centres;
    for (const FootprintCell* cell : regions[r]) {
      top[r] = std::max(top[r], cell->height);
      bottom[r] = std::min(bottom[r], cell->height);
      centres.emplace_back(cell->x + 0.5f, cell->y + 0.5f);
    }
    if (regions[r].size() >= kMinTopCells) outlines[r] = convexHull2d(std::move(centres));
  }
  std::vector<TopFace> faces;
  std::vector<int> face_of_region(regions.size(), -1), region_of_face;
  for (size_t r = 0; r < regions.size(); ++r) {
    if (outlines[r].size() < 3 || top[r] - bottom[r] > kTopFaceSpread ||
        widthOf(outlines[r]) + 1.0f < kTopFaceWidth)
      continue;
    if (levelCellsWithin(outlines[r], bottom[r], top[r], cells) <
        kTopFaceFill * filledCells(outlines[r]))
      continue;
    auto withinHigher = [&](size_t higher) {
      if (higher == r || outlines[higher].size() < 3 || top[higher] <= top[r] + kTopFaceStep)
        return false;
      size_t inside = 0;
      for (const FootprintCell* cell : regions[r])
        inside += insideDistance(outlines[higher], {cell->x + 0.5f, cell->y + 0.5f}) >= 0.0f;
      return 2 * inside >= regions[r].size();
    };
    bool nested = false;
    for (size_t higher = 0; higher < regions.size() && !nested; ++higher)
      nested = withinHigher(higher);
    if (nested) continue;
    face_of_region[r] = static_cast<int>(faces.size());
    region_of_face.push_back(static_cast<int>(r));
    faces.push_back({{}, top[r], parted_by_a_gap[r]});
  }
  // Outlines: the points of a face's cells and of the steep cells around them (its edges) at
  // its height, within half a step.
  std::vector<std::vector<Eigen::Vector2f>> face_points(faces.size());
  // Per cell id: the faces its points may belong to, found at its first point.
  std::vector<std::vector<int>> near_faces_of_cell(cells.size());
  std::vector<char> near_faces_known(cells.size(), 0);
  for (size_t i = 0; i < cluster.size(); ++i) {
    const FootprintCell& cell = *cell_of_point[i];
    std::vector<int>& near_faces = near_faces_of_cell[cell.id];
    if (!near_faces_known[cell.id]) {
      near_faces_known[cell.id] = 1;
      if (!cell.steep()) {
        if (cell.region >= 0) near_faces.push_back(face_of_region[cell.region]);
      } else {
        // The cell itself is steep: in no region.
        forGridNeighbours(cells, cell.x, cell.y, [&](uint64_t, const FootprintCell& next) {
          if (next.region >= 0) near_faces.push_back(face_of_region[next.region]);
        });
        std::sort(near_faces.begin(), near_faces.end());
        near_faces.erase(std::unique(near_faces.begin(), near_faces.end()), near_faces.end());
      }
    }
    for (int f : near_faces) {
      if (f < 0) continue;
      const int r = region_of_face[f];
      if (heights[i] >= bottom[r] - 0.5f * kTopFaceStep &&
          heights[i] <= top[r] + 0.5f * kTopFaceStep)
        face_points[f].push_back(footprints[i]);
    }
  }
  for (TopFace& face : faces)
    face.outline = convexHull2d(std::move(face_points[&face - &faces[0]]));
  // Side by side, outlines do not overlap: the top of a box under another, seen around it,
  // surrounds the upper one's (the stack split parts them at their concave seam).
  auto underAnother = [&](const TopFace& lower) {
    for (const TopFace& upper : faces) {
      if (upper.height <= lower.height || upper.outline.size() < 3) continue;
      size_t inside = 0;
      for (const Eigen::Vector2f& corner : upper.outline)
        inside += insideDistance(lower.outline, corner) > kFootprintCell;
      if (2 * inside >= upper.outline.size()) return true;
    }
    return false;
  };
  std::vector<TopFace> outlined;
  for (const TopFace& face : faces) {
    if (face.outline.size() >= 3 && !underAnother(face)) outlined.push_back(face);
  }
  return outlined;
}

// Each point's top face: among those not lower than the point, the one whose outline it lies
// deepest in (a vertical face projects onto its own top's edge, beside its neighbour's).
std::vector<int> underWhichTop(const std::vector<TopFace>& faces, const std::vector<float>& heights,
                               const std::vector<Eigen::Vector2f>& footprints) {
  std::vector<int> face_of(heights.size(), 0);
  // Each outline's edges once, not for every point (the same distances, bit for bit).
  std::vector<PolygonEdges> outlines;
  outlines.reserve(faces.size());
  for (const TopFace& face : faces) outlines.emplace_back(face.outline);
  for (size_t i = 0; i < heights.size(); ++i) {
    float best = -std::numeric_limits<float>::infinity();
    bool best_over = false;
    for (size_t f = 0; f < faces.size(); ++f) {
      const bool over = faces[f].height >= heights[i] - 0.5f * kTopFaceStep;
      const float inside = outlines[f].insideDistance(footprints[i]);
      if ((over && !best_over) || (over == best_over && inside > best)) {
        best = inside;
        best_over = over;
        face_of[i] = static_cast<int>(f);
      }
    }
  }
  return face_of;
}

// Two level faces of one height (within kOneTopFace) that a knob on their top parts are one top:
// a bottle's cap standing on its shoulder, widened by edge smear, cuts a flattened bottle's
// shoulder in two (issue 12). The knob's footprint cells lie within the faces' joint outline,
// rise above them by kTopStep, are too few for a top face of their own, reach within a cell of
// both faces, and rest on them: their lowest points lie no lower than kTopStep under the faces.
// A marker standing between two boxes of one height rises from the table: its cells hold its
// side down to the table, and the boxes stay apart.
void joinFacesPartedByAKnob(std::vector<TopFace>& faces,
                            const std::unordered_map<uint64_t, FootprintCell>& cells) {
  for (size_t i = 0; i < faces.size(); ++i) {
    for (size_t j = i + 1; j < faces.size(); ++j) {
      if (std::abs(faces[i].height - faces[j].height) > kOneTopFace) continue;
      const float level = std::max(faces[i].height, faces[j].height);
      const float floor = std::min(faces[i].height, faces[j].height) - kTopStep;
      std::vector<Eigen::Vector2f> both = faces[i].outline;
      both.insert(both.end(), faces[j].outline.begin(), faces[j].outline.end());
      std::vector<Eigen::Vector2f> joint = convexHull2d(std::move(both));
      size_t knob = 0;
      bool rests = true, reaches_i = false, reaches_j = false;
      for (const auto& [key, cell] : cells) {
        const Eigen::Vector2f centre =
            Eigen::Vector2f(cell.x + 0.5f, cell.y + 0.5f) * kFootprintCell;
        if (cell.height <= level + kTopStep || insideDistance(joint, centre) < 0.0f) continue;
        ++knob;
        rests = rests && cell.low >= floor;
        reaches_i = reaches_i || insideDistance(faces[i].outline, centre) >= -kFootprintCell;
        reaches_j = reaches_j || insideDistance(faces[j].outline, centre) >= -kFootprintCell;
      }
      if (knob == 0 || knob >= kMinTopCells || !rests || !reaches_i || !reaches_j) continue;
      faces[i] = {std::move(joint), level};
      faces.erase(faces.begin() + j);
      j = i;  // the joined face against the rest again
    }
  }
}

// The part's objects standing side by side, one per top face; the part itself when it has fewer
// than two top faces, or when a face would hold fewer than min_points (that face is dropped).
// `own_top_faces`: whether each object returned lies under a level top face of its own;
// `parted_by_a_gap`: per object, its face's TopFace::parted_by_a_gap.
std::vector<CloudPtr> splitUnderTopFaces(const CloudPtr& part, const Plane& table, int min_points,
                                         bool& own_top_faces, std::vector<int>& parted_by_a_gap) {
  own_top_faces = false;
  parted_by_a_gap.assign(1, -1);
  const Cloud& cloud = *part;
  if (static_cast<int>(cloud.size()) < min_points) return {part};
  const TableProjection onTable(table);
  std::vector<float> heights(cloud.size());
  std::vector<Eigen::Vector2f> footprints(cloud.size());
  for (size_t i = 0; i < cloud.size(); ++i) {
    heights[i] = table.signedDistance(cloud[i].getVector3fMap());
    footprints[i] = onTable(cloud[i]);
  }
  std::unordered_map<uint64_t, FootprintCell> cells;
  std::vector<TopFace> faces = topFaces(cloud, heights, footprints, cells);
  joinFacesPartedByAKnob(faces, cells);
  std::vector<int> face_of;
  while (faces.size() >= 2) {
    face_of = underWhichTop(faces, heights, footprints);
    std::vector<int> size(faces.size(), 0);
    for (int f : face_of) ++size[f];
    const auto smallest = std::min_element(size.begin(), size.end());
    if (*smallest >= min_points) break;
    faces.erase(faces.begin() + (smallest - size.begin()));
  }
  own_top_faces = !faces.empty();
  if (faces.size() < 2) return {part};
  std::vector<std::vector<int>> indices(faces.size());
  for (size_t i = 0; i < face_of.size(); ++i) indices[face_of[i]].push_back(static_cast<int>(i));
  std::vector<CloudPtr> out;
  parted_by_a_gap.clear();
  for (size_t f = 0; f < faces.size(); ++f) {
    auto object = std::make_shared<Cloud>(cloud, indices[f]);
    object->header = cloud.header;
    object->is_dense = true;
    out.push_back(object);
    parted_by_a_gap.push_back(faces[f].parted_by_a_gap);
  }
  return out;
}

}  // namespace

bool mayHoldAStack(const Cloud& cluster, const Plane& table, const ClusteringParams& params) {
  if (cluster.empty()) return false;
  const float top = topOf(cluster, table);
  const TableProjection onTable(table);
  std::vector<Eigen::Vector2f> top_band;
  for (const auto& p : cluster) {
    if (table.signedDistance(p.getVector3fMap()) >= top - kStackStep)
      top_band.push_back(onTable(p));
  }
  const std::vector<Eigen::Vector2f> hull = convexHull2d(std::move(top_band));
  if (hull.size() < 3) return true;  // a ridge or a spike on top: no footprint to judge by
  // Depth noise smears a vertical face sideways, more with range.
  const float smear = sidewaysSmear(centroidOf(cluster).norm(), params);
  const int needed = stackEvidencePoints(params);
  const PolygonEdges edges(hull);
  int beside = 0;
  for (const auto& p : cluster) {
    if (table.signedDistance(p.getVector3fMap()) < top - kStackStep &&
        edges.insideDistance(onTable(p)) < -smear && ++beside >= needed) {
      return true;
    }
  }
  return false;
}

namespace {

// The LCCP parts of a cluster that can hold a stack; the cluster itself when it cannot.
// `may_hold_a_stack` tells whether the cluster was looked at (mayHoldAStack).
std::vector<CloudPtr> splitStack(const CloudPtr& cluster, const Plane& table,
                                 const ClusteringParams& params, int min_points,
                                 bool& may_hold_a_stack) {
  may_hold_a_stack =
      static_cast<int>(cluster->size()) >= 2 * min_points && mayHoldAStack(*cluster, table, params);
  if (!may_hold_a_stack) return {cluster};
  // The neighbour lists do not depend on the convex parts: with a core free (one pile on the
  // table), they are found on it while PCL's supervoxels, serial, take the other. Without one
  // (several clusters on the cores), only when LCCP found parts: the merges below take
  // neighbours of another part, and one part is the cluster whole.
  ConvexParts convex_parts;
  std::optional<NearestOfEach> nearest;
  const unsigned threads = freeWorkerThreads();
  if (threads > 1) {
    parallelFor(
        2,
        [&](size_t task) {
          if (task == 0)
            convex_parts = convexParts(cluster, params);
          else
            nearest.emplace(cluster);
        },
        threads);
  } else {
    convex_parts = convexParts(cluster, params);
    const std::vector<uint32_t>& labels = convex_parts.labels;
    if (std::adjacent_find(labels.begin(), labels.end(), std::not_equal_to<uint32_t>()) ==
        labels.end())
      return {cluster};
    nearest.emplace(cluster);
  }
  mergeSmallParts(*nearest, min_points, convex_parts);
  mergeUnseparatedParts(*cluster, *nearest, table,
                        sidewaysSmear(centroidOf(*cluster).norm(), params), convex_parts);

  std::map<uint32_t, std::vector<int>> parts;
  for (size_t i = 0; i < convex_parts.labels.size(); ++i)
    parts[convex_parts.labels[i]].push_back(static_cast<int>(i));
  if (parts.size() < 2) return {cluster};
  std::vector<CloudPtr> out;
  for (const auto& [label, indices] : parts) {
    auto part = std::make_shared<Cloud>(*cluster, indices);
    part->header = cluster->header;
    part->is_dense = true;
    out.push_back(part);
  }
  return out;
}

// ---- one top face cut in two by an object resting on it (OSD learn19, learn21) ----
// Whether two objects of one part touch: some point of `a` lies within kTouching of `b`.
constexpr float kTouching = 0.015f;  // [m]: neighbouring 5 mm voxels of one surface, and noise
bool touch(const Cloud& a, const CloudConstPtr& b) {
  GridSearch<Point> search(kTouching, false);
  search.setInputCloud(b);
  pcl::Indices near;
  std::vector<float> distances;
  return std::any_of(a.begin(), a.end(), [&](const Point& p) {
    return search.radiusSearch(p, kTouching, near, distances, 1) > 0;
  });
}

// The footprint on the table of a cloud's top band (its points within kTopBand of its top).
std::vector<Eigen::Vector2f> topBandOutline(const Cloud& cloud, float top, const Plane& table,
                                            const TableProjection& onTable) {
  std::vector<Eigen::Vector2f> band;
  for (const auto& p : cloud) {
    if (table.signedDistance(p.getVector3fMap()) >= top - kTopBand) band.push_back(onTable(p));
  }
  return convexHull2d(std::move(band));
}

// Objects the top-face split made of one stack part that are one object: a box with another
// lying across its top shows its own top on both sides of the upper one, two level faces at
// the same height (within kTopStep) that the face split takes for two objects side by side. They
// are joined again when they touch (the lower box's front face runs on under the upper one) and
// the gap between their tops (their joint outline outside both, beyond `smear`) is covered:
// points of `surroundings` (which holds the objects' own) rise above them over at least `needed`
// points, and every footprint cell of the gap where other points than their own are seen lower
// has such a point over it (kMaxUncoveredGapCells aside): what cut the face lies across it. Two
// boxes of one height standing side by side have nothing over the gap between them; the gap between
// diagonal neighbours in a block holds the other two, one of them seen lower.
// Objects whose faces were cut from one region along an empty gap (`parted_by_a_gap`, the same
// number >= 0) are neighbours a few millimetres apart, not halves of one top: nothing lies
// across the gap (their joint outline may still reach over taller neighbours).
constexpr int kMaxUncoveredGapCells = 2;
constexpr float kSurelyOutside = 0.001f;  // [m]
std::vector<CloudPtr> joinTopsCutByAnObjectOnThem(std::vector<CloudPtr> objects,
                                                  std::vector<int> parted_by_a_gap,
                                                  const Cloud& surroundings, const Plane& table,
                                                  float smear, int needed) {
  if (objects.size() < 2) return objects;
  const TableProjection onTable(table);
  auto coveredGap = [&](const Cloud& a, const Cloud& b) {
    const float top_a = topOf(a, table), top_b = topOf(b, table);
    if (std::abs(top_a - top_b) > kOneTopFace) return false;
    const std::vector<Eigen::Vector2f> outline_a = topBandOutline(a, top_a, table, onTable);
    const std::vector<Eigen::Vector2f> outline_b = topBandOutline(b, top_b, table, onTable);
    std::vector<Eigen::Vector2f> both = outline_a;
    both.insert(both.end(), outline_b.begin(), outline_b.end());
    const std::vector<Eigen::Vector2f> joint = convexHull2d(std::move(both));
    if (outline_a.size() < 3 || outline_b.size() < 3 || joint.size() < 3) return false;
    const float top = std::max(top_a, top_b);
    const PolygonEdges joint_edges(joint), edges_a(outline_a), edges_b(outline_b);
    // The joint outline's bounding box, a millimetre wider: points beyond it lie outside the
    // outline whatever the rounding of insideDistance, and most of the surroundings do.
    Eigen::AlignedBox2f joint_box;
    for (const Eigen::Vector2f& corner : joint) joint_box.extend(corner);
    joint_box.extend(joint_box.min() - Eigen::Vector2f::Constant(kSurelyOutside));
    joint_box.extend(joint_box.max() + Eigen::Vector2f::Constant(kSurelyOutside));
    // Per footprint cell of the gap: points over the tops and points lower, beyond kTopStep
    // (at their level lie strips of their own top that went with the object on it), counted +1
    // from the surroundings, -1 from the objects themselves.
    struct GapCell {
      int over = 0, not_over = 0;
    };
    std::unordered_map<uint64_t, GapCell> gap;
    int over = 0;
    // insideDistance(q) >= -smear and >= 0 as insideBy, which stops at the first edge that q
    // lies farther out than the margin: no float lies between a margin and the next one below.
    // The tests in the order that takes the fewest edges: most points in the joint box are the
    // objects' own and inside the joint outline, each found close to its own outline.
    const float lowest = std::numeric_limits<float>::lowest();
    const float smear_margin = std::nextafter(-smear, lowest),
                zero_margin = std::nextafter(0.0f, lowest);
    auto visit = [&](const Cloud& cloud, int sign) {
      for (const auto& p : cloud) {
        const float h = table.signedDistance(p.getVector3fMap());
        const Eigen::Vector2f q = onTable(p);
        if (std::abs(h - top) <= kTopStep || !joint_box.contains(q) ||
            edges_a.insideBy(q, smear_margin) || edges_b.insideBy(q, smear_margin) ||
            !joint_edges.insideBy(q, zero_margin))
          continue;
        const Eigen::Vector2f c = q / kFootprintCell;
        GapCell& cell =
            gap[voxel_key::pack(voxel_key::floorToInt(c.x()), voxel_key::floorToInt(c.y()), 0)];
        if (h > top) {
          cell.over += sign;
          over += sign;
        } else {
          cell.not_over += sign;
        }
      }
    };
    visit(surroundings, 1);
    visit(a, -1);
    visit(b, -1);
    const auto uncovered = std::count_if(gap.begin(), gap.end(), [](const auto& cell) {
      return cell.second.not_over > 0 && cell.second.over <= 0;
    });
    return over >= needed && uncovered <= kMaxUncoveredGapCells;
  };
  for (bool joined = true; joined;) {
    joined = false;
    for (size_t i = 0; i < objects.size() && !joined; ++i) {
      for (size_t j = i + 1; j < objects.size() && !joined; ++j) {
        if ((parted_by_a_gap[i] >= 0 && parted_by_a_gap[i] == parted_by_a_gap[j]) ||
            !coveredGap(*objects[i], *objects[j]) || !touch(*objects[i], objects[j]))
          continue;
        auto merged = std::make_shared<Cloud>(*objects[i]);
        *merged += *objects[j];
        objects[i] = merged;
        objects.erase(objects.begin() + j);
        parted_by_a_gap.erase(parted_by_a_gap.begin() + j);
        joined = true;
      }
    }
  }
  return objects;
}

// ---- a box lying across two others (issue 15) ----
// The plank's front face continues the legs' front faces nearly flush, and LCCP joins the pile
// into one convex part; no top face parts them either (the legs' tops lie under the plank). What
// tells the pile apart is below the plank: horizontal slices of the part under its bottom fall
// into separate pieces (the legs), slices through the plank are one. A single box, can or cup
// is one piece at every level. Slices are taken every kBridgeSliceStep from kStackStep under the
// top down to kStackStep above the table; pieces link within kBridgeLink.
constexpr float kBridgeSliceStep = 0.005f;  // [m]
constexpr float kBridgeLink = 0.015f;       // [m]
// A line of sight to the gap between the legs is clear up to this short of it [m]: no other
// object within kBridgeLink of it, and no surface of the part itself crossed (a point within
// kBridgeSurfaceCrossed: the 5 mm samples of a surface it goes through; a mug's inside lies
// behind its front wall, the gap under a plank in front of everything).
constexpr float kBridgeClearance = 0.03f;
constexpr float kBridgeSurfaceCrossed = 0.005f;

// The part's pieces under a bridge: the legs (each piece of the highest slice with two pieces of
// at least `min_points`), and what lies on them (the rest); the part itself otherwise.
// `surroundings` holds the part's points and the objects around it.
std::vector<CloudPtr> splitUnderABridge(const CloudPtr& part, const Plane& table,
                                        const Cloud& surroundings, int min_points) {
  const Cloud& cloud = *part;
  if (static_cast<int>(cloud.size()) < 3 * min_points) return {part};
  const TableProjection onTable(table);
  std::vector<float> heights(cloud.size());
  for (size_t i = 0; i < cloud.size(); ++i)
    heights[i] = table.signedDistance(cloud[i].getVector3fMap());
  const float top = *std::max_element(heights.begin(), heights.end());
  // Slices from the bottom up: a higher slice holds a lower one's points, so its pieces only
  // join; once one piece is left (at once for a single object), no higher slice parts.
  float level = 0.0f;
  std::vector<int> slice_index;
  std::vector<pcl::Indices> pieces;
  for (float at = kStackStep; at <= top - kStackStep; at += kBridgeSliceStep) {
    auto slice = std::make_shared<Cloud>();
    std::vector<int> index;
    for (size_t i = 0; i < cloud.size(); ++i) {
      if (heights[i] < at) {
        slice->push_back(cloud[i]);
        index.push_back(static_cast<int>(i));
      }
    }
    if (slice->empty()) continue;
    GridSearch<Point> grid(kBridgeLink, false);
    grid.setInputCloud(slice);
    std::vector<pcl::Indices> components = grid.connectedComponents(kBridgeLink);
    if (components.size() < 2) break;
    // Legs stand on the table; a mug's handle, cut off by noise, hangs above it.
    components.erase(std::remove_if(components.begin(), components.end(),
                                    [&](const pcl::Indices& piece) {
                                      float low = std::numeric_limits<float>::infinity();
                                      for (int k : piece) low = std::min(low, heights[index[k]]);
                                      return static_cast<int>(piece.size()) < min_points ||
                                             low > kStackStep;
                                    }),
                     components.end());
    if (components.size() < 2) continue;
    level = at;
    slice_index.swap(index);
    pieces.swap(components);
  }
  if (pieces.size() < 2) return {part};
  // What lies across has a flat top (a plank): a cup's or mug's inside, seen over its rim, is a
  // piece apart from its outer wall in every low slice, under a rim that is only a ring.
  if (!hasFlatTop(cloud, std::vector<uint32_t>(cloud.size(), 0), 0, top, table, onTable))
    return {part};
  // The camera sees through between the legs: no other object lies on the lines of sight to the
  // gap between the pieces' nearest points (each piece's nearest to the camera), below the slice.
  // Pieces of one object whose lower middle another object hides (OSD learn6, learn9: a box
  // behind a box) have that object on those lines.
  const Eigen::Vector3f eye = surroundings.sensor_origin_.head<3>();
  std::vector<Eigen::Vector3f> nearest;
  for (const pcl::Indices& piece : pieces) {
    const Point* near = &cloud[slice_index[piece.front()]];
    for (int k : piece) {
      const Point& p = cloud[slice_index[k]];
      if ((p.getVector3fMap() - eye).squaredNorm() < (near->getVector3fMap() - eye).squaredNorm())
        near = &p;
    }
    nearest.push_back(near->getVector3fMap());
  }
  // Points of the part itself near the line (the pile's own front edges) hide nothing.
  GridSearch<Point> own(kBridgeLink, false);
  own.setInputCloud(part);
  pcl::Indices same;
  std::vector<float> distances;
  auto hidden = [&](const Eigen::Vector3f& gap) {
    const Eigen::Vector3f ray = gap - eye;
    const float length = ray.norm();
    return std::any_of(surroundings.begin(), surroundings.end(), [&](const Point& point) {
      const Eigen::Vector3f p = point.getVector3fMap() - eye;
      const float along = p.dot(ray) / length;
      if (!(along > 0.0f && along < length - kBridgeClearance)) return false;
      const float off = (p - along / length * ray).squaredNorm();
      return off < kBridgeSurfaceCrossed * kBridgeSurfaceCrossed ||
             (off < kBridgeLink * kBridgeLink &&
              own.radiusSearch(point, 1e-4, same, distances, 1) == 0);
    });
  };
  for (size_t a = 0; a < nearest.size(); ++a) {
    for (size_t b = a + 1; b < nearest.size(); ++b) {
      const Eigen::Vector3f middle = 0.5f * (nearest[a] + nearest[b]);
      // Legs stand side by side across the view; a cup's inside lies behind its front wall.
      const Eigen::Vector3f apart = nearest[b] - nearest[a];
      const float along_view = std::abs(apart.dot((middle - eye).normalized()));
      if (along_view >=
          (apart - apart.dot((middle - eye).normalized()) * (middle - eye).normalized()).norm())
        return {part};
      // Halfway up the slice, on the pieces' front.
      const Eigen::Vector3f gap =
          middle - (table.signedDistance(middle) - 0.5f * level) * table.normal;
      if (hidden(gap)) return {part};
    }
  }
  std::vector<std::vector<int>> legs;
  std::vector<std::vector<Eigen::Vector2f>> leg_outlines;
  std::vector<char> in_leg(cloud.size(), 0);
  for (const pcl::Indices& piece : pieces) {
    legs.emplace_back();
    std::vector<Eigen::Vector2f> leg_footprint;
    for (int k : piece) {
      legs.back().push_back(slice_index[k]);
      leg_footprint.push_back(onTable(cloud[slice_index[k]]));
      in_leg[slice_index[k]] = 1;
    }
    leg_outlines.push_back(convexHull2d(std::move(leg_footprint)));
  }
  // A leg's top, seen where it sticks out beyond the bridge's top face, lies above the slice:
  // it goes with the leg (else the leg is cut short and the bridge reaches down to it).
  std::vector<Eigen::Vector2f> bridge_top;
  for (size_t i = 0; i < cloud.size(); ++i) {
    if (heights[i] >= top - kTopBand) bridge_top.push_back(onTable(cloud[i]));
  }
  const std::vector<Eigen::Vector2f> bridge_outline = convexHull2d(std::move(bridge_top));
  std::vector<int> rest;
  for (size_t i = 0; i < cloud.size(); ++i) {
    if (in_leg[i]) continue;
    const Eigen::Vector2f q = onTable(cloud[i]);
    size_t leg = legs.size();
    if (heights[i] < level + kStackStep && bridge_outline.size() >= 3 &&
        insideDistance(bridge_outline, q) < 0) {
      for (size_t l = 0; l < legs.size() && leg == legs.size(); ++l) {
        if (leg_outlines[l].size() >= 3 && insideDistance(leg_outlines[l], q) > -kBridgeLink)
          leg = l;
      }
    }
    if (leg < legs.size())
      legs[leg].push_back(static_cast<int>(i));
    else
      rest.push_back(static_cast<int>(i));
  }
  std::vector<CloudPtr> out;
  for (const std::vector<int>& leg : legs) out.push_back(std::make_shared<Cloud>(cloud, leg));
  if (static_cast<int>(rest.size()) < min_points) return {part};
  out.push_back(std::make_shared<Cloud>(cloud, rest));
  for (CloudPtr& piece : out) {
    piece->header = cloud.header;
    piece->is_dense = true;
  }
  return out;
}

}  // namespace

std::vector<CloudPtr> splitAtConcaveSeams(const CloudPtr& cluster, const Plane& table,
                                          const ClusteringParams& params,
                                          std::vector<int>* side_by_side,
                                          const CloudConstPtr& scene) {
  const int min_points = std::max(1, params.split_min_points);
  std::vector<std::pair<CloudPtr, int>> out;  // part, side-by-side group
  if (!cluster || !(params.split_concavity_deg > 0.0f) || !(params.split_patch_size > 0.0f)) {
    out.emplace_back(cluster, -1);
  } else {
    // Stacked objects part at concave seams, then objects side by side in each part under
    // their own top faces (LCCP joins touching objects across a front face they share). Parts
    // each under a level top face of its own are separate objects, all in one group: the joins
    // took a lower neighbour seen over a taller one's top edge for its inside, or a neighbour
    // for a hidden middle (issue 15). A cup's wall (a rim ring), a handle or a box's side cut
    // off by noise has no top face of its own and may still be joined.
    constexpr int kSeparateObjects = 0;
    bool may_hold_a_stack = false;
    const std::vector<CloudPtr> parts =
        splitStack(cluster, table, params, min_points, may_hold_a_stack);
    const float smear = sidewaysSmear(centroidOf(*cluster).norm(), params);
    // What may rest on a part or stand beside it: every object's points, else the cluster's.
    const Cloud& surroundings = scene ? *scene : *cluster;
    // The stack's parts are split each on its own: on the free cores when the cluster has them
    // (one pile on the table), the objects gathered in the parts' order.
    std::vector<std::vector<std::pair<CloudPtr, int>>> objects_of_part(parts.size());
    parallelFor(
        parts.size(),
        [&](size_t p) {
          const CloudPtr& stack_part = parts[p];
          std::vector<std::pair<CloudPtr, int>>& objects_here = objects_of_part[p];
          // A pile LCCP did not part (a box lying across two) comes apart under its bridge
          // first; its pieces are separate objects, so the joins leave the legs apart.
          const std::vector<CloudPtr> bridge =
              parts.size() == 1 && may_hold_a_stack
                  ? splitUnderABridge(stack_part, table, surroundings, min_points)
                  : std::vector<CloudPtr>{stack_part};
          if (bridge.size() > 1) {
            for (const CloudPtr& object : bridge)
              objects_here.emplace_back(object, kSeparateObjects);
            return;
          }
          bool own_top_faces = false;
          std::vector<int> parted_by_a_gap;
          std::vector<CloudPtr> faces =
              splitUnderTopFaces(stack_part, table, min_points, own_top_faces, parted_by_a_gap);
          const std::vector<CloudPtr> objects =
              joinTopsCutByAnObjectOnThem(std::move(faces), std::move(parted_by_a_gap),
                                          surroundings, table, smear, stackEvidencePoints(params));
          for (const CloudPtr& object : objects)
            objects_here.emplace_back(object, own_top_faces ? kSeparateObjects : -1);
        },
        freeWorkerThreads());
    for (auto& objects_here : objects_of_part)
      out.insert(out.end(), objects_here.begin(), objects_here.end());
  }
  return largestFirst(std::move(out), side_by_side);
}

std::vector<CloudPtr> largestFirst(std::vector<std::pair<CloudPtr, int>> parts,
                                   std::vector<int>* groups) {
  std::stable_sort(parts.begin(), parts.end(),
                   [](const auto& a, const auto& b) { return a.first->size() > b.first->size(); });
  std::vector<CloudPtr> clouds;
  if (groups) groups->clear();
  for (const auto& [cloud, group] : parts) {
    clouds.push_back(cloud);
    if (groups) groups->push_back(group);
  }
  return clouds;
}

}  // namespace tabletop_shapes
