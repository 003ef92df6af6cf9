#include "tools/synth/trajectory.hpp"

#include <cmath>
#include <cstdint>

#include "tools/synth/portable_math.hpp"
#include "tools/synth/random.hpp"

namespace epitrack::synth {

bool parseSceneKind(const std::string& name, SceneKind& kind) {
  if (name == "orbit")
    kind = SceneKind::kOrbit;
  else if (name == "dolly")
    kind = SceneKind::kDolly;
  else if (name == "pan")
    kind = SceneKind::kPan;
  else if (name == "handheld")
    kind = SceneKind::kHandheld;
  else if (name == "planar")
    kind = SceneKind::kPlanar;
  else if (name == "shake")
    kind = SceneKind::kShake;
  else if (name == "fastpan")
    kind = SceneKind::kFastPan;
  else if (name == "occlusion")
    kind = SceneKind::kOcclusion;
  else
    return false;
  return true;
}

const char* sceneKindName(SceneKind kind) {
  switch (kind) {
    case SceneKind::kOrbit:
      return "orbit";
    case SceneKind::kDolly:
      return "dolly";
    case SceneKind::kPan:
      return "pan";
    case SceneKind::kHandheld:
      return "handheld";
    case SceneKind::kPlanar:
      return "planar";
    case SceneKind::kShake:
      return "shake";
    case SceneKind::kFastPan:
      return "fastpan";
    case SceneKind::kOcclusion:
      return "occlusion";
  }
  return "orbit";
}

Pose lookAt(const Eigen::Vector3d& eye, const Eigen::Vector3d& target) {
  const Eigen::Vector3d forward = (target - eye).normalized();
  const Eigen::Vector3d right = forward.cross(Eigen::Vector3d::UnitZ()).normalized();
  const Eigen::Vector3d down = forward.cross(right);
  Pose p;
  p.R_wc.col(0) = right;
  p.R_wc.col(1) = down;
  p.R_wc.col(2) = forward;
  p.t_wc = eye;
  return p;
}

namespace {

double wave(double t, double period, double phase) {
  return portableSin(2.0 * kPi * t / period + phase);
}

// Rotation by the vector w (axis * angle), Rodrigues' formula with portable trigonometry.
Eigen::Matrix3d rotationFromVector(const Eigen::Vector3d& w) {
  const double theta = w.norm();
  if (theta < 1e-300) return Eigen::Matrix3d::Identity();
  const Eigen::Vector3d k = w / theta;
  Eigen::Matrix3d K;
  K << 0, -k.z(), k.y(), k.z(), 0, -k.x(), -k.y(), k.x(), 0;
  return Eigen::Matrix3d::Identity() + portableSin(theta) * K +
         (1.0 - portableCos(theta)) * (K * K);
}

// Hand-held jitter (kShake). Frequencies are in cycles per frame; at 30 fps the four bands are
// 1-2, 2-4, 4-6 and 6-8 Hz, with nearly equal angular amplitudes: the angle wanders by 1-3 deg
// while the high bands, whose acceleration grows with the square of the frequency, give image
// accelerations of 5-20 px/frame^2 at a focal of 600 px for the default 2 deg (the issue-20
// figures for hand-held footage).
constexpr int kShakeBands = 4;
constexpr double kBandLowHz[kShakeBands] = {1.0, 2.0, 4.0, 6.0};
constexpr double kBandHighHz[kShakeBands] = {2.0, 4.0, 6.0, 8.0};
constexpr double kBandWeight[kShakeBands] = {1.0, 0.8, 1.0, 0.9};
constexpr double kAxisWeight[3] = {1.0, 1.0, 0.35};  // pitch, yaw, roll (roll is weaker)
constexpr double kFps = 30.0;
// Jerks: at most one per slot of kJerkSlot frames (with probability kJerkProbability), a fast
// C1-smooth rise over 1.5-3 frames and a slower return over 8-16 frames.
constexpr double kJerkSlot = 40.0;
constexpr double kJerkProbability = 0.7;

// Raised-cosine bump of a jerk: 0 before `tau` = 0, 1 at `rise`, 0 again at `rise + fall`.
double jerkProfile(double tau, double rise, double fall) {
  if (tau <= 0.0 || tau >= rise + fall) return 0.0;
  if (tau < rise) return 0.5 * (1.0 - portableCos(kPi * tau / rise));
  return 0.5 * (1.0 + portableCos(kPi * (tau - rise) / fall));
}

}  // namespace

Eigen::Vector3d shakeRotation(const TrajectoryParams& params, double t) {
  Eigen::Vector3d w = Eigen::Vector3d::Zero();
  if (params.kind != SceneKind::kShake || params.shake_deg <= 0.0) return w;
  double weight_sum = 0.0;
  for (const double b : kBandWeight) weight_sum += b;
  // The peak per axis (every band at its crest) is shake_deg.
  const double scale = degToRad(params.shake_deg) / weight_sum;
  SplitMix64 rng(mixSeed(params.seed, 4242));
  for (int axis = 0; axis < 3; ++axis) {
    for (int band = 0; band < kShakeBands; ++band) {
      const double hz = rng.uniform(kBandLowHz[band], kBandHighHz[band]);
      const double phase = rng.uniform(0.0, 2.0 * kPi);
      // A slow envelope (3-6 s) so the shake is not stationary: 0.55..1 of the band amplitude.
      const double env_period = rng.uniform(90.0, 180.0);
      const double env_phase = rng.uniform(0.0, 2.0 * kPi);
      const double envelope = 0.775 + 0.225 * wave(t, env_period, env_phase);
      w[axis] +=
          scale * kAxisWeight[axis] * kBandWeight[band] * envelope * wave(t, kFps / hz, phase);
    }
  }
  // Jerks of the slots that can reach t (one lasts less than a slot).
  const double slot_f = std::floor(t / kJerkSlot);
  for (double slot = slot_f - 1.0; slot <= slot_f; slot += 1.0) {
    const auto key = static_cast<uint64_t>(static_cast<int64_t>(slot) + (int64_t{1} << 40));
    SplitMix64 jr(mixSeed(params.seed ^ 0x5EEDull, key));
    if (jr.uniform() >= kJerkProbability) continue;
    const double start = (slot + jr.uniform(0.0, 0.75)) * kJerkSlot;
    const double amplitude = degToRad(params.shake_deg) * jr.uniform(0.35, 0.7);
    const double direction = jr.uniform(0.0, 2.0 * kPi);
    const double rise = jr.uniform(1.5, 3.0);
    const double fall = jr.uniform(8.0, 16.0);
    const double s = amplitude * jerkProfile(t - start, rise, fall);
    w.x() += s * portableCos(direction);
    w.y() += s * portableSin(direction);
  }
  return w;
}

Pose trajectoryPose(const TrajectoryParams& params, double t) {
  switch (params.kind) {
    case SceneKind::kOrbit: {
      const double theta = degToRad(-135.0 + params.orbit_speed_deg * t);
      const Eigen::Vector3d eye(6.0 * portableCos(theta), 6.0 * portableSin(theta), 1.7);
      const double a = params.target_wander;
      const Eigen::Vector3d target(a * wave(t, 173.0, 0.3), 0.7 * a * wave(t, 131.0, 1.1),
                                   0.5 + 0.4 * a * wave(t, 97.0, 2.0));
      return lookAt(eye, target);
    }
    case SceneKind::kDolly: {
      const double speed = std::min(0.015, 6.0 / std::max(1, params.frames));
      const Eigen::Vector3d eye(0.15 * wave(t, 200.0, 0.0), -10.0 + speed * t, 1.6);
      return lookAt(eye, Eigen::Vector3d(0.0, 12.0, 1.0));
    }
    case SceneKind::kPan: {
      const Eigen::Vector3d eye(0.0, -7.0, 1.6);
      const double yaw = degToRad(30.0 * wave(t, 400.0, 0.0));
      const double pitch = degToRad(-6.0 + 2.0 * wave(t, 260.0, 0.5));
      const Eigen::Vector3d forward(portableSin(yaw) * portableCos(pitch),
                                    portableCos(yaw) * portableCos(pitch), portableSin(pitch));
      return lookAt(eye, eye + forward);
    }
    case SceneKind::kHandheld: {
      SplitMix64 rng(mixSeed(params.seed, 77));
      double phase[12];
      for (double& p : phase) p = rng.uniform(0.0, 2.0 * kPi);
      Eigen::Vector3d eye(-0.9 + 0.005 * t, -7.0 + 0.0015 * t, 1.55 + 0.04 * wave(t, 150.0, 0.0));
      // Shake: a few incommensurate sinusoids per axis (about 1-4 Hz at 30 fps).
      for (int k = 0; k < 3; ++k) {
        eye[k] += 0.002 * wave(t, 23.0, phase[k]) + 0.001 * wave(t, 9.0, phase[3 + k]);
      }
      Pose p = lookAt(eye, Eigen::Vector3d(0.2 * wave(t, 300.0, 0.0), 0.0, 0.8));
      Eigen::Vector3d w;
      for (int k = 0; k < 3; ++k) {
        w[k] = degToRad(0.15 * wave(t, 45.0, phase[6 + k]) + 0.08 * wave(t, 17.0, phase[9 + k]) +
                        0.04 * wave(t, 7.0, phase[(k + 5) % 12]));
      }
      p.R_wc = p.R_wc * rotationFromVector(w);
      return p;
    }
    case SceneKind::kPlanar: {
      const Eigen::Vector3d eye(-1.5 + 0.009 * t, -0.5 + 0.2 * wave(t, 250.0, 0.0),
                                1.6 + 0.15 * wave(t, 180.0, 1.0));
      const Eigen::Vector3d target(0.6 * wave(t, 300.0, 0.4), 4.0, 1.8 + 0.3 * wave(t, 220.0, 0.9));
      return lookAt(eye, target);
    }
    case SceneKind::kShake: {
      // A slow sideways drift (4 mm/frame) about 7.5 m from the boxes, the back wall 19 m away.
      SplitMix64 rng(mixSeed(params.seed, 78));
      double phase[3];
      for (double& ph : phase) ph = rng.uniform(0.0, 2.0 * kPi);
      Eigen::Vector3d eye(-1.0 + 0.004 * t, -7.5 + 0.001 * t, 1.6 + 0.03 * wave(t, 170.0, 0.4));
      // Translational jitter of a few millimetres (the hand moves as it turns).
      for (int k = 0; k < 3; ++k) eye[k] += 0.003 * wave(t, 11.0 + 4.0 * k, phase[k]);
      Pose p = lookAt(eye, Eigen::Vector3d(0.15 * wave(t, 260.0, 0.2), 0.0, 0.9));
      p.R_wc = p.R_wc * rotationFromVector(shakeRotation(params, t));
      return p;
    }
    case SceneKind::kFastPan: {
      // Yaw = A (sin x - sin 3x / 9), x = 2 pi t / 150: a nearly constant angular speed of
      // 2.5-3.5 deg/frame over most of each sweep and a reversal every 75 frames (2.5 s at 30 fps).
      // The centre walks 1.2 cm/frame sideways by default (2.4 m over 200 frames): enough
      // parallax on the boxes and walls for a full 6-DoF solve, so the clip is a fast pan, not a
      // tripod shot. walk_m 0 keeps the centre at (-1.2, -6, 1.6): the same pan on a tripod.
      const double walk = params.walk_m / 0.012;  // 1 at the default walk
      const Eigen::Vector3d eye(-1.2 + params.walk_m * t, -6.0 + 0.004 * walk * t,
                                1.6 + 0.02 * walk * wave(t, 37.0, 0.3));
      const double x = 2.0 * kPi * t / 150.0;
      const double yaw = degToRad(88.0 * (portableSin(x) - portableSin(3.0 * x) / 9.0));
      const double pitch = degToRad(-4.0 + 3.0 * wave(t, 97.0, 0.7));
      const Eigen::Vector3d forward(portableSin(yaw) * portableCos(pitch),
                                    portableCos(yaw) * portableCos(pitch), portableSin(pitch));
      return lookAt(eye, eye + forward);
    }
    case SceneKind::kOcclusion: {
      // An orbit of radius 6.5 m at 0.35 deg/frame around pillars within 4.6 m of the centre:
      // near pillars sweep across far ones, so corners are occluded and uncovered all the time.
      const double theta = degToRad(-120.0 + 0.35 * t);
      const Eigen::Vector3d eye(6.5 * portableCos(theta), 6.5 * portableSin(theta),
                                1.5 + 0.1 * wave(t, 160.0, 0.0));
      const Eigen::Vector3d target(0.4 * wave(t, 190.0, 0.3), 0.3 * wave(t, 140.0, 1.1),
                                   0.9 + 0.1 * wave(t, 110.0, 2.0));
      return lookAt(eye, target);
    }
  }
  return Pose{};
}

}  // namespace epitrack::synth
