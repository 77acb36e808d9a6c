#include "tabletop_shapes/core/grid_search.h"

#include "tabletop_shapes/core/cpu_features.h"
#include "tabletop_shapes/core/parallel.h"
#include "tabletop_shapes/core/voxel_key.h"

#include <pcl/point_types.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <cstring>
#include <limits>
#include <memory>
#include <mutex>
#include <numeric>
#include <utility>

#if defined(__x86_64__) && defined(__GNUC__)
#include <immintrin.h>
#define TABLETOP_SHAPES_PACK_LANES 1
#endif

namespace tabletop_shapes {
namespace {

// Candidate buffer of the k-nearest search, one per thread: MLS may query one search from
// several OpenMP threads.
thread_local std::vector<std::pair<float, int>> candidates;

inline bool finite(const float x, const float y, const float z) {
  return std::isfinite(x) && std::isfinite(y) && std::isfinite(z);
}

// The squared distances from (qx, qy, qz) to the points (xs, ys, zs), in a loop of its own:
// GCC vectorises it (CMakeLists.txt builds this file with its dynamic cost model; -O2 alone
// vectorises only loops of known length), with the same float arithmetic per point as
// radiusSearch. Eight at a time in an AVX2 clone where the CPU has AVX2 (no fused multiply-add
// in either clone: the same floats).
__attribute__((target_clones("avx2", "default"))) void squaredDistances(
    const std::vector<float>& xs, const std::vector<float>& ys, const std::vector<float>& zs,
    float qx, float qy, float qz, std::vector<float>& squared) {
  squared.resize(xs.size());
  const size_t n = xs.size();
  const float *x = xs.data(), *y = ys.data(), *z = zs.data();
  float* out = squared.data();
  for (size_t j = 0; j < n; ++j) {
    const float dx = x[j] - qx, dy = y[j] - qy, dz = z[j] - qz;
    out[j] = dx * dx + dy * dy + dz * dz;
  }
}

#ifdef TABLETOP_SHAPES_PACK_LANES
// kLeftPack[mask]: the lanes set in the 8-bit `mask`, in order, one byte each (then zeros).
constexpr auto kLeftPack = [] {
  std::array<uint64_t, 256> table{};
  for (unsigned mask = 0; mask < 256; ++mask) {
    for (unsigned lane = 0, kept = 0; lane < 8; ++lane) {
      if (mask >> lane & 1u) table[mask] |= static_cast<uint64_t>(lane) << (8 * kept++);
    }
  }
  return table;
}();

// The lanes of `values` set in the 8-bit `mask`, in order, stored at `to` (8 lanes written);
// how many.
__attribute__((target("avx2"))) inline size_t packLanes(__m256 values, int mask, float* to) {
  const __m256i order =
      _mm256_cvtepu8_epi32(_mm_cvtsi64_si128(static_cast<long long>(kLeftPack[mask])));
  _mm256_storeu_ps(to, _mm256_permutevar8x32_ps(values, order));
  return static_cast<size_t>(__builtin_popcount(mask));
}

// The values of `values` <= bound, in their order, into `kept` (room for values.size());
// returns how many. Eight at a time where the CPU has AVX2 (compared, then moved
// together by kLeftPack's permutation), else one at a time
// (each written, the end moving past it when it is kept): a fifth of the outlier removal's
// instructions went to this loop over each point's ~300 block candidates.
__attribute__((target("avx2"))) size_t keepAtMostAvx2(const std::vector<float>& values, float bound,
                                                      float* kept) {
  const size_t n = values.size();
  const __m256 limit = _mm256_set1_ps(bound);
  size_t count = 0, j = 0;
  for (; j + 8 <= n; j += 8) {
    const __m256 v = _mm256_loadu_ps(values.data() + j);
    count += packLanes(v, _mm256_movemask_ps(_mm256_cmp_ps(v, limit, _CMP_LE_OQ)), kept + count);
  }
  for (; j < n; ++j) {
    kept[count] = values[j];
    count += values[j] <= bound;
  }
  return count;
}
#endif

size_t keepAtMost(const std::vector<float>& values, float bound, float* kept) {
#ifdef TABLETOP_SHAPES_PACK_LANES
  if (cpuHasAvx2()) return keepAtMostAvx2(values, bound, kept);
#endif
  size_t count = 0;
  for (const float v : values) {
    kept[count] = v;
    count += v <= bound;
  }
  return count;
}

#ifdef TABLETOP_SHAPES_PACK_LANES
// The lanes of the block of eight values loaded at `at_block` for the values from `first` on
// (at_block <= first: the last block of n >= 8 values, moved back to end at n, holds a few
// values seen already in its first lanes).
inline int newLanes(size_t first, size_t at_block) { return (0xff << (first - at_block)) & 0xff; }

// smallestValues' split eight values at a time: those whose bin (min(v * scale, last_bin)
// truncated, the same float product and clamp as its bins) is below `bin` appended to `below`,
// those in `bin` to `boundary`, both in the values' order, each list's lanes moved together by
// kLeftPack's permutation (each list needs room for 8 more than it receives; n >= 8). Its scalar
// loop cost 16 instructions a value, a third of the selection.
__attribute__((target("avx2"))) void splitAtBinAvx2(const float* v, size_t n, float scale,
                                                    float last_bin, uint8_t bin, float* below,
                                                    size_t& taken, float* boundary,
                                                    size_t& at_boundary) {
  const __m256 times = _mm256_set1_ps(scale), clamp = _mm256_set1_ps(last_bin);
  const __m256 low = _mm256_set1_ps(bin), high = _mm256_set1_ps(bin + 1.0f);
  auto split = [&](size_t at_block, int lanes) __attribute__((target("avx2"))) {
    const __m256 values = _mm256_loadu_ps(v + at_block);
    const __m256 t = _mm256_min_ps(_mm256_mul_ps(values, times), clamp);
    const __m256 under = _mm256_cmp_ps(t, low, _CMP_LT_OQ);
    const __m256 at = _mm256_andnot_ps(under, _mm256_cmp_ps(t, high, _CMP_LT_OQ));
    taken += packLanes(values, _mm256_movemask_ps(under) & lanes, below + taken);
    at_boundary += packLanes(values, _mm256_movemask_ps(at) & lanes, boundary + at_boundary);
  };
  size_t j = 0;
  for (; j + 8 <= n; j += 8) split(j, 0xff);
  if (j < n) split(n - 8, newLanes(j, n - 8));  // the last block ends at n
}

// How many of the n >= 8 values lie in the bins below `bin` (min(v * scale, last_bin) < bin,
// as splitAtBinAvx2 tells them), eight at a time.
__attribute__((target("avx2"))) size_t countInBinsBelowAvx2(const float* v, size_t n, float scale,
                                                            float last_bin, float bin) {
  const __m256 times = _mm256_set1_ps(scale), clamp = _mm256_set1_ps(last_bin);
  const __m256 limit = _mm256_set1_ps(bin);
  auto count = [&](size_t at_block, int lanes) __attribute__((target("avx2"))) {
    const __m256 t = _mm256_min_ps(_mm256_mul_ps(_mm256_loadu_ps(v + at_block), times), clamp);
    return static_cast<size_t>(
        __builtin_popcount(_mm256_movemask_ps(_mm256_cmp_ps(t, limit, _CMP_LT_OQ)) & lanes));
  };
  size_t counted = 0, j = 0;
  for (; j + 8 <= n; j += 8) counted += count(j, 0xff);
  if (j < n) counted += count(n - 8, newLanes(j, n - 8));  // the last block ends at n
  return counted;
}
#endif

// Buffers of smallestValues, kept between its calls (growing only, never cleared: no
// allocation or zero filling per point).
struct SelectionBuffers {
  std::vector<uint8_t> bins;
  std::vector<float> below, boundary;
};

// The `wanted` smallest of `values` (squared distances, at least `wanted` of them) as `smallest`
// (resized to `wanted`), in no order, the same multiset as nth_element gives; returns the
// greatest of them (the wanted-th smallest). Without nth_element's branchy partitions, which
// mispredicted a branch every ~15 instructions in a third of the outlier removal's time (~70
// candidates per point, 50 wanted): the values are counted in bins of [0, bound] (those above
// it in the last; a lower bin holds only smaller values, as the rounding of v * scale is
// monotone), the bins below the one holding the wanted-th value are taken whole, and only that
// bin's few values are selected among.
float smallestValues(const std::vector<float>& values, size_t wanted, float bound,
                     std::vector<float>& smallest, SelectionBuffers& buffers) {
  constexpr int kBins = 32;
  const size_t n = values.size();
  smallest.resize(wanted);
  const float scale = kBins / bound;
  if (!std::isfinite(scale)) {  // all 0, or too close to 0 to tell apart in bins
    std::vector<float>& all = buffers.boundary;
    all.assign(values.begin(), values.end());
    std::nth_element(all.begin(), all.begin() + (wanted - 1), all.end());
    std::copy(all.begin(), all.begin() + wanted, smallest.begin());
    return all[wanted - 1];
  }
  if (buffers.bins.size() < n) {
    buffers.bins.resize(n), buffers.below.resize(n + 8), buffers.boundary.resize(n + 8);
  }
  const float* v = values.data();
  const float last_bin = kBins - 1.0f;
  // The values in the bins below the wanted-th value's to `below` (fewer than `wanted`), those
  // in its bin to `boundary`; room for 8 more in both for splitAtBinAvx2.
  float *below = buffers.below.data(), *boundary = buffers.boundary.data();
  size_t taken = 0, at_boundary = 0;
#ifdef TABLETOP_SHAPES_PACK_LANES
  if (cpuHasAvx2() && n >= 8) {
    // The wanted-th value's bin (the first whose values and those below are at least `wanted`)
    // by bisection, five counts eight values at a time: fewer instructions than the histogram's
    // ~11 a value.
    int low = 0, high = kBins - 1;
    while (low < high) {
      const int middle = (low + high) / 2;
      if (countInBinsBelowAvx2(v, n, scale, last_bin, middle + 1.0f) >= wanted) {
        high = middle;
      } else {
        low = middle + 1;
      }
    }
    splitAtBinAvx2(v, n, scale, last_bin, static_cast<uint8_t>(low), below, taken, boundary,
                   at_boundary);
  } else
#endif
  {
    uint8_t* bins = buffers.bins.data();
    // Two loops: the first one vectorised.
    for (size_t j = 0; j < n; ++j) bins[j] = static_cast<uint8_t>(std::min(v[j] * scale, last_bin));
    uint32_t counts[kBins] = {};
    for (size_t j = 0; j < n; ++j) ++counts[bins[j]];
    uint8_t bin = 0;
    size_t in_lower_bins = 0;
    while (in_lower_bins + counts[bin] < wanted) in_lower_bins += counts[bin++];
    // Branch-free: each value is written to both lists, and a list's end moves past it when the
    // value belongs there.
    for (size_t j = 0; j < n; ++j) {
      below[taken] = values[j];
      taken += bins[j] < bin;
      boundary[at_boundary] = values[j];
      at_boundary += bins[j] == bin;
    }
  }
  std::copy(below, below + taken, smallest.begin());
  const size_t needed = wanted - taken;
  std::nth_element(boundary, boundary + (needed - 1), boundary + at_boundary);
  std::copy(boundary, boundary + needed, smallest.begin() + taken);
  return boundary[needed - 1];
}

#ifdef TABLETOP_SHAPES_PACK_LANES
// nearIndices eight candidates at a time: their squared distances as squaredDistances computes
// them (no fused multiply-add), and the near ones' indices packed to the front with one
// permutation (the radius search keeps ~1 in 9 of its candidates: the scalar loop cost ~4
// instructions a candidate).
__attribute__((target("avx2"))) size_t nearIndicesInAvx2(const std::vector<float>& xs,
                                                         const std::vector<float>& ys,
                                                         const std::vector<float>& zs,
                                                         const std::vector<int>& indices, float qx,
                                                         float qy, float qz, float radius_sq,
                                                         int* near_indices) {
  const __m256 at_x = _mm256_set1_ps(qx), at_y = _mm256_set1_ps(qy), at_z = _mm256_set1_ps(qz);
  const __m256 limit = _mm256_set1_ps(radius_sq);
  const size_t n = xs.size();
  size_t j = 0, near = 0;
  for (; j + 8 <= n; j += 8) {
    const __m256 dx = _mm256_sub_ps(_mm256_loadu_ps(&xs[j]), at_x);
    const __m256 dy = _mm256_sub_ps(_mm256_loadu_ps(&ys[j]), at_y);
    const __m256 dz = _mm256_sub_ps(_mm256_loadu_ps(&zs[j]), at_z);
    const __m256 squared = _mm256_add_ps(
        _mm256_add_ps(_mm256_mul_ps(dx, dx), _mm256_mul_ps(dy, dy)), _mm256_mul_ps(dz, dz));
    const unsigned mask =
        static_cast<unsigned>(_mm256_movemask_ps(_mm256_cmp_ps(squared, limit, _CMP_LT_OQ)));
    if (mask == 0) continue;
    // Written in place: near <= j, so the eight lanes stay within the first n.
    const __m256i lanes =
        _mm256_cvtepu8_epi32(_mm_cvtsi64_si128(static_cast<long long>(kLeftPack[mask])));
    const __m256i candidates = _mm256_loadu_si256(reinterpret_cast<const __m256i*>(&indices[j]));
    _mm256_storeu_si256(reinterpret_cast<__m256i*>(near_indices + near),
                        _mm256_permutevar8x32_epi32(candidates, lanes));
    near += static_cast<size_t>(__builtin_popcount(mask));
  }
  for (; j < n; ++j) {
    const float dx = xs[j] - qx, dy = ys[j] - qy, dz = zs[j] - qz;
    near_indices[near] = indices[j];
    near += dx * dx + dy * dy + dz * dz < radius_sq;
  }
  return near;
}
#endif

// The indices of the candidates (xs, ys, zs) whose squared distance from (qx, qy, qz) is below
// radius_sq, in the candidates' order, written to near_indices (room for all of them); their
// number.
size_t nearIndices(const std::vector<float>& xs, const std::vector<float>& ys,
                   const std::vector<float>& zs, const std::vector<int>& indices, float qx,
                   float qy, float qz, float radius_sq, int* near_indices,
                   std::vector<float>& squared) {
#ifdef TABLETOP_SHAPES_PACK_LANES
  if (cpuHasAvx2()) {
    return nearIndicesInAvx2(xs, ys, zs, indices, qx, qy, qz, radius_sq, near_indices);
  }
#endif
  squaredDistances(xs, ys, zs, qx, qy, qz, squared);
  // Without a branch: each candidate is written and the end moves past it when it is near.
  size_t near = 0;
  for (size_t j = 0; j < xs.size(); ++j) {
    near_indices[near] = indices[j];
    near += squared[j] < radius_sq;
  }
  return near;
}

// The rings of the n cells (cx, cy, cz) about the cell (x, y, z) (their Chebyshev distances from
// it) into `ring`; the largest. In a loop of its own, eight cells at a time in the AVX2 clone
// (SSE2 has no 32-bit integer abs or max: the default clone's loop is scalar).
__attribute__((target_clones("avx2", "default"))) int ringsOf(const int* cx, const int* cy,
                                                              const int* cz, size_t n, int x, int y,
                                                              int z, int* ring) {
  int last_ring = 0;
  for (size_t j = 0; j < n; ++j) {
    ring[j] = std::max(std::max(std::abs(cx[j] - x), std::abs(cy[j] - y)), std::abs(cz[j] - z));
    last_ring = std::max(last_ring, ring[j]);
  }
  return last_ring;
}

}  // namespace

template <typename PointT>
GridSearch<PointT>::GridSearch(float cell_size, bool sorted)
    : pcl::search::Search<PointT>("GridSearch", sorted),
      cell_size_(cell_size),
      inv_cell_(1.0f / cell_size) {}

template <typename PointT>
uint64_t GridSearch<PointT>::keyOf(int cx, int cy, int cz) const {
  return voxel_key::pack(cx, cy, cz);
}

template <typename PointT>
const typename GridSearch<PointT>::Cell* GridSearch<PointT>::find(uint64_t key) const {
  if (table_.empty()) return nullptr;
  for (size_t slot = voxel_key::hash(key) & mask_;; slot = (slot + 1) & mask_) {
    const Cell& cell = table_[slot];
    if (cell.key == key) return &cell;
    if (cell.key == voxel_key::kEmpty) return nullptr;
  }
}

template <typename PointT>
void GridSearch<PointT>::setInputCloud(const PointCloudConstPtr& cloud,
                                       const IndicesConstPtr& indices) {
  this->input_ = cloud;
  this->indices_ = indices;
  points_.clear();
  table_.clear();
  if (!cloud) return;
  const size_t count = indices ? indices->size() : cloud->size();
  std::vector<std::pair<uint64_t, Entry>> keyed;
  keyed.reserve(count);
  for (int a = 0; a < 3; ++a) {
    low_[a] = std::numeric_limits<int>::max();
    high_[a] = std::numeric_limits<int>::min();
  }
  for (size_t i = 0; i < count; ++i) {
    const int index = indices ? (*indices)[i] : static_cast<int>(i);
    const PointT& p = (*cloud)[index];
    if (!finite(p.x, p.y, p.z)) continue;
    const float v[3] = {p.x * inv_cell_, p.y * inv_cell_, p.z * inv_cell_};
    if (std::abs(v[0]) > voxel_key::kLimit || std::abs(v[1]) > voxel_key::kLimit ||
        std::abs(v[2]) > voxel_key::kLimit) {
      continue;  // kilometres away: not from a depth camera
    }
    int c[3];
    for (int a = 0; a < 3; ++a) {
      c[a] = static_cast<int>(voxel_key::floorToInt(v[a]));
      low_[a] = std::min(low_[a], c[a]);
      high_[a] = std::max(high_[a], c[a]);
    }
    keyed.push_back({keyOf(c[0], c[1], c[2]), Entry{p.x, p.y, p.z, index}});
  }
  // Sorted by cell, then by index: each cell's points are one range, in the cloud's order.
  const bool ascending_indices = !indices || std::is_sorted(indices->begin(), indices->end());
  if (ascending_indices) {
    sortByCell(keyed);
  } else {
    std::sort(keyed.begin(), keyed.end(), [](const auto& a, const auto& b) {
      return a.first != b.first ? a.first < b.first : a.second.index < b.second.index;
    });
  }
  points_.reserve(keyed.size());
  size_t cells = 0;
  for (size_t i = 0; i < keyed.size(); ++i) {
    cells += i == 0 || keyed[i].first != keyed[i - 1].first;
    points_.push_back(keyed[i].second);
  }
  size_t capacity = 16;
  while (capacity < 2 * cells) capacity *= 2;
  table_.assign(capacity, Cell{voxel_key::kEmpty, 0, 0});
  mask_ = capacity - 1;
  for (size_t begin = 0; begin < keyed.size();) {
    size_t end = begin + 1;
    while (end < keyed.size() && keyed[end].first == keyed[begin].first) ++end;
    size_t slot = voxel_key::hash(keyed[begin].first) & mask_;
    while (table_[slot].key != voxel_key::kEmpty) slot = (slot + 1) & mask_;
    table_[slot] = {keyed[begin].first, static_cast<uint32_t>(begin), static_cast<uint32_t>(end)};
    begin = end;
  }
}

template <typename PointT>
void GridSearch<PointT>::sortByCell(std::vector<std::pair<uint64_t, Entry>>& keyed) const {
  // A stable least-significant-digit radix sort of the cells' numbers in the occupied box
  // (x, then y, then z: the keys' order), digits of at most 11 bits: a few passes over the
  // points instead of a comparison sort's n log n (13k points of a 16-object scene: 2 passes).
  if (keyed.size() < 2) return;
  const uint64_t axis_mask = (uint64_t{1} << voxel_key::kAxisBits) - 1;
  uint64_t span[3], low[3];
  for (int a = 0; a < 3; ++a) {
    span[a] = static_cast<uint64_t>(int64_t{high_[a]} - low_[a] + 1);
    low[a] = static_cast<uint64_t>(low_[a] + voxel_key::kAxisOffset);
  }
  std::vector<uint64_t> number(keyed.size());
  for (size_t i = 0; i < keyed.size(); ++i) {
    const uint64_t key = keyed[i].first;
    const uint64_t x = (key >> (2 * voxel_key::kAxisBits)) - low[0];
    const uint64_t y = ((key >> voxel_key::kAxisBits) & axis_mask) - low[1];
    const uint64_t z = (key & axis_mask) - low[2];
    number[i] = (x * span[1] + y) * span[2] + z;
  }
  const uint64_t largest = span[0] * span[1] * span[2] - 1;  // < 2^63: 21 bits per axis
  int bits = 1;
  while (bits < 64 && (largest >> bits) != 0) ++bits;
  constexpr int kMaxDigitBits = 11;
  const int passes = (bits + kMaxDigitBits - 1) / kMaxDigitBits;
  const int digit_bits = (bits + passes - 1) / passes;
  const uint64_t digit_mask = (uint64_t{1} << digit_bits) - 1;
  std::vector<uint32_t> order(keyed.size()), moved(keyed.size());
  std::iota(order.begin(), order.end(), 0u);
  std::vector<uint32_t> start(size_t{1} << digit_bits);
  for (int pass = 0; pass < passes; ++pass) {
    const int shift = pass * digit_bits;
    std::fill(start.begin(), start.end(), 0u);
    for (const uint64_t n : number) ++start[(n >> shift) & digit_mask];
    uint32_t sum = 0;
    for (uint32_t& s : start) sum += std::exchange(s, sum);
    for (const uint32_t i : order) moved[start[(number[i] >> shift) & digit_mask]++] = i;
    order.swap(moved);
  }
  std::vector<std::pair<uint64_t, Entry>> sorted(keyed.size());
  for (size_t k = 0; k < order.size(); ++k) sorted[k] = keyed[order[k]];
  keyed.swap(sorted);
}

template <typename PointT>
typename GridSearch<PointT>::Run GridSearch<PointT>::runAt(size_t begin) const {
  const Entry& first = points_[begin];
  Run run;
  run.cx = static_cast<int>(voxel_key::floorToInt(first.x * inv_cell_));
  run.cy = static_cast<int>(voxel_key::floorToInt(first.y * inv_cell_));
  run.cz = static_cast<int>(voxel_key::floorToInt(first.z * inv_cell_));
  run.end = find(keyOf(run.cx, run.cy, run.cz))->end;
  return run;
}

template <typename PointT>
template <typename Visit>
void GridSearch<PointT>::visitRing(int cx, int cy, int cz, int ring, Visit&& visit) const {
  visitRingCells(cx, cy, cz, ring, [&](const Cell& cell) {
    for (uint32_t i = cell.begin; i < cell.end; ++i) visit(points_[i]);
  });
}

template <typename PointT>
template <typename VisitCell>
void GridSearch<PointT>::visitRingCells(int cx, int cy, int cz, int ring,
                                        VisitCell&& visitOccupied) const {
  auto visitCell = [&](int x, int y, int z) {
    if (x < low_[0] || x > high_[0] || y < low_[1] || y > high_[1] || z < low_[2] || z > high_[2]) {
      return;
    }
    const Cell* cell = find(keyOf(x, y, z));
    if (cell) visitOccupied(*cell);
  };
  if (ring == 0) {
    visitCell(cx, cy, cz);
    return;
  }
  // The shell of the (2 ring + 1)^3 block: its two x faces whole, then the y faces without the
  // x edges, then the z faces without the x and y edges.
  for (int y = cy - ring; y <= cy + ring; ++y) {
    for (int z = cz - ring; z <= cz + ring; ++z) {
      visitCell(cx - ring, y, z);
      visitCell(cx + ring, y, z);
    }
  }
  for (int x = cx - ring + 1; x <= cx + ring - 1; ++x) {
    for (int z = cz - ring; z <= cz + ring; ++z) {
      visitCell(x, cy - ring, z);
      visitCell(x, cy + ring, z);
    }
  }
  for (int x = cx - ring + 1; x <= cx + ring - 1; ++x) {
    for (int y = cy - ring + 1; y <= cy + ring - 1; ++y) {
      visitCell(x, y, cz - ring);
      visitCell(x, y, cz + ring);
    }
  }
}

template <typename PointT>
int GridSearch<PointT>::radiusSearch(const PointT& point, double radius, pcl::Indices& k_indices,
                                     std::vector<float>& k_sqr_distances,
                                     unsigned int max_nn) const {
  k_indices.clear();
  k_sqr_distances.clear();
  if (points_.empty() || !finite(point.x, point.y, point.z) || !(radius >= 0.0)) return 0;
  const float radius_sq = static_cast<float>(radius * radius);  // as pcl::KdTreeFLANN
  const int reach = static_cast<int>(std::ceil(radius * inv_cell_));
  const int cx = static_cast<int>(voxel_key::floorToInt(point.x * inv_cell_));
  const int cy = static_cast<int>(voxel_key::floorToInt(point.y * inv_cell_));
  const int cz = static_cast<int>(voxel_key::floorToInt(point.z * inv_cell_));
  auto& found = candidates;
  found.clear();
  for (int ring = 0; ring <= reach; ++ring) {
    visitRing(cx, cy, cz, ring, [&](const Entry& e) {
      const float dx = e.x - point.x, dy = e.y - point.y, dz = e.z - point.z;
      const float d = dx * dx + dy * dy + dz * dz;
      if (d < radius_sq) found.emplace_back(d, e.index);
    });
  }
  const bool limited = max_nn > 0 && found.size() > max_nn;
  if (limited) {
    std::partial_sort(found.begin(), found.begin() + max_nn, found.end());
    found.resize(max_nn);
  } else if (this->sorted_results_) {
    std::sort(found.begin(), found.end());
  }
  k_indices.reserve(found.size());
  k_sqr_distances.reserve(found.size());
  for (const auto& [d, index] : found) {
    k_indices.push_back(index);
    k_sqr_distances.push_back(d);
  }
  return static_cast<int>(found.size());
}

template <typename PointT>
int GridSearch<PointT>::nearestKSearch(const PointT& point, int k, pcl::Indices& k_indices,
                                       std::vector<float>& k_sqr_distances) const {
  k_indices.clear();
  k_sqr_distances.clear();
  if (points_.empty() || k <= 0 || !finite(point.x, point.y, point.z)) return 0;
  const float fx = point.x * inv_cell_, fy = point.y * inv_cell_, fz = point.z * inv_cell_;
  const int cx = static_cast<int>(voxel_key::floorToInt(fx));
  const int cy = static_cast<int>(voxel_key::floorToInt(fy));
  const int cz = static_cast<int>(voxel_key::floorToInt(fz));
  // Beyond this ring no cell holds a point.
  const int last_ring = std::max(
      {cx - low_[0], high_[0] - cx, cy - low_[1], high_[1] - cy, cz - low_[2], high_[2] - cz});
  // Distance from the point to the nearest face of its own cell [cells]: after ring r every
  // point closer than r + inset cells has been seen.
  const float inset = std::min({fx - cx, cx + 1 - fx, fy - cy, cy + 1 - fy, fz - cz, cz + 1 - fz});
  const size_t wanted = static_cast<size_t>(k);
  auto& found = candidates;
  found.clear();
  for (int ring = 0; ring <= last_ring; ++ring) {
    visitRing(cx, cy, cz, ring, [&](const Entry& e) {
      const float dx = e.x - point.x, dy = e.y - point.y, dz = e.z - point.z;
      found.emplace_back(dx * dx + dy * dy + dz * dz, e.index);
    });
    if (found.size() < wanted) continue;
    std::nth_element(found.begin(), found.begin() + (wanted - 1), found.end());
    const float covered = (static_cast<float>(ring) + inset) * cell_size_;
    if (found[wanted - 1].first <= covered * covered) break;
  }
  const size_t n = std::min(wanted, found.size());
  if (n < found.size()) std::nth_element(found.begin(), found.begin() + (n - 1), found.end());
  std::sort(found.begin(), found.begin() + n);  // cheaper than a partial sort of all
  k_indices.resize(n);
  k_sqr_distances.resize(n);
  for (size_t i = 0; i < n; ++i) {
    k_sqr_distances[i] = found[i].first;
    k_indices[i] = found[i].second;
  }
  return static_cast<int>(n);
}

template <typename PointT>
void GridSearch<PointT>::gatherBlock(int cx, int cy, int cz, std::vector<float>& xs,
                                     std::vector<float>& ys, std::vector<float>& zs,
                                     std::vector<int>* indices) const {
  // The cells' ranges first, then each array sized once and filled: a push_back per point and
  // array cost three times the copy.
  uint32_t begins[27], ends[27];
  int cells = 0;
  size_t count = 0;
  for (int ring = 0; ring <= 1; ++ring) {
    visitRingCells(cx, cy, cz, ring, [&](const Cell& cell) {
      begins[cells] = cell.begin, ends[cells++] = cell.end;
      count += cell.end - cell.begin;
    });
  }
  xs.resize(count), ys.resize(count), zs.resize(count);
  float *x = xs.data(), *y = ys.data(), *z = zs.data();
  const Entry* const entries = points_.data();
  for (int c = 0; c < cells; ++c) {
    for (uint32_t i = begins[c]; i < ends[c]; ++i)
      *x++ = entries[i].x, *y++ = entries[i].y, *z++ = entries[i].z;
  }
  if (!indices) return;
  indices->resize(count);
  int* index = indices->data();
  for (int c = 0; c < cells; ++c) {
    for (uint32_t i = begins[c]; i < ends[c]; ++i) *index++ = entries[i].index;
  }
}

template <typename PointT>
template <typename Gather, typename Select>
void GridSearch<PointT>::forEachPointInBlocks(size_t first, size_t last, Gather&& gather,
                                              Select&& select) const {
  for (size_t begin = first; begin < last;) {
    const Run run = runAt(begin);
    // Every point of the 3 x 3 x 3 block of cells around this one.
    gather(run.cx, run.cy, run.cz);
    for (size_t i = begin; i < run.end; ++i) {
      const Entry& q = points_[i];
      // The block holds every point closer than 1 + inset cells (inset: the distance from q
      // to its cell's nearest face); beyond that the k-th neighbour needs the general search.
      // Only the points within that distance can be among the k nearest found here: the
      // others need not be kept (half of the block on a surface), so the selection is
      // cheaper and finds the same k nearest.
      const float fx = q.x * inv_cell_ - run.cx, fy = q.y * inv_cell_ - run.cy,
                  fz = q.z * inv_cell_ - run.cz;
      const float inset = std::min({fx, 1 - fx, fy, 1 - fy, fz, 1 - fz});
      const float covered = (1.0f + std::max(inset, 0.0f)) * cell_size_;
      select(q, covered * covered);
    }
    begin = run.end;
  }
}

template <typename PointT>
size_t GridSearch<PointT>::runStartAtOrAfter(size_t position) const {
  if (position == 0 || position >= points_.size()) return std::min(position, points_.size());
  const Entry& p = points_[position];
  const Cell* cell = find(keyOf(static_cast<int>(voxel_key::floorToInt(p.x * inv_cell_)),
                                static_cast<int>(voxel_key::floorToInt(p.y * inv_cell_)),
                                static_cast<int>(voxel_key::floorToInt(p.z * inv_cell_))));
  return cell->begin == position ? position : cell->end;
}

template <typename PointT>
void GridSearch<PointT>::forEachNearestK(
    int k, const std::function<void(int, const std::vector<float>&)>& visit, bool ascending,
    unsigned threads) const {
  if (k <= 0 || points_.empty()) return;
  const size_t wanted = static_cast<size_t>(k);
  // The occupied cells for the isolated points (below): listed once, at the first such point,
  // and shared by the threads (they only read them).
  OccupiedCells occupied;
  std::once_flag occupied_listed;
  // Whole runs (cells) per part, so that each point sees the same previous point as in one pass.
  auto nearestInPart = [&](size_t first, size_t last) {
    std::vector<float> xs, ys, zs, block_squared, squared, nearest;
    SelectionBuffers selection;
    CellsByRing by_ring;
    // The previous point of the same cell and its k-th distance: the k nearest of q lie within
    // that distance plus |q - previous| (triangle inequality), a ball far smaller than the
    // block on a surface, so the selection below runs on half the candidates.
    const Entry* previous = nullptr;
    float previous_kth = 0.0f;
    forEachPointInBlocks(
        first, last,
        [&](int cx, int cy, int cz) {
          gatherBlock(cx, cy, cz, xs, ys, zs, nullptr);
          previous = nullptr;
        },
        [&](const Entry& q, float covered_squared) {
          squaredDistances(xs, ys, zs, q.x, q.y, q.z, block_squared);
          // Keeps the candidates with squared distance <= bound: when they are at least k, the
          // k smallest of them are the k smallest of the block (exact whatever the bound).
          float kept_bound = 0.0f;
          auto keepWithin = [&](float bound) {
            kept_bound = bound;
            squared.resize(block_squared.size());
            const size_t kept = keepAtMost(block_squared, bound, squared.data());
            squared.resize(kept);
            return kept;
          };
          size_t kept = 0;
          if (previous) {
            const float dx = q.x - previous->x, dy = q.y - previous->y, dz = q.z - previous->z;
            // 1e-4 relative slack for the float rounding of the distances.
            const float reach = (previous_kth + std::sqrt(dx * dx + dy * dy + dz * dz)) * 1.0001f;
            // A surface point's k-th distance is near its neighbour's: a ball a little larger
            // holds k candidates most times, fewer than the triangle bound's to select among
            // (1.15: the fewest instructions of 1.05-1.4 on the 4 and 16-object speed scenes).
            const float guess = std::min(reach, previous_kth * 1.15f);
            if (guess * guess < covered_squared) kept = keepWithin(guess * guess);
            if (kept < wanted && reach * reach < covered_squared) kept = keepWithin(reach * reach);
          }
          if (kept < wanted) kept = keepWithin(covered_squared);
          if (kept >= wanted) {
            previous = &q;
            previous_kth =
                std::sqrt(smallestValues(squared, wanted, kept_bound, nearest, selection));
          } else if (block_squared.size() >= wanted) {
            // The block's k-th distance bounds the k nearest (an edge point's lie just beyond
            // the block's cover): the cells that ball reaches beyond the block are added.
            squared = block_squared;
            const float kth =
                smallestValues(block_squared, wanted, covered_squared, nearest, selection);
            const float reach = std::sqrt(kth) * 1.0001f;
            addBeyondTheBlock(q, reach, squared);
            smallestValues(squared, wanted, reach * reach, nearest, selection);
          } else {
            // Fewer than k points in the block: an isolated point (flying pixels, a far
            // edge), whose rings run through many empty cells before k points turn up: taken
            // from the occupied cells. The same distances as the k-d tree over the input used
            // here before, whose building cost ~900 instructions a point for ~1 point in 60.
            std::call_once(occupied_listed, [&] { occupied = occupiedCells(); });
            nearestByRings(q, wanted, occupied, by_ring, squared, nearest);
          }
          if (ascending) std::sort(nearest.begin(), nearest.end());
          visit(q.index, nearest);
        });
  };
  forEachPart(threads, nearestInPart);
}

template <typename PointT>
typename GridSearch<PointT>::OccupiedCells GridSearch<PointT>::occupiedCells() const {
  OccupiedCells cells;
  for (size_t begin = 0; begin < points_.size();) {
    const Run run = runAt(begin);
    cells.x.push_back(run.cx), cells.y.push_back(run.cy), cells.z.push_back(run.cz);
    cells.begin.push_back(static_cast<uint32_t>(begin));
    cells.end.push_back(static_cast<uint32_t>(run.end));
    begin = run.end;
  }
  return cells;
}

template <typename PointT>
void GridSearch<PointT>::orderByRing(const OccupiedCells& cells, int x, int y, int z,
                                     CellsByRing& by_ring) const {
  by_ring.x = x, by_ring.y = y, by_ring.z = z, by_ring.valid = true;
  const size_t n = cells.x.size();
  std::vector<int>& ring = by_ring.ring;
  ring.resize(n);
  int* r = ring.data();
  const int last_ring = ringsOf(cells.x.data(), cells.y.data(), cells.z.data(), n, x, y, z, r);
  // A counting sort by ring.
  std::vector<uint32_t>& start = by_ring.ring_start;
  start.assign(static_cast<size_t>(last_ring) + 2, 0u);
  for (size_t j = 0; j < n; ++j) ++start[static_cast<size_t>(r[j]) + 1];
  for (size_t s = 1; s < start.size(); ++s) start[s] += start[s - 1];
  by_ring.order.resize(n);
  std::vector<uint32_t> next(start.begin(), start.end() - 1);
  for (size_t j = 0; j < n; ++j) by_ring.order[next[r[j]]++] = static_cast<uint32_t>(j);
}

template <typename PointT>
void GridSearch<PointT>::nearestByRings(const Entry& q, size_t wanted, const OccupiedCells& cells,
                                        CellsByRing& by_ring, std::vector<float>& found,
                                        std::vector<float>& nearest) const {
  const float fx = q.x * inv_cell_, fy = q.y * inv_cell_, fz = q.z * inv_cell_;
  const int cx = static_cast<int>(voxel_key::floorToInt(fx));
  const int cy = static_cast<int>(voxel_key::floorToInt(fy));
  const int cz = static_cast<int>(voxel_key::floorToInt(fz));
  if (!by_ring.valid || by_ring.x != cx || by_ring.y != cy || by_ring.z != cz) {
    orderByRing(cells, cx, cy, cz, by_ring);
  }
  // As nearestKSearch: after ring r every point closer than r + inset cells has been seen.
  const float inset = std::min({fx - cx, cx + 1 - fx, fy - cy, cy + 1 - fy, fz - cz, cz + 1 - fz});
  // Once k are found, only the k smallest so far and the points nearer than the k-th of them
  // are kept (no other can be among the k nearest): the rings reaching a distant k-th
  // neighbour hold thousands of points.
  found.clear();
  float kth = std::numeric_limits<float>::infinity();
  const float cell_squared = cell_size_ * cell_size_;
  for (size_t r = 0; r + 1 < by_ring.ring_start.size(); ++r) {
    for (uint32_t o = by_ring.ring_start[r]; o < by_ring.ring_start[r + 1]; ++o) {
      const uint32_t c = by_ring.order[o];
      // A cell all farther than the k-th found (its gap from q along each axis, in cells; 1e-3
      // slack for the rounding of the cell units) holds none of the k nearest.
      const float gx = std::max({0.0f, cells.x[c] - fx, fx - (cells.x[c] + 1)});
      const float gy = std::max({0.0f, cells.y[c] - fy, fy - (cells.y[c] + 1)});
      const float gz = std::max({0.0f, cells.z[c] - fz, fz - (cells.z[c] + 1)});
      if ((gx * gx + gy * gy + gz * gz) * cell_squared * 0.999f > kth) continue;
      for (uint32_t i = cells.begin[c]; i < cells.end[c]; ++i) {
        const Entry& e = points_[i];
        const float dx = e.x - q.x, dy = e.y - q.y, dz = e.z - q.z;
        const float d = dx * dx + dy * dy + dz * dz;
        if (d < kth) found.push_back(d);
      }
    }
    if (found.size() < wanted) continue;
    if (found.size() > wanted || kth == std::numeric_limits<float>::infinity()) {
      std::nth_element(found.begin(), found.begin() + (wanted - 1), found.end());
      found.resize(wanted);
      kth = found[wanted - 1];
    }
    const float covered = (static_cast<float>(r) + inset) * cell_size_;
    if (kth <= covered * covered) break;
  }
  nearest.assign(found.begin(), found.begin() + std::min(wanted, found.size()));
}

template <typename PointT>
void GridSearch<PointT>::addBeyondTheBlock(const Entry& q, float reach,
                                           std::vector<float>& squared) const {
  const int cx = static_cast<int>(voxel_key::floorToInt(q.x * inv_cell_));
  const int cy = static_cast<int>(voxel_key::floorToInt(q.y * inv_cell_));
  const int cz = static_cast<int>(voxel_key::floorToInt(q.z * inv_cell_));
  auto cellOf = [&](float v) { return static_cast<int>(voxel_key::floorToInt(v * inv_cell_)); };
  const int x0 = std::max(cellOf(q.x - reach), low_[0]),
            x1 = std::min(cellOf(q.x + reach), high_[0]);
  const int y0 = std::max(cellOf(q.y - reach), low_[1]),
            y1 = std::min(cellOf(q.y + reach), high_[1]);
  const int z0 = std::max(cellOf(q.z - reach), low_[2]),
            z1 = std::min(cellOf(q.z + reach), high_[2]);
  for (int x = x0; x <= x1; ++x) {
    for (int y = y0; y <= y1; ++y) {
      for (int z = z0; z <= z1; ++z) {
        if (std::abs(x - cx) <= 1 && std::abs(y - cy) <= 1 && std::abs(z - cz) <= 1) continue;
        const Cell* cell = find(keyOf(x, y, z));
        if (!cell) continue;
        for (uint32_t i = cell->begin; i < cell->end; ++i) {
          const Entry& e = points_[i];
          const float dx = e.x - q.x, dy = e.y - q.y, dz = e.z - q.z;
          squared.push_back(dx * dx + dy * dy + dz * dz);
        }
      }
    }
  }
}

template <typename PointT>
void GridSearch<PointT>::forEachPart(unsigned threads,
                                     const std::function<void(size_t, size_t)>& visitPart) const {
  threads = std::max(1u, threads);
  const size_t parts = threads > 1 ? std::min<size_t>(4 * threads, points_.size()) : 1;
  std::vector<size_t> bounds(parts + 1);
  for (size_t part = 0; part <= parts; ++part) {
    bounds[part] = runStartAtOrAfter(part * points_.size() / parts);
  }
  parallelFor(
      parts, [&](size_t part) { visitPart(bounds[part], bounds[part + 1]); }, threads);
}

template <typename PointT>
void GridSearch<PointT>::forEachNearestKIndices(
    int k, const std::function<void(int, const pcl::Indices&)>& visit, unsigned threads) const {
  if (k <= 0 || points_.empty()) return;
  const size_t wanted = static_cast<size_t>(k);
  forEachPart(threads, [&](size_t first, size_t last) {
    std::vector<float> xs, ys, zs, squared, fallback_distances;
    std::vector<int> indices;
    std::vector<uint64_t> keys;
    pcl::Indices nearest;
    forEachPointInBlocks(
        first, last, [&](int cx, int cy, int cz) { gatherBlock(cx, cy, cz, xs, ys, zs, &indices); },
        [&](const Entry& q, float covered_squared) {
          // (distance, index) as one integer, as forEachRadiusNeighbours: ordered as
          // nearestKSearch orders its pairs, ties by index.
          squaredDistances(xs, ys, zs, q.x, q.y, q.z, squared);
          keys.clear();
          for (size_t j = 0; j < xs.size(); ++j) {
            const float d = squared[j];
            if (d <= covered_squared) {
              uint32_t bits;
              std::memcpy(&bits, &d, sizeof bits);
              keys.push_back(static_cast<uint64_t>(bits) << 32 | static_cast<uint32_t>(indices[j]));
            }
          }
          if (keys.size() >= wanted) {
            std::nth_element(keys.begin(), keys.begin() + (wanted - 1), keys.end());
            std::sort(keys.begin(), keys.begin() + wanted);
            nearest.resize(wanted);
            for (size_t j = 0; j < wanted; ++j) nearest[j] = static_cast<int>(keys[j] & ~0u);
          } else {
            PointT point;
            point.x = q.x, point.y = q.y, point.z = q.z;
            nearestKSearch(point, k, nearest, fallback_distances);  // the rings, same order
          }
          visit(q.index, nearest);
        });
  });
}

template <typename PointT>
void GridSearch<PointT>::forEachRadiusNeighbours(
    double radius, const std::function<void(int, const pcl::Indices&)>& visit,
    unsigned threads) const {
  if (points_.empty() || !(radius >= 0.0)) return;
  const float radius_sq = static_cast<float>(radius * radius);  // as radiusSearch
  const int reach = static_cast<int>(std::ceil(radius * inv_cell_));
  forEachPart(threads, [&](size_t first, size_t last) {
    std::vector<float> xs, ys, zs, squared;
    std::vector<int> indices;
    std::vector<uint64_t> keys;
    pcl::Indices neighbours;
    for (size_t begin = first; begin < last;) {
      const Run run = runAt(begin);
      const int cx = run.cx, cy = run.cy, cz = run.cz;
      const size_t end = run.end;
      xs.clear(), ys.clear(), zs.clear(), indices.clear();
      for (int ring = 0; ring <= reach; ++ring) {
        visitRing(cx, cy, cz, ring, [&](const Entry& e) {
          xs.push_back(e.x), ys.push_back(e.y), zs.push_back(e.z), indices.push_back(e.index);
        });
      }
      for (size_t i = begin; i < end; ++i) {
        const Entry& q = points_[i];
        if (!this->sorted_results_) {  // in the candidates' order
          neighbours.resize(xs.size());
          neighbours.resize(nearIndices(xs, ys, zs, indices, q.x, q.y, q.z, radius_sq,
                                        neighbours.data(), squared));
          visit(q.index, neighbours);
          continue;
        }
        squaredDistances(xs, ys, zs, q.x, q.y, q.z, squared);
        // (distance, index) as one integer: the bits of a float >= 0 order as its value, so
        // sorting the keys orders as radiusSearch's sort of pairs, in fewer instructions.
        keys.clear();
        for (size_t j = 0; j < xs.size(); ++j) {
          if (squared[j] < radius_sq) {
            uint32_t bits;
            std::memcpy(&bits, &squared[j], sizeof bits);
            keys.push_back(static_cast<uint64_t>(bits) << 32 | static_cast<uint32_t>(indices[j]));
          }
        }
        std::sort(keys.begin(), keys.end());
        neighbours.resize(keys.size());
        for (size_t j = 0; j < keys.size(); ++j) neighbours[j] = static_cast<int>(keys[j] & ~0u);
        visit(q.index, neighbours);
      }
      begin = end;
    }
  });
}

namespace {
constexpr int kMaxSubCellSplit = 4;  // sub-cells per cell along an axis, at most
constexpr int kMaxSubCells = kMaxSubCellSplit * kMaxSubCellSplit * kMaxSubCellSplit;
constexpr float kSubCellMargin = 0.99f;  // a sub-cell's diagonal below this share of the radius
}  // namespace

template <typename PointT>
std::vector<pcl::Indices> GridSearch<PointT>::connectedComponents(double radius,
                                                                  unsigned threads) const {
  std::vector<pcl::Indices> components;
  if (points_.empty() || !(radius >= 0.0)) return components;
  const float radius_sq = static_cast<float>(radius * radius);  // as radiusSearch
  const int reach = static_cast<int>(std::ceil(radius * inv_cell_));
  // Union-find over positions in points_; a root is the smallest position of its set.
  std::vector<uint32_t> parent(points_.size());
  std::iota(parent.begin(), parent.end(), 0u);
  auto root = [&](uint32_t i) {
    while (parent[i] != i) i = parent[i] = parent[parent[i]];
    return i;
  };
  auto close = [&](size_t i, size_t j) {
    const Entry &p = points_[i], &q = points_[j];
    const float dx = q.x - p.x, dy = q.y - p.y, dz = q.z - p.z;
    return dx * dx + dy * dy + dz * dz < radius_sq;
  };
  auto link = [&](size_t i, size_t j) {
    const uint32_t a = root(static_cast<uint32_t>(i)), b = root(static_cast<uint32_t>(j));
    if (a != b) parent[std::max(a, b)] = std::min(a, b);
  };
  // First the pairs within each cell. A cell whose points are then one set is whole (marked at
  // its first position); it stays so, as sets only grow.
  std::vector<char> whole(points_.size(), 0);
  // Sub-cells (a cell cut `split` times along each axis) whose diagonal is shorter than the
  // radius, by a margin far beyond float rounding: a sub-cell's points are all closer than the
  // radius, so they are one set without a distance test, and two sub-cells are one set after
  // their first close pair. Most of a cell's pair tests go (a 2 cm cell of a 5 mm voxel grid
  // holds ~10 points: 45 pairs, against at most 28 sub-cell pairs that mostly end at their
  // first pair). Cells too large for 4 x 4 x 4 sub-cells test every pair.
  int split = 1;
  while (split <= kMaxSubCellSplit && cell_size_ / static_cast<float>(split) * std::sqrt(3.0f) >=
                                          kSubCellMargin * static_cast<float>(radius)) {
    ++split;
  }
  const int sub_cells = split * split * split;
  // The cells of points_[first, last) (whole runs): their points' pairs.
  auto linkWithinCells = [&](size_t first, size_t last) {
    std::vector<uint8_t> sub_of;      // sub-cell of each point of the cell
    std::vector<uint32_t> by_sub;     // the cell's positions grouped by sub-cell
    std::vector<uint32_t> sub_begin;  // start of each used sub-cell's group in by_sub
    std::vector<uint8_t> used;        // the used sub-cells, ascending
    uint32_t count[kMaxSubCells + 1];
    for (size_t begin = first; begin < last;) {
      const Run run = runAt(begin);
      const size_t end = run.end;
      if (split > kMaxSubCellSplit) {
        for (size_t i = begin; i < end; ++i) {
          for (size_t j = i + 1; j < end; ++j) {
            if (close(i, j)) link(i, j);
          }
        }
      } else {
        const float scale = inv_cell_ * static_cast<float>(split);
        auto subAxis = [&](float v, int c) {
          const int64_t s = voxel_key::floorToInt(v * scale) - int64_t{c} * split;
          return static_cast<int>(std::min<int64_t>(std::max<int64_t>(s, 0), split - 1));
        };
        sub_of.resize(end - begin);
        std::fill(count, count + sub_cells + 1, 0u);
        for (size_t i = begin; i < end; ++i) {
          const Entry& e = points_[i];
          const int s =
              (subAxis(e.x, run.cx) * split + subAxis(e.y, run.cy)) * split + subAxis(e.z, run.cz);
          sub_of[i - begin] = static_cast<uint8_t>(s);
          ++count[s + 1];
        }
        used.clear();
        sub_begin.clear();
        for (int s = 0; s < sub_cells; ++s) {
          if (count[s + 1] > 0) {
            used.push_back(static_cast<uint8_t>(s));
            sub_begin.push_back(count[s]);
          }
          count[s + 1] += count[s];
        }
        sub_begin.push_back(static_cast<uint32_t>(end - begin));
        // Positions ascend within each group: its first is the smallest, the set's root.
        by_sub.resize(end - begin);
        for (size_t i = begin; i < end; ++i) by_sub[count[sub_of[i - begin]]++] = i;
        for (size_t g = 0; g < used.size(); ++g) {
          for (uint32_t k = sub_begin[g] + 1; k < sub_begin[g + 1]; ++k)
            parent[by_sub[k]] = by_sub[sub_begin[g]];
        }
        for (size_t a = 0; a < used.size(); ++a) {
          for (size_t b = a + 1; b < used.size(); ++b) {
            if (root(by_sub[sub_begin[a]]) == root(by_sub[sub_begin[b]])) continue;
            bool joined = false;
            for (uint32_t k = sub_begin[a]; k < sub_begin[a + 1] && !joined; ++k) {
              for (uint32_t l = sub_begin[b]; l < sub_begin[b + 1]; ++l) {
                if (!close(by_sub[k], by_sub[l])) continue;
                link(by_sub[k], by_sub[l]);
                joined = true;
                break;
              }
            }
          }
        }
      }
      const uint32_t cell_root = root(static_cast<uint32_t>(begin));
      bool one_set = true;
      for (size_t i = begin + 1; i < end && one_set; ++i)
        one_set = root(static_cast<uint32_t>(i)) == cell_root;
      whole[begin] = one_set;
      begin = end;
    }
  };
  // Then each pair of neighbouring cells once: the cells at a lexicographically positive offset
  // (the other half reach this cell from their side), of those with x in [x_low, x_high]. Two whole
  // cells need no pair once they are one set, and one close pair makes them one. The components do
  // not depend on the order the links come in, nor on links within a set.
  auto linkNeighbourCells = [&](size_t first, size_t last, int x_low, int x_high) {
    for (size_t begin = first; begin < last;) {
      const Run run = runAt(begin);
      const size_t end = run.end;
      for (int x = 0; x <= reach; ++x) {
        for (int y = x == 0 ? 0 : -reach; y <= reach; ++y) {
          for (int z = x == 0 && y == 0 ? 1 : -reach; z <= reach; ++z) {
            const int nx = run.cx + x, ny = run.cy + y, nz = run.cz + z;
            if (nx < x_low || nx > x_high || ny < low_[1] || ny > high_[1] || nz < low_[2] ||
                nz > high_[2]) {
              continue;
            }
            const Cell* cell = find(keyOf(nx, ny, nz));
            if (!cell) continue;
            const bool both_whole = whole[begin] && whole[cell->begin];
            if (both_whole && root(static_cast<uint32_t>(begin)) == root(cell->begin)) continue;
            bool joined = false;
            for (uint32_t j = cell->begin; j < cell->end && !joined; ++j) {
              for (size_t i = begin; i < end; ++i) {
                if (!close(i, j)) continue;
                link(i, j);
                if (both_whole) {
                  joined = true;
                  break;
                }
              }
            }
          }
        }
      }
      begin = end;
    }
  };
  // On two threads, two bands of cells along x (points_ is sorted by cell, x first, so each is
  // a range of positions): each band's links join only its own positions, so the threads share
  // no set; then the pairs across the border, on one thread.
  const size_t n = points_.size();
  const auto cellX = [&](size_t i) {
    return static_cast<int>(voxel_key::floorToInt(points_[i].x * inv_cell_));
  };
  int border_x = cellX(n / 2);
  auto firstAtX = [&](int x) {
    size_t low = 0, high = n;  // the first position whose cell's x is >= x
    while (low < high) {
      const size_t middle = (low + high) / 2;
      if (cellX(middle) < x)
        low = middle + 1;
      else
        high = middle;
    }
    return low;
  };
  size_t border = firstAtX(border_x);
  if (border == 0) border = firstAtX(++border_x);
  if (threads < 2 || border == 0 || border >= n) {
    linkWithinCells(0, n);
    linkNeighbourCells(0, n, std::numeric_limits<int>::min(), high_[0]);
  } else {
    parallelFor(
        2,
        [&](size_t band) {
          if (band == 0) {
            linkWithinCells(0, border);
            linkNeighbourCells(0, border, std::numeric_limits<int>::min(), border_x - 1);
          } else {
            linkWithinCells(border, n);
            linkNeighbourCells(border, n, border_x, high_[0]);
          }
        },
        2);
    linkNeighbourCells(firstAtX(border_x - reach), border, border_x, high_[0]);
  }
  // Components numbered by their smallest input index.
  std::vector<int> smallest(points_.size(), std::numeric_limits<int>::max());
  for (size_t i = 0; i < points_.size(); ++i) {
    int& s = smallest[root(static_cast<uint32_t>(i))];
    s = std::min(s, points_[i].index);
  }
  std::vector<std::pair<int, uint32_t>> roots;  // (smallest input index, root)
  for (size_t i = 0; i < points_.size(); ++i) {
    if (parent[i] == i) roots.emplace_back(smallest[i], static_cast<uint32_t>(i));
  }
  std::sort(roots.begin(), roots.end());
  std::vector<int> component_of(points_.size(), -1);
  components.resize(roots.size());
  for (size_t c = 0; c < roots.size(); ++c) component_of[roots[c].second] = static_cast<int>(c);
  for (size_t i = 0; i < points_.size(); ++i) {
    components[component_of[root(static_cast<uint32_t>(i))]].push_back(points_[i].index);
  }
  for (pcl::Indices& component : components) std::sort(component.begin(), component.end());
  return components;
}

template class GridSearch<pcl::PointXYZ>;
template class GridSearch<pcl::PointNormal>;

}  // namespace tabletop_shapes
