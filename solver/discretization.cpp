// Index: geometry helpers · parametric grids (quad, box, sphere, cylinder) · meshes
//        (split, region growing) · Discretization queries · subdivision
#include "solver/discretization.h"

#include <tbb/parallel_for.h>

#include <algorithm>
#include <cmath>
#include <functional>
#include <map>
#include <sstream>
#include <stdexcept>

#include "solver/ray_tracer.h"

namespace penumbra {

namespace {

using VHandle = ElementMesh::VertexHandle;
using FHandle = ElementMesh::FaceHandle;

ElementMesh::Point toPoint(const Vec3& v) { return ElementMesh::Point(v.x, v.y, v.z); }

Vec3 transformPoint(const Mat4& m, const Vec3& p) { return Vec3(m * glm::dvec4(p, 1.0)); }

/// Cells along one side of a grid, or edge steps of a split triangle, at most: a count beyond
/// it comes from a size far out of scale with the element size (and no memory would hold it).
constexpr double kMaxCells = 1 << 15;
/// Elements one object may have at most (an object of 8M elements would already need gigabytes).
constexpr double kMaxObjectElements = 1 << 23;

/// Cells of about `target` along `length`. Throws std::invalid_argument beyond kMaxCells.
int cellsFor(double length, double target) {
    if (!(length > 0) || !(target > 0)) return 1;
    const double cells = std::ceil(length / target - 1e-9);
    if (!(cells <= kMaxCells))
        throw std::invalid_argument("a length of " + std::to_string(length) + " needs " +
                                    std::to_string(cells) + " cells of " + std::to_string(target) +
                                    " (at most " + std::to_string(static_cast<int>(kMaxCells)) +
                                    "): sizes out of scale with the element size");
    return std::max(1, static_cast<int>(cells));
}

/// Throws std::invalid_argument when an object would have more than kMaxObjectElements.
void checkElementCount(double elements) {
    if (elements > kMaxObjectElements)
        throw std::invalid_argument(std::to_string(elements) + " elements (at most " +
                                    std::to_string(static_cast<long>(kMaxObjectElements)) +
                                    "): sizes out of scale with the element size");
}

constexpr double kMeshPatchNormalCos = 0.7071;  // cos 45°: mesh patches stay roughly flat

}  // namespace

// ---------------------------------------------------------------------------------------------
// toString

std::string Patch::toString() const {
    std::ostringstream s;
    s << "Patch{object " << object << ", area " << area << ", elements " << elements.size()
      << ", centroid (" << centroid.x << ' ' << centroid.y << ' ' << centroid.z << ")}";
    return s.str();
}

std::string Element::toString() const {
    std::ostringstream s;
    s << "Element{patch " << patch << ", object " << object << ", area " << area << ", centroid ("
      << centroid.x << ' ' << centroid.y << ' ' << centroid.z << "), normal (" << normal.x << ' '
      << normal.y << ' ' << normal.z << ")}";
    return s.str();
}

std::string Discretization::toString() const {
    std::ostringstream s;
    s << "Discretization{" << mObjects.size() << " objects, " << mPatches.size() << " patches, "
      << mElements.size() << " elements, area " << mTotalArea << " m²}";
    return s.str();
}

// ---------------------------------------------------------------------------------------------
// Construction

Discretization::Discretization(const Scene& scene, PatchGrouping grouping) : mGrouping(grouping) {
    for (const SceneObject& object : scene.objects) buildObject(scene, object);
}

int Discretization::addObject(const Scene& scene, const SceneObject& object) {
    buildObject(scene, object);
    return static_cast<int>(mObjects.size()) - 1;
}

std::vector<int> Discretization::aliveElements() const {
    std::vector<int> alive;
    for (std::size_t e = 0; e < mElements.size(); ++e)
        if (elementAlive(static_cast<int>(e))) alive.push_back(static_cast<int>(e));
    return alive;
}

void Discretization::setAlive(int object, bool alive) {
    if (mObjects[object].alive == alive) return;
    mObjects[object].alive = alive;
    double area = 0;
    for (const Patch& p : mPatches)
        if (p.object == object) area += p.area;
    mTotalArea += alive ? area : -area;
}

void Discretization::setObjectMaterial(int object, const Material& material) {
    // Which faces have twins is geometry: a two_sided change needs a rebuilt object.
    const int m = addMaterial(material);
    int back = -1;
    for (Patch& p : mPatches) {
        if (p.object != object) continue;
        if (!p.elements.empty() && mObjects[object].isBackFace(mElements[p.elements[0]].face)) {
            if (back < 0) back = addMaterial(backMaterial(material));
            p.material = back;
        } else {
            p.material = m;
        }
    }
    mObjects[object].twoSided = material.twoSided;
}

int Discretization::addMaterial(const Material& m) {
    mMaterials.push_back(m);
    return static_cast<int>(mMaterials.size()) - 1;
}

void Discretization::finishElement(int e) {
    Element& el = mElements[e];
    std::vector<Vec3> poly = elementPolygon(e);
    Vec3 n = newellNormal(poly);
    double len = glm::length(n);
    el.area = 0.5 * len;
    el.normal = len > 0 ? n / len : Vec3(0, 1, 0);
    // Area centroid by fan triangulation.
    Vec3 c(0.0);
    double total = 0;
    for (std::size_t i = 1; i + 1 < poly.size(); ++i) {
        double a = 0.5 * glm::length(glm::cross(poly[i] - poly[0], poly[i + 1] - poly[0]));
        c += a * (poly[0] + poly[i] + poly[i + 1]) / 3.0;
        total += a;
    }
    el.centroid = total > 0 ? c / total : poly[0];
    if (static_cast<std::size_t>(e) < mReceivers.size()) mReceivers[e] = el.centroid;
}

int Discretization::placeReceivers(const RayTracer& tracer) {
    const double eps = tracer.epsilon();
    // Inside another object's solid: the normal and four rays tilted 45° from it all meet the
    // same other object from behind. Under an open surface (a one-sided panel hung above) the
    // tilted rays pass beside it.
    auto insideSolid = [&](const Element& el, const Vec3& x) {
        Vec3 t = std::abs(el.normal.x) > 0.5 ? glm::cross(el.normal, Vec3(0, 1, 0))
                                             : glm::cross(el.normal, Vec3(1, 0, 0));
        t = glm::normalize(t);
        const Vec3 b = glm::cross(el.normal, t);
        const Vec3 directions[5] = {el.normal, el.normal + t, el.normal - t, el.normal + b,
                                    el.normal - b};
        int solid = -1;
        for (const Vec3& d : directions) {
            const RayTracer::FirstHit hit = tracer.firstHit(x + eps * el.normal, glm::normalize(d));
            if (hit.element < 0 || !hit.backFace) return false;
            const int o = mElements[hit.element].object;
            if (o == el.object || (solid >= 0 && o != solid)) return false;
            solid = o;
        }
        return true;
    };
    std::vector<Vec3> placed(mElements.size());
    tbb::parallel_for(std::size_t(0), mElements.size(), [&](std::size_t e) {
        const Element& el = mElements[e];
        placed[e] = el.centroid;
        if (!elementAlive(static_cast<int>(e)) || !insideSolid(el, el.centroid)) return;
        // Sample points of the element: per fan triangle, its centroid and the points a
        // third of the way from it to each corner.
        const std::vector<Vec3> poly = elementPolygon(static_cast<int>(e));
        std::vector<Vec3> open;
        for (std::size_t i = 1; i + 1 < poly.size(); ++i) {
            const Vec3 c = (poly[0] + poly[i] + poly[i + 1]) / 3.0;
            for (const Vec3& p : {c, c + (poly[0] - c) * (2.0 / 3.0),
                                  c + (poly[i] - c) * (2.0 / 3.0), c + (poly[i + 1] - c) * (2.0 / 3.0)})
                if (!insideSolid(el, p)) open.push_back(p);
        }
        if (open.empty()) return;  // wholly covered: it receives nothing wherever it samples
        Vec3 mean(0.0);
        for (const Vec3& p : open) mean += p;
        mean /= static_cast<double>(open.size());
        placed[e] = *std::min_element(open.begin(), open.end(), [&](const Vec3& a, const Vec3& b) {
            return glm::length(a - mean) < glm::length(b - mean);
        });
    });
    int moved = 0;
    for (std::size_t e = 0; e < mElements.size(); ++e) moved += placed[e] != mElements[e].centroid;
    // Every receiver at its centroid: receiver() needs no table.
    if (moved == 0) placed = {};
    mReceivers = std::move(placed);
    return moved;
}

void accumulateFanAreas(const std::vector<Vec3>& poly, std::vector<double>& cumulative) {
    cumulative.clear();
    double sum = 0;
    for (std::size_t i = 0; i + 2 < poly.size(); ++i)
        cumulative.push_back(sum +=
                             glm::length(glm::cross(poly[i + 1] - poly[0], poly[i + 2] - poly[0])));
}

void Discretization::finishPatch(int p) {
    Patch& patch = mPatches[p];
    patch.area = 0;
    Vec3 c(0.0), n(0.0);
    for (int e : patch.elements) {
        const Element& el = mElements[e];
        patch.area += el.area;
        c += el.area * el.centroid;
        n += el.area * el.normal;
    }
    patch.centroid = patch.area > 0 ? c / patch.area : c;
    double len = glm::length(n);
    patch.normal = len > 0 ? n / len : Vec3(0, 1, 0);
    patch.radius = 0;
    for (int e : patch.elements)
        for (const Vec3& v : elementPolygon(e))
            patch.radius = std::max(patch.radius, glm::length(v - patch.centroid));
    accumulateFanAreas(patch.outline, patch.outlineFans);
    const auto& o = patch.outline;
    // o0 + o2 = o1 + o3, to the rounding of coordinates as large as the largest here.
    double extent = 0;
    for (const Vec3& v : o)
        extent = std::max({extent, std::abs(v.x), std::abs(v.y), std::abs(v.z)});
    patch.parallelogram =
        o.size() == 4 && glm::length(o[0] + o[2] - o[1] - o[3]) <= 1e-12 * (1 + extent);
}

namespace {

/// Collects faces for one object before they become elements and patches.
struct SurfaceBuilder {
    ObjectSurface& surface;
    std::vector<std::vector<int>> faceVertices;  ///< per face, object mesh vertex indices
    std::vector<int> faceGroup;                  ///< per face, patch group (or -1: grow later)
    std::vector<int> faceMaterial;

