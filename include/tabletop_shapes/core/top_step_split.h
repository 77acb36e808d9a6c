// Two touching objects whose tops lie within a few millimetres of each other (issue 15): the
// top-face flood fill of cluster_split chains both tops into one level region, whose heights
// then show a step between two flat levels. This splits such a region at the step.
#pragma once

#include <cstddef>
#include <cstdint>
#include <vector>

namespace tabletop_shapes {

// One cell of a footprint grid (integer coordinates, 8-neighbours adjacent) and the height of
// its highest point above the table [m].
struct HeightCell {
  int64_t x, y;
  float height;
};

// The region's cells (indices into `region`) grouped under the tops they belong to: two (or
// more, each group split again) when the heights show a step between two level tops side by
// side, each holding at least `min_cells` cells; the whole region otherwise (one flat top,
// noise, a tilted top, a rim around a lower inside).
std::vector<std::vector<int>> splitAtTopSteps(const std::vector<HeightCell>& region,
                                              size_t min_cells);

}  // namespace tabletop_shapes
