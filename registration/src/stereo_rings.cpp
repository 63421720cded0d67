#include "stampscan/registration/stereo_rings.hpp"

#include "image_line_fit.hpp"
#include "laser_raster.hpp"
#include "stereo_common.hpp"
#include "stampscan/registration/direct_ellipse.hpp"
#include "stampscan/fitting/quadric_patch.hpp"

#include <Eigen/Dense>
#include <opencv2/imgproc.hpp>
#include <tbb/parallel_for.h>

#include <algorithm>
#include <cmath>
#include <numbers>
#include <optional>

namespace stampscan::registration {

namespace {

using detail::median;

// The largest sagitta (mm) of a printed ring on the sheet under it that the stereo pair measures: a
// bend radius of 5.4 mm under a 2.54 mm circle.
constexpr double kMaxRingSagitta = 0.15;

// The rays of a ring's line points from one camera (machine frame).
struct RingRays {
  Vec3 origin;
  std::vector<Vec3> directions;
};

// The line is the image ellipse the line fit found: a smooth curve, so 120 points along it describe
// it as well as 360 did (the same elements' strains within 1e-5) for a third of the casting.
constexpr int kRayPoints = 120;

RingRays raysOf(const ImageRing& ring, const CameraModel& cam, const Eigen::Isometry3d& machine_from_camera) {
  RingRays r{machine_from_camera.translation(), {}};
  for (const auto& q : detail::normalised(ring.edge(kRayPoints), cam))
    r.directions.push_back((machine_from_camera.linear() * Vec3(q.x(), q.y(), 1)).normalized());
  return r;
}

// The sheet under a ring: a quadric w = u^T K u / 2 over the tangent plane at `origin`, with K the
// sheet's curvature from the neighbours; K = 0 is the plane.
struct RingSurface {
  Vec3 origin;
  Eigen::Matrix3d frame;  // columns: tangent axes, normal
  Eigen::Matrix2d curvature = Eigen::Matrix2d::Zero();
};

// Every `stride`-th ray cast onto the surface, in the surface's own coordinates (the hit's
// tangent-plane offset taken as an arc), so that a printed circle stays the ellipse of its stretches
// however the sheet is bent.
std::vector<Eigen::Vector2d> castOnto(const RingRays& rays, const RingSurface& surface, std::size_t stride) {
  const Eigen::Matrix2d& K = surface.curvature;
  const Vec3 p = surface.frame.transpose() * (rays.origin - surface.origin);
  std::vector<Eigen::Vector2d> out;
  for (std::size_t i = 0; i < rays.directions.size(); i += stride) {
    const Vec3 e = surface.frame.transpose() * rays.directions[i];
    double t = -p.z() / e.z();  // the tangent plane's hit, then Newton on the quadric
    for (int k = 0; k < 3; ++k) {
      const Eigen::Vector2d u = p.head<2>() + t * e.head<2>();
      const double f = p.z() + t * e.z() - 0.5 * u.dot(K * u), slope = e.z() - u.dot(K * e.head<2>());
      if (std::abs(slope) < 1e-9) break;  // a ray grazing the sheet: keep the last hit
      t -= f / slope;
    }
    out.push_back(detail::chordToArc(p.head<2>() + t * e.head<2>(), K));
  }
  return out;
}

// The cast ellipse as centre and shape matrix M (x = c + M (cos t, sin t)): what two views must
// agree on.
bool castEllipse(const RingRays& rays, const RingSurface& surface, Eigen::Matrix<double, 5, 1>& out) {
  const std::optional<CentredEllipse> e = fitDirectEllipse(castOnto(rays, surface, 2));  // 60 points
  if (!e) return false;
  out << e->centre.x(), e->centre.y(), e->shape(0, 0), e->shape(0, 1), e->shape(1, 1);
  return true;
}

// Gauss-Newton over the surface's tilt (two angles) and offset along the start normal, starting from
// the tangent plane through `centre` with `normal`; `curvature` is the sheet's there, in the axes of
// fitting::frameAround(normal), and `radius` the printed circle's. Empty when the views do not agree
// on one ellipse.
std::optional<RingSurface> ringSurface(const RingRays& left, const RingRays& right, const Vec3& centre,
                                       const Vec3& normal, const Eigen::Matrix2d& curvature, double radius) {
  const Eigen::Matrix3d start = fitting::frameAround(normal);
  // The tilt is a few degrees at most, so the curvature keeps its axes (an error of the tilt's order
  // in a term that is itself small).
  const auto surfaceOf = [&](const Eigen::Vector3d& q) {
    const Vec3 n = (normal + q(0) * start.col(0) + q(1) * start.col(1)).normalized();
    const Vec3 e1 = (start.col(0) - start.col(0).dot(n) * n).normalized();
    RingSurface p;
    p.origin = centre + q(2) * normal;
    p.frame.col(0) = e1;
    p.frame.col(1) = n.cross(e1);
    p.frame.col(2) = n;
    p.curvature = curvature;
    return p;
  };
  // Residuals: the two ellipses' difference (mm), and a weak pull of the tilt to the start (0.002 mm
  // per radian: a tilt the views can see costs far more).
  constexpr double kTiltPrior = 0.002;
  const auto residual = [&](const Eigen::Vector3d& q, Eigen::Matrix<double, 7, 1>& r) {
    const RingSurface p = surfaceOf(q);
    Eigen::Matrix<double, 5, 1> l, rr;
    if (!castEllipse(left, p, l) || !castEllipse(right, p, rr)) return false;
    // Relative to the cast ellipses' size: in millimetres, turning the plane to face the cameras
    // would shrink both ellipses and their difference with them, a pull away from the true plane.
    const double size = 0.5 * (std::sqrt(l(2) * l(4) - l(3) * l(3)) + std::sqrt(rr(2) * rr(4) - rr(3) * rr(3)));
    if (!(size > 0)) return false;
    r << (l - rr) * (radius / size), kTiltPrior * q(0), kTiltPrior * q(1);
    return true;
  };
  Eigen::Vector3d q = Eigen::Vector3d::Zero();
  Eigen::Matrix<double, 7, 1> r;
  if (!residual(q, r)) return std::nullopt;
  for (int iteration = 0; iteration < 20; ++iteration) {
    Eigen::Matrix<double, 7, 3> J;
    const double steps[3] = {1e-4, 1e-4, 1e-3};
    for (int j = 0; j < 3; ++j) {
      Eigen::Vector3d h = q;
      h(j) += steps[j];
      Eigen::Matrix<double, 7, 1> rh;
      if (!residual(h, rh)) return std::nullopt;
      J.col(j) = (rh - r) / steps[j];
    }
    Eigen::Vector3d delta = -(J.transpose() * J + 1e-12 * Eigen::Matrix3d::Identity()).ldlt().solve(J.transpose() * r);
    if (!delta.allFinite()) return std::nullopt;
    // A trust region: a long step along the barely seen tilt would overshoot the minimum.
    const double tilt_step = delta.head<2>().norm();
    if (tilt_step > 0.2) delta.head<2>() *= 0.2 / tilt_step;
    delta(2) = std::clamp(delta(2), -0.5, 0.5);
    q += delta;
    if (!residual(q, r)) return std::nullopt;
    // A tilt step of 1e-4 rad changes the cast ellipses by its square, and their perspective by the
    // ring's size over its distance times it: 1e-7 of the strain. (1e-6 took 10 rounds a ring
    // instead of 2.4 for the same strains.)
    if (std::abs(delta(2)) < 1e-5 && delta.head<2>().norm() < 1e-4) break;
  }
  // Agreement to 1 % of the ring, more where a camera sees the plane obliquely (the image's error is
  // stretched by 1 / cos on it); otherwise the match is wrong or the sheet is not as assumed.
  const RingSurface surface = surfaceOf(q);
  const Vec3 n = surface.frame.col(2);
  const double cos_left = std::abs(n.dot((surface.origin - left.origin).normalized()));
  const double cos_right = std::abs(n.dot((surface.origin - right.origin).normalized()));
  const double allowed = 0.01 / std::max(0.5, std::min(cos_left, cos_right));
  if (r.head<5>().cwiseAbs().maxCoeff() > allowed || q.head<2>().norm() > 1.2) return std::nullopt;
  return surface;
}

}  // namespace

std::vector<Eigen::Vector2d> ImageRing::edge(int points) const {
  const detail::ImageEllipse e{.centre = centre, .shape = shape, .third = third};
  std::vector<Eigen::Vector2d> out;
  out.reserve(static_cast<std::size_t>(std::max(0, points)));
  for (int k = 0; k < points; ++k) out.push_back(e.point(2 * std::numbers::pi * k / points));
  return out;
}

std::vector<ImageRing> detectImageRings(const cv::Mat& image, double expected_radius_px, const RingDetectionParams& params) {
  cv::Mat I;
  image.convertTo(I, CV_32F);
  const double inner_px = expected_radius_px * (params.printed_radius - 0.5 * params.line_width) / params.printed_radius;
  const double line_px = expected_radius_px * params.line_width / params.printed_radius;
  const double nominal = std::numbers::pi * inner_px * inner_px;
  // 1. Each ring roughly: its interior, the line's inner half-level crossing on rays from it,
  // moved out by half the line's apparent width, and an ellipse through those points.
  // The interiors one by one on TBB's threads (each is independent), kept in their order.
  const std::vector<detail::ImageInterior> interiors = detail::findImageInteriors(I, nominal, line_px, params.ink_ratio, 0.85);
  std::vector<std::optional<detail::ImageEllipse>> rough(interiors.size());
  tbb::parallel_for(std::size_t{0}, interiors.size(), [&](std::size_t index) {
    const detail::ImageInterior& in = interiors[index];
    // Half way to the ink: a line foreshortened on a steep wall is not as dark as a line seen square.
    const double sheet_mid = in.sheet_level, dark = 0.5 * (1 + params.ink_ratio) * sheet_mid;
    const double cx = in.centroid.x(), cy = in.centroid.y();
    const auto sample = [&](double x, double y) {
      // Truncation is the floor for x, y >= 0 (and no call into the maths library).
      if (!(x >= 0 && y >= 0)) return detail::kNaN;
      const int c = static_cast<int>(x), r = static_cast<int>(y);
      if (c + 1 >= I.cols || r + 1 >= I.rows) return detail::kNaN;
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
    constexpr int kRays = 120;  // a start for the fit, which uses every pixel along the line
    std::vector<double> values;
    for (int ray = 0; ray < kRays; ++ray) {
      const double th = 2 * std::numbers::pi * ray / kRays, ux = std::cos(th), uy = std::sin(th);
      values.clear();
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
    if (static_cast<double>(inner_s.size()) < params.min_edge_share * kRays || widths.size() < kRays / 6) return;
    const double half_width = 0.5 * median(widths);
    std::vector<cv::Point2f> line_points;
    for (std::size_t i = 0; i < inner_s.size(); ++i) {
      const Eigen::Vector2d q = Eigen::Vector2d(cx, cy) + (inner_s[i] + half_width) * directions[i];
      line_points.emplace_back(static_cast<float>(q.x()), static_cast<float>(q.y()));
    }
    const cv::RotatedRect box = cv::fitEllipse(line_points);
    const double a = 0.5 * box.size.width, b = 0.5 * box.size.height;
    if (!(a > 1 && b > 1) || !std::isfinite(box.center.x) || !std::isfinite(box.center.y)) return;
    const double angle = box.angle * std::numbers::pi / 180;
    const Eigen::Matrix2d rotation = Eigen::Rotation2Dd(angle).toRotationMatrix();
    detail::ImageEllipse e;
    e.centre = {box.center.x, box.center.y};
    e.shape = rotation * Eigen::Vector2d(a, b).asDiagonal() * rotation.transpose();
    // The gap between four touching rings is bright and, blurred, nearly convex too; but its edge
    // is four arcs bent the wrong way, far from any ellipse.
    std::vector<double> off;
    for (const auto& q : line_points) off.push_back(std::abs(e.distance(Eigen::Vector2d(q.x, q.y))));
    if (median(off) > std::max(0.3, 0.02 * e.meanRadius())) return;
    rough[index] = e;
  });
  std::vector<detail::ImageEllipse> first;
  for (auto& e : rough)
    if (e) first.push_back(*e);

  // 2. The line's centre by a fit of the blurred line model to the pixels along it, leaving out the
  // pixels a touching neighbour's line reaches.
  std::vector<std::optional<ImageRing>> refined(first.size());
  tbb::parallel_for(std::size_t{0}, first.size(), [&](std::size_t i) {
    detail::ImageEllipse e = first[i];
    const double r = e.meanRadius();
    const double reach = Eigen::SelfAdjointEigenSolver<Eigen::Matrix2d>(e.shape).eigenvalues().maxCoeff();
    const double line_width = line_px * r / expected_radius_px;
    detail::Exclusions exclude;
    exclude.reach = 0.5 * line_width + 2.5;
    for (std::size_t j = 0; j < first.size(); ++j)
      if (j != i && (first[j].centre - e.centre).norm() < 2.2 * reach) exclude.rings.push_back(first[j]);
    const detail::LineFitResult fit = detail::fitRingLine(I, line_width, exclude, e);
    if (!fit.ok) return;
    ImageRing ring;
    ring.centre = e.centre;
    ring.blur = fit.blur;
    ring.contrast = fit.contrast;
    ring.rms = fit.rms;
    ring.shape = e.shape;
    ring.third = e.third;
    refined[i] = std::move(ring);
  });
  std::vector<ImageRing> out;
  for (auto& r : refined)
    if (r) out.push_back(std::move(*r));
  return out;
}

std::optional<double> workingDistance(const StereoRig& rig) {
  // The left axis is the line through the origin along z; the right one, in the left camera's frame,
  // through the right camera's centre along its z.
  const Eigen::Isometry3d left_from_right = rig.right_from_left.inverse();
  const Vec3 axis = Vec3::UnitZ(), right_centre = left_from_right.translation(),
             right_axis = left_from_right.linear() * Vec3::UnitZ();
  const double b = axis.dot(right_axis);
  if (1 - b * b < 1e-6) return std::nullopt;  // within 0.08 degrees of parallel
  const Vec3 w = -right_centre;
  const double depth = (b * right_axis.dot(w) - axis.dot(w)) / (1 - b * b);
  if (!(depth > 0)) return std::nullopt;
  return depth;
}

StereoRingImages detectStereoRings(const cv::Mat& left, const cv::Mat& right, double expected_radius_px,
                                   const RingDetectionParams& params) {
  auto [l, r] = detail::detectInBoth(
      left, right, [&](const cv::Mat& image) { return detectImageRings(image, expected_radius_px, params); });
  return {std::move(l), std::move(r)};
}

double priorDepth(const StereoViewPose& pose) {
  return detail::pairPoses(pose.rig, pose.machine_from_head, pose.prior).prior_depth;
}

double pixelsAtDepth(const StereoRig& rig, double mm, double depth) { return mm * rig.left.matrix(0, 0) / depth; }

std::vector<GridElement> measureStereoPair(const StereoRingImages& found, const StereoViewPose& input,
                                           const RingDetectionParams& params, StereoStats* stats) {
  const StereoRig& rig = input.rig;
  const std::vector<Vec3>& prior = input.prior;
  const std::uint32_t view = input.index;
  StereoStats local;
  StereoStats& st = stats ? *stats : local;
  const detail::PairPoses poses = detail::pairPoses(rig, input.machine_from_head, prior);
  if (poses.prior_depth <= 0) return {};
  // The ring's size in pixels at the prior's typical depth.
  const double radius_px = pixelsAtDepth(rig, params.printed_radius, poses.prior_depth);
  // Matched within half a pitch: the next ring along the epipolar line is a whole pitch away, some
  // 6 mm of depth at the nominal standoff.
  const std::vector<ImageRing>& left = found.left;
  const std::vector<ImageRing>& right = found.right;
  const std::vector<detail::StereoMatch> matches = detail::matchFound(left, right, rig, poses, prior, radius_px, st);

  // Each ring's sheet from both views: a printed circle seen by two cameras lies on the surface
  // where the two images' lines, cast onto it, become the same ellipse. Its depth shows in the
  // centres' offset, its tilt across the baseline in the two ellipses' different foreshortening; the
  // tilt along the baseline hardly shows, so it stays near the start, the plane through the
  // triangulated neighbours. The surface's curvature comes from the neighbours too.
  const double r0 = params.printed_radius;
  const Vec3 eyes = 0.5 * (poses.machine_from_left.translation() + poses.machine_from_right.translation());
  std::vector<std::optional<GridElement>> measured(matches.size());
  tbb::parallel_for(std::size_t{0}, matches.size(), [&](std::size_t k) {
    const detail::StereoMatch& m = matches[k];
    std::vector<Vec3> near;
    for (const detail::StereoMatch& q : matches)
      if ((q.centre - m.centre).norm() < 3.5 * r0) near.push_back(q.centre);
    Vec3 normal = (eyes - m.centre).normalized();
    if (near.size() >= 5) {
      Vec3 mean = Vec3::Zero();
      for (const Vec3& p : near) mean += p;
      mean /= static_cast<double>(near.size());
      Eigen::Matrix3d cov = Eigen::Matrix3d::Zero();
      for (const Vec3& p : near) cov += (p - mean) * (p - mean).transpose();
      const Vec3 axis = Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d>(cov).eigenvectors().col(0);
      normal = axis.dot(eyes - m.centre) < 0 ? Vec3(-axis) : axis;
    }
    // The sheet's curvature from a quadric through the neighbours' centres: the ring is cast onto it.
    Eigen::Matrix2d curvature = Eigen::Matrix2d::Zero();
    if (near.size() >= 8) {
      fitting::QuadricPatch::Sums sums(fitting::frameAround(normal), m.centre, r0);
      for (const Vec3& p : near) sums.add(p, 1.0);
      const auto patch = fitting::QuadricPatch::fit(sums);
      // A ring bent over a tight radius is left out all the same: its sagitta on the sheet (0.013 mm
      // on a 60 mm dome, 0.2 mm over a 4 mm radius) is then comparable with the views' disagreement,
      // and the quadric through centres a pitch apart no longer describes the sheet under it. Up to
      // kMaxRingSagitta the views' agreement (ringSurface) and the one ellipse (below) still hold a
      // wrong sheet out: the rings over a pan's 7 mm die radii, sagitta 0.07-0.11 mm, measure their
      // strain to 0.0024 RMS (0.0011 over the rest). A die radius is where a part splits, so
      // its elements are not to be left out lightly.
      if (!patch || !(patch->maxCurvatureAtOrigin() * r0 * r0 / 2 < kMaxRingSagitta)) return;
      curvature = patch->hessianAtOrigin();
    }
    const RingRays rays_left = raysOf(left[m.left], rig.left, poses.machine_from_left);
    const RingRays rays_right = raysOf(right[m.right], rig.right, poses.machine_from_right);
    const std::optional<RingSurface> surface = ringSurface(rays_left, rays_right, m.centre, normal, curvature, r0);
    if (!surface) return;
    // Both views' points, unless one camera sees the ring much more obliquely than the other: its
    // image error, stretched by 1 / cos on the sheet, would only add noise to the better view's.
    const Vec3 n = surface->frame.col(2);
    const double cos_left = std::abs(n.dot((surface->origin - rays_left.origin).normalized()));
    const double cos_right = std::abs(n.dot((surface->origin - rays_right.origin).normalized()));
    std::vector<Eigen::Vector2d> points;
    if (cos_left >= 0.8 * cos_right) points = castOnto(rays_left, *surface, 1);
    if (cos_right >= 0.8 * cos_left) {
      const std::vector<Eigen::Vector2d> points_right = castOnto(rays_right, *surface, 1);
      points.insert(points.end(), points_right.begin(), points_right.end());
    }
    // The points must lie on one ellipse to half the laser's limit (10 um by default, 0.8 % of the
    // ring): a ring seen well by both cameras scatters by 1-2 um, one seen too obliquely or across a
    // fold by ten times that, and measures its strain ten times worse.
    detail::PlaneEllipse e;
    if (!detail::fitEllipseRobust(points, e) || e.rms > 0.5 * params.max_fit_rms) return;
    GridElement g;  // the line's centre: the printed circle itself, so no scaling
    if (!detail::elementFromEllipse(e, 1.0, surface->frame, surface->origin, params, g)) return;
    g.source = Source::Stereo;
    g.view = view;
    g.gauge_mm2 = r0 * r0 / 8;
    measured[k] = g;
  });
  std::vector<GridElement> out;
  for (auto& g : measured) {
    if (!g) {
      ++st.rejected_fit;
      continue;
    }
    out.push_back(*g);
    ++st.matched;
  }
  return out;
}

}  // namespace stampscan::registration

