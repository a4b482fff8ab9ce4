// glTF / OBJ scene import.
// Index: names · materials · objects · lights and cameras · importScene

#include "edit/io/scene_import.h"

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <limits>
#include <map>
#include <nlohmann/json.hpp>
#include <set>
#include <sstream>

#include "core/file_name.h"
#include "core/input_error.h"
#include "core/log.h"
#include "edit/io/mesh_io.h"
#include "edit/io/scene_io.h"
#include "solver/discretization.h"

namespace penumbra {

namespace {

constexpr double kMaxReflectance = 0.99;
/// glTF light intensities are photometric (candela, lm/sr); Penumbra's emission is in watts.
/// 683 lm per W (the luminous efficacy at 555 nm) is the factor Blender's glTF exporter and
/// importer use both ways, so a Blender light of P watts imports with P watts.
constexpr double kLumensPerWatt = 683.0;
/// Receivers an imported scene is discretized into, about (Importer::chooseSettings).
constexpr double kTargetElements = 16000;

std::string rgbText(const Rgb& c) {
    std::ostringstream out;
    out << '(' << c.x << ", " << c.y << ", " << c.z << ')';
    return out.str();
}

/// Extras JSON text → object ({} when empty or not an object).
nlohmann::json parseExtras(const std::string& text) {
    if (text.empty()) return nlohmann::json::object();
    nlohmann::json j = nlohmann::json::parse(text, nullptr, false);
    return j.is_object() ? j : nlohmann::json::object();
}

bool readRgb(const nlohmann::json& j, const char* key, Rgb& out) {
    if (!j.contains(key) || !j[key].is_array() || j[key].size() != 3) return false;
    for (int c = 0; c < 3; ++c) {
        if (!j[key][c].is_number()) return false;
        out[c] = j[key][c].get<double>();
        if (!std::isfinite(out[c])) return false;
    }
    return true;
}

/// Unique names: the first use of a name keeps it, later ones get "-2", "-3", ...
class NameSet {
public:
    std::string take(std::string name, const std::string& fallback) {
        if (name.empty()) name = fallback;
        std::string candidate = name;
        for (int k = 2; mUsed.count(candidate); ++k) candidate = name + "-" + std::to_string(k);
        mUsed.insert(candidate);
        return candidate;
    }

private:
    std::set<std::string> mUsed;
};

struct Importer {
    Importer(const std::string& path, const ImportOptions& options)
        : path(path), options(options) {}

    const std::string& path;
    const ImportOptions& options;
    Scene scene;
    NameSet materialNames, objectIds, cameraNames;
    std::vector<std::string> materialOf;  ///< file material → scene material name ("" unused)
    MeshFileScene file;

    void warn(const std::string& what) const {
        if (options.warn)
            options.warn("warning: " + path + ": " + what);
        else
            spdlog::warn("{}: {}", path, what);
    }

    Material convert(const MeshFileMaterial& m, const std::string& name) const {
        Material out;
        Rgb reflectance = m.baseColor;
        bool clamped = false;
        for (int c = 0; c < 3; ++c) {
            const double v = std::isfinite(reflectance[c]) ? reflectance[c] : 0.0;
            const double r = std::clamp(v, 0.0, kMaxReflectance);
            clamped = clamped || r != reflectance[c];
            reflectance[c] = r;
        }
        if (clamped)
            warn("material '" + name + "': base colour " + rgbText(m.baseColor) +
                 " clamped to reflectance " + rgbText(reflectance) +
                 " (a diffuse surface reflects less than all the light it receives)");
        if (m.textured)
            warn("material '" + name + "': its base colour texture is not read; the factor " +
                 rgbText(m.baseColor) + " alone is the reflectance");
        out.reflectance = reflectance;
        // The file's emissive value is radiance-like (what a viewer shows a surface with);
        // Penumbra's emission is the radiosity leaving it, π times the radiance.
        Rgb emission = M_PI * m.emissive * options.emissionScale;
        const nlohmann::json extras = parseExtras(m.extras);
        Rgb exact;
        if (readRgb(extras, "emission", exact)) emission = exact;  // Penumbra's own export
        for (int c = 0; c < 3; ++c)
            if (!std::isfinite(emission[c]) || emission[c] < 0) emission[c] = 0;
        out.emission = emission;
        out.twoSided = m.doubleSided;
        return out;
    }

