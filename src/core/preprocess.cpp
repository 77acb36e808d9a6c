// §2.1 preprocessing: flying pixels and the maximum range, then a voxel grid whose voxels become
// their centroid.
//
// Flying pixels: at a depth edge a depth camera returns points between the foreground and the
// background. Such a point is far, along its line of sight, from all its image neighbours,
// while a surface point, however slanted, has a neighbour across the line of sight on the
// same surface. Dropping them keeps objects one behind the other from being bridged into one
// cluster.
//
// Faster than pcl::VoxelGrid (which sorts (voxel, point) pairs): a pass over bands of image rows
// on all cores decides each pixel (flying, out of range), four pixels at a time, packs a kept
// point's integer voxel coordinates into a 63-bit key and gathers the view bounds on the way; a
// second pass, one per side of the camera frame (x < 0, x >= 0) on its own core, each over the
// whole image in image order, adds each point of its side to its voxel's running sum, found
// through an open-addressing hash table. Neighbouring pixels of an organised cloud
// mostly share a voxel, so the left and the upper pixel's voxels are tried first. The tables and
// the sums are members and are reused from frame to frame; the output lists the voxels in the order
// they are first met, so it is deterministic and the same whatever the number of threads.
#include "tabletop_shapes/core/preprocess.h"

#include "tabletop_shapes/core/float4.h"
#include "tabletop_shapes/core/parallel.h"
#include "tabletop_shapes/core/voxel_key.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <vector>

#ifdef __SSE2__
#include <emmintrin.h>
#endif

