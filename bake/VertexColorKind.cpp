#include "bake/VertexColorKind.h"

#include "bake/ReceiverKind.h"
#include "bake/Scene.h"
#include "stream/AtomicFile.h"
#include "stream/Error.h"
#include "stream/GltfModel.h"

#include <tiny_gltf.h>

#include <glm/geometric.hpp>
#include <glm/mat3x3.hpp>
#include <glm/matrix.hpp>

#include <algorithm>
#include <cstring>
#include <filesystem>
#include <map>
#include <sstream>

namespace penumbra {
namespace {

/// One triangle primitive that contributes receivers: its vertices are receivers
/// [first, first + count) of the kind's ReceiverSet.
struct PrimitiveRange {
    int mesh = 0, primitive = 0;
    size_t first = 0, count = 0;
};

/// One "meshes" entry: a glTF file, its model (kept for writing the copy) and its receivers.
struct VertexFile {
    size_t entry = 0;  ///< index into the scene's geometry list
    std::string input, output, where;
    glm::dmat4 sceneMatrix{1.0};
    tinygltf::Model model;
    std::vector<PrimitiveRange> primitives;
};

std::string lowerExtension(const std::string& path) {
    std::string ext = std::filesystem::path(path).extension().string();
    for (char& c : ext) c = char(std::tolower(static_cast<unsigned char>(c)));
    return ext;
}

/// Corner indices (into the vertex list) of triangle t of a primitive drawn in @p mode.
void corners(int mode, uint64_t t, uint64_t c[3]) {
    if (mode == TINYGLTF_MODE_TRIANGLE_STRIP) c[0] = t, c[1] = t + 1 + t % 2, c[2] = t + 2 - t % 2;
    else if (mode == TINYGLTF_MODE_TRIANGLE_FAN) c[0] = t + 1, c[1] = t + 2, c[2] = 0;
    else c[0] = 3 * t, c[1] = 3 * t + 1, c[2] = 3 * t + 2;
}

/// Adds receivers for one primitive placed by @p world. Positions are read through the shared
/// validated accessor views; the checks here are the ones specific to reading vertex attributes.
void addPrimitive(VertexFile& file, const std::vector<GltfAccessorView>& accessors, int m, int p,
                  const glm::dmat4& world, ReceiverSet& out) {
    const tinygltf::Primitive& prim = file.model.meshes[size_t(m)].primitives[size_t(p)];
    const std::string where = fmt::format("{}: mesh {} primitive {}", file.input, m, p);
    const int mode = prim.mode < 0 ? TINYGLTF_MODE_TRIANGLES : prim.mode;
    if (mode != TINYGLTF_MODE_TRIANGLES && mode != TINYGLTF_MODE_TRIANGLE_STRIP && mode != TINYGLTF_MODE_TRIANGLE_FAN)
        return;  // points and lines carry no surface to shade
    auto attribute = [&](const char* name) -> const GltfAccessorView* {
        auto it = prim.attributes.find(name);
        if (it == prim.attributes.end()) return nullptr;
        if (it->second < 0 || size_t(it->second) >= accessors.size())
            fail(where, "attribute {} refers to accessor {} (file has {})", name, it->second, accessors.size());
        const GltfAccessorView& v = accessors[size_t(it->second)];
        if (v.components != 3 || v.sparse || (!v.data && v.count > 0) ||
            v.componentType == TINYGLTF_COMPONENT_TYPE_INT || v.componentType == TINYGLTF_COMPONENT_TYPE_UNSIGNED_INT)
            fail(where, "attribute {} (accessor {}) must be a dense VEC3 of floats or quantized integers", name,
                 it->second);
        return &v;
    };
    const GltfAccessorView* positions = attribute("POSITION");
    if (!positions) return;  // not rendered, per the spec
    const GltfAccessorView* normals = attribute("NORMAL");
    const size_t n = positions->count;
    if (normals && normals->count != n)
        fail(where, "NORMAL has {} elements but POSITION has {}", normals->count, n);

    // The vertex sequence in drawing order, checked against the vertex count.
    std::vector<uint32_t> sequence;
    if (prim.indices >= 0) {
        if (size_t(prim.indices) >= accessors.size())
            fail(where, "indices refer to accessor {} (file has {})", prim.indices, accessors.size());
        const GltfAccessorView& iv = accessors[size_t(prim.indices)];
        if (iv.components != 1 || iv.sparse ||
            (iv.componentType != TINYGLTF_COMPONENT_TYPE_UNSIGNED_BYTE &&
             iv.componentType != TINYGLTF_COMPONENT_TYPE_UNSIGNED_SHORT &&
             iv.componentType != TINYGLTF_COMPONENT_TYPE_UNSIGNED_INT))
            fail(where, "indices accessor {} must be a dense SCALAR of unsigned integers", prim.indices);
        sequence.resize(iv.count);
        for (size_t i = 0; i < iv.count; ++i) {
            sequence[i] = readGltfIndex(iv, i);
            if (sequence[i] >= n) fail(where, "index {} at element {} is past the {} vertices", sequence[i], i, n);
        }
    } else {
        sequence.resize(n);
        for (size_t i = 0; i < n; ++i) sequence[i] = uint32_t(i);
    }

    const glm::dmat3 linear(world);
    const glm::dmat3 normalMatrix = glm::transpose(glm::inverse(linear));
    const bool mirrored = glm::determinant(linear) < 0;
    const size_t first = out.position.size();
    out.position.resize(first + n);
    out.normal.resize(first + n, glm::vec3(0.f));
    for (size_t v = 0; v < n; ++v) {
        glm::dvec3 x = world * glm::dvec4(glm::dvec3(readGltfElement(*positions, v)), 1.0);
        if (!std::isfinite(x.x) || !std::isfinite(x.y) || !std::isfinite(x.z))
            fail(where, "vertex {} is not finite after its transforms", v);
        out.position[first + v] = glm::vec3(x);
        if (normals) {
            glm::dvec3 nn = normalMatrix * glm::dvec3(readGltfElement(*normals, v));
            double len = glm::length(nn);
            // A zero normal means "no receiver cosine" (ReceiverShading), the honest fallback.
            if (len > 0 && std::isfinite(len)) out.normal[first + v] = glm::vec3(nn / len);
        }
    }
    if (!normals) {
        // Area-weighted face normals: the unnormalized cross product is twice the area.
        std::vector<glm::dvec3> sum(n, glm::dvec3(0.0));
        const uint64_t triangles = mode == TINYGLTF_MODE_TRIANGLES ? sequence.size() / 3
                                   : sequence.size() >= 3          ? sequence.size() - 2
                                                                   : 0;
        for (uint64_t t = 0; t < triangles; ++t) {
            uint64_t c[3];
            corners(mode, t, c);
            const uint32_t a = sequence[c[0]], b = sequence[c[1]], d = sequence[c[2]];
            glm::dvec3 pa(out.position[first + a]), pb(out.position[first + b]), pd(out.position[first + d]);
            // World-space winding of a mirrored node is reversed; its front face is not.
            glm::dvec3 face = glm::cross(pb - pa, pd - pa) * (mirrored ? -1.0 : 1.0);
            sum[a] += face, sum[b] += face, sum[d] += face;
        }
        for (size_t v = 0; v < n; ++v) {
            double len = glm::length(sum[v]);
            if (len > 0 && std::isfinite(len)) out.normal[first + v] = glm::vec3(sum[v] / len);
        }
    }
    file.primitives.push_back({m, p, first, n});
}

/// Appends @p bytes to buffer 0 as a new bufferView and accessor; returns the accessor index.
int appendAccessor(tinygltf::Model& model, const std::vector<float>& values, int type, size_t count) {
    if (model.buffers.empty()) model.buffers.emplace_back();
    std::vector<unsigned char>& data = model.buffers[0].data;
    data.resize((data.size() + 3) / 4 * 4, 0);  // float accessors need 4-byte alignment
    tinygltf::BufferView view;
    view.buffer = 0;
    view.byteOffset = data.size();
    view.byteLength = values.size() * sizeof(float);
    view.target = TINYGLTF_TARGET_ARRAY_BUFFER;
    data.resize(data.size() + view.byteLength);
    if (!values.empty()) std::memcpy(data.data() + view.byteOffset, values.data(), view.byteLength);
    model.bufferViews.push_back(view);

    tinygltf::Accessor accessor;
    accessor.bufferView = int(model.bufferViews.size() - 1);
    accessor.componentType = TINYGLTF_COMPONENT_TYPE_FLOAT;
    accessor.type = type;
    accessor.count = count;
    model.accessors.push_back(accessor);
    return int(model.accessors.size() - 1);
}

bool keepImageUri(const std::string*, const std::string*, const tinygltf::Image*, bool, std::string*, void*) {
    return false;  // never re-encode or move images: the copy keeps referring to the originals
}

/// Writes the copy with the results of receivers [0, n) of each primitive range.
void writeCopy(VertexFile& file, const ReceiverResults& results) {
    tinygltf::Model& model = file.model;
    for (const PrimitiveRange& r : file.primitives) {
        std::vector<float> v(results.visibility.begin() + long(r.first), results.visibility.begin() + long(r.first + r.count));
        std::vector<float> e, colour;
        for (size_t i = 0; i < r.count; ++i) {
            const glm::vec3& x = results.irradiance[r.first + i];
            e.insert(e.end(), {x.x, x.y, x.z});
            colour.insert(colour.end(), {v[i], v[i], v[i]});
        }
        auto& attributes = model.meshes[size_t(r.mesh)].primitives[size_t(r.primitive)].attributes;
        attributes["_VISIBILITY"] = appendAccessor(model, v, TINYGLTF_TYPE_SCALAR, r.count);
        attributes["_IRRADIANCE"] = appendAccessor(model, e, TINYGLTF_TYPE_VEC3, r.count);
        if (!attributes.count("COLOR_0")) attributes["COLOR_0"] = appendAccessor(model, colour, TINYGLTF_TYPE_VEC3, r.count);
    }
    // Every buffer is already in memory: embed them all (buffer 0 as the GLB BIN chunk), so the
    // copy stands alone and is written in one atomic step.
    for (tinygltf::Buffer& b : model.buffers) b.uri.clear();
    // Images stay where they are; re-point relative file URIs from the copy's folder.
    const std::filesystem::path inDir = std::filesystem::absolute(file.input).parent_path();
    const std::filesystem::path outDir = std::filesystem::absolute(file.output).parent_path();
    for (tinygltf::Image& image : model.images)
        if (!image.uri.empty() && image.uri.rfind("data:", 0) != 0 && image.uri.find("://") == std::string::npos)
            image.uri = (inDir / image.uri).lexically_normal().lexically_relative(outDir).generic_string();

    const bool binary = lowerExtension(file.output) == ".glb";
    tinygltf::TinyGLTF writer;
    writer.SetImageWriter(&keepImageUri, nullptr);
    std::ostringstream stream;
    if (!writer.WriteGltfSceneToStream(&model, stream, !binary, binary)) fail(file.output, "tinygltf could not serialize the copy");
    const std::string bytes = stream.str();
    ensureParentDirectory(file.output);
    writeFileAtomically(file.output,
                        std::span<const uint8_t>(reinterpret_cast<const uint8_t*>(bytes.data()), bytes.size()));
}

class VertexColorKind final : public ReceiverKind {
public:
    explicit VertexColorKind(std::vector<VertexFile> files) : files_(std::move(files)) {}