    /// The scene material for file material `index` (-1: the default), added on first use.
    std::string sceneMaterial(int index) {
        if (index < 0) {
            if (mDefault.empty()) {
                mDefault = materialNames.take("default", "default");
                scene.materials.push_back({mDefault, Material{}});
            }
            return mDefault;
        }
        if (materialOf[index].empty()) {
            const MeshFileMaterial& m = file.materials[index];
            const std::string name =
                materialNames.take(m.name, "material-" + std::to_string(index));
            scene.materials.push_back({name, convert(m, name)});
            materialOf[index] = name;
        }
        return materialOf[index];
    }

    /// A named material from Penumbra's export extras (reflectance, emission exact).
    std::string extrasMaterial(const nlohmann::json& extras) {
        Rgb reflectance;
        if (!readRgb(extras, "reflectance", reflectance)) return "";
        Material m;
        m.reflectance = glm::clamp(reflectance, Rgb(0.0), Rgb(kMaxReflectance));
        Rgb emission(0.0);
        if (readRgb(extras, "emission", emission)) m.emission = glm::max(emission, Rgb(0.0));
        std::string name = extras.contains("material") && extras["material"].is_string()
                               ? extras["material"].get<std::string>()
                               : std::string();
        // The same name and values as a material already made: shared.
        for (const NamedMaterial& existing : scene.materials)
            if (existing.name == name && existing.material.reflectance == m.reflectance &&
                existing.material.emission == m.emission)
                return name;
        name = materialNames.take(name, "material");
        scene.materials.push_back({name, m});
        return name;
    }

    void addPart(MeshFilePart& part, double unit) {
        const nlohmann::json extras = parseExtras(part.extras);
        std::string id = extras.contains("penumbra_id") && extras["penumbra_id"].is_string()
                             ? extras["penumbra_id"].get<std::string>()
                             : part.name;
        SceneObject object;
        object.id = objectIds.take(id, "object");
        object.shape.type = ShapeType::Mesh;
        TriMesh& mesh = part.mesh;
        Vec3 lo(std::numeric_limits<double>::infinity()), hi(-lo);
        for (Vec3& p : mesh.positions) {
            p *= unit;
            lo = glm::min(lo, p);
            hi = glm::max(hi, p);
        }
        const Vec3 centre = 0.5 * (lo + hi);
        for (Vec3& p : mesh.positions) p -= centre;
        object.transform.translate = centre;
        const std::string fromExtras = extrasMaterial(extras);
        if (!fromExtras.empty() && extras.contains("object") && extras["object"].is_object()) {
            // Penumbra's own export of a primitive shape: the object as its scene file had it
            // (a box, not the box's element triangles).
            nlohmann::json source = extras["object"];
            source["id"] = object.id;
            source["material"] = fromExtras;
            scene.objects.push_back(
                objectFromJson(source, scene, path, "node '" + part.name + "' extras.object", ""));
            return;
        }
        std::set<int> used(part.triangleMaterial.begin(), part.triangleMaterial.end());
        if (!fromExtras.empty()) {
            object.material = fromExtras;
        } else if (used.size() <= 1) {
            object.material = sceneMaterial(used.empty() ? -1 : *used.begin());
        } else {
            // Several materials: the mesh carries them per triangle.
            std::map<int, int> local;
            for (int m : used) {
                local[m] = static_cast<int>(mesh.materials.size());
                const std::string name = sceneMaterial(m);
                mesh.materials.push_back(*scene.findMaterial(name));
                mesh.materialNames.push_back(name);
            }
            mesh.triangleMaterial.resize(part.triangleMaterial.size());
            for (std::size_t t = 0; t < part.triangleMaterial.size(); ++t)
                mesh.triangleMaterial[t] = local[part.triangleMaterial[t]];
        }
        object.shape.mesh = std::move(mesh);
        scene.objects.push_back(std::move(object));
    }

