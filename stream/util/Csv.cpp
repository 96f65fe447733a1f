#include "stream/util/Csv.h"

#include "stream/util/Error.h"

#include "stream/util/InputFile.h"
#include "stream/util/TextInput.h"

#include <cerrno>
#include <charconv>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <memory>
#include <string_view>

namespace penumbra {

namespace {

std::string_view trim(std::string_view s) {
    while (!s.empty() && (s.front() == ' ' || s.front() == '\t')) s.remove_prefix(1);
    while (!s.empty() && (s.back() == ' ' || s.back() == '\t' || s.back() == '\r')) s.remove_suffix(1);
    return s;
}

enum class FieldKind { Number, NonFinite, Empty, Text };

/// Classifies one field and parses it into @p value when it is a finite number. from_chars is
/// locale independent, unlike strtod, so "1.5" parses the same everywhere.
FieldKind parseField(std::string_view field, double& value) {
    if (field.empty()) return FieldKind::Empty;
    std::string_view digits = field;
    if (digits.front() == '+') digits.remove_prefix(1);  // from_chars rejects a leading '+'
    auto [end, ec] = std::from_chars(digits.data(), digits.data() + digits.size(), value);
    if (digits.empty() || end != digits.data() + digits.size()) return FieldKind::Text;
    if (ec == std::errc::result_out_of_range) return FieldKind::NonFinite;
    if (ec != std::errc()) return FieldKind::Text;
    return std::isfinite(value) ? FieldKind::Number : FieldKind::NonFinite;
}

std::vector<std::string_view> splitFields(std::string_view line) {
    std::vector<std::string_view> fields;
    for (;;) {
        size_t comma = line.find(',');
        fields.push_back(trim(line.substr(0, comma)));
        if (comma == std::string_view::npos) break;
        line.remove_prefix(comma + 1);
    }
    return fields;
}

}  // namespace

std::vector<std::vector<double>> readCsvNumbers(const std::string& path, size_t expectedColumns) {
    std::unique_ptr<std::FILE, int (*)(std::FILE*)> in(openInputStream(path), &std::fclose);
    std::unique_ptr<char, void (*)(void*)> buffer(nullptr, &std::free);  // getline(3)'s, hence malloc
    size_t capacity = 0;

    std::vector<std::vector<double>> rows;
    size_t lineNo = 0;
    bool sawContent = false;  // a header is only allowed before the first content line
    for (;;) {
        char* raw = buffer.release();
        errno = 0;
        const ssize_t length = ::getline(&raw, &capacity, in.get());
        buffer.reset(raw);
        if (length < 0) {
            checkLineReadEnded(in.get(), fmt::format("{}:{}", path, lineNo + 1), errno);
            break;
        }
        ++lineNo;
        std::string_view line(raw, size_t(length));
        if (!line.empty() && line.back() == '\n') line.remove_suffix(1);
        if (std::memchr(raw, 0, size_t(length))) fail(fmt::format("{}:{}", path, lineNo), "is binary, not CSV text (a NUL byte)");
        if (lineNo == 1 && line.substr(0, 3) == "\xEF\xBB\xBF") line.remove_prefix(3);  // BOM
        line = trim(line);
        if (line.empty() || line.front() == '#') continue;

        const std::string where = fmt::format("{}:{}", path, lineNo);
        std::vector<std::string_view> fields = splitFields(line);
        std::vector<double> values;
        values.reserve(fields.size());
        size_t badField = 0;  // 1-based index of the first field that is not a finite number
        bool allText = true;
        for (size_t i = 0; i < fields.size(); ++i) {
            double v = 0;
            FieldKind kind = parseField(fields[i], v);
            allText = allText && kind == FieldKind::Text;
            if (kind == FieldKind::Number) {
                values.push_back(v);
                continue;
            }
            if (badField == 0) badField = i + 1;
        }

        // Only the first content line may be a header such as "x,y,z", and only if every field is
        // a word: "1,,3" or "nan,0,0" are broken data rows, not column names, and so is
        // "0,0,0,0,1,0O" (a typo), which was taken for a header and its receiver dropped.
        if (allText && !sawContent) {
            // A header names every column. One of another width is more likely data in another
            // separator ("0;0;0;0;1;0" was taken as a header, and the file as empty).
            if (expectedColumns != 0 && fields.size() != expectedColumns)
                fail(where, "expected {} comma-separated columns but found {}{}", expectedColumns, fields.size(),
                     line.find_first_of(";\t") != std::string_view::npos ? " (fields are separated by commas, not ';' or tabs)"
                                                                           : "");
            sawContent = true;
            continue;
        }
        if (badField != 0) {
            std::string_view f = fields[badField - 1];
            if (f.empty()) fail(where, "field {} is empty", badField);
            // Quote at most a screenful of a field: a binary file read by mistake has huge ones.
            if (f.size() > 40)
                fail(where, "field {} '{}...' is not a finite number", badField, f.substr(0, 40));
            fail(where, "field {} '{}' is not a finite number", badField, f);
        }
        sawContent = true;
        if (expectedColumns == 0) expectedColumns = values.size();
        if (values.size() != expectedColumns)
            fail(where, "expected {} columns but found {}", expectedColumns, values.size());
        rows.push_back(std::move(values));
    }
    return rows;
}

}  // namespace penumbra
