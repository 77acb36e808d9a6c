// Neighbour search on a uniform grid: a drop-in pcl::search::Search for the core's point sets.
// The core's clouds are voxel-grid centroids (one point per 5 mm voxel) and its queries are
// radius searches of 2 cm and k-nearest searches of a few dozen points: such neighbourhoods
// span a few grid cells, found by one hash lookup each, where a k-d tree descends and
// backtracks through ~log2(n) levels per query. Results are exact (the same sets as a k-d tree;
// a radius search keeps squared distances < radius^2 as FLANN does) and, when sorted, ordered
// by distance, so the algorithms built on them give the same answers.
//
// Only .cpp files include this header (it pulls in pcl::search); explicit instantiations for
// pcl::PointXYZ and pcl::PointNormal are in grid_search.cpp.
#pragma once

#include <pcl/search/search.h>

#include <cstdint>
#include <functional>
#include <utility>
#include <vector>

namespace tabletop_shapes {

template <typename PointT>
class GridSearch : public pcl::search::Search<PointT> {
 public:
  using typename pcl::search::Search<PointT>::PointCloud;
  using typename pcl::search::Search<PointT>::PointCloudConstPtr;
  using typename pcl::search::Search<PointT>::IndicesConstPtr;
  using pcl::search::Search<PointT>::nearestKSearch;
  using pcl::search::Search<PointT>::radiusSearch;

  // cell_size: about the radius of the typical query (2 cm for the core's searches) [m].
  explicit GridSearch(float cell_size, bool sorted = true);

  void setInputCloud(const PointCloudConstPtr& cloud,
                     const IndicesConstPtr& indices = IndicesConstPtr()) override;

  int nearestKSearch(const PointT& point, int k, pcl::Indices& k_indices,
                     std::vector<float>& k_sqr_distances) const override;

  int radiusSearch(const PointT& point, double radius, pcl::Indices& k_indices,
                   std::vector<float>& k_sqr_distances, unsigned int max_nn = 0) const override;

  // The k nearest neighbours of every point of the input at once: visit(index, squared
  // distances) with the k smallest squared distances in ascending order (the point itself
  // first, at 0), or in no order when !ascending (cheaper: no sort), points in no particular
  // order. Faster than one nearestKSearch per point: the candidates around each cell are
  // gathered once for all the points in it. threads > 1: the cells are shared out among that
  // many threads, which call visit concurrently (for different points), with the same lists.
  void forEachNearestK(int k, const std::function<void(int, const std::vector<float>&)>& visit,
                       bool ascending = true, unsigned threads = 1) const;
  // The points searched: the input's finite ones (forEachNearestK visits each of them once).
  size_t searchedPoints() const { return points_.size(); }
  // The same with the neighbours' input indices: visit(index, the k nearest, nearest first,
  // equal distances by index), the lists one nearestKSearch per point gives. threads > 1: as
  // forEachNearestK.
  void forEachNearestKIndices(int k, const std::function<void(int, const pcl::Indices&)>& visit,
                              unsigned threads = 1) const;

  // The neighbours of every point of the input within `radius` (squared distance < radius^2),
  // as radiusSearch finds and orders them: visit(index, neighbour indices), points in no
  // particular order. The same lists as one radiusSearch per point, cheaper: the candidates
  // around each cell are gathered once for all the points in it, and the distances to them are
  // one loop over flat arrays. threads > 1: the cells are shared out among that many threads,
  // which call visit concurrently (for different points), with the same lists.
  void forEachRadiusNeighbours(double radius,
                               const std::function<void(int, const pcl::Indices&)>& visit,
                               unsigned threads = 1) const;
  // The connected components of the input's points linked when closer than `radius` (squared
  // distance < radius^2, as radiusSearch): the input indices of each, ascending, components in
  // the order of their smallest index, as pcl::extractEuclideanClusters finds them (before it
  // filters and sorts them by size). One pass over each point's neighbouring cells, without
  // the result vectors of one radius search per point. threads > 1: two bands of cells linked
  // at once, then the pairs across their border; the same components.
  std::vector<pcl::Indices> connectedComponents(double radius, unsigned threads = 1) const;

