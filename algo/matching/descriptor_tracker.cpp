#include "algo/matching/descriptor_tracker.hpp"

#include <algorithm>
#include <numeric>

#include <Eigen/LU>

#include "algo/geometry/undistort.hpp"

namespace epitrack {

namespace {

int nodesPerFrame(const DescriptorTrackerOptions& o) {
  return std::max(1, o.features.max_features) + std::max(0, o.max_propagated);
}

}  // namespace

const char* toString(DescriptorTracker::Status s) {
  switch (s) {
    case DescriptorTracker::Status::kOk:
      return "ok";
    case DescriptorTracker::Status::kSizeMismatch:
      return "size-mismatch";
  }
  return "unknown";
}

DescriptorTracker::DescriptorTracker(const DescriptorTrackerOptions& options, int width, int height,
                                     int expected_frames)
    : options_(options),
      width_(width),
      height_(height),
      extractor_(options.features, width, height),
      matcher_(nodesPerFrame(options)),
      ransac_(std::max(8, 2 * nodesPerFrame(options))),
      essential_(std::max(8, 2 * nodesPerFrame(options))),
      lk_(options.lk, 1) {
  if (options_.window <= DescriptorTrackerOptions::kAllPairs)
    options_.window = std::max(1, expected_frames - 1);
  options_.window = std::max(1, options_.window);
  // LK propagates from the previous lk_propagation_frames frames only: their pyramids and this
  // frame's.
  const int propagation_frames =
      std::min(options_.window, std::max(1, options_.lk_propagation_frames));
  pyramids_.resize(static_cast<std::size_t>(propagation_frames) + 1);
  for (Pyramid& p : pyramids_) p.configure(width, height, options.lk.levels + 1);
  if (knownIntrinsics()) {
    Eigen::Matrix3d K;
    K << options_.focal_px, 0.0, options_.cx, 0.0, options_.focal_px * options_.aspect, options_.cy,
        0.0, 0.0, 1.0;
    K_inv_ = K.inverse();
  }
  const auto n = static_cast<std::size_t>(std::max(1, options_.features.max_features));
  options_.max_propagated = std::max(0, options_.max_propagated);
  const std::size_t nodes_per_frame = n + static_cast<std::size_t>(options_.max_propagated);
  slots_.resize(static_cast<std::size_t>(options_.window) + 1);
  seed_sets_.resize(static_cast<std::size_t>(options_.window) + 1);
  for (SeedSet& ss : seed_sets_) ss.matches.resize(2 * nodes_per_frame);
  seed_dist_.resize(2 * nodes_per_frame);
  disp_x_.resize(2 * nodes_per_frame);
  disp_y_.resize(2 * nodes_per_frame);
  seed_order_.resize(2 * nodes_per_frame);
  for (auto& s : slots_) {
    s.keypoints.resize(nodes_per_frame);
    if (options_.orientation != DescriptorOrientation::kOriented) s.upright.resize(nodes_per_frame);
    if (options_.orientation != DescriptorOrientation::kUpright) s.oriented.resize(nodes_per_frame);
  }
  matches_.resize(2 * nodes_per_frame);
  xa_.resize(2 * nodes_per_frame);
  xb_.resize(2 * nodes_per_frame);
  na_.resize(2 * nodes_per_frame);
  nb_.resize(2 * nodes_per_frame);
  order_.resize(2 * nodes_per_frame);
  inlier_.resize(2 * nodes_per_frame);
  index_.resize(2 * nodes_per_frame);
  const auto nodes = static_cast<std::size_t>(std::max(0, expected_frames)) * nodes_per_frame;
  all_keypoints_.reserve(nodes);
  node_frame_.reserve(nodes);
  parent_.reserve(nodes);
  next_.reserve(nodes);
  set_size_.reserve(nodes);
  frame_offset_.reserve(static_cast<std::size_t>(std::max(0, expected_frames)) + 1);
  frame_stamp_.reserve(static_cast<std::size_t>(std::max(0, expected_frames)));
  pairs_.reserve(static_cast<std::size_t>(std::max(0, expected_frames)) *
                 static_cast<std::size_t>(options_.window));
}

std::span<const Keypoint> DescriptorTracker::keypoints(int f) const {
  if (f < 0 || f >= frameCount()) return {};
  const auto b = static_cast<std::size_t>(frame_offset_[static_cast<std::size_t>(f)]);
  const auto e = static_cast<std::size_t>(frame_offset_[static_cast<std::size_t>(f) + 1]);
  return {all_keypoints_.data() + b, e - b};
}

int DescriptorTracker::trackOf(int f, int i) const {
  if (f < 0 || f >= frameCount()) return -1;
  const int node = frame_offset_[static_cast<std::size_t>(f)] + i;
  if (i < 0 || node >= frame_offset_[static_cast<std::size_t>(f) + 1] ||
      static_cast<std::size_t>(node) >= track_of_node_.size())
    return -1;
  return track_of_node_[static_cast<std::size_t>(node)];
}

int DescriptorTracker::find(int node) {
  // Path halving.
  while (parent_[static_cast<std::size_t>(node)] != node) {
    auto& p = parent_[static_cast<std::size_t>(node)];
    p = parent_[static_cast<std::size_t>(p)];
    node = p;
  }
  return node;
}

bool DescriptorTracker::unite(int a, int b) {
  int ra = find(a), rb = find(b);
  if (ra == rb) return false;
  // Refuse a merge that would hold two features of one frame: mark the frames of one set, walk
  // the other.
  ++stamp_;
  int m = ra;
  do {
    frame_stamp_[static_cast<std::size_t>(node_frame_[static_cast<std::size_t>(m)])] = stamp_;
    m = next_[static_cast<std::size_t>(m)];
  } while (m != ra);
  m = rb;
  do {
    if (frame_stamp_[static_cast<std::size_t>(node_frame_[static_cast<std::size_t>(m)])] == stamp_)
      return false;
    m = next_[static_cast<std::size_t>(m)];
  } while (m != rb);
  if (set_size_[static_cast<std::size_t>(ra)] < set_size_[static_cast<std::size_t>(rb)])
    std::swap(ra, rb);
  parent_[static_cast<std::size_t>(rb)] = ra;
  set_size_[static_cast<std::size_t>(ra)] += set_size_[static_cast<std::size_t>(rb)];
  std::swap(next_[static_cast<std::size_t>(ra)], next_[static_cast<std::size_t>(rb)]);
  return true;
}

int DescriptorTracker::putativeMatches(const Slot& older, const Slot& current, bool oriented) {
  const auto& da = oriented ? older.oriented : older.upright;
  const auto& db = oriented ? current.oriented : current.upright;
  int count = 0;
  matcher_.match({older.keypoints.data(), static_cast<std::size_t>(older.count)},
                 {da.data(), static_cast<std::size_t>(older.count)},
                 {current.keypoints.data(), static_cast<std::size_t>(current.count)},
                 {db.data(), static_cast<std::size_t>(current.count)}, options_.match, matches_,
                 count);
  return count;
}

bool DescriptorTracker::robustFit(int n, uint64_t seed, int max_iterations, Eigen::Matrix3d& F) {
  // Over xa_[0, n), xb_[0, n) (pixels): E-RANSAC on normalized points when the intrinsics are
  // known, F-RANSAC otherwise; F in pixels either way.
  if (knownIntrinsics()) {
    for (int i = 0; i < n; ++i) {
      na_[static_cast<std::size_t>(i)] = normalize(xa_[static_cast<std::size_t>(i)]);
      nb_[static_cast<std::size_t>(i)] = normalize(xb_[static_cast<std::size_t>(i)]);
    }
    EssentialRansacOptions eo;
    eo.ransac = options_.fundamental.ransac;
    eo.ransac.seed = seed;
    eo.ransac.max_iterations = std::min(eo.ransac.max_iterations, max_iterations);
    eo.focal_px = options_.focal_px;
    EssentialRansacResult er;
    if (essential_.estimate({na_.data(), static_cast<std::size_t>(n)},
                            {nb_.data(), static_cast<std::size_t>(n)}, eo,
                            er) != EssentialRansac::Status::kOk)
      return false;
    F = K_inv_.transpose() * er.E * K_inv_;
    F /= F.norm();
    return F.allFinite();
  }
  FundamentalOptions fo = options_.fundamental;
  fo.ransac.seed = seed;
  fo.ransac.max_iterations = std::min(fo.ransac.max_iterations, max_iterations);
  FundamentalResult fr;
  if (ransac_.estimate({xa_.data(), static_cast<std::size_t>(n)},
                       {xb_.data(), static_cast<std::size_t>(n)}, fo,
                       fr) != FundamentalRansac::Status::kOk)
    return false;
  F = fr.F;
  return true;
}

bool DescriptorTracker::refit(int n, Eigen::Matrix3d& F) const {
  // Least squares over xa_[0, n), xb_[0, n): the eight-point fit (on normalized points and
  // projected onto the essential manifold when the intrinsics are known).
  Eigen::Matrix3d M;
  if (knownIntrinsics()) {
    for (int i = 0; i < n; ++i) {
      na_[static_cast<std::size_t>(i)] = normalize(xa_[static_cast<std::size_t>(i)]);
      nb_[static_cast<std::size_t>(i)] = normalize(xb_[static_cast<std::size_t>(i)]);
    }
    if (!fitFundamentalEightPoint({na_.data(), static_cast<std::size_t>(n)},
                                  {nb_.data(), static_cast<std::size_t>(n)}, {}, M))
      return false;
    M = K_inv_.transpose() * projectToEssential(M) * K_inv_;
  } else if (!fitFundamentalEightPoint({xa_.data(), static_cast<std::size_t>(n)},
                                       {xb_.data(), static_cast<std::size_t>(n)}, {}, M)) {
    return false;
  }
  if (!M.allFinite() || !(M.norm() > 0.0)) return false;
  F = M / M.norm();
  return true;
}

Eigen::Vector2d DescriptorTracker::undistortedPixel(double x, double y) const {
  if (!undistorts()) return {x, y};
  const double fy = options_.focal_px * options_.aspect;
  const Eigen::Vector2d n = undistortNormalized(
      options_.k1, options_.k2,
      Eigen::Vector2d((x - options_.cx) / options_.focal_px, (y - options_.cy) / fy));
  return {options_.cx + options_.focal_px * n.x(), options_.cy + fy * n.y()};
}

Eigen::Vector2d DescriptorTracker::normalize(const Eigen::Vector2d& px) const {
  return Eigen::Vector2d((px.x() - options_.cx) / options_.focal_px,
                         (px.y() - options_.cy) / (options_.focal_px * options_.aspect));
}

bool DescriptorTracker::verify(const Slot& older, const Slot& current, int count, uint64_t seed,
                               bool chain_pair, Eigen::Matrix3d& F, int& inliers) {
  const int max_iterations =
      chain_pair ? options_.fundamental.ransac.max_iterations : options_.graph_ransac_iterations;
  inliers = 0;
  if (count < std::max(8, options_.min_inliers)) return false;  // could not be accepted
  const auto position = [&](const DescriptorMatch& m, Eigen::Vector2d& a, Eigen::Vector2d& b) {
    const Keypoint& p = older.keypoints[static_cast<std::size_t>(m.a)];
    const Keypoint& q = current.keypoints[static_cast<std::size_t>(m.b)];
    a = undistortedPixel(static_cast<double>(p.x), static_cast<double>(p.y));
    b = undistortedPixel(static_cast<double>(q.x), static_cast<double>(q.y));
  };
  const double t = options_.fundamental.ransac.threshold;
  const double t2 = t * t;
  // Support of a model over every match (and its mask in inlier_).
  const auto support = [&](const Eigen::Matrix3d& model, bool write) {
    int n = 0;
    for (int i = 0; i < count; ++i) {
      Eigen::Vector2d a, b;
      position(matches_[static_cast<std::size_t>(i)], a, b);
      const bool in = sampsonSquared(model, a, b) < t2;
      n += in ? 1 : 0;
      if (write) inlier_[static_cast<std::size_t>(i)] = in ? 1 : 0;
    }
    return n;
  };
  bool found = false;
  const int seeds = std::max(16, static_cast<int>(options_.seed_fraction * count));
  const bool seed_stage = seeds < count && options_.seed_fraction > 0.0;
  for (int i = 0; i < count; ++i)
    position(matches_[static_cast<std::size_t>(i)], xa_[static_cast<std::size_t>(i)],
             xb_[static_cast<std::size_t>(i)]);
  Eigen::Matrix3d model;
  // A graph pair (beyond the chain window) is verified by the seed stage alone when there is one.
  if ((chain_pair || !seed_stage) && robustFit(count, seed, max_iterations, model)) {
    F = model;
    inliers = support(F, false);
    found = true;
  }
  // The most distinctive matches (lowest best / second-best distance ratio).
  if (seed_stage) {
    std::iota(index_.begin(), index_.begin() + count, 0);
    const auto ratio = [&](int i) {
      const DescriptorMatch& m = matches_[static_cast<std::size_t>(i)];
      return m.second > 0 && m.second < 1000 ? static_cast<double>(m.distance) / m.second : 0.0;
    };
    std::stable_sort(index_.begin(), index_.begin() + count,
                     [&](int i, int j) { return ratio(i) < ratio(j); });
    for (int k = 0; k < seeds; ++k)
      position(matches_[static_cast<std::size_t>(index_[static_cast<std::size_t>(k)])],
               xa_[static_cast<std::size_t>(k)], xb_[static_cast<std::size_t>(k)]);
    if (robustFit(seeds, seed + 1, max_iterations, model)) {
      // Refit on its support among every match (a few rounds: the support grows).
      int n = support(model, true);
      for (int round = 0; round < 3 && n >= 8; ++round) {
        int c = 0;
        for (int i = 0; i < count; ++i) {
          if (!inlier_[static_cast<std::size_t>(i)]) continue;
          position(matches_[static_cast<std::size_t>(i)], xa_[static_cast<std::size_t>(c)],
                   xb_[static_cast<std::size_t>(c)]);
          ++c;
        }
        Eigen::Matrix3d better;
        if (!refit(c, better)) break;
        const int n2 = support(better, false);
        if (n2 < n) break;
        model = better;
        n = support(model, true);
      }
      if (!found || n > inliers) {
        F = model;
        inliers = n;
        found = true;
      }
    }
  }
  if (!found) return false;
  inliers = support(F, true);
  return true;
}

void DescriptorTracker::matchPair(const Slot& older, const Slot& current) {
  FramePairMatches pm;
  pm.frame_a = older.frame;
  pm.frame_b = current.frame;
  const uint64_t seed = options_.fundamental.ransac.seed +
                        static_cast<uint64_t>(older.frame) * 7919u +
                        static_cast<uint64_t>(current.frame);
  const bool chain_pair = current.frame - older.frame <= options_.chain_window;
  const auto acceptable = [&](int inliers, int count) {
    return inliers >= (chain_pair ? options_.min_inliers : options_.graph_min_inliers) &&
           inliers >= options_.min_inlier_ratio * static_cast<double>(count);
  };
  Eigen::Matrix3d F;
  int count = 0, inliers = 0;
  bool oriented = options_.orientation == DescriptorOrientation::kOriented;
  count = putativeMatches(older, current, oriented);
  bool ok =
      verify(older, current, count, seed, chain_pair, F, inliers) && acceptable(inliers, count);
  if (!ok && options_.orientation == DescriptorOrientation::kBoth) {
    oriented = true;
    count = putativeMatches(older, current, true);
    ok = verify(older, current, count, seed, chain_pair, F, inliers) && acceptable(inliers, count);
  }
  pm.putative = count;
  pm.inliers = inliers;
  pm.oriented = oriented;
  if (!ok) {
    pairs_.push_back(pm);
    return;
  }
  pm.verified = true;
  pm.F = F;
  // Keep the inliers (in place).
  int kept = 0;
  for (int i = 0; i < count; ++i)
    if (inlier_[static_cast<std::size_t>(i)])
      matches_[static_cast<std::size_t>(kept++)] = matches_[static_cast<std::size_t>(i)];
  pm.inliers = kept;
  {  // the seeds of the LK propagation
    SeedSet& ss = seed_sets_[static_cast<std::size_t>(current.frame - older.frame)];
    ss.count = std::min(kept, static_cast<int>(ss.matches.size()));
    std::copy_n(matches_.begin(), ss.count, ss.matches.begin());
    ss.oriented = oriented;
    ss.F = F;
  }
  const int merging = selectMerged(older, current, kept, F, pm.tight);
  // Best matches first: they win when two matches would put two features of a frame in a track.
  std::iota(order_.begin(), order_.begin() + merging, 0);
  std::stable_sort(order_.begin(), order_.begin() + merging, [&](int i, int j) {
    return matches_[static_cast<std::size_t>(i)].distance <
           matches_[static_cast<std::size_t>(j)].distance;
  });
  const int base_a = frame_offset_[static_cast<std::size_t>(older.frame)];
  const int base_b = frame_offset_[static_cast<std::size_t>(current.frame)];
  for (int k = 0; k < merging; ++k) {
    const DescriptorMatch& m =
        matches_[static_cast<std::size_t>(order_[static_cast<std::size_t>(k)])];
    if (unite(base_a + m.a, base_b + m.b)) ++pm.merged;
  }
  pairs_.push_back(pm);
}

int DescriptorTracker::selectMerged(const Slot& older, const Slot& current, int count,
                                    const Eigen::Matrix3d& F, int& tight) {
  const double t2 = options_.merge_max_sampson_px * options_.merge_max_sampson_px;
  tight = 0;
  for (int i = 0; i < count; ++i) {
    const DescriptorMatch& m = matches_[static_cast<std::size_t>(i)];
    const Keypoint& p = older.keypoints[static_cast<std::size_t>(m.a)];
    const Keypoint& q = current.keypoints[static_cast<std::size_t>(m.b)];
    const Eigen::Vector2d a = undistortedPixel(static_cast<double>(p.x), static_cast<double>(p.y));
    const Eigen::Vector2d b = undistortedPixel(static_cast<double>(q.x), static_cast<double>(q.y));
    const bool in = sampsonSquared(F, a, b) <= t2;
    inlier_[static_cast<std::size_t>(i)] = in ? 1 : 0;
    tight += in ? 1 : 0;
  }
  if (tight < options_.merge_min_tight) return count;  // a weak pair: every inlier
  int kept = 0;
  for (int i = 0; i < count; ++i)
    if (inlier_[static_cast<std::size_t>(i)])
      matches_[static_cast<std::size_t>(kept++)] = matches_[static_cast<std::size_t>(i)];
  return kept;
}

DescriptorTracker::Status DescriptorTracker::addFrame(ImageView<const uint8_t> image,
                                                      ImageView<const uint8_t> mask) {
  if (image.width != width_ || image.height != height_) return Status::kSizeMismatch;
  const int f = frameCount();
  Slot& slot = slots_[static_cast<std::size_t>(f) % slots_.size()];
  int found = 0;
  if (extractor_.extract(image, mask, slot.keypoints, slot.upright, slot.oriented, found) !=
      FeatureExtractor::Status::kOk)
    return Status::kSizeMismatch;
  slot.frame = f;
  slot.count = found;
  const int base = frame_offset_.back();
  for (int i = 0; i < found; ++i) {
    all_keypoints_.push_back(slot.keypoints[static_cast<std::size_t>(i)]);
    node_frame_.push_back(f);
    parent_.push_back(base + i);
    next_.push_back(base + i);
    set_size_.push_back(1);
  }
  frame_offset_.push_back(base + found);
  frame_stamp_.push_back(0);
  if (options_.lk_propagation)
    pyramids_[static_cast<std::size_t>(f) % pyramids_.size()].build(image);
  for (SeedSet& ss : seed_sets_) ss.count = 0;
  for (int k = 1; k <= options_.window && f - k >= 0; ++k) {
    const Slot& older = slots_[static_cast<std::size_t>(f - k) % slots_.size()];
    matchPair(older, slot);
  }
  const int sources = std::min(options_.window, std::max(1, options_.lk_propagation_frames));
  for (int k = 1; options_.lk_propagation && k <= sources && f - k >= 0; ++k) {
    const SeedSet& ss = seed_sets_[static_cast<std::size_t>(k)];
    if (ss.count >= std::max(1, options_.lk_neighbours))
      propagate(slots_[static_cast<std::size_t>(f - k) % slots_.size()], slot, ss);
  }
  return Status::kOk;
}

bool DescriptorTracker::setHasFrame(int node, int frame) const {
  int m = node;
  do {
    if (node_frame_[static_cast<std::size_t>(m)] == frame) return true;
    m = next_[static_cast<std::size_t>(m)];
  } while (m != node);
  return false;
}

void DescriptorTracker::propagate(Slot& previous, Slot& current, const SeedSet& seeds) {
  const Pyramid& from = pyramids_[static_cast<std::size_t>(previous.frame) % pyramids_.size()];
  const Pyramid& to = pyramids_[static_cast<std::size_t>(current.frame) % pyramids_.size()];
  const int seed_count = seeds.count;
  const int base_prev = frame_offset_[static_cast<std::size_t>(previous.frame)];
  const int k = std::min(options_.lk_neighbours, seed_count);
  const int detected = current.count;  // keypoints found in this frame (before any propagated)
  const int capacity = static_cast<int>(current.keypoints.size());
  const double t2 = options_.fundamental.ransac.threshold * options_.fundamental.ransac.threshold;
  const double merge2 = options_.merge_radius_px * options_.merge_radius_px;
  const bool oriented = seeds.oriented;
  const auto& desc_prev = oriented ? previous.oriented : previous.upright;
  int propagated = 0;
  for (int i = 0; i < previous.count; ++i) {
    const int node = base_prev + i;
    if (setHasFrame(node, current.frame)) continue;  // already matched into this frame
    const Keypoint& p = previous.keypoints[static_cast<std::size_t>(i)];
    // Prediction: the median displacement of the k nearest verified matches.
    for (int s = 0; s < seed_count; ++s) {
      const Keypoint& q =
          previous
              .keypoints[static_cast<std::size_t>(seeds.matches[static_cast<std::size_t>(s)].a)];
      const float dx = q.x - p.x, dy = q.y - p.y;
      seed_dist_[static_cast<std::size_t>(s)] = dx * dx + dy * dy;
      seed_order_[static_cast<std::size_t>(s)] = s;
    }
    std::partial_sort(seed_order_.begin(), seed_order_.begin() + k,
                      seed_order_.begin() + seed_count, [&](int32_t u, int32_t v) {
                        const float du = seed_dist_[static_cast<std::size_t>(u)];
                        const float dv = seed_dist_[static_cast<std::size_t>(v)];
                        return du < dv || (du == dv && u < v);
                      });
    for (int j = 0; j < k; ++j) {
      const DescriptorMatch& m =
          seeds.matches[static_cast<std::size_t>(seed_order_[static_cast<std::size_t>(j)])];
      disp_x_[static_cast<std::size_t>(j)] = current.keypoints[static_cast<std::size_t>(m.b)].x -
                                             previous.keypoints[static_cast<std::size_t>(m.a)].x;
      disp_y_[static_cast<std::size_t>(j)] = current.keypoints[static_cast<std::size_t>(m.b)].y -
                                             previous.keypoints[static_cast<std::size_t>(m.a)].y;
    }
    std::nth_element(disp_x_.begin(), disp_x_.begin() + k / 2, disp_x_.begin() + k);
    std::nth_element(disp_y_.begin(), disp_y_.begin() + k / 2, disp_y_.begin() + k);
    if (lk_.setTemplate(0, from, p.x, p.y) != LkStatus::kTracked) continue;
    float x = p.x + disp_x_[static_cast<std::size_t>(k / 2)];
    float y = p.y + disp_y_[static_cast<std::size_t>(k / 2)];
    float residual = 0.0f;
    if (lk_.align(0, to, x, y, residual) != LkStatus::kTracked ||
        !(static_cast<double>(residual) <= options_.lk_max_residual))
      continue;
    const Eigen::Vector2d xa = undistortedPixel(static_cast<double>(p.x), static_cast<double>(p.y));
    const Eigen::Vector2d xb = undistortedPixel(static_cast<double>(x), static_cast<double>(y));
    if (!(sampsonSquared(seeds.F, xa, xb) <= t2)) continue;
    BinaryDescriptor up, ori;
    int16_t bin = 0;
    if (!extractor_.describeAt(x, y, current.upright.empty() ? nullptr : &up,
                               current.oriented.empty() ? nullptr : &ori, bin))
      continue;
    if (hammingDistance(desc_prev[static_cast<std::size_t>(i)], oriented ? ori : up) >
        options_.lk_max_distance)
      continue;
    // A keypoint of this frame at that place: the same point.
    int near = -1;
    double near2 = merge2;
    for (int j = 0; j < detected; ++j) {
      const Keypoint& q = current.keypoints[static_cast<std::size_t>(j)];
      const double dx = static_cast<double>(q.x - x), dy = static_cast<double>(q.y - y);
      const double d2 = dx * dx + dy * dy;
      if (d2 <= near2) {
        near2 = d2;
        near = j;
      }
    }
    const int base_cur = frame_offset_[static_cast<std::size_t>(current.frame)];
    if (near >= 0) {
      if (unite(node, base_cur + near)) ++propagated;
      continue;
    }
    if (current.count >= capacity || propagated >= options_.max_propagated) continue;
    const int j = current.count++;
    Keypoint& kp = current.keypoints[static_cast<std::size_t>(j)];
    kp.x = x;
    kp.y = y;
    kp.response = 0.0f;
    kp.level = 0;
    kp.angle_bin = bin;
    if (!current.upright.empty()) current.upright[static_cast<std::size_t>(j)] = up;
    if (!current.oriented.empty()) current.oriented[static_cast<std::size_t>(j)] = ori;
    const int v = base_cur + j;
    all_keypoints_.push_back(kp);
    node_frame_.push_back(current.frame);
    parent_.push_back(v);
    next_.push_back(v);
    set_size_.push_back(1);
    frame_offset_.back() = v + 1;
    if (unite(node, v)) ++propagated;
  }
  for (auto it = pairs_.rbegin(); it != pairs_.rend(); ++it) {
    if (it->frame_a == previous.frame && it->frame_b == current.frame) {
      it->propagated = propagated;
      break;
    }
  }
}

void DescriptorTracker::buildTracks(TrackTable& table) {
  const int nodes = frame_offset_.back();
  track_of_node_.assign(static_cast<std::size_t>(nodes), -1);
  std::vector<int32_t> track_of_root(static_cast<std::size_t>(nodes), -1);
  int tracks = 0;
  std::size_t observations = 0;
  for (int v = 0; v < nodes; ++v) {
    const int r = find(v);
    if (set_size_[static_cast<std::size_t>(r)] < options_.min_track_length) continue;
    auto& t = track_of_root[static_cast<std::size_t>(r)];
    if (t < 0) t = tracks++;
    track_of_node_[static_cast<std::size_t>(v)] = t;
    ++observations;
  }
  table.reserve(frameCount(), observations);
  for (int f = 0; f < frameCount(); ++f) {
    for (int v = frame_offset_[static_cast<std::size_t>(f)];
         v < frame_offset_[static_cast<std::size_t>(f) + 1]; ++v) {
      const int t = track_of_node_[static_cast<std::size_t>(v)];
      if (t < 0) continue;
      const Keypoint& k = all_keypoints_[static_cast<std::size_t>(v)];
      table.add(f, t, k.x, k.y);
    }
  }
  table.setFrameCount(frameCount());
  table.finalize();
}

}  // namespace epitrack
