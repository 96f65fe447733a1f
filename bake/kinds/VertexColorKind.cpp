#include "bake/kinds/VertexColorKind.h"
#include "stream/util/PathText.h"

#include "stream/GltfBuffers.h"
#include "bake/kinds/ReceiverKind.h"
#include "bake/Scene.h"
#include "stream/util/AtomicFile.h"
#include "stream/util/Error.h"
#include "stream/GltfBytes.h"
#include "stream/GltfDocument.h"
#include "stream/GltfPrimitive.h"
#include "stream/TinyGltfLoad.h"

#include <tiny_gltf.h>

#include <glm/geometric.hpp>
#include <glm/mat3x3.hpp>
#include <glm/matrix.hpp>

#include <algorithm>
#include <cmath>
#include <cstdint>
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
    bool colourUnorm16 = false;  ///< "color_format": "unorm16": COLOR_0 as normalized unsigned shorts
    ReceiverClass receiverClass;  ///< the entry's receive_shadows and receiver_offset
    uint64_t fileBytes = 0;
    std::vector<PrimitiveRange> primitives;
};

/// Adds receivers for one primitive placed by @p world, read through the shared glTF walker
/// (GltfPrimitive.h), which does every check of positions, normals and indices.
void addPrimitive(VertexFile& file, GltfPrimitiveReader& reader, const glm::dmat4& world, ReceiverSet& out) {
    const GltfPrimitiveLayout& layout = reader.layout();
    const size_t n = size_t(layout.vertices);
    const bool normals = reader.has("NORMAL");
    const glm::dmat3 linear(world);
    const glm::dmat3 normalMatrix = glm::transpose(glm::inverse(linear));
    const bool mirrored = glm::determinant(linear) < 0;
    const size_t first = out.position.size();
    out.position.resize(first + n);
    out.normal.resize(first + n, glm::vec3(0.f));
    for (size_t v = 0; v < n; ++v) {
        glm::dvec3 x = world * glm::dvec4(glm::dvec3(reader.position(v)), 1.0);
        if (!std::isfinite(x.x) || !std::isfinite(x.y) || !std::isfinite(x.z))
            fail(file.input, "mesh {} primitive {}: vertex {} is not finite after its transforms", layout.mesh, layout.primitive, v);
        out.position[first + v] = glm::vec3(x);
        if (normals) {
            glm::dvec3 nn = normalMatrix * glm::dvec3(glm::vec3(reader.attribute("NORMAL", 3, v)));
            double len = glm::length(nn);
            // A zero normal means "no receiver cosine" (ReceiverShading), the honest fallback.
            if (len > 0 && std::isfinite(len)) out.normal[first + v] = glm::vec3(nn / len);
        }
    }
    if (!normals) {
        // Area-weighted face normals: the unnormalized cross product is twice the area.
        std::vector<glm::dvec3> sum(n, glm::dvec3(0.0));
        for (uint64_t t = 0; t < layout.triangles; ++t) {
            const std::array<uint32_t, 3> c = reader.triangle(t);
            glm::dvec3 pa(out.position[first + c[0]]), pb(out.position[first + c[1]]), pd(out.position[first + c[2]]);
            // World-space winding of a mirrored node is reversed; its front face is not.
            glm::dvec3 face = glm::cross(pb - pa, pd - pa) * (mirrored ? -1.0 : 1.0);
            sum[c[0]] += face, sum[c[1]] += face, sum[c[2]] += face;
        }
        for (size_t v = 0; v < n; ++v) {
            double len = glm::length(sum[v]);
            if (len > 0 && std::isfinite(len)) out.normal[first + v] = glm::vec3(sum[v] / len);
        }
    }
    file.primitives.push_back({layout.mesh, layout.primitive, first, n});
}

/// Appends float @p values as a vertex attribute accessor; returns its index.
int appendAccessor(tinygltf::Model& model, const std::vector<float>& values, int type, size_t count) {
    return appendGltfAccessor(model, values.data(), values.size() * sizeof(float), TINYGLTF_COMPONENT_TYPE_FLOAT, type, count,
                              TINYGLTF_TARGET_ARRAY_BUFFER);
}

bool keepImageUri(const std::string*, const std::string*, const tinygltf::Image*, bool, std::string*, void*) {
    return false;  // never re-encode or move images: the copy keeps referring to the originals
}

