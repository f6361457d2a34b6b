#include "meshpde/io/text_records.h"

#include <algorithm>

namespace meshpde {

void for_each_text_record(std::string_view text, FieldSeparator separator,
                          const std::function<void(int line, const std::vector<std::string>& fields)>& fn) {
  constexpr std::string_view kSpace = " \t\r\v\f";
  std::vector<std::string> fields;
  int line = 0;
  for (std::size_t begin = 0; begin <= text.size();) {
    std::size_t end = text.find('\n', begin);
    if (end == std::string_view::npos) end = text.size();
    std::string_view record = text.substr(begin, end - begin);
    begin = end + 1;
    ++line;
    record = record.substr(0, record.find('#'));
    if (record.find_first_not_of(kSpace) == std::string_view::npos) continue;
    fields.clear();
    if (separator == FieldSeparator::CommaOrSpace) {
      std::string field;
      for (const char c : record) {
        if (c == ',' || kSpace.find(c) != std::string_view::npos) {
          if (!field.empty()) fields.push_back(std::move(field));
          field.clear();
        } else {
          field += c;
        }
      }
      if (!field.empty()) fields.push_back(std::move(field));
      if (fields.empty()) continue;  // separators only: no record
    } else {
      for (std::size_t from = 0;;) {
        const std::size_t comma = record.find(',', from);
        std::string_view f =
            record.substr(from, comma == std::string_view::npos ? std::string_view::npos : comma - from);
        const std::size_t b = f.find_first_not_of(kSpace);
        f = b == std::string_view::npos ? std::string_view() : f.substr(b, f.find_last_not_of(kSpace) - b + 1);
        fields.emplace_back(f);
        if (comma == std::string_view::npos) break;
        from = comma + 1;
      }
      // A comma that ends the record starts no field.
      if (fields.size() > 1 && fields.back().empty() && record[record.find_last_not_of(kSpace)] == ',')
        fields.pop_back();
    }
    fn(line, fields);
  }
}

}  // namespace meshpde
