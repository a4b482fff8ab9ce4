#pragma once
// File names as the readers and writers of every module choose a format by them, and the
// path of an executable installed beside the running one.

#include <string>

namespace penumbra {

/// The extension of `path`'s file name with its dot, in lower case (ASCII): ".gltf" for
/// "Scene.GLTF", "" when there is none.
std::string lowerExtension(const std::string& path);

/// The executable `name` in the folder of the running one (penumbra and penumbra-bench are
/// built and installed side by side).
std::string siblingExecutable(const std::string& name);

}  // namespace penumbra
