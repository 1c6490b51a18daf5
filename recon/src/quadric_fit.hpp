// Least-squares quadric height field h(u, v) = c0 u^2 + c1 uv + c2 v^2 + c3 u + c4 v + c5 from
// its normal equations: shared by the noise measure of the spacing estimate (the fit's
// residuals) and the second-order projection of the cube representatives (its value at the
// representative, c5).
// SPDX-License-Identifier: MIT
#pragma once

#include <Eigen/Core>
#include <algorithm>
#include <cmath>

namespace scanmesh::recon::detail {

/// The design row of (u, v) in the order above; u and v should be scaled to about [-1, 1] so
/// that the normal equations stay well conditioned.
inline void quadric_row(double u, double v, double* row) {
  row[0] = u * u;
  row[1] = u * v;
  row[2] = v * v;
  row[3] = u;
  row[4] = v;
  row[5] = 1.0;
}

/// Solves ata * coef = ath by Cholesky. False, coef untouched, when a pivot falls below 1e-10 of
/// the largest diagonal entry: the points do not determine a quadric (all on a conic, such as
/// two straight scan lines).
inline bool solve_quadric(const Eigen::Matrix<double, 6, 6>& ata,
                          const Eigen::Matrix<double, 6, 1>& ath,
                          Eigen::Matrix<double, 6, 1>& coef) {
  double l[6][6] = {};
  double max_diag = 0;
  for (int c = 0; c < 6; ++c) max_diag = std::max(max_diag, ata(c, c));
  for (int c = 0; c < 6; ++c) {
    double dsum = ata(c, c);
    for (int q = 0; q < c; ++q) dsum -= l[c][q] * l[c][q];
    if (!(dsum > 1e-10 * max_diag)) return false;
    l[c][c] = std::sqrt(dsum);
    for (int r = c + 1; r < 6; ++r) {
      double v = ata(r, c);
      for (int q = 0; q < c; ++q) v -= l[r][q] * l[c][q];
      l[r][c] = v / l[c][c];
    }
  }
  double y[6];
  for (int r = 0; r < 6; ++r) {
    double v = ath[r];
    for (int q = 0; q < r; ++q) v -= l[r][q] * y[q];
    y[r] = v / l[r][r];
  }
  for (int r = 5; r >= 0; --r) {
    double v = y[r];
    for (int q = r + 1; q < 6; ++q) v -= l[q][r] * coef[q];
    coef[r] = v / l[r][r];
  }
  return true;
}

}  // namespace scanmesh::recon::detail
