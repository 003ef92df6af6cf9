#pragma once

#include <array>
#include <cstdint>
#include <limits>
#include <span>
#include <vector>

#include <Eigen/Cholesky>
#include <Eigen/Core>
#include <Eigen/LU>

#include "algo/geometry/rolling_shutter.hpp"

namespace epitrack {

/// A camera of the bundle adjustment: the world-to-camera transform x_c = R_cw X + t_cw.
struct BaCamera {
  Eigen::Matrix3d R_cw = Eigen::Matrix3d::Identity();
  Eigen::Vector3d t_cw = Eigen::Vector3d::Zero();
};

/// Intrinsics shared by every camera: fx = f, fy = f * aspect, principal point fixed, radial
/// distortion k1, k2 on normalized coordinates (ARCHITECTURE.md convention).
struct BaIntrinsics {
  double f = 1.0;
  double aspect = 1.0;
  double cx = 0.0;
  double cy = 0.0;
  double k1 = 0.0;
  double k2 = 0.0;
};

/// A camera's neighbours along the trajectory (the cameras of the previous and the next frame; -1:
/// none), for the smooth-trajectory rolling-shutter adjustment.
struct BaTrajectoryNeighbours {
  int previous = -1;
  int next = -1;
};

/// One measurement: point `point` seen by camera `camera` at pixel `xy`.
struct BaObservation {
  int camera = 0;
  int point = 0;
  Eigen::Vector2d xy = Eigen::Vector2d::Zero();
};

struct BundleAdjustmentOptions {
  int max_iterations = 30;
  double huber_px = 1.0;         ///< Huber loss threshold in pixels (<= 0: plain least squares)
  bool refine_focal = false;     ///< also estimate the shared focal length
  int refine_distortion = 0;     ///< 0: none, 1: k1, 2: k1 and k2
  double initial_lambda = 1e-4;  ///< Levenberg-Marquardt damping (relative to the diagonal)
  double function_tolerance = 1e-10;  ///< stop when the relative cost decrease falls below
  double step_tolerance = 1e-12;      ///< stop when the relative step falls below
  /// Rolling shutter (the solve overload with motions): prior pulling each free camera's readout
  /// motion (w, v) towards zero, weighted like this many pixels per radian and per world unit
  /// (per frame interval). It keeps v defined when the points are far (v then has no image
  /// effect) and is negligible against the rows' evidence otherwise (about f x tau px per radian
  /// per point, thousands).
  double velocity_prior = 1.0;
  /// What each camera's motion prior pulls towards (one per camera; empty: zero). The rolling-
  /// shutter refinement passes the frame-to-frame motion here: free per-frame motions with points
  /// free are nearly degenerate (the scene can bend to absorb them: Albl et al., ECCV 2016), and
  /// tying each to the trajectory's motion removes that.
  std::span<const RollingShutterMotion> motion_prior_mean;
  /// The smooth-trajectory adjustment (solveTrajectory): also estimate the line delay (the
  /// readout), one parameter shared by every camera.
  bool refine_readout = false;
  /// The smooth-trajectory adjustment: after an iteration that formed and factorized the reduced
  /// system, the next ones reuse that factorization with the new gradient (a chord step: the
  /// Newton step of the Hessian as it was, the frozen W and V^-1 in the back-substitution),
  /// until one fails to lower the cost; then a full iteration again. For an adjustment started
  /// near its minimum (the rolling-shutter refinement after the global-shutter solve) the
  /// Hessian hardly moves, while forming it is O(k^2) per point of k observations.
  bool reuse_factorization = false;
};

struct BundleAdjustmentSummary {
  enum class Status {
    kConverged,         ///< a tolerance was met
    kMaxIterations,     ///< ran out of iterations (the result is still the best found)
    kInvalidInput,      ///< indices out of range, capacities exceeded, non-finite values
    kNumericalFailure,  ///< the normal equations could not be solved
  };
  Status status = Status::kInvalidInput;
  int iterations = 0;
  int chord_steps = 0;  ///< of those, steps with the factorization reused (reuse_factorization)
  double initial_cost = 0.0;  ///< 1/2 sum of robustified squared residuals (pixels^2)
  double final_cost = 0.0;
  double initial_rms_px = 0.0;  ///< RMS reprojection error before and after (plain, not robust)
  double final_rms_px = 0.0;
  /// solveTrajectory: the line delay at the end (frame intervals per row) and, with
  /// refine_readout, its standard error: the larger of the one that takes every observation's
  /// error as independent (the reduced system's inverse at the minimum scaled by the residuals'
  /// variance, `line_delay_std_error_independent`) and the cluster-robust one (one cluster per
  /// point: a track's errors are correlated along it). 0 when not refined.
  double line_delay = 0.0;
  double line_delay_std_error = 0.0;
  double line_delay_std_error_independent = 0.0;
};

/// What a BundleAdjuster's storage is sized for.
enum class BaCapacity : uint8_t {
  kGlobalShutter,  ///< `solve` (6 parameters per camera)
  /// Also `solve` with a readout motion per camera (12 parameters per camera: a reduced system
  /// 4x larger) and `solveTrajectory`.
  kRollingShutter,
  /// Also `solveTrajectory` (6 per camera: the motions are the trajectory's, not parameters).
  kSmoothTrajectory,
};

/// Sparse bundle adjustment by Levenberg-Marquardt with the Schur complement (Triggs et al.,
/// "Bundle Adjustment — A Modern Synthesis", §6; Hartley & Zisserman §A6.3): the point blocks
/// (3x3) are eliminated and the reduced camera system (6 per free camera + the shared intrinsics)
/// is solved densely by an in-place Cholesky factorisation. Residuals are robustified by the Huber
/// loss (IRLS weights). Rotations are updated on the left, R <- exp([dtheta]x) R.
///
/// Gauge: monocular BA is defined up to a similarity. Mark at least one camera fixed (its pose
/// stays); the remaining scale freedom is held by the damping (and should be fixed by the caller,
/// e.g. by renormalising the result).
///
/// Storage is sized at construction from the capacities; `solve` does not allocate.
class BundleAdjuster {
 public:
  BundleAdjuster(int max_cameras, int max_points, int max_observations,
                 BaCapacity capacity = BaCapacity::kGlobalShutter);

