#pragma once
// The command-line flags of a glTF/OBJ import (edit/io/scene_import.h), shared by `penumbra` and
// `penumbra-editor`.

#include <CLI/CLI.hpp>
#include <map>
#include <string>

#include "edit/io/scene_import.h"

namespace penumbra {

/// --emission-scale, --light-size and --units into `import`.
inline void addImportFlags(CLI::App* cmd, ImportOptions& import) {
    cmd->add_option("--emission-scale", import.emissionScale,
                    "glTF/OBJ: multiply emission by S (emission = pi x emissive x S; default 1)")
        ->check(CLI::NonNegativeNumber);
    cmd->add_option("--light-size", import.lightRadius,
                    "glTF: radius in metres of the sphere standing for a point light (default "
                    "0.05)")
        ->check(CLI::PositiveNumber);
    cmd->add_option("--units", import.objUnit, "OBJ: file units, mm, cm or m (default m)")
        ->transform(CLI::CheckedTransformer(
            std::map<std::string, double>{{"mm", 0.001}, {"cm", 0.01}, {"m", 1.0}}));
}

}  // namespace penumbra
