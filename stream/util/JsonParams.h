#pragma once
/// @file JsonParams.h
/// @brief Strict, self-describing access to a JSON object of parameters. Every error names the
/// file and the full key path ("scene.json: lights[0].u: expected an array of 3 numbers"), and
/// finish() rejects keys nobody asked for, so a typo never silently falls back to a default.

#include <glm/vec2.hpp>
#include <glm/vec3.hpp>
#include <nlohmann/json.hpp>

#include <optional>
#include <set>
#include <string>
#include <vector>

namespace penumbra {

class JsonParams {
public:
    /// @param file file name for messages; @param path key path of @p object ("" for the root)
    /// @throw InputError when @p object is not a JSON object
    JsonParams(const nlohmann::json& object, std::string file, std::string path);

    bool has(const std::string& key) const;
    /// Full location of a key for messages: "scene.json: lights[0].u".
    std::string where(const std::string& key = "") const;
    std::string path(const std::string& key) const;
    const std::string& file() const { return file_; }

    double number(const std::string& key) const;
    double number(const std::string& key, double fallback) const;
    int64_t integer(const std::string& key, int64_t fallback, int64_t lo, int64_t hi) const;
    int64_t integer(const std::string& key, int64_t lo, int64_t hi) const;
    /// An integer in [lo, hi] of the whole unsigned 64-bit range (never clamped).
    uint64_t unsignedInteger(const std::string& key, uint64_t fallback, uint64_t lo, uint64_t hi) const;
    /// A random seed: any integer in 0..2^64-1.
    uint64_t seed(const std::string& key, uint64_t fallback) const;
    bool boolean(const std::string& key, bool fallback) const;
    std::string string(const std::string& key) const;
    std::string string(const std::string& key, const std::string& fallback) const;
    glm::dvec3 vec3(const std::string& key) const;
    glm::dvec3 vec3(const std::string& key, const glm::dvec3& fallback) const;
    glm::dvec2 vec2(const std::string& key) const;
    glm::dvec2 vec2(const std::string& key, const glm::dvec2& fallback) const;
    /// A [lo, hi] pair of numbers (ranges such as "height": [0.2, 0.5]); lo <= hi is checked.
    glm::dvec2 range(const std::string& key, const glm::dvec2& fallback) const;
    /// The raw value (marked as used), or nullptr when absent.
    const nlohmann::json* raw(const std::string& key) const;

    /// @throw InputError naming the first key that was never read, with the known key it is
    /// closest to ("receivers.fov: unknown key; did you mean \"fov_deg\"?").
    void finish() const;
    /// @brief Fails for a required @p key that is absent, naming a given key that looks like a
    /// misspelling of it ("receivers: missing required field; is \"recievers\" a misspelling?").
    /// @throw InputError always.
    [[noreturn]] void missing(const std::string& key) const;

private:
    const nlohmann::json& get(const std::string& key) const;
    const nlohmann::json& object_;
    std::string file_, path_;
    mutable std::set<std::string> used_;
    mutable std::set<std::string> asked_;  ///< every key looked for, present or not: the known keys
};

/// @brief Reads and parses a JSON file (a scene, a benchmark's example).
/// @throw InputError naming @p path when it cannot be opened or is not valid JSON (with the byte).
nlohmann::json readJsonFile(const std::string& path);

}  // namespace penumbra