  /// Refines `cameras` (except those with camera_fixed[i] != 0), every point of `points`, and the
  /// intrinsics requested by `options`, in place. `points_fixed` may be empty (all free).
  BundleAdjustmentSummary solve(std::span<BaCamera> cameras, std::span<const uint8_t> camera_fixed,
                                std::span<Eigen::Vector3d> points,
                                std::span<const uint8_t> points_fixed,
                                std::span<const BaObservation> observations,
                                BaIntrinsics& intrinsics, const BundleAdjustmentOptions& options);

  /// How well the adjustment determines each camera's centre, at a minimum of `solve` (global
  /// shutter; call it with the solve's arguments after it): the marginal covariance of the
  /// centre C = -R^T t from the inverse of the reduced camera system at the minimum (the points
  /// eliminated by the Schur complement, which marginalises them, and the refined intrinsics
  /// marginalised with them; the smallest relative damping of 1e-9, 1e-6, 1e-3 that factors),
  /// scaled by the residuals' variance sigma^2 = 2 cost / dof. Gauge: the fixed cameras keep
  /// their pose; with one fixed camera the overall scale is held by the constraint that the free
  /// cameras do not move along the similarity's scaling about its centre (two or more fixed
  /// cameras hold it themselves). `centre_sd[c]` = sqrt(trace Sigma_C) in world units (0 for a
  /// fixed camera, -1 for a free camera without one observation in front of it: undetermined).
  /// False: invalid input, no fixed camera, or a system that is not positive definite.
  bool centreStandardDeviations(
      std::span<const BaCamera> cameras, std::span<const uint8_t> camera_fixed,
      std::span<const Eigen::Vector3d> points, std::span<const uint8_t> points_fixed,
      std::span<const BaObservation> observations, const BaIntrinsics& intrinsics,
      const BundleAdjustmentOptions& options, std::span<double> centre_sd);

  /// The rolling-shutter adjustment (issue 27): each camera's pose is its reference row's and
  /// `motions[c]` its motion over the readout (algo/geometry/rolling_shutter.hpp: constant angular
  /// velocity in the camera frame, linear velocity of the centre in the world frame, per frame
  /// interval), refined with the pose for every free camera (a fixed camera keeps both). Every
  /// observation is projected on the row where the point is seen (the fixed point of the row);
  /// the Jacobians are analytic and include the row's own dependence on the parameters. The
  /// motions are per camera, not a smooth trajectory across frames: one observation then
  /// touches one camera (the Schur complement's structure is unchanged), and the motion within a
  /// readout is free to differ from the frame-to-frame motion (hand shake changes direction within
  /// a frame interval). With `shutter.line_delay == 0` or empty `motions` this is `solve` above,
  /// bit for bit. Needs the rolling-shutter capacity (constructor); `motions.size()` must equal
  /// `cameras.size()`.
  BundleAdjustmentSummary solve(std::span<BaCamera> cameras, std::span<const uint8_t> camera_fixed,
                                std::span<Eigen::Vector3d> points,
                                std::span<const uint8_t> points_fixed,
                                std::span<const BaObservation> observations,
                                BaIntrinsics& intrinsics, const BundleAdjustmentOptions& options,
                                const RollingShutter& shutter,
                                std::span<RollingShutterMotion> motions);

