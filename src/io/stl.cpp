// STL, ascii and binary. STL stores every triangle's corners separately; corners
// at exactly the same position are welded into one vertex.
#include <fmt/format.h>

#include <Eigen/Geometry>
#include <cstring>
#include <unordered_map>

#include "io_detail.h"

namespace meshpde::detail {

namespace {

struct Key {
  double x, y, z;
  bool operator==(const Key& o) const { return x == o.x && y == o.y && z == o.z; }
};
struct KeyHash {
  std::size_t operator()(const Key& k) const {
    auto h = [](double v) {
      if (v == 0) v = 0;  // +0 and -0 weld together.
      uint64_t b;
      std::memcpy(&b, &v, 8);
      return b * 0x9E3779B97F4A7C15ull;
    };
    return h(k.x) ^ (h(k.y) >> 1) ^ (h(k.z) << 1);
  }
};

class Welder {
 public:
  int add(double x, double y, double z) {
    const auto [it, inserted] = index_.try_emplace(Key{x, y, z}, static_cast<int>(xyz_.size() / 3));
    if (inserted) xyz_.insert(xyz_.end(), {x, y, z});
    return it->second;
  }
  std::vector<double>& xyz() { return xyz_; }

 private:
  std::unordered_map<Key, int, KeyHash> index_;
  std::vector<double> xyz_;
};

bool looks_binary(std::string_view b) {
  if (b.size() < 84) return false;
  uint32_t n;
  std::memcpy(&n, b.data() + 80, 4);
  if (84 + 50ull * n == b.size()) return true;
  // Some exporters write "solid" into binary headers; the size check above decides.
  return b.substr(0, 5) != "solid";
}

}  // namespace

MeshData read_stl(std::string_view b, const std::string& name) {
  if (b.empty()) fail(name, "header", "empty file");
  Welder weld;
  std::vector<int> tris;
  if (looks_binary(b)) {
    if (b.size() < 84) fail(name, "header", "file is shorter than the 84-byte binary STL header");
    uint32_t n;
    std::memcpy(&n, b.data() + 80, 4);
    if (84 + 50ull * n > b.size())
      fail(name, "header",
           fmt::format("claims {} triangles but holds only {} bytes of triangle data", n, b.size() - 84));
    tris.reserve(3ull * n);
    for (uint32_t t = 0; t < n; ++t) {
      const char* p = b.data() + 84 + 50ull * t + 12;  // skip the normal
      for (int c = 0; c < 3; ++c) {
        float v[3];
        std::memcpy(v, p + 12 * c, 12);
        for (float x : v)
          if (!std::isfinite(x)) fail(name, fmt::format("triangle {}", t), "non-finite coordinate");
        tris.push_back(weld.add(v[0], v[1], v[2]));
      }
    }
  } else {
    TextCursor in(b, name);
    if (!in.next_content_line() || in.token() != "solid") fail(name, "line 1", "expected 'solid'");
    int corners = 0;
    bool ended = false;
    while (in.next_content_line()) {
      const auto key = in.token();
      if (key == "vertex") {
        const double x = in.real("x"), y = in.real("y"), z = in.real("z");
        tris.push_back(weld.add(x, y, z));
        ++corners;
      } else if (key == "facet" || key == "outer") {
        if (key == "facet") corners = 0;
      } else if (key == "endloop") {
        if (corners != 3) in.error(fmt::format("a facet has {} vertices; STL facets have 3", corners));
      } else if (key == "endfacet") {
      } else if (key == "endsolid") {
        ended = true;
      } else if (key == "solid") {
        ended = false;
      } else {
        in.error(fmt::format("unexpected '{}' in ascii STL", TextCursor::clip(key)));
      }
    }
    if (!ended) fail(name, "end of file", "missing 'endsolid' (truncated file?)");
    if (tris.size() % 3 != 0) fail(name, "end of file", "the last facet is incomplete");
  }
  MeshData d;
  d.V = to_positions(weld.xyz());
  d.F = to_triangles(tris);
  return d;
}

std::string write_stl(const MeshData& d, bool binary) {
  std::string out;
  auto normal = [&](Eigen::Index f) {
    const Eigen::Vector3d a = d.V.row(d.F(f, 0)), b = d.V.row(d.F(f, 1)), c = d.V.row(d.F(f, 2));
    const Eigen::Vector3d n = (b - a).cross(c - a);
    return n.norm() > 0 ? Eigen::Vector3d(n.normalized()) : Eigen::Vector3d::Zero();
  };
  if (binary) {
    out.assign(80, ' ');
    out.replace(0, 20, "meshpde binary STL  ");
    const uint32_t n = static_cast<uint32_t>(d.F.rows());
    out.append(reinterpret_cast<const char*>(&n), 4);
    for (Eigen::Index f = 0; f < d.F.rows(); ++f) {
      const Eigen::Vector3d nn = normal(f);
      float v[12];
      for (int c = 0; c < 3; ++c) v[c] = static_cast<float>(nn[c]);
      for (int k = 0; k < 3; ++k)
        for (int c = 0; c < 3; ++c) v[3 + 3 * k + c] = static_cast<float>(d.V(d.F(f, k), c));
      out.append(reinterpret_cast<const char*>(v), sizeof(v));
      out.append(2, '\0');
    }
  } else {
    out = "solid meshpde\n";
    for (Eigen::Index f = 0; f < d.F.rows(); ++f) {
      const Eigen::Vector3d nn = normal(f);
      fmt::format_to(std::back_inserter(out), "facet normal {} {} {}\n outer loop\n", nn[0], nn[1], nn[2]);
      for (int k = 0; k < 3; ++k)
        fmt::format_to(std::back_inserter(out), "  vertex {} {} {}\n", d.V(d.F(f, k), 0), d.V(d.F(f, k), 1),
                       d.V(d.F(f, k), 2));
      out += " endloop\nendfacet\n";
    }
    out += "endsolid meshpde\n";
  }
  return out;
}

}  // namespace meshpde::detail
