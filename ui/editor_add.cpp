// EditorApp's Add menu: the library of primitives and meshes (ui/mesh_library.h), where a new
// object goes (the surface under the viewport's centre), and the add itself.

#include <algorithm>
#include <filesystem>
#include <optional>

#include "edit/io/mesh_io.h"
#include "ui/editor_app.h"

namespace penumbra {

void EditorApp::refreshMeshLibrary() {
    namespace fs = std::filesystem;
    std::string source = findSourceDir(fs::current_path().string());
    if (source.empty() && !mScenePath.empty()) source = findSourceDir(mScenePath);
    mMeshLibrary = listMeshes(meshLibraryRoots(mScenePath, source));
}

PlacementTarget EditorApp::addTarget() {
    Vec3 origin = mView.position(), direction = mView.forward();
    std::optional<Vec3> hit, right, down;
    if (mRunner && mViewportW > 0 && mViewportH > 0) {
        const Camera camera = mView.toCamera();
        const double cx = 0.5 * mViewportW, cy = 0.5 * mViewportH;
        const double step = std::max(2.0, 0.01 * mViewportH);
        const Ray ray = pixelRay(camera, mViewportW, mViewportH, cx, cy);
        origin = ray.origin, direction = ray.direction;
        const Pick centre = mRunner->pick(camera, mViewportW, mViewportH, cx, cy);
        if (centre.hit()) {
            hit = centre.position;
            // Neighbours on the same object give the surface's plane.
            const Pick r = mRunner->pick(camera, mViewportW, mViewportH, cx + step, cy);
            const Pick d = mRunner->pick(camera, mViewportW, mViewportH, cx, cy + step);
            if (r.hit() && r.id == centre.id) right = r.position;
            if (d.hit() && d.id == centre.id) down = d.position;
        }
    }
    return placementTarget(origin, direction, hit, right, down, std::max(mView.distance, 0.5));
}

std::string EditorApp::addFromLibrary(const LibraryEntry& entry) {
    if (!mRunner || mDrag.active()) return "";
    const auto doc = mRunner->document();
    if (!doc) return "";
    const std::string material = defaultMaterial(doc->materials);
    const std::string id = uniqueObjectId(
        entry.type == ShapeType::Mesh ? entry.path : entry.label, [&](const std::string& name) {
            // Ids given out but not yet in the document (a queued add) count.
            return doc->find(name) != nullptr || mIssuedIds.count(name) > 0;
        });
    mIssuedIds.insert(id);
    const PlacementTarget target = addTarget();
    if (entry.type != ShapeType::Mesh) {
        if (material.empty()) {
            mStatus = "the scene has no material for a new object";
            return "";
        }
        SceneObject o;
        o.id = id;
        o.shape = makePrimitive(entry.type, kPrimitiveSize);
        o.material = material;
        o.transform = placeInBox(shapeBounds(o.shape), kPrimitiveSize, target);
        submit(AddCommand{o});
    } else {
        // Loaded on the solver thread (a large mesh takes a while), named relative to the
        // scene file as scene files and logs name meshes.
        const std::string file = entry.path;
        const std::string relative = sceneRelativePath(file, mScenePath);
        mRunner->submitMade([id, file, relative, material, target](EditSession&) -> EditCommand {
            SceneObject o;
            o.id = id;
            o.shape.type = ShapeType::Mesh;
            o.shape.file = relative;
            o.shape.mesh = loadMeshFile(file);
            if (o.shape.mesh.triangleMaterial.empty()) o.material = material;
            o.transform = placeInBox(shapeBounds(o.shape), kMeshSize, target);
            return AddCommand{std::move(o)};
        });
    }
    mSelection = id;
    mStatus = "added " + id;
    return id;
}

}  // namespace penumbra
