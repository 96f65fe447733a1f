#include "stream/GeometryFile.h"
#include "stream/util/PathText.h"

#include "stream/util/AtomicFile.h"
#include "stream/util/Error.h"
#include "stream/GltfBuffers.h"
#include "stream/GltfConvert.h"
#include "stream/GltfDocument.h"
#include "stream/GltfReader.h"
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

/// A triangle soup: three vertices per triangle, no indices, as `generate` writes it.
void writeGltf(TriangleSource& in, const std::string& outPath, bool binary) {
    // A count known up front is checked before the work (120M generated triangles were refused
    // after 13 s).
    if (const std::optional<uint64_t> count = in.sizeHint(); count && *count > GltfStreamWriter::kMaxBufferBytes / 36)
        fail(outPath, "{} triangles do not fit in one glTF buffer (at most {} at 36 bytes each: 4 GiB)", *count,
             GltfStreamWriter::kMaxBufferBytes / 36);
    GltfStreamWriter out(outPath, binary);
    addTrianglesOf(in, out, "", GltfStreamWriter::Indexing::None);
    out.commit();
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
    checkGeometryOutputExtension(outPath);
}

void checkGeometryOutputExtension(const std::string& outPath) {
    const std::string ext = lowercaseExtension(outPath);
    if (ext != ".ptri" && ext != ".obj" && ext != ".glb" && ext != ".gltf")
        fail(outPath, "unknown output extension '{}' (expected .obj, .gltf, .glb or .ptri)", ext);
}

void convertGeometryFile(const std::string& inPath, const std::string& outPath, std::optional<bool> progressQuiet) {
    const std::string out = lowercaseExtension(outPath);
    const std::optional<GeometryFormat> in = geometryFormatOf(inPath);
    std::optional<OpeningProgress> opening;  // the readers' own passes ([check], [load])
    if (progressQuiet) opening.emplace(*progressQuiet);
    auto openTriangles = [&] {
        TriangleSourcePtr source = openGeometryFile(inPath);
        if (!progressQuiet) return source;
        const std::string phase = "convert " + std::filesystem::path(inPath).filename().string();
        return TriangleSourcePtr(std::make_unique<ProgressSource>(std::move(source), phase, *progressQuiet));
    };
    if (out == ".glb" || out == ".gltf") {
        GltfStreamWriter writer(outPath, out == ".glb");
        if (in && *in != GeometryFormat::Ptri) {
            // Meshes keep their normals, texture coordinates and names; corners are welded.
            checkInputFile(inPath);
            addMeshesOfFile(inPath, writer);
        } else {  // a triangle stream: corners shared by position
            addTrianglesOf(*openTriangles(), writer, std::filesystem::path(outPath).stem().string(), GltfStreamWriter::Indexing::Welded);
        }
        return writer.commit();
    }
    if (in == GeometryFormat::Gltf) warnIfMaterialsDropped(inPath, loadGltfDocument(inPath));
    convertGeometry(*openTriangles(), outPath);
}

}  // namespace penumbra
