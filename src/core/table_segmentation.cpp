// §2.2-2.4: the support plane (RANSAC + OLS), its convex hull, the object points above it and
// the statistical outlier removal; plus the estimation of "up" for a camera of unknown tilt.
#include "tabletop_shapes/core/table_segmentation.h"

#include "tabletop_shapes/core/convex_polygon.h"
#include "tabletop_shapes/core/cpu_features.h"
#include "tabletop_shapes/core/densest_slab.h"
#include "tabletop_shapes/core/float4.h"
#include "tabletop_shapes/core/grid_search.h"
#include "tabletop_shapes/core/parallel.h"
#include "tabletop_shapes/core/plane_support.h"

#include <Eigen/Eigenvalues>

#include <algorithm>
#include <cstdio>
#include <cmath>
#include <condition_variable>
#include <cstdint>
#include <cstring>
#include <exception>
#include <iterator>
#include <limits>
#include <memory>
#include <mutex>
#include <numeric>
#include <optional>
#include <random>

#ifdef __SSE__
#include <xmmintrin.h>
#endif
#if defined(__x86_64__) && defined(__GNUC__)
#include <immintrin.h>
#endif

namespace tabletop_shapes {
namespace {

// A support plane needs at least this many object points above it (inside its hull) to count
// as "a plane with objects on it" when the candidates are ranked.
constexpr int kMinSupportedPoints = 50;
// RANSAC scores hypotheses on a random subset of at most this many points: the ranking is the
// same as on the full cloud, and a VGA frame costs a fraction of the time.
constexpr size_t kMaxScoringPoints = 20000;
// The plane search and the choice of the support look at every k-th finite point of a frame
// with more than this many (a VGA frame's 5 mm voxels: ~105k, every 6th): a table's plane from
// 10-15k points is as sure as from 80k (its offset's standard error ~0.02 mm), while the search's
// ~25 passes over the points (refits, inlier collections, the checks of each candidate) cost in
// proportion. The chosen table's inliers, hull and object points are then taken from every point.
constexpr size_t kPlaneSearchPoints = kMaxScoringPoints;
constexpr double kRansacConfidence = 0.99;
// Thickness of the slab of inliers taken as the surface itself: the sensor's noise at 1-1.5 m
// (Kinect v1: sigma 1.6-3.5 mm) on either side [m].
constexpr float kSurfaceSlab = 0.008f;
// A higher candidate whose hull is smaller than this fraction of a lower candidate's hull, and
// that stands inside it and within the object height band, is an object's top (a box), not a
// support plane.
constexpr float kObjectTopAreaFraction = 0.25f;
// Support candidates are within this angle of the dominant plane's normal (cos 4 deg).
constexpr float kParallelCosine = 0.99756f;
// Points this far below a candidate, seen through it this far inside its hull and standing this
// far inside it, mean it is not a surface [m]. Within the inset lies the table's own edge: its
// front face (3 cm thick tables) and, on an active-stereo camera, the edge bleeding and depth
// noise that move the hull's edge over it (rendered RealSense scenes: 750 such points 1-5 cm
// inside, 3-9 cm below). A wall behind the table adds its strip at the table's height to the
// inliers, so the hull spans the gap between them, through which the wall below shows: those
// points stand under the hull's edge, not inside it.
constexpr float kBelowSupportDepth = 0.10f;
constexpr float kBelowSupportInset = 0.05f;
// ... and lie below it by more than this many times the depth noise at their range: a far table
// seen by an active-stereo camera (sigma 2-4 cm at 2.5-3 m) has hundreds of points 3-10 cm
// below itself, deep inside its hull.
constexpr float kBelowNoiseSigmas = 4.0f;
// A slice through objects' vertical walls fills the inlier band evenly (RMS residual 0.58 of
// the band's half width); a surface's noise lies well within it (tables of the 80 rendered
// everyday Kinect and RealSense scenes: 0.09-0.18). A slice keeps the plain rule: its line of
// sight this far inside.
constexpr float kMaxSurfaceBandFill = 0.45f;
constexpr float kBelowSliceInset = 0.01f;
// A support surface is seen as a surface: its inliers fill most of its hull (tables on rendered
// and OSD scenes fill 56-99 % of 5 cm cells, the gaps being the shadows of objects). A RANSAC
// sliver through scattered points (the table's front edge, flying pixels, a box top) spans a
// wide hull that it barely fills (5 % at 1.45 m on a rendered scene, where it had been chosen
// over the table). Cells of 5 cm hold several points even for clouds thinned to 2-3 cm.
constexpr float kCoverageCell = 0.05f;
constexpr float kMinSupportCoverage = 0.25f;
// A plane is a surface seen with the sensor's noise: its inliers crowd into the kSurfaceSlab
// around it. Scattered points (a cloud of random points) fill the RANSAC band evenly: the
// densest slab then holds no more points per millimetre than the rest of the band (contrast
// ~1.0-1.3 from chance alone at min_inliers). A Kinect plane at 3 m (sigma ~10 mm, the
// farthest preprocess keeps) still gives 1.5; tables at 0.5-1.5 m give 3 or more.
constexpr float kMinSurfaceContrast = 1.5f;
// estimateUp: a support plane's normal, oriented towards the camera, points up in the image
// (negative optical y) by at least this cosine; walls facing a level or downward-tilted camera,
// box faces and ceilings do not.
constexpr float kMinImageUpCosine = 0.1f;
// Object points within hull_margin of the hull's edge are kept when linked to the points further
// in by steps this short: twice the preprocessing voxel, so neighbouring surface samples link [m].
constexpr float kEdgeLinkDistance = 0.01f;
// GridSearch cell of the outlier removal's k-nearest searches [m].
constexpr float kOutlierSearchCell = 0.025f;
// addPointsOverTheHiddenTable: how far beyond the hull points are taken [m]: two rows of objects
// (on rendered covered tables a reach of 0.12-0.15 m cut back-row objects in two, from 0.2 m on
// every one was whole); and the bins of its depth image on the tangents (0.23 deg: 5 mm voxels
// at 1.25 m).
constexpr float kBeyondHullReach = 0.25f;
constexpr float kRangeImageBin = 0.004f;

// refinePlaneOLS; kFinite: the points are known finite (below).
template <bool kFinite>
bool refinePlane(const Cloud& points, const std::vector<int>& indices, Plane& plane);

// How candidate planes are oriented and which normals are acceptable.
struct NormalConstraint {
  Eigen::Vector3f axis;  // accepted normals satisfy normal . axis >= min_cos
  float min_cos;
  bool orient_to_origin;  // orient normals towards the camera (else along axis)
};

// How the candidate's nearer half of inliers (where the inlier band does not clip a sensor's
// noise yet) lies about its plane: the RMS residual, and the RMS of residual / range^2, the depth
// noise at 1 m for noise growing with the square of the range (structured light, active stereo).
struct SurfaceNoise {
  float rms = 0.0f;
  float at_one_metre = 0.0f;
};

struct Candidate {
  Plane plane;
  std::vector<int> inliers;
  // How many of the frame's points each of the search's points stands for (PlaneSearchSample):
  // point counts of the checks are scaled by it; and the frame, when the search's points are a
  // sample of it (hasPointsBelow counts the points below the candidate in the frame: its 50
  // points would be 8-9 of the sample, too few to tell a slice through box tops and gaps from a
  // table seen in gaps).
  int stride = 1;
  const Cloud* frame = nullptr;
  // The planes found before this one, whose inliers the search had removed (in its points).
  std::vector<Plane> found_before;
  std::vector<Eigen::Vector3f> hull;  // 3-D, on the plane, counter-clockwise about the normal
  std::vector<Eigen::Vector2f> hull_2d;
  PolygonEdges hull_edges;  // of hull_2d: the point-in-hull tests of whole frames
  Eigen::Vector3f u, v;     // in-plane basis of hull_2d
  float area = 0.0f;
  Eigen::Vector3f centroid = Eigen::Vector3f::Zero();
  // surfaceNoiseOf's result, once computed: the chosen table's is asked twice (hasPointsBelow,
  // then the result's depth noise).
  mutable std::optional<SurfaceNoise> noise;
  // selectSupport's checks (coverageOf, pointsBelowOf, objectsOf), once computed: findPlanes'
  // judge may compute them ahead. Each is asked by the judge's thread or, after it has been
  // joined, by the thread that searched the candidates.
  mutable std::optional<float> coverage;
  mutable std::optional<bool> points_below;
  mutable std::optional<std::vector<int>> objects;
};

// A count of the frame's points as a count of the candidate's search points (rounded up).
int inSearchPoints(int frame_points, const Candidate& candidate) {
  return (frame_points + candidate.stride - 1) / candidate.stride;
}

// The points a plane search looks at: the finite ones of every stride-th point of the frame, in
// its order (the voxels of neighbouring pixels follow each other, so the sample is spread over
// the whole image), at most about max_points; the frame itself when it holds no more than that.
class PlaneSearchSample {
 public:
  explicit PlaneSearchSample(const Cloud& cloud, size_t max_points = kPlaneSearchPoints)
      : frame_(cloud) {
    stride_ = static_cast<int>((cloud.size() + max_points - 1) / std::max<size_t>(max_points, 1));
    if (stride_ <= 1) {
      stride_ = 1;
      return;
    }
    sampled_.reserve(cloud.size() / stride_ + 1);
    for (size_t i = 0; i < cloud.size(); i += stride_) {
      if (cloud[i].getVector3fMap().allFinite()) sampled_.push_back(cloud[i]);
    }
    sampled_.header = cloud.header;
    sampled_.sensor_origin_ = cloud.sensor_origin_;
    sampled_.sensor_orientation_ = cloud.sensor_orientation_;
  }
  const Cloud& frame() const { return frame_; }
  const Cloud& points() const { return stride_ > 1 ? sampled_ : frame_; }
  int stride() const { return stride_; }

