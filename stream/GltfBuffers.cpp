#include "stream/GltfBuffers.h"

#include "stream/util/AtomicFile.h"
#include "stream/util/Error.h"

#include <cstdint>
#include <cstring>
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

void writeGltfModel(tinygltf::Model& model, const std::string& path, bool binary) {
    std::ostringstream encoded;
    tinygltf::TinyGLTF writer;
    if (!writer.WriteGltfSceneToStream(&model, encoded, /*prettyPrint=*/!binary, binary) || !encoded)
        fail(path, "tinygltf could not encode the model");
    const std::string bytes = std::move(encoded).str();
    writeFileAtomically(path, std::span(reinterpret_cast<const uint8_t*>(bytes.data()), bytes.size()));
}

}  // namespace penumbra
