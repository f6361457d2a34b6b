// The CHOLMOD factors of a build without CHOLMOD (cholmod_factors.cpp otherwise): none
// can be made. direct.cpp asks cholmod_built() first, so these throws are a last guard.
#include "cholmod_factors.h"
#include "meshpde/core/errors.h"

namespace meshpde::detail {

namespace {
[[noreturn]] void missing() {
  throw SolverError("CHOLMOD was requested but meshpde was built without it (install libsuitesparse-dev)");
}
}  // namespace

bool cholmod_built() {
  return false;
}

struct CholmodFactor::Impl {};
CholmodFactor::CholmodFactor() {
  missing();
}
CholmodFactor::~CholmodFactor() = default;
void CholmodFactor::analyze(const Eigen::SparseMatrix<double>&, const std::vector<int>*, bool) {
  missing();
}
bool CholmodFactor::factorize(const Eigen::SparseMatrix<double>&) {
  missing();
}
Eigen::MatrixXd CholmodFactor::solve(const Eigen::MatrixXd&, bool) const {
  missing();
}
double CholmodFactor::nonzeros() const {
  return 0;
}
double CholmodFactor::pivot_ratio() const {
  return 0;
}
std::vector<int> CholmodFactor::order() const {
  return {};
}

struct CholmodInOrder::Impl {};
CholmodInOrder::CholmodInOrder() {
  missing();
}
CholmodInOrder::~CholmodInOrder() = default;
bool CholmodInOrder::factorize(const Eigen::SparseMatrix<double>&) {
  missing();
}
void CholmodInOrder::forward(Eigen::MatrixXd&) {
  missing();
}
void CholmodInOrder::backward(Eigen::MatrixXd&) {
  missing();
}
Eigen::MatrixXd CholmodInOrder::trailing_block(Eigen::Index) const {
  missing();
}
double CholmodInOrder::nonzeros() const {
  return 0;
}

Eigen::MatrixXd lower_gram(const Eigen::MatrixXd& C) {
  return C.triangularView<Eigen::Lower>() * C.transpose();
}

}  // namespace meshpde::detail