  /// The rolling-shutter adjustment with a smooth trajectory (issue 27): no motion parameters;
  /// each camera's motion over the readout is the trajectory's motion at that camera, the central
  /// difference of its neighbours' poses (one-sided with one neighbour, zero with none):
  ///   w = (Log(R_p R_c^T) - Log(R_n R_c^T)) / 2,   v = (c_n - c_p) / 2   (per frame interval),
  /// so the motion within a readout is tied to the motion between frames and the readout (the
  /// line delay, `options.refine_readout`) is observable as one parameter. An observation then
  /// touches its camera and that camera's neighbours; the reduced system stays 6 per free camera
  /// (a point's coupling blocks are merged per camera, so a point seen in k consecutive frames
  /// pairs k + 2 blocks). `neighbours.size()` and `motions.size()` must equal `cameras.size()`;
  /// `motions` receives the trajectory's motions at the end. Needs the rolling-shutter capacity.
  BundleAdjustmentSummary solveTrajectory(
      std::span<BaCamera> cameras, std::span<const uint8_t> camera_fixed,
      std::span<Eigen::Vector3d> points, std::span<const uint8_t> points_fixed,
      std::span<const BaObservation> observations, BaIntrinsics& intrinsics,
      const BundleAdjustmentOptions& options, const RollingShutter& shutter,
      std::span<const BaTrajectoryNeighbours> neighbours, std::span<RollingShutterMotion> motions);

  /// The trajectory's motion at camera c (see solveTrajectory) and, when `D` is given, its
  /// derivative with respect to the pose updates (dtheta, dt) of the previous camera (columns
  /// 0-5), c itself (6-11) and the next camera (12-17).
  static RollingShutterMotion trajectoryMotion(std::span<const BaCamera> cameras,
                                               const BaTrajectoryNeighbours& neighbours, int c,
                                               Eigen::Matrix<double, 6, 18>* D);

  /// Rolling-shutter projection: the pixel where `X` is seen (the fixed point of its row, to
  /// 1e-9 px) and the row's time `tau`; false when behind the camera or not settling.
  static bool projectRollingShutter(const BaCamera& camera, const RollingShutterMotion& motion,
                                    const RollingShutter& shutter, const BaIntrinsics& k,
                                    const Eigen::Vector3d& X, Eigen::Vector2d& uv, double& tau,
                                    double start_row = kNoRow);
  /// No row known yet: projectRollingShutter starts from the reference row's projection.
  static constexpr double kNoRow = std::numeric_limits<double>::quiet_NaN();

  /// Its analytic Jacobians with respect to the camera update (dtheta, dt), the motion (w, v), the
  /// point and the intrinsics (f, k1, k2), the row's dependence included.
  static bool projectRollingShutterWithJacobians(
      const BaCamera& camera, const RollingShutterMotion& motion, const RollingShutter& shutter,
      const BaIntrinsics& k, const Eigen::Vector3d& X, Eigen::Vector2d& uv,
      Eigen::Matrix<double, 2, 6>& J_cam, Eigen::Matrix<double, 2, 6>& J_motion,
      Eigen::Matrix<double, 2, 3>& J_point, Eigen::Matrix<double, 2, 3>& J_intr,
      Eigen::Vector2d* J_line_delay = nullptr);

  /// J^T v of those Jacobians (the gradient of a residual weighted by `v`), at the row time `tau`
  /// projectRollingShutter found: vector products (reverse mode) instead of the 2 x 6 matrices.
  struct RollingShutterGradient {
    Eigen::Matrix<double, 6, 1> camera;  ///< (dtheta, dt)
    Eigen::Matrix<double, 6, 1> motion;  ///< (w, v)
    Eigen::Vector3d point;
    Eigen::Vector3d intrinsics;  ///< (f, k1, k2)
    double line_delay = 0.0;
  };
  static bool rollingShutterGradient(const BaCamera& camera, const RollingShutterMotion& motion,
                                     const RollingShutter& shutter, const BaIntrinsics& k,
                                     const Eigen::Vector3d& X, double tau, const Eigen::Vector2d& v,
                                     RollingShutterGradient& out);