    VHandle addVertex(const Vec3& objectPos) { return surface.mesh.add_vertex(toPoint(objectPos)); }

    /// Adds a polygon; when OpenMesh refuses it (non-manifold), its vertices are duplicated
    /// so it stands alone. Returns false for degenerate polygons.
    bool mirrored = false;  ///< the transform has negative determinant: reverse windings

    bool addFace(std::vector<VHandle> vs, int group, int material) {
        if (mirrored) std::reverse(vs.begin(), vs.end());
        // Drop repeated consecutive vertices (grid poles, cap centres).
        std::vector<VHandle> clean;
        for (VHandle v : vs)
            if (clean.empty() || clean.back() != v) clean.push_back(v);
        while (clean.size() > 1 && clean.front() == clean.back()) clean.pop_back();
        if (clean.size() < 3) return false;
        FHandle f = surface.mesh.add_face(clean);
        if (!f.is_valid()) {
            std::vector<VHandle> copy;
            for (VHandle v : clean) {
                const ElementMesh::Point p = surface.mesh.point(v);  // add_vertex may reallocate
                copy.push_back(surface.mesh.add_vertex(p));
            }
            f = surface.mesh.add_face(copy);
            if (!f.is_valid()) return false;
            clean = copy;
        }
        std::vector<int> idx;
        for (VHandle v : clean) idx.push_back(v.idx());
        faceVertices.push_back(std::move(idx));
        faceGroup.push_back(group);
        faceMaterial.push_back(material);
        return true;
    }
};

/// A parametric surface P(u, v), u and v in [0, 1], gridded into patches of elements.
struct ParamGrid {
    std::function<Vec3(double, double)> point;    ///< object space
    Vec3 outwardAt;                               ///< reference direction at (0.5, 0.5)
    bool wrapU = false;                           ///< u = 0 and u = 1 coincide
    bool collapseV0 = false, collapseV1 = false;  ///< the rows v = 0 / v = 1 are a single point
    int minCellsU = 1, minCellsV = 1;
};

/// Lays an object's shape out as faces of a SurfaceBuilder: parametric shapes as grids of
/// patches (groups) of elements, meshes as their triangles split to the element size.
struct ShapeFaces {
    ShapeFaces(SurfaceBuilder& b, const glm::dmat3& linearPart, double patch, double element,
               int material, const std::vector<int>& perMesh)
        : builder(b),
          surface(b.surface),
          linear(linearPart),
          patchSize(patch),
          elementSize(element),
          objectMaterial(material),
          meshMaterials(perMesh) {}

