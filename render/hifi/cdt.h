#pragma once
// Constrained Delaunay triangulation of a convex polygon with segments inside it: the one
// place CGAL's triangulation headers are compiled (CGAL 5.5, exact predicates, constraint
// intersections constructed).

#include <array>
#include <glm/vec2.hpp>
#include <utility>
#include <vector>

namespace penumbra {

struct Triangulation2 {
    std::vector<glm::dvec2> points;
    std::vector<std::array<int, 3>> triangles;  ///< counter-clockwise
};

/// Triangulates the convex polygon `boundary` (either winding) so that each edge of it and
/// each of `segments` (which must lie inside it; parts outside are the caller's to clip) is a
/// union of triangle edges. Crossing segments are split at their intersection.
Triangulation2 triangulateConstrained(
    const std::vector<glm::dvec2>& boundary,
    const std::vector<std::pair<glm::dvec2, glm::dvec2>>& segments);

}  // namespace penumbra