 private:
  const Cloud& frame_;
  Cloud sampled_;
  int stride_ = 1;
};

// selectSupport's checks of a candidate, each computed once (defined below).
float coverageOf(const Cloud& cloud, const Candidate& candidate);
bool pointsBelowOf(const Cloud& cloud, const Candidate& candidate, const TableParams& params);
const std::vector<int>& objectsOf(const Cloud& cloud, const Candidate& candidate,
                                  const TableParams& params);

Plane orient(Plane plane, const NormalConstraint& constraint) {
  const bool flip =
      constraint.orient_to_origin ? plane.d < 0.0f : plane.normal.dot(constraint.axis) < 0.0f;
  if (flip) {
    plane.normal = -plane.normal;
    plane.d = -plane.d;
  }
  return plane;
}

bool acceptable(const Plane& oriented, const NormalConstraint& constraint) {
  return oriented.normal.dot(constraint.axis) >= constraint.min_cos;
}

// Plane through three points; false when they are (nearly) collinear.
bool planeThrough(const Eigen::Vector3f& a, const Eigen::Vector3f& b, const Eigen::Vector3f& c,
                  Plane& plane) {
  const Eigen::Vector3f n = (b - a).cross(c - a);
  const float norm = n.norm();
  if (!(norm > 1e-9f)) return false;
  plane.normal = n / norm;
  plane.d = -plane.normal.dot(a);
  return true;
}

// Which points of a cloud lie in a band about a plane: their signed distance in [low, high]
// (inclusive) or (low, high), each computed with Plane::signedDistance's float operations in its
// order (Eigen's dot: nx x + (ny y + nz z), then + d), so the same points pass as with
// signedDistance. Points with a coordinate that is not finite have no finite distance and never
// pass.
struct PlaneBand {
  Plane plane;
  float low, high;
  bool inclusive;
  bool contains(const Eigen::Vector3f& p) const {
    const float distance = plane.signedDistance(p);
    return inclusive ? distance >= low && distance <= high : distance > low && distance < high;
  }
};

#if defined(__x86_64__) && defined(__GNUC__)
// Points p (the lower half) and q (the upper) of a cloud, x y z and the fourth float each.
__attribute__((target("avx2"), always_inline)) inline __m256 pointPair(const Point* p,
                                                                       const Point* q) {
  return _mm256_insertf128_ps(_mm256_castps128_ps256(_mm_loadu_ps(&p->x)), _mm_loadu_ps(&q->x), 1);
}

// bandMasks eight lanes at a time (no fused multiply-add: the same floats).
__attribute__((target("avx2"))) void bandMasksAvx2(const Point* points, size_t blocks,
                                                   const PlaneBand& band, uint8_t* masks) {
  const __m256 nx = _mm256_set1_ps(band.plane.normal.x()),
               ny = _mm256_set1_ps(band.plane.normal.y()),
               nz = _mm256_set1_ps(band.plane.normal.z()), d = _mm256_set1_ps(band.plane.d);
  const __m256 low = _mm256_set1_ps(band.low), high = _mm256_set1_ps(band.high);
  for (size_t b = 0; b < blocks; ++b, points += 8) {
    // Points 0-3 in the lower halves, 4-7 in the upper: transposed within each half, the lanes
    // hold the points in order.
    const __m256 p0 = pointPair(points, points + 4), p1 = pointPair(points + 1, points + 5),
                 p2 = pointPair(points + 2, points + 6), p3 = pointPair(points + 3, points + 7);
    const __m256d low01 = _mm256_castps_pd(_mm256_unpacklo_ps(p0, p1)),
                  low23 = _mm256_castps_pd(_mm256_unpacklo_ps(p2, p3));
    const __m256 x = _mm256_castpd_ps(_mm256_unpacklo_pd(low01, low23));
    const __m256 y = _mm256_castpd_ps(_mm256_unpackhi_pd(low01, low23));
    const __m256 z =
        _mm256_castpd_ps(_mm256_unpacklo_pd(_mm256_castps_pd(_mm256_unpackhi_ps(p0, p1)),
                                            _mm256_castps_pd(_mm256_unpackhi_ps(p2, p3))));
    const __m256 distance =
        _mm256_add_ps(_mm256_add_ps(_mm256_mul_ps(nx, x),
                                    _mm256_add_ps(_mm256_mul_ps(ny, y), _mm256_mul_ps(nz, z))),
                      d);
    const __m256 in = band.inclusive ? _mm256_and_ps(_mm256_cmp_ps(distance, low, _CMP_GE_OQ),
                                                     _mm256_cmp_ps(distance, high, _CMP_LE_OQ))
                                     : _mm256_and_ps(_mm256_cmp_ps(distance, low, _CMP_GT_OQ),
                                                     _mm256_cmp_ps(distance, high, _CMP_LT_OQ));
    masks[b] = static_cast<uint8_t>(_mm256_movemask_ps(in));
  }
}
#endif

// Which of the points [0, 8 blocks) of `points` lie in the band: bit j of masks[b] for point
// 8 b + j. Eight lanes at a time where the CPU has AVX2, else four.
void bandMasks(const Point* points, size_t blocks, const PlaneBand& band, uint8_t* masks) {
#if defined(__x86_64__) && defined(__GNUC__)
  if (cpuHasAvx2()) return bandMasksAvx2(points, blocks, band, masks);
#endif
#ifdef __SSE__
  const Float4 nx = broadcast(band.plane.normal.x()), ny = broadcast(band.plane.normal.y()),
               nz = broadcast(band.plane.normal.z()), d = broadcast(band.plane.d);
  const Float4 low = broadcast(band.low), high = broadcast(band.high);
  for (size_t b = 0; b < 2 * blocks; ++b, points += 4) {
    Float4 x, y, z;
    coordinatesOfFour(points, x, y, z);
    const Float4 distance = (nx * x + (ny * y + nz * z)) + d;
    const Int4 in = band.inclusive ? (distance >= low) & (distance <= high)
                                   : (distance > low) & (distance < high);
    const unsigned lanes = lanesOf(in);
    masks[b / 2] = static_cast<uint8_t>(b % 2 ? masks[b / 2] | lanes << 4 : lanes);
  }
#else
  for (size_t k = 0; k < 8 * blocks; ++k) {
    const unsigned in = band.contains(points[k].getVector3fMap());
    masks[k / 8] = static_cast<uint8_t>(k % 8 ? masks[k / 8] | in << (k % 8) : in);
  }
#endif
}

// The most blocks of eight points forEachBandMask tests at a time.
constexpr size_t kMaskBlocks = 128;

// Calls visitBlocks(first, masks, blocks) for the cloud's points from `first` on, blocks of eight
// at a time, with their bandMasks, up to 1024 points a call (so that a visit that stops early
// leaves few computed in vain), then visitRest(i) for each of the last cloud.size() % 8 points
// in the band, in order, while both return true.
template <typename VisitBlocks, typename VisitRest>
void forEachBandMask(const Cloud& cloud, const PlaneBand& band, VisitBlocks&& visitBlocks,
                     VisitRest&& visitRest) {
  uint8_t masks[kMaskBlocks];
  const size_t n = cloud.size();
  size_t i = 0;
  while (n - i >= 8) {
    const size_t blocks = std::min(kMaskBlocks, (n - i) / 8);
    bandMasks(cloud.points.data() + i, blocks, band, masks);
    if (!visitBlocks(i, masks, blocks)) return;
    i += 8 * blocks;
  }
  for (; i < n; ++i) {
    if (band.contains(cloud[i].getVector3fMap()) && !visitRest(static_cast<int>(i))) return;
  }
}

// Calls visit(i) for the points of `cloud` whose signed distance from `plane` lies within
// [low, high] (inclusive) or (low, high), in the cloud's order, while visit returns true (as
// PlaneBand tells them). A frame's passes over its ~100k points (object points, points below a
// candidate, the hidden table's) keep a few thousand.
template <typename Visit>
void forEachPointInBand(const Cloud& cloud, const Plane& plane, float low, float high,
                        bool inclusive, Visit&& visit) {
  forEachBandMask(
      cloud, PlaneBand{plane, low, high, inclusive},
      [&](size_t first, const uint8_t* masks, size_t blocks) {
        for (size_t b = 0; b < blocks; ++b) {
          for (unsigned lanes = masks[b]; lanes != 0; lanes &= lanes - 1) {
            if (!visit(static_cast<int>(first + 8 * b) + __builtin_ctz(lanes))) return false;
          }
        }
        return true;
      },
      visit);
}

// The points of `cloud` within half_width of `plane` (|signed distance| <= half_width, as
// forEachPointInBand's inclusive band tests them) and farther than `threshold` from every plane
// of `others`, in the cloud's order, as `within`. Their indices stored four at a time (the lane
// numbers of each half of a mask from a table) instead of one call per point: onEveryPoint's
// three passes keep most of the frame (~80 k points of the 4-object speed scene), where the
// visit per point cost twice the distances of all.
void collectInBand(const Cloud& cloud, const Plane& plane, float half_width,
                   const std::vector<Plane>& others, float threshold, std::vector<int>& within) {
  // kInOrder[mask]: the lanes set in the 4-bit mask, in order (then zeros); kCount: how many.
  static constexpr int kInOrder[16][4] = {{0, 0, 0, 0}, {0, 0, 0, 0}, {1, 0, 0, 0}, {0, 1, 0, 0},
                                          {2, 0, 0, 0}, {0, 2, 0, 0}, {1, 2, 0, 0}, {0, 1, 2, 0},
                                          {3, 0, 0, 0}, {0, 3, 0, 0}, {1, 3, 0, 0}, {0, 1, 3, 0},
                                          {2, 3, 0, 0}, {0, 2, 3, 0}, {1, 2, 3, 0}, {0, 1, 2, 3}};
  static constexpr uint8_t kCount[16] = {0, 1, 1, 2, 1, 2, 2, 3, 1, 2, 2, 3, 2, 3, 3, 4};
  within.resize(cloud.size() + 4);  // room for the four lanes stored past the last one kept
  int* const out = within.data();
  size_t kept = 0;
  auto nearOther = [&](const Eigen::Vector3f& p) {
    return std::any_of(others.begin(), others.end(), [&](const Plane& other) {
      return std::abs(other.signedDistance(p)) <= threshold;
    });
  };
  uint8_t near_others[kMaskBlocks];
  forEachBandMask(
      cloud, PlaneBand{plane, -half_width, half_width, true},
      [&](size_t first, uint8_t* masks, size_t blocks) {
        for (const Plane& other : others) {  // |distance| <= threshold: within [-it, it]
          bandMasks(cloud.points.data() + first, blocks,
                    PlaneBand{other, -threshold, threshold, true}, near_others);
          for (size_t b = 0; b < blocks; ++b) masks[b] &= ~near_others[b];
        }
        auto store = [&](unsigned lanes, int at) {
          Int4 order;
          std::memcpy(&order, kInOrder[lanes], sizeof order);
          const Int4 indices = order + at;
          std::memcpy(out + kept, &indices, sizeof indices);
          kept += kCount[lanes];
        };
        for (size_t b = 0; b < blocks; ++b) {
          const int at = static_cast<int>(first + 8 * b);
          store(masks[b] & 15u, at);
          store(masks[b] >> 4, at + 4);
        }
        return true;
      },
      [&](int i) {
        if (!nearOther(cloud[i].getVector3fMap())) out[kept++] = i;
        return true;
      });
  within.resize(kept);
}

// RANSAC's scoring points as four-float columns of x, y and z: a hypothesis's inliers are
// counted four at a time as ((nx x + ny y) + nz z) + d. Eigen's dot in Plane::signedDistance
// adds in another order (nx x + (ny y + nz z)): a point within a float's rounding of the
// threshold may count differently from a plain loop (deterministic; the refits use
// signedDistance's order).
class ScoringPoints {
 public:
  ScoringPoints(const Cloud& cloud, const std::vector<int>& indices)
      : columns_((indices.size() + 3) / 4) {
    for (size_t k = 0; k < columns_.size() * 4; ++k) {
      Column& column = columns_[k / 4];
      // Padding: NaN, never within any distance.
      const float nan = std::numeric_limits<float>::quiet_NaN();
      Eigen::Vector3f p = Eigen::Vector3f::Constant(nan);
      if (k < indices.size()) p = cloud[indices[k]].getVector3fMap();
      column.x[k % 4] = p.x(), column.y[k % 4] = p.y(), column.z[k % 4] = p.z();
    }
  }

  size_t countWithin(const Plane& plane, float threshold) const {
    const Floats nx = Floats{} + plane.normal.x(), ny = Floats{} + plane.normal.y(),
                 nz = Floats{} + plane.normal.z(), d = Floats{} + plane.d,
                 limit = Floats{} + threshold;
    Ints count = {0, 0, 0, 0};
    for (const Column& column : columns_) {
      const Floats distance = nx * column.x + ny * column.y + nz * column.z + d;
      const Floats magnitude = (Floats)((Ints)distance & 0x7fffffff);  // |distance|
      count -= magnitude <= limit;                                     // true is -1
    }
    return static_cast<size_t>(count[0]) + count[1] + count[2] + count[3];
  }

