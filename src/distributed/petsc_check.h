// PETSc's error codes as meshpde's exceptions, for the distributed component's
// translation units (private to src/distributed).
#pragma once

#include <fmt/format.h>
#include <petscsys.h>

#include "meshpde/core/errors.h"

namespace meshpde::detail {

/// \throw SolverError naming `what` when PETSc returned an error.
inline void petsc_check(PetscErrorCode e, const char* what) {
  if (e != 0) throw SolverError(fmt::format("PETSc: {} failed (error {})", what, static_cast<int>(e)));
}

}  // namespace meshpde::detail