namespace tabletop_shapes {
using voxel_key::floorToInt;

namespace {

inline bool finitePoint(float x, float y, float z) {
  return std::isfinite(x) && std::isfinite(y) && std::isfinite(z);
}

// The voxel sums share the voxels out between two threads by the side of the camera frame they
// lie in (the sign of x, the top bit of the key's x): for a pinhole camera the image's left and
// right of the principal point, so each row is one run of each side's pixels, and a thread skips
// the other side's run in a few steps. (The four quadrants, signs of x and y, as four items for
// two threads: each pass reads all keys, and four passes were slower on the wall.)
constexpr size_t kSides = 2;
constexpr uint64_t kSideBit = uint64_t{1} << (3 * voxel_key::kAxisBits - 1);

// A new key's lookup starts the load of the hash slot of the key this many pixels on: most new
// voxels' home slots are then in the cache when their lookup comes (the table is larger than L2;
// preprocess alone, speed4, one thread: 4, 6, 8 and 12 pixels about as fast, 2 and 16+ slower).
constexpr int kPrefetchAhead = 8;

// The voxel table's hash: one multiply by 2^64 / golden ratio, its upper half folded onto the
// lower bits, which the table's mask keeps. Cheaper than voxel_key::hash, which most new voxels
// computed twice (the prefetch, the lookup), for a few more probes (speed4's left side, 53k
// voxels: 0.39 past the home slot at 40 % full, 0.85 at 50 %; splitmix 0.35 and 0.51):
// preprocess alone, speed4, one thread, 4.30 -> 4.04 ms (fastest of 200 frames); the 45 OSD
// scenes 2.5 % faster. (The product's upper bits alone, shifted by the table's size: 0.37 and
// 0.43 probes, fewer instructions, but 0.1 ms slower.)
inline uint64_t slotHash(uint64_t key) {
  const uint64_t product = key * 0x9e3779b97f4a7c15ull;
  return product ^ product >> 32;
}

inline size_t sideOf(uint64_t key) { return key >> (3 * voxel_key::kAxisBits - 1) & 1; }

// The first of keys[from, end) that is neither kEmpty nor on the side whose key bit is `side`
// (kEmpty: on neither, the first key not kEmpty); end when there is none. A thread skips the
// other thread's side and the dropped pixels with it.
inline int nextOtherSide(const uint64_t* keys, int from, int end, uint64_t side) {
  int u = from;
#ifdef __SSE2__
  // Four keys at a time, on their upper 32 bits: kEmpty's are all ones (a key has 63 bits),
  // and they hold the side's bit.
  static_assert(3 * voxel_key::kAxisBits - 1 >= 32, "the side lies in the key's upper half");
  const uint64_t side_bit = side == voxel_key::kEmpty ? 0 : kSideBit;
  const __m128i sides = _mm_set1_epi32(static_cast<int>(side >> 32)),
                bits = _mm_set1_epi32(static_cast<int>(side_bit >> 32)), ones = _mm_set1_epi32(-1);
  for (; u + 4 <= end; u += 4) {
    const __m128 first = _mm_loadu_ps(reinterpret_cast<const float*>(keys + u)),
                 second = _mm_loadu_ps(reinterpret_cast<const float*>(keys + u + 2));
    const __m128i upper = _mm_castps_si128(_mm_shuffle_ps(first, second, _MM_SHUFFLE(3, 1, 3, 1)));
    const __m128i skipped = _mm_or_si128(_mm_cmpeq_epi32(upper, ones),
                                         _mm_cmpeq_epi32(_mm_and_si128(upper, bits), sides));
    if (_mm_movemask_epi8(skipped) != 0xffff) break;
  }
#endif
  while (u < end && (keys[u] == voxel_key::kEmpty || (keys[u] & kSideBit) == side)) ++u;
  return u;
}

}  // namespace

void Preprocessor::VoxelTable::clear() {
  if (slots_.empty() || ++frame_ == 0) {  // a new table, or the frame count wrapped
    slots_.assign(std::max<size_t>(slots_.size(), 1024), Slot{voxel_key::kEmpty, 0, 0});
    frame_ = 1;
  }
  sums.clear();
}

void Preprocessor::VoxelTable::grow() {
  const size_t capacity = 2 * slots_.size();
  slots_.assign(capacity, Slot{voxel_key::kEmpty, 0, 0});
  for (uint32_t voxel = 0; voxel < sums.size(); ++voxel) {
    const uint64_t key = sums[voxel].key;
    size_t slot = slotHash(key) & (capacity - 1);
    while (slots_[slot].frame == frame_) slot = (slot + 1) & (capacity - 1);
    slots_[slot] = {key, voxel, frame_};
  }
}

// Inline: the voxel sum's inner loop calls it (out of line, a shared library's call goes
// through the PLT). Half the kept pixels of a VGA frame start a new voxel: its insert is inline
// too, but for the table's growth.
inline uint32_t Preprocessor::VoxelTable::voxelOf(uint64_t key, uint32_t pixel) {
  // At most half full.
  const size_t mask = slots_.size() - 1;
  size_t slot = slotHash(key) & mask;
  while (slots_[slot].frame == frame_) {
    if (slots_[slot].key == key) return slots_[slot].voxel;
    slot = (slot + 1) & mask;
  }
  if (2 * (sums.size() + 1) > slots_.size()) return insertGrowing(key, pixel);
  const uint32_t voxel = static_cast<uint32_t>(sums.size());
  slots_[slot] = {key, voxel, frame_};
  // Written in place, field by field: a VoxelSum built on the stack and copied in was read back
  // across its narrower stores, a failed store forwarding on every new voxel.
  VoxelSum& sum = sums.emplace_back();  // zeros
  sum.key = key;
  sum.first_pixel = pixel;
  return voxel;
}

inline void Preprocessor::VoxelTable::prefetch(uint64_t key) const {
  const Slot& slot = slots_[slotHash(key) & (slots_.size() - 1)];
#if defined(__GNUC__) && (defined(__x86_64__) || defined(__i386__))
  // GCC 12 at -O1 and above drops this loop's __builtin_prefetch.
  asm volatile("prefetcht0 %0" : : "m"(slot));
#else
  __builtin_prefetch(&slot);
#endif
}

uint32_t Preprocessor::VoxelTable::insertGrowing(uint64_t key, uint32_t pixel) {
  grow();  // at least twice the slots: voxelOf's probe finds an empty one, and room for more
  return voxelOf(key, pixel);
}

size_t Preprocessor::VoxelTable::bytes() const {
  return slots_.capacity() * sizeof(Slot) + sums.capacity() * sizeof(VoxelSum);
}

void Preprocessor::VoxelTable::release() {
  // 8x: a normal frame's own table is 2-4x its voxels; below 1 MB nothing is worth giving back.
  constexpr size_t kSlack = 8, kKeepBytes = 1 << 20;
  const size_t voxels = std::max<size_t>(sums.size(), 1024);
  if (slots_.capacity() * sizeof(Slot) > kKeepBytes && slots_.capacity() > kSlack * voxels) {
    std::vector<Slot>().swap(slots_);  // the next frame starts small and grows
  }
  if (sums.capacity() * sizeof(VoxelSum) > kKeepBytes && sums.capacity() > kSlack * voxels) {
    sums.shrink_to_fit();
  }
}

template <typename PointT>
void Preprocessor::keyRows(const pcl::PointCloud<PointT>& in, int width, bool drop_flying,
                           int first_row, int end_row, ViewBoundsGatherer::Band* view) {
  const int height = static_cast<int>(keys_.size() / width);
  const bool limit_range = params_.max_range > 0.0f;
  const float max_range_sq = params_.max_range * params_.max_range;
  const bool grid = params_.leaf_size > 0.0f;
  const float inv_leaf = grid ? 1.0f / params_.leaf_size : 0.0f;
  // Neighbour q of p lies within the angle a of p's line of sight when
  // along^2 > cot^2(a) * across^2, with along = (q - p).p / |p|, across^2 = |q - p|^2 - along^2,
  // i.e. ((q - p).p)^2 * (1 + cot^2(a)) > cot^2(a) * |q - p|^2 * |p|^2 (no square roots), with p
  // taken from the sensor origin.
  const float cot = drop_flying ? 1.0f / std::tan(degToRad(params_.flying_pixel_angle_deg)) : 0.0f;
  const float cot_sq = cot * cot, along_weight = 1.0f + cot_sq;
  // Lines of sight start at the cloud's sensor origin (the frame's origin for a camera frame).
  const float eye_x = in.sensor_origin_.x(), eye_y = in.sensor_origin_.y(),
              eye_z = in.sensor_origin_.z();
  auto onSurface = [&](const PointT& p, float sight_sq, const PointT& q) {
    const float dx = q.x - p.x, dy = q.y - p.y, dz = q.z - p.z;
    const float dot = dx * (p.x - eye_x) + dy * (p.y - eye_y) + dz * (p.z - eye_z);
    return dot * dot * along_weight <= cot_sq * (dx * dx + dy * dy + dz * dz) * sight_sq;
  };
  auto flying = [&](const PointT* row, int u, int v) {
    const PointT& p = row[u];
    const float sx = p.x - eye_x, sy = p.y - eye_y, sz = p.z - eye_z;
    const float sight_sq = sx * sx + sy * sy + sz * sz;
    // The left neighbour first: on most surfaces it already clears the point.
    bool any_neighbour = u > 0 && std::isfinite(row[u - 1].z);
    if (any_neighbour && onSurface(p, sight_sq, row[u - 1])) return false;
    static constexpr int du[] = {1, 0, 0, -1, 1, -1, 1}, dv[] = {0, -1, 1, -1, -1, 1, 1};
    for (int n = 0; n < 7; ++n) {
      const int nu = u + du[n], nv = v + dv[n];
      if (static_cast<unsigned>(nu) >= static_cast<unsigned>(width) ||
          static_cast<unsigned>(nv) >= static_cast<unsigned>(height))
        continue;
      const PointT& q = in.points[static_cast<size_t>(nv) * width + nu];
      if (!std::isfinite(q.z)) continue;
      any_neighbour = true;
      if (onSurface(p, sight_sq, q)) return false;
    }
    // A point without any valid neighbour gives no evidence either way: kept.
    return any_neighbour;
  };
  const float limit = voxel_key::kLimit;
  // The key of a pixel that passed the flying pixel test, kEmpty beyond the key's reach.
  auto keyOf = [&](const PointT& p) {
    if (!grid) return uint64_t{0};  // kept; no voxel
    const float vx = p.x * inv_leaf, vy = p.y * inv_leaf, vz = p.z * inv_leaf;
    // Coordinates beyond 2^20 voxels from the origin cannot come from a depth camera.
    if (std::abs(vx) > limit || std::abs(vy) > limit || std::abs(vz) > limit) {
      return voxel_key::kEmpty;
    }
    return voxel_key::pack(floorToInt(vx), floorToInt(vy), floorToInt(vz));
  };
  auto keyPixel = [&](const PointT* row, int u, int v) {
    const PointT& p = row[u];
    // Depth cameras mark missing depth in z. The costly flying pixel test last.
    if (!finitePoint(p.x, p.y, p.z)) return voxel_key::kEmpty;
    if (view) view->add(u, p.x, p.y, p.z);
    if (limit_range && p.x * p.x + p.y * p.y + p.z * p.z > max_range_sq) return voxel_key::kEmpty;
    if (drop_flying && flying(row, u, v)) return voxel_key::kEmpty;
    return keyOf(p);
  };
#ifdef __SSE2__
  // Four pixels at a time, with the float operations of the scalar tests in the same order (the
  // same decisions): finiteness, range, the left neighbour's flying pixel test (it clears most
  // points; the others take the scalar test of all neighbours), the view's extremes and the
  // voxel coordinates.
  const __m128 most = _mm_set1_ps(std::numeric_limits<float>::max());  // no extreme yet
  __m128 min_tan_x = most, max_tan_x = _mm_sub_ps(_mm_setzero_ps(), most), min_tan_y = most,
         max_tan_y = max_tan_x, min_z = most;
#endif
  auto keyRow = [&](int v) {
    const PointT* row = &in.points[static_cast<size_t>(v) * width];
    uint64_t* keys = &keys_[static_cast<size_t>(v) * width];
    int u = 0;
#ifdef __SSE2__
    if (view) {  // the row's first and last valid pixels; the ones between give extremes only
      int first = 0, last = width - 1;
      auto valid = [&](int c) {
        return finitePoint(row[c].x, row[c].y, row[c].z) && row[c].z > 0.0f;
      };
      while (first < width && !valid(first)) ++first;
      while (last > first && !valid(last)) --last;
      if (first < width) view->add(first, row[first].x, row[first].y, row[first].z);
      if (last > first) view->add(last, row[last].x, row[last].y, row[last].z);
    }
    // The constants and flags in the row's locals: the keys' stores go through __m128i, which
    // may alias anything, and would have each one the lambda captures loaded again for every
    // four pixels.
    const __m128 zero = _mm_setzero_ps(), eye_xs = _mm_set1_ps(eye_x), eye_ys = _mm_set1_ps(eye_y),
                 eye_zs = _mm_set1_ps(eye_z), along_weights = _mm_set1_ps(along_weight),
                 cot_sqs = _mm_set1_ps(cot_sq), max_range_sqs = _mm_set1_ps(max_range_sq),
                 inv_leafs = _mm_set1_ps(inv_leaf), limits = _mm_set1_ps(limit),
                 sign = _mm_set1_ps(-0.0f), huge = _mm_set1_ps(std::numeric_limits<float>::max());
    const bool with_view = view != nullptr, in_range_only = limit_range, flying_test = drop_flying,
               with_grid = grid;
    const int row_width = width;
    __m128 left_x = zero, left_y = zero, left_z = zero;  // of the previous four pixels
    // The extremes in locals (registers), not in the accumulators the lambda captures.
    __m128 row_min_tan_x = min_tan_x, row_max_tan_x = max_tan_x, row_min_tan_y = min_tan_y,
           row_max_tan_y = max_tan_y, row_min_z = min_z;
    for (; u + 4 <= row_width; u += 4) {
      Float4 lanes_x, lanes_y, lanes_z;
      coordinatesOfFour(row + u, lanes_x, lanes_y, lanes_z);
      const __m128 x = (__m128)lanes_x, y = (__m128)lanes_y, z = (__m128)lanes_z;
      const __m128 finite = _mm_cmpeq_ps(
          _mm_add_ps(_mm_add_ps(_mm_sub_ps(x, x), _mm_sub_ps(y, y)), _mm_sub_ps(z, z)), zero);
      if (with_view) {
        const __m128 valid = _mm_and_ps(finite, _mm_cmpgt_ps(z, zero));
        const __m128 tan_x = _mm_div_ps(x, z), tan_y = _mm_div_ps(y, z);
        auto pick = [&](__m128 value, __m128 otherwise) {
          return _mm_or_ps(_mm_and_ps(valid, value), _mm_andnot_ps(valid, otherwise));
        };
        row_min_tan_x = _mm_min_ps(row_min_tan_x, pick(tan_x, huge));
        row_max_tan_x = _mm_max_ps(row_max_tan_x, pick(tan_x, _mm_sub_ps(zero, huge)));
        row_min_tan_y = _mm_min_ps(row_min_tan_y, pick(tan_y, huge));
        row_max_tan_y = _mm_max_ps(row_max_tan_y, pick(tan_y, _mm_sub_ps(zero, huge)));
        row_min_z = _mm_min_ps(row_min_z, pick(z, huge));
      }
      __m128 kept = finite;
      if (in_range_only) {
        const __m128 range_sq =
            _mm_add_ps(_mm_add_ps(_mm_mul_ps(x, x), _mm_mul_ps(y, y)), _mm_mul_ps(z, z));
        kept = _mm_and_ps(kept, _mm_cmple_ps(range_sq, max_range_sqs));
      }
      // The left neighbours: the previous pixel of each lane.
      const __m128 shifted_x = _mm_castsi128_ps(_mm_slli_si128(_mm_castps_si128(x), 4)),
                   shifted_y = _mm_castsi128_ps(_mm_slli_si128(_mm_castps_si128(y), 4)),
                   shifted_z = _mm_castsi128_ps(_mm_slli_si128(_mm_castps_si128(z), 4));
      const __m128 qx = _mm_move_ss(shifted_x, _mm_shuffle_ps(left_x, left_x, 0xff)),
                   qy = _mm_move_ss(shifted_y, _mm_shuffle_ps(left_y, left_y, 0xff)),
                   qz = _mm_move_ss(shifted_z, _mm_shuffle_ps(left_z, left_z, 0xff));
      left_x = x, left_y = y, left_z = z;
      int kept_lanes = _mm_movemask_ps(kept);
      if (flying_test && kept_lanes) {
        const __m128 sx = _mm_sub_ps(x, eye_xs), sy = _mm_sub_ps(y, eye_ys),
                     sz = _mm_sub_ps(z, eye_zs);
        const __m128 sight_sq =
            _mm_add_ps(_mm_add_ps(_mm_mul_ps(sx, sx), _mm_mul_ps(sy, sy)), _mm_mul_ps(sz, sz));
        // The lanes whose neighbour q is finite and on their surface: onSurface's operations.
        auto onSurfaceLanes = [&](__m128 qx, __m128 qy, __m128 qz) {
          const __m128 dx = _mm_sub_ps(qx, x), dy = _mm_sub_ps(qy, y), dz = _mm_sub_ps(qz, z);
          const __m128 dot =
              _mm_add_ps(_mm_add_ps(_mm_mul_ps(dx, sx), _mm_mul_ps(dy, sy)), _mm_mul_ps(dz, sz));
          const __m128 along = _mm_mul_ps(_mm_mul_ps(dot, dot), along_weights);
          const __m128 across = _mm_mul_ps(
              _mm_mul_ps(cot_sqs, _mm_add_ps(_mm_add_ps(_mm_mul_ps(dx, dx), _mm_mul_ps(dy, dy)),
                                             _mm_mul_ps(dz, dz))),
              sight_sq);
          const __m128 finite = _mm_cmpeq_ps(_mm_sub_ps(qz, qz), zero);
          return _mm_movemask_ps(_mm_and_ps(finite, _mm_cmple_ps(along, across)));
        };
        int cleared = onSurfaceLanes(qx, qy, qz);
        if (u == 0) cleared &= ~1;  // the row's first pixel has no left neighbour
        // The right neighbours (the scalar test's next), the next pixel of each lane, clear most
        // of the rest: a point whose left neighbour lies across a depth edge.
        if ((kept_lanes & ~cleared) && u + 4 < row_width) {
          auto nextOf = [](__m128 value, float next) {  // value's lanes 1-3, then next
            const __m128 last = _mm_shuffle_ps(value, _mm_set1_ps(next), _MM_SHUFFLE(0, 0, 3, 3));
            return _mm_shuffle_ps(value, last, _MM_SHUFFLE(2, 0, 2, 1));
          };
          const PointT& next = row[u + 4];
          cleared |= onSurfaceLanes(nextOf(x, next.x), nextOf(y, next.y), nextOf(z, next.z));
        }
        for (int lanes = kept_lanes & ~cleared; lanes; lanes &= lanes - 1) {
          const int lane = __builtin_ctz(static_cast<unsigned>(lanes));
          if (flying(row, u + lane, v)) kept_lanes &= ~(1 << lane);
        }
      }
      if (!kept_lanes) {  // all four dropped: kEmpty (all bits) without voxel coordinates
        static_assert(voxel_key::kEmpty == ~uint64_t{0}, "kEmpty has all bits set");
        const __m128i empty = _mm_set1_epi32(-1);
        _mm_storeu_si128(reinterpret_cast<__m128i*>(keys + u), empty);
        _mm_storeu_si128(reinterpret_cast<__m128i*>(keys + u + 2), empty);
        continue;
      }
      if (!with_grid) {
        for (int lane = 0; lane < 4; ++lane) {
          keys[u + lane] = kept_lanes >> lane & 1 ? 0 : voxel_key::kEmpty;
        }
        continue;
      }
      const __m128 vx = _mm_mul_ps(x, inv_leafs), vy = _mm_mul_ps(y, inv_leafs),
                   vz = _mm_mul_ps(z, inv_leafs);
      const __m128 reach = _mm_max_ps(_mm_max_ps(_mm_andnot_ps(sign, vx), _mm_andnot_ps(sign, vy)),
                                      _mm_andnot_ps(sign, vz));
      kept_lanes &= _mm_movemask_ps(_mm_cmple_ps(reach, limits));
      auto floorOf = [](__m128 value) {  // as floorToInt, for |value| < 2^31
        const __m128i truncated = _mm_cvttps_epi32(value);
        return _mm_add_epi32(truncated,
                             _mm_castps_si128(_mm_cmplt_ps(value, _mm_cvtepi32_ps(truncated))));
      };
      voxel_key::packFour(floorOf(vx), floorOf(vy), floorOf(vz), kept_lanes, keys + u);
    }
    min_tan_x = row_min_tan_x, max_tan_x = row_max_tan_x, min_tan_y = row_min_tan_y;
    max_tan_y = row_max_tan_y, min_z = row_min_z;
#endif
    // The rest one by one (with the view: a column added again or later keeps first and last).
    for (; u < width; ++u) keys[u] = keyPixel(row, u, v);
  };

  for (int v = first_row; v < end_row; ++v) {
    keyRow(v);
    if (view) view_.endRow(*view, static_cast<size_t>(v));
  }
#ifdef __SSE2__
  if (view) {
    auto lanes = [](__m128 value, float* out) { _mm_storeu_ps(out, value); };
    alignas(16) float lx[4], hx[4], ly[4], hy[4], lz[4];
    lanes(min_tan_x, lx), lanes(max_tan_x, hx), lanes(min_tan_y, ly), lanes(max_tan_y, hy);
    lanes(min_z, lz);
    for (int lane = 0; lane < 4; ++lane) {
      view->addExtremes(lx[lane], hx[lane], ly[lane], hy[lane], lz[lane]);
    }
  }
#endif
}

template <typename PointT>
void Preprocessor::sumOwnedVoxels(const pcl::PointCloud<PointT>& in, int width, int height,
                                  size_t owner, size_t owners) {
  VoxelTable& table = owners_[owner].table;
  table.clear();
  // Neighbouring pixels mostly share a voxel: the left one's (last_key) or the one above's
  // (row_voxels keeps the previous row's voxels) is taken without a hash lookup.
  const bool rows = height > 1;
  std::vector<uint32_t>& row_voxels = owners_[owner].row_voxels;
  row_voxels.resize(rows ? 2 * static_cast<size_t>(width) : 0);
  uint32_t* above = row_voxels.data();
  uint32_t* current = rows ? above + width : nullptr;
  uint64_t last_key = voxel_key::kEmpty, last_side = ~uint64_t{0};
  uint32_t last_voxel = 0;
  bool owned = false;
  for (int v = 0; v < height; ++v) {
    const size_t row = static_cast<size_t>(v) * width;
    const uint64_t* keys = &keys_[row];
    for (int u = 0; u < width; ++u) {
      const uint64_t key = keys[u];
      if (key == voxel_key::kEmpty) {  // on to the last dropped pixel of the run
        u = nextOtherSide(keys, u + 1, width, voxel_key::kEmpty) - 1;
        continue;
      }
      if (key != last_key) {
        last_key = key;
        if ((key & kSideBit) != last_side) {
          last_side = key & kSideBit;
          owned = owners == 1 || sideOf(key) == owner;
        }
        if (!owned) {  // on to the pixel before the next key of another side
          u = nextOtherSide(keys, u + 1, width, last_side) - 1;
          continue;
        }
        if (u + kPrefetchAhead < width && keys[u + kPrefetchAhead] != voxel_key::kEmpty) {
          table.prefetch(keys[u + kPrefetchAhead]);
        }
        // The pixel above with the same key is this owner's too: its voxel was kept.
        last_voxel = v > 0 && keys_[row - width + u] == key
                         ? above[u]
                         : table.voxelOf(key, static_cast<uint32_t>(row + u));
      } else if (!owned) {
        continue;
      }
      if (rows) current[u] = last_voxel;
      const PointT& p = in.points[row + u];
      VoxelSum& sum = table.sums[last_voxel];
      sum.x += p.x, sum.y += p.y, sum.z += p.z;
      ++sum.count;
    }
    std::swap(above, current);
  }
}

void Preprocessor::writeCentroids(size_t owners, size_t pixels, size_t pieces, unsigned threads,
                                  Cloud& out) {
  size_t voxels = 0;
  for (size_t owner = 0; owner < owners; ++owner) voxels += owners_[owner].table.sums.size();
  // The points a reused cloud held are overwritten, not zeroed first.
  out.points.resize(voxels);
  pieces = std::max<size_t>(1, std::min(pieces, voxels));
  // Each owner's voxels are in the order they are first met; the output merges them. A piece
  // takes the voxels first met in its range of pixels; the voxels first met before the range
  // tell where its output starts.
  parallelFor(
      pieces,
      [&](size_t piece) {
        const size_t begin_pixel = piece * pixels / pieces,
                     end_pixel = (piece + 1) * pixels / pieces;
        auto firstMetFrom = [](const std::vector<VoxelSum>& sums, size_t pixel) {
          return static_cast<size_t>(std::lower_bound(sums.begin(), sums.end(), pixel,
                                                      [](const VoxelSum& sum, size_t at) {
                                                        return sum.first_pixel < at;
                                                      }) -
                                     sums.begin());
        };
        std::vector<const VoxelSum*> next(owners), end(owners);
        size_t at = 0;
        for (size_t owner = 0; owner < owners; ++owner) {
          const std::vector<VoxelSum>& sums = owners_[owner].table.sums;
          const size_t from = firstMetFrom(sums, begin_pixel);
          next[owner] = sums.data() + from;
          end[owner] = sums.data() + firstMetFrom(sums, end_pixel);
          at += from;
        }
        for (;;) {
          // The owner whose next voxel is met first takes its voxels met before any other's.
          size_t first_owner = owners;
          uint32_t first = std::numeric_limits<uint32_t>::max(), others_first = first;
          for (size_t owner = 0; owner < owners; ++owner) {
            if (next[owner] == end[owner]) continue;
            if (next[owner]->first_pixel < first) {
              others_first = first, first = next[owner]->first_pixel, first_owner = owner;
            } else {
              others_first = std::min(others_first, next[owner]->first_pixel);
            }
          }
          if (first_owner == owners) break;
          // Locals: the output's stores cannot alias them.
          const VoxelSum *sum = next[first_owner], *const last = end[first_owner];
          pcl::PointXYZ* point = &out.points[at];
          do {
            const double inv_count = 1.0 / sum->count;
            *point++ = pcl::PointXYZ(static_cast<float>(sum->x * inv_count),
                                     static_cast<float>(sum->y * inv_count),
                                     static_cast<float>(sum->z * inv_count));
            ++sum;
          } while (sum != last && sum->first_pixel < others_first);
          at += static_cast<size_t>(sum - next[first_owner]);
          next[first_owner] = sum;
        }
      },
      threads);
}

void Preprocessor::apply(const pcl::PointCloud<pcl::PointXYZ>& in, Cloud& out, ViewBounds* view) {
  if (&in == &out) {  // in-place call: build the result separately, then swap
    Cloud result;
    applyImpl(in, result, view);
    out.swap(result);
    return;
  }
  applyImpl(in, out, view);
}

void Preprocessor::apply(const pcl::PointCloud<pcl::PointXYZRGB>& in, Cloud& out,
                         ViewBounds* view) {
  applyImpl(in, out, view);
}

void Preprocessor::apply(const pcl::PointCloud<pcl::PointXYZRGBA>& in, Cloud& out,
                         ViewBounds* view) {
  applyImpl(in, out, view);
}

size_t Preprocessor::bufferBytes() const {
  size_t bytes = keys_.capacity() * sizeof(uint64_t);
  for (const VoxelOwner& owner : owners_) {
    bytes += owner.table.bytes() + owner.row_voxels.capacity() * sizeof(uint32_t);
  }
  return bytes;
}

void Preprocessor::releaseOversizedBuffers(size_t input_points) {
  // One key per input point: kept while frames of about this size come.
  constexpr size_t kKeySlack = 2, kKeepBytes = 1 << 20;
  if (keys_.capacity() * sizeof(uint64_t) > kKeepBytes &&
      keys_.capacity() > kKeySlack * input_points) {
    std::vector<uint64_t>().swap(keys_);
  }
  for (VoxelOwner& owner : owners_) {
    owner.table.release();
    if (owner.row_voxels.capacity() * sizeof(uint32_t) > kKeepBytes &&
        owner.row_voxels.capacity() > kKeySlack * input_points) {
      std::vector<uint32_t>().swap(owner.row_voxels);
    }
  }
}

template <typename PointT>
void Preprocessor::applyImpl(const pcl::PointCloud<PointT>& in, Cloud& out, ViewBounds* view) {
  out.header = in.header;
  out.width = 0;
  out.height = 1;
  out.is_dense = true;
  out.sensor_origin_ = in.sensor_origin_;
  out.sensor_orientation_ = in.sensor_orientation_;

  // An unorganised cloud is one row without image neighbours (no flying pixels).
  const bool organised = in.height > 1 && static_cast<size_t>(in.width) * in.height == in.size();
  const int width = organised ? static_cast<int>(in.width) : static_cast<int>(in.size());
  const int height = organised ? static_cast<int>(in.height) : 1;
  const bool drop_flying = organised && params_.flying_pixel_angle_deg > 0.0f;
  const bool gather_view = view && organised && width > 1;
  keys_.resize(in.points.size());

  // Each pixel's key depends on the input alone: bands of rows on all cores. More bands than
  // cores, so that a core slowed by other work takes fewer.
  const unsigned threads = workerThreads();
  const int bands = threads > 1 ? std::min(height, static_cast<int>(4 * threads)) : 1;
  if (gather_view) view_.reset(static_cast<size_t>(bands), static_cast<size_t>(height));
  if (width > 0) {
    parallelFor(
        static_cast<size_t>(bands),
        [&](size_t b) {
          ViewBoundsGatherer::Band band_view;
          keyRows(in, width, drop_flying, static_cast<int>(b * height / bands),
                  static_cast<int>((b + 1) * height / bands), gather_view ? &band_view : nullptr);
          if (gather_view) view_.setBand(b, band_view);
        },
        threads);
  }
  if (view) *view = gather_view ? view_.bounds() : ViewBounds();

  if (params_.leaf_size <= 0.0f) {  // no voxel grid: the valid points within range
    out.points.clear();
    out.points.reserve(in.points.size());
    for (size_t i = 0; i < in.points.size(); ++i) {
      const PointT& p = in.points[i];
      if (keys_[i] != voxel_key::kEmpty) out.points.emplace_back(p.x, p.y, p.z);
    }
    out.width = static_cast<uint32_t>(out.points.size());
    releaseOversizedBuffers(in.points.size());
    return;
  }

  // The voxel sums on all cores, each thread summing the voxels it owns in one pass in image
  // order: each voxel's double sum adds its points in that order, and the voxels come out in the
  // order they are first met, whatever the number of threads. (Summing per band of rows and
  // merging the bands' tables was slower: most voxels hold one or two points, and the merge's
  // inserts missed the cache.)
  const size_t owners = threads > 1 ? kSides : 1;
  if (owners_.size() < owners) owners_.resize(owners);
  parallelFor(
      owners, [&](size_t owner) { sumOwnedVoxels(in, width, height, owner, owners); }, threads);
  writeCentroids(owners, in.points.size(), static_cast<size_t>(bands), threads, out);
  out.width = static_cast<uint32_t>(out.points.size());
  releaseOversizedBuffers(in.points.size());
}

}  // namespace tabletop_shapes
