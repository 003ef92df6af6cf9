#pragma once

#include <array>
#include <cstdint>
#include <span>
#include <vector>

#include <Eigen/Core>

#include "algo/flow/pyramidal_lk.hpp"
#include "algo/geometry/essential_five_point.hpp"
#include "algo/geometry/fundamental.hpp"
#include "algo/image/image_view.hpp"
#include "algo/image/pyramid.hpp"
#include "algo/matching/descriptor_matcher.hpp"
#include "algo/matching/feature_extractor.hpp"
#include "algo/sfm/track_table.hpp"

namespace epitrack {

/// Which descriptor a frame pair is matched with.
enum class DescriptorOrientation : uint8_t {
  kUpright,   ///< the pattern unrotated: most distinctive when the camera does not roll
  kOriented,  ///< rotated to each keypoint's orientation: invariant to in-plane rotation
  kBoth,      ///< upright first; oriented when the upright matches do not verify
};

struct DescriptorTrackerOptions {
  FeatureExtractorOptions features;
  DescriptorOrientation orientation = DescriptorOrientation::kBoth;
  DescriptorMatchOptions match;
  /// Each frame is matched against this many previous frames; kAllPairs (0): against every
  /// previous frame (the `expected_frames` of the constructor), so every pair of a photo set is
  /// matched and verified whatever the order of its files (the view graph: docs/tracker.md).
  int window = 2;
  static constexpr int kAllPairs = 0;
  /// Pairs more than chain_window frames apart (the pairs only a wide window or kAllPairs
  /// matches) are verified by the seed stage alone (below), with at most
  /// graph_ransac_iterations RANSAC iterations: in
  /// a photo set most pairs do not overlap and their RANSAC would run to its maximum (2000
  /// five-point iterations, four times: 75 % of a 47-view matching), while a pair that does
  /// overlap has a high inlier fraction among its most distinctive matches (the seed stage), which
  /// a few hundred samples find.
  int chain_window = 2;
  int graph_ransac_iterations = 300;
  /// A graph pair needs this many inliers (a chain pair min_inliers): on the TUM cabinet key
  /// frames, matched pair by pair, 40 pairs of views 60-180 degrees apart (no common surface;
  /// a plain cabinet whose corners repeat) verified with 20-30 inliers of 85-150 putative
  /// matches and merged wrong tracks (52/58 views, ATE 14 %); the true graph pairs of templeRing
  /// have 40-1400, the loop closure of the cabinet 43-54.
  int graph_min_inliers = 40;
  /// Geometric verification: F-RANSAC on the putative matches of a frame pair (Sampson distance
  /// threshold in pixels); a pair with fewer inliers than min_inliers, or an inlier fraction below
  /// min_inlier_ratio, contributes no match.
  FundamentalOptions fundamental{RansacOptions{2.0, 0.999, 8, 2000, 1}, 4};
  /// Besides RANSAC over every putative match, RANSAC over the most distinctive ones (the best
  /// seed_fraction by ratio, at least 16): their higher inlier fraction finds F when the rest is
  /// mostly wrong (PROSAC's idea, Chum & Matas 2005, in two stages); the F with the larger support
  /// over every match wins.
  double seed_fraction = 0.35;
  int min_inliers = 20;
  double min_inlier_ratio = 0.15;
  int min_track_length = 2;  ///< shorter tracks are left out of the track table
  /// Which inliers of a verified pair join the tracks: when at least merge_min_tight of them lie
  /// within merge_max_sampson_px (Sampson distance to the verified model, pixels), only those;
  /// otherwise every inlier. The RANSAC threshold (2 px) admits matches a pixel or two off the
  /// true corner (a corner found at a coarse pyramid level, JPEG blocks), and a track carries
  /// that error into the solve: templeRing's 47 views 0.042 -> 0.039 % of the path, the TUM
  /// cabinet key frames 3.5 -> 2.4 % (results.md). A weak pair (a graph pair with 40-100 inliers,
  /// the plain side of the cabinet) keeps all of them: its views would lose their registration.
  /// Verification and the LK propagation's seeds are not affected.
  double merge_max_sampson_px = 1.0;
  int merge_min_tight = 100;
  /// Known intrinsics (focal_px > 0): the pairs are verified by five-point E-RANSAC on normalized
  /// points (fewer samples and fewer degrees of freedom than F: it holds at lower inlier
  /// fractions); the RANSAC threshold stays a Sampson distance in pixels.
  double focal_px = 0.0;
  double cx = 0.0, cy = 0.0;
  double aspect = 1.0;  ///< fy / fx
  /// Known radial distortion (with focal_px; the model of CameraIntrinsics): every keypoint is
  /// undistorted before verification, so E, the Sampson threshold and the LK propagation's
  /// epipolar test see pinhole geometry. A k1 of -0.28 bends a line near the edge of the image by
  /// tens of pixels, far beyond the 2 px threshold: without it the pairs of a wide-angle lens
  /// verify only near the centre. Descriptors and matching stay on the image as taken.
  double k1 = 0.0, k2 = 0.0;
  /// LK propagation, after the descriptor matching of a frame: every point of the previous frame
  /// that did not match into this one (a corner the detector missed here, weak texture, a
  /// repeated pattern) is aligned by pyramidal Lucas-Kanade (its patch in the previous frame as
  /// template, affine at the base level) from the position its verified neighbours predict (the
  /// median displacement of the nearest verified matches),
  /// which puts LK inside its convergence range however far the key frames are apart. A result
  /// must converge below lk_max_residual, lie within the RANSAC threshold of its epipolar line
  /// and keep its descriptor (Hamming distance within lk_max_distance); it joins a keypoint
  /// found within merge_radius_px, or becomes a point of this frame (up to max_propagated per
  /// frame) that later frames match and propagate in turn.
  bool lk_propagation = true;
  LkOptions lk{21, 3, 10, 0.01, 4.0, 1e9, true, true, -1};
  int lk_neighbours = 4;
  double lk_max_residual = 0.6;
  int lk_max_distance = 80;
  double merge_radius_px = 2.0;
  int max_propagated = 1000;
  /// Frames propagated from (the previous one, then the one before...; at most `window`): a point
  /// the previous frame lost (blur, occlusion) continues from the frame before. 2 made the TUM
  /// key frames worse (50 of 58 frames solved instead of 55-58 over eight seeds).
  int lk_propagation_frames = 1;
};

/// The figures of one matched frame pair.
struct FramePairMatches {
  int frame_a = 0;  ///< the earlier frame
  int frame_b = 0;
  int putative = 0;    ///< after the ratio test and the mutual check
  int inliers = 0;     ///< consistent with F
  int propagated = 0;  ///< LK propagation into frame_b (frame_a = frame_b - 1 only)
  int tight = 0;       ///< inliers within merge_max_sampson_px of the model
  int merged = 0;      ///< merged matches that joined two tracks (not already one, no conflict)
  bool verified = false;
  bool oriented = false;  ///< matched with the oriented descriptor
  /// The verified model, x_b^T F x_a = 0 in pixels (undistorted pixels when the options give a
  /// distortion: DescriptorTracker::undistortedPixel).
  Eigen::Matrix3d F = Eigen::Matrix3d::Zero();
};

/// Tracks from descriptor matching, for key frames that LK cannot bridge: each new frame's
/// features (FeatureExtractor: multi-scale Shi-Tomasi + oriented BRIEF) are matched against the
/// previous `window` frames (nearest first: DescriptorMatcher, ratio test, mutual check), each
/// pair verified by E- or F-RANSAC, LK propagating what the matching missed, and the verified
/// matches chained into tracks by union-find over (frame, feature), so a point seen in frames 3,
/// 4 and 6 is one track. A merge that would put two features of one frame into one track is
/// refused (the matches are taken best first, nearest frames first).
///
/// Per-frame work (extraction, matching, RANSAC) uses buffers sized at construction. The
/// clip-level store (every frame's keypoints and the union-find, a few dozen bytes per feature)
/// is reserved for `expected_frames` and grows beyond it, like the TrackTable it feeds.
class DescriptorTracker {
 public:
  enum class Status { kOk, kSizeMismatch };

