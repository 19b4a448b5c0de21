#pragma once
// Line-oriented text files (TUM lists, EuRoC csv, KITTI poses, IMU logs): split into fields,
// with the line number kept, so that every parse error can name file, line and field.
#include <string>
#include <vector>

#include "core/timestamp.hpp"

namespace kestrel::io {

struct TextRow {
  int line = 0;  // 1-based line number in the file
  std::vector<std::string> fields;
};

class TextTable {
 public:
  // Splits on whitespace and commas; skips blank lines and lines starting with '#'.
  // Throws kestrel::Error naming the file when it cannot be read.
  static TextTable read(const std::string& path);
  static TextTable parse(const std::string& text, const std::string& name_for_errors);

  const std::string& path() const { return path_; }
  const std::vector<TextRow>& rows() const { return rows_; }
  bool empty() const { return rows_.empty(); }

  // Checks that the row has at least n fields; the error names what the row should hold.
  void require_fields(const TextRow& row, std::size_t n, const std::string& what) const;
  // Field `col` as a finite double; `field` names it in errors (e.g. "tx").
  double number(const TextRow& row, std::size_t col, const std::string& field) const;
  // Field `col` as decimal seconds or as integer nanoseconds.
  Timestamp seconds(const TextRow& row, std::size_t col, const std::string& field) const;
  Timestamp nanoseconds(const TextRow& row, std::size_t col, const std::string& field) const;
  // Throws an error at this row.
  [[noreturn]] void fail(const TextRow& row, const std::string& field,
                         const std::string& message) const;

 private:
  std::string path_;
  std::vector<TextRow> rows_;
};

}  // namespace kestrel::io
