#include "stereo_common.hpp"

#include "laser_raster.hpp"

#include <Eigen/Dense>
#include <opencv2/calib3d.hpp>
#include <opencv2/imgproc.hpp>

#include <algorithm>
#include <cmath>
#include <map>

namespace stampscan::registration::detail {

// Pixels to undistorted normalised image coordinates (x/z, y/z).
std::vector<Eigen::Vector2d> normalised(const std::vector<Eigen::Vector2d>& px, const CameraModel& cam) {
  if (px.empty()) return {};
  std::vector<cv::Point2d> in, out;
  for (const auto& p : px) in.emplace_back(p.x(), p.y());
  cv::undistortPoints(in, out, cv::Mat(cam.matrix), cam.distortion,
                      cv::noArray(), cv::noArray(), cv::TermCriteria(cv::TermCriteria::COUNT | cv::TermCriteria::EPS, 30, 1e-10));
  std::vector<Eigen::Vector2d> r;
  for (const auto& p : out) r.emplace_back(p.x, p.y);
  return r;
}

Eigen::Vector2d projectPoint(const Vec3& camera_point, const CameraModel& cam) {
  std::vector<cv::Point3d> in{{camera_point.x(), camera_point.y(), camera_point.z()}};
  std::vector<cv::Point2d> out;
  cv::projectPoints(in, cv::Vec3d(0, 0, 0), cv::Vec3d(0, 0, 0), cv::Mat(cam.matrix), cam.distortion, out);
  return {out[0].x, out[0].y};
}

// Closest point between two rays (origin, unit direction): the triangulated point, and the gap.
Vec3 midpoint(const Vec3& o1, const Vec3& d1, const Vec3& o2, const Vec3& d2, double* gap) {
  const Vec3 w = o1 - o2;
  const double b = d1.dot(d2), d = d1.dot(w), e = d2.dot(w);
  const double denom = 1 - b * b;
  const double s = denom > 1e-12 ? (b * e - d) / denom : 0, t = denom > 1e-12 ? (e - b * d) / denom : e;
  const Vec3 p1 = o1 + s * d1, p2 = o2 + t * d2;
  if (gap) *gap = (p1 - p2).norm();
  return 0.5 * (p1 + p2);
}

PairPoses pairPoses(const StereoRig& rig, const Eigen::Isometry3d& machine_from_head, const std::vector<Vec3>& prior) {
  PairPoses p;
  p.machine_from_left = machine_from_head * rig.head_from_left;
  p.machine_from_right = p.machine_from_left * rig.right_from_left.inverse();
  p.left_from_machine = p.machine_from_left.inverse();
  p.right_from_machine = p.machine_from_right.inverse();
  std::vector<double> depths;
  for (std::size_t i = 0; i < prior.size(); i += std::max<std::size_t>(1, prior.size() / 500)) {
    const double z = (p.left_from_machine * prior[i]).z();
    if (z > 0) depths.push_back(z);
  }
  p.prior_depth = depths.empty() ? 0.0 : median(depths);
  return p;
}

std::vector<ImageInterior> findImageInteriors(const cv::Mat& I, double nominal_area, double line_px, double ink_ratio,
                                              double min_convexity) {
  // The closing must bridge the darkest band: where two elements touch, their lines run side by
  // side, and the optics blur each edge by a pixel or so whatever the resolution. Where it does
  // not (lines 1.3 px wide on a coarse camera), the sheet level sinks between touching rings, the
  // lines pass as interior and whole areas of rings join into one region.
  const int half = std::max({1, static_cast<int>(std::ceil(1.5 * line_px)), static_cast<int>(std::ceil(line_px + 1.5))});
  const int k = 2 * half + 1;
  cv::Mat sheet;
  cv::morphologyEx(I, sheet, cv::MORPH_CLOSE, cv::getStructuringElement(cv::MORPH_ELLIPSE, cv::Size(k, k)));
  const cv::Mat interior = I >= ink_ratio * sheet;
  cv::Mat labels, stats, centroids;
  const int n = cv::connectedComponentsWithStats(interior, labels, stats, centroids, 4, CV_32S);
  std::vector<ImageInterior> out;
  for (int label = 1; label < n; ++label) {
    const int area = stats.at<int>(label, cv::CC_STAT_AREA);
    if (area < 0.25 * nominal_area || area > 4.0 * nominal_area) continue;
    const int x0 = stats.at<int>(label, cv::CC_STAT_LEFT), y0 = stats.at<int>(label, cv::CC_STAT_TOP);
    const int bw = stats.at<int>(label, cv::CC_STAT_WIDTH), bh = stats.at<int>(label, cv::CC_STAT_HEIGHT);
    if (x0 <= 1 || y0 <= 1 || x0 + bw >= I.cols - 1 || y0 + bh >= I.rows - 1 || bw < 5 || bh < 5) continue;
    const cv::Mat mask = labels(cv::Rect(x0, y0, bw, bh)) == label;
    std::vector<std::vector<cv::Point>> contours;
    cv::findContours(mask, contours, cv::RETR_EXTERNAL, cv::CHAIN_APPROX_NONE, cv::Point(x0, y0));
    if (contours.empty()) continue;
    ImageInterior in;
    cv::convexHull(contours.front(), in.hull);
    if (area < min_convexity * cv::contourArea(in.hull)) continue;  // not convex: a gap between elements
    std::vector<double> level;
    for (int r = y0; r < y0 + bh; ++r)
      for (int c = x0; c < x0 + bw; ++c)
        if (labels.at<int>(r, c) == label) level.push_back(I.at<float>(r, c));
    in.sheet_level = median(level);
    in.centroid = {centroids.at<double>(label, 0), centroids.at<double>(label, 1)};
    in.area = area;
    out.push_back(std::move(in));
  }
  return out;
}

namespace {
// How many cells the prior's neighbourhood of an element may widen to: the cells are a ring's
// radius wide, so 6 reach some 5 mm beyond the 3 x 3 cells, across the widest glare spot.
constexpr int kMaxPriorReach = 6;
}  // namespace

std::vector<StereoMatch> matchAcrossViews(const std::vector<Eigen::Vector2d>& left_centres,
                                          const std::vector<Eigen::Vector2d>& right_centres, const StereoRig& rig,
                                          const PairPoses& poses, const std::vector<Vec3>& prior, double window_px,
                                          StereoStats& st) {
  // The prior in the left image: pixel position and depth, bucketed.
  const double cell = std::max(4.0, window_px);
  std::map<std::pair<int, int>, std::vector<Vec3>> buckets;  // (u, v, depth)
  for (const Vec3& X : prior) {
    const Vec3 c = poses.left_from_machine * X;
    if (c.z() <= 0) continue;
    const Eigen::Vector2d px = projectPoint(c, rig.left);
    buckets[{static_cast<int>(std::floor(px.x() / cell)), static_cast<int>(std::floor(px.y() / cell))}].push_back(Vec3(px.x(), px.y(), c.z()));
  }
  const auto left_n = normalised(left_centres, rig.left), right_n = normalised(right_centres, rig.right);

  std::vector<StereoMatch> matches;
  for (std::size_t i = 0; i < left_centres.size(); ++i) {
    const int bx = static_cast<int>(std::floor(left_centres[i].x() / cell)), by = static_cast<int>(std::floor(left_centres[i].y() / cell));
    // The prior around the element: the 3 x 3 cells about it, widened ring by ring while it holds
    // too few points for a plane. The laser loses a polished spot of the sheet to glare (up to 9 mm
    // across), and the elements there would otherwise go unmatched although both cameras see them;
    // the sheet is smooth, so a plane through the prior a few millimetres around still puts the
    // depth well within the pitch's ambiguity (some 6 mm along the epipolar line).
    std::vector<Vec3> z;
    double reach_cells = 1;
    for (int reach = 0; reach <= kMaxPriorReach && (reach <= 1 || z.size() < 6); ++reach) {
      for (int dy = -reach; dy <= reach; ++dy)
        for (int dx = -reach; dx <= reach; ++dx) {
          if (std::max(std::abs(dx), std::abs(dy)) != reach) continue;  // the ring at this reach only
          const auto it = buckets.find({bx + dx, by + dy});
          if (it != buckets.end()) z.insert(z.end(), it->second.begin(), it->second.end());
        }
      reach_cells = std::max(1, reach);
    }
    if (z.empty()) {
      ++st.without_prior;
      continue;
    }
    // The depth at the element from a plane through the prior around it (on a steep wall the depth
    // changes by millimetres across the neighbourhood), kept within the depths seen there.
    std::vector<double> depths_near;
    for (const Vec3& q : z) depths_near.push_back(q.z());
    double depth = median(depths_near);
    if (z.size() >= 6) {
      Eigen::MatrixXd A(static_cast<Eigen::Index>(z.size()), 3);
      Eigen::VectorXd b(static_cast<Eigen::Index>(z.size()));
      for (std::size_t k = 0; k < z.size(); ++k) {
        A.row(static_cast<Eigen::Index>(k)) << 1, (z[k].x() - left_centres[i].x()) / (cell * reach_cells),
            (z[k].y() - left_centres[i].y()) / (cell * reach_cells);
        b(static_cast<Eigen::Index>(k)) = z[k].z();
      }
      const Eigen::Vector3d plane = A.colPivHouseholderQr().solve(b);
      const auto [lo, hi] = std::minmax_element(depths_near.begin(), depths_near.end());
      if (std::isfinite(plane(0))) depth = std::clamp(plane(0), *lo, *hi);
    }
    const Vec3 guess_left = depth * Vec3(left_n[i].x(), left_n[i].y(), 1.0);
    const Eigen::Vector2d predicted =
        projectPoint(poses.right_from_machine * (poses.machine_from_left * guess_left), rig.right);
    const Vec3 o1 = poses.machine_from_left.translation(), o2 = poses.machine_from_right.translation();
    const Vec3 d1 = (poses.machine_from_left.linear() * Vec3(left_n[i].x(), left_n[i].y(), 1)).normalized();
    std::size_t best = right_centres.size();
    double best_d = window_px;
    Vec3 X = Vec3::Zero();
    for (std::size_t j = 0; j < right_centres.size(); ++j) {
      const double d = (right_centres[j] - predicted).norm();
      if (d >= best_d) continue;
      const Vec3 d2 = (poses.machine_from_right.linear() * Vec3(right_n[j].x(), right_n[j].y(), 1)).normalized();
      double gap = 0;
      const Vec3 candidate = midpoint(o1, d1, o2, d2, &gap);
      if (gap > 0.2) continue;  // not the same point: off the epipolar line
      best_d = d, best = j, X = candidate;
    }
    if (best == right_centres.size()) {
      ++st.unmatched;
      continue;
    }
    matches.push_back({i, best, X});
  }

  return matches;
}

}  // namespace stampscan::registration::detail