  DescriptorTracker(const DescriptorTrackerOptions& options, int width, int height,
                    int expected_frames = 0);

  /// Extracts, matches and chains one frame (the next frame index).
  Status addFrame(ImageView<const uint8_t> image, ImageView<const uint8_t> mask = {});

  [[nodiscard]] int frameCount() const { return static_cast<int>(frame_offset_.size()) - 1; }
  /// Keypoints of frame f (level-0 pixels).
  [[nodiscard]] std::span<const Keypoint> keypoints(int f) const;
  /// The matched pairs of every frame so far, in the order matched.
  [[nodiscard]] const std::vector<FramePairMatches>& pairs() const { return pairs_; }
  /// Track index of feature i of frame f (dense, numbered by first appearance; -1: in no track of
  /// at least min_track_length frames). Valid after `buildTracks`.
  [[nodiscard]] int trackOf(int f, int i) const;

  /// Fills `table` with every track of at least min_track_length frames (track ids = the dense
  /// track indices of trackOf), one observation per frame, and finalizes it.
  void buildTracks(TrackTable& table);

  [[nodiscard]] const DescriptorTrackerOptions& options() const { return options_; }

  /// The pixel where (x, y) would be seen by the lens without its distortion (the pinhole image
  /// through the same K); (x, y) itself when the options give no distortion.
  [[nodiscard]] Eigen::Vector2d undistortedPixel(double x, double y) const;

