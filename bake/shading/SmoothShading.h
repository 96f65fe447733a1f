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
/// bits): only the vertices of triangles that won a pixel are kept (at most 3 per pixel), and a
/// pass over every face (the bake's cast, which reads them all anyway) lowers their l_bend with
/// every face that touches them, except faces across a crease (kCreaseDeg): the bend is meant for
/// smooth surfaces tessellated coarsely, and a box's sides must not darken its top. Faces are
/// oriented like the visible triangle that owns the vertex (its winding sign relative to the
/// camera-facing normal), so meshes must be consistently wound for exact results.

#include "bake/light/Light.h"
#include "bake/shading/PositionIndex.h"

#include <glm/vec3.hpp>

#include <array>
#include <cstdint>
#include <span>
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

/// Faces meeting at a crease sharper than this do not bend each other's shading: a box's top face
/// is not darkened by its sides. Every visible face owns its vertices' slots (faces with the same
/// normal share them); a slot's l_bend is the minimum over the faces around the vertex whose
/// normals are within this angle of its owner's.
inline constexpr double kCreaseDeg = 60.0;
inline constexpr double kCreaseCos = 0.5;  // cos(kCreaseDeg)

/// @brief Per-vertex bent values for the visible triangles of a camera.
///
/// Receivers are added in receiver order, either with their triangles' vertices (addTriangles())
/// or, cheaper during the z-buffer pass, with the triangles' positions in the scene stream
/// (expectTriangleIds(), then recover() with the whole stream in order). Then every face of the
/// scene, in any order, goes through add(); receivers added later need their own add() pass.
/// Holds 12 bytes per receiver (its three vertex slots) and about 70 + 4 * lights per slot (a
/// visible vertex of a visible face); 12 more per receiver while ids wait for recover().
class VertexBend {
public:
    explicit VertexBend(std::vector<LightDirection> lights) : lights_(std::move(lights)) {}
    /// @param triangles each receiver's visible triangle; @param normals each receiver's
    /// (camera-facing) normal, which fixes the orientation of the faces around its vertices.
    VertexBend(std::span<const std::array<glm::vec3, 3>> triangles, std::span<const glm::vec3> normals,
               std::vector<LightDirection> lights);
    void addTriangles(std::span<const std::array<glm::vec3, 3>> triangles, std::span<const glm::vec3> normals);
    /// Receivers whose triangles are known by id (CameraRasterizer::recordTriangleIds()).
    void expectTriangleIds(std::vector<uint64_t> ids);
    /// The scene stream, chunk by chunk in stream order: finds the triangles expectTriangleIds() named.
    void recover(std::span<const Triangle> chunk);
    /// Lowers the bent values with every face of @p chunk that touches a visible vertex.
    void add(std::span<const Triangle> chunk);
    /// @brief Smooth-shading factor of receiver @p r (at @p position with normal @p normal) for
    /// light @p light; 1 for a receiver whose triangle was never found.
    double factor(size_t r, const glm::dvec3& position, const glm::dvec3& normal, int light) const;
    /// Bytes held (for the memory plan and stats).
    uint64_t bytes() const;
    /// @brief The most bytes() can reach for @p receivers receivers whose visible triangles are
    /// among @p triangles distinct ones (each gives at most three vertex slots), with @p lights
    /// lights, for memory plans made before the table is filled.
    static uint64_t boundBytes(uint64_t receivers, uint64_t triangles, size_t lights);
    /// @brief boundBytes() with the distinct triangles expectTriangleIds() named (call after it).
    uint64_t plannedBytes() const;
    /// @brief plannedBytes() once the table holds @p receivers receivers: more than it holds now
    /// are appended by addTriangles() (a refinement's), among any of the scene's @p triangles.
    uint64_t plannedBytes(uint64_t receivers, uint64_t triangles) const;
    /// @brief The indices of @p ids in ascending order of the ids without
    /// CameraRasterizer::kFlippedBit, equal ids in index order (recover()'s order).
    static std::vector<uint32_t> sortedByTriangle(const std::vector<uint64_t>& ids);
    /// Vertex slots (distinct visible vertices, once per distinct owner face normal).
    size_t vertices() const { return vertex_.size(); }

private:
    static PositionKey keyOf(const glm::vec3& p);
    static constexpr uint32_t kNone = ~0u;
    /// The slot of vertex @p v owned by a face with camera-facing unit normal @p owner (winding
    /// sign @p sign), made if new.
    uint32_t slotOf(const glm::vec3& v, float sign, const glm::vec3& owner);
    std::array<uint32_t, 3> cornersOf(const std::array<glm::vec3, 3>& triangle, float sign);
    std::vector<LightDirection> lights_;
    std::vector<std::array<uint32_t, 3>> corners_;     ///< per receiver: its triangle's vertex slots
    PositionIndex index_;                               ///< vertex position -> its latest slot
    std::vector<uint32_t> next_;                        ///< per slot: the position's previous slot
    std::vector<glm::vec3> vertex_;                     ///< per slot: position
    std::vector<glm::vec3> owner_;                      ///< per slot: its face's camera-facing normal
    std::vector<float> sign_;                           ///< per slot: winding sign of its owner
    std::vector<float> bend_;                           ///< per slot and light: min dot(l, n_F)
    std::vector<double> cosines_;                       ///< add(): each light's cosine at the current vertex
    // Waiting for recover(): receiver r's triangle id, receivers sorted by id, the next one.
    std::vector<uint64_t> ids_;
    /// A one-hash Bloom filter over index_'s keys, rebuilt by add() when slots were added.
    std::vector<uint64_t> filter_;
    uint64_t filterMask_ = 0;
    size_t filterSize_ = 0;
    void buildFilter();
    std::vector<uint32_t> order_;
    size_t cursor_ = 0, firstWaiting_ = 0;
    uint64_t seen_ = 0;
};

}  // namespace penumbra
