// The compiled extension _meshpde. The package meshpde (python/meshpde) re-exports it
// with keyword-only signatures and docstrings; users import meshpde, not this.
#include <pybind11/pybind11.h>

#include "bindings.h"
#include "convert.h"
#include "meshpde/core/errors.h"

namespace py = pybind11;

PYBIND11_MODULE(_meshpde, m) {
  m.doc() = "meshpde's compiled core (import meshpde instead)";
  m.attr("__version__") = MESHPDE_VERSION;
#ifdef MESHPDE_HAVE_MEDICAL
  m.attr("has_medical") = true;
#else
  m.attr("has_medical") = false;
#endif
  // meshpde.Error (a RuntimeError) is the base of both library errors: InputError (a
  // malformed file, a bad parameter; also a ValueError) and SolverError (a solve that
  // cannot proceed), so code catching the builtin classes works too.
  static py::exception<meshpde::Error> error(m, "Error", PyExc_RuntimeError);
  static py::exception<meshpde::InputError> input_error(m, "InputError",
                                                        py::make_tuple(error, py::handle(PyExc_ValueError)));
  static py::exception<meshpde::SolverError> solver_error(m, "SolverError", error);
  // An index out of range: an InputError, and an IndexError as Python reports one.
  static py::exception<meshpde::python::IndexOutOfRange> out_of_range(
      m, "OutOfRangeError", py::make_tuple(input_error, py::handle(PyExc_IndexError)));
  py::register_exception_translator([](std::exception_ptr p) {
    try {
      if (p) std::rethrow_exception(p);
    } catch (const meshpde::python::IndexOutOfRange& e) {
      PyErr_SetString(out_of_range.ptr(), e.what());
    } catch (const meshpde::InputError& e) {
      PyErr_SetString(input_error.ptr(), e.what());
    } catch (const meshpde::SolverError& e) {
      PyErr_SetString(solver_error.ptr(), e.what());
    } catch (const meshpde::Error& e) {
      PyErr_SetString(error.ptr(), e.what());
    }
  });
  meshpde::python::bind_mesh(m);
  meshpde::python::bind_operators(m);
  meshpde::python::bind_apps(m);
  meshpde::python::bind_sessions(m);
#ifdef MESHPDE_HAVE_MEDICAL
  meshpde::python::bind_segmentation(m);
#endif
}
