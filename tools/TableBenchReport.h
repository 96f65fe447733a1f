#pragma once
/// @file TableBenchReport.h
/// @brief The Markdown that `penumbra bench table2` writes: the tables, the targets with their
/// verdicts, and the splice into docs/BENCHMARKS.md between the generated-section markers.

#include <nlohmann/json.hpp>

#include <string>

namespace penumbra {

/// @brief Replaces the generated part of a BENCHMARKS.md text (between the table2 markers) with
/// @p generated; without markers, appends a "Table 2" section with them. Other sections are kept.
std::string replaceTable2Section(const std::string& document, const std::string& generated);

/// @brief The generated Markdown (machine, command, tables, targets) for a result document.
std::string table2Markdown(const nlohmann::json& result);

/// @brief A byte count (JSON number) in MiB with one decimal.
std::string formatMiB(const nlohmann::json& bytes);

}  // namespace penumbra