    ReceiverSet receivers() override {
        ReceiverSet set;
        for (VertexFile& file : files_) {
            loadGltfModel(file.input, file.model);
            const std::vector<GltfAccessorView> accessors = checkGltfAccessors(file.input, file.model);
            const std::vector<GltfMeshNode> nodes = walkGltfScene(file.input, file.model);
            // A vertex attribute holds one value per vertex, so a mesh drawn by two nodes (two
            // different shadows) cannot be written back; say so instead of picking one.
            std::map<int, int> drawnBy;
            for (const GltfMeshNode& node : nodes)
                if (auto [it, fresh] = drawnBy.emplace(node.mesh, node.node); !fresh)
                    fail(file.input, "mesh {} is drawn by nodes {} and {}; vertex results need one placement per mesh",
                         node.mesh, it->second, node.node);
            for (const GltfMeshNode& node : nodes) {
                if (node.mesh < 0 || size_t(node.mesh) >= file.model.meshes.size())
                    fail(file.input, "node {} refers to mesh {} (file has {})", node.node, node.mesh,
                         file.model.meshes.size());
                const glm::dmat4 world = file.sceneMatrix * node.world;
                for (size_t p = 0; p < file.model.meshes[size_t(node.mesh)].primitives.size(); ++p)
                    addPrimitive(file, accessors, node.mesh, int(p), world, set);
            }
        }
        return set;
    }

