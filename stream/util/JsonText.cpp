#include "stream/util/JsonText.h"

#include "stream/util/Error.h"

#include <set>
#include <vector>

namespace penumbra {
namespace {

/// Thrown from the parser's callback: a key given twice in one object.
struct DuplicateKey {};

/// The key path the parser is in, kept from its callback events, so an error can name the key.
class KeyPath {
public:
    /// @throw DuplicateKey for a key the current object already holds (nlohmann keeps the last
    /// silently, so "samples": 16 then "samples": 64 baked with 64 and no word).
    void on(nlohmann::json::parse_event_t event, const nlohmann::json& parsed) {
        using Event = nlohmann::json::parse_event_t;
        switch (event) {
            case Event::object_start: frames_.push_back({false, {}, 0, {}}); break;
            case Event::array_start: frames_.push_back({true, {}, 0, {}}); break;
            case Event::key:
                if (!frames_.empty() && parsed.is_string()) {
                    Frame& f = frames_.back();
                    f.key = parsed.get<std::string>();
                    if (!f.keys.insert(f.key).second) throw DuplicateKey{};
                }
                break;
            case Event::object_end:
            case Event::array_end:
                if (!frames_.empty()) frames_.pop_back();
                elementDone();
                break;
            case Event::value: elementDone(); break;
        }
    }

    /// "lights[0].power", or "" at the top level.
    std::string text() const {
        std::string out;
        for (const Frame& f : frames_) {
            if (f.array) {
                out += '[';
                out += std::to_string(f.elements);
                out += ']';
            } else if (!f.key.empty()) {
                if (!out.empty()) out += '.';
                out += f.key;
            }
        }
        return out;
    }

private:
    struct Frame {
        bool array;
        std::string key;
        size_t elements;
        std::set<std::string> keys;  ///< an object's keys so far
    };
    void elementDone() {
        if (!frames_.empty() && frames_.back().array) ++frames_.back().elements;
    }
    std::vector<Frame> frames_;
};

/// nlohmann's what() without its "[json.exception.parse_error.101] " tag.
std::string withoutTag(const std::string& what) {
    size_t close = what.find("] ");
    return what.rfind("[json.exception.", 0) == 0 && close != std::string::npos ? what.substr(close + 2) : what;
}

}  // namespace

void checkJsonDepth(std::string_view text, const std::string& where, int limit) {
    int depth = 0;
    bool inString = false, escaped = false;
    for (size_t i = 0; i < text.size(); ++i) {
        const char c = text[i];
        if (inString) {
            if (escaped) escaped = false;
            else if (c == '\\') escaped = true;
            else if (c == '"') inString = false;
            continue;
        }
        if (c == '"') {
            inString = true;
        } else if (c == '[' || c == '{') {
            if (++depth > limit) fail(where, "JSON nests deeper than {} levels (at byte {})", limit, i);
        } else if ((c == ']' || c == '}') && depth > 0) {
            --depth;
        }
    }
}

nlohmann::json parseJsonText(std::string_view text, const std::string& where) {
    checkJsonDepth(text, where);
    KeyPath path;
    auto track = [&](int, nlohmann::json::parse_event_t event, nlohmann::json& parsed) {
        path.on(event, parsed);
        return true;
    };
    auto at = [&] {
        std::string key = path.text();
        return key.empty() ? where : fmt::format("{}: {}", where, key);
    };
    auto in = [&] {
        std::string key = path.text();
        return key.empty() ? key : fmt::format(" (in {})", key);
    };
    try {
        return nlohmann::json::parse(text.begin(), text.end(), track);
    } catch (const DuplicateKey&) {
        fail(at(), "is given twice in one object (a key may appear once)");
    } catch (const nlohmann::json::parse_error& e) {
        fail(where, "invalid JSON at byte {}{}: {}", e.byte, in(), withoutTag(e.what()));
    } catch (const nlohmann::json::exception& e) {
        fail(at(), "{}", withoutTag(e.what()));
    } catch (const std::bad_alloc&) {
        throw;
    } catch (const std::exception& e) {
        fail(at(), "cannot parse JSON: {}", e.what());
    }
}

}  // namespace penumbra