 private:
  using Floats = float __attribute__((vector_size(16)));
  using Ints = int32_t __attribute__((vector_size(16)));
  struct Column {
    Floats x, y, z;
  };
  std::vector<Column> columns_;
};

// The surface of a plane: its inliers' densest kSurfaceSlab, the plane refined on the points
// within it and its inliers (within `threshold`) collected again; `collect(plane, half_width,
// indices)` gives the points within half_width of a plane. Objects standing on the surface add
// the lowest centimetres of their sides evenly over the band above it; where they cover most of
// a table they outnumber the table's own points there, and the plane with the most inliers lies
// 1.5 cm above the table (test: a table 70 % covered by boxes). False, with plane and inliers
// unchanged, when the slab holds fewer than 3 points or no plane.
template <typename Collect>
bool refitOnDensestSlab(const Cloud& cloud, const NormalConstraint& constraint, float threshold,
                        const Collect& collect, Plane& plane, std::vector<int>& inliers) {
  std::vector<float> distances(inliers.size());
  size_t k = 0;
#ifdef __SSE__
  // Four at a time, each lane with signedDistance's float operations in its order.
  const Float4 nx = broadcast(plane.normal.x()), ny = broadcast(plane.normal.y()),
               nz = broadcast(plane.normal.z()), d = broadcast(plane.d);
  for (; k + 4 <= inliers.size(); k += 4) {
    Float4 x, y, z;
    coordinatesOfFour(cloud.points.data(), &inliers[k], x, y, z);
    const Float4 distance = (nx * x + (ny * y + nz * z)) + d;
    std::memcpy(&distances[k], &distance, sizeof distance);
  }
#endif
  for (; k < inliers.size(); ++k)
    distances[k] = plane.signedDistance(cloud[inliers[k]].getVector3fMap());
  const DensestSlab slab_of_most = densestSlab(distances, kSurfaceSlab);
  if (slab_of_most.count < 3) return false;
  Plane shifted = plane;
  shifted.d -= (slab_of_most.low + slab_of_most.high) / 2;
  std::vector<int> slab;
  collect(shifted, kSurfaceSlab / 2, slab);
  Plane refined = shifted;
  if (!refinePlane<true>(cloud, slab, refined)) return false;
  plane = orient(refined, constraint);
  collect(plane, threshold, inliers);
  return true;
}

// RANSAC for the plane with the most inliers among `indices` whose (oriented) normal satisfies
// the constraint, refined by OLS and re-collected. False when no acceptable plane is found.
// The refined plane is returned even when it leaves the constraint: its inliers then lie on a
// plane tilted beyond it, which a hypothesis within it cut along a strip (a 20 deg plane was
// taken as a table through a strip 7.7 deg from up), and the caller refuses it.
bool ransacPlane(const Cloud& cloud, const std::vector<int>& indices, const TableParams& params,
                 const NormalConstraint& constraint, std::mt19937& rng, Plane& plane,
                 std::vector<int>& inliers) {
  if (indices.size() < 3) return false;
  std::vector<int> scoring = indices;
  if (scoring.size() > kMaxScoringPoints) {
    std::shuffle(scoring.begin(), scoring.end(), rng);
    scoring.resize(kMaxScoringPoints);
  }
  const ScoringPoints scoring_points(cloud, scoring);
  std::uniform_int_distribution<size_t> pick(0, indices.size() - 1);
  const float threshold = params.distance_threshold;
  size_t best_count = 0;
  Plane best;
  double needed = params.max_iterations;
  for (int iteration = 0; iteration < params.max_iterations && iteration < needed; ++iteration) {
    Plane hypothesis;
    if (!planeThrough(cloud[indices[pick(rng)]].getVector3fMap(),
                      cloud[indices[pick(rng)]].getVector3fMap(),
                      cloud[indices[pick(rng)]].getVector3fMap(), hypothesis)) {
      continue;
    }
    hypothesis = orient(hypothesis, constraint);
    if (!acceptable(hypothesis, constraint)) continue;
    const size_t count = scoring_points.countWithin(hypothesis, threshold);
    if (count > best_count) {
      best_count = count;
      best = hypothesis;
      const double w = static_cast<double>(count) / static_cast<double>(scoring.size());
      const double all_inliers = 1.0 - w * w * w;
      needed = all_inliers <= 0.0 ? 0.0 : std::log(1.0 - kRansacConfidence) / std::log(all_inliers);
    }
  }
  if (best_count < 3) return false;
  const PointsNearPlane search_points(cloud, indices);
  // Two rounds of OLS on the inliers: the second one on the set the refined plane explains.
  plane = best;
  bool inliers_of_plane = false;  // `inliers` are those of `plane`: no need to collect again
  for (int round = 0; round < 2; ++round) {
    search_points.collect(plane, threshold, inliers);
    inliers_of_plane = true;
    Plane refined = plane;
    if (!refinePlane<true>(cloud, inliers, refined)) break;
    plane = orient(refined, constraint);
    inliers_of_plane = false;
    if (!acceptable(plane, constraint)) {
      search_points.collect(plane, threshold, inliers);
      return true;
    }
  }
  // The surface itself: two rounds of refitOnDensestSlab.
  auto collect = [&](const Plane& band, float half_width, std::vector<int>& within) {
    search_points.collect(band, half_width, within);
  };
  for (int round = 0; round < 2; ++round) {
    if (!refitOnDensestSlab(cloud, constraint, threshold, collect, plane, inliers)) break;
    inliers_of_plane = true;
    if (!acceptable(plane, constraint)) return true;
  }
  if (!inliers_of_plane) search_points.collect(plane, threshold, inliers);
  return true;
}

// The candidate's hull. `inside`: points known to lie within it (the hull of a sample of its
// inliers, on a plane a few micrometres from this one at the hull): the inliers surely inside
// the ExtremeOctagon of those points are dropped as they are projected, before they are stored
// and sorted. The hull is the same; should the octagon not lie within it (some of `inside` out
// of the hull), it is made again from all inliers.
void buildHull(const Cloud& cloud, Candidate& candidate,
               const std::vector<Eigen::Vector3f>& inside = {}) {
  const Eigen::Vector3f& n = candidate.plane.normal;
  candidate.u = n.unitOrthogonal();
  candidate.v = n.cross(candidate.u);
  std::vector<Eigen::Vector2f> inner;
  for (const Eigen::Vector3f& p : inside)
    inner.emplace_back(candidate.u.dot(p), candidate.v.dot(p));
  constexpr float kInsideTolerance = 5e-5f;  // [m]
  const ExtremeOctagon octagon(inner, 2 * kInsideTolerance);
  std::vector<Eigen::Vector2f> projected;
  auto projectInliers = [&](bool drop_surely_inside) {
    projected.clear();
    auto keep = [&](const Eigen::Vector2f& q) {
      if (!drop_surely_inside || !octagon.surelyInside(q)) projected.push_back(q);
    };
    const std::vector<int>& inliers = candidate.inliers;
    size_t k = 0;
#ifdef __SSE__
    // Four inliers at a time (a table's ~76 k): each lane makes the float operations of Eigen's
    // dot in its order (u.x x + (u.y y + u.z z)), as forEachPointInBand's lanes, so the same
    // projections.
    const Eigen::Vector3f &u = candidate.u, &v = candidate.v;
    const Float4 ux = broadcast(u.x()), uy = broadcast(u.y()), uz = broadcast(u.z());
    const Float4 vx = broadcast(v.x()), vy = broadcast(v.y()), vz = broadcast(v.z());
    for (; k + 4 <= inliers.size(); k += 4) {
      Float4 x, y, z;
      coordinatesOfFour(cloud.points.data(), &inliers[k], x, y, z);
      const Float4 along_u = ux * x + (uy * y + uz * z), along_v = vx * x + (vy * y + vz * z);
      for (int lane = 0; lane < 4; ++lane) keep(Eigen::Vector2f(along_u[lane], along_v[lane]));
    }
#endif
    for (; k < inliers.size(); ++k) {
      const Eigen::Vector3f p = cloud[inliers[k]].getVector3fMap();
      keep(Eigen::Vector2f(candidate.u.dot(p), candidate.v.dot(p)));
    }
  };
  projectInliers(true);
  candidate.hull_2d = convexHull2d(std::move(projected));
  if (!octagon.within(candidate.hull_2d, kInsideTolerance)) {
    projectInliers(false);
    candidate.hull_2d = convexHull2d(std::move(projected));
  }
  candidate.hull_edges = PolygonEdges(candidate.hull_2d);
  const Eigen::Vector3f origin = -candidate.plane.d * n;  // the plane point nearest the origin
  candidate.hull.clear();
  candidate.area = 0.0f;
  Eigen::Vector2f centroid_2d = Eigen::Vector2f::Zero();
  for (size_t i = 0; i < candidate.hull_2d.size(); ++i) {
    const Eigen::Vector2f& a = candidate.hull_2d[i];
    const Eigen::Vector2f& b = candidate.hull_2d[(i + 1) % candidate.hull_2d.size()];
    candidate.hull.push_back(origin + a.x() * candidate.u + a.y() * candidate.v);
    candidate.area += 0.5f * (a.x() * b.y() - b.x() * a.y());
    centroid_2d += a;
  }
  if (!candidate.hull_2d.empty()) centroid_2d /= static_cast<float>(candidate.hull_2d.size());
  candidate.centroid = origin + centroid_2d.x() * candidate.u + centroid_2d.y() * candidate.v;
}

// The tangents (x / z, y / z) of the cloud's points: what the camera's image spans.
struct ImageSpan {
  Eigen::Vector2f low{0.0f, 0.0f}, high{0.0f, 0.0f};
  bool known = false;
};

ImageSpan imageSpanOf(const Cloud& cloud) {
  ImageSpan span;
  span.low.setConstant(std::numeric_limits<float>::max());
  span.high.setConstant(-std::numeric_limits<float>::max());
  for (const auto& point : cloud.points) {
    if (!(point.z > 0.0f) || !point.getVector3fMap().allFinite()) continue;
    const Eigen::Vector2f tangent(point.x / point.z, point.y / point.z);
    span.low = span.low.cwiseMin(tangent);
    span.high = span.high.cwiseMax(tangent);
    span.known = true;
  }
  return span;
}

// A point above the candidate but outside its hull that stands on the table beyond the image's
// border: the table beneath it is out of view (so the hull, of the table seen, ends at the
// border), yet the camera sees the table behind it, inside the hull. A box cut by the image's
// bottom border of a steep view projects onto the table in front of the visible table: every
// one was lost. Something in front of the table's visible front edge has its foot in view (the
// floor's extension), and a wall behind the table has its line of sight beyond the hull.
bool standsBeyondTheImage(const Eigen::Vector3f& p, float height, const Candidate& candidate,
                          const Eigen::Vector3f& eye, float eye_height, const ImageSpan& span) {
  if (!(height < eye_height)) return false;  // the line of sight does not reach the table
  const Eigen::Vector3f crossing = eye + (p - eye) * (eye_height / (eye_height - height));
  const Eigen::Vector2f q(candidate.u.dot(crossing), candidate.v.dot(crossing));
  if (!candidate.hull_edges.insideBy(q, 0.0f)) return false;
  const Eigen::Vector3f foot = p - height * candidate.plane.normal;
  if (!(foot.z() > 0.0f)) return true;  // behind the camera
  const Eigen::Vector2f tangent(foot.x() / foot.z(), foot.y() / foot.z());
  return (tangent.array() < span.low.array()).any() || (tangent.array() > span.high.array()).any();
}

// Appends to `indices` the points of `candidates` (indices into `cloud`) linked to one of `seeds`
// (indices into `cloud`) by steps of at most kEdgeLinkDistance through candidates.
void addLinkedPoints(const Cloud& cloud, const std::vector<int>& candidates,
                     const std::vector<int>& seeds, std::vector<int>& indices) {
  if (candidates.empty() || seeds.empty()) return;
  auto candidate_points = std::make_shared<Cloud>();
  candidate_points->reserve(candidates.size());
  for (int i : candidates) candidate_points->push_back(cloud[i]);
  GridSearch<Point> tree(kEdgeLinkDistance, false);
  tree.setInputCloud(candidate_points);
  std::vector<bool> linked(candidates.size(), false);
  std::vector<int> frontier, neighbours;
  std::vector<float> distances;
  auto takeNeighbours = [&](const Point& p) {
    tree.radiusSearch(p, kEdgeLinkDistance, neighbours, distances);
    for (int j : neighbours) {
      if (!linked[j]) {
        linked[j] = true;
        frontier.push_back(j);
      }
    }
  };
  for (int i : seeds) takeNeighbours(cloud[i]);
  while (!frontier.empty()) {
    const int j = frontier.back();
    frontier.pop_back();
    indices.push_back(candidates[j]);
    takeNeighbours((*candidate_points)[j]);
  }
}

// Points of `cloud` in the height band above the candidate and inside its hull: those at least
// hull_margin inside, and those nearer the hull's edge that belong to something reaching that far
// in (linked to such points by steps of at most kEdgeLinkDistance through the edge band). The
// margin drops noise along the table's edge; but where the table runs out of the image, the
// hull's edge is the image border, and an object standing there (OSD learn38's mug) lost the
// points that lie over the border's 2 cm band. Points outside the hull standing beyond the
// image's border (standsBeyondTheImage) count as inner points.
void objectIndices(const Cloud& cloud, const Candidate& candidate, const TableParams& params,
                   std::vector<int>& indices) {
  indices.clear();
  if (candidate.hull_2d.size() < 3) return;
  const Eigen::Vector3f eye = cloud.sensor_origin_.head<3>();
  const float eye_height = candidate.plane.signedDistance(eye);
  ImageSpan span;  // computed at the first point outside the hull that needs it
  bool span_computed = false;
  std::vector<int> edge_indices;
  std::vector<int> reaching_the_band;  // inner points near enough to link to the band
  forEachPointInBand(
      cloud, candidate.plane, params.min_height, params.max_height, true, [&](int i) {
        const Eigen::Vector3f p = cloud[i].getVector3fMap();
        const float height = candidate.plane.signedDistance(p);
        const Eigen::Vector2f q(candidate.u.dot(p), candidate.v.dot(p));
        const float inside = candidate.hull_edges.insideDistance(q);
        if (inside >= params.hull_margin) {
          if (inside < params.hull_margin + kEdgeLinkDistance) reaching_the_band.push_back(i);
          indices.push_back(i);
        } else if (inside >= 0.0f) {
          edge_indices.push_back(i);
        } else if (eye_height > 0.0f) {
          if (!span_computed) span = imageSpanOf(cloud), span_computed = true;
          if (span.known && standsBeyondTheImage(p, height, candidate, eye, eye_height, span)) {
            reaching_the_band.push_back(i);
            indices.push_back(i);
          }
        }
        return true;
      });
  if (edge_indices.empty() || reaching_the_band.empty()) return;

  // Grow from the inner points into the edge band.
  addLinkedPoints(cloud, edge_indices, reaching_the_band, indices);
  std::sort(indices.begin(), indices.end());  // keep the cloud's order
}

// The nearest range the camera sees in each direction from `eye`: a depth image of the cloud in
// bins of kRangeImageBin on the tangents x / z, y / z (optical frame), so that an unorganised
// (voxel-filtered) cloud can still tell what hides what.
class NearestRangeImage {
 public:
  NearestRangeImage(const Cloud& cloud, const Eigen::Vector3f& eye) : eye_(eye) {
    std::vector<Eigen::Vector3f> seen;  // tangent x, tangent y, range
    seen.reserve(cloud.size());
    Eigen::Vector2f low = Eigen::Vector2f::Constant(std::numeric_limits<float>::max());
    Eigen::Vector2f high = -low;
    for (const Point& point : cloud.points) {
      const Eigen::Vector3f ray = point.getVector3fMap() - eye;
      if (!(ray.z() > 0.0f) || !ray.allFinite()) continue;
      const Eigen::Vector2f tangent = ray.head<2>() / ray.z();
      low = low.cwiseMin(tangent), high = high.cwiseMax(tangent);
      seen.emplace_back(tangent.x(), tangent.y(), ray.norm());
    }
    if (seen.empty()) return;
    low_ = low;
    columns_ = static_cast<int>((high.x() - low.x()) / kRangeImageBin) + 1;
    rows_ = static_cast<int>((high.y() - low.y()) / kRangeImageBin) + 1;
    nearest_.assign(static_cast<size_t>(columns_) * rows_, std::numeric_limits<float>::infinity());
    for (const Eigen::Vector3f& s : seen) {
      float& nearest = nearest_[bin(s.head<2>())];
      nearest = std::min(nearest, s.z());
    }
  }

