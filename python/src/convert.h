// Plain numpy data in and out of the Python module.
//
// Every argument a user passes is checked here before it reaches the library, so
// that a wrong shape, a NaN or an index out of range raises a Python exception that
// names the argument (meshpde.InputError, a ValueError, for shapes, types and values;
// meshpde.OutOfRangeError, an InputError and an IndexError, for indices) instead of
// reaching an Eigen assertion or a crash. float32, integer,
// int64 and Fortran-ordered arrays are converted (copied) to the library's types.
#pragma once

#include <pybind11/numpy.h>
#include <pybind11/pybind11.h>

#include <Eigen/Core>
#include <Eigen/SparseCore>
#include <cstdint>
#include <span>
#include <string>
#include <vector>

#include "meshpde/core/errors.h"
#include "meshpde/core/warnings.h"
#include "meshpde/mesh/mesh.h"
#include "meshpde/operators/fem_operators.h"

namespace meshpde::python {

namespace py = pybind11;

/// An argument taken as any Python object and checked where it is used (by the
/// functions below), shown in signatures and help() under a name that says what it
/// takes, where a plain py::handle would show `handle`. The names are given by the
/// handle_type_name specializations at the end of this file.
template <int Kind>
class AnyArgument : public py::object {
 public:
  using py::object::object;
  static bool check_(py::handle h) { return h.ptr() != nullptr; }
};
/// Any array-like value (a numpy array of any dtype and order, a list of lists, ...):
/// `numpy.typing.ArrayLike`.
using ArrayLike = AnyArgument<0>;
/// An optional path, a str or os.PathLike, or None: `os.PathLike | None`.
using OptionalPath = AnyArgument<1>;
/// A DICOM series chosen by its UID (a str) or number (an int), or None (the only
/// one): `str | int | None`.
using SeriesChoice = AnyArgument<2>;

/// An index out of range: Python's meshpde.OutOfRangeError (both a meshpde.InputError
/// and an IndexError).
class IndexOutOfRange : public InputError {
 public:
  using InputError::InputError;
};

/// (n, 3) finite coordinates. \throw InputError naming `name`.
Positions positions_arg(const py::handle& obj, const char* name = "V");

/// (m, 3) integer vertex indices in [0, num_vertices). \throw InputError (shape,
/// dtype, non-integral values), IndexOutOfRange (an index out of range, naming the face).
Triangles triangles_arg(const py::handle& obj, Eigen::Index num_vertices, const char* name = "F");

/// Mesh from (V, F), both checked as above.
Mesh mesh_arg(const py::handle& V, const py::handle& F);

/// A 1-D array of finite numbers; `length` >= 0 requires that many entries.
Eigen::VectorXd vector_arg(const py::handle& obj, const char* name, Eigen::Index length = -1);

/// A (rows, cols) array of finite numbers (a 1-D array is one column); -1 leaves a
/// dimension free.
Field field_arg(const py::handle& obj, const char* name, Eigen::Index rows = -1, Eigen::Index cols = -1);

/// A (k, 3) array of finite positions as points (field_arg's checks).
std::vector<Eigen::Vector3d> points_arg(const py::handle& obj, const char* name);

/// Vertex indices (an int, a sequence or a 1-D integer array), each in [0, num_vertices).
std::vector<int> vertices_arg(const py::handle& obj, const char* name, Eigen::Index num_vertices);

/// One vertex index in [0, num_vertices). \throw IndexError naming `name`.
int vertex_arg(long long v, const char* name, Eigen::Index num_vertices);

/// numpy copies of library data.
py::array_t<double> to_numpy(const Eigen::MatrixXd& m);
py::array_t<double> to_numpy(const Field& m);
py::array_t<double> to_numpy(const Eigen::VectorXd& v);
py::array_t<int> to_numpy(const Triangles& F);
py::array_t<int> to_numpy(const std::vector<int>& v);

/// scipy.sparse.csr_matrix of an Eigen sparse matrix (any storage order).
py::object to_csr(const Eigen::SparseMatrix<double>& A);

/// A JSON object made by the library (a report) as a dict, through Python's json module.
py::dict json_to_python(const std::string& text);
/// scipy.sparse.csr_matrix over these arrays (sorted rows; not copied).
py::object csr_from_arrays(const py::array_t<double>& data, const py::array_t<int>& indices,
                           const py::array_t<int>& indptr, std::size_t rows, std::size_t cols);

/// Calls PyErr_CheckSignals with the GIL held and throws py::error_already_set on
/// Ctrl-C, so that a loop in the library stops with KeyboardInterrupt. For callbacks
/// that run while the GIL is released.
void check_interrupt();

/// Runs f (which returns a value) with the library's warnings (core/warnings.h) collected,
/// then gives each as a Python UserWarning; the GIL must be held.
template <class F>
auto with_warnings(F&& f) {
  WarningCollector collected;
  auto result = f();
  for (const std::string& m : collected.take())
    if (PyErr_WarnEx(PyExc_UserWarning, m.c_str(), 1) < 0) throw py::error_already_set();
  return result;
}

}  // namespace meshpde::python

namespace pybind11::detail {
template <>
struct handle_type_name<meshpde::python::ArrayLike> {
  static constexpr auto name = const_name("numpy.typing.ArrayLike");
};
template <>
struct handle_type_name<meshpde::python::OptionalPath> {
  static constexpr auto name = const_name("os.PathLike | None");
};
template <>
struct handle_type_name<meshpde::python::SeriesChoice> {
  static constexpr auto name = const_name("str | int | None");
};
}  // namespace pybind11::detail
