// Splitting a Euclidean cluster that holds several touching or stacked objects (beyond the
// paper): surface patches (supervoxels) joined where the surface between them is convex
// (LCCP, Stein et al. 2014); the seam between two touching objects, or between a stacked box
// and the one below, is concave. Geometry only (XYZ).
#pragma once

#include "tabletop_shapes/core/types.h"

#include <utility>
#include <vector>

namespace tabletop_shapes {

// Whether the cluster can hold more than one object, one rising above the other, cheaply (a
// pass over its points): some of its points lie lower than its top band (the points within
// 2 cm of its highest point) and outside that band's footprint on the table, beyond depth
// noise. A box, cylinder, cup or bowl standing alone has every point under its top's footprint
// and is not split: the split (supervoxels + LCCP) costs far more than fitting.
bool mayHoldAStack(const Cloud& cluster, const Plane& table, const ClusteringParams& params);

// The clouds of `parts`, largest first (stable), and, when `groups` is given, each one's
// side-by-side group in the same order (the form splitAtConcaveSeams and the joins return).
std::vector<CloudPtr> largestFirst(std::vector<std::pair<CloudPtr, int>> parts,
                                   std::vector<int>* groups);

// The cluster's parts, largest first; the cluster itself when it is not split. Stacked parts
// (mayHoldAStack) are kept apart where one rises above the other (stacked or leaning on it,
// heights from `table`); objects side by side where each has a level top face of its own
// (touching boxes and cans, issue 15). `side_by_side`, when given, gets one entry per part: parts
// each under a level top face of its own share a number >= 0 (separate objects: the joins of
// cluster_join.h must not join them again), other parts -1. `scene`, when given, holds the
// points of every object on the table: a box whose top another object (of any cluster) lies
// across shows two level faces, and stays one object.
std::vector<CloudPtr> splitAtConcaveSeams(const CloudPtr& cluster, const Plane& table,
                                          const ClusteringParams& params,
                                          std::vector<int>* side_by_side = nullptr,
                                          const CloudConstPtr& scene = nullptr);

}  // namespace tabletop_shapes