    /// Element and shooter sizes: the smallest element size at which the solver makes at most
    /// kTargetElements receivers of the meshes' fronts and the point lights' spheres, whatever
    /// the scene's scale (the defaults' 0.1 m would give a large hall millions). Counted as the
    /// solver splits them, not from the area: a triangle whose longest edge is n element sizes
    /// becomes n² elements, so a quad made of two triangles gives about four times its area's
    /// share. A two-sided material's back sheet doubles its faces but is not counted: the same
    /// room from OBJ (one-sided) and from glTF (two-sided, as Blender writes it) gets the same
    /// size. Rounded up to two significant digits (0.16, not 0.1573...).
    void chooseSettings() {
        // What is counted: the meshes' fronts (the scene itself: its settings are set below
        // anyway) and the lights' spheres.
        Scene lights;
        double area = 0;
        for (const SceneObject& o : scene.objects) {
            const TriMesh& m = o.shape.mesh;
            const glm::dmat3 linear(o.transform.worldFromObject());
            for (const auto& t : m.triangles) {
                const Vec3 p0 = linear * m.positions[t[0]];
                area += 0.5 * glm::length(glm::cross(linear * m.positions[t[1]] - p0,
                                                     linear * m.positions[t[2]] - p0));
            }
        }
        for (const MeshFileLight& light : file.lights)
            if (light.type != "directional") {
                lights.objects.push_back(lightObject(light));
                area += 4 * M_PI * options.lightRadius * options.lightRadius;
            }
        if (!(area > 0)) return;
        auto elementsAt = [&](double size) {
            for (Scene* counted : {&scene, &lights}) {
                counted->settings.elementSize = size;
                counted->settings.patchSize = 4 * size;
            }
            try {
                return Discretization::countElements(scene) + Discretization::countElements(lights);
            } catch (const std::invalid_argument&) {
                return std::numeric_limits<double>::infinity();  // too fine for some object
            }
        };
        auto twoDigitsUp = [](double size) {
            // Divided, not multiplied, by the power of ten below 1 so the value prints as
            // written.
            const double unit = std::pow(10.0, std::floor(std::log10(size)) - 1);
            const double steps = std::ceil(size / unit - 1e-9);
            return unit < 1 ? steps / std::round(1 / unit) : steps * unit;
        };
        // The count falls as the size grows; it reaches the target between a quarter and four
        // times the size that would share the area out evenly, unless the meshes' own triangles
        // already outnumber it (then the largest: every triangle one element).
        const double even = std::sqrt(area / kTargetElements);
        double lo = even / 4, hi = 4 * even;
        if (elementsAt(hi) <= kTargetElements) {
            for (int i = 0; i < 40 && hi - lo > 1e-3 * hi; ++i) {
                const double mid = 0.5 * (lo + hi);
                (elementsAt(mid) <= kTargetElements ? hi : lo) = mid;
            }
        }
        scene.settings.elementSize = twoDigitsUp(hi);
        scene.settings.patchSize = 4 * scene.settings.elementSize;
    }

    /// The surface area the solver gives `object` with the scene's settings (its elements').
    double facetedArea(const SceneObject& object, const Material& material) const {
        Scene one;
        one.settings = scene.settings;
        one.materials.push_back({object.material, material});
        one.objects.push_back(object);
        const Discretization disc(one);
        double area = 0;
        for (const Element& e : disc.elements()) area += e.area;
        return area;
    }

    /// A point light's sphere, without its id and material.
    SceneObject lightObject(const MeshFileLight& light) const {
        SceneObject object;
        object.shape.type = ShapeType::Sphere;
        object.shape.radius = options.lightRadius;
        object.shape.segments = 16;
        object.transform.translate = light.position;
        object.patchSize = 2 * options.lightRadius;
        return object;
    }

