#include "stream/GltfBuffers.h"

#include "stream/util/AtomicFile.h"
#include "stream/util/Error.h"
#include "stream/GltfDocument.h"

#include <nlohmann/json.hpp>

#include <cstdint>
#include <cstring>
#include <filesystem>
#include <span>
#include <sstream>

namespace penumbra {

int appendGltfAccessor(tinygltf::Model& model, const void* bytes, size_t size, int componentType, int type, size_t count,
                       int target) {
    if (model.buffers.empty()) model.buffers.emplace_back();
    std::vector<unsigned char>& data = model.buffers[0].data;
    data.resize((data.size() + 3) / 4 * 4, 0);
    tinygltf::BufferView view;
    view.buffer = 0;
    view.byteOffset = data.size();
    view.byteLength = size;
    view.target = target;
    data.resize(data.size() + size);
    if (size > 0) std::memcpy(data.data() + view.byteOffset, bytes, size);
    model.bufferViews.push_back(view);
    tinygltf::Accessor accessor;
    accessor.bufferView = int(model.bufferViews.size() - 1);
    accessor.componentType = componentType;
    accessor.type = type;
    accessor.count = count;
    model.accessors.push_back(accessor);
    return int(model.accessors.size() - 1);
}

int appendGltfMeshNode(tinygltf::Model& model, const std::string& name, tinygltf::Primitive primitive) {
    tinygltf::Mesh mesh;
    mesh.name = name;
    mesh.primitives.push_back(std::move(primitive));
    model.meshes.push_back(std::move(mesh));
    tinygltf::Node node;
    node.name = name;
    node.mesh = int(model.meshes.size() - 1);
    model.nodes.push_back(std::move(node));
    return int(model.nodes.size() - 1);
}

namespace {

bool keepImageUri(const std::string*, const std::string*, const tinygltf::Image*, bool, std::string*, void*) {
    return false;  // never re-encode or move images: the copy keeps referring to the originals
}

}  // namespace

std::filesystem::path externalBufferPath(const std::string& path, size_t i, size_t count) {
    const std::filesystem::path p(path);
    return p.parent_path() / (p.stem().string() + (count == 1 ? std::string() : "-" + std::to_string(i)) + ".bin");
}

void writeGltfModel(tinygltf::Model& model, const std::string& path, bool binary, bool keepImageUris) {
    // A .gltf embeds its buffers as data: URIs only up to what a reader keeps in memory whole
    // (kMaxDataUriBytes: penumbra's own readers refuse more); larger ones go to .bin files beside
    // it, as exporters do. Every export above half a million triangles was unreadable before.
    std::vector<std::pair<size_t, std::vector<unsigned char>>> external;
    // (A .glb holds buffer 0 in its BIN chunk; any other buffer is a URI like a .gltf's.)
    for (size_t i = 0; i < model.buffers.size(); ++i)
        if ((!binary || i > 0) && model.buffers[i].data.size() > kMaxDataUriBytes) external.emplace_back(i, std::move(model.buffers[i].data));
    std::ostringstream encoded;
    tinygltf::TinyGLTF writer;
    if (keepImageUris) writer.SetImageWriter(&keepImageUri, nullptr);
    const bool ok = writer.WriteGltfSceneToStream(&model, encoded, /*prettyPrint=*/!binary, binary) && encoded;
    for (auto& [i, data] : external) model.buffers[i].data = std::move(data);  // the caller's model, unchanged
    if (!ok) fail(path, "tinygltf could not encode the model");
    std::string bytes = std::move(encoded).str();
    std::vector<std::filesystem::path> written;
    struct Cleanup {  // the .bin files go again if the .gltf is not written
        std::vector<std::filesystem::path>& files;
        bool keep = false;
        ~Cleanup() {
            std::error_code ignored;
            if (!keep) for (const auto& f : files) std::filesystem::remove(f, ignored);
        }
    } cleanup{written};
    if (!external.empty()) {
        nlohmann::json doc = nlohmann::json::parse(bytes);
        for (size_t k = 0; k < external.size(); ++k) {
            const size_t i = external[k].first;
            const std::vector<unsigned char>& data = model.buffers[i].data;
            const std::filesystem::path bin = externalBufferPath(path, k, external.size());
            writeFileAtomically(bin.string(), std::span(data.data(), data.size()));
            written.push_back(bin);
            doc["buffers"][i] = {{"byteLength", data.size()}, {"uri", bin.filename().string()}};
        }
        bytes = doc.dump(2);
    }
    writeFileAtomically(path, std::span(reinterpret_cast<const uint8_t*>(bytes.data()), bytes.size()));
    cleanup.keep = true;
}

}  // namespace penumbra
