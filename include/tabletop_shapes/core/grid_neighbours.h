// The 8-neighbour walk over a footprint grid keyed by voxel_key::pack(x, y, 0), shared by the
// top-face flood fill and neck watershed of cluster_split and the top-step split (issue 15).
#pragma once

#include "tabletop_shapes/core/voxel_key.h"

#include <cstdint>

namespace tabletop_shapes {

// Calls visit(key, value) for each of the 8 neighbours of cell (x, y) that `cells` (a map keyed
// by voxel_key::pack(x, y, 0)) holds, in a fixed order: the walks must not depend on hashing.
template <typename Map, typename Visit>
void forGridNeighbours(Map& cells, int64_t x, int64_t y, Visit&& visit) {
  for (int64_t dx = -1; dx <= 1; ++dx) {
    for (int64_t dy = -1; dy <= 1; ++dy) {
      if (!dx && !dy) continue;
      const uint64_t key = voxel_key::pack(x + dx, y + dy, 0);
      auto it = cells.find(key);
      if (it != cells.end()) visit(key, it->second);
    }
  }
}

}  // namespace tabletop_shapes
