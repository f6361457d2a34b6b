// Per-vertex fields, the data every operator and solver reads and writes.
#pragma once

#include <Eigen/Core>

namespace meshpde {

/// Per-vertex fields: #V rows, one column per component (1 for scalars, 3 for
/// displacements), row-major so a vertex's components are contiguous.
using Field = Eigen::Matrix<double, Eigen::Dynamic, Eigen::Dynamic, Eigen::RowMajor>;

}  // namespace meshpde
