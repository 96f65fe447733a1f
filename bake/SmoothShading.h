#pragma once
/// @file SmoothShading.h
/// @brief Smooth coherent shading (Sintorn, Eisemann & Assarsson 2008, Section 4.3) for camera
/// receivers: the cosine term of the shaded outputs is blended with a per-vertex "bent" value so
/// that low-poly meshes do not leak light past the terminator.
///
/// Each vertex of a visible triangle gets l_bend = min over its adjacent faces F of dot(l, n_F),
/// with l the unit direction from the vertex to the light (to the sun for a sun). A receiver
/// interpolates l_bend barycentrically over its triangle and uses
///   s = alpha * l_f + (1 - alpha) * l_bend,   alpha = clamp(3 l_bend, 0, 1),
/// l_f = dot(l, n) at the receiver. Its irradiance from that light is scaled by s / l_f
/// (clamped to [0, 1]; zero when l_f <= 0), which keeps the Heckbert-Herf sum where the
/// neighbourhood faces the light and fades it to zero towards the terminator.
///
/// Adjacency across a streamed triangle soup is found by hashing vertex positions (exact float
/// bits): only the vertices of triangles that won a pixel are kept (at most 3 per pixel), and one
/// extra pass over the stream lowers their l_bend with every face that touches them. Faces are
/// oriented like the visible triangle that owns the vertex (its winding sign relative to the
/// camera-facing normal), so meshes must be consistently wound for exact results.

#include "bake/Light.h"

#include <glm/vec3.hpp>

#include <array>
#include <cstdint>
#include <span>
#include <unordered_map>
#include <vector>

namespace penumbra {

struct Triangle;

/// @brief Where light l comes from: a point (area-light centre) or a direction (sun).
struct LightDirection {
    glm::dvec3 point{0.0};
    glm::dvec3 towardLight{0.0};  ///< non-zero for a sun: unit direction to the sun
    glm::dvec3 at(const glm::dvec3& p) const;
};

/// @brief The light directions used by smooth shading, one per light, in scene order.
std::vector<LightDirection> lightDirections(const std::vector<LightDesc>& lights);

/// @brief s / l_f: the factor smooth shading applies to a receiver's irradiance from one light.
double smoothShadingFactor(double lf, double lbend);

/// @brief Per-vertex bent values for the visible triangles of a camera.
class VertexBend {
public:
    /// @param triangles each receiver's visible triangle; @param normals each receiver's
    /// (camera-facing) normal, which fixes the orientation of the faces around its vertices.
    VertexBend(std::vector<std::array<glm::vec3, 3>> triangles, std::span<const glm::vec3> normals,
               std::vector<LightDirection> lights);
    /// Lowers the bent values with every face of @p chunk that touches a visible vertex.
    void add(std::span<const Triangle> chunk);
    /// @brief Smooth-shading factor of receiver @p r (at @p position with normal @p normal) for light @p light.
    double factor(size_t r, const glm::dvec3& position, const glm::dvec3& normal, int light) const;
    /// Bytes held (for documentation and stats).
    uint64_t bytes() const;

private:
    struct Key {
        uint32_t x, y, z;
        bool operator==(const Key&) const = default;
    };
    struct KeyHash {
        size_t operator()(const Key& k) const;
    };
    static Key keyOf(const glm::vec3& p);
    std::vector<std::array<glm::vec3, 3>> triangles_;
    std::vector<LightDirection> lights_;
    std::unordered_map<Key, uint32_t, KeyHash> index_;  ///< vertex -> slot
    std::vector<float> sign_;                           ///< per slot: winding sign of its owner
    std::vector<float> bend_;                           ///< per slot and light: min dot(l, n_F)
};

}  // namespace penumbra