  // The nearest range seen in the direction of `p` (within one bin around it); infinity when
  // nothing is seen there or `p` lies out of the image.
  float nearestToward(const Eigen::Vector3f& p) const {
    const Eigen::Vector3f ray = p - eye_;
    float nearest = std::numeric_limits<float>::infinity();
    if (nearest_.empty() || !(ray.z() > 0.0f)) return nearest;
    const Eigen::Vector2f cell = (ray.head<2>() / ray.z() - low_) / kRangeImageBin;
    const int column = static_cast<int>(std::floor(cell.x())),
              row = static_cast<int>(std::floor(cell.y()));
    for (int r = std::max(row - 1, 0); r <= std::min(row + 1, rows_ - 1); ++r) {
      for (int c = std::max(column - 1, 0); c <= std::min(column + 1, columns_ - 1); ++c) {
        nearest = std::min(nearest, nearest_[static_cast<size_t>(r) * columns_ + c]);
      }
    }
    return nearest;
  }

 private:
  size_t bin(const Eigen::Vector2f& tangent) const {
    const Eigen::Vector2f cell = (tangent - low_) / kRangeImageBin;
    const int column = std::min(static_cast<int>(cell.x()), columns_ - 1);
    const int row = std::min(static_cast<int>(cell.y()), rows_ - 1);
    return static_cast<size_t>(row) * columns_ + column;
  }