 private:
  struct Slot {  // one frame of the matching window
    int frame = -1;
    int count = 0;
    std::vector<Keypoint> keypoints;
    std::vector<BinaryDescriptor> upright, oriented;
  };
  struct SeedSet {  // the verified matches of (frame - k, frame) and their model
    std::vector<DescriptorMatch> matches;
    int count = 0;
    bool oriented = false;
    Eigen::Matrix3d F = Eigen::Matrix3d::Zero();
  };
  int find(int node);
  bool unite(int a, int b);
  void matchPair(const Slot& older, const Slot& current);
  void propagate(Slot& previous, Slot& current, const SeedSet& seeds);
  /// The inliers matches_[0, count) that join the tracks: counts those within
  /// merge_max_sampson_px of F (`tight`); when they are at least merge_min_tight, moves them to
  /// the front (in order) and returns their count, else returns count.
  int selectMerged(const Slot& older, const Slot& current, int count, const Eigen::Matrix3d& F,
                   int& tight);
  [[nodiscard]] bool setHasFrame(int node, int frame) const;
  /// Putative matches of the pair with one descriptor kind into matches_; returns their count.
  int putativeMatches(const Slot& older, const Slot& current, bool oriented);
  /// F-RANSAC over matches_[0, count): F, the inlier mask (inlier_) and count; false when none.
  bool verify(const Slot& older, const Slot& current, int count, uint64_t seed, bool chain_pair,
              Eigen::Matrix3d& F, int& inliers);
  bool robustFit(int n, uint64_t seed, int max_iterations, Eigen::Matrix3d& F);
  bool refit(int n, Eigen::Matrix3d& F) const;
  [[nodiscard]] bool knownIntrinsics() const { return options_.focal_px > 0.0; }
  [[nodiscard]] bool undistorts() const {
    return knownIntrinsics() && (options_.k1 != 0.0 || options_.k2 != 0.0);
  }
  [[nodiscard]] Eigen::Vector2d normalize(const Eigen::Vector2d& px) const;

  DescriptorTrackerOptions options_;
  int width_ = 0, height_ = 0;
  FeatureExtractor extractor_;
  DescriptorMatcher matcher_;
  FundamentalRansac ransac_;
  EssentialRansac essential_;
  Eigen::Matrix3d K_inv_ = Eigen::Matrix3d::Identity();
  std::vector<Slot> slots_;  // ring of window + 1 frames
  // Per-pair scratch (sized at construction).
  std::vector<DescriptorMatch> matches_;
  std::vector<Eigen::Vector2d> xa_, xb_;
  mutable std::vector<Eigen::Vector2d> na_, nb_;
  std::vector<int> order_;
  std::vector<uint8_t> inlier_;
  std::vector<int> index_;
  // Clip-level store.
  std::vector<Keypoint> all_keypoints_;
  std::vector<int> frame_offset_{0};  // node range of frame f: [offset[f], offset[f + 1])
  std::vector<int32_t> node_frame_;
  std::vector<int32_t> parent_, next_;  // union-find parent; circular list of a set's members
  std::vector<int32_t> set_size_;
  std::vector<int32_t> frame_stamp_;  // conflict test scratch (per frame)
  int32_t stamp_ = 0;
  std::vector<int32_t> track_of_node_;
  std::vector<FramePairMatches> pairs_;
  // LK propagation: the pyramids of the previous and the current frame, one LK slot, and the
  // verified matches (previous -> current) with their model.
  std::vector<Pyramid> pyramids_;  // ring of lk_propagation_frames + 1 frames
  PyramidalLk lk_;
  std::vector<SeedSet> seed_sets_;  // by k = frame distance (1..window)
  std::vector<float> seed_dist_, disp_x_, disp_y_;
  std::vector<int32_t> seed_order_;
};

const char* toString(DescriptorTracker::Status s);

}  // namespace epitrack
