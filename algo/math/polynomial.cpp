#include "algo/math/polynomial.hpp"

#include <algorithm>
#include <cmath>

#include <Eigen/Eigenvalues>

namespace epitrack {

int solveQuadraticReal(const double c[3], double roots[2]) {
  const double a = c[2], b = c[1], k = c[0];
  if (std::abs(a) < 1e-300) {
    if (std::abs(b) < 1e-300) return 0;
    roots[0] = -k / b;
    return 1;
  }
  const double disc = b * b - 4.0 * a * k;
  if (disc < 0.0) return 0;
  // q = -(b + sign(b) sqrt(disc)) / 2 avoids cancellation (Numerical Recipes §5.6).
  const double q = -0.5 * (b + std::copysign(std::sqrt(disc), b));
  if (q == 0.0) {
    roots[0] = 0.0;
    return 1;
  }
  roots[0] = q / a;
  roots[1] = k / q;
  return 2;
}

namespace {

double evalPoly(const double c[5], int degree, double x) {
  double v = c[degree];
  for (int i = degree - 1; i >= 0; --i) v = v * x + c[i];
  return v;
}

double evalDerivative(const double c[5], int degree, double x) {
  double v = degree * c[degree];
  for (int i = degree - 1; i >= 1; --i) v = v * x + i * c[i];
  return v;
}

}  // namespace

int solveQuarticReal(const double c[5], double roots[4]) {
  const double scale =
      std::max({std::abs(c[0]), std::abs(c[1]), std::abs(c[2]), std::abs(c[3]), std::abs(c[4])});
  if (!(scale > 0.0) || !std::isfinite(scale)) return 0;
  int degree = 4;
  while (degree > 0 && std::abs(c[degree]) <= 1e-14 * scale) --degree;
  if (degree == 0) return 0;
  if (degree <= 2) {
    double q[3] = {c[0], c[1], degree == 2 ? c[2] : 0.0};
    return solveQuadraticReal(q, roots);
  }
  // Companion matrix of the monic polynomial (fixed 4x4 storage, no allocation).
  Eigen::Matrix4d m = Eigen::Matrix4d::Zero();
  for (int i = 1; i < degree; ++i) m(i, i - 1) = 1.0;
  for (int i = 0; i < degree; ++i) m(i, degree - 1) = -c[i] / c[degree];
  if (degree == 3) {
    m(3, 3) = 0.0;  // unused corner; keep the 3x3 block only
  }
  int count = 0;
  if (degree == 4) {
    Eigen::EigenSolver<Eigen::Matrix4d> es(m, false);
    const auto& ev = es.eigenvalues();
    for (int i = 0; i < 4; ++i) {
      if (std::abs(ev[i].imag()) <= 1e-6 * std::max(1.0, std::abs(ev[i].real())))
        roots[count++] = ev[i].real();
    }
  } else {
    Eigen::Matrix3d m3 = m.topLeftCorner<3, 3>();
    Eigen::EigenSolver<Eigen::Matrix3d> es(m3, false);
    const auto& ev = es.eigenvalues();
    for (int i = 0; i < 3; ++i) {
      if (std::abs(ev[i].imag()) <= 1e-6 * std::max(1.0, std::abs(ev[i].real())))
        roots[count++] = ev[i].real();
    }
  }
  for (int i = 0; i < count; ++i) {
    double x = roots[i];
    for (int it = 0; it < 3; ++it) {
      const double d = evalDerivative(c, degree, x);
      if (d == 0.0) break;
      const double step = evalPoly(c, degree, x) / d;
      if (!std::isfinite(step)) break;
      x -= step;
    }
    if (std::isfinite(x)) roots[i] = x;
  }
  return count;
}

}  // namespace epitrack
