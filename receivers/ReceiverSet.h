#pragma once
/// @file ReceiverSet.h
/// @brief The points that need shadow information, whatever produced them.

#include <glm/vec3.hpp>

#include <cstdint>
#include <vector>

namespace penumbra {

/// @brief Receiver points with normals (structure of arrays). For camera receivers `pixel` maps
/// each receiver to its pixel (y * width + x) and `depth` is the distance from the eye.
struct ReceiverSet {
    std::vector<glm::vec3> position;
    std::vector<glm::vec3> normal;
    std::vector<uint32_t> pixel;  ///< empty unless the receivers come from an image
    std::vector<float> depth;     ///< empty unless the receivers come from an image
    int width = 0, height = 0;    ///< image size for camera receivers

    size_t size() const { return position.size(); }
    /// Bytes held per receiver, for the "samples mem" column of the stats.
    size_t bytes() const {
        return position.size() * sizeof(glm::vec3) + normal.size() * sizeof(glm::vec3) +
               pixel.size() * sizeof(uint32_t) + depth.size() * sizeof(float);
    }
};

}  // namespace penumbra
