#include "bake/kinds/VertexColorKind.h"
#include "stream/util/PathText.h"

#include "stream/GltfBuffers.h"
#include "bake/kinds/CameraKind.h"
#include "bake/kinds/CameraOutput.h"
#include "bake/kinds/ReceiverKind.h"
#include "bake/output/ImageWriters.h"
#include "bake/output/MeshPreview.h"
#include "bake/output/PreviewTone.h"
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
#include <optional>
#include <span>
#include <sstream>

namespace penumbra {
namespace {

/// One triangle primitive that contributes receivers: its vertices are receivers
/// [first, first + count) of the kind's ReceiverSet. Primitives of one mesh that share a POSITION
/// accessor share its receivers (and, in the copy, its result accessors): @p owner is the first
/// of them, the one that added the receivers.
struct PrimitiveRange {
    int mesh = 0, primitive = 0;
    size_t first = 0, count = 0;
    size_t owner = 0;  ///< index in VertexFile::primitives of the range that added the receivers
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
    std::map<std::pair<int, int>, size_t> owners;                ///< (mesh, POSITION accessor) -> owner range
    std::map<size_t, std::vector<glm::dvec3>> faceNormalSums;   ///< owner range -> sums, for meshes without normals
};

/// Adds the area-weighted face normals of @p reader's triangles to @p sum (the unnormalized cross
/// product is twice the area), from the world positions of receivers [first, first + n).
void addFaceNormals(GltfPrimitiveReader& reader, const ReceiverSet& set, size_t first, bool mirrored, std::vector<glm::dvec3>& sum) {
    for (uint64_t t = 0; t < reader.layout().triangles; ++t) {
        const std::array<uint32_t, 3> c = reader.triangle(t);
        glm::dvec3 pa(set.position[first + c[0]]), pb(set.position[first + c[1]]), pd(set.position[first + c[2]]);
        // World-space winding of a mirrored node is reversed; its front face is not.
        glm::dvec3 face = glm::cross(pb - pa, pd - pa) * (mirrored ? -1.0 : 1.0);
        sum[c[0]] += face, sum[c[1]] += face, sum[c[2]] += face;
    }
}

/// Adds receivers for one primitive placed by @p world, read through the shared glTF walker
/// (GltfPrimitive.h), which does every check of positions, normals and indices. A primitive whose
/// mesh already placed its POSITION accessor shares those receivers: only its faces are read.
void addPrimitive(VertexFile& file, GltfPrimitiveReader& reader, const glm::dmat4& world, ReceiverSet& out) {
    const GltfPrimitiveLayout& layout = reader.layout();
    const bool mirrored = glm::determinant(glm::dmat3(world)) < 0;
    const auto [owner, fresh] = file.owners.emplace(std::pair(layout.mesh, layout.positions), file.primitives.size());
    if (!fresh) {
        const PrimitiveRange shared = file.primitives[owner->second];
        file.primitives.push_back({layout.mesh, layout.primitive, shared.first, shared.count, owner->second});
        if (auto sums = file.faceNormalSums.find(owner->second); sums != file.faceNormalSums.end())
            addFaceNormals(reader, out, shared.first, mirrored, sums->second);
        return;
    }
    const size_t n = size_t(layout.vertices);
    const bool normals = reader.has("NORMAL");
    const glm::dmat3 normalMatrix = glm::transpose(glm::inverse(glm::dmat3(world)));
    const size_t first = out.position.size();
    out.position.resize(first + n);
    out.normal.resize(first + n, glm::vec3(0.f));
    size_t zeroNormals = 0;
    for (size_t v = 0; v < n; ++v) {
        glm::dvec3 x = world * glm::dvec4(glm::dvec3(reader.position(v)), 1.0);
        if (!std::isfinite(x.x) || !std::isfinite(x.y) || !std::isfinite(x.z))
            fail(file.input, "mesh {} primitive {}: vertex {} is not finite after its transforms", layout.mesh, layout.primitive, v);
        out.position[first + v] = glm::vec3(x);
        if (normals) {
            glm::dvec3 nn = normalMatrix * glm::dvec3(glm::vec3(reader.attribute("NORMAL", 3, v)));
            double len = glm::length(nn);
            // A zero NORMAL (invalid glTF; a degenerate transform) takes its faces' normal, as a
            // mesh without normals does: left at zero it would mean "no receiver cosine".
            if (len > 0 && std::isfinite(len)) out.normal[first + v] = glm::vec3(nn / len);
            else ++zeroNormals;
        }
    }
    file.primitives.push_back({layout.mesh, layout.primitive, first, n, file.primitives.size()});
    if (zeroNormals)
        printWarning("{}: mesh {} primitive {}: {} vertex NORMAL(s) of zero length take their faces' normal", file.input,
                     layout.mesh, layout.primitive, zeroNormals);
    if (!normals || zeroNormals)
        addFaceNormals(reader, out, first, mirrored, file.faceNormalSums[file.primitives.size() - 1] = std::vector<glm::dvec3>(n));
}

/// Normalizes the face-normal sums of the meshes without normals (or with zero ones) into their
/// receivers' normals where they have none, once every primitive sharing their vertices has
/// added its faces.
void finishNormals(VertexFile& file, ReceiverSet& out) {
    for (const auto& [owner, sum] : file.faceNormalSums) {
        const size_t first = file.primitives[owner].first;
        for (size_t v = 0; v < sum.size(); ++v) {
            const double len = glm::length(sum[v]);
            if (out.normal[first + v] == glm::vec3(0.f) && len > 0 && std::isfinite(len)) out.normal[first + v] = glm::vec3(sum[v] / len);
        }
    }
    file.faceNormalSums.clear();
}

/// Appends float @p values as a vertex attribute accessor; returns its index.
int appendAccessor(tinygltf::Model& model, const std::vector<float>& values, int type, size_t count) {
    return appendGltfAccessor(model, values.data(), values.size() * sizeof(float), TINYGLTF_COMPONENT_TYPE_FLOAT, type, count,
                              TINYGLTF_TARGET_ARRAY_BUFFER);
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
/// The copy of mesh @p i of @p count at @p output: the output itself for one, else STEM-i.EXT.
std::string copyPath(const std::string& output, size_t i, size_t count) {
    if (count == 1) return output;
    const std::filesystem::path out(output);
    return (out.parent_path() / fmt::format("{}-{}{}", out.stem().string(), i, out.extension().string())).string();
}

void writeCopy(VertexFile& file, const ReceiverResults& results) {
    tinygltf::Model model;
    loadTinyGltf(file.input, model);
    struct Written {
        int visibility = -1, irradiance = -1, colour = -1;
    };
    std::map<size_t, Written> written;  // owner range -> its accessors, shared by the ranges sharing its vertices
    for (size_t k = 0; k < file.primitives.size(); ++k) {
        const PrimitiveRange& r = file.primitives[k];
        auto& attributes = model.meshes[size_t(r.mesh)].primitives[size_t(r.primitive)].attributes;
        Written& w = written[r.owner];
        if (w.visibility < 0) {
            std::vector<float> v(results.visibility.begin() + long(r.first), results.visibility.begin() + long(r.first + r.count));
            std::vector<float> e;
            for (size_t i = 0; i < r.count; ++i) {
                const glm::vec3& x = results.irradiance[r.first + i];
                e.insert(e.end(), {x.x, x.y, x.z});
            }
            w.visibility = appendAccessor(model, v, TINYGLTF_TYPE_SCALAR, r.count);
            w.irradiance = appendAccessor(model, e, TINYGLTF_TYPE_VEC3, r.count);
            if (!attributes.count("COLOR_0")) w.colour = appendColour(model, v, file.colourUnorm16);
        }
        attributes["_VISIBILITY"] = w.visibility;
        attributes["_IRRADIANCE"] = w.irradiance;
        if (!attributes.count("COLOR_0")) {
            if (w.colour < 0) {
                std::vector<float> v(results.visibility.begin() + long(r.first), results.visibility.begin() + long(r.first + r.count));
                w.colour = appendColour(model, v, file.colourUnorm16);
            }
            attributes["COLOR_0"] = w.colour;
        }
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

    ensureParentDirectory(file.output);
    writeGltfModel(model, file.output, lowercaseExtension(file.output) == ".glb", /*keepImageUris=*/true);
}

/// Calls @p visit(reader, world) for every triangle primitive of @p file, in the receivers' order,
/// after the checks that a copy can be written (one placement per mesh, uncompressed).
template <class Visit>
void walkPrimitives(const VertexFile& file, Visit&& visit) {
    const GltfDocument doc = loadGltfDocument(file.input);
    GltfBytes bytes(doc, UINT64_MAX);
    const std::vector<GltfMeshNode> nodes = walkGltfScene(doc);
    // A vertex attribute holds one value per vertex, so a mesh drawn by two nodes (two
    // different shadows) cannot be written back; say so instead of picking one.
    std::map<int, int> drawnBy;
    for (const GltfMeshNode& node : nodes) {
        if (auto [it, fresh] = drawnBy.emplace(node.mesh, node.node); !fresh)
            fail(file.input, "mesh {} is drawn by nodes {} and {}; vertex results need one placement per mesh", node.mesh,
                 it->second, node.node);
        if (doc.nodes[size_t(node.node)].instanced())
            fail(file.input, "node {} uses EXT_mesh_gpu_instancing; vertex results need one placement per mesh", node.node);
    }
    for (const GltfMeshNode& node : nodes) {
        const glm::dmat4 world = file.sceneMatrix * node.world;
        for (size_t p = 0; p < doc.meshes[size_t(node.mesh)].primitives.size(); ++p) {
            const auto layout = gltfTrianglePrimitive(doc, node.mesh, int(p));
            if (!layout) continue;  // points and lines carry no surface to shade
            if (layout->compressed())
                fail(layout->where(doc), "is compressed; vertex results can only be written into an uncompressed "
                     "glTF (decompress it with gltfpack -noq, or bake a lightmap)");
            GltfPrimitiveReader reader(doc, bytes, *layout);
            visit(reader, world);
        }
    }
}

/// @brief Renders every file's triangles with their baked irradiance (the camera preview's tone
/// mapping) from @p camera, or from a view framing the receivers, and writes the PNG.
void writePreview(std::span<const VertexFile> files, const OutputContext& c, const std::optional<CameraDesc>& camera) {
    glm::dvec3 lo(0.0), hi(0.0);
    if (!c.receivers.position.empty()) {
        lo = hi = glm::dvec3(c.receivers.position[0]);
        for (const glm::vec3& p : c.receivers.position) lo = glm::min(lo, glm::dvec3(p)), hi = glm::max(hi, glm::dvec3(p));
    }
    MeshPreviewRaster raster(camera ? *camera : framingCamera(lo, hi));
    std::vector<float> luminance(c.results.irradiance.size());
    for (size_t i = 0; i < luminance.size(); ++i) luminance[i] = previewLuminance(c.results.irradiance[i]);
    const PreviewTone tone = previewTone(luminance);
    for (const VertexFile& file : files) {
        size_t k = 0;
        walkPrimitives(file, [&](GltfPrimitiveReader& reader, const glm::dmat4&) {
            const size_t first = file.primitives.at(k++).first;
            for (uint64_t t = 0; t < reader.layout().triangles; ++t) {
                const std::array<uint32_t, 3> v = reader.triangle(t);
                std::array<glm::vec3, 3> p, colour;
                for (size_t j = 0; j < 3; ++j)
                    p[j] = c.receivers.position[first + v[j]], colour[j] = tone(c.results.irradiance[first + v[j]]);
                raster.add(p, colour);
            }
        });
    }
    writePng8(previewPath(c.output), raster.width(), raster.height(), 3, raster.rgb());
}

class VertexColorKind final : public ReceiverKind {
public:
    VertexColorKind(std::vector<VertexFile> files, std::optional<CameraDesc> camera)
        : files_(std::move(files)), camera_(std::move(camera)) {}

    ReceiverSet receivers() override {
        ReceiverSet set;
        for (VertexFile& file : files_) {
            const size_t begin = set.size();
            walkPrimitives(file, [&](GltfPrimitiveReader& reader, const glm::dmat4& world) { addPrimitive(file, reader, world, set); });
            finishNormals(file, set);
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
        // The preview comes after the copies: its raster and a luminance per receiver.
        const int w = camera_ ? camera_->width : 640, h = camera_ ? camera_->height : 480;
        return std::max(bytes, MeshPreviewRaster::bytes(w, h) + receivers * 4);
    }

    void write(const OutputContext& c) override {
        // At the output asked for now: a library caller's write(path) may name another than the
        // scene's (the copies went to the scene's output, the preview to the path).
        for (size_t i = 0; i < files_.size(); ++i) files_[i].output = copyPath(c.output, i, files_.size());
        for (VertexFile& file : files_) writeCopy(file, c.results);
        writePreview(files_, c, camera_);
    }

private:
    std::vector<VertexFile> files_;
    std::optional<CameraDesc> camera_;  ///< receivers.camera: the preview's view
};

}  // namespace

namespace {

const ReceiverKindRegistration kVertices{"vertices", [](const JsonParams& j, const SceneDesc& scene, KindUse use) {
        const std::vector<size_t> meshes = geometryIndices(j, "meshes", scene);
        const std::string colourFormat = j.string("color_format", "float");
        if (colourFormat != "float" && colourFormat != "unorm16")
            fail(j.where("color_format"), "expected \"float\" or \"unorm16\", got \"{}\"", colourFormat);
        requireOutputExtension(scene, {".glb", ".gltf"}, "vertices");
        std::optional<CameraDesc> camera;
        if (const nlohmann::json* raw = j.raw("camera")) {
            if (!raw->is_object()) fail(j.where("camera"), "expected an object such as {{\"eye\": [3, 2, 4], \"target\": [0, 0, 0]}}");
            JsonParams view(*raw, j.file(), j.path("camera"));
            camera = readCameraView(view);
            view.finish();
            validateCamera(*camera);
        }
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
            file.output = copyPath(scene.output, i, meshes.size());
            // Known now, so that the plan before the scan counts the copy as the one after it
            // does (a refusal named 82M, and 82M was refused again naming 83M).
            std::error_code unknown;  // a missing file is reported when it is opened
            file.fileBytes = std::filesystem::file_size(file.input, unknown);
            if (unknown) file.fileBytes = 0;
            files.push_back(std::move(file));
        }
        return use == KindUse::Validate ? nullptr : std::make_unique<VertexColorKind>(std::move(files), std::move(camera));
    }, ".glb", &previewOutputs};

}  // namespace

}  // namespace penumbra
