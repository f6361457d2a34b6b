// Internal helpers shared by the format readers: a line-aware text cursor that
// produces "file:line" messages, and the checks every reader applies.
#pragma once

#include <fmt/format.h>

#include <charconv>
#include <cmath>
#include <cstdint>
#include <string>
#include <string_view>

#include "meshpde/core/errors.h"
#include "meshpde/io/mesh_io.h"

namespace meshpde::detail {

[[noreturn]] inline void fail(const std::string& name, const std::string& where, const std::string& what) {
  throw InputError(fmt::format("{}: {}: {}", name, where, what));
}

/// Splits a buffer into lines and lines into whitespace-separated tokens.
class TextCursor {
 public:
  TextCursor(std::string_view text, std::string name, std::size_t start = 0, int line = 0)
      : text_(text), name_(std::move(name)), pos_(start), line_(line) {}

  /// Advances to the next line; false at end of input.
  bool next_line() {
    if (pos_ >= text_.size()) return false;
    const std::size_t end = text_.find('\n', pos_);
    const std::size_t stop = end == std::string_view::npos ? text_.size() : end;
    cur_ = text_.substr(pos_, stop - pos_);
    if (!cur_.empty() && cur_.back() == '\r') cur_.remove_suffix(1);
    pos_ = stop == text_.size() ? stop : stop + 1;
    ++line_;
    tok_ = 0;
    return true;
  }
  /// Advances past blank lines and lines starting with `comment`; false at end.
  bool next_content_line(char comment = '#') {
    while (next_line()) {
      skip_space();
      if (tok_ < cur_.size() && cur_[tok_] != comment) return true;
    }
    return false;
  }
  std::string_view line() const { return cur_; }
  int line_number() const { return line_; }
  std::size_t position() const { return pos_; }
  const std::string& name() const { return name_; }

  bool has_token() {
    skip_space();
    return tok_ < cur_.size() && cur_[tok_] != '#';
  }
  std::string_view token() {
    skip_space();
    const std::size_t b = tok_;
    while (tok_ < cur_.size() && !is_space(cur_[tok_])) ++tok_;
    return cur_.substr(b, tok_ - b);
  }
  std::string_view rest() {
    skip_space();
    return cur_.substr(tok_);
  }

  double real(const char* what) {
    const auto t = token();
    if (t.empty()) error(fmt::format("expected {} but the line ends", what));
    double v = 0;
    const auto [p, ec] = std::from_chars(t.data(), t.data() + t.size(), v);
    if (ec != std::errc() || p != t.data() + t.size()) error(fmt::format("expected {} but found '{}'", what, clip(t)));
    if (!std::isfinite(v)) error(fmt::format("{} is not finite ('{}')", what, clip(t)));
    return v;
  }
  long long integer(const char* what) {
    const auto t = token();
    if (t.empty()) error(fmt::format("expected {} but the line ends", what));
    long long v = 0;
    const auto [p, ec] = std::from_chars(t.data(), t.data() + t.size(), v);
    if (ec != std::errc() || p != t.data() + t.size()) error(fmt::format("expected {} but found '{}'", what, clip(t)));
    return v;
  }

  [[noreturn]] void error(const std::string& what) const { fail(name_, fmt::format("line {}", line_), what); }

  static std::string clip(std::string_view t) {
    std::string s(t.substr(0, 40));
    for (char& c : s)
      if (static_cast<unsigned char>(c) < 32 || static_cast<unsigned char>(c) > 126) c = '?';
    return t.size() > 40 ? s + "..." : s;
  }

 private:
  static bool is_space(char c) { return c == ' ' || c == '\t' || c == '\v' || c == '\f' || c == '\r'; }
  void skip_space() {
    while (tok_ < cur_.size() && is_space(cur_[tok_])) ++tok_;
  }
  std::string_view text_;
  std::string name_;
  std::size_t pos_ = 0;
  int line_ = 0;
  std::string_view cur_;
  std::size_t tok_ = 0;
};

/// Appends a polygon's fan triangulation; returns the number of triangles added.
template <class Vec>
int add_polygon(std::vector<int>& tris, const Vec& poly) {
  for (std::size_t k = 1; k + 1 < poly.size(); ++k) {
    tris.push_back(poly[0]);
    tris.push_back(poly[k]);
    tris.push_back(poly[k + 1]);
  }
  return static_cast<int>(poly.size()) - 2;
}

inline Triangles to_triangles(const std::vector<int>& tris) {
  Triangles F(static_cast<Eigen::Index>(tris.size() / 3), 3);
  for (std::size_t k = 0; k < tris.size(); ++k) F(static_cast<Eigen::Index>(k / 3), k % 3) = tris[k];
  return F;
}
inline Positions to_positions(const std::vector<double>& xyz) {
  Positions V(static_cast<Eigen::Index>(xyz.size() / 3), 3);
  for (std::size_t k = 0; k < xyz.size(); ++k) V(static_cast<Eigen::Index>(k / 3), k % 3) = xyz[k];
  return V;
}

/// Fails unless every face index lies in [0, nv). `where` formats the element.
inline void check_indices(const std::string& name, const Triangles& F, int nv) {
  for (Eigen::Index f = 0; f < F.rows(); ++f)
    for (int c = 0; c < 3; ++c)
      if (F(f, c) < 0 || F(f, c) >= nv)
        fail(name, fmt::format("face {}", f), fmt::format("vertex index {} outside [0, {})", F(f, c), nv));
}

MeshData read_obj(std::string_view text, const std::string& name);
MeshData read_off(std::string_view text, const std::string& name);
MeshData read_ply(std::string_view bytes, const std::string& name);
MeshData read_stl(std::string_view bytes, const std::string& name);
std::string write_obj(const MeshData& d);
std::string write_off(const MeshData& d);
std::string write_ply(const MeshData& d, bool binary);
std::string write_stl(const MeshData& d, bool binary);

}  // namespace meshpde::detail
