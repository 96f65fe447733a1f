#include "stream/Transform.h"

#include "stream/util/Error.h"

#include <glm/mat3x3.hpp>
#include <glm/matrix.hpp>

#include <cmath>
#include <utility>

namespace penumbra {

namespace {

/// Cosine and sine of an angle in degrees; exact at multiples of 90 degrees, where
/// std::cos(M_PI / 2) would give 6e-17 instead of 0 and smear axis-aligned geometry.
std::pair<float, float> cosSinDegrees(float degrees) {
    double turns = std::fmod(static_cast<double>(degrees), 360.0);
    if (turns < 0) turns += 360.0;
    if (turns == 0.0) return {1.0f, 0.0f};
    if (turns == 90.0) return {0.0f, 1.0f};
    if (turns == 180.0) return {-1.0f, 0.0f};
    if (turns == 270.0) return {0.0f, -1.0f};
    double radians = turns * (3.14159265358979323846 / 180.0);
    return {static_cast<float>(std::cos(radians)), static_cast<float>(std::sin(radians))};
}

// glm matrices are column-major: m[column][row].
glm::mat4 rotationX(float degrees) {
    auto [c, s] = cosSinDegrees(degrees);
    glm::mat4 m(1.0f);
    m[1][1] = c, m[1][2] = s;
    m[2][1] = -s, m[2][2] = c;
    return m;
}

glm::mat4 rotationY(float degrees) {
    auto [c, s] = cosSinDegrees(degrees);
    glm::mat4 m(1.0f);
    m[0][0] = c, m[0][2] = -s;
    m[2][0] = s, m[2][2] = c;
    return m;
}

glm::mat4 rotationZ(float degrees) {
    auto [c, s] = cosSinDegrees(degrees);
    glm::mat4 m(1.0f);
    m[0][0] = c, m[0][1] = s;
    m[1][0] = -s, m[1][1] = c;
    return m;
}

}  // namespace

glm::mat4 Transform::matrix() const {
    glm::mat4 scaling(scale);
    scaling[3][3] = 1.0f;
    glm::mat4 translation(1.0f);
    translation[3] = glm::vec4(translate, 1.0f);
    return translation * rotationZ(rotateDeg.z) * rotationY(rotateDeg.y) * rotationX(rotateDeg.x) *
           scaling;
}

bool Transform::isIdentity() const { return matrix() == glm::mat4(1.0f); }

TransformedSource::TransformedSource(TriangleSourcePtr inner, const glm::mat4& matrix, std::string where)
    : DecoratedSource(std::move(inner)), matrix_(matrix), where_(std::move(where)),
      mirrors_(glm::determinant(glm::mat3(matrix)) < 0.0f) {}

size_t TransformedSource::read(std::span<Triangle> out) {
    size_t n = inner_->read(out);
    for (size_t i = 0; i < n; ++i) {
        Triangle& t = out[i];
        for (auto& p : t.v) p = transformPoint(matrix_, p);
        // A cut-out's corner UVs follow its vertices (stream/AlphaTable.h): it keeps their order, and
        // so its outline, and only faces the other way (the blocking rule is two-sided).
        if (mirrors_ && !alphaIdOf(t.flags)) std::swap(t.v[1], t.v[2]);
        if (!isFinite(t))
            fail(where_.empty() ? inner_->name() : where_, "moves a vertex of {} beyond the float range (a coordinate is not finite)",
                 inner_->name());
    }
    return n;
}

Transform parseTransform(const JsonParams& entry) {
    Transform t;
    const nlohmann::json* raw = entry.raw("transform");
    if (!raw) return t;
    JsonParams j(*raw, entry.file(), entry.path("transform"));
    const double scale = j.number("scale", 1.0);
    if (!(scale != 0.0)) fail(j.where("scale"), "must not be zero");
    // Vertices are float: a value float cannot hold would make every vertex infinite.
    auto asFloat = [&](const char* key, double v) {
        if (!std::isfinite(float(v))) fail(j.where(key), "{:g} is beyond the float range of vertices", v);
        return float(v);
    };
    t.scale = asFloat("scale", scale);
    const glm::dvec3 translate = j.vec3("translate", glm::dvec3(0.0));
    const glm::dvec3 rotate = j.vec3("rotate_deg", glm::dvec3(0.0));
    t.rotateDeg = {asFloat("rotate_deg", rotate.x), asFloat("rotate_deg", rotate.y), asFloat("rotate_deg", rotate.z)};
    t.translate = {asFloat("translate", translate.x), asFloat("translate", translate.y), asFloat("translate", translate.z)};
    j.finish();
    return t;
}

}  // namespace penumbra
