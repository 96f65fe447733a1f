#pragma once
/// @file Transform.h
/// @brief Placing geometry in the world: a scale/rotate/translate description and a source
/// adapter that applies a matrix to every vertex streaming through it.

#include "stream/util/JsonParams.h"
#include "stream/TriangleSource.h"

#include <glm/mat4x4.hpp>
#include <glm/vec3.hpp>

namespace penumbra {

/// @brief A uniform scale, Euler rotation and translation, as written in scene files.
struct Transform {
    float scale = 1;
    glm::vec3 rotateDeg{0};  ///< degrees about X, then Y, then Z (extrinsic, fixed world axes)
    glm::vec3 translate{0};

    /// @brief The matrix T * Rz * Ry * Rx * S: scale first, rotate X then Y then Z, translate last.
    /// Multiples of 90 degrees give exact 0/±1 entries, so axis swaps keep coordinates bit-exact.
    glm::mat4 matrix() const;

    /// True when matrix() is the identity.
    bool isIdentity() const;
};

/// @brief Reads the optional "transform" object of a geometry entry ({"scale", "rotate_deg",
/// "translate"}); the identity when absent.
/// @throw InputError naming the key (zero scale, wrong type, unknown key).
Transform parseTransform(const JsonParams& entry);

/// @brief @p p transformed by @p m as a point (affine: the bottom row is ignored), in the float
/// arithmetic every reader uses, so that blockers and receivers from one file agree bit for bit.
inline glm::vec3 transformPoint(const glm::mat4& m, const glm::vec3& p) { return glm::vec3(m * glm::vec4(p, 1.0f)); }

/// @brief Streams another source with a matrix applied to every vertex (p' = M * (p, 1)).
///
/// The bottom row of the matrix is ignored (affine transforms only). When the matrix mirrors
/// (negative determinant of its 3x3 part) the second and third vertex of every triangle are
/// swapped, so that the counter-clockwise side stays the front side in world space, as glTF
/// prescribes for mirrored nodes.
class TransformedSource final : public DecoratedSource {
public:
    /// @param inner the source whose vertices are transformed; owned.
    /// @param matrix applied to each vertex as a point.
    /// @param where what errors name ("scene.json: geometry[2].transform"); empty: the inner source.
    TransformedSource(TriangleSourcePtr inner, const glm::mat4& matrix, std::string where = {});

    /// @throw InputError when the inner source does, or when a transformed vertex is not finite.
    size_t read(std::span<Triangle> out) override;
    /// One triangle out for one in: a skip is the inner source's.
    uint64_t skip(uint64_t count) override { return inner_->skip(count); }

private:
    glm::mat4 matrix_;
    std::string where_;
    bool mirrors_;
};

}  // namespace penumbra
