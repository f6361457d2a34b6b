// The parts of the compiled module _meshpde, one per layer of the library.
#pragma once

#include <pybind11/pybind11.h>

namespace meshpde::python {

void bind_mesh(pybind11::module_& m);          // io, diagnostics, generators, normals, pictures
void bind_operators(pybind11::module_& m);     // K, M, intrinsic Delaunay, curvature
void bind_apps(pybind11::module_& m);          // heat, wave, fair, interpolate, correct
void bind_sessions(pybind11::module_& m);      // PdeSession, HapticSession, DragSession, GlobalBilaplacianSolver
void bind_segmentation(pybind11::module_& m);  // segmentations, a segment's surface and back (meshpde::medical)

}  // namespace meshpde::python
