#include "algo/geometry/homography.hpp"

#include <cmath>

#include <Eigen/Eigenvalues>
#include <Eigen/LU>

#include "algo/geometry/dlt_rows.hpp"
#include "algo/geometry/point_normalization.hpp"

namespace epitrack {

double homographyTransferSquared(const Eigen::Matrix3d& H, const Eigen::Vector2d& x1,
                                 const Eigen::Vector2d& x2) {
  const Eigen::Vector3d p = H * x1.homogeneous();
  if (!(std::abs(p.z()) > 1e-12)) return std::numeric_limits<double>::infinity();
  return (p.hnormalized() - x2).squaredNorm();
}

namespace {

// The two rows of x2 x (H x1) = 0 (H & Z eq. 4.3), H row-major in the 9-vector.
inline void dltRows(const Eigen::Vector2d& a, const Eigen::Vector2d& b,
                    Eigen::Matrix<double, 9, 1>& r0, Eigen::Matrix<double, 9, 1>& r1) {
  r0 << 0, 0, 0, -a.x(), -a.y(), -1, b.y() * a.x(), b.y() * a.y(), b.y();
  r1 << a.x(), a.y(), 1, 0, 0, 0, -b.x() * a.x(), -b.x() * a.y(), -b.x();
}

struct HomographyKernel {
  static constexpr int kMinSamples = 4;
  static constexpr int kMaxModels = 1;
  using Model = Eigen::Matrix3d;
  std::span<const Eigen::Vector2d> x1, x2;

