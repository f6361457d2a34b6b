#include "convert.h"

#include <fmt/format.h>

#include <cmath>
#include <sstream>

namespace meshpde::python {

namespace {

std::string shape_text(const py::array& a) {
  std::string s = "(";
  for (py::ssize_t d = 0; d < a.ndim(); ++d) s += fmt::format("{}{}", d ? ", " : "", a.shape(d));
  return s + (a.ndim() == 1 ? ",)" : ")");
}

std::string dtype_text(const py::array& a) {
  return py::str(a.dtype()).cast<std::string>();
}

// Any array-like as a numpy array, or ValueError naming the argument.
py::array as_array(const py::handle& obj, const char* name) {
  if (obj.is_none()) throw InputError(fmt::format("{}: expected an array, got None", name));
  py::array a;
  try {
    a = py::array::ensure(obj);
  } catch (const py::error_already_set&) {
  }
  if (!a)
    throw InputError(fmt::format("{}: expected an array, got {}", name, py::str(obj.get_type()).cast<std::string>()));
  return a;
}

void require_real(const py::array& a, const char* name) {
  const char k = a.dtype().kind();
  if (k != 'f' && k != 'i' && k != 'u')
    throw InputError(fmt::format("{}: expected real numbers, got dtype {}", name, dtype_text(a)));
}

using Doubles = py::array_t<double, py::array::c_style | py::array::forcecast>;

}  // namespace

Positions positions_arg(const py::handle& obj, const char* name) {
  const py::array a = as_array(obj, name);
  require_real(a, name);
  if (a.ndim() != 2 || a.shape(1) != 3)
    throw InputError(
        fmt::format("{}: expected an (n, 3) array of vertex coordinates, got shape {}", name, shape_text(a)));
  const Doubles d = Doubles::ensure(a);
  const auto r = d.unchecked<2>();
  Positions V(r.shape(0), 3);
  for (py::ssize_t i = 0; i < r.shape(0); ++i)
    for (int c = 0; c < 3; ++c) {
      const double x = r(i, c);
      if (!std::isfinite(x))
        throw InputError(fmt::format("{}: vertex {} has a non-finite coordinate ({})", name, i, x));
      V(i, c) = x;
    }
  return V;
}

Triangles triangles_arg(const py::handle& obj, Eigen::Index num_vertices, const char* name) {
  const py::array a = as_array(obj, name);
  const char kind = a.dtype().kind();
  if (kind != 'i' && kind != 'u')
    throw InputError(fmt::format("{}: expected integer vertex indices, got dtype {} (convert with .astype(int))", name,
                                 dtype_text(a)));
  if (a.ndim() != 2 || a.shape(1) != 3)
    throw InputError(fmt::format("{}: expected an (m, 3) array of triangles, got shape {}", name, shape_text(a)));
  Triangles F(a.shape(0), 3);
  // Read in the array's own integer type when it is int32 (no converted copy).
  auto fill = [&](auto tag) {
    using T = decltype(tag);
    using Typed = py::array_t<T, py::array::c_style | py::array::forcecast>;
    const Typed t = Typed::ensure(a);
    const T* p = t.data();
    for (py::ssize_t k = 0; k < 3 * t.shape(0); ++k) {
      const auto v = static_cast<long long>(p[k]);
      if (v < 0 || v >= num_vertices)
        throw IndexOutOfRange(
            fmt::format("{}: face {} has vertex index {}, out of range for {} vertices", name, k / 3, v, num_vertices));
      F.data()[k] = static_cast<int>(v);
    }
  };
  if (a.dtype().is(py::dtype::of<std::int32_t>()))
    fill(std::int32_t{});
  else
    fill(std::int64_t{});
  return F;
}

Mesh mesh_arg(const py::handle& V, const py::handle& F) {
  Positions P = positions_arg(V);
  Triangles T = triangles_arg(F, P.rows());
  return Mesh(std::move(P), std::move(T));
}

Eigen::VectorXd vector_arg(const py::handle& obj, const char* name, Eigen::Index length) {
  const py::array a = as_array(obj, name);
  require_real(a, name);
  if (a.ndim() != 1 || (length >= 0 && a.shape(0) != length))
    throw InputError(fmt::format("{}: expected a 1-D array{}, got shape {}", name,
                                 length >= 0 ? fmt::format(" of length {}", length) : std::string(), shape_text(a)));
  const Doubles d = Doubles::ensure(a);
  const auto r = d.unchecked<1>();
  Eigen::VectorXd v(r.shape(0));
  for (py::ssize_t i = 0; i < r.shape(0); ++i) {
    if (!std::isfinite(r(i))) throw InputError(fmt::format("{}: entry {} is not finite ({})", name, i, r(i)));
    v[i] = r(i);
  }
  return v;
}

Field field_arg(const py::handle& obj, const char* name, Eigen::Index rows, Eigen::Index cols) {
  const py::array a = as_array(obj, name);
  require_real(a, name);
  if (a.ndim() != 1 && a.ndim() != 2)
    throw InputError(fmt::format("{}: expected a 1-D or 2-D array, got shape {}", name, shape_text(a)));
  const py::ssize_t n = a.shape(0), m = a.ndim() == 2 ? a.shape(1) : 1;
  if ((rows >= 0 && n != rows) || (cols >= 0 && m != cols))
    throw InputError(fmt::format("{}: expected shape ({}, {}), got {}", name, rows >= 0 ? std::to_string(rows) : "n",
                                 cols >= 0 ? std::to_string(cols) : "k", shape_text(a)));
  const Doubles d = Doubles::ensure(a);
  Field out(n, m);
  const double* p = d.data();
  for (py::ssize_t i = 0; i < n * m; ++i) {
    if (!std::isfinite(p[i]))
      throw InputError(
          fmt::format("{}: row {} has a non-finite value ({})", name, i / std::max<py::ssize_t>(m, 1), p[i]));
    out.data()[i] = p[i];
  }
  return out;
}

std::vector<Eigen::Vector3d> points_arg(const py::handle& obj, const char* name) {
  const Field P = field_arg(obj, name, -1, 3);
  std::vector<Eigen::Vector3d> out;
  out.reserve(static_cast<std::size_t>(P.rows()));
  for (Eigen::Index i = 0; i < P.rows(); ++i) out.emplace_back(P.row(i).transpose());
  return out;
}

int vertex_arg(long long v, const char* name, Eigen::Index num_vertices) {
  if (v < 0 || v >= num_vertices)
    throw IndexOutOfRange(fmt::format("{}: vertex {} is out of range for {} vertices", name, v, num_vertices));
  return static_cast<int>(v);
}

std::vector<int> vertices_arg(const py::handle& obj, const char* name, Eigen::Index num_vertices) {
  if (py::isinstance<py::int_>(obj)) return {vertex_arg(obj.cast<long long>(), name, num_vertices)};
  const py::array a = as_array(obj, name);
  const char k = a.dtype().kind();
  if (a.size() > 0 && k != 'i' && k != 'u')
    throw InputError(fmt::format("{}: expected integer vertex indices, got dtype {}", name, dtype_text(a)));
  if (a.ndim() != 1)
    throw InputError(fmt::format("{}: expected a 1-D list of vertex indices, got shape {}", name, shape_text(a)));
  using Longs = py::array_t<long long, py::array::c_style | py::array::forcecast>;
  const Longs l = Longs::ensure(a);
  std::vector<int> out;
  out.reserve(static_cast<std::size_t>(l.size()));
  for (py::ssize_t i = 0; i < l.size(); ++i) out.push_back(vertex_arg(l.data()[i], name, num_vertices));
  return out;
}

py::array_t<double> to_numpy(const Eigen::MatrixXd& m) {
  py::array_t<double> a({m.rows(), m.cols()});
  auto w = a.mutable_unchecked<2>();
  for (Eigen::Index i = 0; i < m.rows(); ++i)
    for (Eigen::Index j = 0; j < m.cols(); ++j) w(i, j) = m(i, j);
  return a;
}

py::array_t<double> to_numpy(const Field& m) {
  py::array_t<double> a({m.rows(), m.cols()});
  std::copy(m.data(), m.data() + m.size(), a.mutable_data());
  return a;
}

py::array_t<double> to_numpy(const Eigen::VectorXd& v) {
  py::array_t<double> a(v.size());
  std::copy(v.data(), v.data() + v.size(), a.mutable_data());
  return a;
}

py::array_t<int> to_numpy(const Triangles& F) {
  py::array_t<int> a({F.rows(), Eigen::Index(3)});
  std::copy(F.data(), F.data() + F.size(), a.mutable_data());
  return a;
}

py::array_t<int> to_numpy(const std::vector<int>& v) {
  py::array_t<int> a(static_cast<py::ssize_t>(v.size()));
  std::copy(v.begin(), v.end(), a.mutable_data());
  return a;
}

py::object to_csr(const Eigen::SparseMatrix<double>& A) {
  Eigen::SparseMatrix<double, Eigen::RowMajor> R = A;
  R.makeCompressed();
  py::array_t<double> data(R.nonZeros());
  py::array_t<int> indices(R.nonZeros());
  py::array_t<int> indptr(R.rows() + 1);
  std::copy(R.valuePtr(), R.valuePtr() + R.nonZeros(), data.mutable_data());
  std::copy(R.innerIndexPtr(), R.innerIndexPtr() + R.nonZeros(), indices.mutable_data());
  std::copy(R.outerIndexPtr(), R.outerIndexPtr() + R.rows() + 1, indptr.mutable_data());
  return csr_from_arrays(data, indices, indptr, static_cast<std::size_t>(R.rows()), static_cast<std::size_t>(R.cols()));
}

py::object csr_from_arrays(const py::array_t<double>& data, const py::array_t<int>& indices,
                           const py::array_t<int>& indptr, std::size_t rows, std::size_t cols) {
  const py::object csr = py::module_::import("scipy.sparse").attr("csr_matrix");
  py::object A = csr(py::make_tuple(data, indices, indptr), py::arg("shape") = py::make_tuple(rows, cols),
                     py::arg("copy") = false);
  A.attr("has_sorted_indices") = true;  // saves scipy a scan when it needs sorted rows
  return A;
}

void check_interrupt() {
  py::gil_scoped_acquire gil;
  if (PyErr_CheckSignals() != 0) throw py::error_already_set();
}

py::dict json_to_python(const std::string& text) {
  return py::module_::import("json").attr("loads")(text).cast<py::dict>();
}

}  // namespace meshpde::python