 private:
  struct Cell {
    uint64_t key;
    uint32_t begin, end;  // range in points_
  };
  struct Entry {
    float x, y, z;
    int index;  // in the input cloud
  };
  uint64_t keyOf(int cx, int cy, int cz) const;
  // Sorts (key, entry) pairs given in ascending index order by key, stably (then by index),
  // keys within the occupied range low_ .. high_.
  void sortByCell(std::vector<std::pair<uint64_t, Entry>>& keyed) const;
  const Cell* find(uint64_t key) const;
  // The cell of the run of points_ starting at `begin` (points_ is sorted by cell, so a run
  // is one cell's points) and the position just past the run.
  struct Run {
    int cx, cy, cz;
    size_t end;
  };
  Run runAt(size_t begin) const;
  // For each run of points_[first, last) in one cell (first and last: run starts or the end):
  // gather(cx, cy, cz) with the cell's numbers, then select(q, covered_squared) for each point q
  // of the run: the 3 x 3 x 3 block of cells around it holds every point whose squared distance
  // from q is at most covered_squared.
  template <typename Gather, typename Select>
  void forEachPointInBlocks(size_t first, size_t last, Gather&& gather, Select&& select) const;
  // The coordinates (and, when `indices` is given, the input indices) of the points of the
  // 3 x 3 x 3 block of cells around (cx, cy, cz), as visitRing's rings 0 and 1 visit them.
  void gatherBlock(int cx, int cy, int cz, std::vector<float>& xs, std::vector<float>& ys,
                   std::vector<float>& zs, std::vector<int>* indices) const;
  // The start of the run holding points_[position], or of the next run when it starts inside
  // one; points_.size() at the end.
  size_t runStartAtOrAfter(size_t position) const;
  // Calls visitPart(first, last) for parts of points_ made of whole runs (cells), on up to
  // `threads` threads: one part for one thread, else 4 per thread, so that a thread slowed by
  // other work takes fewer.
  void forEachPart(unsigned threads, const std::function<void(size_t, size_t)>& visitPart) const;
  // The occupied cells, each with its range of points_, in points_' order (one array per field:
  // orderByRing's loop over them is vectorised).
  struct OccupiedCells {
    std::vector<int> x, y, z;
    std::vector<uint32_t> begin, end;
  };
  OccupiedCells occupiedCells() const;
  // The occupied cells ordered by ring around the cell (x, y, z) (their Chebyshev distance from
  // it in cells): those of ring r are order[ring_start[r] .. ring_start[r + 1]).
  struct CellsByRing {
    int x = 0, y = 0, z = 0;
    bool valid = false;
    std::vector<int> ring;
    std::vector<uint32_t> order, ring_start;
  };
  void orderByRing(const OccupiedCells& cells, int x, int y, int z, CellsByRing& by_ring) const;
  // The squared distances from q (a point of points_) to its `wanted` nearest points (all of
  // them when fewer), in no order, into `nearest`: nearestKSearch's rings, taken from the
  // occupied cells ordered by ring around q's cell (by_ring, reordered when q is in another
  // cell) instead of one hash lookup per cell of each ring. An isolated point's k-th neighbour
  // lies up to 24 cells away (the speed scenes): its rings run through thousands of empty cells.
  void nearestByRings(const Entry& q, size_t wanted, const OccupiedCells& cells,
                      CellsByRing& by_ring, std::vector<float>& found,
                      std::vector<float>& nearest) const;
  // Appends to `squared` the squared distances from q to the points outside the 3 x 3 x 3 block
  // of cells around q's cell that lie in cells within `reach` of q along each axis.
  void addBeyondTheBlock(const Entry& q, float reach, std::vector<float>& squared) const;
  // Calls visit(entry) for every point in the cells within `ring` cells of (cx, cy, cz)
  // (Chebyshev distance exactly `ring`).
  template <typename Visit>
  void visitRing(int cx, int cy, int cz, int ring, Visit&& visit) const;
  // The same with visitOccupied(cell) for each occupied cell of the ring.
  template <typename VisitCell>
  void visitRingCells(int cx, int cy, int cz, int ring, VisitCell&& visitOccupied) const;

  float cell_size_, inv_cell_;
  std::vector<Entry> points_;  // sorted by cell
  std::vector<Cell> table_;    // open addressing; key ~0 = empty
  size_t mask_ = 0;
  int low_[3] = {0, 0, 0}, high_[3] = {0, 0, 0};  // occupied cell range per axis
};

}  // namespace tabletop_shapes
