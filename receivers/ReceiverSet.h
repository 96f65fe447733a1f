#pragma once
/// @file ReceiverSet.h
/// @brief The points that need shadow information, whatever produced them.

#include <glm/vec3.hpp>

#include <cstdint>
#include <span>
#include <vector>

namespace penumbra {

/// @brief Receiver points with normals (structure of arrays). For camera receivers `pixel` maps
/// each receiver to its pixel (y * width + x) and `depth` is the distance from the eye.
struct ReceiverSet {
    std::vector<glm::vec3> position;
    std::vector<glm::vec3> normal;
    std::vector<uint32_t> pixel;  ///< empty unless the receivers come from an image
    std::vector<float> depth;     ///< empty unless the receivers come from an image
    /// Receivers on a "receive_shadows": false entry (1): reported unshadowed whatever the
    /// method finds (Pipeline.cpp). Empty when every receiver receives shadows.
    std::vector<uint8_t> unshadowed;
    int width = 0, height = 0;    ///< image size for camera receivers

    size_t size() const { return position.size(); }
    /// True when receiver @p r is reported unshadowed ("receive_shadows": false).
    bool isUnshadowed(size_t r) const { return !unshadowed.empty() && unshadowed[r]; }
    /// Bytes held per receiver, for the "samples mem" column of the stats.
    size_t bytes() const {
        return position.size() * sizeof(glm::vec3) + normal.size() * sizeof(glm::vec3) +
               pixel.size() * sizeof(uint32_t) + depth.size() * sizeof(float) + unshadowed.size();
    }
};

/// @brief The positions and normals of receivers [first, size) of a set, without a copy: what a
/// method that reads only the points takes (a refinement pass's tail of a million-receiver set
/// cost milliseconds to copy).
struct ReceiverPoints {
    std::span<const glm::vec3> position, normal;
    ReceiverPoints(const ReceiverSet& set, size_t first = 0)  // NOLINT: a set is its points
        : position(std::span<const glm::vec3>(set.position).subspan(first)),
          normal(std::span<const glm::vec3>(set.normal).subspan(first)) {}
    size_t size() const { return position.size(); }
};

/// @brief What a receiver made on a geometry entry's surface does: the entry's
/// "receive_shadows" and "receiver_offset" (Triangle.h, receiver class; SceneDesc::receiverClasses).
struct ReceiverClass {
    bool receiveShadows = true;
    double offset = 0.0;  ///< scene units along the receiver's normal
    bool operator==(const ReceiverClass&) const = default;
};

/// @brief Receiver @p r of @p set takes class @p c: it moves along its normal by the offset (in
/// double, rounded once to float), and is marked unshadowed when the class receives no shadows.
inline void applyReceiverClass(ReceiverSet& set, size_t r, const ReceiverClass& c) {
    if (c.offset != 0.0)
        set.position[r] = glm::vec3(glm::dvec3(set.position[r]) + c.offset * glm::dvec3(set.normal[r]));
    if (!c.receiveShadows) {
        if (set.unshadowed.empty()) set.unshadowed.assign(set.size(), 0);
        set.unshadowed[r] = 1;
    }
}

/// @brief Receivers [@p first, @p first + @p classes.size()) take the classes @p classes index
/// in @p table (a camera's per-pixel classes).
inline void applyReceiverClasses(ReceiverSet& set, size_t first, std::span<const uint8_t> classes,
                                 const std::vector<ReceiverClass>& table) {
    for (size_t i = 0; i < classes.size(); ++i)
        if (classes[i] && classes[i] < table.size()) applyReceiverClass(set, first + i, table[classes[i]]);
}

}  // namespace penumbra