  /// Projection used by the adjustment (for tests and callers): false when behind the camera.
  static bool project(const BaCamera& camera, const BaIntrinsics& k, const Eigen::Vector3d& X,
                      Eigen::Vector2d& uv);
  /// The projection of a point already in camera coordinates (false behind the camera).
  static bool projectCameraPoint(const BaIntrinsics& k, const Eigen::Vector3d& p_camera,
                                 Eigen::Vector2d& uv);

  /// Analytic Jacobians of the projection with respect to the camera update (dtheta, dt), the point
  /// and the intrinsics (f, k1, k2). Exposed for the numeric-vs-analytic test.
  static bool projectWithJacobians(const BaCamera& camera, const BaIntrinsics& k,
                                   const Eigen::Vector3d& X, Eigen::Vector2d& uv,
                                   Eigen::Matrix<double, 2, 6>& J_cam,
                                   Eigen::Matrix<double, 2, 3>& J_point,
                                   Eigen::Matrix<double, 2, 3>& J_intr);

 private:
  /// The reduced system's layout of one solve: 6 parameters per free camera, then the refined
  /// intrinsics (f, k1, k2 as `kcol` lists them).
  struct Layout {
    int nc = 0, np = 0, no = 0;  // cameras, points, observations
    int nk = 0;                  // intrinsics refined
    int k0 = 0;                  // their first index (6 x free cameras)
    int n = 0;                   // reduced-system size
    int kcol[4] = {0, 0, 0, 0};  // 0: f, 1: k1, 2: k2, 3: the line delay
    bool rs = false;             // rolling shutter: 12 per free camera, the motion at slot + 6
    bool traj = false;  // smooth trajectory: 6 per free camera, observations touch neighbours
  };
  BundleAdjustmentSummary solveImpl(std::span<BaCamera> cameras,
                                    std::span<const uint8_t> camera_fixed,
                                    std::span<Eigen::Vector3d> points,
                                    std::span<const uint8_t> points_fixed,
                                    std::span<const BaObservation> observations,
                                    BaIntrinsics& intrinsics,
                                    const BundleAdjustmentOptions& options);
  bool validInput(std::span<const BaCamera> cameras, std::span<const uint8_t> camera_fixed,
                  std::span<const Eigen::Vector3d> points, std::span<const uint8_t> points_fixed,
                  std::span<const BaObservation> observations,
                  const BundleAdjustmentOptions& options) const;
  /// Camera slots, observations grouped by point (CSR) and, per point, by free camera slot.
  Layout buildLayout(std::span<const uint8_t> camera_fixed,
                     std::span<const BaObservation> observations, int np,
                     const BundleAdjustmentOptions& options);
  /// The undamped normal equations at the current parameters: U and g_c (S_, rhs_), V and g_p
  /// per point, the coupling blocks W per observation; diag_ holds U's diagonal.
  void linearize(std::span<const BaCamera> cameras, std::span<const Eigen::Vector3d> points,
                 std::span<const BaObservation> observations, const BaIntrinsics& k,
                 const BundleAdjustmentOptions& options, const Layout& L);
  /// linearize for the smooth-trajectory model (pair_Wc_ accumulated per merged entry).
  void linearizeTrajectory(std::span<const BaCamera> cameras,
                           std::span<const Eigen::Vector3d> points,
                           std::span<const BaObservation> observations, const BaIntrinsics& k,
                           const BundleAdjustmentOptions& options, const Layout& L);
  /// The smooth-trajectory model's cost at the current parameters (as evaluateCost) and, from
  /// the same projections, the gradients g_c and g_p alone (rhs_, gp_; U, V and W keep the last
  /// full linearization's: the chord step's). The pulls on each camera's motion are summed per
  /// camera, then carried onto its three poses by motion_D_ once.
  double trajectoryCostAndGradient(std::span<const BaCamera> cameras,
                                   std::span<const Eigen::Vector3d> points,
                                   std::span<const BaObservation> observations,
                                   const BaIntrinsics& k, const BundleAdjustmentOptions& options,
                                   const Layout& L, double* rms = nullptr);
  /// The reduced system's right-hand side b_ from the gradients (rhs_, gp_) and the last form's
  /// W, V^-1: formReducedSystem's, and the chord step's with a new gradient.
  void formReducedRhs(std::span<const uint8_t> points_fixed, const Layout& L);
  /// Sum of point p's observations' intrinsics couplings (Wk_).
  Eigen::Matrix<double, 4, 3> intrinsicsCoupling(std::size_t p) const;
  /// The reduced-system slots of the previous, own and next camera of `camera` (-1: none, fixed).
  void trajectorySlots(int camera, int slot[3]) const;
  /// The chord step (BundleAdjustmentOptions::reuse_factorization): the reduced right-hand side
  /// from the new gradients and the last form's W V^-1, solved with the Cholesky factor left in
  /// A_; false when it does not lower `cost` (the step undone).
  bool chordStep(std::span<BaCamera> cameras, std::span<Eigen::Vector3d> points,
                 std::span<const uint8_t> points_fixed, std::span<const BaObservation> observations,
                 BaIntrinsics& k, const BundleAdjustmentOptions& options, const Layout& L,
                 double& cost, double& rms, double& step2);
  /// One observation of the smooth-trajectory model linearized: its residual r, Huber weight w,
  /// Jacobians on the previous, own and next camera's pose (J, at reduced-system slots `slot`,
  /// -1: fixed or none), on the refined intrinsics (Jk, `Layout::kcol` order) and on the point.
  struct TrajectoryObservationJacobian {
    Eigen::Vector2d r = Eigen::Vector2d::Zero();
    double w = 0.0;
    Eigen::Matrix<double, 2, 6> J[3];
    int slot[3] = {-1, -1, -1};
    Eigen::Matrix<double, 2, 4> Jk = Eigen::Matrix<double, 2, 4>::Zero();
    Eigen::Matrix<double, 2, 3> Jp = Eigen::Matrix<double, 2, 3>::Zero();
  };
  /// Fills `out` for observation `o` (motion_D_ and motions_ current); false: not projected.
  bool trajectoryObservationJacobian(std::span<const BaCamera> cameras,
                                     std::span<const Eigen::Vector3d> points,
                                     const BaObservation& o, const BaIntrinsics& k,
                                     const BundleAdjustmentOptions& options, const Layout& L,
                                     TrajectoryObservationJacobian& out) const;
  /// The line delay's variance from the scatter of each point's pull on it (the cluster-robust
  /// sandwich, one cluster per point): `u` = A^-1 e_readout on the reduced system.
  double lineDelayClusterVariance(std::span<const BaCamera> cameras,
                                  std::span<const Eigen::Vector3d> points,
                                  std::span<const uint8_t> points_fixed,
                                  std::span<const BaObservation> observations,
                                  const BaIntrinsics& k, const BundleAdjustmentOptions& options,
                                  const Layout& L, const Eigen::Ref<const Eigen::VectorXd>& u);
  /// The trajectory's motions of every camera from the current poses (into motions_, their
  /// derivatives into motion_D_).
  void updateTrajectoryMotions(std::span<const BaCamera> cameras);
  /// The line delay's standard errors at the current parameters (after the iterations), into
  /// `summary` (line_delay_std_error and line_delay_std_error_independent).
  void lineDelayStdErrors(std::span<const BaCamera> cameras,
                          std::span<const Eigen::Vector3d> points,
                          std::span<const uint8_t> points_fixed,
                          std::span<const BaObservation> observations, const BaIntrinsics& k,
                          const BundleAdjustmentOptions& options, const Layout& L, double cost,
                          BundleAdjustmentSummary& summary);
  /// Adds the scale's gauge constraint (centreStandardDeviations) to A_, over the cameras whose
  /// `undetermined` entry is not negative; false: none of them moves.
  bool holdScale(std::span<const BaCamera> cameras, const BaCamera& anchor_camera,
                 std::span<const double> undetermined, const Layout& L);
  /// The damped Schur complement for `lambda` (A_, mirrored) and its right-hand side (b_).
  void formReducedSystem(double lambda, std::span<const uint8_t> points_fixed, const Layout& L);
  /// The damped Schur complement for `lambda` solved for the camera and intrinsics step
  /// (delta_); false when it is not positive definite.
  bool solveReducedSystem(double lambda, std::span<const uint8_t> points_fixed, const Layout& L);
  /// The points' step dp_ = V^-1 (-g_p - W^T dc); returns the squared norm of the whole step.
  double backSubstitute(std::span<const BaObservation> observations,
                        std::span<const uint8_t> points_fixed, const Layout& L);
  /// Applies delta_ and dp_ (backing the parameters up first).
  void applyStep(std::span<BaCamera> cameras, std::span<Eigen::Vector3d> points, BaIntrinsics& k,
                 const Layout& L);
  /// Restores the parameters applyStep backed up.
  void undoStep(std::span<BaCamera> cameras, std::span<Eigen::Vector3d> points);
  double evaluateCost(std::span<const BaCamera> cameras, std::span<const Eigen::Vector3d> points,
                      std::span<const BaObservation> observations, const BaIntrinsics& k,
                      double huber, double* rms) const;

