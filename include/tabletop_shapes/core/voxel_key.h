// Integer voxel coordinates packed into one 63-bit key, and the hash that spreads such keys
// over an open-addressing table: shared by the preprocessing voxel grid and GridSearch.
#pragma once

#include <cstdint>

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

}  // namespace voxel_key
}  // namespace tabletop_shapes
