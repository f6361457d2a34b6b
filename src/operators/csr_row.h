// Internal: one CSR row of K applied to an M-component, row-major field,
//     y_i = K_ii x_i + sum_j K_ij x_j,
// shared by the whole-mesh kernels (fem_operators.cpp) and the localized solver's
// compact system (pde_session.cpp). M is a compile-time constant so the components
// stay in registers; inlined into callers, including their AVX2 clones.
#pragma once

namespace meshpde::detail {

template <int M>
inline void csr_row(int i, const int* off, const int* nbr, const double* w, const double* kii, const double* x,
                    double* y) {
  double acc[M];
  for (int c = 0; c < M; ++c) acc[c] = kii[i] * x[M * i + c];
  for (int s = off[i]; s < off[i + 1]; ++s) {
    const double* xs = x + M * nbr[s];
    for (int c = 0; c < M; ++c) acc[c] += w[s] * xs[c];
  }
  for (int c = 0; c < M; ++c) y[M * i + c] = acc[c];
}

}  // namespace meshpde::detail
