// CSV lines read as views: the number of fields before anything is stored, then each field
// in turn, with no string per field (a line of 40M commas made 40M strings, 2.3 GB). Read
// by kneedyn score (result and events CSVs) and kneedyn batch (variants), each past a
// byte-order mark.
#pragma once

#include <algorithm>
#include <cstddef>
#include <string_view>
#include <type_traits>

namespace kneedyn::scene_detail {

// The fields of a line: one more than its commas (a trailing comma ends an empty field, as a
// split with std::getline gave); none for an empty line.
inline size_t CsvFieldCount(std::string_view line) {
  return line.empty() ? 0 : static_cast<size_t>(std::count(line.begin(), line.end(), ',')) + 1;
}

// A field without the double quotes around it, as RFC 4180 writers quote every field (R's
// write.csv, Python's csv.QUOTE_ALL); a field with quotes inside is left as it is (no kneedyn
// name or number holds a quote or a comma).
inline std::string_view WithoutCsvQuotes(std::string_view field) {
  if (field.size() >= 2 && field.front() == '"' && field.back() == '"' &&
      field.find('"', 1) == field.size() - 1) {
    return field.substr(1, field.size() - 2);
  }
  return field;
}

// Calls f(index, field) for each field of `line` in order, as views of it (untrimmed,
// WithoutCsvQuotes). A callable that returns bool ends the walk by returning false.
template <typename F>
void ForEachCsvField(std::string_view line, F&& f) {
  if (line.empty()) return;
  for (size_t c = 0, start = 0;; ++c) {
    const size_t comma = line.find(',', start);
    const std::string_view field = WithoutCsvQuotes(
        line.substr(start, comma == std::string_view::npos ? std::string_view::npos : comma - start));
    if constexpr (std::is_same_v<std::invoke_result_t<F&, size_t, std::string_view>, bool>) {
      if (!f(c, field)) return;
    } else {
      f(c, field);
    }
    if (comma == std::string_view::npos) return;
    start = comma + 1;
  }
}

// The text after a UTF-8 byte-order mark, which spreadsheet programs put before a CSV's
// header ("\xEF\xBB\xBFtime_s" would otherwise be an unknown name).
inline std::string_view WithoutByteOrderMark(std::string_view text) {
  constexpr std::string_view kBom = "\xEF\xBB\xBF";
  return text.substr(0, kBom.size()) == kBom ? text.substr(kBom.size()) : text;
}

}  // namespace kneedyn::scene_detail
