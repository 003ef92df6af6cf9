#include "algo/geometry/essential_five_point.hpp"

#include <algorithm>
#include <array>
#include <cmath>
#include <complex>
#include <limits>

#include <Eigen/Eigenvalues>
#include <Eigen/LU>
#include <Eigen/QR>
#include <Eigen/SVD>

#include "algo/core/assert.hpp"
#include "algo/geometry/dlt_rows.hpp"
#include "algo/geometry/fundamental.hpp"

namespace epitrack {

namespace {

// Polynomials of degree <= 3 in (x, y, z): one coefficient per monomial x^a y^b z^c. The order
// puts the ten cubic monomials first (x^3 x^2y x^2z xy^2 xyz xz^2 y^3 y^2z yz^2 z^3), then the
// ten standard monomials of the action matrix (x^2 xy xz y^2 yz z^2 x y z 1).
constexpr int kMonomials = 20;
struct Exponent {
  int a, b, c;
};
constexpr std::array<Exponent, kMonomials> kOrder = {{
    {3, 0, 0}, {2, 1, 0}, {2, 0, 1}, {1, 2, 0}, {1, 1, 1}, {1, 0, 2}, {0, 3, 0},
    {0, 2, 1}, {0, 1, 2}, {0, 0, 3}, {2, 0, 0}, {1, 1, 0}, {1, 0, 1}, {0, 2, 0},
    {0, 1, 1}, {0, 0, 2}, {1, 0, 0}, {0, 1, 0}, {0, 0, 1}, {0, 0, 0},
}};

constexpr int monomialIndex(int a, int b, int c) {
  for (int i = 0; i < kMonomials; ++i)
    if (kOrder[static_cast<std::size_t>(i)].a == a && kOrder[static_cast<std::size_t>(i)].b == b &&
        kOrder[static_cast<std::size_t>(i)].c == c)
      return i;
  return -1;
}

using Poly = std::array<double, kMonomials>;

// kProduct[i][j]: the index of monomial i times monomial j (-1: beyond degree 3).
struct ProductTable {
  std::array<std::array<int8_t, kMonomials>, kMonomials> index{};
  constexpr ProductTable() {
    for (int i = 0; i < kMonomials; ++i)
      for (int j = 0; j < kMonomials; ++j) {
        const Exponent& e = kOrder[static_cast<std::size_t>(i)];
        const Exponent& f = kOrder[static_cast<std::size_t>(j)];
        index[static_cast<std::size_t>(i)][static_cast<std::size_t>(j)] =
            static_cast<int8_t>(monomialIndex(e.a + f.a, e.b + f.b, e.c + f.c));
      }
  }
};
constexpr ProductTable kProduct{};

// The monomials are ordered by decreasing degree: a polynomial of degree d has its non-zero
// coefficients from kFirstOfDegree[d] on (linear: x y z 1, quadratic: from x^2).
constexpr int kFirstOfDegree[4] = {19, 16, 10, 0};

Poly multiply(const Poly& p, int p_degree, const Poly& q, int q_degree) {
  Poly r{};
  for (int i = kFirstOfDegree[p_degree]; i < kMonomials; ++i) {
    const double pi = p[static_cast<std::size_t>(i)];
    for (int j = kFirstOfDegree[q_degree]; j < kMonomials; ++j) {
      // NOLINTNEXTLINE(bugprone-signed-char-misuse): -1 marks "no product", the sign is wanted
      const int k = kProduct.index[static_cast<std::size_t>(i)][static_cast<std::size_t>(j)];
      EPITRACK_ASSERT(k >= 0);  // products stay within degree 3 by construction
      r[static_cast<std::size_t>(k)] += pi * q[static_cast<std::size_t>(j)];
    }
  }
  return r;
}

Poly add(const Poly& p, const Poly& q, double sq = 1.0) {
  Poly r;
  for (int i = 0; i < kMonomials; ++i)
    r[static_cast<std::size_t>(i)] =
        p[static_cast<std::size_t>(i)] + sq * q[static_cast<std::size_t>(i)];
  return r;
}

using PolyMatrix = std::array<std::array<Poly, 3>, 3>;

PolyMatrix multiply(const PolyMatrix& A, int a_degree, const PolyMatrix& B, int b_degree) {
  PolyMatrix C{};
  for (int i = 0; i < 3; ++i)
    for (int j = 0; j < 3; ++j)
      for (int k = 0; k < 3; ++k)
        C[static_cast<std::size_t>(i)][static_cast<std::size_t>(j)] =
            add(C[static_cast<std::size_t>(i)][static_cast<std::size_t>(j)],
                multiply(A[static_cast<std::size_t>(i)][static_cast<std::size_t>(k)], a_degree,
                         B[static_cast<std::size_t>(k)][static_cast<std::size_t>(j)], b_degree));
  return C;
}

}  // namespace

double essentialSampsonSquared(const Eigen::Matrix3d& E, const Eigen::Vector2d& n1,
                               const Eigen::Vector2d& n2) {
  return sampsonSquared(E, n1, n2);
}

Eigen::Matrix3d projectToEssential(const Eigen::Matrix3d& M) {
  Eigen::JacobiSVD<Eigen::Matrix3d> svd(M, Eigen::ComputeFullU | Eigen::ComputeFullV);
  const double s = 1.0 / std::sqrt(2.0);
  return svd.matrixU() * Eigen::Vector3d(s, s, 0.0).asDiagonal() * svd.matrixV().transpose();
}

int essentialFivePoint(const Eigen::Vector2d n1[5], const Eigen::Vector2d n2[5],
                       Eigen::Matrix3d E[10]) {
  // Null space of the five constraints: the last four columns of Q in the QR factorisation of
  // their transpose (9 x 5).
  Eigen::Matrix<double, 9, 5> At;
  for (int i = 0; i < 5; ++i) At.col(i) = epipolarCoefficients(n1[i], n2[i]);
  const Eigen::HouseholderQR<Eigen::Matrix<double, 9, 5>> qr(At);
  const Eigen::Matrix<double, 9, 9> V = qr.householderQ();
  if (!V.allFinite()) return 0;
  // E = x X + y Y + z Z + W with X, Y, Z, W the columns 5..8 of V.
  PolyMatrix Ep{};
  const int ix = monomialIndex(1, 0, 0), iy = monomialIndex(0, 1, 0), iz = monomialIndex(0, 0, 1),
            i1 = monomialIndex(0, 0, 0);
  for (int r = 0; r < 3; ++r) {
    for (int c = 0; c < 3; ++c) {
      Poly& p = Ep[static_cast<std::size_t>(r)][static_cast<std::size_t>(c)];
      p.fill(0.0);
      const int k = 3 * r + c;
      p[static_cast<std::size_t>(ix)] = V(k, 5);
      p[static_cast<std::size_t>(iy)] = V(k, 6);
      p[static_cast<std::size_t>(iz)] = V(k, 7);
      p[static_cast<std::size_t>(i1)] = V(k, 8);
    }
  }
  PolyMatrix Et{};
  for (int r = 0; r < 3; ++r)
    for (int c = 0; c < 3; ++c)
      Et[static_cast<std::size_t>(r)][static_cast<std::size_t>(c)] =
          Ep[static_cast<std::size_t>(c)][static_cast<std::size_t>(r)];
  const PolyMatrix EEt = multiply(Ep, 1, Et, 1);
  const PolyMatrix EEtE = multiply(EEt, 2, Ep, 1);
  const Poly trace = add(add(EEt[0][0], EEt[1][1]), EEt[2][2]);
  Eigen::Matrix<double, 10, 20> M;
  // 2 E E^T E - tr(E E^T) E = 0 (nine equations).
  for (int r = 0; r < 3; ++r) {
    for (int c = 0; c < 3; ++c) {
      const Poly eq =
          add(add(EEtE[static_cast<std::size_t>(r)][static_cast<std::size_t>(c)],
                  EEtE[static_cast<std::size_t>(r)][static_cast<std::size_t>(c)]),
              multiply(trace, 2, Ep[static_cast<std::size_t>(r)][static_cast<std::size_t>(c)], 1),
              -1.0);
      for (int m = 0; m < kMonomials; ++m) M(3 * r + c, m) = eq[static_cast<std::size_t>(m)];
    }
  }
  // det(E) = 0, expanded along the first row.
  const auto& e = Ep;
  const auto mul11 = [](const Poly& a, const Poly& b) { return multiply(a, 1, b, 1); };
  const Poly minor0 = add(mul11(e[1][1], e[2][2]), mul11(e[1][2], e[2][1]), -1.0);
  const Poly minor1 = add(mul11(e[1][0], e[2][2]), mul11(e[1][2], e[2][0]), -1.0);
  const Poly minor2 = add(mul11(e[1][0], e[2][1]), mul11(e[1][1], e[2][0]), -1.0);
  const Poly det = add(add(multiply(e[0][0], 1, minor0, 2), multiply(e[0][1], 1, minor1, 2), -1.0),
                       multiply(e[0][2], 1, minor2, 2));
  for (int m = 0; m < kMonomials; ++m) M(9, m) = det[static_cast<std::size_t>(m)];
  // Gauss-Jordan on the cubic monomials: cubic_k = -G(k, :) * basis.
  const Eigen::Matrix<double, 10, 10> C = M.leftCols<10>();
  const Eigen::FullPivLU<Eigen::Matrix<double, 10, 10>> lu(C);
  if (!lu.isInvertible()) return 0;
  const Eigen::Matrix<double, 10, 10> G = lu.solve(M.rightCols<10>());
  if (!G.allFinite()) return 0;
  // Action matrix of x on the basis (x^2 xy xz y^2 yz z^2 x y z 1): x * basis = Mx * basis.
  Eigen::Matrix<double, 10, 10> Mx = Eigen::Matrix<double, 10, 10>::Zero();
  for (int k = 0; k < 6; ++k) Mx.row(k) = -G.row(k);  // x^3 x^2y x^2z xy^2 xyz xz^2
  Mx(6, 0) = 1.0;                                     // x * x = x^2
  Mx(7, 1) = 1.0;                                     // x * y = xy
  Mx(8, 2) = 1.0;                                     // x * z = xz
  Mx(9, 6) = 1.0;                                     // x * 1 = x
  const Eigen::EigenSolver<Eigen::Matrix<double, 10, 10>> es(Mx);
  if (es.info() != Eigen::Success) return 0;
  int count = 0;
  for (int k = 0; k < 10; ++k) {
    const std::complex<double> lambda = es.eigenvalues()(k);
    if (std::abs(lambda.imag()) > 1e-8 * std::max(1.0, std::abs(lambda.real()))) continue;
    const Eigen::Matrix<double, 10, 1> v = es.eigenvectors().col(k).real();
    if (!(std::abs(v(9)) > 1e-12 * v.norm())) continue;
    const double x = v(6) / v(9), y = v(7) / v(9), z = v(8) / v(9);
    Eigen::Matrix3d Es;
    for (int r = 0; r < 3; ++r)
      for (int c = 0; c < 3; ++c) {
        const int i = 3 * r + c;
        Es(r, c) = x * V(i, 5) + y * V(i, 6) + z * V(i, 7) + V(i, 8);
      }
    const double n = Es.norm();
    if (!(n > 0.0) || !Es.allFinite()) continue;
    E[count++] = Es / n;
  }
  return count;
}

namespace {

// Depths of a correspondence in both cameras (x2 = R x1 + t) by the midpoint of the rays; false
// when the rays are parallel.
bool pointDepths(const Eigen::Matrix3d& R, const Eigen::Vector3d& t, const Eigen::Vector2d& a,
                 const Eigen::Vector2d& b, double& d1, double& d2) {
  const Eigen::Vector3d f1 = a.homogeneous();
  const Eigen::Vector3d f2 = R.transpose() * b.homogeneous();
  const Eigen::Vector3d c2 = -R.transpose() * t;
  const double a11 = f1.dot(f1), a12 = -f1.dot(f2), a22 = f2.dot(f2);
  const double b1 = f1.dot(c2), b2 = -f2.dot(c2);
  const double det = a11 * a22 - a12 * a12;
  if (!(std::abs(det) > 1e-14 * a11 * a22)) return false;
  d1 = (a22 * b1 - a12 * b2) / det;
  d2 = (a11 * b2 - a12 * b1) / det;
  return true;
}

struct EssentialModel {
  Eigen::Matrix3d E = Eigen::Matrix3d::Zero();
  Eigen::Matrix3d R = Eigen::Matrix3d::Identity();  // the factorisation the points face
  Eigen::Vector3d t = Eigen::Vector3d::Zero();
};

// Of the four (R, t) of E, the one with the most of `indices` in front of both cameras.
void chooseFactorisation(EssentialModel& m, std::span<const Eigen::Vector2d> n1,
                         std::span<const Eigen::Vector2d> n2, const int* indices, int count) {
  Eigen::JacobiSVD<Eigen::Matrix3d> svd(m.E, Eigen::ComputeFullU | Eigen::ComputeFullV);
  Eigen::Matrix3d U = svd.matrixU(), V = svd.matrixV();
  if (U.determinant() < 0) U.col(2) *= -1.0;
  if (V.determinant() < 0) V.col(2) *= -1.0;
  Eigen::Matrix3d W;
  W << 0, -1, 0, 1, 0, 0, 0, 0, 1;
  const Eigen::Matrix3d Rs[2] = {U * W * V.transpose(), U * W.transpose() * V.transpose()};
  int best = -1;
  for (int r = 0; r < 2; ++r) {
    for (const double sign : {1.0, -1.0}) {
      const Eigen::Vector3d t = sign * U.col(2);
      int front = 0;
      for (int k = 0; k < count; ++k) {
        double d1 = 0.0, d2 = 0.0;
        const auto i = static_cast<std::size_t>(indices[k]);
        if (pointDepths(Rs[r], t, n1[i], n2[i], d1, d2) && d1 > 0.0 && d2 > 0.0) ++front;
      }
      if (front > best) {
        best = front;
        m.R = Rs[r];
        m.t = t;
      }
    }
  }
}

struct EssentialKernel {
  static constexpr int kMinSamples = 5;
  static constexpr int kMaxModels = 10;
  using Model = EssentialModel;
  std::span<const Eigen::Vector2d> n1, n2;
  double scale2 = 1.0;     // focal^2: normalized squared distances to pixels^2
  bool cheirality = true;  // a correspondence behind either camera is no inlier
  double gate2 = std::numeric_limits<double>::infinity();  // beyond: an outlier whatever its depth
  int* scratch = nullptr;                                  // inlier indices (capacity: all points)

