#pragma once
// The one exception type for parse and I/O failures. Its message always names where the
// problem is (file, line, field) so a user can fix their input without a debugger.
#include <stdexcept>
#include <string>

namespace kestrel {

class Error : public std::runtime_error {
 public:
  explicit Error(const std::string& message) : std::runtime_error(message) {}

  // "FILE:LINE: field 'FIELD': MESSAGE" — line <= 0 and an empty field are left out.
  static Error at(const std::string& file, int line, const std::string& field,
                  const std::string& message) {
    // Appends one piece at a time: GCC 12 warns falsely (-Wrestrict) on chained operator+.
    std::string text;
    text.reserve(file.size() + field.size() + message.size() + 32);
    text.append(file);
    if (line > 0) text.append(":").append(std::to_string(line));
    text.append(": ");
    if (!field.empty()) text.append("field '").append(field).append("': ");
    text.append(message);
    return Error(text);
  }
};

}  // namespace kestrel