  int max_cameras_;
  int max_points_;
  int max_observations_;
  BaCapacity capacity_;
  // The rolling-shutter solve in progress (empty motions: the global shutter).
  RollingShutter shutter_;
  std::span<RollingShutterMotion> motions_;
  double velocity_prior_ = 0.0;
  std::span<const RollingShutterMotion> motion_prior_mean_;
  /// The motion prior's residual of camera c: its motion less the prior's mean.
  [[nodiscard]] Eigen::Matrix<double, 6, 1> motionPriorResidual(std::size_t c) const;
  /// `cost` plus the motion prior's cost of the free cameras.
  [[nodiscard]] double addMotionPriorCost(double cost) const;
  std::vector<RollingShutterMotion> motions_backup_;
  // The smooth-trajectory solve in progress (empty: not that model).
  std::span<const BaTrajectoryNeighbours> neighbours_;
  std::vector<Eigen::Matrix<double, 6, 18>> motion_D_;  // per camera d motion / d poses
  std::vector<std::array<int, 3>> obs_entry_;           // per observation its merged pair entries
  // trajectoryCostAndGradient's per-camera sums of the pulls on the pose and on the motion.
  std::vector<Eigen::Matrix<double, 6, 1>> camera_gradient_;
  std::vector<Eigen::Matrix<double, 6, 1>> motion_gradient_;
  bool gradient_current_ = false;  // rhs_ and gp_ hold the gradient at the current parameters
  double line_delay_backup_ = 0.0;
  std::vector<Eigen::Matrix<double, 6, 3>> Wv_;  // per observation J_motion^T W J_p
  std::vector<int> pair_begin_;                  // per point, its first pair entry
  // Workspaces (sized in the constructor).
  std::vector<int> camera_slot_;       // reduced-system slot of each camera, -1 if fixed
  std::vector<int> point_obs_offset_;  // CSR over points: observations of point p
  std::vector<int> point_obs_index_;
  std::vector<int> point_obs_cursor_;
  // Per point, its observations by free cameras sorted by reduced-system slot (from pair_begin_,
  // the CSR offsets above for the global shutter; pair_end_ ends the free ones; with a rolling
  // shutter each observation has two entries, its camera's pose slot and motion slot), with
  // contiguous copies of their W blocks: the Schur complement's pair loop then reads memory in
  // order and visits each camera pair once.
  std::vector<int> pair_obs_;
  std::vector<int> pair_slot_;
  std::vector<int> pair_end_;
  std::vector<Eigen::Matrix<double, 6, 3>> pair_Wc_;
  std::vector<Eigen::Matrix3d> V_;               // per point J_p^T W J_p
  std::vector<Eigen::Vector3d> gp_;              // per point J_p^T W r
  std::vector<Eigen::Matrix<double, 6, 3>> Wc_;  // per observation J_c^T W J_p
  std::vector<Eigen::Matrix<double, 4, 3>> Wk_;  // per observation J_k^T W J_p
  std::vector<Eigen::Matrix3d> Vinv_;
  /// The row each observation was last projected to (rolling shutter; kNoRow: none yet): where
  /// the next projection's row iteration starts, one or two projections fewer after a small
  /// step. A start, not state: the projection converges to the same row from anywhere near.
  mutable std::vector<double> row_;
  std::vector<Eigen::Vector3d> dp_;
  std::vector<BaCamera> cameras_backup_;
  std::vector<Eigen::Vector3d> points_backup_;
  Eigen::MatrixXd S_;    // undamped reduced-system blocks U (camera + intrinsics)
  Eigen::MatrixXd A_;    // damped Schur complement, factorised in place
  Eigen::VectorXd rhs_;  // gradient of the reduced parameters
  Eigen::VectorXd b_;
  Eigen::VectorXd delta_;
  Eigen::VectorXd diag_;
  BaIntrinsics k_backup_;
};

}  // namespace epitrack