/// @brief Places the copy where the bake placed the mesh: a root node with the scene entry's
/// transform above each scene's roots, so the colours, baked at the transformed size, come back
/// on geometry of that size (a bunny baked at x10 opens at x10 in Blender).
void applySceneTransform(tinygltf::Model& model, const glm::dmat4& m) {
    if (m == glm::dmat4(1.0)) return;
    for (tinygltf::Scene& scene : model.scenes) {
        tinygltf::Node root;
        root.name = "penumbra_scene_transform";
        for (int c = 0; c < 4; ++c)
            for (int r = 0; r < 4; ++r) root.matrix.push_back(m[c][r]);  // column-major, as glTF
        root.children = scene.nodes;
        model.nodes.push_back(std::move(root));
        scene.nodes = {int(model.nodes.size() - 1)};
    }
}

/// Appends the grey visible fractions @p v as COLOR_0, as floats or normalized unsigned shorts.
int appendColour(tinygltf::Model& model, const std::vector<float>& v, bool unorm16) {
    if (!unorm16) {
        std::vector<float> colour;
        for (float x : v) colour.insert(colour.end(), {x, x, x});
        return appendAccessor(model, colour, TINYGLTF_TYPE_VEC3, v.size());
    }
    // glTF aligns each vertex attribute element to 4 bytes: a VEC3 of shorts is padded to 8.
    std::vector<uint16_t> padded;
    for (float x : v) {
        const auto q = uint16_t(std::lround(std::clamp(double(x), 0.0, 1.0) * 65535.0));
        padded.insert(padded.end(), {q, q, q, 0});
    }
    const int accessor = appendGltfAccessor(model, padded.data(), padded.size() * sizeof(uint16_t), TINYGLTF_COMPONENT_TYPE_UNSIGNED_SHORT,
                                            TINYGLTF_TYPE_VEC3, v.size(), TINYGLTF_TARGET_ARRAY_BUFFER);
    model.bufferViews[size_t(model.accessors[size_t(accessor)].bufferView)].byteStride = 8;
    model.accessors[size_t(accessor)].normalized = true;
    return accessor;
}

/// Writes the copy with the results of receivers [0, n) of each primitive range.
void writeCopy(VertexFile& file, const ReceiverResults& results) {
    tinygltf::Model model;
    loadTinyGltf(file.input, model);
    for (const PrimitiveRange& r : file.primitives) {
        std::vector<float> v(results.visibility.begin() + long(r.first), results.visibility.begin() + long(r.first + r.count));
        std::vector<float> e;
        for (size_t i = 0; i < r.count; ++i) {
            const glm::vec3& x = results.irradiance[r.first + i];
            e.insert(e.end(), {x.x, x.y, x.z});
        }
        auto& attributes = model.meshes[size_t(r.mesh)].primitives[size_t(r.primitive)].attributes;
        attributes["_VISIBILITY"] = appendAccessor(model, v, TINYGLTF_TYPE_SCALAR, r.count);
        attributes["_IRRADIANCE"] = appendAccessor(model, e, TINYGLTF_TYPE_VEC3, r.count);
        if (!attributes.count("COLOR_0")) attributes["COLOR_0"] = appendColour(model, v, file.colourUnorm16);
    }
    applySceneTransform(model, file.sceneMatrix);
    // Every buffer is already in memory: embed them all (buffer 0 as the GLB BIN chunk), so the
    // copy stands alone and is written in one atomic step.
    for (tinygltf::Buffer& b : model.buffers) b.uri.clear();
    // Images stay where they are; re-point relative file URIs from the copy's folder.
    const std::filesystem::path inDir = std::filesystem::absolute(file.input).parent_path();
    const std::filesystem::path outDir = std::filesystem::absolute(file.output).parent_path();
    for (tinygltf::Image& image : model.images)
        if (!image.uri.empty() && image.uri.rfind("data:", 0) != 0 && image.uri.find("://") == std::string::npos)
            image.uri = (inDir / image.uri).lexically_normal().lexically_relative(outDir).generic_string();

    const bool binary = lowercaseExtension(file.output) == ".glb";
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
            const size_t begin = set.size();
            const GltfDocument doc = loadGltfDocument(file.input);
            GltfBytes bytes(doc, UINT64_MAX);
            const std::vector<GltfMeshNode> nodes = walkGltfScene(doc);
            // A vertex attribute holds one value per vertex, so a mesh drawn by two nodes (two
            // different shadows) cannot be written back; say so instead of picking one.
            std::map<int, int> drawnBy;
            for (const GltfMeshNode& node : nodes) {
                if (auto [it, fresh] = drawnBy.emplace(node.mesh, node.node); !fresh)
                    fail(file.input, "mesh {} is drawn by nodes {} and {}; vertex results need one placement per mesh",
                         node.mesh, it->second, node.node);
                if (doc.nodes[size_t(node.node)].instanced())
                    fail(file.input, "node {} uses EXT_mesh_gpu_instancing; vertex results need one placement per mesh", node.node);
            }
            for (const GltfMeshNode& node : nodes) {
                const glm::dmat4 world = file.sceneMatrix * node.world;
                for (size_t p = 0; p < doc.meshes[size_t(node.mesh)].primitives.size(); ++p) {
                    const auto layout = gltfTrianglePrimitive(doc, node.mesh, int(p));
                    if (!layout) continue;  // points and lines carry no surface to shade
                    if (layout->draco || layout->decodeBytes > 0)
                        fail(layout->where(doc), "is compressed; vertex results can only be written into an uncompressed "
                             "glTF (decompress it with gltfpack -noq, or bake a lightmap)");
                    GltfPrimitiveReader reader(doc, bytes, *layout);
                    addPrimitive(file, reader, world, set);
                }
            }
            file.fileBytes = std::filesystem::file_size(file.input);
            for (size_t r = begin; r < set.size(); ++r) applyReceiverClass(set, r, file.receiverClass);
        }
        return set;
    }

    uint64_t outputBytes(uint64_t receivers) const override {
        // The copy is built in memory: the model with every buffer (tinygltf), the appended
        // accessors (28 bytes per vertex), and the serialized file, about the input again.
        uint64_t bytes = receivers * 28 * 2;
        for (const VertexFile& file : files_) bytes = std::max(bytes, 3 * file.fileBytes + receivers * 56);
        return bytes;
    }

    void write(const OutputContext& c) override {
        for (VertexFile& file : files_) writeCopy(file, c.results);
    }