    void write(const OutputContext& c) override {
        for (VertexFile& file : files_) writeCopy(file, c.results);
    }

private:
    std::vector<VertexFile> files_;
};

}  // namespace

void registerVertexColorKind() {
    registerReceiverKind("vertices", [](const JsonParams& j, const SceneDesc& scene) {
        const nlohmann::json* meshes = j.raw("meshes");
        if (!meshes) fail(j.where("meshes"), "missing (a list of indices into \"geometry\")");
        if (!meshes->is_array() || meshes->empty())
            fail(j.where("meshes"), "expected a non-empty array of indices into \"geometry\"");
        const std::string ext = lowerExtension(scene.output);
        if (ext != ".glb" && ext != ".gltf")
            fail(scene.file + ": output", "\"{}\" must end in .glb or .gltf for vertices receivers", scene.output);
        std::vector<VertexFile> files;
        for (size_t i = 0; i < meshes->size(); ++i) {
            const nlohmann::json& m = (*meshes)[i];
            const std::string where = fmt::format("{}[{}]", j.where("meshes"), i);
            if (!m.is_number_integer()) fail(where, "expected an index into \"geometry\"");
            const int64_t index = m.get<int64_t>();
            if (index < 0 || uint64_t(index) >= scene.geometry.size())
                fail(where, "geometry index {} is out of range (the scene has {} entries)", index, scene.geometry.size());
            const GeometryDesc& g = scene.geometry[size_t(index)];
            VertexFile file;
            file.entry = size_t(index);
            file.where = where;
            if (g.params.contains("path") && g.params["path"].is_string())
                file.input = resolveScenePath(scene.baseDir, g.params["path"].get<std::string>(), scene.file + ": " + g.path + ".path");
            const std::string inExt = lowerExtension(file.input);
            const bool gltfType = g.type == "gltf" || g.type == "glb" || g.type == "file";
            if (!gltfType || (inExt != ".gltf" && inExt != ".glb"))
                fail(where, "{} is a \"{}\" entry; vertices receivers need a .gltf or .glb file", g.path, g.type);
            file.sceneMatrix = glm::dmat4(g.transform.matrix());
            file.output = scene.output;
            if (meshes->size() > 1) {
                std::filesystem::path out(scene.output);
                file.output = (out.parent_path() / fmt::format("{}-{}{}", out.stem().string(), i, out.extension().string())).string();
            }
            files.push_back(std::move(file));
        }
        return std::make_unique<VertexColorKind>(std::move(files));
    });
}

}  // namespace penumbra