  bool sampleIsDegenerate(std::span<const int>) const { return false; }
  int fit(std::span<const int> s, Model* models) const {
    Eigen::Vector2d a[5], b[5];
    for (int i = 0; i < 5; ++i) {
      a[i] = n1[static_cast<std::size_t>(s[static_cast<std::size_t>(i)])];
      b[i] = n2[static_cast<std::size_t>(s[static_cast<std::size_t>(i)])];
    }
    Eigen::Matrix3d E[10];
    const int n = essentialFivePoint(a, b, E);
    for (int k = 0; k < n; ++k) {
      models[k].E = E[k];
      if (cheirality) chooseFactorisation(models[k], n1, n2, s.data(), 5);
    }
    return n;
  }
  double squaredError(int i, const Model& m) const {
    const auto u = static_cast<std::size_t>(i);
    const double e2 = scale2 * sampsonSquared(m.E, n1[u], n2[u]);
    if (!cheirality || !(e2 < gate2)) return e2;
    double d1 = 0.0, d2 = 0.0;
    if (!pointDepths(m.R, m.t, n1[u], n2[u], d1, d2) || !(d1 > 0.0) || !(d2 > 0.0))
      return std::numeric_limits<double>::infinity();
    return e2;
  }
  // Eight-point refit on the inliers (widened, then at the threshold), projected onto the
  // essential manifold.
  bool localOptimize(Model& m, double t2) const {
    bool changed = false;
    for (const double widen : {4.0, 1.0}) {
      int c = 0;
      for (std::size_t i = 0; i < n1.size(); ++i)
        if (squaredError(static_cast<int>(i), m) < widen * t2) scratch[c++] = static_cast<int>(i);
      if (c < 9) return changed;
      Eigen::Matrix3d refit;
      if (!fitFundamentalEightPoint(
              n1, n2, std::span<const int>(scratch, static_cast<std::size_t>(c)), refit))
        return changed;
      m.E = projectToEssential(refit);
      m.E /= m.E.norm();
      if (cheirality) chooseFactorisation(m, n1, n2, scratch, c);
      changed = true;
    }
    return changed;
  }
};

}  // namespace

EssentialRansac::EssentialRansac(int max_points)
    : max_points_(max_points),
      inlier_index_(static_cast<std::size_t>(std::max(1, max_points))),
      mask_(static_cast<std::size_t>(std::max(1, max_points))) {}

EssentialRansac::Status EssentialRansac::estimate(std::span<const Eigen::Vector2d> n1,
                                                  std::span<const Eigen::Vector2d> n2,
                                                  const EssentialRansacOptions& options,
                                                  EssentialRansacResult& result) {
  result = {};
  const int n = static_cast<int>(n1.size());
  if (n1.size() != n2.size() || n < 5) return Status::kTooFewPoints;
  if (n > max_points_) return Status::kTooManyPoints;
  for (int i = 0; i < n; ++i)
    if (!n1[static_cast<std::size_t>(i)].allFinite() ||
        !n2[static_cast<std::size_t>(i)].allFinite())
      return Status::kNonFinite;
  EssentialKernel k;
  k.n1 = n1;
  k.n2 = n2;
  k.scale2 = options.focal_px * options.focal_px;
  k.scratch = inlier_index_.data();
  k.cheirality = options.cheirality;
  // Residuals beyond 4 x threshold never count (LO widens to 4 t^2): no depths for them.
  k.gate2 = 4.0 * options.ransac.threshold * options.ransac.threshold;
  Ransac<EssentialKernel> ransac;
  EssentialModel E;
  RansacSummary summary;
  if (!ransac.run(k, n, options.ransac, E, summary)) return Status::kDegenerate;
  const double t2 = options.ransac.threshold * options.ransac.threshold;
  int count = 0;
  for (int i = 0; i < n; ++i) {
    const bool in = k.squaredError(i, E) < t2;
    mask_[static_cast<std::size_t>(i)] = in ? 1 : 0;
    count += in ? 1 : 0;
  }
  if (count < 5) return Status::kDegenerate;
  result.E = E.E;
  result.inliers = count;
  result.iterations = summary.iterations;
  result.mask = std::span<const uint8_t>(mask_.data(), n1.size());
  return Status::kOk;
}

}  // namespace epitrack