    SurfaceBuilder& builder;
    ObjectSurface& surface;
    glm::dmat3 linear;  ///< object to world, without the translation
    double patchSize, elementSize;
    int objectMaterial;  ///< -1: each triangle takes its mesh material
    const std::vector<int>& meshMaterials;
    bool cellPatches = false;  ///< every grid cell a patch (group) of its own
    int nextGroup = 0;
    std::map<int, std::vector<Vec3>> groupOutline;  ///< per group, its boundary (object space)
    double planned = 0;  ///< elements of the object so far (checkElementCount)
    bool countOnly = false;  ///< plan the elements (planned) without building any faces

    void addShape(const Shape& shape) {
        switch (shape.type) {
            case ShapeType::Quad: {
                double sx = shape.size.x, sz = shape.size.z;
                if (shape.size.z == 0 && shape.size.y != 0) sz = shape.size.y;
                addGrid(
                    {[=](double u, double v) { return Vec3(-sx / 2 + u * sx, 0, sz / 2 - v * sz); },
                     Vec3(0, 1, 0)});
                break;
            }
            case ShapeType::Box: {
                Vec3 h = shape.size / 2.0;
                const Vec3 axes[3] = {{1, 0, 0}, {0, 1, 0}, {0, 0, 1}};
                for (int k = 0; k < 3; ++k)
                    for (double sign : {1.0, -1.0}) {
                        Vec3 n = sign * axes[k];
                        Vec3 a = axes[(k + 1) % 3], b = axes[(k + 2) % 3];
                        double la = glm::dot(shape.size, a), lb = glm::dot(shape.size, b);
                        Vec3 centre = n * glm::dot(h, axes[k]);
                        addGrid({[=](double u, double v) {
                                     return centre + a * ((u - 0.5) * la) + b * ((v - 0.5) * lb);
                                 },
                                 n});
                    }
                break;
            }
            case ShapeType::Sphere: {
                double r = shape.radius;
                ParamGrid g{[=](double u, double v) {
                                double phi = 2 * M_PI * u, theta = M_PI * v;
                                return Vec3(r * std::sin(theta) * std::cos(phi),
                                            r * std::cos(theta),
                                            r * std::sin(theta) * std::sin(phi));
                            },
                            Vec3(0, 0, 1)};
                // (0.5, 0.5) is at phi = π, on the equator: outward is -X.
                g.outwardAt = Vec3(-1, 0, 0);
                g.wrapU = true;
                g.collapseV0 = g.collapseV1 = true;
                g.minCellsU = shape.segments;
                g.minCellsV = std::max(2, shape.segments / 2);
                addGrid(g);
                break;
            }
            case ShapeType::Cylinder: {
                double r = shape.radius, hh = shape.height / 2;
                ParamGrid side{[=](double u, double v) {
                                   double phi = 2 * M_PI * u;
                                   return Vec3(r * std::cos(phi), -hh + v * 2 * hh,
                                               r * std::sin(phi));
                               },
                               Vec3(-1, 0, 0)};
                side.wrapU = true;
                side.minCellsU = shape.segments;
                addGrid(side);
                for (double sign : {1.0, -1.0}) {
                    ParamGrid cap{[=](double u, double v) {
                                      double phi = 2 * M_PI * u;
                                      return Vec3(v * r * std::cos(phi), sign * hh,
                                                  v * r * std::sin(phi));
                                  },
                                  Vec3(0, sign, 0)};
                    cap.wrapU = true;
                    cap.collapseV0 = true;
                    cap.minCellsU = shape.segments;
                    addGrid(cap);
                }
                break;
            }
            case ShapeType::Mesh: {
                addMesh(shape.mesh);
                break;
            }
        }
    }

