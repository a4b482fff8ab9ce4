#pragma once
// File names as the readers and writers of every module choose a format by them.

#include <string>

namespace penumbra {

/// The extension of `path`'s file name with its dot, in lower case (ASCII): ".gltf" for
/// "Scene.GLTF", "" when there is none.
std::string lowerExtension(const std::string& path);

}  // namespace penumbra
