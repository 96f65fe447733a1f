#include "stream/util/JsonParams.h"

#include "stream/util/Error.h"
#include "stream/util/InputFile.h"
#include "stream/util/JsonText.h"

#include <fmt/ranges.h>

#include <cerrno>
#include <cmath>
#include <cstring>
#include <cstdio>
#include <memory>
#include <vector>
#include <algorithm>
#include <cstdint>

namespace penumbra {

namespace {
/// A scene or benchmark file is a few kilobytes; this only keeps a mistaken huge file from
/// being read into memory whole.
constexpr size_t kMaxJsonFileBytes = size_t(1) << 28;
}  // namespace

JsonParams::JsonParams(const nlohmann::json& object, std::string file, std::string path)
    : object_(object), file_(std::move(file)), path_(std::move(path)) {
    if (!object_.is_object()) fail(where(), "expected an object, got {}", object_.type_name());
}

bool JsonParams::has(const std::string& key) const {
    asked_.insert(key);
    return object_.contains(key);
}

std::string JsonParams::path(const std::string& key) const {
    if (key.empty()) return path_;
    return path_.empty() ? key : path_ + "." + key;
}

std::string JsonParams::where(const std::string& key) const {
    std::string p = path(key);
    return p.empty() ? file_ : file_ + ": " + p;
}

const nlohmann::json& JsonParams::get(const std::string& key) const {
    asked_.insert(key);
    auto it = object_.find(key);
    if (it == object_.end()) missing(key);
    used_.insert(key);
    return *it;
}

const nlohmann::json* JsonParams::raw(const std::string& key) const {
    asked_.insert(key);
    auto it = object_.find(key);
    if (it == object_.end()) return nullptr;
    used_.insert(key);
    return &*it;
}

double JsonParams::number(const std::string& key) const {
    const auto& v = get(key);
    if (!v.is_number()) fail(where(key), "expected a number, got {}", v.type_name());
    double d = v.get<double>();
    if (!std::isfinite(d)) fail(where(key), "expected a finite number");
    return d;
}

double JsonParams::number(const std::string& key, double fallback) const {
    return has(key) ? number(key) : fallback;
}

namespace {

/// An integer-valued JSON number: an integer, or a float with no fraction that a double holds
/// exactly. Anything else is refused naming @p where.
void requireIntegral(const nlohmann::json& v, const std::string& where) {
    const bool integral = v.is_number_integer() || (v.is_number_float() && std::floor(v.get<double>()) == v.get<double>() &&
                                                     std::abs(v.get<double>()) < 9e15);
    if (!integral) fail(where, "expected an integer, got {}", v.dump());
}

}  // namespace

int64_t JsonParams::integer(const std::string& key, int64_t lo, int64_t hi) const {
    const auto& v = get(key);
    requireIntegral(v, where(key));
    // An unsigned value beyond int64 is out of every signed range: refuse it, never clamp it.
    if (v.is_number_unsigned() && v.get<uint64_t>() > uint64_t(INT64_MAX))
        fail(where(key), "must be in {}..{}, got {}", lo, hi, v.dump());
    const int64_t i = v.is_number_integer() ? v.get<int64_t>() : int64_t(v.get<double>());
    if (i < lo || i > hi) fail(where(key), "must be in {}..{}, got {}", lo, hi, i);
    return i;
}

uint64_t JsonParams::unsignedInteger(const std::string& key, uint64_t fallback, uint64_t lo, uint64_t hi) const {
    if (!has(key)) return fallback;
    const auto& v = get(key);
    requireIntegral(v, where(key));
    const bool negative = v.is_number_integer() ? !v.is_number_unsigned() && v.get<int64_t>() < 0 : v.get<double>() < 0;
    const uint64_t u = v.is_number_unsigned() ? v.get<uint64_t>() : (v.is_number_integer() ? uint64_t(v.get<int64_t>()) : uint64_t(v.get<double>()));
    if (negative || u < lo || u > hi) fail(where(key), "must be in {}..{}, got {}", lo, hi, v.dump());
    return u;
}

uint64_t JsonParams::seed(const std::string& key, uint64_t fallback) const {
    return unsignedInteger(key, fallback, 0, UINT64_MAX);
}

int64_t JsonParams::integer(const std::string& key, int64_t fallback, int64_t lo, int64_t hi) const {
    return has(key) ? integer(key, lo, hi) : fallback;
}

bool JsonParams::boolean(const std::string& key, bool fallback) const {
    if (!has(key)) return fallback;
    const auto& v = get(key);
    if (!v.is_boolean()) fail(where(key), "expected true or false, got {}", v.dump());
    return v.get<bool>();
}

std::string JsonParams::string(const std::string& key) const {
    const auto& v = get(key);
    if (!v.is_string()) fail(where(key), "expected a string, got {}", v.type_name());
    return v.get<std::string>();
}

std::string JsonParams::string(const std::string& key, const std::string& fallback) const {
    return has(key) ? string(key) : fallback;
}

namespace {
template <int N>
void readNumbers(const nlohmann::json& v, const std::string& where, double* out) {
    if (!v.is_array() || v.size() != N) fail(where, "expected an array of {} numbers, got {}", N, v.dump());
    for (int i = 0; i < N; ++i) {
        if (!v[i].is_number()) fail(where, "expected an array of {} numbers, got {}", N, v.dump());
        out[i] = v[i].get<double>();
        if (!std::isfinite(out[i])) fail(where, "element {} is not finite", i);
    }
}
}  // namespace

glm::dvec3 JsonParams::vec3(const std::string& key) const {
    glm::dvec3 r;
    readNumbers<3>(get(key), where(key), &r.x);
    return r;
}

glm::dvec3 JsonParams::vec3(const std::string& key, const glm::dvec3& fallback) const {
    return has(key) ? vec3(key) : fallback;
}

glm::dvec2 JsonParams::vec2(const std::string& key) const {
    glm::dvec2 r;
    readNumbers<2>(get(key), where(key), &r.x);
    return r;
}

glm::dvec2 JsonParams::vec2(const std::string& key, const glm::dvec2& fallback) const {
    return has(key) ? vec2(key) : fallback;
}

glm::dvec2 JsonParams::range(const std::string& key, const glm::dvec2& fallback) const {
    if (!has(key)) return fallback;
    const auto& v = get(key);
    if (v.is_number()) return glm::dvec2(number(key));  // a single value is a degenerate range
    glm::dvec2 r = vec2(key);
    if (r.x > r.y) fail(where(key), "range is empty: {} > {}", r.x, r.y);
    return r;
}

namespace {

/// Edits (insertions, deletions, substitutions and swaps of neighbours) from @p a to @p b.
size_t editDistance(const std::string& a, const std::string& b) {
    std::vector<std::vector<size_t>> d(a.size() + 1, std::vector<size_t>(b.size() + 1));
    for (size_t i = 0; i <= a.size(); ++i) d[i][0] = i;
    for (size_t j = 0; j <= b.size(); ++j) d[0][j] = j;
    for (size_t i = 1; i <= a.size(); ++i)
        for (size_t j = 1; j <= b.size(); ++j) {
            d[i][j] = std::min({d[i - 1][j] + 1, d[i][j - 1] + 1, d[i - 1][j - 1] + (a[i - 1] != b[j - 1])});
            if (i > 1 && j > 1 && a[i - 1] == b[j - 2] && a[i - 2] == b[j - 1]) d[i][j] = std::min(d[i][j], d[i - 2][j - 2] + 1);
        }
    return d[a.size()][b.size()];
}

/// True when @p typed looks like a misspelling of @p known: a few edits for its length, or
/// @p known with a unit or qualifier dropped or added at an underscore ("fov" for "fov_deg").
bool looksLike(const std::string& typed, const std::string& known) {
    const size_t shorter = std::min(typed.size(), known.size());
    const size_t allowed = shorter <= 4 ? 1 : shorter <= 8 ? 2 : 3;
    if (editDistance(typed, known) <= allowed) return true;
    auto prefixAtUnderscore = [](const std::string& part, const std::string& whole) {
        return part.size() >= 2 && whole.size() > part.size() && whole.compare(0, part.size(), part) == 0 &&
               whole[part.size()] == '_';
    };
    return prefixAtUnderscore(typed, known) || prefixAtUnderscore(known, typed);
}

/// The candidate closest to @p typed that looks like it, or "" for none.
std::string closest(const std::string& typed, const std::vector<std::string>& candidates) {
    std::string best;
    size_t bestDistance = SIZE_MAX;
    for (const std::string& c : candidates)
        if (c != typed && looksLike(typed, c))
            if (size_t d = editDistance(typed, c); d < bestDistance) best = c, bestDistance = d;
    return best;
}

}  // namespace

void JsonParams::finish() const {
    for (auto it = object_.begin(); it != object_.end(); ++it) {
        if (used_.count(it.key())) continue;
        std::vector<std::string> known;  // the keys asked for that the object does not give
        for (const std::string& k : asked_)
            if (!object_.contains(k)) known.push_back(k);
        const std::string guess = closest(it.key(), known);
        if (guess.empty()) fail(where(it.key()), "unknown key");
        fail(where(it.key()), "unknown key; did you mean \"{}\"?", guess);
    }
}

void JsonParams::missing(const std::string& key) const {
    std::vector<std::string> given;  // the object's keys that nothing asked for
    for (auto it = object_.begin(); it != object_.end(); ++it)
        if (!asked_.count(it.key())) given.push_back(it.key());
    const std::string typo = closest(key, given);
    if (typo.empty()) fail(where(key), "missing required field");
    fail(where(key), "missing required field; is \"{}\" a misspelling of it?", typo);
}

nlohmann::json readJsonFile(const std::string& path) {
    std::unique_ptr<std::FILE, int (*)(std::FILE*)> file(openInputStream(path), &std::fclose);
    std::string text;
    char block[1 << 16];
    while (size_t n = std::fread(block, 1, sizeof block, file.get())) {
        if (text.size() + n > kMaxJsonFileBytes)
            fail(path, "larger than {} MiB, which is too large for a JSON file", kMaxJsonFileBytes >> 20);
        text.append(block, n);
    }
    if (std::ferror(file.get())) fail(path, "read failed: {}", std::strerror(errno));
    return parseJsonText(text, path);
}

}  // namespace penumbra
