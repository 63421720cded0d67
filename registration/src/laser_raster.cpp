#include "laser_raster.hpp"

#include "sheet_arcs.hpp"
#include "stampscan/registration/direct_ellipse.hpp"

#include <Eigen/Dense>
#include <opencv2/imgproc.hpp>

#include <algorithm>
#include <cmath>
#include <numbers>
#include <optional>

namespace stampscan::registration::detail {

double Raster::sample(double x, double y) const {
  const int c = static_cast<int>(std::floor(x)), r = static_cast<int>(std::floor(y));
  if (!ok(r, c) || !ok(r, c + 1) || !ok(r + 1, c) || !ok(r + 1, c + 1)) return kNaN;
  const double fx = x - c, fy = y - r;
  const auto I = [&](int rr, int cc) { return static_cast<double>(intensity.at<float>(rr, cc)); };
  return (1 - fy) * ((1 - fx) * I(r, c) + fx * I(r, c + 1)) + fy * ((1 - fx) * I(r + 1, c) + fx * I(r + 1, c + 1));
}

bool Raster::lift(double x, double y, Vec3& out) const {
  const int c = static_cast<int>(std::floor(x)), r = static_cast<int>(std::floor(y));
  if (!ok(r, c) || !ok(r, c + 1) || !ok(r + 1, c) || !ok(r + 1, c + 1)) return false;
  const double fx = x - c, fy = y - r;
  out = (1 - fy) * ((1 - fx) * at(r, c) + fx * at(r, c + 1)) + fy * ((1 - fx) * at(r + 1, c) + fx * at(r + 1, c + 1));
  return true;
}

Raster buildRaster(const std::vector<Profile>& sweep, const HeadTrack& track, const DigitizerCalibration& cal) {
  Raster R;
  R.rows = static_cast<int>(sweep.size());
  R.cols = sweep.empty() ? 0 : static_cast<int>(sweep.front().range.size());
  R.intensity = cv::Mat::zeros(R.rows, R.cols, CV_32F);
  R.valid = cv::Mat::zeros(R.rows, R.cols, CV_8U);
  R.position.assign(static_cast<std::size_t>(R.rows) * R.cols, Vec3::Constant(kNaN));
  for (int r = 0; r < R.rows; ++r) {
    const Profile& p = sweep[static_cast<std::size_t>(r)];
    const std::int64_t t = cal.exposureTime(p);
    if (static_cast<int>(p.range.size()) != R.cols || !track.covers(t)) continue;
    const Eigen::Isometry3d pose = track.poseAt(t) * cal.head_from_digitizer;
    if (r == R.rows / 2) R.viewpoint = pose.translation();
    for (int c = 0; c < R.cols; ++c) {
      const auto i = static_cast<std::size_t>(c);
      if (!(p.range[i] > 0) || i >= p.intensity.size() || p.intensity[i] == 65535) continue;
      R.position[static_cast<std::size_t>(r) * R.cols + c] = pose * sensorPoint(p, i);
      R.intensity.at<float>(r, c) = static_cast<float>(p.intensity[i]);
      R.valid.at<std::uint8_t>(r, c) = 255;
    }
  }
  // A return lost between two that returned, across or along the profiles (on a steep wall 1-2 %
  // of the points are lost so), is filled between them: a ray through it then reads the line's
  // crossing on whole data. Wider holes stay holes.
  struct Filled {
    int r, c;
    Vec3 position;
    float intensity;
  };
  std::vector<Filled> filled;
  const auto between = [&](int r, int c, int dr, int dc) {
    filled.push_back({r, c, 0.5 * (R.at(r - dr, c - dc) + R.at(r + dr, c + dc)),
                      0.5f * (R.intensity.at<float>(r - dr, c - dc) + R.intensity.at<float>(r + dr, c + dc))});
  };
  for (int r = 1; r + 1 < R.rows; ++r)
    for (int c = 1; c + 1 < R.cols; ++c) {
      if (R.ok(r, c)) continue;
      if (R.ok(r, c - 1) && R.ok(r, c + 1)) between(r, c, 0, 1);
      else if (R.ok(r - 1, c) && R.ok(r + 1, c)) between(r, c, 1, 0);
    }
  for (const Filled& f : filled) {
    R.position[static_cast<std::size_t>(f.r) * R.cols + f.c] = f.position;
    R.intensity.at<float>(f.r, f.c) = f.intensity;
    R.valid.at<std::uint8_t>(f.r, f.c) = 255;
  }
  std::vector<double> dc, dr;
  for (int r = 0; r + 1 < R.rows; r += 7)
    for (int c = 0; c + 1 < R.cols; c += 7) {
      if (R.ok(r, c) && R.ok(r, c + 1)) dc.push_back((R.at(r, c + 1) - R.at(r, c)).norm());
      if (R.ok(r, c) && R.ok(r + 1, c)) dr.push_back((R.at(r + 1, c) - R.at(r, c)).norm());
    }
  R.col_mm = median(dc);
  R.row_mm = median(dr);
  return R;
}

namespace {

// One bright region of the interiors' mask (a candidate), as connectedComponentsWithStats found it.
struct Region {
  int label, area, x0, y0, width, height;
  double cx, cy;  // its centroid, px
};

// A ring's or a cell's interior is convex; the four-pointed gaps between touching rings are not.
bool convexEnough(const cv::Mat& labels, const Region& g) {
  const cv::Mat mask = labels(cv::Rect(g.x0, g.y0, g.width, g.height)) == g.label;
  std::vector<std::vector<cv::Point>> contours;
  cv::findContours(mask, contours, cv::RETR_EXTERNAL, cv::CHAIN_APPROX_NONE);
  double hull_area = 0;
  if (!contours.empty()) {
    std::vector<cv::Point> hull;
    cv::convexHull(contours.front(), hull);
    hull_area = cv::contourArea(hull);
  }
  return hull_area > 0 && g.area >= 0.85 * hull_area;
}

// The region's sheet level: the median of its pixels away from gaps in the data, or nothing when
// most of it lies by one. A steep wall loses a return here and there (1-2 % of the points at 55-60
// degrees); a region with such a hole is still measured, its rays through the hole are left out by
// the edge's own checks (innerEdge, the share and the widest gap). Refusing every region touching a
// gap had left most wall elements of the pan to the cameras (428 of 719 refusals on a whole pan).
std::optional<double> sheetLevel(const Raster& R, const cv::Mat& labels, const cv::Mat& gaps, const Region& g) {
  std::vector<double> level;
  std::size_t by_gap = 0;
  for (int r = g.y0; r < g.y0 + g.height; ++r)
    for (int c = g.x0; c < g.x0 + g.width; ++c)
      if (labels.at<int>(r, c) == g.label) {
        if (gaps.at<std::uint8_t>(r, c)) ++by_gap;
        else level.push_back(R.intensity.at<float>(r, c));
      }
  if (level.size() < by_gap) return std::nullopt;
  return median(level);
}

// The sub-pixel inner edge along rays from the centroid, isotropic on the part: one point per ray
// that crosses the line (dark, then bright again) on valid data; the widest gap between such rays.
// A ray marches on over a hole in the data of up to two and a half pixels (returns lost here and
// there on a steep wall; a lone one is filled by buildRaster) but never reads the crossing across
// one. Such a hole could hide a blurred line, and the ray would then cross the next line out: a
// point of a ray that passed a hole and stands off its neighbouring rays' edge by more than the
// line's width is left out.
struct InnerEdge {
  std::vector<Vec3> points;
  double max_gap_deg = 0;
};

InnerEdge innerEdge(const Raster& R, const InteriorSearch& params, double cx, double cy, double sheet_mid) {
  constexpr int kRays = 360;
  const double reach = 1.5 * params.inner_reach_mm * std::exp(params.max_strain);
  const double dark = params.ink_ratio * sheet_mid;
  const double longest_hole = std::max(0.5 * params.line_width, 2.5 * std::max(R.col_mm, R.row_mm));
  struct Sample {
    double s, v;
  };
  std::vector<Sample> values;
  std::vector<double> radius(kRays, kNaN);  // mm along the ray, NaN for no crossing
  std::vector<char> passed_hole(kRays, 0);
  for (int k = 0; k < kRays; ++k) {
    const double th = 2 * std::numbers::pi * k / kRays;
    const double ux = std::cos(th) / R.col_mm, uy = std::sin(th) / R.row_mm;  // px per mm along the ray
    const double step = 0.25 / std::hypot(ux, uy);                            // a quarter pixel, in mm
    // March until the ray has crossed the line; it needs valid data only that far.
    values.clear();
    bool broken = false, in_ink = false, crossed = false;
    double hole = 0;
    for (double s = 0; s <= reach && !crossed; s += step) {
      const double v = R.sample(cx + s * ux, cy + s * uy);
      if (std::isnan(v)) {
        hole += step;
        if (hole > longest_hole) {
          broken = true;
          break;
        }
        continue;
      }
      if (hole > 0) passed_hole[static_cast<std::size_t>(k)] = 1;
      hole = 0;
      values.push_back({s, v});
      if (v < dark) in_ink = true;
      else if (in_ink) crossed = true;
    }
    if (broken || !crossed || values.size() < 4) continue;
    double ink = values.front().v;
    for (const Sample& x : values) ink = std::min(ink, x.v);
    const double mid = 0.5 * (sheet_mid + ink);
    for (std::size_t i = 1; i < values.size(); ++i)
      if (values[i].v < mid && values[i - 1].v >= mid) {
        if (values[i].s - values[i - 1].s < 1.5 * step) {
          const double f = (values[i - 1].v - mid) / (values[i - 1].v - values[i].v);
          radius[static_cast<std::size_t>(k)] = values[i - 1].s + f * (values[i].s - values[i - 1].s);
        }
        break;
      }
  }
  InnerEdge edge;
  int last_ray = -1, first_ray = -1;
  std::vector<double> around;
  for (int k = 0; k < kRays; ++k) {
    const double r = radius[static_cast<std::size_t>(k)];
    if (std::isnan(r)) continue;
    if (passed_hole[static_cast<std::size_t>(k)]) {
      around.clear();
      for (int d = -5; d <= 5; ++d)
        if (d != 0 && !std::isnan(radius[static_cast<std::size_t>((k + d + kRays) % kRays)]))
          around.push_back(radius[static_cast<std::size_t>((k + d + kRays) % kRays)]);
      if (around.size() < 4 || std::abs(r - median(around)) > params.line_width) continue;
    }
    const double th = 2 * std::numbers::pi * k / kRays;
    Vec3 p;
    if (!R.lift(cx + r * std::cos(th) / R.col_mm, cy + r * std::sin(th) / R.row_mm, p)) continue;
    edge.points.push_back(p);
    if (last_ray >= 0) edge.max_gap_deg = std::max(edge.max_gap_deg, static_cast<double>(k - last_ray));
    if (first_ray < 0) first_ray = k;
    last_ray = k;
  }
  if (first_ray >= 0) edge.max_gap_deg = std::max(edge.max_gap_deg, static_cast<double>(kRays - last_ray + first_ray));
  return edge;
}

// The plane through the edge (its normal towards the sensor), and the edge in it.
Interior interiorOf(const Raster& R, const cv::Mat& labels, const Region& g, std::vector<Vec3> edge) {
  Vec3 mean = Vec3::Zero();
  for (const Vec3& p : edge) mean += p;
  mean /= static_cast<double>(edge.size());
  Eigen::Matrix3d cov = Eigen::Matrix3d::Zero();
  for (const Vec3& p : edge) cov += (p - mean) * (p - mean).transpose();
  Vec3 normal = Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d>(cov).eigenvectors().col(0);
  if (normal.dot(R.viewpoint - mean) < 0) normal = -normal;
  const Eigen::Matrix3d frame = fitting::frameAround(normal);
  Interior in;
  for (const Vec3& p : edge) in.plane.emplace_back(frame.col(0).dot(p - mean), frame.col(1).dot(p - mean));
  in.edge = std::move(edge);
  in.mean = mean;
  in.normal = normal;
  in.frame = frame;
  for (int r = g.y0; r < g.y0 + g.height; ++r)
    for (int c = g.x0; c < g.x0 + g.width; ++c)
      if (labels.at<int>(r, c) == g.label) in.pixels.push_back(R.at(r, c));
  return in;
}

}  // namespace

std::vector<Interior> findInteriors(const Raster& R, const InteriorSearch& params, RingDetectionStats& st) {
  std::vector<Interior> out;
  // Too short a sweep, or one without two neighbouring returns to measure the spacing: nothing.
  if (R.rows < 3 || !(R.col_mm > 0) || !(R.row_mm > 0)) return out;
  const double w = params.line_width;
  // 1. Ink against the local sheet level: a grey closing wider than the line removes the lines.
  const int kc = 2 * static_cast<int>(std::ceil(1.5 * w / R.col_mm)) + 1;
  const int kr = 2 * static_cast<int>(std::ceil(1.5 * w / R.row_mm)) + 1;
  cv::Mat sheet;
  cv::morphologyEx(R.intensity, sheet, cv::MORPH_CLOSE, cv::getStructuringElement(cv::MORPH_ELLIPSE, cv::Size(kc, kr)));
  cv::Mat interior = (R.intensity >= params.ink_ratio * sheet) & R.valid;
  // 2. Bright regions of about the interior's size. 4-connectivity: a thin diagonal line separates.
  cv::Mat labels, comp_stats, centroids;
  const int n = cv::connectedComponentsWithStats(interior, labels, comp_stats, centroids, 4, CV_32S);
  const double nominal_area = params.nominal_area_mm2 / (R.col_mm * R.row_mm);
  const double min_area = nominal_area * std::exp(2 * params.min_strain), max_area = nominal_area * std::exp(2 * params.max_strain);
  cv::Mat gaps;
  cv::dilate(~R.valid, gaps, cv::Mat());
  for (int label = 1; label < n; ++label) {
    const Region g{label,
                   comp_stats.at<int>(label, cv::CC_STAT_AREA),
                   comp_stats.at<int>(label, cv::CC_STAT_LEFT),
                   comp_stats.at<int>(label, cv::CC_STAT_TOP),
                   comp_stats.at<int>(label, cv::CC_STAT_WIDTH),
                   comp_stats.at<int>(label, cv::CC_STAT_HEIGHT),
                   centroids.at<double>(label, 0),
                   centroids.at<double>(label, 1)};
    if (g.area < 0.5 * min_area || g.area > max_area) continue;  // lines, background, merged cells
    ++st.candidates;
    if (g.width < 5 || g.height < 5 || !convexEnough(labels, g)) {
      ++st.rejected_size;
      continue;
    }
    if (g.x0 <= 1 || g.y0 <= 1 || g.x0 + g.width >= R.cols - 1 || g.y0 + g.height >= R.rows - 1) {
      ++st.rejected_gap;
      continue;
    }
    const std::optional<double> sheet_mid = sheetLevel(R, labels, gaps, g);
    if (!sheet_mid) {
      ++st.rejected_gap;
      continue;
    }
    // 3. The inner edge; only whole rings: an arc leaves the ellipse's axes poorly determined.
    InnerEdge edge = innerEdge(R, params, g.cx, g.cy, *sheet_mid);
    if (edge.points.size() < static_cast<std::size_t>(params.min_edge_share * 360) ||
        edge.max_gap_deg > params.max_edge_gap_deg) {
      ++st.rejected_gap;
      continue;
    }
    // 4. The plane through the edge, and the edge in it.
    out.push_back(interiorOf(R, labels, g, std::move(edge.points)));
  }
  return out;
}

double surfaceOffset(const Interior& interior, const Vec3& centre, double radius) {
  double offset = 0;
  int count = 0;
  for (const Vec3& p : interior.pixels) {
    const Vec3 d = p - centre;
    const double along = d.dot(interior.normal);
    if ((d - along * interior.normal).norm() < radius) {
      offset += along;
      ++count;
    }
  }
  return count > 0 ? offset / count : 0.0;
}

namespace {

// w = c0 + c1 u + c2 v + c3 u^2 + c4 uv + c5 v^2 + c6 u^3 + c7 u^2 v + c8 u v^2 + c9 v^3, with (u, v)
// the plane coordinates over `scale`.
struct CubicHeight {
  Eigen::Matrix<double, 10, 1> c = Eigen::Matrix<double, 10, 1>::Zero();
  double scale = 1;
  static Eigen::Matrix<double, 10, 1> row(double u, double v) {
    Eigen::Matrix<double, 10, 1> r;
    r << 1, u, v, u * u, u * v, v * v, u * u * u, u * u * v, u * v * v, v * v * v;
    return r;
  }
  Eigen::Vector2d slope(const Eigen::Vector2d& q) const {  // dw/du, dw/dv in mm/mm
    const double u = q.x() / scale, v = q.y() / scale;
    return Eigen::Vector2d(c(1) + 2 * c(3) * u + c(4) * v + 3 * c(6) * u * u + 2 * c(7) * u * v + c(8) * v * v,
                           c(2) + c(4) * u + 2 * c(5) * v + c(7) * u * u + 2 * c(8) * u * v + 3 * c(9) * v * v) /
           scale;
  }
  Eigen::Matrix2d hessian(const Eigen::Vector2d& q) const {  // 1/mm
    const double u = q.x() / scale, v = q.y() / scale;
    Eigen::Matrix2d h;
    h(0, 0) = 2 * c(3) + 6 * c(6) * u + 2 * c(7) * v;
    h(0, 1) = h(1, 0) = c(4) + 2 * c(7) * u + 2 * c(8) * v;
    h(1, 1) = 2 * c(5) + 2 * c(8) * u + 6 * c(9) * v;
    return h / (scale * scale);
  }
};

std::optional<CubicHeight> sheetUnder(const Interior& in) {
  double reach = 0;
  for (const Eigen::Vector2d& q : in.plane) reach = std::max(reach, q.norm());
  if (!(reach > 0) || in.edge.size() + in.pixels.size() < 30) return std::nullopt;
  CubicHeight h;
  h.scale = reach;
  Eigen::Matrix<double, 10, 10> ata = Eigen::Matrix<double, 10, 10>::Zero();
  Eigen::Matrix<double, 10, 1> atb = Eigen::Matrix<double, 10, 1>::Zero();
  const auto add = [&](const Vec3& p) {
    const Vec3 d = in.frame.transpose() * (p - in.mean);
    const Eigen::Matrix<double, 10, 1> r = CubicHeight::row(d.x() / reach, d.y() / reach);
    ata.selfadjointView<Eigen::Lower>().rankUpdate(r);
    atb += r * d.z();
  };
  for (const Vec3& p : in.edge) add(p);
  for (const Vec3& p : in.pixels) add(p);
  const Eigen::LDLT<Eigen::Matrix<double, 10, 10>> solve(ata.selfadjointView<Eigen::Lower>());
  if (solve.info() != Eigen::Success) return std::nullopt;
  h.c = solve.solve(atb);
  if (!h.c.allFinite()) return std::nullopt;
  return h;
}

}  // namespace

std::vector<Eigen::Vector2d> unrolledOutline(const Interior& interior, const std::vector<Eigen::Vector2d>& outline,
                                             const Eigen::Vector2d& centre) {
  const std::optional<CubicHeight> sheet = sheetUnder(interior);
  if (!sheet) return outline;
  // Five-point Gauss-Legendre on [0, 1]: the path's length along the sheet over the straight line in
  // the plane, exact for the cubic's slope to well below a micrometre over a ring.
  static constexpr double kNodes[5] = {0.046910077030668, 0.230765344947158, 0.5, 0.769234655052842,
                                       0.953089922969332};
  static constexpr double kWeights[5] = {0.118463442528095, 0.239314335249683, 0.284444444444444,
                                         0.239314335249683, 0.118463442528095};
  const Eigen::Matrix2d K = sheet->hessian(centre);
  std::vector<Eigen::Vector2d> out;
  out.reserve(outline.size());
  for (const Eigen::Vector2d& q : outline) {
    const Eigen::Vector2d d = q - centre;
    const double chord = d.norm();
    if (!(chord > 0)) {
      out.push_back(q);
      continue;
    }
    double length = 0;
    for (int i = 0; i < 5; ++i) {
      const double rise = sheet->slope(centre + kNodes[i] * d).dot(d) / chord;
      length += kWeights[i] * std::sqrt(1 + rise * rise);
    }
    out.push_back(centre + chord * length * chordToArc(d, K).normalized());
  }
  return out;
}

std::vector<double> ellipseResiduals(const PlaneEllipse& e, const std::vector<Eigen::Vector2d>& points) {
  // The axis' cosine and sine once for all points (per point, they were a fifth of a stereo view's
  // measurement).
  const double c = std::cos(e.angle), s = std::sin(e.angle);
  std::vector<double> out;
  out.reserve(points.size());
  for (const Eigen::Vector2d& q : points) {
    const Eigen::Vector2d d = q - e.centre;
    const double x = c * d.x() + s * d.y(), y = -s * d.x() + c * d.y();
    const double rho = std::sqrt((x / e.a) * (x / e.a) + (y / e.b) * (y / e.b));
    out.push_back(rho > 0 ? d.norm() * (1 - 1 / rho) : -d.norm());
  }
  return out;
}

namespace {
bool fitEllipseOnce(const std::vector<Eigen::Vector2d>& pts, PlaneEllipse& out) {
  if (pts.size() < 20) return false;
  const std::optional<CentredEllipse> fit = fitDirectEllipse(pts);
  if (!fit) return false;
  const Eigen::SelfAdjointEigenSolver<Eigen::Matrix2d> axes(fit->shape);  // ascending
  out.a = axes.eigenvalues()(1);
  out.b = axes.eigenvalues()(0);
  if (!(out.b > 0)) return false;
  out.centre = fit->centre;
  // The major axis' angle in [pi / 2, 3 pi / 2): the direction cv::fitEllipseDirect gave before,
  // so that the elements' major directions keep their sign.
  const Eigen::Vector2d major = axes.eigenvectors().col(1);
  out.angle = std::atan2(major.y(), major.x());
  while (out.angle < 0.5 * std::numbers::pi) out.angle += std::numbers::pi;
  while (out.angle >= 1.5 * std::numbers::pi) out.angle -= std::numbers::pi;
  double sum = 0;
  for (const double residual : ellipseResiduals(out, pts)) sum += residual * residual;
  out.rms = std::sqrt(sum / static_cast<double>(pts.size()));
  out.used = pts.size();
  return true;
}
}  // namespace



bool fitEllipseRobust(const std::vector<Eigen::Vector2d>& plane, PlaneEllipse& e) {
  if (!fitEllipseOnce(plane, e)) return false;
  std::vector<double> res = ellipseResiduals(e, plane);
  for (double& r : res) r = std::abs(r);
  const double cut = std::max(3 * 1.4826 * median(res), 0.004);
  std::vector<Eigen::Vector2d> kept;
  for (std::size_t i = 0; i < plane.size(); ++i)
    if (res[i] <= cut) kept.push_back(plane[i]);
  return fitEllipseOnce(kept, e);
}

bool elementFromEllipse(const PlaneEllipse& e, double scale, const Eigen::Matrix3d& frame, const Vec3& origin,
                        const RingDetectionParams& params, GridElement& g) {
  const double r0 = params.printed_radius;
  g.semi_major = e.a * scale;
  g.semi_minor = e.b * scale;
  g.major_strain = std::log(g.semi_major / r0);
  g.minor_strain = std::log(g.semi_minor / r0);
  if (g.major_strain > params.max_strain || g.minor_strain < params.min_strain) return false;
  g.thickness_strain = -(g.major_strain + g.minor_strain);
  g.major_direction = (std::cos(e.angle) * frame.col(0) + std::sin(e.angle) * frame.col(1)).normalized();
  g.normal = frame.col(2);
  g.position = origin + e.centre.x() * frame.col(0) + e.centre.y() * frame.col(1);
  g.fit_rms = e.rms;
  g.edge_points = e.used;
  return true;
}

bool elementFromStretch(const Eigen::Matrix2d& B, const Eigen::Matrix3d& frame, const SquareDetectionParams& params,
                        GridElement& g) {
  const Eigen::SelfAdjointEigenSolver<Eigen::Matrix2d> eig(B);
  if (!(eig.eigenvalues()(0) > 0)) return false;
  g.major_strain = 0.5 * std::log(eig.eigenvalues()(1));
  g.minor_strain = 0.5 * std::log(eig.eigenvalues()(0));
  if (g.major_strain > params.max_strain || g.minor_strain < params.min_strain) return false;
  g.thickness_strain = -(g.major_strain + g.minor_strain);
  const Eigen::Vector2d d = eig.eigenvectors().col(1);
  g.major_direction = (d.x() * frame.col(0) + d.y() * frame.col(1)).normalized();
  g.semi_major = 0.5 * params.pitch * std::exp(g.major_strain);
  g.semi_minor = 0.5 * params.pitch * std::exp(g.minor_strain);
  g.normal = frame.col(2);
  return true;
}

}  // namespace stampscan::registration::detail
