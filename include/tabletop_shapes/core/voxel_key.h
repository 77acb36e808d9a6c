// Integer voxel coordinates packed into one 63-bit key, and the hash that spreads such keys
// over an open-addressing table: shared by the preprocessing voxel grid and GridSearch.
#pragma once

#include <cstdint>

#ifdef __SSE2__
#include <emmintrin.h>
#endif

namespace tabletop_shapes {
namespace voxel_key {

constexpr int kAxisBits = 21;                                   // bits per voxel coordinate
constexpr int64_t kAxisOffset = int64_t{1} << (kAxisBits - 1);  // makes coordinates >= 0
constexpr uint64_t kEmpty = ~uint64_t{0};                       // never a 63-bit key
// Coordinates beyond this many voxels from the origin cannot be packed (nor come from a
// depth camera).
constexpr float kLimit = static_cast<float>(kAxisOffset - 1);

inline uint64_t hash(uint64_t key) {  // splitmix64 finaliser: spreads neighbouring voxels
  key ^= key >> 31;
  key *= 0x7fb5d329728ea185ull;
  key ^= key >> 27;
  key *= 0x81dadef4bc2dd44dull;
  key ^= key >> 33;
  return key;
}

// floor() without the libm call that std::floor costs on baseline x86-64 (no SSE4.1); |v| must
// fit an int64.
inline int64_t floorToInt(float v) {
  const int64_t i = static_cast<int64_t>(v);
  return i - (v < static_cast<float>(i));
}

// |x|, |y|, |z| < kAxisOffset.
inline uint64_t pack(int64_t x, int64_t y, int64_t z) {
  return (static_cast<uint64_t>(x + kAxisOffset) << (2 * kAxisBits)) |
         (static_cast<uint64_t>(y + kAxisOffset) << kAxisBits) |
         static_cast<uint64_t>(z + kAxisOffset);
}

#ifdef __SSE2__
// pack() of four lanes' coordinates (|x|, |y|, |z| < kAxisOffset, as 32-bit integers) into
// keys[0..3], kEmpty in the lanes whose bit in kept_lanes is clear: the preprocessing keys
// four pixels at a time.
inline void packFour(__m128i x, __m128i y, __m128i z, int kept_lanes, uint64_t* keys) {
  // Made >= 0 in 32 bits (below 2^kAxisBits), then widened to 64 bits two lanes at a time.
  const __m128i offset = _mm_set1_epi32(static_cast<int32_t>(kAxisOffset)),
                lane_bits = _mm_setr_epi32(1, 2, 4, 8), none = _mm_setzero_si128();
  x = _mm_add_epi32(x, offset), y = _mm_add_epi32(y, offset), z = _mm_add_epi32(z, offset);
  const __m128i kept =
      _mm_cmpeq_epi32(_mm_and_si128(_mm_set1_epi32(kept_lanes), lane_bits), lane_bits);
  auto packTwo = [&](__m128i x2, __m128i y2, __m128i z2, __m128i kept2) {
    const __m128i key = _mm_or_si128(
        _mm_or_si128(_mm_slli_epi64(x2, 2 * kAxisBits), _mm_slli_epi64(y2, kAxisBits)), z2);
    return _mm_or_si128(key, _mm_xor_si128(kept2, _mm_set1_epi32(-1)));  // all bits: kEmpty
  };
  _mm_storeu_si128(reinterpret_cast<__m128i*>(keys),
                   packTwo(_mm_unpacklo_epi32(x, none), _mm_unpacklo_epi32(y, none),
                           _mm_unpacklo_epi32(z, none), _mm_unpacklo_epi32(kept, kept)));
  _mm_storeu_si128(reinterpret_cast<__m128i*>(keys + 2),
                   packTwo(_mm_unpackhi_epi32(x, none), _mm_unpackhi_epi32(y, none),
                           _mm_unpackhi_epi32(z, none), _mm_unpackhi_epi32(kept, kept)));
}
#endif

}  // namespace voxel_key
}  // namespace tabletop_shapes
