#include "tabletop_shapes/core/densest_slab.h"

#include "tabletop_shapes/core/cpu_features.h"
#include "tabletop_shapes/core/float4.h"

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <cstring>

#if defined(__x86_64__) && defined(__GNUC__)
#include <immintrin.h>
#endif

namespace tabletop_shapes {
namespace {

constexpr float kBinsPerWidth = 256.0f;

// The float's bits as an unsigned integer ordered as the values, -0 before +0: the order of
// the sorted values the result is defined on.
uint32_t orderKey(float value) {
  uint32_t bits;
  std::memcpy(&bits, &value, sizeof bits);
  return bits & 0x80000000u ? ~bits : bits | 0x80000000u;
}
// The float of an order key.
float valueOf(uint32_t key) {
  const uint32_t bits = key & 0x80000000u ? key & 0x7fffffffu : ~key;
  float value;
  std::memcpy(&value, &bits, sizeof value);
  return value;
}
bool keyLess(float a, float b) { return orderKey(a) < orderKey(b); }

// The definition itself: for values that are not all finite, or too spread for the bins.
DensestSlab bySorting(std::vector<float> sorted, float width) {
  std::sort(sorted.begin(), sorted.end(), keyLess);
  size_t best_begin = 0, best_end = 0;
  for (size_t begin = 0, end = 0; begin < sorted.size(); ++begin) {
    while (end < sorted.size() && sorted[end] <= sorted[begin] + width) ++end;
    if (end - begin > best_end - best_begin) best_begin = begin, best_end = end;
  }
  if (best_end == 0) return {};
  return {best_end - best_begin, sorted[best_begin], sorted[best_end - 1]};
}

#if defined(__x86_64__) && defined(__GNUC__)
__attribute__((target("avx2"))) void binsOfAvx2(const float* values, size_t n, float lo,
                                                float inv_bin, uint32_t* bins) {
  const __m256 low = _mm256_set1_ps(lo), scale = _mm256_set1_ps(inv_bin);
  size_t j = 0;
  for (; j + 8 <= n; j += 8) {
    const __m256 at = _mm256_mul_ps(_mm256_sub_ps(_mm256_loadu_ps(values + j), low), scale);
    _mm256_storeu_si256(reinterpret_cast<__m256i*>(bins + j), _mm256_cvttps_epi32(at));
  }
  for (; j < n; ++j)
    bins[j] = static_cast<uint32_t>(static_cast<int32_t>((values[j] - lo) * inv_bin));
}
#endif

// The bins of the n values in [lo, hi], (v - lo) * inv_bin truncated (as densestSlab's binOf:
// they lie below n + 4096, so truncating to 32 bits is truncating to 64), into `bins`. Eight at
// a time where the CPU has AVX2 (the same float operations).
void binsOf(const float* values, size_t n, float lo, float inv_bin, uint32_t* bins) {
#if defined(__x86_64__) && defined(__GNUC__)
  if (cpuHasAvx2()) return binsOfAvx2(values, n, lo, inv_bin, bins);
#endif
  for (size_t j = 0; j < n; ++j) {
    bins[j] = static_cast<uint32_t>(static_cast<int32_t>((values[j] - lo) * inv_bin));
  }
}

}  // namespace

DensestSlab densestSlab(const std::vector<float>& values, float width) {
  if (values.empty()) return {};
  const size_t n = values.size();
  float lo = values[0], hi = values[0];
  bool finite = true;
  size_t i = 0;
#ifdef __SSE__
  // Four at a time (the scalar loop, not vectorised by GCC, cost ~20 instructions a value): each
  // lane's min / max as std::min / std::max take them; v - v is 0 only for a finite v. The
  // range matters only when every value is finite (else bySorting below), and the minimum and
  // maximum of finite floats are the same floats in any order (a zero's sign aside, which
  // neither the bins nor the comparisons below tell apart).
  if (n >= 4) {
    Float4 low = broadcast(lo), high = broadcast(hi);
    Int4 all_finite = Int4{} - 1;
    for (; i + 4 <= n; i += 4) {
      Float4 v;
      std::memcpy(&v, &values[i], sizeof v);
      low = (Float4)_mm_min_ps((__m128)v, (__m128)low);
      high = (Float4)_mm_max_ps((__m128)v, (__m128)high);
      all_finite &= (v - v) == Float4{};
    }
    for (int lane = 0; lane < 4; ++lane) {
      lo = std::min(lo, low[lane]);
      hi = std::max(hi, high[lane]);
      finite = finite && all_finite[lane] != 0;
    }
  }
#endif
  for (; i < n; ++i) {
    const float v = values[i];
    lo = std::min(lo, v);
    hi = std::max(hi, v);
    finite = finite && std::isfinite(v);
  }
  const float inv_bin = kBinsPerWidth / width;
  if (!finite || !(width > 0.0f) || !std::isfinite(inv_bin) ||
      !((hi - lo) * inv_bin < static_cast<float>(n) + 4096.0f)) {
    return bySorting(values, width);
  }
  // Bins in the values' order: a <= b gives binOf(a) <= binOf(b) (rounding is monotone), so a
  // value in a lower bin than x is < x and one in a higher bin > x, whatever the rounding.
  // Through int64_t: one conversion instruction, where float to size_t is a compare and two
  // paths (the same bin: (v - lo) * inv_bin lies in [0, n + 4096)).
  auto binOf = [&](float v) {
    return static_cast<size_t>(static_cast<int64_t>((v - lo) * inv_bin));
  };
  const size_t bins = binOf(hi) + 1;
  // Each value's bin, computed once for the two passes below (buffers kept from call to call,
  // growing only: no zero filling per call).
  thread_local std::vector<uint32_t> bin_of;
  thread_local std::vector<float> grouped;
  if (bin_of.size() < n) bin_of.resize(n), grouped.resize(n);
  binsOf(values.data(), n, lo, inv_bin, bin_of.data());
  std::vector<uint32_t> start(bins + 1, 0);  // start[b]: the values in the bins below b
  std::vector<float> bin_min(bins, hi), bin_max(bins, lo);
  for (size_t j = 0; j < n; ++j) {
    const float v = values[j];
    const size_t b = bin_of[j];
    ++start[b + 1];
    bin_min[b] = std::min(bin_min[b], v);
    bin_max[b] = std::max(bin_max[b], v);
  }
  for (size_t b = 0; b < bins; ++b) start[b + 1] += start[b];
  // The values a run starting at a value of bin b can hold at least (from the bin's smallest
  // value on, with x = that value + width) and at most (x = the bin's largest value + width):
  // every value in the bins below that of the run's end value x is <= x.
  auto valuesFromBinTo = [&](size_t b, float x) -> size_t {
    return x >= hi ? n - start[b] : start[binOf(x)] - start[b];
  };
  auto valuesFromBinThrough = [&](size_t b, float x) -> size_t {
    return x >= hi ? n - start[b] : start[binOf(x) + 1] - start[b];
  };
  size_t surely = 0;  // the longest run some bin surely starts
  for (size_t b = 0; b < bins; ++b) {
    if (start[b + 1] == start[b]) continue;
    surely = std::max(surely, valuesFromBinTo(b, bin_min[b] + width));
  }
  // Only bins that can start a run that long can hold the longest run's first value.
  auto canStart = [&](size_t b) {
    return start[b + 1] != start[b] && valuesFromBinThrough(b, bin_max[b] + width) >= surely;
  };
  // The bins the search below reads: those that can start the run, those its end values x (a
  // start bin's values + width) fall in, and the last nonempty bin below those (where a run
  // ends that holds no value of x's bin), and the last bin (x >= hi). Only their values are
  // grouped by bin, a few per cent of a plane's; should another be read, it is grouped then.
  std::vector<char> needed(bins, 0);
  for (size_t b = 0; b < bins; ++b) {
    if (!canStart(b)) continue;
    needed[b] = 1;
    const float first_x = bin_min[b] + width, last_x = bin_max[b] + width;
    const size_t first_end = first_x >= hi ? bins - 1 : binOf(first_x);
    const size_t last_end = last_x >= hi ? bins - 1 : binOf(last_x);
    std::fill(needed.begin() + first_end, needed.begin() + last_end + 1, 1);
    size_t below = first_end;
    while (below > 0 && start[below] == start[below - 1]) --below;  // bins below it empty
    if (below > 0) needed[below - 1] = 1;
  }
  // The needed bins' values grouped by bin: the sorted order once each bin is sorted (done when
  // needed).
  std::vector<uint32_t> next(start.begin(), start.end() - 1);
  for (size_t j = 0; j < n; ++j) {
    const size_t b = bin_of[j];
    if (needed[b]) grouped[next[b]++] = values[j];
  }
  std::vector<char> bin_sorted(bins, 0);
  std::vector<uint32_t> keys;
  auto sortBin = [&](size_t b) {
    if (bin_sorted[b]) return;
    if (!needed[b]) {
      for (size_t j = 0; j < n; ++j) {
        if (bin_of[j] == b) grouped[next[b]++] = values[j];
      }
    }
    // Sorted as their order keys, each computed once (not twice per comparison); the values
    // back from the keys.
    keys.clear();
    for (uint32_t k = start[b]; k < start[b + 1]; ++k) keys.push_back(orderKey(grouped[k]));
    std::sort(keys.begin(), keys.end());
    for (uint32_t k = start[b]; k < start[b + 1]; ++k) grouped[k] = valueOf(keys[k - start[b]]);
    bin_sorted[b] = 1;
  };
  // The candidate start bins' begins in ascending order, each run's end found as in the sorted
  // array (it only grows).
  size_t best_begin = 0, best_end = 0;
  for (size_t b = 0; b < bins; ++b) {
    if (!canStart(b)) continue;
    sortBin(b);
    size_t end = start[b];
    for (size_t begin = start[b]; begin < start[b + 1]; ++begin) {
      const float x = grouped[begin] + width;
      if (x >= hi) {
        end = n;
      } else {
        const size_t end_bin = binOf(x);
        sortBin(end_bin);
        end = std::max<size_t>(end, start[end_bin]);
        while (end < start[end_bin + 1] && grouped[end] <= x) ++end;
      }
      if (end - begin > best_end - best_begin) best_begin = begin, best_end = end;
    }
  }
  // The run's last value: its bin sorted.
  const size_t last_bin =
      static_cast<size_t>(std::upper_bound(start.begin(), start.end(), best_end - 1) -
                          start.begin()) -
      1;
  sortBin(last_bin);
  return {best_end - best_begin, grouped[best_begin], grouped[best_end - 1]};
}

}  // namespace tabletop_shapes
