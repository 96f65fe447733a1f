#include "stream/GltfDocument.h"

#include "stream/util/Error.h"
#include "stream/GltfJson.h"
#include "stream/GltfMaterials.h"
#include "stream/GltfTranslucency.h"
#include "stream/util/InputFile.h"
#include "stream/util/PathText.h"
#include "stream/util/JsonText.h"
#include "stream/util/RegularFile.h"
#include "stream/util/SafePath.h"

#include <nlohmann/json.hpp>

#include <glm/gtc/matrix_transform.hpp>
#include <glm/gtc/quaternion.hpp>
#include <glm/gtc/type_ptr.hpp>

#include <cerrno>
#include <cmath>
#include <cstring>
#include <filesystem>
#include <optional>
#include <tuple>
#include <limits>
#include <mutex>
#include <set>


namespace penumbra {
namespace {

using Json = GltfJson;
using Members = GltfMembers;

constexpr uint32_t kGlbMagic = 0x46546C67u, kJsonChunk = 0x4E4F534Au, kBinChunk = 0x004E4942u;

uint32_t u32(const unsigned char* p) {
    uint32_t v;
    std::memcpy(&v, p, 4);
    return v;
}

/// Reads the JSON text; for a .glb also locates the BIN chunk (offset and length in the file).
std::string readJsonText(const std::string& path, std::optional<std::pair<uint64_t, uint64_t>>& bin) {
    RegularFile file(path);
    unsigned char header[20] = {};
    file.read(header, size_t(std::min<uint64_t>(file.size(), 20)), 0);
    if (file.size() == 0) fail(path, "is empty");
    // Told apart by content, but a .glb that is not one is named so, not as the JSON parser's
    // complaint about its first byte.
    if (lowercaseExtension(path) == ".glb" && (file.size() < 4 || u32(header) != kGlbMagic))
        fail(path, "is not a GLB file: it starts with \"{}\", not \"glTF\"",
             printableLine(std::string_view(reinterpret_cast<const char*>(header), size_t(std::min<uint64_t>(file.size(), 4)))));
    if (file.size() >= 4 && u32(header) == kGlbMagic) {
        if (file.size() < 20) fail(path, "truncated GLB header (expected at least 20 bytes, found {})", file.size());
        if (uint32_t version = u32(header + 4); version != 2) fail(path, "unsupported GLB version {}", version);
        const uint64_t length = u32(header + 8), jsonLength = u32(header + 12);
        if (length > file.size()) fail(path, "truncated (GLB header declares {} bytes, file has {})", length, file.size());
        if (u32(header + 16) != kJsonChunk) fail(path, "first GLB chunk is not JSON");
        const uint64_t binStart = 20 + jsonLength;
        if (binStart > length) fail(path, "GLB JSON chunk ({} bytes) runs past the end of the file", jsonLength);
        if (binStart < length) {
            if (binStart + 8 > length) fail(path, "truncated GLB chunk header after the JSON chunk");
            unsigned char chunk[8];
            file.read(chunk, 8, binStart);
            const uint64_t binLength = u32(chunk);
            if (binStart + 8 + binLength > length)
                fail(path, "GLB BIN chunk ({} bytes) runs past the end of the file", binLength);
            if (u32(chunk + 4) != kBinChunk) fail(path, "second GLB chunk is not BIN");
            bin.emplace(binStart + 8, binLength);
        }
        std::string text(size_t(jsonLength), '\0');
        file.read(text.data(), text.size(), 20);
        return text;
    }
    std::string text(size_t(file.size()), '\0');
    file.read(text.data(), text.size(), 0);
    return text;
}

}  // namespace

uint64_t gltfJsonTextBytes(const std::string& path) {
    try {
        RegularFile file(path);
        unsigned char header[16] = {};
        if (file.size() < sizeof(header)) return file.size();
        file.read(header, sizeof(header), 0);
        if (u32(header) != kGlbMagic) return file.size();          // a .gltf: all of it is JSON
        return std::min<uint64_t>(u32(header + 12), file.size());  // the JSON chunk's length
    } catch (const InputError&) {
        return 0;
    }
}

uint64_t gltfJsonObjectCount(const std::string& path) {
    std::string text;
    try {
        std::optional<std::pair<uint64_t, uint64_t>> bin;
        text = readJsonText(path, bin);
    } catch (const InputError&) {
        return 0;  // opening says why
    }
    uint64_t objects = 0;
    bool inString = false;
    for (size_t i = 0; i < text.size(); ++i) {
        const char c = text[i];
        if (inString) {
            if (c == '\\') ++i;
            else if (c == '"') inString = false;
        } else if (c == '"') {
            inString = true;
        } else {
            objects += c == '{';
        }
    }
    return objects;
}

namespace {

int componentsOf(const std::string& type) {
    if (type == "SCALAR") return 1;
    if (type == "VEC2") return 2;
    if (type == "VEC3") return 3;
    if (type == "VEC4" || type == "MAT2") return 4;
    if (type == "MAT3") return 9;
    if (type == "MAT4") return 16;
    return 0;
}

GltfBuffer parseBuffer(const std::string& path, const Json& j, size_t i, const std::optional<std::pair<uint64_t, uint64_t>>& bin) {
    Members m{path, j, fmt::format("buffer {}", i)};
    GltfBuffer b;
    b.byteLength = m.required("byteLength");
    const std::string uri = m.string("uri");
    if (uri.empty()) {
        if (i == 0 && bin) {
            if (b.byteLength > bin->second)
                fail(path, "buffer 0 byteLength {} is larger than the GLB BIN chunk ({} bytes)", b.byteLength, bin->second);
            b.source = GltfBuffer::Source::GlbChunk, b.file = path, b.fileOffset = bin->first;
        }
        return b;  // without a source: only meshopt fallback views may refer to it (checked with the views)
    }
    if (uri.rfind("data:", 0) == 0) {
        const size_t comma = uri.find(',');
        if (comma == std::string::npos || uri.substr(0, comma).find(";base64") == std::string::npos)
            fail(path, "buffer {}: only base64 data URIs are supported", i);
        // The larger of what byteLength claims and what the URI holds (its base64 decodes to
        // three bytes per four characters), so that the message names the size that is too large.
        const uint64_t held = (uri.size() - comma - 1) / 4 * 3;
        if (b.byteLength > kMaxDataUriBytes || held > kMaxDataUriBytes + 3)
            fail(path, "buffer {}: an embedded data: URI of {} bytes is above the {} MiB limit for embedded buffers (they "
                 "cannot be read in windows); store it as a .bin file or write a .glb", i, std::max<uint64_t>(b.byteLength, held),
                 kMaxDataUriBytes >> 20);
        if (!decodeGltfBase64(std::string_view(uri).substr(comma + 1), b.bytes))
            fail(path, "buffer {}: malformed base64 in its data: URI", i);
        if (b.bytes.size() < b.byteLength)
            fail(path, "buffer {}: its data: URI holds {} bytes, byteLength says {}", i, b.bytes.size(), b.byteLength);
        b.bytes.resize(size_t(b.byteLength));
        b.source = GltfBuffer::Source::DataUri;
        return b;
    }
    if (uri.find("://") != std::string::npos) fail(path, "buffer {}: URI \"{}\" is not a local file", i, uri);
    std::filesystem::path base = std::filesystem::path(path).parent_path();
    // The URI must stay in the model's directory (SafePath.h), and is recorded as an input so
    // that no output of the bake replaces it.
    b.file = containedPath(base, gltfPercentDecoded(uri), fmt::format("{}: buffers[{}].uri", path, i), "the model's directory");
    // A missing or unreadable buffer file is named with the model that wants it ("nope.bin:
    // cannot open" said nothing of which glTF, or which scene entry, that was).
    std::optional<RegularFile> opened;
    try {
        checkInputFile(b.file);
        opened.emplace(b.file);  // a regular file, or an error naming it
    } catch (const InputError& e) {
        throw InputError(fmt::format("{} (buffer {} of {})", e.what(), i, path));
    }
    const RegularFile& file = *opened;
    if (file.size() < b.byteLength)
        fail(path, "buffer {} ({}) has {} bytes, but its byteLength is {}", i, uri, file.size(), b.byteLength);
    b.source = GltfBuffer::Source::File;
    return b;
}

GltfBufferView parseView(const std::string& path, const Json& j, size_t i, const std::vector<GltfBuffer>& buffers) {
    Members m{path, j, fmt::format("bufferView {}", i)};
    GltfBufferView v;
    v.buffer = m.index("buffer");
    v.byteOffset = m.unsignedOr("byteOffset", 0);
    v.byteLength = m.required("byteLength");
    const uint64_t stride = m.unsignedOr("byteStride", 0);
    if (stride != 0 && (stride < 4 || stride > 252)) fail(path, "bufferView {} byteStride {} is not in [4, 252]", i, stride);
    v.byteStride = uint32_t(stride);
    auto within = [&](int buffer, uint64_t offset, uint64_t length, const char* what) {
        if (buffer < 0 || size_t(buffer) >= buffers.size())
            fail(path, "bufferView {}{} refers to buffer {} (file has {})", i, what, buffer, buffers.size());
        uint64_t end = 0;
        const uint64_t bytes = buffers[size_t(buffer)].byteLength;
        if (__builtin_add_overflow(offset, length, &end) || end > bytes)
            fail(path, "bufferView {}{} (bytes {}..+{}) lies outside buffer {} ({} bytes)", i, what, offset, length, buffer, bytes);
    };
    within(v.buffer, v.byteOffset, v.byteLength, "");
    const Json& extensions = m.objectAt("extensions");
    if (auto it = extensions.find("EXT_meshopt_compression"); it != extensions.end()) {
        if (!it->is_object()) fail(path, "bufferView {} EXT_meshopt_compression must be an object", i);
        Members e{path, *it, fmt::format("bufferView {} EXT_meshopt_compression", i)};
        GltfMeshoptView c;
        c.buffer = e.index("buffer");
        c.byteOffset = e.unsignedOr("byteOffset", 0);
        c.byteLength = e.required("byteLength");
        c.byteStride = uint32_t(std::min<uint64_t>(e.required("byteStride"), 1u << 20));
        c.count = e.required("count");
        within(c.buffer, c.byteOffset, c.byteLength, " EXT_meshopt_compression");
        const std::string mode = e.string("mode"), filter = e.string("filter");
        if (mode == "ATTRIBUTES") c.mode = GltfMeshoptView::Mode::Attributes;
        else if (mode == "TRIANGLES") c.mode = GltfMeshoptView::Mode::Triangles;
        else if (mode == "INDICES") c.mode = GltfMeshoptView::Mode::Indices;
        else fail(path, "bufferView {} EXT_meshopt_compression: unknown mode \"{}\"", i, mode);
        if (filter.empty() || filter == "NONE") c.filter = GltfMeshoptView::Filter::None;
        else if (filter == "OCTAHEDRAL") c.filter = GltfMeshoptView::Filter::Octahedral;
        else if (filter == "QUATERNION") c.filter = GltfMeshoptView::Filter::Quaternion;
        else if (filter == "EXPONENTIAL") c.filter = GltfMeshoptView::Filter::Exponential;
        else fail(path, "bufferView {} EXT_meshopt_compression: unknown filter \"{}\"", i, filter);
        const bool attributes = c.mode == GltfMeshoptView::Mode::Attributes;
        if ((attributes && (c.byteStride == 0 || c.byteStride > 256 || c.byteStride % 4 != 0)) ||
            (!attributes && c.byteStride != 2 && c.byteStride != 4))
            fail(path, "bufferView {} EXT_meshopt_compression: byteStride {} is invalid for mode {}", i, c.byteStride, mode);
        uint64_t decoded = 0;
        if (__builtin_mul_overflow(c.count, uint64_t(c.byteStride), &decoded) || decoded > v.byteLength)
            fail(path, "bufferView {} EXT_meshopt_compression: {} elements of {} bytes do not fit its {} bytes", i, c.count,
                 c.byteStride, v.byteLength);
        v.meshopt = c;
    } else if (buffers[size_t(v.buffer)].source == GltfBuffer::Source::None) {
        fail(path, "bufferView {} refers to buffer {}, which has no uri (and the file is not a .glb holding it)", i, v.buffer);
    }
    return v;
}

/// Fails unless @p count elements of @p elementBytes, @p stride apart from @p offset, lie inside
/// bufferView @p view: offset + stride * (count - 1) + elementBytes, every step overflow-checked,
/// since the operands come straight from the JSON. @p what names the reader ("accessor 3").
void checkInsideView(const std::string& path, const std::string& what, const std::vector<GltfBufferView>& views, int view,
                     uint64_t offset, uint64_t stride, uint64_t count, uint64_t elementBytes) {
    if (view < 0 || size_t(view) >= views.size()) fail(path, "{} refers to bufferView {} (file has {})", what, view, views.size());
    if (count == 0) return;
    const uint64_t length = views[size_t(view)].byteLength;
    uint64_t needed = 0;
    const bool overflow = __builtin_mul_overflow(stride, count - 1, &needed) || __builtin_add_overflow(needed, offset, &needed) ||
                          __builtin_add_overflow(needed, elementBytes, &needed);
    if (overflow) fail(path, "{} reads past the end of bufferView {} (needs more than 2^64 bytes, has {})", what, view, length);
    if (needed > length) fail(path, "{} reads past the end of bufferView {} (needs {} bytes, has {})", what, view, needed, length);
}

GltfSparse parseSparse(const std::string& path, const Json& j, size_t i, const GltfAccessor& a,
                       const std::vector<GltfBufferView>& views) {
    const std::string what = fmt::format("accessor {} sparse", i);
    if (!j.is_object()) fail(path, "{} must be an object", what);
    Members m{path, j, what};
    GltfSparse s;
    s.count = m.required("count");
    if (s.count == 0 || s.count > a.count)
        fail(path, "{} count {} must be in 1..{} (the accessor's count)", what, s.count, a.count);
    if (!m.find("indices") || !m.find("values")) fail(path, "{} needs both indices and values", what);
    Members indices{path, m.objectAt("indices"), what + " indices"};
    Members values{path, m.objectAt("values"), what + " values"};
    s.indicesView = int(std::min<uint64_t>(indices.required("bufferView"), uint64_t(std::numeric_limits<int>::max())));
    s.indicesOffset = indices.unsignedOr("byteOffset", 0);
    s.indexType = int(std::min<uint64_t>(indices.required("componentType"), uint64_t(std::numeric_limits<int>::max())));
    if (s.indexType != kGltfUnsignedByte && s.indexType != kGltfUnsignedShort && s.indexType != kGltfUnsignedInt)
        fail(path, "{} indices componentType {} must be an unsigned integer type", what, s.indexType);
    s.valuesView = int(std::min<uint64_t>(values.required("bufferView"), uint64_t(std::numeric_limits<int>::max())));
    s.valuesOffset = values.unsignedOr("byteOffset", 0);
    const uint64_t indexBytes = uint64_t(gltfComponentBytes(s.indexType));
    checkInsideView(path, what + " indices", views, s.indicesView, s.indicesOffset, indexBytes, s.count, indexBytes);
    checkInsideView(path, what + " values", views, s.valuesView, s.valuesOffset, a.elementBytes, s.count, a.elementBytes);
    // Both arrays are tightly packed whatever the view says; a stride that disagrees would leave
    // the layout ambiguous.
    for (const auto& [view, bytes, name] : {std::tuple{s.indicesView, indexBytes, "indices"}, std::tuple{s.valuesView, uint64_t(a.elementBytes), "values"}}) {
        const uint32_t stride = views[size_t(view)].byteStride;
        if (stride != 0 && stride != bytes)
            fail(path, "{} {}: bufferView {} has byteStride {}, but sparse arrays are tightly packed ({} bytes)", what, name,
                 view, stride, bytes);
    }
    return s;
}

GltfAccessor parseAccessor(const std::string& path, const Json& j, size_t i, const std::vector<GltfBufferView>& views) {
    Members m{path, j, fmt::format("accessor {}", i)};
    GltfAccessor a;
    a.componentType = int(m.required("componentType"));
    const int componentBytes = gltfComponentBytes(a.componentType);
    if (componentBytes == 0) fail(path, "accessor {} has invalid componentType {}", i, a.componentType);
    const std::string type = m.string("type");
    a.components = componentsOf(type);
    if (a.components == 0) fail(path, "accessor {} has invalid type \"{}\"", i, type);
    const Json* normalized = m.find("normalized");
    a.normalized = normalized && normalized->is_boolean() && normalized->get<bool>();
    a.count = m.required("count");
    a.byteOffset = m.unsignedOr("byteOffset", 0);
    a.elementBytes = uint32_t(componentBytes * a.components);
    if (const Json* sparse = m.find("sparse")) a.sparse = parseSparse(path, *sparse, i, a, views);
    a.bufferView = m.index("bufferView");
    if (a.bufferView < 0) return a;  // zeros (or a Draco-decoded primitive's attribute)
    if (size_t(a.bufferView) >= views.size())
        fail(path, "accessor {} refers to bufferView {} (file has {})", i, a.bufferView, views.size());
    const GltfBufferView& view = views[size_t(a.bufferView)];
    const uint32_t stride = view.meshopt ? view.meshopt->byteStride : view.byteStride;
    a.stride = stride == 0 ? a.elementBytes : stride;
    if (a.stride < a.elementBytes)
        fail(path, "accessor {}: bufferView {} byteStride {} is smaller than the {}-byte element", i, a.bufferView, stride,
             a.elementBytes);
    checkInsideView(path, fmt::format("accessor {}", i), views, a.bufferView, a.byteOffset, a.stride, a.count, a.elementBytes);
    return a;
}

std::vector<std::pair<std::string, int>> indexMap(const std::string& path, const Json& object, const std::string& what) {
    std::vector<std::pair<std::string, int>> out;
    for (auto it = object.begin(); it != object.end(); ++it) {
        if (!it->is_number_integer() || it->get<int64_t>() < 0 || it->get<int64_t>() > std::numeric_limits<int>::max())
            fail(path, "{} {} must be a non-negative index", what, it.key());
        out.emplace_back(it.key(), it->get<int>());
    }
    return out;
}

/// The VEC size glTF 2.0 requires of a vertex attribute that penumbra reads (POSITION, NORMAL,
/// TEXCOORD_n), or 0 for others. Checked as the file opens, so that every command refuses the same
/// file: a MASK material's TEXCOORD_0 of VEC3 went unread by a bake when the texture was uniform,
/// while convert to glTF refused it.
int requiredComponents(const std::string& attribute) {
    if (attribute == "POSITION" || attribute == "NORMAL") return 3;
    if (attribute.starts_with("TEXCOORD_")) return 2;
    return 0;
}

GltfMeshDesc parseMesh(const GltfDocument& doc, const Json& j, size_t i) {
    const std::string& path = doc.path;
    Members m{path, j, fmt::format("mesh {}", i)};
    GltfMeshDesc mesh;
    mesh.name = m.string("name");
    const Json* primitives = m.find("primitives");
    if (!primitives || !primitives->is_array()) fail(path, "mesh {} has no primitives array", i);
    for (size_t p = 0; p < primitives->size(); ++p) {
        const Json& pj = (*primitives)[p];
        const std::string where = fmt::format("mesh {} primitive {}", i, p);
        if (!pj.is_object()) fail(path, "{} must be an object", where);
        Members pm{path, pj, where};
        GltfPrimitiveDesc prim;
        prim.attributes = indexMap(path, pm.objectAt("attributes"), where + " attribute");
        for (const auto& [name, accessor] : prim.attributes)
            if (size_t(accessor) >= doc.accessors.size())
                fail(path, "{}: attribute {} refers to accessor {} (file has {})", where, name, accessor, doc.accessors.size());
            else if (const int want = requiredComponents(name); want && doc.accessors[size_t(accessor)].components != want)
                fail(path, "{}: {} accessor {} is not VEC{}", where, name, accessor, want);
            else if ((name == "POSITION" || name == "NORMAL") && !doc.meshQuantization &&
                     doc.accessors[size_t(accessor)].componentType != kGltfFloat)
                // Read as integers, a float file's bytes made garbage geometry with exit 0.
                fail(path, "{}: {} accessor {} has componentType {}, not FLOAT, and the file does not declare "
                     "KHR_mesh_quantization", where, name, accessor, doc.accessors[size_t(accessor)].componentType);
        prim.indices = pm.index("indices");
        if (prim.indices >= int(doc.accessors.size()))
            fail(path, "{}: indices refer to accessor {} (file has {})", where, prim.indices, doc.accessors.size());
        prim.mode = int(pm.unsignedOr("mode", kGltfTriangles));
        prim.material = pm.index("material");
        if (prim.material >= int(doc.materials.materials.size()))
            fail(path, "{}: refers to material {} (file has {})", where, prim.material, doc.materials.materials.size());
        if (prim.mode > kGltfTriangleFan) fail(path, "{}: invalid mode {}", where, prim.mode);
        const Json& extensions = pm.objectAt("extensions");
        if (auto it = extensions.find("KHR_draco_mesh_compression"); it != extensions.end()) {
            if (!it->is_object()) fail(path, "{}: KHR_draco_mesh_compression must be an object", where);
            Members d{path, *it, where + " KHR_draco_mesh_compression"};
            GltfDraco draco;
            draco.bufferView = d.index("bufferView");
            if (draco.bufferView < 0 || size_t(draco.bufferView) >= doc.views.size())
                fail(path, "{}: KHR_draco_mesh_compression refers to bufferView {} (file has {})", where, draco.bufferView,
                     doc.views.size());
            draco.attributes = indexMap(path, d.objectAt("attributes"), where + " KHR_draco_mesh_compression attribute");
            prim.draco = std::move(draco);
        }
        mesh.primitives.push_back(std::move(prim));
    }
    return mesh;
}

glm::dmat4 localMatrix(const std::string& path, const Members& m, size_t index, bool& matrixOverTrs) {
    auto check = [&](const std::vector<double>& values, size_t expected, const char* what) {
        if (!values.empty() && values.size() != expected)
            fail(path, "node {} {} has {} values (needs {})", index, what, values.size(), expected);
        for (double x : values)
            if (!std::isfinite(x)) fail(path, "node {} {} is not finite", index, what);
        return !values.empty();
    };
    const std::vector<double> matrix = m.numbers("matrix"), t = m.numbers("translation"), q = m.numbers("rotation"),
                              s = m.numbers("scale");
    const bool hasT = check(t, 3, "translation"), hasR = check(q, 4, "rotation"), hasS = check(s, 3, "scale");
    if (check(matrix, 16, "matrix")) {
        // glTF 2.0 allows a matrix or TRS, not both. Viewers use the matrix, and so does this;
        // the TRS was dropped without a word. TRS at its defaults (some exporters write them)
        // says nothing and goes unremarked.
        const bool identityTrs = (!hasT || (t[0] == 0 && t[1] == 0 && t[2] == 0)) &&
                                 (!hasR || (q[0] == 0 && q[1] == 0 && q[2] == 0 && q[3] == 1)) &&
                                 (!hasS || (s[0] == 1 && s[1] == 1 && s[2] == 1));
        matrixOverTrs = !identityTrs;
        return glm::make_mat4(matrix.data());  // both column-major
    }
    glm::dmat4 local(1.0);
    if (hasT) local = glm::translate(local, glm::dvec3(t[0], t[1], t[2]));
    if (hasR) local *= glm::mat4_cast(glm::normalize(glm::dquat(q[3], q[0], q[1], q[2])));  // glTF order x, y, z, w
    if (hasS) local = glm::scale(local, glm::dvec3(s[0], s[1], s[2]));
    return local;
}

GltfNodeDesc parseNode(const GltfDocument& doc, const Json& j, size_t i, size_t nodeCount) {
    const std::string& path = doc.path;
    Members m{path, j, fmt::format("node {}", i)};
    GltfNodeDesc node;
    node.name = m.string("name");
    node.mesh = m.index("mesh");
    if (node.mesh >= int(doc.meshes.size())) fail(path, "node {} refers to mesh {} (file has {})", i, node.mesh, doc.meshes.size());
    if (const Json* children = m.find("children")) {
        if (!children->is_array()) fail(path, "node {} children must be an array", i);
        for (const Json& c : *children) {
            if (!c.is_number_integer()) fail(path, "node {} children must be node indices", i);
            const int64_t child = c.get<int64_t>();
            if (child < 0 || uint64_t(child) >= nodeCount) fail(path, "node {} has child {} (file has {} nodes)", i, child, nodeCount);
            node.children.push_back(int(child));
        }
    }
    node.local = localMatrix(path, m, i, node.matrixOverTrs);
    const Json& extensions = m.objectAt("extensions");
    if (auto it = extensions.find("EXT_mesh_gpu_instancing"); it != extensions.end() && it->is_object()) {
        Members e{path, *it, fmt::format("node {} EXT_mesh_gpu_instancing", i)};
        for (const auto& [name, accessor] : indexMap(path, e.objectAt("attributes"), e.what + " attribute")) {
            if (size_t(accessor) >= doc.accessors.size())
                fail(path, "{} attribute {} refers to accessor {} (file has {})", e.what, name, accessor, doc.accessors.size());
            if (name == "TRANSLATION") node.instanceTranslation = accessor;
            else if (name == "ROTATION") node.instanceRotation = accessor;
            else if (name == "SCALE") node.instanceScale = accessor;
        }
    }
    return node;
}

void findRoots(const Json& root, GltfDocument& doc) {
    const std::string& path = doc.path;
    const Json& scenes = gltfArrayOf(path, root, "scenes");
    int scene = -1;
    if (auto it = root.find("scene"); it != root.end()) {
        if (!it->is_number_integer() || it->get<int64_t>() < 0) fail(path, "\"scene\" must be a scene index");
        if (it->get<uint64_t>() >= scenes.size())
            fail(path, "default scene {} does not exist (file has {})", it->get<uint64_t>(), scenes.size());
        scene = it->get<int>();
    }
    if (scene < 0 && !scenes.empty()) scene = 0;
    if (scene >= 0) {
        Members m{path, scenes[size_t(scene)], fmt::format("scene {}", scene)};
        if (const Json* nodes = m.find("nodes")) {
            if (!nodes->is_array()) fail(path, "scene {} nodes must be an array", scene);
            for (const Json& n : *nodes) {
                if (!n.is_number_integer() || n.get<int64_t>() < 0 || n.get<uint64_t>() >= doc.nodes.size())
                    fail(path, "scene {} refers to node {} (file has {})", scene, n.dump(), doc.nodes.size());
                doc.roots.push_back(n.get<int>());
            }
        }
        return;
    }
    // No scenes: every node that is nobody's child is a root.
    std::vector<bool> isChild(doc.nodes.size(), false);
    for (const GltfNodeDesc& node : doc.nodes)
        for (int child : node.children) isChild[size_t(child)] = true;
    for (size_t n = 0; n < doc.nodes.size(); ++n)
        if (!isChild[n]) doc.roots.push_back(int(n));
}

/// glTF 2.0 requires "asset" with a "version". Without the check a file lacking it baked as
/// blockers, but a vertex bake, whose output is written through tinygltf, failed only after its
/// cast; and a glTF 1.0 file (another format) read as if it were 2.0.
void checkAsset(const std::string& path, const Json& root) {
    const auto asset = root.find("asset");
    if (asset == root.end() || !asset->is_object()) fail(path, "has no \"asset\" object, which glTF 2.0 requires");
    const auto version = asset->find("version");
    if (version == asset->end() || !version->is_string()) fail(path, "asset.version must be a string such as \"2.0\"");
    const std::string v = version->get<std::string>();
    if (v.rfind("2.", 0) != 0) fail(path, "is glTF version \"{}\"; penumbra reads glTF 2.x", v);
}

void checkRequiredExtensions(const std::string& path, const Json& root) {
    static const char* known[] = {"KHR_mesh_quantization", "EXT_mesh_gpu_instancing", "EXT_meshopt_compression",
                                  "KHR_draco_mesh_compression", "KHR_materials_unlit", "KHR_texture_transform",
                                  "KHR_materials_transmission",
                                  "KHR_texture_basisu", "EXT_texture_webp"};
    auto it = root.find("extensionsRequired");
    if (it == root.end() || !it->is_array()) return;
    for (const Json& e : *it) {
        if (!e.is_string()) fail(path, "extensionsRequired must hold strings");
        const std::string name = e.get<std::string>();
        if (std::none_of(std::begin(known), std::end(known), [&](const char* k) { return name == k; }))
            fail(path, "requires the glTF extension {}, which penumbra does not support", name);
    }
}

}  // namespace

int GltfPrimitiveDesc::attribute(const std::string& name) const {
    for (const auto& [n, accessor] : attributes)
        if (n == name) return accessor;
    return -1;
}

int gltfComponentBytes(int componentType) {
    switch (componentType) {
    case kGltfByte:
    case kGltfUnsignedByte: return 1;
    case kGltfShort:
    case kGltfUnsignedShort: return 2;
    case kGltfUnsignedInt:
    case kGltfFloat: return 4;
    default: return 0;
    }
}

uint64_t GltfDocument::residentBytes() const {
    uint64_t bytes = sizeof(*this) + buffers.size() * sizeof(GltfBuffer) + views.size() * sizeof(GltfBufferView) +
                     accessors.size() * sizeof(GltfAccessor) + nodes.size() * (sizeof(GltfNodeDesc) + 16) + roots.size() * 4 +
                     materialAlphaIds.size() * sizeof(uint32_t);
    for (const GltfBuffer& b : buffers) bytes += b.bytes.capacity() + b.file.capacity();
    for (const GltfMeshDesc& m : meshes)
        bytes += sizeof(GltfMeshDesc) + m.primitives.size() * (sizeof(GltfPrimitiveDesc) + 4 * 48);
    return bytes;
}

namespace {

/// Whether this is the first warning of kind @p what about the document at @p path in this
/// process: a bake loads a document more than once (alpha planning, the blocker stream, receiver
/// meshes), and said so as many times.
bool firstWarningAbout(const std::string& path, const char* what) {
    static std::mutex mutex;
    static std::set<std::pair<std::string, std::string>> warned;
    std::lock_guard lock(mutex);
    return warned.emplace(path, what).second;
}

bool anyNonZero(const Json& weights) {
    if (!weights.is_array()) return false;
    return std::any_of(weights.begin(), weights.end(), [](const Json& w) { return w.is_number() && w.get<double>() != 0.0; });
}

/// Morph targets at non-zero weights and skins pose a mesh in a viewer; a bake takes the base
/// positions in the node's transform, so it says so (a blocker posed elsewhere cast its shadow
/// from its rest place, silently).
void warnUnposed(const std::string& path, const Json& root) {
    const Json& meshes = gltfArrayOf(path, root, "meshes");
    const Json& nodes = gltfArrayOf(path, root, "nodes");
    std::vector<bool> weighted(meshes.size(), false);
    for (size_t m = 0; m < meshes.size(); ++m) weighted[m] = meshes[m].is_object() && anyNonZero(meshes[m].value("weights", Json()));
    size_t skinned = 0;
    for (const Json& n : nodes) {
        if (!n.is_object()) continue;
        skinned += n.contains("skin");
        const Json mesh = n.value("mesh", Json());
        if (mesh.is_number_unsigned() && mesh.get<uint64_t>() < meshes.size() && anyNonZero(n.value("weights", Json())))
            weighted[mesh.get<uint64_t>()] = true;
    }
    size_t morphed = 0;
    for (size_t m = 0; m < meshes.size(); ++m) {
        if (!weighted[m] || !meshes[m].contains("primitives") || !meshes[m]["primitives"].is_array()) continue;
        for (const Json& p : meshes[m]["primitives"])
            if (p.is_object() && p.contains("targets") && p["targets"].is_array() && !p["targets"].empty()) {
                ++morphed;
                break;
            }
    }
    if (morphed && firstWarningAbout(path, "morph"))
        printWarning("{}: {} mesh(es) have morph targets at non-zero weights; they are baked at their base positions "
                     "(morph targets are not applied)", path, morphed);
    if (skinned && firstWarningAbout(path, "skin"))
        printWarning("{}: {} node(s) are skinned; their meshes are baked in the node's transform, unposed (skins are not "
                     "applied)", path, skinned);
}

}  // namespace

namespace {

/// Records the model's image files as inputs of the run, read or not: a copy of the model (a
/// vertex bake's) still refers to them, and a bake's preview written over one (out NAME.glb,
/// preview NAME.png, a texture NAME.png) replaced it with exit 0. Missing ones, and URIs outside
/// the model's directory, are the readers' business where they read them.
void recordImageFiles(const std::string& path, const Json& root) {
    const auto images = root.find("images");
    if (images == root.end() || !images->is_array()) return;
    const std::filesystem::path base = std::filesystem::path(path).parent_path();
    for (const Json& image : *images) {
        const auto uri = image.is_object() ? image.find("uri") : image.end();
        if (!image.is_object() || uri == image.end() || !uri->is_string()) continue;
        const std::string text = uri->get<std::string>();
        if (text.empty() || text.rfind("data:", 0) == 0 || text.find("://") != std::string::npos) continue;
        recordReferencedFile((base / gltfPercentDecoded(text)).lexically_normal().string());
    }
}

}  // namespace

GltfDocument loadGltfDocument(const std::string& path) {
    GltfDocument doc;
    doc.path = path;
    std::optional<std::pair<uint64_t, uint64_t>> bin;
    Json root;
    {
        std::string text = readJsonText(path, bin);
        doc.jsonBytes = text.size();
        checkJsonDepth(text, path);
        try {
            root = Json::parse(text);
        } catch (const std::exception& e) {
            fail(path, "{}", e.what());
        }
    }
    if (!root.is_object()) fail(path, "the glTF JSON is not an object");
    checkAsset(path, root);
    checkRequiredExtensions(path, root);
    for (const char* list : {"extensionsUsed", "extensionsRequired"})
        if (auto it = root.find(list); it != root.end() && it->is_array())
            for (const Json& e : *it) doc.meshQuantization = doc.meshQuantization || e == "KHR_mesh_quantization";
    const Json& buffers = gltfArrayOf(path, root, "buffers");
    for (size_t i = 0; i < buffers.size(); ++i) doc.buffers.push_back(parseBuffer(path, buffers[i], i, bin));
    const Json& views = gltfArrayOf(path, root, "bufferViews");
    for (size_t i = 0; i < views.size(); ++i) doc.views.push_back(parseView(path, views[i], i, doc.buffers));
    const Json& accessors = gltfArrayOf(path, root, "accessors");
    for (size_t i = 0; i < accessors.size(); ++i) doc.accessors.push_back(parseAccessor(path, accessors[i], i, doc.views));
    doc.materials = parseGltfMaterials(path, root, doc.views.size());
    doc.materialAlphaIds = gltfMaterialAlphaIds(path, root);
    const Json& meshes = gltfArrayOf(path, root, "meshes");
    for (size_t i = 0; i < meshes.size(); ++i) doc.meshes.push_back(parseMesh(doc, meshes[i], i));
    const Json& nodes = gltfArrayOf(path, root, "nodes");
    size_t matrixOverTrs = 0, firstOverTrs = 0;
    for (size_t i = 0; i < nodes.size(); ++i) {
        doc.nodes.push_back(parseNode(doc, nodes[i], i, nodes.size()));
        if (doc.nodes.back().matrixOverTrs && !matrixOverTrs++) firstOverTrs = i;
    }
    if (matrixOverTrs && firstWarningAbout(path, "matrix"))
        printWarning("{}: {} node(s) (node {} first) have both a matrix and a translation, rotation or scale, which glTF 2.0 "
                     "does not allow; the matrix is used, as viewers do", path, matrixOverTrs, firstOverTrs);
    warnUnposed(path, root);
    findRoots(root, doc);
    recordImageFiles(path, root);
    return doc;
}

std::vector<GltfMeshNode> walkGltfScene(const GltfDocument& doc) {
    // Iterative depth-first walk. glTF requires the hierarchy to be a forest; reaching a node
    // twice means a cycle (infinite recursion) or a shared child (exponential instancing), both
    // rejected. Sharing a mesh between nodes is the way to instance, and is fine.
    std::vector<GltfMeshNode> placed;
    std::vector<bool> reached(doc.nodes.size(), false);
    std::vector<std::pair<int, glm::dmat4>> stack;
    for (auto r = doc.roots.rbegin(); r != doc.roots.rend(); ++r) stack.emplace_back(*r, glm::dmat4(1.0));
    while (!stack.empty()) {
        auto [n, parent] = stack.back();
        stack.pop_back();
        if (reached[size_t(n)]) fail(doc.path, "node {} is reached twice (the node hierarchy must be a tree)", n);
        reached[size_t(n)] = true;
        const GltfNodeDesc& node = doc.nodes[size_t(n)];
        const glm::dmat4 world = parent * node.local;
        if (node.mesh >= 0) placed.push_back({n, node.mesh, world});
        for (auto c = node.children.rbegin(); c != node.children.rend(); ++c) stack.emplace_back(*c, world);
    }
    return placed;
}

}  // namespace penumbra