  Eigen::Vector3f eye_;
  Eigen::Vector2f low_ = Eigen::Vector2f::Zero();
  int columns_ = 0, rows_ = 0;
  std::vector<float> nearest_;
};

// Adds to `indices` (objectIndices of the chosen table) the points that stand on the table
// beyond its hull where the table is hidden (issue 15). On a table mostly covered by objects the
// table shows only in front and in gaps: its hull ends a row or two before the back, and the
// back rows' points, over no seen table, were dropped (rendered covered clutter: 10 of 191
// objects lost so, 2 of them rejected as a wall's foot for the few points left inside the hull).
// A point up to kBeyondHullReach outside the hull, in the height band, is taken when the table
// beneath it is hidden (its foot on the plane lies behind a nearer surface by more than the
// edge band of table_edge.h: hull_margin + 4 sigma of the table's depth noise) and it is linked
// to the object points at the hull's edge by steps of kEdgeLinkDistance through such points and
// the edge band's points not yet taken; only behind the hull (the camera looks over the table
// towards its foot), as objects on the table hide only the table behind them. Where the camera
// sees past the table (the floor beyond its edge) or sees the foot itself (a wall's foot, the
// table's own edge), no point is taken; nor in front of the hull, where an object's own overhang
// hides its foot (a bowl's rim at the image's lower border became a piece of its own).
void addPointsOverTheHiddenTable(const Cloud& cloud, const Candidate& table,
                                 const TableParams& params, float depth_noise_at_one_metre,
                                 std::vector<int>& indices) {
  const Eigen::Vector3f eye = cloud.sensor_origin_.head<3>();
  if (table.hull_2d.size() < 3 || indices.empty() || !(table.plane.signedDistance(eye) > 0.0f)) {
    return;
  }
  auto insideHull = [&](const Eigen::Vector3f& p) {
    return table.hull_edges.insideDistance(Eigen::Vector2f(table.u.dot(p), table.v.dot(p)));
  };
  std::vector<bool> taken(cloud.size(), false);
  for (int i : indices) taken[i] = true;
  std::vector<int> in_band, beyond;  // not taken, in the height band: in the edge band, beyond it
  forEachPointInBand(cloud, table.plane, params.min_height, params.max_height, true, [&](int i) {
    if (taken[i]) return true;
    const float inside = insideHull(cloud[i].getVector3fMap());
    if (inside >= 0.0f && inside < params.hull_margin) {
      in_band.push_back(i);
    } else if (inside < 0.0f && inside >= -kBeyondHullReach) {
      beyond.push_back(i);
    }
    return true;
  });
  if (beyond.empty()) return;
  std::vector<int> linkable = in_band;
  const NearestRangeImage range_image(cloud, eye);
  const Eigen::Vector2f eye_2d(table.u.dot(eye), table.v.dot(eye));
  for (int i : beyond) {
    const Eigen::Vector3f p = cloud[i].getVector3fMap();
    const Eigen::Vector3f foot = p - table.plane.signedDistance(p) * table.plane.normal;
    const float range = (foot - eye).norm();
    const float band =
        params.hull_margin + kBelowNoiseSigmas * depth_noise_at_one_metre * range * range;
    const Eigen::Vector2f foot_2d(table.u.dot(p), table.v.dot(p));
    if (range_image.nearestToward(foot) < range - band &&
        segmentMeetsPolygon(table.hull_2d, eye_2d, foot_2d)) {
      linkable.push_back(i);
    }
  }
  std::vector<int> seeds;  // the object points at the hull's edge
  for (int i : indices) {
    if (insideHull(cloud[i].getVector3fMap()) < params.hull_margin + kEdgeLinkDistance) {
      seeds.push_back(i);
    }
  }
  addLinkedPoints(cloud, linkable, seeds, indices);
  std::sort(indices.begin(), indices.end());  // keep the cloud's order
}

// How much denser the inliers are within the kSurfaceSlab around the plane than in the rest
// of the RANSAC band (both per millimetre of thickness): ~1 for scattered points, above
// kMinSurfaceContrast for a surface. Infinite when the band is too thin to tell.
float surfaceContrast(const Cloud& cloud, const Candidate& candidate, float threshold) {
  const float band = 2.0f * threshold;
  if (band < 1.5f * kSurfaceSlab || candidate.inliers.empty()) {
    return std::numeric_limits<float>::infinity();
  }
  std::vector<float> distances;
  distances.reserve(candidate.inliers.size());
  for (int i : candidate.inliers) {
    distances.push_back(candidate.plane.signedDistance(cloud[i].getVector3fMap()));
  }
  const float in_slab = static_cast<float>(densestSlab(distances, kSurfaceSlab).count);
  const float outside = std::max(1.0f, static_cast<float>(distances.size()) - in_slab);
  return (in_slab / kSurfaceSlab) / (outside / (band - kSurfaceSlab));
}

// Up to max_planes planes satisfying the constraint, each with >= min_inliers points; the
// inliers of each are removed before the next is searched. A plane whose refined normal leaves
// the constraint, or whose inliers are scattered points rather than a surface, is no candidate:
// `refused`, when given, receives why (for the reason of "no table"). `among`, when given,
// limits the search to those points (sorted indices). check_as_support: selectSupport will
// choose among the candidates; its checks of each plane higher than those found before it (it
// checks the highest first) are made ahead, beside the search.
std::vector<Candidate> findPlanes(const PlaneSearchSample& sample, const TableParams& params,
                                  const NormalConstraint& constraint,
                                  std::vector<std::string>* refused = nullptr,
                                  const std::vector<int>* among = nullptr,
                                  bool check_as_support = false) {
  const Cloud& cloud = sample.points();
  const size_t stride = static_cast<size_t>(sample.stride());
  std::vector<int> remaining;
  remaining.reserve(among ? among->size() : cloud.size());
  for (size_t i = 0; i < cloud.size(); ++i) {
    if (cloud[i].getVector3fMap().allFinite()) remaining.push_back(static_cast<int>(i));
  }
  if (among) {
    std::vector<int> kept;
    std::set_intersection(remaining.begin(), remaining.end(), among->begin(), among->end(),
                          std::back_inserter(kept));
    remaining.swap(kept);
  }
  std::mt19937 rng(42);  // deterministic: the same frame gives the same table
  // A plane found is judged (its tilt, surface contrast and hull) on a thread of its own while
  // the next one is searched among the points left: the search needs only its inliers.
  struct Judged {
    Candidate candidate;
    bool check_as_support = false;
    std::string refusal;
    std::exception_ptr error;
  };
  auto judge = [&](Judged& judged) {
    try {
      Candidate& candidate = judged.candidate;
      char refusal[128] = "";
      if (!acceptable(candidate.plane, constraint)) {
        const float cosine = std::clamp(candidate.plane.normal.dot(constraint.axis), -1.0f, 1.0f);
        std::snprintf(refusal, sizeof refusal, "a plane of %zu points tilted %.1f deg from up",
                      candidate.inliers.size() * stride,
                      std::acos(cosine) * 180.0f / static_cast<float>(kPi));
      } else if (const float contrast =
                     surfaceContrast(cloud, candidate, params.distance_threshold);
                 contrast < kMinSurfaceContrast) {
        std::snprintf(refusal, sizeof refusal,
                      "%zu scattered points, not a surface (%.2fx denser within %.0f mm of the "
                      "plane than beyond, a surface >= %.1fx)",
                      candidate.inliers.size() * stride, contrast, kSurfaceSlab * 1000.0f,
                      kMinSurfaceContrast);
      }
      judged.refusal = refusal;
      if (!judged.refusal.empty()) return;
      buildHull(cloud, candidate);
      // selectSupport's checks, in its order: each only when the one before passed.
      if (judged.check_as_support && coverageOf(cloud, candidate) >= kMinSupportCoverage &&
          !pointsBelowOf(cloud, candidate, params)) {
        objectsOf(cloud, candidate, params);
      }
    } catch (...) {
      judged.error = std::current_exception();
    }
  };
  const bool judge_aside = workerThreads() > 1;
  // In the order found; with judge_aside, appended under queue_mutex and judged in that order
  // by judgeFound beside the search (on the pool's threads: starting a thread per plane cost
  // ~50 us, 2.5 times a frame).
  std::vector<std::unique_ptr<Judged>> found;
  std::mutex queue_mutex;
  std::condition_variable queued;
  bool searched = false;
  auto judgeFound = [&] {
    for (size_t next = 0;; ++next) {
      Judged* judged = nullptr;
      {
        std::unique_lock<std::mutex> lock(queue_mutex);
        queued.wait(lock, [&] { return searched || next < found.size(); });
        if (next >= found.size()) return;
        judged = found[next].get();
      }
      judge(*judged);
    }
  };
  const size_t min_inliers = std::max<size_t>(
      3, (static_cast<size_t>(std::max(0, params.min_inliers)) + stride - 1) / stride);
  auto search = [&] {
    struct Searched {  // also when the search throws: the judging then ends
      std::mutex& mutex;
      std::condition_variable& queued;
      bool& searched;
      ~Searched() {
        {
          std::lock_guard<std::mutex> lock(mutex);
          searched = true;
        }
        queued.notify_all();
      }
    } searched_at_end{queue_mutex, queued, searched};
    std::vector<Plane> found_before;
    for (int round = 0; round < params.max_planes && remaining.size() >= min_inliers; ++round) {
      auto judged = std::make_unique<Judged>();
      Candidate& candidate = judged->candidate;
      candidate.stride = static_cast<int>(stride);
      if (stride > 1) candidate.frame = &sample.frame();
      candidate.found_before = found_before;
      if (!ransacPlane(cloud, remaining, params, constraint, rng, candidate.plane,
                       candidate.inliers)) {
        break;
      }
      if (candidate.inliers.size() < min_inliers) break;  // later planes are smaller still
      found_before.push_back(candidate.plane);
      // Made ahead only beside the search: on one thread they would only be made sooner.
      judged->check_as_support =
          check_as_support && judge_aside &&
          std::all_of(found.begin(), found.end(), [&](const std::unique_ptr<Judged>& before) {
            return candidate.plane.d < before->candidate.plane.d;
          });
      Judged& to_judge = *judged;
      if (judge_aside) {
        {
          std::lock_guard<std::mutex> lock(queue_mutex);
          found.push_back(std::move(judged));
        }
        queued.notify_all();
      } else {
        judge(to_judge);
        found.push_back(std::move(judged));
      }
      // Remove the inliers (both index lists are sorted).
      std::vector<int> rest;
      rest.reserve(remaining.size() - candidate.inliers.size());
      std::set_difference(remaining.begin(), remaining.end(), candidate.inliers.begin(),
                          candidate.inliers.end(), std::back_inserter(rest));
      remaining.swap(rest);
    }
  };
  if (judge_aside) {
    parallelFor(
        2, [&](size_t item) { item == 0 ? search() : judgeFound(); }, 2);
  } else {
    search();
  }
  std::vector<Candidate> candidates;
  for (const auto& judged : found) {
    if (judged->error) std::rethrow_exception(judged->error);
    if (!judged->refusal.empty()) {
      if (refused) refused->push_back(judged->refusal);
      continue;
    }
    candidates.push_back(std::move(judged->candidate));
  }
  return candidates;
}

// Fraction of the kCoverageCell grid cells inside the candidate's hull that hold an inlier.
float hullCoverage(const Cloud& cloud, const Candidate& candidate) {
  if (candidate.hull_2d.size() < 3) return 0.0f;
  Eigen::Vector2f low = candidate.hull_2d.front(), high = low;
  for (const Eigen::Vector2f& q : candidate.hull_2d) {
    low = low.cwiseMin(q);
    high = high.cwiseMax(q);
  }
  const int columns = static_cast<int>((high.x() - low.x()) / kCoverageCell) + 1;
  const int rows = static_cast<int>((high.y() - low.y()) / kCoverageCell) + 1;
  // Hulls beyond 100 x 100 m (unfiltered far points) are not judged: the grid would be huge.
  if (static_cast<long>(columns) * rows > 4000000L) return 1.0f;
  std::vector<char> occupied(static_cast<size_t>(columns) * static_cast<size_t>(rows), 0);
  for (int i : candidate.inliers) {
    const Eigen::Vector3f p = cloud[i].getVector3fMap();
    const int column = static_cast<int>((candidate.u.dot(p) - low.x()) / kCoverageCell);
    const int row = static_cast<int>((candidate.v.dot(p) - low.y()) / kCoverageCell);
    if (column >= 0 && column < columns && row >= 0 && row < rows) {
      occupied[static_cast<size_t>(row) * columns + column] = 1;
    }
  }
  int inside = 0, covered = 0;
  for (int row = 0; row < rows; ++row) {
    for (int column = 0; column < columns; ++column) {
      const Eigen::Vector2f centre =
          low + kCoverageCell * Eigen::Vector2f(column + 0.5f, row + 0.5f);
      if (!candidate.hull_edges.insideBy(centre, 0.0f)) continue;
      ++inside;
      covered += occupied[static_cast<size_t>(row) * columns + column];
    }
  }
  return inside > 0 ? static_cast<float>(covered) / static_cast<float>(inside) : 1.0f;
}

SurfaceNoise surfaceNoise(const Cloud& cloud, const Candidate& candidate,
                          const Eigen::Vector3f& eye) {
  SurfaceNoise noise;
  std::vector<float> ranges;
  ranges.reserve(candidate.inliers.size());
  for (int i : candidate.inliers) ranges.push_back((cloud[i].getVector3fMap() - eye).norm());
  if (ranges.empty()) return noise;
  std::vector<float> sorted = ranges;
  std::nth_element(sorted.begin(), sorted.begin() + sorted.size() / 2, sorted.end());
  const float median_range = sorted[sorted.size() / 2];
  double sum = 0.0, scaled_sum = 0.0;
  size_t count = 0;
  for (size_t k = 0; k < ranges.size(); ++k) {
    if (!(ranges[k] <= median_range && ranges[k] > 0.0f)) continue;
    const float residual =
        candidate.plane.signedDistance(cloud[candidate.inliers[k]].getVector3fMap());
    const float scaled = residual / (ranges[k] * ranges[k]);
    sum += residual * residual;
    scaled_sum += scaled * scaled;
    ++count;
  }
  if (count == 0) return noise;
  noise.rms = static_cast<float>(std::sqrt(sum / count));
  noise.at_one_metre = static_cast<float>(std::sqrt(scaled_sum / count));
  return noise;
}

// surfaceNoise from the cloud's sensor origin, computed once per candidate.
const SurfaceNoise& surfaceNoiseOf(const Cloud& cloud, const Candidate& candidate) {
  if (!candidate.noise)
    candidate.noise = surfaceNoise(cloud, candidate, cloud.sensor_origin_.head<3>());
  return *candidate.noise;
}

// A support surface hides what lies just beneath it from the camera: a point below it whose
// line of sight crosses the candidate well inside its hull would have been occluded by it. A
// horizontal slice through several objects (a box top plus rings of the other objects' walls
// within the inlier distance: seen on rendered scenes with 600-2000 inliers) shows the lower
// parts of those objects through itself. Testing the line of sight, not the point's own place
// under the hull, keeps a real table: the flying pixels and the floor seen just past its near
// edge lie under its hull, but their lines of sight pass outside it (at 1.5 m this rejected
// the table for the floor). The viewpoint is the cloud's sensor origin (the camera frame's
// origin unless the cloud says otherwise).
// A surface (its inliers lie close to the plane, not spread evenly over the inlier band as a
// slice through vertical walls is) is judged with its own depth noise and edge (see
// kBelowSupportInset, kBelowNoiseSigmas); a slice with the plain rule.
bool hasPointsBelow(const Cloud& cloud, const Candidate& candidate, const TableParams& params) {
  if (candidate.hull_2d.size() < 3) return false;
  const Eigen::Vector3f eye = cloud.sensor_origin_.head<3>();
  const float eye_height = candidate.plane.signedDistance(eye);
  if (!(eye_height > 0.0f)) return false;  // seen from below: nothing to hide
  const SurfaceNoise& noise = surfaceNoiseOf(cloud, candidate);
  const bool surface = noise.rms < kMaxSurfaceBandFill * params.distance_threshold;
  const float inset = surface ? kBelowSupportInset : kBelowSliceInset;
  const float noise_at_one_metre = surface ? noise.at_one_metre : 0.0f;
  int below = 0;
  // The depth band first (depth = -signed distance): most points are not in it, and need no
  // noise depth.
  const float least_depth = 2 * params.distance_threshold;
  const Cloud& frame = candidate.frame ? *candidate.frame : cloud;
  forEachPointInBand(frame, candidate.plane, -kBelowSupportDepth, -least_depth, false, [&](int i) {
    const Eigen::Vector3f p = frame[i].getVector3fMap();
    const float depth = -candidate.plane.signedDistance(p);
    const float noise_depth = kBelowNoiseSigmas * noise_at_one_metre * (p - eye).squaredNorm();
    if (!(depth > std::max(least_depth, noise_depth))) return true;
    // Where the line of sight eye -> p crosses the plane.
    const Eigen::Vector3f crossing = eye + (p - eye) * (eye_height / (eye_height + depth));
    const Eigen::Vector2f q(candidate.u.dot(crossing), candidate.v.dot(crossing));
    const Eigen::Vector2f foot(candidate.u.dot(p), candidate.v.dot(p));
    below += candidate.hull_edges.insideBy(q, inset) &&
             (!surface || candidate.hull_edges.insideBy(foot, inset));
    return below < kMinSupportedPoints;
  });
  return below >= kMinSupportedPoints;
}

float coverageOf(const Cloud& cloud, const Candidate& candidate) {
  if (!candidate.coverage) candidate.coverage = hullCoverage(cloud, candidate);
  return *candidate.coverage;
}

bool pointsBelowOf(const Cloud& cloud, const Candidate& candidate, const TableParams& params) {
  if (!candidate.points_below) candidate.points_below = hasPointsBelow(cloud, candidate, params);
  return *candidate.points_below;
}

const std::vector<int>& objectsOf(const Cloud& cloud, const Candidate& candidate,
                                  const TableParams& params) {
  if (!candidate.objects) objectIndices(cloud, candidate, params, candidate.objects.emplace());
  return *candidate.objects;
}

// True when `top` looks like the top face of an object standing on `base`.
bool isObjectTop(const Candidate& top, const Candidate& base, const TableParams& params) {
  if (top.area >= kObjectTopAreaFraction * base.area) return false;
  const float height = base.plane.signedDistance(top.centroid);
  if (height < params.min_height || height > params.max_height) return false;
  const Eigen::Vector2f q(base.u.dot(top.centroid), base.v.dot(top.centroid));
  return base.hull_edges.insideBy(q, 0.0f);
}

// The support plane among the candidates: the highest one (nearest the camera along its normal,
// i.e. smallest d) that fills its hull, with objects on it, and is not itself an object's top;
// when none carries objects, the highest one. Returns -1 for no candidates. Tables, floors and
// box tops are level together: a candidate tilted against the dominant (first, largest) plane is a
// RANSAC sliver through box tops and noise, never a support (seen on rendered scenes at 0.6-1.3 m).
// `support_objects`, when given, receives the chosen plane's object points (objectIndices), which
// the selection has computed already for a plane with objects.
// `with_objects`, when given, tells whether the chosen plane passed the rules and carries objects.
int selectSupport(const Cloud& cloud, const std::vector<Candidate>& candidates,
                  const TableParams& params, std::vector<int>* support_objects = nullptr,
                  bool* with_objects = nullptr) {
  if (with_objects) *with_objects = false;
  if (candidates.empty()) return -1;
  std::vector<int> order(candidates.size());
  std::iota(order.begin(), order.end(), 0);
  std::sort(order.begin(), order.end(),
            [&](int a, int b) { return candidates[a].plane.d < candidates[b].plane.d; });
  for (size_t rank = 0; rank < order.size(); ++rank) {
    const Candidate& candidate = candidates[order[rank]];
    if (candidate.plane.normal.dot(candidates.front().plane.normal) < kParallelCosine) continue;
    if (coverageOf(cloud, candidate) < kMinSupportCoverage) continue;
    if (pointsBelowOf(cloud, candidate, params)) continue;
    bool object_top = false;
    for (size_t lower = rank + 1; lower < order.size() && !object_top; ++lower) {
      object_top = isObjectTop(candidate, candidates[order[lower]], params);
    }
    if (object_top) continue;
    const std::vector<int>& objects = objectsOf(cloud, candidate, params);
    if (static_cast<int>(objects.size()) >= inSearchPoints(kMinSupportedPoints, candidate)) {
      if (support_objects) *support_objects = objects;
      if (with_objects) *with_objects = true;
      return order[rank];
    }
  }
  int chosen = 0;
  for (int index : order) {  // none carries objects: the highest level plane
    if (candidates[index].plane.normal.dot(candidates.front().plane.normal) >= kParallelCosine) {
      chosen = index;
      break;
    }
  }
  if (support_objects) *support_objects = objectsOf(cloud, candidates[chosen], params);
  return chosen;
}

// The camera's height above a candidate (the viewpoint is the cloud's sensor origin).
float cameraHeightAbove(const Cloud& cloud, const Candidate& candidate) {
  return candidate.plane.signedDistance(cloud.sensor_origin_.head<3>());
}

// True when the candidate's normal lies within 4 deg (kParallelCosine) of `up`.
bool levelWith(const Candidate& candidate, const Eigen::Vector3f& up) {
  return candidate.plane.normal.dot(up) >= kParallelCosine;
}

// How well a candidate at the known camera height fits a table: 3 for a level surface (levelWith
// `up`) that hides nothing beneath it (hasPointsBelow), 2 level, 1 tilted hiding nothing, 0.
// On a table mostly covered by boxes, a plane tilted 3-8 deg through box tops and the table's
// gaps passes the table's height within the tolerance, holds more points than the table, and
// shows the table in the gaps beneath it (rendered covered clutter: 5 of 8 scenes, the fits
// then 3-8 cm off); an up known only roughly (the table tilted against it) still gets its
// tilted table.
int knownHeightRank(const Cloud& cloud, const Candidate& candidate, const TableParams& params,
                    const Eigen::Vector3f& up) {
  return 2 * levelWith(candidate, up) + !pointsBelowOf(cloud, candidate, params);
}

// The knownHeightRank of each candidate within the tolerance of the known camera height, -1 for
// the others, in `ranks` beside `candidates`: only the candidates added since the last call are
// ranked (hasPointsBelow scans the whole cloud, and the table stage asks up to 3 times).
void rankAtKnownHeight(const Cloud& cloud, const std::vector<Candidate>& candidates,
                       const TableParams& params, const Eigen::Vector3f& up,
                       std::vector<int>& ranks) {
  for (size_t i = ranks.size(); i < candidates.size(); ++i) {
    const bool at_height = !(std::abs(cameraHeightAbove(cloud, candidates[i]) -
                                      params.camera_height) > params.camera_height_tolerance);
    ranks.push_back(at_height ? knownHeightRank(cloud, candidates[i], params, up) : -1);
  }
}

// With a known camera height: among the candidates within the tolerance of it, the one of the
// highest knownHeightRank, of those the one with the most inliers; -1 when none is. `ranks` keeps
// the ranks beside `candidates` between calls (rankAtKnownHeight). `rank`, when given, receives
// the chosen one's rank.
int supportAtKnownHeight(const Cloud& cloud, const std::vector<Candidate>& candidates,
                         const TableParams& params, const Eigen::Vector3f& up,
                         std::vector<int>& ranks, int* rank = nullptr) {
  rankAtKnownHeight(cloud, candidates, params, up, ranks);
  int chosen = -1, chosen_rank = -1;
  for (size_t i = 0; i < candidates.size(); ++i) {
    if (ranks[i] < 0) continue;
    if (ranks[i] > chosen_rank ||
        (ranks[i] == chosen_rank &&
         candidates[i].inliers.size() > candidates[chosen].inliers.size())) {
      chosen = static_cast<int>(i);
      chosen_rank = ranks[i];
    }
  }
  if (rank) *rank = chosen_rank;
  return chosen;
}

// Points within the tolerance (and the inlier distance) of the plane normal to `up` at the known
// camera height: where the table must be. Box tops can outnumber the table seen in gaps, and
// with one level per box they take all max_planes searches.
std::vector<int> pointsAtKnownHeight(const Cloud& cloud, const Eigen::Vector3f& up,
                                     const TableParams& params) {
  const Eigen::Vector3f eye = cloud.sensor_origin_.head<3>();
  const Plane expected{up, params.camera_height - up.dot(eye)};
  const float band = params.camera_height_tolerance + params.distance_threshold;
  std::vector<int> band_points;
  forEachPointInBand(cloud, expected, -band, band, true, [&](int i) {
    band_points.push_back(i);
    return true;
  });
  return band_points;
}

// The least height of a table top above the floor it stands on [m] (a coffee table: 0.4 m).
constexpr float kTableAboveFloor = 0.3f;

// On a table mostly covered by boxes, planes tilted 5-7 deg through box tops and the table's
// gaps (within up_tolerance_deg) can have the most inliers and take every search: the table is
// then no candidate and the floor, level with up, is chosen (rendered covered clutter, issue
// 15). When the chosen support is level with `up` (within 4 deg, so up is right) and some
// other candidate lies kTableAboveFloor or more above it (tilted, or level box tops refused for
// the table seen below them), the level planes among the points that high are searched alone; a
// level support with objects above the chosen one replaces it (candidates, chosen and objects). An
// up known only roughly (the table tilted against it) keeps the wide search's choice. The level
// support replacing the chosen one must stand at least kTableAboveFloor above it: a level plane a
// few centimetres up cuts the objects' sides (a rendered paper scene: 1000 inliers 2 cm above the
// 37306 of its table replaced it), a table stands well above the floor.
void preferHigherLevelSupport(const PlaneSearchSample& sample, const TableParams& params,
                              const Eigen::Vector3f& up, std::vector<Candidate>& candidates,
                              int& chosen, std::vector<int>& objects) {
  const Cloud& cloud = sample.points();
  auto level = [&](const Candidate& c) { return c.plane.normal.dot(up) >= kParallelCosine; };
  if (chosen < 0 || !level(candidates[chosen])) return;
  // Only a plane high above the chosen support (tilted through a hidden table's gaps, or box
  // tops over it) betrays such a table; planes near the chosen one (object sides, box tops on
  // it) do not, and the level search they would start costs as much as the table stage (+194M
  // instructions on a rendered 16-object frame).
  const Plane& support = candidates[chosen].plane;
  auto high_above = [&](const Candidate& c) {
    return support.signedDistance(c.centroid) >= kTableAboveFloor;
  };
  if (std::none_of(candidates.begin(), candidates.end(), high_above)) return;
  // Only points a table there could hold are searched: the chosen support's points took one
  // of the searches again, and box tops at several levels the rest (rendered covered scene
  // 3877104083: floor, box tops, two refused planes; the table was no candidate).
  std::vector<int> points_high_above;
  forEachPointInBand(cloud, support, kTableAboveFloor - params.distance_threshold,
                     std::numeric_limits<float>::infinity(), true, [&](int i) {
                       points_high_above.push_back(i);
                       return true;
                     });
  std::vector<Candidate> level_candidates = findPlanes(
      sample, params, NormalConstraint{up, kParallelCosine, false}, nullptr, &points_high_above);
  std::vector<int> level_objects;
  bool with_objects = false;
  const int level_chosen =
      selectSupport(cloud, level_candidates, params, &level_objects, &with_objects);
  if (!with_objects ||
      !(level_candidates[level_chosen].plane.d < candidates[chosen].plane.d - kTableAboveFloor)) {
    return;
  }
  candidates.swap(level_candidates);
  chosen = level_chosen;
  objects.swap(level_objects);
}

// The support chosen among a PlaneSearchSample, on every point of the frame: its inliers among
// the frame's points that no plane found before it had taken (the search had removed those from
// its points), the plane refit once more on their densest slab (ransacPlane's last round, on
// every point: where the sample's slab and the frame's hold the same points, the plane the whole
// search on every point would give), and the hull.
Candidate onEveryPoint(const Cloud& frame, const Candidate& found, const TableParams& params,
                       const NormalConstraint& constraint) {
  Candidate table;
  table.plane = found.plane;
  table.found_before = found.found_before;
  auto collect = [&](const Plane& plane, float half_width, std::vector<int>& within) {
    collectInBand(frame, plane, half_width, found.found_before, params.distance_threshold, within);
  };
  collect(table.plane, params.distance_threshold, table.inliers);
  refitOnDensestSlab(frame, constraint, params.distance_threshold, collect, table.plane,
                     table.inliers);
  buildHull(frame, table, found.hull);
  return table;
}

}  // namespace

TableResult TableSegmenter::segment(const CloudConstPtr& cloud) const {
  TableResult result;
  result.table_points = std::make_shared<Cloud>();
  result.object_points = std::make_shared<Cloud>();
  if (!cloud || cloud->empty()) {
    result.reason = "empty cloud";
    return result;
  }
  result.table_points->header = cloud->header;
  result.object_points->header = cloud->header;
  const float up_norm = params_.up.norm();
  if (!(up_norm > 0.0f) || !params_.up.allFinite()) {
    result.reason = "invalid up vector";
    return result;
  }
  const NormalConstraint constraint{params_.up / up_norm,
                                    std::cos(degToRad(params_.up_tolerance_deg)), false};
  // The support is searched for and chosen among a sample of the points; with the camera's
  // height known, among all: there the choice between a table seen only in gaps and planes
  // tilted through box tops and the gaps, both at the height, falls to their inlier counts, which
  // a sample blurs (a rendered covered scene lost 5 of its 24 objects to such a plane).
  const bool height_known = params_.camera_height > 0.0f;
  const PlaneSearchSample sample(*cloud, height_known ? cloud->size() : kPlaneSearchPoints);
  const Cloud& search = sample.points();
  std::vector<std::string> refused;
  std::vector<Candidate> candidates =
      findPlanes(sample, params_, constraint, &refused, nullptr, !height_known);
  std::vector<int> known_height_ranks;  // beside `candidates` when the camera height is known
  if (height_known) {
    // No level surface hiding nothing at the height (knownHeightRank 3): the level planes of
    // the height band are searched alone (box tops can take every search, tilted planes through
    // them and the gaps too), then, when none is at the height, the band's planes within
    // up_tolerance_deg.
    int rank = -1;
    const int at_height = supportAtKnownHeight(search, candidates, params_, constraint.axis,
                                               known_height_ranks, &rank);
    if (rank < 3) {
      const std::vector<int> band = pointsAtKnownHeight(search, constraint.axis, params_);
      for (const NormalConstraint& search_constraint :
           {NormalConstraint{constraint.axis, kParallelCosine, false}, constraint}) {
        std::vector<Candidate> found =
            findPlanes(sample, params_, search_constraint, &refused, &band);
        for (Candidate& candidate : found) candidates.push_back(std::move(candidate));
        if (at_height >= 0 || supportAtKnownHeight(search, candidates, params_, constraint.axis,
                                                   known_height_ranks) >= 0) {
          break;
        }
      }
    }
  }
  if (candidates.empty()) {
    char reason[128];
    std::snprintf(reason, sizeof reason, "no plane within %g deg of up with at least %d points",
                  params_.up_tolerance_deg, params_.min_inliers);
    result.reason = reason;
    for (size_t i = 0; i < refused.size(); ++i) {
      result.reason += (i == 0 ? "; refused: " : ", ") + refused[i];
    }
    return result;
  }
  std::vector<int> objects;
  int chosen = -1;
  if (height_known) {
    chosen = supportAtKnownHeight(search, candidates, params_, constraint.axis, known_height_ranks);
    if (chosen < 0) {
      std::string heights;
      for (const Candidate& candidate : candidates) {
        char height[16];
        std::snprintf(height, sizeof height, "%s%.3f", heights.empty() ? "" : ", ",
                      cameraHeightAbove(search, candidate));
        heights += height;
      }
      char reason[160];
      std::snprintf(reason, sizeof reason,
                    "no plane within %g m of table.camera_height = %g m below the camera (planes "
                    "found ",
                    params_.camera_height_tolerance, params_.camera_height);
      result.reason = reason + heights + " m below it)";
      return result;
    }
  } else {
    chosen = selectSupport(search, candidates, params_, &objects);
    preferHigherLevelSupport(sample, params_, constraint.axis, candidates, chosen, objects);
  }
  std::optional<Candidate> on_every_point;
  if (sample.stride() > 1)
    on_every_point = onEveryPoint(*cloud, candidates[chosen], params_, constraint);
  const Candidate& table = on_every_point ? *on_every_point : candidates[chosen];
  if (height_known || on_every_point) objects = objectsOf(*cloud, table, params_);

  result.found = true;
  result.plane = table.plane;
  // The depth noise from the chosen plane's inliers among the search's points (computed already
  // by hasPointsBelow): the same statistic, on every k-th inlier.
  result.depth_noise_at_one_metre = surfaceNoiseOf(search, candidates[chosen]).at_one_metre;
  addPointsOverTheHiddenTable(*cloud, table, params_, result.depth_noise_at_one_metre, objects);
  result.inliers = static_cast<int>(table.inliers.size());
  result.hull = table.hull;
  result.table_points->reserve(table.inliers.size());
  for (int i : table.inliers) result.table_points->push_back((*cloud)[i]);

  auto above = std::make_shared<Cloud>();
  above->header = cloud->header;
  // The camera's position travels with the points: the clustering's bowl join needs it.
  above->sensor_origin_ = cloud->sensor_origin_;
  above->sensor_orientation_ = cloud->sensor_orientation_;
  above->reserve(objects.size());
  for (int i : objects) above->push_back((*cloud)[i]);
  removeStatisticalOutliers(above, params_.outlier_k, params_.outlier_alpha, *result.object_points);
  return result;
}

namespace {

#if defined(__x86_64__) && defined(__GNUC__)
#define TABLETOP_SHAPES_PLANE_SUMS_AVX2 1
// refinePlane's sums over the points `indices` (valid, finite) four doubles at a time, x y z and
// the point's fourth float (a lane not used): `sums` of the coordinates; about `centre` (its
// fourth 0), `squares` of the centred coordinates {xx, yy, xz, -} and `products` {xy, yz, zz,
// -}. Each lane adds the products refinePlane's pairs make (x z as z x), in the same order: the
// same doubles, in half the instructions.
__attribute__((target("avx2"))) void coordinateSumsAvx2(const Cloud& points,
                                                        const std::vector<int>& indices,
                                                        double sums[4]) {
  __m256d sum = _mm256_setzero_pd();
  for (const int i : indices) sum = _mm256_add_pd(sum, _mm256_cvtps_pd(_mm_loadu_ps(&points[i].x)));
  _mm256_storeu_pd(sums, sum);
}

__attribute__((target("avx2"))) void scatterSumsAvx2(const Cloud& points,
                                                     const std::vector<int>& indices,
                                                     const double centre[4], double squares[4],
                                                     double products[4]) {
  const __m256d mean = _mm256_loadu_pd(centre);
  __m256d square_sums = _mm256_setzero_pd(), product_sums = _mm256_setzero_pd();
  for (const int i : indices) {
    const __m256d q = _mm256_sub_pd(_mm256_cvtps_pd(_mm_loadu_ps(&points[i].x)), mean);
    // q times {x, y, x, y} and {y, z, z, w}.
    square_sums = _mm256_add_pd(square_sums, _mm256_mul_pd(q, _mm256_permute4x64_pd(q, 0x44)));
    product_sums = _mm256_add_pd(product_sums, _mm256_mul_pd(q, _mm256_permute4x64_pd(q, 0xe9)));
  }
  _mm256_storeu_pd(squares, square_sums);
  _mm256_storeu_pd(products, product_sums);
}
#endif

// refinePlaneOLS; kFinite: the indices are valid and their points finite (RANSAC's points,
// finite by construction), so neither is tested.
template <bool kFinite>
bool refinePlane(const Cloud& points, const std::vector<int>& indices, Plane& plane) {
  // Eq. 4-8 minimise sum (A x + B y + C z + D)^2 with one coefficient fixed. The paper fixes
  // D = -1, which fails for a plane through the origin (D = 0); we fix instead the normal
  // component the plane leans on most, which is never 0 for that plane. The input plane only
  // gives the orientation of the result. The normal equations of the three free coefficients
  // are solved on centred coordinates (D then follows from the centroid), the numerically
  // stable form of eq. 8.
  if (indices.size() < 3) return false;
  // The sums on pairs of doubles (SSE2 through GCC's vector extension), the scatter's six
  // distinct entries only: each entry is the same sum of the same products as the Eigen
  // expressions mean += p and scatter += q q^T give, in about half the instructions (this runs
  // on every table hypothesis's 50-100k inliers).
  using Pair = double __attribute__((vector_size(16)));
  Pair sum_xy = {0.0, 0.0};
  double sum_z = 0.0;
  size_t count = 0;
  auto finite = [](const Point& p) {
    return kFinite || (std::isfinite(p.x) && std::isfinite(p.y) && std::isfinite(p.z));
  };
#ifdef TABLETOP_SHAPES_PLANE_SUMS_AVX2
  const bool four_lanes = kFinite && cpuHasAvx2();
#else
  const bool four_lanes = false;
#endif
  if (four_lanes) {
    double sums[4];
    coordinateSumsAvx2(points, indices, sums);
    sum_xy = Pair{sums[0], sums[1]}, sum_z = sums[2], count = indices.size();
  } else {
    for (int i : indices) {
      if (!kFinite && (i < 0 || static_cast<size_t>(i) >= points.size())) return false;
      const Point& p = points[i];
      if (!finite(p)) continue;
      sum_xy += Pair{p.x, p.y};
      sum_z += p.z;
      ++count;
    }
  }
  if (count < 3) return false;
  Eigen::Vector3d mean(sum_xy[0], sum_xy[1], sum_z);
  mean /= static_cast<double>(count);
  const Pair mean_xy = {mean.x(), mean.y()};
  // Paired so that two of the three products need no lane shuffle of their own.
  Pair xx_yy = {0.0, 0.0}, xy_yz = {0.0, 0.0}, xz_zz = {0.0, 0.0};
  if (four_lanes) {
    const double centre[4] = {mean.x(), mean.y(), mean.z(), 0.0};
    double squares[4], products[4];
    scatterSumsAvx2(points, indices, centre, squares, products);
    xx_yy = Pair{squares[0], squares[1]}, xy_yz = Pair{products[0], products[1]};
    xz_zz = Pair{squares[2], products[2]};
  } else {
    for (int i : indices) {
      const Point& p = points[i];
      if (!finite(p)) continue;
      const Pair xy = Pair{p.x, p.y} - mean_xy;
      const double x = xy[0], y = xy[1], z = p.z - mean.z();
      const Pair zz = {z, z};
      xx_yy += xy * xy;
      xy_yz += xy * Pair{y, z};
      xz_zz += Pair{x, z} * zz;
    }
  }
  Eigen::Matrix3d scatter;
  scatter << xx_yy[0], xy_yz[0], xz_zz[0], xy_yz[0], xx_yy[1], xy_yz[1], xz_zz[0], xy_yz[1],
      xz_zz[1];

  // The fixed coefficient: the normal component that is largest for these points (from the
  // scatter's least-variance direction, so a poor initial plane cannot pick a degenerate one).
  const Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d> eigen(scatter);
  const Eigen::Vector3d least_variance = eigen.eigenvectors().col(0);
  int axes[3] = {0, 1, 2};
  std::sort(axes, axes + 3, [&](int a, int b) {
    return std::abs(least_variance[a]) > std::abs(least_variance[b]);
  });
  const double trace = scatter.trace();
  if (!(trace > 0.0)) return false;
  for (int k : axes) {
    const int i = (k + 1) % 3, j = (k + 2) % 3;
    // Minimise sum (q_k + a q_i + b q_j)^2: [S_ii S_ij; S_ij S_jj] (a b) = -(S_ik S_jk).
    Eigen::Matrix2d normal_matrix;
    normal_matrix << scatter(i, i), scatter(i, j), scatter(i, j), scatter(j, j);
    const double det = normal_matrix.determinant();
    if (!(std::abs(det) > 1e-12 * trace * trace)) continue;  // degenerate in this direction
    const Eigen::Vector2d ab =
        normal_matrix.inverse() * -Eigen::Vector2d(scatter(i, k), scatter(j, k));
    Eigen::Vector3d n;
    n[k] = 1.0;
    n[i] = ab.x();
    n[j] = ab.y();
    n.normalize();
    if (!n.allFinite()) continue;
    Eigen::Vector3f normal = n.cast<float>();
    if (normal.dot(plane.normal) < 0.0f) normal = -normal;  // keep the caller's orientation
    plane.normal = normal;
    plane.d = static_cast<float>(-normal.cast<double>().dot(mean));
    return true;
  }
  return false;  // collinear or coincident points
}

}  // namespace

bool refinePlaneOLS(const Cloud& points, const std::vector<int>& indices, Plane& plane) {
  return refinePlane<false>(points, indices, plane);
}

namespace {

// The bounds of the squared distances and the sum of their roots, in double, in any order.
struct RootSum {
  float smallest, largest, smallest_nonzero;
  double sum;
};

// squared[first .. n) added to `result` one at a time.
void addRoots(const float* squared, size_t first, size_t n, RootSum& result) {
  for (size_t j = first; j < n; ++j) {
    const float d = squared[j];
    result.smallest = std::min(result.smallest, d);
    result.largest = std::max(result.largest, d);
    if (d > 0.0f) result.smallest_nonzero = std::min(result.smallest_nonzero, d);
    result.sum += std::sqrt(d);
  }
}

#if defined(__x86_64__) && defined(__GNUC__)
// rootSum eight values at a time, in one pass (the roots correctly rounded, as std::sqrt): the
// two passes of four cost ~480 instructions for a point's 51 distances.
__attribute__((target("avx2"))) RootSum rootSumAvx2(const float* squared, size_t n) {
  const float infinity = std::numeric_limits<float>::infinity();
  __m256 smallest8 = _mm256_set1_ps(squared[0]), largest8 = smallest8;
  __m256 nonzero8 = _mm256_set1_ps(infinity);
  __m256d low = _mm256_setzero_pd(), high = _mm256_setzero_pd();
  const __m256 zero = _mm256_setzero_ps(), none = _mm256_set1_ps(infinity);
  // `counted`: the lanes whose roots are added (the others' values were added before).
  auto add = [&](__m256 d, __m256 counted) __attribute__((target("avx2"))) {
    smallest8 = _mm256_min_ps(smallest8, d);
    largest8 = _mm256_max_ps(largest8, d);
    nonzero8 =
        _mm256_min_ps(nonzero8, _mm256_blendv_ps(none, d, _mm256_cmp_ps(d, zero, _CMP_GT_OQ)));
    const __m256 root = _mm256_and_ps(_mm256_sqrt_ps(d), counted);
    low = _mm256_add_pd(low, _mm256_cvtps_pd(_mm256_castps256_ps128(root)));
    high = _mm256_add_pd(high, _mm256_cvtps_pd(_mm256_extractf128_ps(root, 1)));
  };
  const __m256 all = _mm256_castsi256_ps(_mm256_set1_epi32(-1));
  size_t j = 0;
  for (; j + 8 <= n; j += 8) add(_mm256_loadu_ps(squared + j), all);
  if (j < n && n >= 8) {
    // The last eight values, ending at n: those seen already count again for the bounds (no
    // change) and add a root of 0 to the sum (no change either; in the order of a sum that
    // sumOfDistancesButTheNearest uses only when every order gives it exactly).
    const __m256i lane = _mm256_setr_epi32(0, 1, 2, 3, 4, 5, 6, 7);
    const __m256i first_new = _mm256_set1_epi32(static_cast<int>(j + 8 - n) - 1);
    add(_mm256_loadu_ps(squared + n - 8), _mm256_castsi256_ps(_mm256_cmpgt_epi32(lane, first_new)));
    j = n;
  }
  alignas(32) float lanes[3][8];
  alignas(32) double sums[2][4];
  _mm256_store_ps(lanes[0], smallest8), _mm256_store_ps(lanes[1], largest8);
  _mm256_store_ps(lanes[2], nonzero8);
  _mm256_store_pd(sums[0], low), _mm256_store_pd(sums[1], high);
  RootSum result{squared[0], squared[0], infinity, 0.0};
  for (int lane = 0; lane < 8; ++lane) {
    result.smallest = std::min(result.smallest, lanes[0][lane]);
    result.largest = std::max(result.largest, lanes[1][lane]);
    result.smallest_nonzero = std::min(result.smallest_nonzero, lanes[2][lane]);
  }
  for (int lane = 0; lane < 4; ++lane) result.sum += sums[0][lane] + sums[1][lane];
  addRoots(squared, j, n, result);
  return result;
}
#endif

// The bounds of the n >= 1 squared distances and the sum of their roots, four at a time.
RootSum rootSum(const float* squared, size_t n) {
#if defined(__x86_64__) && defined(__GNUC__)
  if (cpuHasAvx2()) return rootSumAvx2(squared, n);
#endif
  using Floats = float __attribute__((vector_size(16)));
  using Doubles = double __attribute__((vector_size(16)));
  const size_t blocks = n / 4;
  const float infinity = std::numeric_limits<float>::infinity();
  Floats smallest4 = Floats{} + squared[0], largest4 = smallest4, nonzero4 = Floats{} + infinity;
  Doubles low = {0.0, 0.0}, high = {0.0, 0.0};
  for (size_t b = 0; b < blocks; ++b) {
    Floats d;
    std::memcpy(&d, &squared[4 * b], sizeof d);
    smallest4 = d < smallest4 ? d : smallest4;
    largest4 = d > largest4 ? d : largest4;
    nonzero4 = d > 0.0f && d < nonzero4 ? d : nonzero4;
#ifdef __SSE__
    const Floats root = (Floats)_mm_sqrt_ps((__m128)d);  // correctly rounded, as std::sqrt
#else
    const Floats root = {std::sqrt(d[0]), std::sqrt(d[1]), std::sqrt(d[2]), std::sqrt(d[3])};
#endif
    low += Doubles{root[0], root[1]};
    high += Doubles{root[2], root[3]};
  }
  RootSum result{squared[0], squared[0], infinity, (low[0] + low[1]) + (high[0] + high[1])};
  for (int lane = 0; lane < 4; ++lane) {
    result.smallest = std::min(result.smallest, smallest4[lane]);
    result.largest = std::max(result.largest, largest4[lane]);
    result.smallest_nonzero = std::min(result.smallest_nonzero, nonzero4[lane]);
  }
  addRoots(squared, 4 * blocks, n, result);
  return result;
}

// The sum of the square roots of `squared` (in any order) but its smallest, in double, as PCL
// sums them in ascending order, bit for bit. The order does not matter when the double sum is
// exact: every root is a float, a multiple of 2^(e - 23) with 2^e <= the smallest nonzero root;
// while n * the largest root < 2^(53 + e - 23), every partial sum is a multiple of that
// quantum below 2^53 of them, hence exact, and so is the sum of all less the smallest root.
// Neighbours between a few millimetres and centimetres apart are always far within that (then
// the roots are taken and summed by rootSum, in one pass with the bounds); other sets are
// sorted (into `sorted`) and summed in order.
double sumOfDistancesButTheNearest(const std::vector<float>& squared, std::vector<float>& sorted) {
  if (squared.empty()) return 0.0;
  const size_t n = squared.size();
  const RootSum roots = rootSum(squared.data(), n);
  // Squared distances: n * sqrt(largest) <= 2^29 * sqrt(smallest nonzero), squared.
  const double count = static_cast<double>(n);
  if (!(count * count * roots.largest <= 0x1p58 * roots.smallest_nonzero) && roots.largest > 0.0f) {
    sorted.assign(squared.begin(), squared.end());
    std::sort(sorted.begin(), sorted.end());
    double sum = 0.0;
    for (size_t j = 1; j < sorted.size(); ++j) sum += std::sqrt(sorted[j]);
    return sum;
  }
  return roots.sum - std::sqrt(roots.smallest);
}

}  // namespace

// §2.4 as pcl::StatisticalOutlierRemoval computes it (mean distance to the k nearest
// neighbours, kept while <= mean + alpha * stddev over all points), with the neighbours from a
// GridSearch instead of a k-d tree: the same points are kept, in a fraction of the time.
void removeStatisticalOutliers(const CloudConstPtr& in, int k, float alpha, Cloud& out) {
  out.clear();
  if (!in) return;
  out.header = in->header;
  // Too few points for k-neighbour statistics: keep them all.
  if (k <= 0 || static_cast<int>(in->size()) <= k) {
    out = *in;
    return;
  }
  // The k neighbours of a 5 mm voxel surface lie within ~2 cm: the block of 3 x 3 x 3 cells
  // around a point holds them, gathered once per cell. 2 cm cells left the k-th neighbour of
  // edge points outside too often (the slow general search then): 2x PCL's instructions; 2.5 cm
  // cost 7-13 % fewer instructions than 3 cm (fewer candidates per block) and 2 or 4 cm more
  // (callgrind on the 4 and 16-object speed scenes and OSD learn10 / learn33).
  GridSearch<Point> search(kOutlierSearchCell);
  search.setInputCloud(in);
  std::vector<float> distances(in->size(), 0.0f);  // points without neighbours: 0, as PCL
  // On all cores: each point's distance depends on its neighbours alone. Every searched point
  // is visited: they are the valid ones (counted once here, not by an increment per point
  // shared by the threads).
  search.forEachNearestK(
      k + 1,
      [&](int i, const std::vector<float>& squared) {
        thread_local std::vector<float> sorted;
        distances[i] = static_cast<float>(sumOfDistancesButTheNearest(squared, sorted) / k);
      },
      false, workerThreads());
  const int valid_count = static_cast<int>(search.searchedPoints());
  double sum = 0.0, squared_sum = 0.0;
  for (const float distance : distances) {
    sum += distance;
    squared_sum += distance * distance;
  }
  const double mean = sum / static_cast<double>(valid_count);
  const double variance =
      (squared_sum - sum * sum / static_cast<double>(valid_count)) / (valid_count - 1.0);
  const double threshold = mean + alpha * std::sqrt(variance);
  out.reserve(in->size());
  for (size_t i = 0; i < in->size(); ++i) {
    if (distances[i] <= threshold) out.push_back((*in)[i]);
  }
  out.header = in->header;
  out.sensor_origin_ = in->sensor_origin_;
  out.sensor_orientation_ = in->sensor_orientation_;
}

bool estimateUp(const CloudConstPtr& cloud, const TableParams& params, Eigen::Vector3f& up) {
  if (!cloud || cloud->empty()) return false;
  // Candidates: large planes with the camera on their positive side whose normal points up in
  // the image (walls facing the camera and box faces do not).
  const NormalConstraint constraint{Eigen::Vector3f(0.0f, -1.0f, 0.0f), kMinImageUpCosine, true};
  const PlaneSearchSample sample(*cloud);
  const std::vector<Candidate> candidates = findPlanes(sample, params, constraint);
  if (candidates.empty()) return false;
  // Up is a direction shared by the table, the floor and shelves: take the direction with the
  // most inliers summed over the candidates parallel to it (within up_tolerance_deg). This
  // keeps a tilted plane in the background (a chair, a screen's top) from setting "up" just
  // because it is nearer the camera.
  const float min_cos = std::cos(degToRad(params.up_tolerance_deg));
  auto parallel = [&](const Candidate& a, const Candidate& b) {
    return a.plane.normal.dot(b.plane.normal) >= min_cos;
  };
  size_t best_support = 0;
  const Candidate* direction = nullptr;
  for (const Candidate& a : candidates) {
    size_t support = 0;
    for (const Candidate& b : candidates) support += parallel(a, b) ? b.inliers.size() : 0;
    if (support > best_support) best_support = support, direction = &a;
  }
  std::vector<Candidate> group;
  for (const Candidate& candidate : candidates) {
    if (parallel(*direction, candidate)) group.push_back(candidate);
  }
  // Within that direction, the support plane is chosen as TableSegmenter::segment does.
  up = group[selectSupport(sample.points(), group, params)].plane.normal;
  return true;
}

bool tableIsTheDominantLevelPlane(const Cloud& cloud, const TableResult& table) {
  if (!table.found || !(table.plane.signedDistance(cloud.sensor_origin_.head<3>()) > 0.0f) ||
      !(-table.plane.normal.y() >= kMinImageUpCosine)) {
    return false;
  }
  // More than half of all points holds more than half of the finite ones: no count needed.
  const size_t twice_the_inliers = 2 * static_cast<size_t>(table.inliers);
  if (twice_the_inliers > cloud.size()) return true;
  size_t finite = 0;
  for (const auto& p : cloud.points) finite += p.getVector3fMap().allFinite();
  return twice_the_inliers > finite;
}

}  // namespace tabletop_shapes
