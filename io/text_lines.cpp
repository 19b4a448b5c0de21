#include "io/text_lines.hpp"

#include <charconv>
#include <cmath>
#include <fstream>
#include <sstream>

#include "core/error.hpp"

namespace kestrel::io {

TextTable TextTable::read(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  if (!in) throw Error::at(path, 0, "", "cannot open file");
  std::stringstream ss;
  ss << in.rdbuf();
  if (in.bad()) throw Error::at(path, 0, "", "read error");
  return parse(ss.str(), path);
}

TextTable TextTable::parse(const std::string& text, const std::string& name) {
  TextTable t;
  t.path_ = name;
  int line_no = 0;
  std::size_t pos = 0;
  while (pos <= text.size()) {
    std::size_t eol = text.find('\n', pos);
    if (eol == std::string::npos) eol = text.size();
    ++line_no;
    std::string_view line(text.data() + pos, eol - pos);
    pos = eol + 1;
    std::size_t first = line.find_first_not_of(" \t\r");
    if (first == std::string_view::npos || line[first] == '#') {
      if (eol == text.size()) break;
      continue;
    }
    TextRow row;
    row.line = line_no;
    std::size_t i = first;
    while (i < line.size()) {
      while (i < line.size() && (line[i] == ' ' || line[i] == '\t' || line[i] == '\r')) ++i;
      if (i >= line.size()) break;
      std::size_t j = i;
      while (j < line.size() && line[j] != ' ' && line[j] != '\t' && line[j] != '\r' &&
             line[j] != ',') {
        ++j;
      }
      row.fields.emplace_back(line.substr(i, j - i));
      i = j;
      while (i < line.size() && (line[i] == ' ' || line[i] == '\t' || line[i] == '\r')) ++i;
      if (i < line.size() && line[i] == ',') {
        ++i;
        // "a,,b": an empty field is still a field, so column positions stay right.
        std::size_t k = i;
        while (k < line.size() && (line[k] == ' ' || line[k] == '\t' || line[k] == '\r')) ++k;
        if (k >= line.size() || line[k] == ',') row.fields.emplace_back();
      }
    }
    t.rows_.push_back(std::move(row));
    if (eol == text.size()) break;
  }
  return t;
}

void TextTable::fail(const TextRow& row, const std::string& field,
                     const std::string& message) const {
  throw Error::at(path_, row.line, field, message);
}

void TextTable::require_fields(const TextRow& row, std::size_t n, const std::string& what) const {
  if (row.fields.size() < n) {
    fail(row, "",
         "expected " + std::to_string(n) + " fields (" + what + "), got " +
             std::to_string(row.fields.size()));
  }
}

double TextTable::number(const TextRow& row, std::size_t col, const std::string& field) const {
  if (col >= row.fields.size()) fail(row, field, "missing");
  const std::string& s = row.fields[col];
  double v = 0.0;
  const char* begin = s.data();
  const char* end = s.data() + s.size();
  if (!s.empty() && *begin == '+') ++begin;
  auto [ptr, ec] = std::from_chars(begin, end, v);
  if (s.empty() || ec != std::errc() || ptr != end) {
    fail(row, field, "expected a number, got '" + s + "'");
  }
  if (!std::isfinite(v)) fail(row, field, "must be finite, got '" + s + "'");
  return v;
}

Timestamp TextTable::seconds(const TextRow& row, std::size_t col, const std::string& field) const {
  if (col >= row.fields.size()) fail(row, field, "missing");
  const auto t = parse_seconds(row.fields[col]);
  if (!t) fail(row, field, "expected a time in seconds, got '" + row.fields[col] + "'");
  return *t;
}

Timestamp TextTable::nanoseconds(const TextRow& row, std::size_t col,
                                 const std::string& field) const {
  if (col >= row.fields.size()) fail(row, field, "missing");
  const auto t = parse_nanoseconds(row.fields[col]);
  if (!t) fail(row, field, "expected a time in integer nanoseconds, got '" + row.fields[col] + "'");
  return *t;
}

}  // namespace kestrel::io
