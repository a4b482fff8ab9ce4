#include "render/hifi/cdt.h"

#include <CGAL/Constrained_Delaunay_triangulation_2.h>
#include <CGAL/Exact_predicates_inexact_constructions_kernel.h>

#include <map>

namespace penumbra {

namespace {

using Kernel = CGAL::Exact_predicates_inexact_constructions_kernel;
using Vb = CGAL::Triangulation_vertex_base_2<Kernel>;
using Fb = CGAL::Constrained_triangulation_face_base_2<Kernel>;
using Tds = CGAL::Triangulation_data_structure_2<Vb, Fb>;
// Exact_predicates_tag: constraints may cross; their intersection points are constructed.
using Cdt = CGAL::Constrained_Delaunay_triangulation_2<Kernel, Tds, CGAL::Exact_predicates_tag>;

}  // namespace

Triangulation2 triangulateConstrained(
    const std::vector<glm::dvec2>& boundary,
    const std::vector<std::pair<glm::dvec2, glm::dvec2>>& segments) {
    Cdt cdt;
    const std::size_t n = boundary.size();
    for (std::size_t i = 0; i < n; ++i) {
        const glm::dvec2& a = boundary[i];
        const glm::dvec2& b = boundary[(i + 1) % n];
        cdt.insert_constraint(Kernel::Point_2(a.x, a.y), Kernel::Point_2(b.x, b.y));
    }
    for (const auto& [a, b] : segments) {
        if (a == b) continue;
        cdt.insert_constraint(Kernel::Point_2(a.x, a.y), Kernel::Point_2(b.x, b.y));
    }
    Triangulation2 out;
    std::map<Cdt::Vertex_handle, int> index;
    for (auto v = cdt.finite_vertices_begin(); v != cdt.finite_vertices_end(); ++v) {
        index.emplace(v, static_cast<int>(out.points.size()));
        out.points.emplace_back(v->point().x(), v->point().y());
    }
    for (auto f = cdt.finite_faces_begin(); f != cdt.finite_faces_end(); ++f)
        out.triangles.push_back(
            {index.at(f->vertex(0)), index.at(f->vertex(1)), index.at(f->vertex(2))});
    return out;
}

}  // namespace penumbra
