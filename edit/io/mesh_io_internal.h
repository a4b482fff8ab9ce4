#pragma once
// Mesh reading's internals shared by its translation units (mesh_io.cpp, mesh_io_off_ply.cpp):
// the polygon soup a reader fills and the strict OFF and PLY readers. Include only from those.

#include <cstddef>
#include <string>
#include <vector>

#include "solver/scene.h"

namespace penumbra::mesh_io_detail {

/// Faces as the file states them, before triangulation and cleanup.
struct PolygonSoup {
    std::vector<Vec3> positions;
    std::vector<int> indices;          ///< all faces' vertex indices, concatenated
    std::vector<size_t> faceStart{0};  ///< face f is indices[faceStart[f], faceStart[f+1])
    std::vector<int> faceMaterial;     ///< per face, index into materials or -1
    std::vector<Material> materials;
    std::vector<std::string> materialNames;

    size_t faceCount() const { return faceStart.size() - 1; }

    void addFace(const int* vertices, size_t count, int material) {
        indices.insert(indices.end(), vertices, vertices + count);
        faceStart.push_back(indices.size());
        faceMaterial.push_back(material);
    }
};

/// OFF and PLY (ASCII and binary), strict: one InputError naming the file and what is wrong.
PolygonSoup readOff(const std::string& path);
PolygonSoup readPly(const std::string& path);

}  // namespace penumbra::mesh_io_detail
