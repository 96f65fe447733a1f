#include "bake/output/GltfBuffers.h"

#include <cstring>

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

}  // namespace penumbra