    /// Grids a parametric surface: patches of about patchSize, elements of about
    /// elementSize, measured in world space.
    void addGrid(const ParamGrid& grid) {
        auto worldLen = [&](Vec3 a, Vec3 b) { return glm::length(linear * (b - a)); };
        // Longest world-space length of a u-line and of a v-line.
        double lenU = 0, lenV = 0;
        for (double t : {0.0, 0.5, 1.0}) {
            double lu = 0, lv = 0;
            for (int k = 0; k < 16; ++k) {
                lu += worldLen(grid.point(k / 16.0, t), grid.point((k + 1) / 16.0, t));
                lv += worldLen(grid.point(t, k / 16.0), grid.point(t, (k + 1) / 16.0));
            }
            lenU = std::max(lenU, lu);
            lenV = std::max(lenV, lv);
        }
        int pu = cellsFor(lenU, patchSize), pv = cellsFor(lenV, patchSize);
        int eu = cellsFor(lenU / pu, elementSize), ev = cellsFor(lenV / pv, elementSize);
        while (pu * eu < grid.minCellsU) ++eu;
        while (pv * ev < grid.minCellsV) ++ev;
        planned += static_cast<double>(pu) * eu * pv * ev;
        checkElementCount(planned);
        if (countOnly) return;
        int nu = pu * eu, nv = pv * ev;
        // Orientation: cross(dP/du, dP/dv) must point outward.
        Vec3 du = grid.point(0.51, 0.5) - grid.point(0.49, 0.5);
        Vec3 dv = grid.point(0.5, 0.51) - grid.point(0.5, 0.49);
        bool flip = glm::dot(glm::cross(du, dv), grid.outwardAt) < 0;
        auto P = [&](int i, int j) {
            double u = static_cast<double>(i) / nu;
            return grid.point(flip ? 1.0 - u : u, static_cast<double>(j) / nv);
        };
        std::vector<VHandle> verts((nu + 1) * (nv + 1));
        VHandle pole0, pole1;
        for (int j = 0; j <= nv; ++j)
            for (int i = 0; i <= nu; ++i) {
                VHandle& h = verts[j * (nu + 1) + i];
                if (grid.wrapU && i == nu)
                    h = verts[j * (nu + 1)];
                else if (grid.collapseV0 && j == 0)
                    h = pole0.is_valid() ? pole0 : (pole0 = builder.addVertex(P(i, j)));
                else if (grid.collapseV1 && j == nv)
                    h = pole1.is_valid() ? pole1 : (pole1 = builder.addVertex(P(i, j)));
                else
                    h = builder.addVertex(P(i, j));
            }
        auto corner = [&](int i, int j) {
            const auto& q = surface.mesh.point(verts[j * (nu + 1) + i]);
            return Vec3(q[0], q[1], q[2]);
        };
        // The boundary of cells [i0, i1) × [j0, j1), walked along the grid lines.
        auto outlineCells = [&](int i0, int i1, int j0, int j1) {
            std::vector<Vec3> outline;
            for (int i = i0; i < i1; ++i) outline.push_back(corner(i, j0));
            for (int j = j0; j < j1; ++j) outline.push_back(corner(i1, j));
            for (int i = i1; i > i0; --i) outline.push_back(corner(i, j1));
            for (int j = j1; j > j0; --j) outline.push_back(corner(i0, j));
            return outline;
        };
        // Faces in the same order whether cells are patches or not, so both groupings have
        // the same elements at the same indices.
        for (int b = 0; b < pv; ++b)
            for (int a = 0; a < pu; ++a) {
                int group = -1;
                if (!cellPatches) {
                    group = nextGroup++;
                    groupOutline[group] = outlineCells(a * eu, (a + 1) * eu, b * ev, (b + 1) * ev);
                }
                for (int j = b * ev; j < (b + 1) * ev; ++j)
                    for (int i = a * eu; i < (a + 1) * eu; ++i) {
                        if (cellPatches) {
                            group = nextGroup++;
                            groupOutline[group] = outlineCells(i, i + 1, j, j + 1);
                        }
                        builder.addFace(
                            {verts[j * (nu + 1) + i], verts[j * (nu + 1) + i + 1],
                             verts[(j + 1) * (nu + 1) + i + 1], verts[(j + 1) * (nu + 1) + i]},
                            group, objectMaterial);
                    }
            }
    }