    void addLight(const MeshFileLight& light) {
        if (light.type == "directional") {
            warn("light '" + light.name +
                 "': directional lights have no place or area to emit from; ignored");
            return;
        }
        if (light.type == "spot")
            warn("light '" + light.name +
                 "': a spot light's cone is not modelled; it emits in every direction as a "
                 "point light of the same intensity");
        // A point light of intensity I (candela) sends Φ = 4πI lumens, 4πI / 683 watts, in
        // all; a sphere emitting E from its surface sends E × its area. Its area as the solver
        // facets it (a little less than 4πr²) gives it exactly the light's power.
        const Rgb power = glm::max(
            4 * M_PI * light.colour * light.intensity / kLumensPerWatt * options.emissionScale,
            Rgb(0.0));
        const std::string name = light.name.empty() ? "light" : light.name;
        SceneObject object = lightObject(light);
        object.id = objectIds.take("light-" + name, "light");
        Material m;
        m.reflectance = Rgb(0.0);
        m.emission = Rgb(1.0);
        object.material = materialNames.take("light-" + name, "light");
        try {
            m.emission = power / facetedArea(object, m);
        } catch (const std::invalid_argument& e) {
            // The light's sphere at the element size the meshes' area chose.
            throw InputError(path, "light '" + name + "'", e.what());
        }
        scene.materials.push_back({object.material, m});
        scene.objects.push_back(std::move(object));
    }

    void addCamera(const MeshFileCamera& camera) {
        if (!camera.perspective) {
            warn("camera '" + camera.name + "': orthographic cameras are not supported; ignored");
            return;
        }
        Camera c;
        c.name = cameraNames.take(camera.name, "camera");
        c.position = camera.position;
        c.lookAt = camera.position + glm::normalize(camera.forward);
        c.up = glm::normalize(camera.up);
        c.fovDeg = camera.yfovDeg;
        scene.cameras.push_back(c);
    }

    Scene run() {
        const bool obj = lowerExtension(path) == ".obj";
        file = loadMeshFileScene(path);
        for (const std::string& what : file.ignored) warn("ignored: " + what);
        materialOf.assign(file.materials.size(), "");
        for (MeshFilePart& part : file.parts) addPart(part, obj ? options.objUnit : 1.0);
        // Penumbra's own export carries the scene's settings; otherwise sizes from the area.
        const nlohmann::json asset = parseExtras(file.assetExtras);
        const bool exported = asset.contains("settings") && asset["settings"].is_object() &&
                              asset["settings"].value("patch_size", 0.0) > 0 &&
                              asset["settings"].value("element_size", 0.0) > 0;
        if (exported) {
            scene.settings.patchSize = asset["settings"]["patch_size"].get<double>();
            scene.settings.elementSize = asset["settings"]["element_size"].get<double>();
        } else {
            chooseSettings();
        }
        for (const MeshFileLight& light : file.lights) addLight(light);
        for (const MeshFileCamera& camera : file.cameras) addCamera(camera);
        const bool lit = std::any_of(scene.materials.begin(), scene.materials.end(),
                                     [](const NamedMaterial& m) { return m.material.isEmitter(); });
        if (!lit)
            warn("nothing emits light (no emissive material, no point light): the scene is dark");
        return std::move(scene);
    }

private:
    std::string mDefault;
};

}  // namespace

bool isImportableScene(const std::string& path) {
    const std::string e = lowerExtension(path);
    return e == ".gltf" || e == ".glb" || e == ".obj";
}

Scene importScene(const std::string& path, const ImportOptions& options) {
    if (!(options.emissionScale >= 0) || !std::isfinite(options.emissionScale))
        throw InputError(path, "", "the emission scale must be a finite number >= 0");
    if (!(options.lightRadius > 0) || !std::isfinite(options.lightRadius))
        throw InputError(path, "", "the light size must be a finite number > 0");
    if (!(options.objUnit > 0) || !std::isfinite(options.objUnit))
        throw InputError(path, "", "the unit must be a finite number > 0");
    Importer importer(path, options);
    return importer.run();
}

}  // namespace penumbra
