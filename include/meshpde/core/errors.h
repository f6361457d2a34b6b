// Exception hierarchy of meshpde.
//
// Two kinds of failure reach the caller:
//  - InputError: the caller's data is unusable (a malformed file, an index out of
//    range, a NaN coordinate). The message names the file and the line or element.
//  - SolverError: the numerics cannot proceed (a non-SPD system, a request the
//    solver cannot honour). Non-convergence of an iterative solver is NOT an error:
//    it is reported as a status in the solver's result.
#pragma once

#include <stdexcept>
#include <string>

namespace meshpde {

class Error : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

class InputError : public Error {
 public:
  using Error::Error;
};

class SolverError : public Error {
 public:
  using Error::Error;
};

}  // namespace meshpde
