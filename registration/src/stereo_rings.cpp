#include "stampscan/registration/stereo_rings.hpp"

#include "laser_raster.hpp"

#include <Eigen/Dense>
#include <opencv2/calib3d.hpp>
#include <opencv2/imgproc.hpp>

#include <algorithm>
#include <cmath>
#include <map>
#include <numbers>

namespace stampscan::registration {

namespace {

using detail::median;

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

}  // namespace

std::vector<ImageRing> detectImageRings(const cv::Mat& image, double expected_radius_px, const RingDetectionParams& params) {
  cv::Mat I;
  image.convertTo(I, CV_32F);
  const double inner_px = expected_radius_px * (params.printed_radius - 0.5 * params.line_width) / params.printed_radius;
  const double line_px = expected_radius_px * params.line_width / params.printed_radius;
  const int k = 2 * std::max(1, static_cast<int>(std::ceil(1.5 * line_px))) + 1;
  cv::Mat sheet;
  cv::morphologyEx(I, sheet, cv::MORPH_CLOSE, cv::getStructuringElement(cv::MORPH_ELLIPSE, cv::Size(k, k)));
  const cv::Mat interior = I >= params.ink_ratio * sheet;
  cv::Mat labels, stats, centroids;
  const int n = cv::connectedComponentsWithStats(interior, labels, stats, centroids, 4, CV_32S);
  const double nominal = std::numbers::pi * inner_px * inner_px;
  std::vector<ImageRing> out;
  for (int label = 1; label < n; ++label) {
    const int area = stats.at<int>(label, cv::CC_STAT_AREA);
    // The apparent size also changes with distance and tilt: a wide window.
    if (area < 0.25 * nominal || area > 4.0 * nominal) continue;
    const int x0 = stats.at<int>(label, cv::CC_STAT_LEFT), y0 = stats.at<int>(label, cv::CC_STAT_TOP);
    const int bw = stats.at<int>(label, cv::CC_STAT_WIDTH), bh = stats.at<int>(label, cv::CC_STAT_HEIGHT);
    if (x0 <= 1 || y0 <= 1 || x0 + bw >= I.cols - 1 || y0 + bh >= I.rows - 1 || bw < 5 || bh < 5) continue;
    const cv::Mat mask = labels(cv::Rect(x0, y0, bw, bh)) == label;
    std::vector<std::vector<cv::Point>> contours;
    cv::findContours(mask, contours, cv::RETR_EXTERNAL, cv::CHAIN_APPROX_NONE);
    if (contours.empty()) continue;
    std::vector<cv::Point> hull;
    cv::convexHull(contours.front(), hull);
    if (area < 0.85 * cv::contourArea(hull)) continue;  // not convex: a gap between rings
    std::vector<double> level;
    for (int r = y0; r < y0 + bh; ++r)
      for (int c = x0; c < x0 + bw; ++c)
        if (labels.at<int>(r, c) == label) level.push_back(I.at<float>(r, c));
    const double sheet_mid = median(level), dark = params.ink_ratio * sheet_mid;
    const double cx = centroids.at<double>(label, 0), cy = centroids.at<double>(label, 1);
    const auto sample = [&](double x, double y) {
      const int c = static_cast<int>(std::floor(x)), r = static_cast<int>(std::floor(y));
      if (c < 0 || r < 0 || c + 1 >= I.cols || r + 1 >= I.rows) return detail::kNaN;
      const double fx = x - c, fy = y - r;
      return (1 - fy) * ((1 - fx) * I.at<float>(r, c) + fx * I.at<float>(r, c + 1)) +
             fy * ((1 - fx) * I.at<float>(r + 1, c) + fx * I.at<float>(r + 1, c + 1));
    };
    // Along each ray, the line's two half-depth crossings. Their midpoint is the line's centre
    // whatever the blur; but where a touching neighbour's line runs alongside, the outer crossing
    // moves out. So: the inner crossing of every ray, plus half the line's apparent width, taken as
    // the median over the rays.
    std::vector<double> inner_s, widths;
    std::vector<Eigen::Vector2d> directions;
    for (int ray = 0; ray < 360; ++ray) {
      const double th = 2 * std::numbers::pi * ray / 360, ux = std::cos(th), uy = std::sin(th);
      std::vector<double> values;
      bool in_ink = false, crossed = false;
      for (double s = 0; s <= 3 * inner_px && !crossed; s += 0.25) {
        const double v = sample(cx + s * ux, cy + s * uy);
        if (std::isnan(v)) break;
        values.push_back(v);
        if (v < dark) in_ink = true;
        else if (in_ink) crossed = true;
      }
      if (!crossed) continue;
      const double mid = 0.5 * (sheet_mid + *std::min_element(values.begin(), values.end()));
      double s_in = -1, s_out = -1;
      for (std::size_t i = 1; i < values.size(); ++i) {
        const double f = (values[i - 1] - mid) / (values[i - 1] - values[i]);
        if (s_in < 0 && values[i] < mid && values[i - 1] >= mid) s_in = 0.25 * (static_cast<double>(i - 1) + f);
        else if (s_in >= 0 && values[i] >= mid && values[i - 1] < mid) {
          s_out = 0.25 * (static_cast<double>(i - 1) + f);
          break;
        }
      }
      if (s_in < 0) continue;
      inner_s.push_back(s_in);
      directions.emplace_back(ux, uy);
      if (s_out > s_in) widths.push_back(s_out - s_in);
    }
    if (static_cast<double>(inner_s.size()) < params.min_edge_share * 360 || widths.size() < 60) continue;
    const double half_width = 0.5 * median(widths);
    ImageRing ring;
    for (std::size_t i = 0; i < inner_s.size(); ++i)
      ring.edge.push_back(Eigen::Vector2d(cx, cy) + (inner_s[i] + half_width) * directions[i]);
    for (const auto& p : ring.edge) ring.centre += p;
    ring.centre /= static_cast<double>(ring.edge.size());
    out.push_back(std::move(ring));
  }
  return out;
}

std::vector<GridElement> measureStereoPair(const cv::Mat& left_image, const cv::Mat& right_image, const StereoRig& rig,
                                           const Eigen::Isometry3d& machine_from_head, const std::vector<Vec3>& prior,
                                           const RingDetectionParams& params, std::uint32_t view, StereoStats* stats) {
  StereoStats local;
  StereoStats& st = stats ? *stats : local;
  const Eigen::Isometry3d machine_from_left = machine_from_head * rig.head_from_left;
  const Eigen::Isometry3d machine_from_right = machine_from_left * rig.right_from_left.inverse();
  const Eigen::Isometry3d left_from_machine = machine_from_left.inverse(), right_from_machine = machine_from_right.inverse();
  // The ring's size in pixels at the prior's typical depth.
  std::vector<double> depths;
  for (std::size_t i = 0; i < prior.size(); i += std::max<std::size_t>(1, prior.size() / 500)) {
    const double z = (left_from_machine * prior[i]).z();
    if (z > 0) depths.push_back(z);
  }
  if (depths.empty()) return {};
  const double focal = rig.left.matrix(0, 0);
  const double radius_px = params.printed_radius * focal / median(depths);
  const std::vector<ImageRing> left = detectImageRings(left_image, radius_px, params);
  const std::vector<ImageRing> right = detectImageRings(right_image, radius_px, params);
  st.left_rings += left.size();
  st.right_rings += right.size();

  // The prior in the left image: pixel position and depth, bucketed.
  const double cell = std::max(4.0, radius_px);
  std::map<std::pair<int, int>, std::vector<double>> buckets;
  for (const Vec3& X : prior) {
    const Vec3 c = left_from_machine * X;
    if (c.z() <= 0) continue;
    const Eigen::Vector2d px = projectPoint(c, rig.left);
    buckets[{static_cast<int>(std::floor(px.x() / cell)), static_cast<int>(std::floor(px.y() / cell))}].push_back(c.z());
  }
  std::vector<Eigen::Vector2d> left_centres, right_centres;
  for (const auto& r : left) left_centres.push_back(r.centre);
  for (const auto& r : right) right_centres.push_back(r.centre);
  const auto left_n = normalised(left_centres, rig.left), right_n = normalised(right_centres, rig.right);

  struct Match {
    std::size_t l, r;
    Vec3 centre;
  };
  std::vector<Match> matches;
  for (std::size_t i = 0; i < left.size(); ++i) {
    const int bx = static_cast<int>(std::floor(left[i].centre.x() / cell)), by = static_cast<int>(std::floor(left[i].centre.y() / cell));
    std::vector<double> z;
    for (int dy = -1; dy <= 1; ++dy)
      for (int dx = -1; dx <= 1; ++dx) {
        const auto it = buckets.find({bx + dx, by + dy});
        if (it != buckets.end()) z.insert(z.end(), it->second.begin(), it->second.end());
      }
    if (z.empty()) {
      ++st.without_prior;
      continue;
    }
    const Vec3 guess_left = median(z) * Vec3(left_n[i].x(), left_n[i].y(), 1.0);
    const Eigen::Vector2d predicted = projectPoint(right_from_machine * (machine_from_left * guess_left), rig.right);
    // The nearest right ring to where the prior puts it, within a third of the pitch in pixels.
    std::size_t best = right.size();
    double best_d = 0.6 * radius_px;
    for (std::size_t j = 0; j < right.size(); ++j) {
      const double d = (right[j].centre - predicted).norm();
      if (d < best_d) best_d = d, best = j;
    }
    if (best == right.size()) {
      ++st.unmatched;
      continue;
    }
    const Vec3 o1 = machine_from_left.translation(), o2 = machine_from_right.translation();
    const Vec3 d1 = (machine_from_left.linear() * Vec3(left_n[i].x(), left_n[i].y(), 1)).normalized();
    const Vec3 d2 = (machine_from_right.linear() * Vec3(right_n[best].x(), right_n[best].y(), 1)).normalized();
    double gap = 0;
    const Vec3 X = midpoint(o1, d1, o2, d2, &gap);
    if (gap > 0.2) {  // not the same point: off the epipolar line
      ++st.unmatched;
      continue;
    }
    matches.push_back({i, best, X});
  }

  // The surface around each ring from its triangulated neighbours, then both images' line points
  // cast onto it.
  std::vector<GridElement> out;
  const double r0 = params.printed_radius;
  for (const Match& m : matches) {
    std::vector<Vec3> near;
    for (const Match& q : matches)
      if ((q.centre - m.centre).norm() < 5.5 * r0) near.push_back(q.centre);
    if (near.size() < 8) {
      ++st.rejected_fit;
      continue;
    }
    Vec3 mean = Vec3::Zero();
    for (const Vec3& p : near) mean += p;
    mean /= static_cast<double>(near.size());
    Eigen::Matrix3d cov = Eigen::Matrix3d::Zero();
    for (const Vec3& p : near) cov += (p - mean) * (p - mean).transpose();
    Vec3 axis = Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d>(cov).eigenvectors().col(0);
    if (axis.dot(machine_from_left.translation() - m.centre) < 0) axis = -axis;
    // Height field h(u, v) = c0 + c1 u + c2 v + c3 u^2 + c4 u v + c5 v^2 over the PCA plane, centred
    // on this ring.
    const Eigen::Matrix3d pca = fitting::frameAround(axis);
    Eigen::MatrixXd A(static_cast<Eigen::Index>(near.size()), 6);
    Eigen::VectorXd z(static_cast<Eigen::Index>(near.size()));
    for (std::size_t k = 0; k < near.size(); ++k) {
      const Vec3 d = near[k] - m.centre;
      const double u = pca.col(0).dot(d), v = pca.col(1).dot(d);
      A.row(static_cast<Eigen::Index>(k)) << 1, u, v, u * u, u * v, v * v;
      z(static_cast<Eigen::Index>(k)) = pca.col(2).dot(d);
    }
    const Eigen::Matrix<double, 6, 1> c = A.colPivHouseholderQr().solve(z);
    const auto height = [&](const Vec3& X) {
      const Vec3 d = X - m.centre;
      const double u = pca.col(0).dot(d), v = pca.col(1).dot(d);
      return pca.col(2).dot(d) - (c(0) + c(1) * u + c(2) * v + c(3) * u * u + c(4) * u * v + c(5) * v * v);
    };
    const Vec3 surface_centre = m.centre + c(0) * pca.col(2);
    const Vec3 normal = (pca.col(2) - c(1) * pca.col(0) - c(2) * pca.col(1)).normalized();
    const Eigen::Matrix3d frame = fitting::frameAround(normal);
    std::vector<Eigen::Vector2d> plane;
    const auto cast = [&](const ImageRing& ring, const CameraModel& cam, const Eigen::Isometry3d& pose) {
      for (const auto& q : normalised(ring.edge, cam)) {
        const Vec3 o = pose.translation();
        const Vec3 d = (pose.linear() * Vec3(q.x(), q.y(), 1)).normalized();
        double t = (surface_centre - o).dot(normal) / d.dot(normal);
        for (int it = 0; it < 8; ++it) {  // Newton on the height along the ray (secant slope)
          const double f = height(o + t * d), f2 = height(o + (t + 1e-3) * d);
          if (std::abs(f2 - f) < 1e-15) break;
          const double step = f * 1e-3 / (f2 - f);
          t -= step;
          if (std::abs(step) < 1e-7) break;
        }
        const Vec3 X = o + t * d - surface_centre;
        plane.emplace_back(frame.col(0).dot(X), frame.col(1).dot(X));
      }
    };
    cast(left[m.l], rig.left, machine_from_left);
    cast(right[m.r], rig.right, machine_from_right);
    detail::PlaneEllipse e;
    if (!detail::fitEllipseRobust(plane, e) || e.rms > 2.5 * params.max_fit_rms) {
      ++st.rejected_fit;
      continue;
    }
    GridElement g;  // the line's centre: the printed circle itself, so no scaling
    if (!detail::elementFromEllipse(e, 1.0, frame, surface_centre, params, g)) {
      ++st.rejected_fit;
      continue;
    }
    g.source = Source::Stereo;
    g.view = view;
    out.push_back(g);
    ++st.matched;
  }
  return out;
}

}  // namespace stampscan::registration
