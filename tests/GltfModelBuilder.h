#pragma once
/// @file GltfModelBuilder.h
/// @brief Small glTF models built in memory and saved with tinygltf's writer, for the reader's
/// tests. The writer does not validate, so malformed models are as easy to build.

#include "StreamTestFiles.h"

#include <catch2/catch.hpp>
#include <tiny_gltf.h>

#include <glm/vec3.hpp>

#include <sstream>
#include <string>
#include <vector>

namespace penumbra::test {

/// Builds a model into buffer 0; save() writes it as .glb or as .gltf with a data URI.
struct ModelBuilder {
    tinygltf::Model model;

    ModelBuilder() {
        model.asset.version = "2.0";
        model.buffers.emplace_back();
    }

    /// Appends bytes to buffer 0 (4-byte aligned) and returns a bufferView over them.
    int view(const void* data, size_t size, size_t stride = 0) {
        auto& bytes = model.buffers[0].data;
        bytes.resize((bytes.size() + 3) / 4 * 4);
        tinygltf::BufferView v;
        v.buffer = 0;
        v.byteOffset = bytes.size();
        v.byteLength = size;
        v.byteStride = stride;
        bytes.insert(bytes.end(), static_cast<const uint8_t*>(data), static_cast<const uint8_t*>(data) + size);
        model.bufferViews.push_back(v);
        return int(model.bufferViews.size() - 1);
    }
    template <typename T>
    int view(const std::vector<T>& values, size_t stride = 0) {
        return view(values.data(), values.size() * sizeof(T), stride);
    }

    int accessor(int bufferView, int componentType, int type, size_t count, bool normalized = false,
                 size_t byteOffset = 0) {
        tinygltf::Accessor a;
        a.bufferView = bufferView;
        a.componentType = componentType;
        a.type = type;
        a.count = count;
        a.normalized = normalized;
        a.byteOffset = byteOffset;
        model.accessors.push_back(a);
        return int(model.accessors.size() - 1);
    }

    int positions(const std::vector<glm::vec3>& points) {
        return accessor(view(points), TINYGLTF_COMPONENT_TYPE_FLOAT, TINYGLTF_TYPE_VEC3, points.size());
    }

    template <typename Index>
    int indices(const std::vector<Index>& values) {
        int type = sizeof(Index) == 1   ? TINYGLTF_COMPONENT_TYPE_UNSIGNED_BYTE
                   : sizeof(Index) == 2 ? TINYGLTF_COMPONENT_TYPE_UNSIGNED_SHORT
                                        : TINYGLTF_COMPONENT_TYPE_UNSIGNED_INT;
        return accessor(view(values), type, TINYGLTF_TYPE_SCALAR, values.size());
    }

    int mesh(std::vector<tinygltf::Primitive> primitives) {
        tinygltf::Mesh m;
        m.primitives = std::move(primitives);
        model.meshes.push_back(m);
        return int(model.meshes.size() - 1);
    }

    /// A node showing @p mesh (or -1), returned by reference for setting transforms.
    tinygltf::Node& node(int mesh = -1, std::vector<int> children = {}) {
        tinygltf::Node n;
        n.mesh = mesh;
        n.children = std::move(children);
        model.nodes.push_back(n);
        return model.nodes.back();
    }
    int lastNode() const { return int(model.nodes.size() - 1); }

    void scene(std::vector<int> roots) {
        tinygltf::Scene s;
        s.nodes = std::move(roots);
        model.scenes.push_back(s);
    }

    /// Saves as .glb (binary) or .gltf with an embedded data URI; returns the path.
    std::string save(const ScratchDir& dir, const std::string& name) const {
        bool binary = name.size() > 4 && name.substr(name.size() - 4) == ".glb";
        tinygltf::Model copy = model;
        if (copy.buffers[0].data.empty()) copy.buffers.clear();  // a GLB cannot hold an empty BIN chunk
        std::ostringstream out;
        tinygltf::TinyGLTF writer;
        REQUIRE(writer.WriteGltfSceneToStream(&copy, out, false, binary));
        writeText(dir.file(name), out.str());
        return dir.file(name);
    }
};

inline tinygltf::Primitive primitive(int positions, int indices = -1, int mode = TINYGLTF_MODE_TRIANGLES) {
    tinygltf::Primitive p;
    p.attributes["POSITION"] = positions;
    p.indices = indices;
    p.mode = mode;
    return p;
}

/// A one-mesh, one-node, one-scene model around @p prim, for tests about a single primitive.
inline std::string single(ModelBuilder& b, const ScratchDir& dir, const tinygltf::Primitive& prim, const std::string& name = "m.glb") {
    b.node(b.mesh({prim}));
    b.scene({b.lastNode()});
    return b.save(dir, name);
}


}  // namespace penumbra::test