private:
    std::vector<VertexFile> files_;
};

}  // namespace

namespace {

const ReceiverKindRegistration kVertices{"vertices", [](const JsonParams& j, const SceneDesc& scene, KindUse use) {
        const std::vector<size_t> meshes = geometryIndices(j, "meshes", scene);
        const std::string colourFormat = j.string("color_format", "float");
        if (colourFormat != "float" && colourFormat != "unorm16")
            fail(j.where("color_format"), "expected \"float\" or \"unorm16\", got \"{}\"", colourFormat);
        requireOutputExtension(scene, {".glb", ".gltf"}, "vertices");
        std::vector<VertexFile> files;
        for (size_t i = 0; i < meshes.size(); ++i) {
            const size_t index = meshes[i];
            const std::string where = fmt::format("{}[{}]", j.where("meshes"), i);
            const GeometryDesc& g = scene.geometry[size_t(index)];
            VertexFile file;
            file.entry = size_t(index);
            file.where = where;
            if (g.params.contains("path") && g.params["path"].is_string())
                file.input = resolveScenePath(scene.baseDir, g.params["path"].get<std::string>(), scene.file + ": " + g.path + ".path");
            const std::string inExt = lowercaseExtension(file.input);
            const bool gltfType = g.type == "gltf" || g.type == "glb" || g.type == "file";
            if (!gltfType || (inExt != ".gltf" && inExt != ".glb"))
                fail(where, "{} is a \"{}\" entry; vertices receivers need a .gltf or .glb file", g.path, g.type);
            file.sceneMatrix = glm::dmat4(g.transform.matrix());
            file.colourUnorm16 = colourFormat == "unorm16";
            file.receiverClass = scene.receiverClasses[g.receiverClass];
            file.output = scene.output;
            if (meshes.size() > 1) {
                std::filesystem::path out(scene.output);
                file.output = (out.parent_path() / fmt::format("{}-{}{}", out.stem().string(), i, out.extension().string())).string();
            }
            files.push_back(std::move(file));
        }
        return use == KindUse::Validate ? nullptr : std::make_unique<VertexColorKind>(std::move(files));
    }, ".glb"};

}  // namespace

}  // namespace penumbra