  bool sampleIsDegenerate(std::span<const int> s) const {
    // Three collinear points in either image make the four-point DLT degenerate.
    for (int a = 0; a < 4; ++a) {
      const int i = s[static_cast<std::size_t>(a)];
      const int j = s[static_cast<std::size_t>((a + 1) % 4)];
      const int k = s[static_cast<std::size_t>((a + 2) % 4)];
      for (const auto* x : {&x1, &x2}) {
        const Eigen::Vector2d u =
            (*x)[static_cast<std::size_t>(j)] - (*x)[static_cast<std::size_t>(i)];
        const Eigen::Vector2d v =
            (*x)[static_cast<std::size_t>(k)] - (*x)[static_cast<std::size_t>(i)];
        if (std::abs(u.x() * v.y() - u.y() * v.x()) < 1e-6 * (u.squaredNorm() + v.squaredNorm()))
          return true;
      }
    }
    return false;
  }
  int fit(std::span<const int> s, Model* models) const {
    Eigen::Matrix3d H;
    if (!fitHomographyDlt(x1, x2, s, H)) return 0;
    models[0] = H;
    return 1;
  }
  double squaredError(int i, const Model& H) const {
    return homographyTransferSquared(H, x1[static_cast<std::size_t>(i)],
                                     x2[static_cast<std::size_t>(i)]);
  }
};

}  // namespace

bool fitHomographyDlt(std::span<const Eigen::Vector2d> x1, std::span<const Eigen::Vector2d> x2,
                      std::span<const int> indices, Eigen::Matrix3d& H) {
  const std::size_t n = indices.empty() ? x1.size() : indices.size();
  if (n < 4 || x1.size() != x2.size()) return false;
  Eigen::Matrix3d T1, T2;
  if (!hartleyNormalization(x1, indices, T1) || !hartleyNormalization(x2, indices, T2))
    return false;
  Eigen::Matrix<double, 9, 1> h;
  Eigen::Matrix<double, 9, 1> r0, r1;
  if (n == 4) {
    Eigen::Matrix<double, 8, 9> A;
    for (std::size_t i = 0; i < 4; ++i) {
      const std::size_t k = indices.empty() ? i : static_cast<std::size_t>(indices[i]);
      dltRows((T1 * x1[k].homogeneous()).hnormalized(), (T2 * x2[k].homogeneous()).hnormalized(),
              r0, r1);
      A.row(static_cast<int>(2 * i)) = r0.transpose();
      A.row(static_cast<int>(2 * i + 1)) = r1.transpose();
    }
    if (!nullVector8x9(A, h)) return false;
  } else {
    Eigen::Matrix<double, 9, 9> AtA = Eigen::Matrix<double, 9, 9>::Zero();
    for (std::size_t i = 0; i < n; ++i) {
      const std::size_t k = indices.empty() ? i : static_cast<std::size_t>(indices[i]);
      dltRows((T1 * x1[k].homogeneous()).hnormalized(), (T2 * x2[k].homogeneous()).hnormalized(),
              r0, r1);
      AtA.selfadjointView<Eigen::Upper>().rankUpdate(r0);
      AtA.selfadjointView<Eigen::Upper>().rankUpdate(r1);
    }
    Eigen::Matrix<double, 9, 9> full = AtA.selfadjointView<Eigen::Upper>();
    Eigen::SelfAdjointEigenSolver<Eigen::Matrix<double, 9, 9>> es(full);
    if (es.info() != Eigen::Success) return false;
    if (!(es.eigenvalues()(1) > 1e-12 * std::max(1e-300, es.eigenvalues()(8)))) return false;
    h = es.eigenvectors().col(0);
  }
  H = T2.inverse() * matrix3FromRowMajor(h) * T1;
  if (!H.allFinite() || std::abs(H(2, 2)) < 1e-12 * H.norm()) {
    if (!H.allFinite() || H.norm() == 0.0) return false;
    H /= H.norm();
  } else {
    H /= H(2, 2);
  }
  return std::abs(H.determinant()) > 1e-12 * std::pow(H.norm(), 3);
}

HomographyRansac::HomographyRansac(int max_points)
    : max_points_(max_points),
      inlier_index_(static_cast<std::size_t>(max_points)),
      mask_(static_cast<std::size_t>(max_points)) {}

HomographyRansac::Status HomographyRansac::estimate(std::span<const Eigen::Vector2d> x1,
                                                    std::span<const Eigen::Vector2d> x2,
                                                    const HomographyOptions& options,
                                                    HomographyResult& result) {
  result = {};
  const int n = static_cast<int>(x1.size());
  if (x1.size() != x2.size() || n < 4) return Status::kTooFewPoints;
  if (n > max_points_) return Status::kTooManyPoints;
  for (std::size_t i = 0; i < x1.size(); ++i)
    if (!x1[i].allFinite() || !x2[i].allFinite()) return Status::kNonFinite;
  HomographyKernel k{x1, x2};
  Ransac<HomographyKernel> ransac;
  Eigen::Matrix3d H;
  RansacSummary summary;
  if (!ransac.run(k, n, options.ransac, H, summary)) return Status::kDegenerate;
  const double t2 = options.ransac.threshold * options.ransac.threshold;
  auto collect = [&](const Eigen::Matrix3d& model, double& score) {
    int count = 0;
    score = 0.0;
    for (int i = 0; i < n; ++i) {
      const double e2 = k.squaredError(i, model);
      if (e2 < t2) inlier_index_[static_cast<std::size_t>(count++)] = i;
      score += e2 < t2 ? e2 : t2;
    }
    return count;
  };
  double score = 0.0;
  int count = collect(H, score);
  for (int round = 0; round < options.refit_rounds && count >= 4; ++round) {
    Eigen::Matrix3d refit;
    if (!fitHomographyDlt(
            x1, x2, std::span<const int>(inlier_index_.data(), static_cast<std::size_t>(count)),
            refit))
      break;
    double s2 = 0.0;
    for (int i = 0; i < n; ++i) {
      const double e2 = k.squaredError(i, refit);
      s2 += e2 < t2 ? e2 : t2;
    }
    if (s2 >= score) break;
    H = refit;
    count = collect(H, score);
  }
  double sum = 0.0;
  for (int i = 0; i < n; ++i) {
    const double e2 = k.squaredError(i, H);
    mask_[static_cast<std::size_t>(i)] = e2 < t2 ? 1 : 0;
    if (e2 < t2) sum += e2;
  }
  if (count < 4) return Status::kDegenerate;
  result.H = H;
  result.inliers = count;
  result.iterations = summary.iterations;
  result.rms_transfer_px = std::sqrt(sum / count);
  result.mask = std::span<const uint8_t>(mask_.data(), x1.size());
  return Status::kOk;
}

}  // namespace epitrack
