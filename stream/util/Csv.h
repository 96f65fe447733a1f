#pragma once
/// @file Csv.h
/// @brief Plain numeric CSV tables (receiver point lists exported from spreadsheets and GIS).

#include <cstddef>
#include <string>
#include <vector>

namespace penumbra {

/// @brief Reads a comma-separated table of numbers.
///
/// Accepted: an optional header row (the first non-blank, non-comment line, when every field of
/// it is a word: neither a number, nor empty, nor nan/inf), blank lines,
/// lines whose first non-blank character is '#', spaces around fields, CRLF line endings and
/// a UTF-8 byte order mark. Every value must be a finite decimal number; nan/inf are
/// rejected because they would silently poison every downstream computation.
///
/// @param path file to read; also the prefix of every error message.
/// @param expectedColumns number of fields each data row must have; 0 means "whatever the
///        first data row has", with every later row required to match it.
/// @return the data rows, each with exactly the expected number of values.
/// @throw InputError "PATH:LINE: ..." for a bad field or a wrong column count, or
///        "PATH: ..." when the file cannot be read.
std::vector<std::vector<double>> readCsvNumbers(const std::string& path, size_t expectedColumns);

}  // namespace penumbra