    void addMesh(const TriMesh& tm) {
        std::vector<VHandle> base;
        if (!countOnly) {
            base.reserve(tm.positions.size());
            for (const Vec3& p : tm.positions) base.push_back(builder.addVertex(p));
        }
        // Points on a split edge are shared by both triangles: key (lo, hi, step from lo).
        std::map<std::tuple<int, int, int>, VHandle> edgePoints;
        for (std::size_t t = 0; t < tm.triangles.size(); ++t) {
            const auto& tri = tm.triangles[t];
            int material = objectMaterial;
            if (material < 0 && !countOnly) {
                int tmi = t < tm.triangleMaterial.size() ? tm.triangleMaterial[t] : 0;
                material = meshMaterials.at(std::clamp(tmi, 0, int(meshMaterials.size()) - 1));
            }
            Vec3 p[3];
            for (int k = 0; k < 3; ++k) p[k] = tm.positions[tri[k]];
            double longest = 0;
            for (int k = 0; k < 3; ++k)
                longest = std::max(longest, glm::length(linear * (p[(k + 1) % 3] - p[k])));
            int n = cellsFor(longest, elementSize);
            planned += static_cast<double>(n) * n;
            checkElementCount(planned);
            if (countOnly) continue;
            if (n == 1) {
                builder.addFace({base[tri[0]], base[tri[1]], base[tri[2]]}, -1, material);
                continue;
            }
            // Regular split into n² triangles; lattice point (i, j): i steps from vertex 0
            // toward 1, j toward 2.
            auto latticeVertex = [&](int i, int j) -> VHandle {
                int k0 = n - i - j;
                if (i == n) return base[tri[1]];
                if (j == n) return base[tri[2]];
                if (k0 == n) return base[tri[0]];
                Vec3 pos = (double(k0) * p[0] + double(i) * p[1] + double(j) * p[2]) / double(n);
                auto edgeKey = [&](int a, int b, int stepsFromA) {
                    int va = tri[a], vb = tri[b];
                    return va < vb ? std::make_tuple(va, vb, stepsFromA)
                                   : std::make_tuple(vb, va, n - stepsFromA);
                };
                std::tuple<int, int, int> key;
                if (j == 0)
                    key = edgeKey(0, 1, i);
                else if (i == 0)
                    key = edgeKey(0, 2, j);
                else if (k0 == 0)
                    key = edgeKey(1, 2, j);
                else
                    return builder.addVertex(pos);  // interior point
                auto it = edgePoints.find(key);
                if (it != edgePoints.end()) return it->second;
                return edgePoints[key] = builder.addVertex(pos);
            };
            std::vector<VHandle> lattice;
            auto at = [&](int i, int j) { return lattice[j * (n + 1) + i]; };
            lattice.resize((n + 1) * (n + 1));
            for (int j = 0; j <= n; ++j)
                for (int i = 0; i + j <= n; ++i) lattice[j * (n + 1) + i] = latticeVertex(i, j);
            for (int j = 0; j < n; ++j)
                for (int i = 0; i + j < n; ++i) {
                    builder.addFace({at(i, j), at(i + 1, j), at(i, j + 1)}, -1, material);
                    if (i + j + 1 < n)
                        builder.addFace({at(i + 1, j), at(i + 1, j + 1), at(i, j + 1)}, -1,
                                        material);
                }
        }
    }
};

}  // namespace

double Discretization::countElements(const Scene& scene) {
    double count = 0;
    ObjectSurface surface;  // untouched when counting
    SurfaceBuilder builder{surface, {}, {}, {}};
    const std::vector<int> noMeshMaterials;
    for (const SceneObject& obj : scene.objects) {
        ShapeFaces faces(builder, glm::dmat3(obj.transform.worldFromObject()),
                         obj.patchSize > 0 ? obj.patchSize : scene.settings.patchSize,
                         scene.settings.elementSize, 0, noMeshMaterials);
        faces.countOnly = true;
        try {
            faces.addShape(obj.shape);
        } catch (const std::invalid_argument& e) {
            throw std::invalid_argument("object '" + obj.id + "': " + e.what());
        }
        count += faces.planned;
    }
    return count;
}

void Discretization::buildObject(const Scene& scene, const SceneObject& obj) {
    mObjects.push_back({});
    ObjectSurface& surface = mObjects.back();
    surface.id = obj.id;
    surface.worldFromObject = obj.transform.worldFromObject();
    const Mat4& M = surface.worldFromObject;
    const glm::dmat3 linear(M);
    const double patchSize = obj.patchSize > 0 ? obj.patchSize : scene.settings.patchSize;

    // Materials: the object's, or the mesh's own per triangle.
    int objectMaterial = -1;
    std::vector<int> meshMaterials;
    if (!obj.material.empty()) {
        const Material* m = scene.findMaterial(obj.material);
        if (!m)
            throw std::invalid_argument("object '" + obj.id + "': unknown material '" +
                                        obj.material + "'");
        objectMaterial = addMaterial(*m);
        surface.twoSided = m->twoSided;
    } else {
        for (const Material& m : obj.shape.mesh.materials) meshMaterials.push_back(addMaterial(m));
        if (meshMaterials.empty()) objectMaterial = addMaterial(Material{});
    }

    // Faces.
    SurfaceBuilder builder{surface, {}, {}, {}};
    builder.mirrored = glm::determinant(linear) < 0;
    ShapeFaces faces(builder, linear, patchSize, scene.settings.elementSize, objectMaterial,
                     meshMaterials);
    // An object's own patch size stands in either grouping (a lamp that shoots as one).
    const bool leaves = mGrouping == PatchGrouping::Elements && !(obj.patchSize > 0);
    faces.cellPatches = leaves;
    try {
        faces.addShape(obj.shape);
    } catch (const std::invalid_argument& e) {
        throw std::invalid_argument("object '" + obj.id + "': " + e.what());
    }
    if (builder.faceVertices.empty())
        throw std::invalid_argument("object '" + obj.id + "': no valid faces");

    // World positions.
    surface.worldPositions.resize(surface.mesh.n_vertices());
    for (auto v : surface.mesh.vertices()) {
        const auto& q = surface.mesh.point(v);
        surface.worldPositions[v.idx()] = transformPoint(M, Vec3(q[0], q[1], q[2]));
    }

    // Elements, one per face.
    const int objIdx = static_cast<int>(mObjects.size()) - 1;
    const int firstPatch = static_cast<int>(mPatches.size());
    const int firstElement = static_cast<int>(mElements.size());
    const int faceCount = static_cast<int>(builder.faceVertices.size());
    surface.faceElement.resize(surface.mesh.n_faces(), -1);
    for (int f = 0; f < faceCount; ++f) {
        Element el;
        el.object = objIdx;
        el.face = f;
        el.vertices = builder.faceVertices[f];
        mElements.push_back(std::move(el));
        surface.faceElement[f] = firstElement + f;
        finishElement(firstElement + f);
    }

    // Patches, their outlines, the back sheet.
    const std::map<int, int> groupPatch =
        makePatches(objIdx, firstElement, builder.faceGroup, builder.faceMaterial,
                    leaves ? std::min(patchSize, scene.settings.elementSize) : patchSize);
    outlinePlanarPatches(groupPatch, faces.groupOutline, M, builder.mirrored);
    addBackSheet(objIdx, firstPatch);
    for (int p = firstPatch; p < static_cast<int>(mPatches.size()); ++p) {
        finishPatch(p);
        mTotalArea += mPatches[p].area;
    }
}

std::map<int, int> Discretization::makePatches(int objIdx, int firstElement,
                                               const std::vector<int>& faceGroup,
                                               const std::vector<int>& faceMaterial,
                                               double patchSize) {
    // Gridded groups as given; mesh faces grown into regions over OpenMesh adjacency.
    const int faceCount = static_cast<int>(faceGroup.size());
    std::map<int, int> groupPatch;
    std::vector<int> facePatch(faceCount, -1);
    auto newPatch = [&](int material) {
        Patch p;
        p.object = objIdx;
        p.material = material;
        mPatches.push_back(std::move(p));
        return static_cast<int>(mPatches.size()) - 1;
    };
    for (int f = 0; f < faceCount; ++f) {
        int g = faceGroup[f];
        if (g < 0) continue;
        auto it = groupPatch.find(g);
        int p = it != groupPatch.end() ? it->second : (groupPatch[g] = newPatch(faceMaterial[f]));
        facePatch[f] = p;
    }
    const double targetArea = patchSize * patchSize;
    for (int seed = 0; seed < faceCount; ++seed) {
        if (facePatch[seed] >= 0) continue;
        int p = newPatch(faceMaterial[seed]);
        const Vec3 seedNormal = mElements[firstElement + seed].normal;
        double area = 0;
        std::vector<int> frontier{seed};
        facePatch[seed] = p;
        for (std::size_t k = 0; k < frontier.size() && area < targetArea; ++k) {
            int f = frontier[k];
            area += mElements[firstElement + f].area;
            for (auto ff : mObjects[objIdx].mesh.ff_range(FHandle(f))) {
                int g = ff.idx();
                if (g >= faceCount || facePatch[g] >= 0) continue;
                if (faceMaterial[g] != faceMaterial[seed]) continue;
                if (glm::dot(mElements[firstElement + g].normal, seedNormal) < kMeshPatchNormalCos)
                    continue;
                if (area >= targetArea) break;
                facePatch[g] = p;
                frontier.push_back(g);
            }
        }
        // Faces claimed but never expanded still belong to p (they were counted by claim).
    }
    for (int f = 0; f < faceCount; ++f) {
        int e = firstElement + f;
        mElements[e].patch = facePatch[f];
        mPatches[facePatch[f]].elements.push_back(e);
    }
    return groupPatch;
}

void Discretization::outlinePlanarPatches(const std::map<int, int>& groupPatch,
                                          std::map<int, std::vector<Vec3>>& groupOutline,
                                          const Mat4& worldFromObject, bool mirrored) {
    for (auto [group, patch] : groupPatch) {
        // A planar gridded patch integrates as one polygon (collapsed pole corners removed).
        Patch& P = mPatches[patch];
        bool planar = true;
        for (int e : P.elements)
            planar =
                planar && glm::dot(mElements[e].normal, mElements[P.elements[0]].normal) > 1 - 1e-9;
        if (!planar) continue;
        std::vector<Vec3> ring;
        if (mirrored) std::reverse(groupOutline[group].begin(), groupOutline[group].end());
        for (const Vec3& c : groupOutline[group]) {
            Vec3 w = transformPoint(worldFromObject, c);
            if (ring.empty() || glm::length(ring.back() - w) > 1e-12) ring.push_back(w);
        }
        while (ring.size() > 1 && glm::length(ring.back() - ring.front()) <= 1e-12) ring.pop_back();
        // Drop points in the middle of straight runs: fewer edges for the contour integral.
        for (std::size_t k = 0; k < ring.size() && ring.size() > 3;) {
            const Vec3& prev = ring[(k + ring.size() - 1) % ring.size()];
            const Vec3& next = ring[(k + 1) % ring.size()];
            Vec3 u = ring[k] - prev, v = next - ring[k];
            if (glm::length(glm::cross(u, v)) <= 1e-12 * glm::length(u) * glm::length(v) &&
                glm::dot(u, v) > 0)
                ring.erase(ring.begin() + static_cast<std::ptrdiff_t>(k));
            else
                ++k;
        }
        // Only a convex outline: sampling fans it from its first vertex.
        bool convex = ring.size() >= 3;
        Vec3 n0 = newellNormal(ring);
        for (std::size_t k = 0; convex && k < ring.size(); ++k) {
            const Vec3& a = ring[k];
            const Vec3& b = ring[(k + 1) % ring.size()];
            const Vec3& c = ring[(k + 2) % ring.size()];
            convex = glm::dot(glm::cross(b - a, c - b), n0) > -1e-12 * glm::dot(n0, n0);
        }
        if (convex) P.outline = std::move(ring);
    }
}

Material Discretization::backMaterial(const Material& front) {
    // The back of a two-sided surface reflects like its front; emission stays front-only.
    Material back = front;
    back.emission = Rgb(0.0);
    if (!front.twoSided) back.reflectance = Rgb(0.0);
    return back;
}

void Discretization::addBackSheet(int objIdx, int firstPatch) {
    // DESIGN.md: a two-sided material reflects on both sides. Its faces get twins on a back
    // sheet of their own vertices with reversed winding: elements and patches like any other
    // (normals flipped, no emission), not traced by Embree — RayTracer maps a hit on the back
    // of a front face to its twin.
    ObjectSurface& surface = mObjects[objIdx];
    const int lastPatch = static_cast<int>(mPatches.size());
    bool any = false;
    for (int p = firstPatch; p < lastPatch && !any; ++p)
        any = mMaterials[mPatches[p].material].twoSided;
    if (!any) return;
    surface.faceTwin.assign(surface.mesh.n_faces(), -1);
    surface.firstBackFace = static_cast<int>(surface.mesh.n_faces());
    std::map<int, VHandle> backVertex;  // front vertex -> its back-sheet copy
    std::map<int, int> backMaterialOf;
    for (int p = firstPatch; p < lastPatch; ++p) {
        const int frontMaterial = mPatches[p].material;
        if (!mMaterials[frontMaterial].twoSided) continue;
        auto m = backMaterialOf.find(frontMaterial);
        if (m == backMaterialOf.end())
            m = backMaterialOf
                    .insert({frontMaterial, addMaterial(backMaterial(mMaterials[frontMaterial]))})
                    .first;
        Patch back;
        back.object = objIdx;
        back.material = m->second;
        back.outline.assign(mPatches[p].outline.rbegin(), mPatches[p].outline.rend());
        const int q = static_cast<int>(mPatches.size());
        const std::vector<int> frontElements = mPatches[p].elements;
        mPatches.push_back(std::move(back));
        for (int e : frontElements) {
            std::vector<VHandle> vs;
            for (auto it = mElements[e].vertices.rbegin(); it != mElements[e].vertices.rend();
                 ++it) {
                auto found = backVertex.find(*it);
                if (found == backVertex.end()) {
                    // Copies first: add_vertex and push_back may reallocate.
                    const ElementMesh::Point p = surface.mesh.point(VHandle(*it));
                    const Vec3 world = surface.worldPositions[*it];
                    found = backVertex.insert({*it, surface.mesh.add_vertex(p)}).first;
                    surface.worldPositions.push_back(world);
                }
                vs.push_back(found->second);
            }
            FHandle f = surface.mesh.add_face(vs);
            if (!f.is_valid()) {  // a non-manifold spot: the twin stands alone
                for (VHandle& v : vs) {
                    const Vec3 world = surface.worldPositions[v.idx()];
                    const ElementMesh::Point p = surface.mesh.point(v);
                    v = surface.mesh.add_vertex(p);
                    surface.worldPositions.push_back(world);
                }
                f = surface.mesh.add_face(vs);
                if (!f.is_valid()) continue;
            }
            Element twin;
            twin.object = objIdx;
            twin.face = f.idx();
            twin.patch = q;
            for (VHandle v : vs) twin.vertices.push_back(v.idx());
            const int te = static_cast<int>(mElements.size());
            mElements.push_back(std::move(twin));
            finishElement(te);
            mPatches[q].elements.push_back(te);
            surface.faceElement.resize(surface.mesh.n_faces(), -1);
            surface.faceElement[f.idx()] = te;
            surface.faceTwin.resize(surface.mesh.n_faces(), -1);
            surface.faceTwin[mElements[e].face] = f.idx();
            surface.faceTwin[f.idx()] = mElements[e].face;
        }
        if (mPatches[q].elements.empty()) mPatches.pop_back();
    }
}

// ---------------------------------------------------------------------------------------------
// Queries

std::vector<Vec3> Discretization::elementPolygon(int element) const {
    const Element& el = mElements[element];
    const ObjectSurface& s = mObjects[el.object];
    std::vector<Vec3> poly;
    poly.reserve(el.vertices.size());
    for (int v : el.vertices) poly.push_back(s.worldPositions[v]);
    return poly;
}

std::vector<int> Discretization::elementNeighbours(int element) const {
    const Element& el = mElements[element];
    const ObjectSurface& s = mObjects[el.object];
    std::vector<int> out;
    for (int v : el.vertices)
        for (auto f : s.mesh.vf_range(VHandle(v))) {
            int e = s.faceElement[f.idx()];
            if (e >= 0 && e != element && std::find(out.begin(), out.end(), e) == out.end())
                out.push_back(e);
        }
    return out;
}

std::vector<Rgb> Discretization::vertexValues(int object,
                                              const std::vector<Rgb>& elementValue) const {
    const ObjectSurface& s = mObjects[object];
    std::vector<Rgb> out(s.mesh.n_vertices(), Rgb(0.0));
    for (auto v : s.mesh.vertices()) {
        Rgb sum(0.0);
        double w = 0;
        for (auto f : s.mesh.vf_range(v)) {
            int e = s.faceElement[f.idx()];
            if (e < 0) continue;
            sum += mElements[e].area * elementValue[e];
            w += mElements[e].area;
        }
        out[v.idx()] = w > 0 ? sum / w : sum;
    }
    return out;
}

// ---------------------------------------------------------------------------------------------
// Subdivision (Cohen et al. 1988 §3.4)

std::vector<int> Discretization::subdivideElement(int element) {
    Element parent = mElements[element];
    ObjectSurface& s = mObjects[parent.object];
    ElementMesh& mesh = s.mesh;
    const glm::dmat4 objectFromWorld = glm::inverse(s.worldFromObject);
    const std::size_t n = parent.vertices.size();
    if (n != 3 && n != 4) return {element};

    // Midpoint of each edge: reuse a vertex already inserted by a subdivided neighbour (it
    // lies on the edge, between the two corners, in the neighbour's polygon), else make one.
    auto midpoint = [&](int a, int b) -> int {
        Vec3 m = 0.5 * (s.worldPositions[a] + s.worldPositions[b]);
        double tol = 1e-9 * (1.0 + glm::length(m));
        for (auto f : mesh.vf_range(VHandle(a)))
            for (auto v : mesh.fv_range(f))
                if (glm::length(s.worldPositions[v.idx()] - m) < tol) return v.idx();
        VHandle h = mesh.add_vertex(toPoint(Vec3(objectFromWorld * glm::dvec4(m, 1.0))));
        s.worldPositions.push_back(m);
        return h.idx();
    };
    std::vector<int> corner = parent.vertices, mid(n);
    for (std::size_t k = 0; k < n; ++k) mid[k] = midpoint(corner[k], corner[(k + 1) % n]);

    // New polygons.
    std::vector<std::vector<int>> polys;
    if (n == 3) {
        polys = {{corner[0], mid[0], mid[2]},
                 {mid[0], corner[1], mid[1]},
                 {mid[2], mid[1], corner[2]},
                 {mid[0], mid[1], mid[2]}};
    } else {
        Vec3 c(0.0);
        for (int v : corner) c += s.worldPositions[v];
        c /= 4.0;
        VHandle h = mesh.add_vertex(toPoint(Vec3(objectFromWorld * glm::dvec4(c, 1.0))));
        s.worldPositions.push_back(c);
        int centre = h.idx();
        for (int k = 0; k < 4; ++k) polys.push_back({corner[k], mid[k], centre, mid[(k + 3) % 4]});
    }

    // Neighbours across each edge get the midpoint inserted (keeps the mesh conforming).
    auto insertIntoNeighbours = [&](int a, int b, int m) {
        for (int e = 0; e < static_cast<int>(mElements.size()); ++e) {
            if (e == element || mElements[e].object != parent.object) continue;
            std::vector<int>& vs = mElements[e].vertices;
            for (std::size_t k = 0; k < vs.size(); ++k) {
                int u = vs[k], w = vs[(k + 1) % vs.size()];
                if ((u == b && w == a) || (u == a && w == b)) {
                    vs.insert(vs.begin() + k + 1, m);
                    break;
                }
            }
        }
    };
    for (std::size_t k = 0; k < n; ++k)
        insertIntoNeighbours(corner[k], corner[(k + 1) % n], mid[k]);

    // Rebuild the object's OpenMesh faces from the element polygons (topology changed).
    ElementMesh rebuilt;
    for (auto v : mesh.vertices()) rebuilt.add_vertex(mesh.point(v));
    std::vector<int> result{element};
    mElements[element].vertices = polys[0];
    for (std::size_t k = 1; k < polys.size(); ++k) {
        Element child = parent;
        child.vertices = polys[k];
        mElements.push_back(child);
        int idx = static_cast<int>(mElements.size()) - 1;
        result.push_back(idx);
        mPatches[parent.patch].elements.push_back(idx);
    }
    s.faceElement.clear();
    for (int e = 0; e < static_cast<int>(mElements.size()); ++e) {
        if (mElements[e].object != parent.object) continue;
        std::vector<VHandle> hs;
        for (int v : mElements[e].vertices) hs.push_back(VHandle(v));
        FHandle f = rebuilt.add_face(hs);
        if (!f.is_valid()) {
            std::vector<VHandle> copy;
            for (VHandle v : hs) copy.push_back(rebuilt.add_vertex(rebuilt.point(v)));
            f = rebuilt.add_face(copy);
            // The copies keep their world positions.
            for (VHandle v : hs) s.worldPositions.push_back(s.worldPositions[v.idx()]);
            for (std::size_t k = 0; k < copy.size(); ++k) mElements[e].vertices[k] = copy[k].idx();
        }
        mElements[e].face = f.idx();
        if (static_cast<int>(s.faceElement.size()) <= f.idx())
            s.faceElement.resize(f.idx() + 1, -1);
        s.faceElement[f.idx()] = e;
    }
    mesh = std::move(rebuilt);
    for (int e : result) finishElement(e);
    return result;
}

std::pair<int, int> Discretization::elementRange(int object) const {
    int lo = std::numeric_limits<int>::max(), hi = -1;
    for (int e : mObjects[object].faceElement)
        if (e >= 0) lo = std::min(lo, e), hi = std::max(hi, e);
    return hi < 0 ? std::pair<int, int>{0, 0} : std::pair<int, int>{lo, hi - lo + 1};
}

bool Discretization::sameElements(int a, int b) const {
    const int n = static_cast<int>(mObjects.size());
    if (a < 0 || b < 0 || a >= n || b >= n) return false;
    const ObjectSurface& x = mObjects[a];
    const ObjectSurface& y = mObjects[b];
    return x.id == y.id && x.faceElement.size() == y.faceElement.size() &&
           elementRange(a).second == elementRange(b).second && elementRange(a).second > 0;
}

}  // namespace penumbra
