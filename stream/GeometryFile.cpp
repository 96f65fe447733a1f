#include "stream/GeometryFile.h"
#include "stream/util/PathText.h"

#include "stream/util/AtomicFile.h"
#include "stream/util/Error.h"
#include "stream/GltfBuffers.h"
#include "stream/GltfMeshWriter.h"
#include "stream/GltfReader.h"
#include "stream/IndexedMesh.h"
#include "stream/util/InputFile.h"
#include "stream/ObjReader.h"
#include "stream/util/TextInput.h"
#include "stream/PtriFormat.h"
#include "stream/ProgressSource.h"

#include <tiny_gltf.h>

#include <glm/common.hpp>
#include <glm/geometric.hpp>

#include <algorithm>
#include <cctype>
#include <cstring>
#include <filesystem>
#include <limits>
#include <sstream>

namespace penumbra {

namespace {

/// Calls @p consume with successive chunks of @p source, from its start.
template <typename Consume>
void forEachChunk(TriangleSource& source, Consume&& consume) {
    source.rewind();
    std::vector<Triangle> chunk(kTriangleChunk);
    while (size_t n = source.read(chunk)) consume(std::span<const Triangle>(chunk.data(), n));
}

void writePtri(TriangleSource& in, const std::string& outPath) {
    PtriWriter writer(outPath);
    forEachChunk(in, [&](std::span<const Triangle> triangles) { writer.write(triangles); });
    writer.finish();
}

void writeObj(TriangleSource& in, const std::string& outPath) {
    AtomicFile file(outPath);
    fmt::memory_buffer text;
    fmt::format_to(std::back_inserter(text), "# triangle soup written by penumbra: 3 vertices per face\n");
    uint64_t vertex = 1;  // OBJ indices start at 1
    forEachChunk(in, [&](std::span<const Triangle> triangles) {
        for (const Triangle& t : triangles) {
            // "{}" prints the shortest text that parses back to the same float.
            for (const glm::vec3& p : t.v) fmt::format_to(std::back_inserter(text), "v {} {} {}\n", p.x, p.y, p.z);
            fmt::format_to(std::back_inserter(text), "f {} {} {}\n", vertex, vertex + 1, vertex + 2);
            vertex += 3;
        }
        if (text.size() >= (1u << 20)) {
            file.write(text.data(), text.size());
            text.clear();
        }
    });
    file.write(text.data(), text.size());
    file.commit();
}

void writeGltf(TriangleSource& in, const std::string& outPath, bool binary) {
    // The JSON states buffer and accessor sizes up front, so the positions are gathered first,
    // straight into the bytes the buffer will hold.
    std::vector<unsigned char> positionBytes;
    uint64_t vertexCount = 0;
    glm::vec3 lo(0.0f), hi(0.0f);
    // A GLB's length fields are 32-bit; stay well inside them (headers and JSON need room too).
    const uint64_t maxTriangles = (std::numeric_limits<uint32_t>::max() - (1u << 20)) / 36;
    forEachChunk(in, [&](std::span<const Triangle> triangles) {
        if (vertexCount / 3 + triangles.size() > maxTriangles)
            fail(outPath, "more than {} triangles do not fit in one glTF buffer", maxTriangles);
        if (vertexCount == 0 && !triangles.empty()) lo = hi = triangles[0].v[0];
        for (const Triangle& t : triangles) {
            for (const glm::vec3& p : t.v) {
                const auto* bytes = reinterpret_cast<const unsigned char*>(&p);
                positionBytes.insert(positionBytes.end(), bytes, bytes + sizeof p);
                lo = glm::min(lo, p);
                hi = glm::max(hi, p);
            }
            vertexCount += 3;
        }
    });

    tinygltf::Model model;
    model.asset.version = "2.0";
    model.asset.generator = "penumbra";
    if (vertexCount > 0) {
        tinygltf::Buffer buffer;
        buffer.data = std::move(positionBytes);
        tinygltf::BufferView view;
        view.buffer = 0;
        view.byteLength = buffer.data.size();
        view.target = TINYGLTF_TARGET_ARRAY_BUFFER;
        tinygltf::Accessor accessor;
        accessor.bufferView = 0;
        accessor.componentType = TINYGLTF_COMPONENT_TYPE_FLOAT;
        accessor.type = TINYGLTF_TYPE_VEC3;
        accessor.count = vertexCount;
        accessor.minValues = {lo.x, lo.y, lo.z};  // required for POSITION by the spec
        accessor.maxValues = {hi.x, hi.y, hi.z};
        tinygltf::Primitive primitive;
        primitive.attributes["POSITION"] = 0;
        primitive.mode = TINYGLTF_MODE_TRIANGLES;
        tinygltf::Mesh mesh;
        mesh.primitives.push_back(primitive);
        tinygltf::Node node;
        node.mesh = 0;
        model.buffers.push_back(std::move(buffer));
        model.bufferViews.push_back(view);
        model.accessors.push_back(accessor);
        model.meshes.push_back(mesh);
        model.nodes.push_back(node);
        tinygltf::Scene scene;
        scene.nodes.push_back(0);
        model.scenes.push_back(scene);
        model.defaultScene = 0;
    }
    // An empty source writes a model without scenes: tinygltf would serialize an empty scene
    // as null, which its own loader then rejects.

    writeGltfModel(model, outPath, binary);
}

}  // namespace

std::optional<GeometryFormat> geometryFormatOf(const std::string& path) {
    std::string ext = lowercaseExtension(path);
    if (ext == ".obj") return GeometryFormat::Obj;
    if (ext == ".gltf" || ext == ".glb") return GeometryFormat::Gltf;
    if (ext == ".ptri") return GeometryFormat::Ptri;
    return std::nullopt;
}

TriangleSourcePtr openGeometryFile(const std::string& path, const std::vector<std::string>& parts) {
    std::optional<GeometryFormat> format = geometryFormatOf(path);
    if (!format)
        fail(path, "unknown geometry file extension '{}' (expected .obj, .gltf, .glb or .ptri)", lowercaseExtension(path));
    return openGeometryFile(path, *format, parts);
}

TriangleSourcePtr openGeometryFile(const std::string& path, GeometryFormat format, const std::vector<std::string>& parts,
                                   std::shared_ptr<const GltfAlphaIds> gltfAlpha) {
    checkInputFile(path);
    if (format != GeometryFormat::Obj && !parts.empty()) fail(path, "\"parts\" selects o/g groups of OBJ files only");
    switch (format) {
        case GeometryFormat::Obj: {
            checkTextFile(path, "OBJ");
            TriangleSourcePtr source = openObj(path, parts);
            warnIfNoFaces(path, source->sizeHint().value_or(1));
            return source;
        }
        case GeometryFormat::Gltf: return openGltf(path, std::move(gltfAlpha));
        case GeometryFormat::Ptri: return openPtri(path);
    }
    fail(path, "unknown geometry format");
}

GeometryInfo scanGeometry(TriangleSource& source) {
    GeometryInfo info;
    forEachChunk(source, [&](std::span<const Triangle> triangles) {
        for (const Triangle& t : triangles) {
            if (info.triangles++ == 0) info.lo = info.hi = t.v[0];
            for (const glm::vec3& p : t.v) {
                info.lo = glm::min(info.lo, p);
                info.hi = glm::max(info.hi, p);
            }
            glm::dvec3 a(t.v[0]), b(t.v[1]), c(t.v[2]);
            info.area += 0.5 * glm::length(glm::cross(b - a, c - a));
        }
    });
    source.rewind();
    return info;
}

void convertGeometry(TriangleSource& in, const std::string& outPath) {
    std::string ext = lowercaseExtension(outPath);
    if (ext == ".ptri") return writePtri(in, outPath);
    if (ext == ".obj") return writeObj(in, outPath);
    if (ext == ".glb" || ext == ".gltf") return writeGltf(in, outPath, ext == ".glb");
    fail(outPath, "unknown output extension '{}' (expected .obj, .gltf, .glb or .ptri)", ext);
}

void convertGeometryFile(const std::string& inPath, const std::string& outPath, std::optional<bool> progressQuiet) {
    const std::string out = lowercaseExtension(outPath);
    const std::optional<GeometryFormat> in = geometryFormatOf(inPath);
    std::optional<OpeningProgress> opening;  // the readers' own passes ([check], [load])
    if (progressQuiet) opening.emplace(*progressQuiet);
    if ((out == ".glb" || out == ".gltf") && in && *in != GeometryFormat::Ptri) {
        // Meshes keep their normals, texture coordinates and names; corners are welded.
        checkInputFile(inPath);
        std::vector<IndexedMesh> meshes = loadIndexedMeshes(inPath, glm::mat4(1.0f));
        for (IndexedMesh& m : meshes) m = weldVertices(m);
        return writeIndexedGltf(meshes, outPath, out == ".glb");
    }
    TriangleSourcePtr source = openGeometryFile(inPath);
    if (progressQuiet)
        source = std::make_unique<ProgressSource>(std::move(source), "convert " + std::filesystem::path(inPath).filename().string(), *progressQuiet);
    if (out == ".glb" || out == ".gltf")  // a triangle stream: corners shared by position
        return writeIndexedGltf({meshOfTriangles(*source, std::filesystem::path(outPath).stem().string())}, outPath, out == ".glb");
    convertGeometry(*source, outPath);
}

}  // namespace penumbra
