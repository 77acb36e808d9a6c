// Splitting a level region of the height grid at a step between two tops (issue 15).
#include "tabletop_shapes/core/top_step_split.h"

#include "tabletop_shapes/core/convex_polygon.h"
#include "tabletop_shapes/core/grid_neighbours.h"
#include "tabletop_shapes/core/voxel_key.h"

#include <Eigen/Dense>

#include <algorithm>
#include <cmath>
#include <numeric>
#include <unordered_map>

namespace tabletop_shapes {
namespace {

// Two tops differ by at least this [m]: within a few millimetres depth noise (Kinect steps of
// 3-4 mm at 1.1-1.3 m) cannot tell a step from a tilt.
constexpr float kMinStep = 0.003f;
// A step, not a tilt: one plane through all cells leaves residuals (of the smoothed heights) at
// least this many times those of two levels, one per top. A tilted top fits a plane.
constexpr float kStepOverPlane = 1.3f;
// The two levels' largest connected pieces hold at least this share of the region's cells:
// noise splits a flat top into speckles, a step into two pieces.
constexpr float kCoherentShare = 0.85f;
// Side by side: at most this share of either top's cells lies within the other's outline (a
// rim around a lower inside, or a top's edge cells, seen lower, surround the rest).
constexpr float kMaxNested = 0.2f;

using CellIndex = std::unordered_map<uint64_t, int>;

uint64_t keyOf(int64_t x, int64_t y) { return voxel_key::pack(x, y, 0); }

// Calls visit(j) for the region's cells j among the 8 neighbours of its cell i.
template <typename Visit>
void forNeighbours(const std::vector<HeightCell>& region, const CellIndex& index_of, int i,
                   Visit&& visit) {
  forGridNeighbours(index_of, region[i].x, region[i].y, [&](uint64_t, int j) { visit(j); });
}

// The largest 8-connected piece among the cells `member` marks.
std::vector<int> largestPiece(const std::vector<HeightCell>& region, const CellIndex& index_of,
                              const std::vector<char>& member) {
  std::vector<char> seen(region.size(), 0);
  std::vector<int> largest, piece, stack;
  for (size_t seed = 0; seed < region.size(); ++seed) {
    if (!member[seed] || seen[seed]) continue;
    piece.clear();
    stack.assign(1, static_cast<int>(seed));
    seen[seed] = 1;
    while (!stack.empty()) {
      const int i = stack.back();
      stack.pop_back();
      piece.push_back(i);
      forNeighbours(region, index_of, i, [&](int j) {
        if (member[j] && !seen[j]) seen[j] = 1, stack.push_back(j);
      });
    }
    if (piece.size() > largest.size()) largest.swap(piece);
  }
  return largest;
}

// The share of `cells` whose centres lie within the convex outline of `around`.
float shareWithin(const std::vector<HeightCell>& region, const std::vector<int>& cells,
                  const std::vector<int>& around) {
  std::vector<Eigen::Vector2f> centres;
  for (int i : around) centres.emplace_back(region[i].x, region[i].y);
  const std::vector<Eigen::Vector2f> hull = convexHull2d(std::move(centres));
  if (hull.size() < 3) return 0.0f;
  const auto within = std::count_if(cells.begin(), cells.end(), [&](int i) {
    return insideDistance(
               hull, {static_cast<float>(region[i].x), static_cast<float>(region[i].y)}) > 0.0f;
  });
  return static_cast<float>(within) / static_cast<float>(cells.size());
}

// RMS residual of the cells' `heights` about one plane over the grid.
float planeResidual(const std::vector<HeightCell>& region, const std::vector<float>& heights,
                    const std::vector<int>& cells) {
  Eigen::MatrixXf a(cells.size(), 3);
  Eigen::VectorXf b(cells.size());
  for (size_t k = 0; k < cells.size(); ++k) {
    a.row(k) << 1.0f, static_cast<float>(region[cells[k]].x),
        static_cast<float>(region[cells[k]].y);
    b(k) = heights[cells[k]];
  }
  const Eigen::Vector3f plane = a.colPivHouseholderQr().solve(b);
  return std::sqrt((a * plane - b).squaredNorm() / static_cast<float>(cells.size()));
}

float meanOf(const std::vector<float>& heights, const std::vector<int>& cells) {
  float sum = 0.0f;
  for (int i : cells) sum += heights[i];
  return sum / static_cast<float>(cells.size());
}

// The two tops of the region, each a list of indices, or nothing when it shows no step.
std::vector<std::vector<int>> twoTops(const std::vector<HeightCell>& region, size_t min_cells) {
  const size_t n = region.size();
  if (n < 2 * min_cells) return {};
  CellIndex index_of;
  for (size_t i = 0; i < n; ++i) index_of.emplace(keyOf(region[i].x, region[i].y), i);
  // Heights smoothed by the median of each cell's neighbourhood: noise halves, a step stays.
  std::vector<float> smooth(n);
  std::vector<float> around;
  for (size_t i = 0; i < n; ++i) {
    around.assign(1, region[i].height);
    forNeighbours(region, index_of, static_cast<int>(i),
                  [&](int j) { around.push_back(region[j].height); });
    std::nth_element(around.begin(), around.begin() + around.size() / 2, around.end());
    smooth[i] = around[around.size() / 2];
  }
  // The level that parts the smoothed heights best (Otsu): most variance between the two sides.
  std::vector<int> order(n);
  std::iota(order.begin(), order.end(), 0);
  std::sort(order.begin(), order.end(), [&](int a, int b) { return smooth[a] < smooth[b]; });
  const double total = std::accumulate(smooth.begin(), smooth.end(), 0.0);
  double below = 0.0, best = 0.0;
  float level = 0.0f;
  for (size_t k = 0; k + 1 < n; ++k) {
    below += smooth[order[k]];
    if (k + 1 < min_cells || n - k - 1 < min_cells || smooth[order[k]] == smooth[order[k + 1]])
      continue;
    const double low = below / (k + 1), high = (total - below) / (n - k - 1);
    const double between = static_cast<double>(k + 1) * (n - k - 1) * (high - low) * (high - low);
    if (between > best) {
      best = between;
      level = 0.5f * (smooth[order[k]] + smooth[order[k + 1]]);
    }
  }
  if (!(best > 0.0)) return {};
  std::vector<char> is_high(n), is_low(n);
  for (size_t i = 0; i < n; ++i) is_high[i] = smooth[i] > level, is_low[i] = !is_high[i];
  std::vector<int> low = largestPiece(region, index_of, is_low);
  std::vector<int> high = largestPiece(region, index_of, is_high);
  if (low.size() < min_cells || high.size() < min_cells ||
      low.size() + high.size() < kCoherentShare * n)
    return {};
  if (shareWithin(region, low, high) > kMaxNested || shareWithin(region, high, low) > kMaxNested)
    return {};
  const float low_mean = meanOf(smooth, low), high_mean = meanOf(smooth, high);
  if (high_mean - low_mean < kMinStep) return {};
  std::vector<int> both = low;
  both.insert(both.end(), high.begin(), high.end());
  float two_levels = 0.0f;
  for (int i : low) two_levels += (smooth[i] - low_mean) * (smooth[i] - low_mean);
  for (int i : high) two_levels += (smooth[i] - high_mean) * (smooth[i] - high_mean);
  two_levels = std::sqrt(two_levels / static_cast<float>(both.size()));
  if (planeResidual(region, smooth, both) < kStepOverPlane * two_levels) return {};
  // The cells of neither piece (speckles along the step) join the piece they touch first,
  // growing both pieces a ring at a time.
  std::vector<int> group(n, -1);
  for (int i : low) group[i] = 0;
  for (int i : high) group[i] = 1;
  for (bool grown = true; grown;) {
    grown = false;
    std::vector<int> next = group;
    for (size_t i = 0; i < n; ++i) {
      if (group[i] >= 0) continue;
      forNeighbours(region, index_of, static_cast<int>(i), [&](int j) {
        if (next[i] < 0 && group[j] >= 0) next[i] = group[j];
      });
      grown |= next[i] >= 0;
    }
    group.swap(next);
  }
  std::vector<std::vector<int>> tops(2);
  for (size_t i = 0; i < n; ++i) tops[std::max(group[i], 0)].push_back(static_cast<int>(i));
  return tops;
}

}  // namespace

std::vector<std::vector<int>> splitAtTopSteps(const std::vector<HeightCell>& region,
                                              size_t min_cells) {
  std::vector<std::vector<int>> tops = twoTops(region, min_cells);
  if (tops.empty()) {
    std::vector<int> all(region.size());
    std::iota(all.begin(), all.end(), 0);
    return {all};
  }
  // Each top may hold a step of its own (three objects of nearly one height in a row).
  std::vector<std::vector<int>> out;
  for (const std::vector<int>& top : tops) {
    std::vector<HeightCell> cells;
    for (int i : top) cells.push_back(region[i]);
    for (const std::vector<int>& part : splitAtTopSteps(cells, min_cells)) {
      out.emplace_back();
      for (int k : part) out.back().push_back(top[k]);
    }
  }
  return out;
}

}  // namespace tabletop_shapes
