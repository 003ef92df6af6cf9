#include "tools/synth/trajectory.hpp"

#include <cmath>

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

}  // namespace

Pose trajectoryPose(const TrajectoryParams& params, double t) {
  switch (params.kind) {
    case SceneKind::kOrbit: {
      const double theta = degToRad(-135.0 + 0.25 * t);
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
  }
  return Pose{};
}

}  // namespace epitrack::synth
