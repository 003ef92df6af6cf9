// epitrack-solve: from a video to a camera track and point cloud (ARCHITECTURE.md "Commands").
#include <cstdio>
#include <string>

#include "hal/cpu/cpu_features.hpp"
#include "tools/common/command_line.hpp"
#include "tools/common/interrupt.hpp"
#include "tools/export/reconstruction_scene_frame.hpp"
#include "tools/solve/solve_pipeline.hpp"

using epitrack::tools::CommandLine;

namespace {

bool parseVector(const std::string& text, Eigen::Vector3d& v, std::string& error) {
  double a = 0, b = 0, c = 0;
  char tail = 0;
  if (std::sscanf(text.c_str(), "%lf,%lf,%lf%c", &a, &b, &c, &tail) != 3 ||
      !std::isfinite(a + b + c)) {
    error = "expected X,Y,Z (three numbers separated by commas), got '" + text + "'";
    return false;
  }
  v = Eigen::Vector3d(a, b, c);
  return true;
}

}  // namespace

int main(int argc, char** argv) {
  epitrack::hal::selectKernelsForThisCpu();
  epitrack::tools::SolveCommandOptions o;
  // A sparse 2D tracker sees far fewer corners on a grazing floor than on a facing wall: accept a
  // level plane with a twentieth of the points as the ground.
  o.scene.min_plane_fraction = 0.05;
  o.tracker.max_features = epitrack::tools::kSolveFeatures;
  std::string distortion = "auto";
  std::string readout_choice = "none";
  bool quiet = false;
  CommandLine cl(
      "epitrack-solve", "INPUT --out DIR [options]",
      "Tracks INPUT, self-calibrates the focal length (unless given), reconstructs the camera\n"
      "path and a point cloud, and writes DIR/cameras.tum, intrinsics.txt, points.ply,\n"
      "summary.json, report.html, colmap/, blender_camera.py, camera.chan, camera.nk and, with\n"
      "--render or --overlay, the augmented frames DIR/augmented/*.jpg and DIR/augmented.avi.\n"
      "INPUT: a frame directory, .y4m (or - for Y4M on stdin), .mjpeg, v4l2:/dev/videoN.\n"
      "Ctrl-C (SIGINT) or SIGTERM stops at the next consistent point: summary.json then says\n"
      "\"interrupted\" and lists the outputs written; a second Ctrl-C kills at once.\n"
      "Exit: 0 solved (at least 90 % of the frames; or a tripod solve), 1 the solve failed\n"
      "(summary.json says why), 2 bad command line or unusable INPUT/--intrinsics/--mask/--out,\n"
      "3 partial: outputs written but fewer than 90 % of the frames solved (summary.json's\n"
      "unsolved_ranges say which and why), 4 trajectory-uncertain (the camera centres not\n"
      "determined), 5 inconsistent (key frames whose own view pairs contradict the solve:\n"
      "summary.json view_pair_check), 130 (143) stopped by SIGINT (SIGTERM).");
  cl.positional("INPUT", "frames to solve", &o.input);
  cl.text("out", "DIR", "output directory (created)", &o.out_dir);
  cl.require("out");
  cl.text("intrinsics", "FILE", "given intrinsics (fx fy cx cy width height [k1 k2])",
          &o.intrinsics_file);
  cl.real("focal", "PX", "given focal length in pixels (principal point at the centre)",
          &o.focal_px, 1.0, 1e6);
  cl.flag("refine-focal",
          "with --intrinsics or --focal: the given focal is a starting value, refined in the "
          "final bundle adjustment (lens metadata, an approximate calibration)",
          &o.solver.refine_given_focal);
  cl.choice("distortion", {"auto", "none", "k1", "k1k2"},
            "radial distortion (k1, k2) estimated in the final bundle adjustment: auto = tried, "
            "and kept when the lens shows (it moves some pixel by 2 px or more and lowers the "
            "median reprojection error by a fifth; summary.json distortion); none = a pinhole "
            "camera (default auto; with --intrinsics that give k1 or k2, those are used)",
            &distortion);
  cl.real("readout-ms", "MS",
          "rolling shutter: the sensor's readout time (first row to last; phones and CMOS "
          "modules 10-35 ms). The solve works on the tracks moved to each frame's middle-row "
          "time, then each frame's pose and its motion over the readout are refined, the points "
          "seen from the rows' poses (a tripod: the rotations, each row at its own time); the "
          "poses written are the middle row's (default 0: global shutter)",
          &o.readout_ms, 0.0, 1000.0);
  cl.choice("readout", {"auto", "none"},
            "rolling shutter: auto = estimate the readout (the motion within each frame against "
            "the motion between frames); the model is used when the estimate is observable and "
            "above zero, summary.json says readout_ms, readout_source and readout_observable "
            "(default none)",
            &readout_choice);
  cl.text("tracks", "CSV",
          "solve these 2D tracks (tracks.csv: frame,track_id,x,y, frames numbered as "
          "epitrack-track numbers INPUT's readable frames) instead of tracking INPUT; INPUT "
          "still gives the frame size and the frames to render; with --matcher descriptors "
          "they are solved as key frames",
          &o.tracks_file);
  cl.text("mask", "PGM|DIR", "zero pixels are never tracked (one image, or one per frame)",
          &o.mask);
  cl.text("origin", "plane|first-camera|track:ID",
          "scene frame: dominant plane (default), the first camera, or a track's point",
          &o.origin_text);
  cl.choice("render", {"towers", "cube", "axes", "none"},
            "virtual object rendered into DIR/augmented (default none)", &o.render);
  cl.choice("overlay", {"tracks", "none"},
            "tracks: augmented frames side by side with the tracked features (green: fit the "
            "solve, orange: outliers, red: no 3D point); default none",
            &o.overlay);
  cl.option("object-at", "X,Y,Z",
            "where the object stands in the scene frame (default: on the ground where it is in "
            "view in the most frames)",
            [&](const std::string& v, std::string& e) {
              Eigen::Vector3d at;
              if (!parseVector(v, at, e)) return false;
              o.object_at = at;
              return true;
            });
  double object_scale = 0.0;  // 0: not given
  cl.real("object-scale", "S",
          "object size factor (default: a quarter of the image height at its median distance)",
          &object_scale, 1e-6, 1e6);
  std::string matcher = "auto";
  cl.choice("matcher", {"lk", "descriptors", "auto"},
            "2D tracks: lk = pyramidal Lucas-Kanade frame to frame (video); descriptors = "
            "oriented BRIEF matched against the previous frames, verified, chained (key frames, "
            "photo sets); auto (default) = LK unless fewer than 35 % of its tracks survive from "
            "frame to frame over the first 16 frames, or a pair after the first keeps fewer "
            "than 30 % (a cut in the file order)",
            &matcher);
  cl.integer("match-features", "N", "descriptor matcher: keypoints per frame (default 2000)",
             &o.matching.features.max_features, 50, 100000);
  o.matching.window = epitrack::tools::kMatchWindowAuto;
  cl.option("match-window", "N|all|auto",
            "descriptor matcher: previous frames each frame is matched against; all = every "
            "pair of frames (the view graph of a photo set, whatever the order of its files); "
            "auto (default) = all for at most 60 frames, else 2",
            [&](const std::string& v, std::string& e) {
              return epitrack::tools::parseMatchWindow(v, o.matching.window, e);
            });
  cl.integer("features", "N",
             "2D features tracked (default " + std::to_string(epitrack::tools::kSolveFeatures) +
                 "; epitrack-track and the device: 300)",
             &o.tracker.max_features, 8, 100000);
  cl.integer("window", "PX", "LK window side, odd (default 21)", &o.tracker.window, 3, 99);
  cl.integer("levels", "L", "pyramid levels beyond the base (default 3)", &o.tracker.levels, 0, 7);
  cl.real("keyframe-parallax", "DEG", "median parallax that makes a new keyframe (default 2)",
          &o.solver.keyframe_parallax_deg, 0.1, 30.0);
  cl.integer("ba-window", "N", "keyframes refined while solving (default 8)", &o.solver.ba_window,
             2, 1000);
  cl.real("max-centre-sd", "STEPS",
          "status trajectory-uncertain (exit 4) when the camera centres' standard deviation in "
          "the final adjustment exceeds this fraction of the mean frame-to-frame step; 0 = not "
          "checked (default 0.12)",
          &o.solver.max_centre_sd_steps, 0.0, 100.0);
  int seed = 1;
  cl.integer("seed", "S", "RANSAC seed (default 1)", &seed, 0, 2147483647);
  cl.real("max-memory", "MIB",
          "refuse a clip whose buffers would need more than this (default 4096 MiB)",
          &o.max_memory_mib, 16.0, 1e7);
  cl.flag("force",
          "replace the outputs of an earlier solve in DIR (without it, a DIR holding one "
          "is refused)",
          &o.force);
  cl.flag("quiet", "no progress on stderr", &quiet);
  if (const auto r = cl.parse(argc, argv); r != CommandLine::Result::kOk)
    return CommandLine::exitCode(r);
  if (o.tracker.window % 2 == 0) return cl.usageError("--window must be odd");
  if (!o.intrinsics_file.empty() && o.focal_px > 0.0)
    return cl.usageError("give either --intrinsics or --focal, not both");
  if (o.solver.refine_given_focal && o.intrinsics_file.empty() && !(o.focal_px > 0.0))
    return cl.usageError("--refine-focal needs a focal to start from (--intrinsics or --focal)");
  if (!o.tracks_file.empty() && !o.mask.empty())
    return cl.usageError("--mask applies to tracking; the tracks of --tracks are used as given");
  std::string error;
  if (!epitrack::io::parseOriginOption(o.origin_text, o.scene, error))
    return cl.usageError("--origin: " + error);
  if (object_scale > 0.0) o.object_scale = object_scale;
  o.distortion = distortion == "k1k2" ? 2 : distortion == "k1" ? 1 : 0;
  o.detect_distortion = distortion == "auto";
  o.readout_auto = readout_choice == "auto";
  if (o.readout_auto && o.readout_ms > 0.0)
    return cl.usageError("give either --readout-ms or --readout auto, not both");
  // A rolling shutter declared or looked for: the tracker's motion model follows the rows of a
  // jerk (GlobalMotionOptions::row_term, docs/tracker.md).
  o.tracker.motion.row_term = o.readout_auto || o.readout_ms > 0.0;
  epitrack::tools::parseMatcher(matcher, o.matcher);
  o.solver.seed = static_cast<uint64_t>(seed);
  if (quiet) o.progress = epitrack::io::ProgressReporter::Mode::kQuiet;
  epitrack::tools::installInterruptHandlers();
  return epitrack::tools::runSolve(o);
}
