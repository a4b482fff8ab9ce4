// A libFuzzer target over one of the parsers that read what users hand Penumbra (issue 26):
// PENUMBRA_FUZZ_KIND picks the scene file (loadScene), the edit log (readEditLog), a mesh file
// (loadMeshFile; PENUMBRA_FUZZ_EXT names its format: obj, off, ply, gltf, glb), an imported
// scene (importScene; .gltf, .glb or .obj) or a holodeck file (HoloFile: opened for writing,
// which repairs a torn tail, and every stored beam read). The parsers read paths, as users give them, so each
// input is written to a file of its own in a private folder first. A parser returns or throws
// InputError (the one error for bad input, reported as one line and exit status 2); any other
// exception, a crash or a sanitizer report is a finding. scripts/fuzz.sh builds and runs these.

#include <unistd.h>

#include <cstddef>
#include <cstdint>
#include <filesystem>
#include <fstream>
#include <string>

#include "core/input_error.h"
#include "edit/edit_log.h"
#include "edit/io/mesh_io.h"
#include "edit/io/scene_import.h"
#include "edit/io/scene_io.h"
#include "render/holodeck/holo_file.h"

#define PENUMBRA_FUZZ_SCENE 1
#define PENUMBRA_FUZZ_LOG 2
#define PENUMBRA_FUZZ_MESH 3
#define PENUMBRA_FUZZ_IMPORT 4
#define PENUMBRA_FUZZ_HOLODECK 5

namespace {

/// The input's file: in a folder of this process's own (RAM-backed when /dev/shm exists).
const std::string& inputPath() {
    static const std::string path = [] {
        namespace fs = std::filesystem;
        const fs::path base =
            fs::exists("/dev/shm") ? fs::path("/dev/shm") : fs::temp_directory_path();
        const fs::path dir = base / ("penumbra-fuzz-" + std::to_string(::getpid()));
        fs::create_directories(dir);
        return (dir / ("input." PENUMBRA_FUZZ_EXT)).string();
    }();
    return path;
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
    const std::string& path = inputPath();
    {
        std::ofstream out(path, std::ios::binary | std::ios::trunc);
        out.write(reinterpret_cast<const char*>(data), static_cast<std::streamsize>(size));
    }
    try {
#if PENUMBRA_FUZZ_KIND == PENUMBRA_FUZZ_SCENE
        (void)penumbra::loadScene(path);
#elif PENUMBRA_FUZZ_KIND == PENUMBRA_FUZZ_LOG
        (void)penumbra::readEditLog(path);
#elif PENUMBRA_FUZZ_KIND == PENUMBRA_FUZZ_MESH
        (void)penumbra::loadMeshFile(path);
#elif PENUMBRA_FUZZ_KIND == PENUMBRA_FUZZ_IMPORT
        (void)penumbra::importScene(path);
#elif PENUMBRA_FUZZ_KIND == PENUMBRA_FUZZ_HOLODECK
        penumbra::HoloFile file(path, {});
        for (const auto& [section, beam] : file.storedBeams()) (void)file.readBeam(section, beam);
        (void)file.info();
#else
#error "PENUMBRA_FUZZ_KIND must name a parser"
#endif
    } catch (const penumbra::InputError&) {
        // Refused with one clear line: the expected answer to most inputs.
    }
    return 0;
}
