// Small text tables as users write them by hand: vertex lists, constraint files, probe
// paths. One record a line; '#' starts a comment; blank lines are skipped.
#pragma once

#include <functional>
#include <string>
#include <string_view>
#include <vector>

namespace meshpde {

/// How a record's fields are separated.
enum class FieldSeparator {
  /// commas and white space alike; empty fields vanish ("1, 2 3" -> 1 2 3), and a
  /// line of separators only is no record
  CommaOrSpace,
  /// commas only, each field trimmed; an empty field stays ("1,,2" -> "1" "" "2"), a
  /// comma at the end of the record starts none ("1,2," -> "1" "2")
  Comma,
};

/// Calls fn(line, fields) for each record of `text` in order (fields never empty), `line` counting from 1
/// (for messages that name it). The comment and the line's end (\n or \r\n) are not
/// part of any field.
void for_each_text_record(std::string_view text, FieldSeparator separator,
                          const std::function<void(int line, const std::vector<std::string>& fields)>& fn);

}  // namespace meshpde
