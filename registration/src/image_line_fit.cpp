#include "image_line_fit.hpp"

#include "stampscan/fitting/median.hpp"

#include <Eigen/Dense>

#include <algorithm>
#include <array>
#include <cmath>
#include <limits>
#include <numbers>

namespace stampscan::registration::detail {

Eigen::Vector2d ImageEllipse::point(double t) const {
  const Eigen::Vector2d u(std::cos(t), std::sin(t));
  const double h = third.x() * std::cos(3 * t) + third.y() * std::sin(3 * t);
  if (h == 0) return centre + shape * u;
  // The outward normal at parameter t is along M^-1 u (M is symmetric).
  return centre + shape * u + h * (shape.inverse() * u).normalized();
}

namespace {
// The signed distance from an ellipse, with M^-1 given (a pixel loop asks it of the same ellipse
// thousands of times). rho = |M^-1 (x - c)| is 1 on the curve; dividing rho - 1 by its gradient's
// length turns it into a distance with unit slope across the curve.
double ellipseDistance(const ImageEllipse& e, const Eigen::Matrix2d& inverse, const Eigen::Vector2d& x) {
  const Eigen::Vector2d u = inverse * (x - e.centre);
  const double rho = u.norm();
  if (rho < 1e-9) return -e.meanRadius();
  const double slope = (inverse * u).norm() / rho;
  const double ct = u.x() / rho, st = u.y() / rho;  // of t, u's angle
  return (rho - 1) / slope - e.third.x() * ct * (4 * ct * ct - 3) - e.third.y() * st * (3 - 4 * st * st);
}
}  // namespace

double ImageEllipse::distance(const Eigen::Vector2d& x) const { return ellipseDistance(*this, shape.inverse(), x); }

double ImageEllipse::meanRadius() const { return std::sqrt(std::max(0.0, shape.determinant())); }

namespace {

// Where a pixel lies against the line: its signed distance d from the centre line (positive
// outside), the line's width there against its mean, and the line's curvature there (1/px).
//
// The curvature matters because the blur bends the profile: a thin ring of radius R blurred by a
// Gaussian of width s is darkest not on the ring but s^2 / (2 R) inside it (its profile across is
// the Gaussian times 1 / sqrt(rho), the 2D spread of a curved line). At the cameras' blur that is
// 0.1 % of the ring, all one way, so the model's profile is centred there: P(d + s^2 curvature / 2).
struct Where {
  double d = 0, width_scale = 1, curvature = 0;
};

// The geometry the fit moves: a parameter vector, and where a pixel lies against the line.
struct RingGeometry {
  static constexpr int N = 7;  // centre x, y; M11, M12, M22; the third harmonic's a, b
  ImageEllipse e;
  Eigen::Matrix2d inverse = e.shape.inverse();
  double det = 0, mean = 0;  // of the shape, the same for every pixel
  explicit RingGeometry(const ImageEllipse& ellipse) : e(ellipse) { prepare(); }
  std::array<double, N> get() const {
    return {e.centre.x(), e.centre.y(), e.shape(0, 0), e.shape(0, 1), e.shape(1, 1), e.third.x(), e.third.y()};
  }
  void set(const std::array<double, N>& p) {
    e.centre = {p[0], p[1]};
    e.shape << p[2], p[3], p[3], p[4];
    e.third = {p[5], p[6]};
    prepare();
  }
  void prepare() {
    inverse = e.shape.inverse();
    det = e.shape.determinant();
    mean = e.meanRadius();
    inverse2 = inverse * inverse;
    for (int k = 0; k < 3; ++k) {  // M11, M12 (both off-diagonal entries), M22
      Eigen::Matrix2d E = Eigen::Matrix2d::Zero();
      if (k == 0) E(0, 0) = 1;
      else if (k == 1) E(0, 1) = E(1, 0) = 1;
      else E(1, 1) = 1;
      inverse_E[k] = inverse * E;
      inverse2_E[k] = inverse2 * E;
      half_trace_inverse_E[k] = 0.5 * inverse_E[k].trace();
    }
  }
  // The same for every pixel, so made once per parameter vector: A^2, and A E and A^2 E for each
  // shape entry's unit change E (the slopes below).
  Eigen::Matrix2d inverse2 = Eigen::Matrix2d::Zero();
  std::array<Eigen::Matrix2d, 3> inverse_E{}, inverse2_E{};
  std::array<double, 3> half_trace_inverse_E{};
  // The signed distance d, and how wide the line is there against the ring's mean (an affine image of
  // the printed annulus is widest across the major axis's ends), with their slopes in the
  // parameters when asked. With A = M^-1, u = A (x - c), rho = |u|, v = A u, g = |v| / rho:
  // d = (rho - 1) / g - h(t), t = atan2(u), width_scale = 1 / (g sqrt(det M)). The harmonic's
  // dependence on t is left out of the ellipse's slopes: h is a fraction of a pixel, and t moves
  // with the centre by 1 / radius, so the slopes it adds are a few per cent of theirs.
  void locate(const Eigen::Vector2d& x, Where& at, double* dd = nullptr, double* dscale = nullptr) const {
    const Eigen::Vector2d u = inverse * (x - e.centre);
    const double rho = std::max(1e-9, u.norm());
    const Eigen::Vector2d v = inverse * u;
    const double vn = std::max(1e-12, v.norm());
    const double g = vn / rho;
    // t is u's angle; cos 3t and sin 3t from its cosine and sine, without trigonometry.
    const double ct = u.x() / rho, st = u.y() / rho;
    const double c3 = ct * (4 * ct * ct - 3), s3 = st * (3 - 4 * st * st);
    at.d = (rho - 1) / g - e.third.x() * c3 - e.third.y() * s3;
    at.width_scale = 1 / (g * mean);
    // The ellipse's curvature at t: det M / |M u'(t)|^3.
    const double speed = (e.shape * Eigen::Vector2d(-st, ct)).norm();
    at.curvature = det / std::max(1e-9, speed * speed * speed);
    const double width_scale = at.width_scale;
    if (!dd) return;
    dd[5] = -c3;
    dd[6] = -s3;
    dscale[5] = dscale[6] = 0;
    // The same divisions in every slope, made once.
    const double inv_rho = 1 / rho, inv_vn = 1 / vn, inv_g = 1 / g, dd_dg = -(rho - 1) * inv_g * inv_g;
    const auto slopes = [&](const Eigen::Vector2d& du, const Eigen::Vector2d& dv, double dlog_mean, int k) {
      const double drho = u.dot(du) * inv_rho;
      const double dg = (v.dot(dv) * inv_vn - g * drho) * inv_rho;
      dd[k] = drho * inv_g + dd_dg * dg;
      dscale[k] = -width_scale * (dg * inv_g + dlog_mean);
    };
    for (int k = 0; k < 2; ++k) {  // the centre: du = -A e_k, dv = -A^2 e_k
      slopes(-inverse.col(k), -inverse2.col(k), 0.0, k);
    }
    for (int k = 0; k < 3; ++k) {  // M11, M12 (both off-diagonal entries), M22: dA = -A E A
      const Eigen::Vector2d du = -(inverse_E[k] * u);
      const Eigen::Vector2d dv = -(inverse_E[k] * v) - inverse2_E[k] * u;
      slopes(du, dv, half_trace_inverse_E[k], 2 + k);
    }
  }
  bool plausible() const {
    return e.shape.determinant() > 0 && e.shape.trace() > 0 && e.third.norm() < 0.1 * e.meanRadius();
  }
};

struct StraightGeometry {
  static constexpr int N = 2;  // angle of the normal; offset from the anchor, a point near the line
  ImageLine l;
  Eigen::Vector2d anchor = Eigen::Vector2d::Zero();
  std::array<double, N> get() const { return {std::atan2(l.normal.y(), l.normal.x()), l.offset - l.normal.dot(anchor)}; }
  void set(const std::array<double, N>& p) {
    l.normal = {std::cos(p[0]), std::sin(p[0])};
    l.offset = p[1] + l.normal.dot(anchor);
  }
  void locate(const Eigen::Vector2d& x, Where& at, double* dd = nullptr, double* dscale = nullptr) const {
    at.d = l.distance(x);
    at.width_scale = 1;
    at.curvature = 0;
    if (!dd) return;
    const Eigen::Vector2d r = x - anchor;
    dd[0] = -l.normal.y() * r.x() + l.normal.x() * r.y();
    dd[1] = -1;
    dscale[0] = dscale[1] = 0;
  }
  bool plausible() const { return true; }
};

struct Sample {
  Eigen::Vector2d x;
  double value;
};

// The standard normal's density and distribution function at z from one exponential: the
// distribution by Abramowitz & Stegun 26.2.17, the density times a polynomial in 1 / (1 + p |z|),
// within 7.5e-8 everywhere. A model value then errs by a ten-millionth of the ink's contrast, far
// below one grey level; std::erfc took a tenth of the stereo views' measurement.
struct Normal {
  double cdf, pdf;
};
Normal normalAt(double z) {
  const double pdf = 0.3989422804014327 * std::exp(-0.5 * z * z);
  const double t = 1 / (1 + 0.2316419 * std::abs(z));
  const double tail =
      pdf * t * (0.319381530 + t * (-0.356563782 + t * (1.781477937 + t * (-1.821255978 + t * 1.330274429))));
  return {z >= 0 ? 1 - tail : tail, pdf};
}
double cdf(double z) { return normalAt(z).cdf; }

// Squared radii from an ellipse's centre within which, and beyond which, ellipseDistance is at
// least `reach` in size, so that a pixel there needs no call. With semi-axes a1 >= a2 and u = M^-1
// (x - c): |x - c| / a1 <= |u| <= |x - c| / a2, and the distance's slope lies in [1 / a1, 1 / a2];
// the third harmonic moves it by at most |a| + |b|.
struct ClearOfEllipse {
  double inside_sq = -1, outside_sq = 0;
  ClearOfEllipse(const ImageEllipse& e, double reach) {
    const Eigen::Vector2d axes = Eigen::SelfAdjointEigenSolver<Eigen::Matrix2d>(e.shape).eigenvalues();
    const double a2 = axes.minCoeff(), a1 = axes.maxCoeff();
    const double margin = reach + std::abs(e.third.x()) + std::abs(e.third.y());
    if (!(a2 > 0)) {
      outside_sq = std::numeric_limits<double>::infinity();  // a degenerate shape: always asked
      return;
    }
    const double inside = a2 - margin, outside = a1 * (1 + margin / a2);
    inside_sq = inside > 0 ? inside * inside : -1;
    outside_sq = outside * outside;
  }
  bool clear(const ImageEllipse& e, const Eigen::Vector2d& x) const {
    const double r2 = (x - e.centre).squaredNorm();
    return r2 < inside_sq || r2 > outside_sq;
  }
};

// The exclusions with their rings' inverse shapes, made once per fit.
struct PreparedExclusions {
  const Exclusions& ex;
  std::vector<Eigen::Matrix2d> inverses;
  std::vector<ClearOfEllipse> clear;
  explicit PreparedExclusions(const Exclusions& e) : ex(e) {
    for (const auto& r : e.rings) {
      inverses.push_back(r.shape.inverse());
      clear.emplace_back(r, e.reach);
    }
  }
};

bool excluded(const Eigen::Vector2d& x, const PreparedExclusions& prepared) {
  const Exclusions& ex = prepared.ex;
  for (std::size_t k = 0; k < ex.rings.size(); ++k)
    if (!prepared.clear[k].clear(ex.rings[k], x) && std::abs(ellipseDistance(ex.rings[k], prepared.inverses[k], x)) < ex.reach)
      return true;
  for (const auto& l : ex.lines)
    if (std::abs(l.distance(x)) < ex.reach) return true;
  return false;
}

// The model of a printed line in the pixels, and its parts of the fit: the sheet's plane (l0, lx,
// ly), the ink's contrast k, the blur s and the line's width w beside the geometry's parameters.
template <typename Geometry>
class LineModel {
 public:
  static constexpr int G = Geometry::N, P = G + 6;
  static constexpr int L0 = G, LX = G + 1, LY = G + 2, K = G + 3, S = G + 4, W = G + 5;
  using Vector = Eigen::Matrix<double, P, 1>;
  using Matrix = Eigen::Matrix<double, P, P>;

  LineModel(const std::vector<Sample>& samples, double line_px, const Eigen::Vector2d& origin, double scale)
      : samples_(samples), line_px_(line_px), origin_(origin), scale_(scale), weight_(samples.size(), 1.0) {}

  // The start: the sheet from pixels clear of the line, the contrast from those on it. False when
  // either are too few, or the sheet is dark.
  bool start(const Geometry& geometry, Vector& p) const {
    const double s0 = 0.8;
    std::vector<double> sheet, ink;
    for (const Sample& q : samples_) {
      Where at;
      geometry.locate(q.x, at);
      if (std::abs(at.d) > 0.5 * line_px_ * at.width_scale + 2.5 * s0) sheet.push_back(q.value);
      else if (std::abs(at.d) < 0.25 * line_px_ * at.width_scale) ink.push_back(q.value);
    }
    if (sheet.size() < 8 || ink.size() < 4) return false;
    const double level = fitting::medianOr(sheet, 0.0);
    if (level <= 0) return false;
    const double peak = cdf(0.5 * line_px_ / s0) - cdf(-0.5 * line_px_ / s0);
    const auto g = geometry.get();
    for (int i = 0; i < G; ++i) p(i) = g[static_cast<std::size_t>(i)];
    p.template tail<6>() << level, 0, 0, std::clamp((1 - fitting::medianOr(ink, 0.0) / level) / peak, 0.05, 1.0), s0, line_px_;
    return true;
  }

  // Where a sample lies under a parameter vector, the geometry's slopes there, and the line
  // profile's edges: what the residual needs, and all the normal equations need at an accepted
  // step (so that a step costs one pass over the pixels, not two).
  struct Located {
    Where at;
    double dd[G], dscale[G];
    Normal outer, inner;  // at (d +- half width) / blur
  };

  // The residuals of every sample under q (the geometry set to q's), and where each lies.
  void evaluate(const Vector& q, Geometry& geom, std::vector<double>& residual, std::vector<Located>& located) const {
    std::array<double, G> g;
    for (int i = 0; i < G; ++i) g[static_cast<std::size_t>(i)] = q(i);
    geom.set(g);
    residual.resize(samples_.size());
    located.resize(samples_.size());
    for (std::size_t i = 0; i < samples_.size(); ++i) {
      Located& l = located[i];
      geom.locate(samples_[i].x, l.at, l.dd, l.dscale);
      const Eigen::Vector2d r = (samples_[i].x - origin_) / scale_;
      const double sheet_level = q(L0) + q(LX) * r.x() + q(LY) * r.y();
      const double half = 0.5 * q(W) * l.at.width_scale;
      const double d = l.at.d + 0.5 * q(S) * q(S) * l.at.curvature;  // see Where::curvature
      l.outer = normalAt((d + half) / q(S));
      l.inner = normalAt((d - half) / q(S));
      residual[i] = samples_[i].value - sheet_level * (1 - q(K) * (l.outer.cdf - l.inner.cdf));
    }
  }

  // Tukey's biweight of each residual against its robust spread.
  void reweigh(const std::vector<double>& r, double level) {
    std::vector<double> a(r.size());
    for (std::size_t i = 0; i < r.size(); ++i) a[i] = std::abs(r[i]);
    const double c = 4.685 * std::max(1e-6 * level, 1.4826 * fitting::medianOr(a, 0.0));
    for (std::size_t i = 0; i < r.size(); ++i) {
      const double u = r[i] / c;
      weight_[i] = std::abs(u) < 1 ? (1 - u * u) * (1 - u * u) : 0.0;
    }
  }

  double cost(const std::vector<double>& r) const {
    double c = 0;
    for (std::size_t i = 0; i < r.size(); ++i) c += weight_[i] * r[i] * r[i];
    return c;
  }

  // The weighted normal equations H delta = b at p, from where evaluate(p) located the samples.
  // The Jacobian: the model's slopes in the distance and the local width, times their slopes in
  // the geometry; and in the photometry.
  void normalEquations(const Vector& p, const std::vector<double>& residual, const std::vector<Located>& located,
                       Matrix& H, Vector& b) const {
    H.setZero();
    b.setZero();
    for (std::size_t i = 0; i < samples_.size(); ++i) {
      if (weight_[i] <= 0) continue;
      const Eigen::Vector2d r = (samples_[i].x - origin_) / scale_;
      const Located& l = located[i];
      const Where& at = l.at;
      const double half = 0.5 * p(W) * at.width_scale;
      const double d = at.d + 0.5 * p(S) * p(S) * at.curvature;
      const double zp = (d + half) / p(S), zm = (d - half) / p(S);
      const Normal& np = l.outer;
      const Normal& nm = l.inner;
      const double cover = np.cdf - nm.cdf;
      const double sheet_level = p(L0) + p(LX) * r.x() + p(LY) * r.y();
      const double dm_dcover = -sheet_level * p(K);
      const double dm_dd = dm_dcover * (np.pdf - nm.pdf) / p(S);
      const double dm_dhalf = dm_dcover * (np.pdf + nm.pdf) / p(S);
      Vector J;
      for (int j = 0; j < G; ++j) J(j) = dm_dd * l.dd[j] + dm_dhalf * 0.5 * p(W) * l.dscale[j];
      const double shade = 1 - p(K) * cover;
      J(L0) = shade;
      J(LX) = shade * r.x();
      J(LY) = shade * r.y();
      J(K) = -sheet_level * cover;
      J(S) = -dm_dcover * (zp * np.pdf - zm * nm.pdf) / p(S) + dm_dd * p(S) * at.curvature;
      J(W) = dm_dhalf * 0.5 * at.width_scale;
      // The lower triangle, column by column (Eigen's rank update of a fixed 13 x 13 triangle runs
      // element by element).
      const Vector weighted = weight_[i] * J;
      for (int k = 0; k < P; ++k) H.col(k).tail(P - k) += J(k) * weighted.tail(P - k);
      b += residual[i] * weighted;
    }
    H.template triangularView<Eigen::StrictlyUpper>() = H.transpose();
  }

  // A step's parameters within what a printed line can be.
  bool plausible(const Vector& q) const {
    return q(S) >= 0.15 && q(S) <= 4 && q(K) > 0 && q(W) >= 0.2 && q(W) <= 4 * line_px_ + 2;
  }

  const std::vector<double>& weights() const { return weight_; }

 private:
  const std::vector<Sample>& samples_;
  double line_px_;
  Eigen::Vector2d origin_;
  double scale_;
  std::vector<double> weight_;
};

// Levenberg-Marquardt over the geometry and the photometry (LineModel), reweighted robustly after
// each accepted step.
template <typename Geometry>
LineFitResult fitModel(const std::vector<Sample>& samples, double line_px, const Eigen::Vector2d& origin, double scale,
                       Geometry& geometry) {
  using Model = LineModel<Geometry>;
  constexpr int G = Model::G, P = Model::P;
  LineFitResult result;
  result.pixels = samples.size();
  if (samples.size() < 12 * static_cast<std::size_t>(P)) return result;
  Model fit(samples, line_px, origin, scale);
  typename Model::Vector p;
  if (!fit.start(geometry, p)) return result;
  std::vector<double> residual, trial;
  std::vector<typename Model::Located> located, trial_located;
  Geometry geom = geometry;
  fit.evaluate(p, geom, residual, located);
  fit.reweigh(residual, p(Model::L0));
  double lambda = 1e-3;
  const std::array<double, G> g0 = geometry.get();
  for (int iteration = 0; iteration < 30; ++iteration) {
    result.iterations = static_cast<std::size_t>(iteration + 1);
    typename Model::Matrix H;
    typename Model::Vector b, delta;
    fit.normalEquations(p, residual, located, H, b);
    const double before = fit.cost(residual);
    bool improved = false;
    for (int attempt = 0; attempt < 8 && !improved; ++attempt) {
      typename Model::Matrix A = H;
      for (int j = 0; j < P; ++j) A(j, j) += lambda * (H(j, j) + 1e-9);
      delta = A.ldlt().solve(b);
      const typename Model::Vector q = p + delta;
      if (!delta.allFinite() || !fit.plausible(q)) {
        lambda *= 4;
        continue;
      }
      Geometry candidate = geom;
      fit.evaluate(q, candidate, trial, trial_located);
      if (candidate.plausible() && fit.cost(trial) <= before) {
        p = q;
        geom = candidate;
        residual.swap(trial);
        located.swap(trial_located);
        improved = true;
        lambda = std::max(1e-7, lambda / 3);
      } else {
        lambda *= 4;
      }
    }
    if (!improved) break;
    fit.reweigh(residual, p(Model::L0));
    // A thousandth of a pixel: a strain of 1e-4 moves a 20 px ring's axes by 0.002 px, and the step
    // after this one would be smaller still. (2e-4 took 5.7 rounds a ring instead of 4.3 and changed
    // no measured strain's RMS against the truth.)
    if (delta.template head<G>().cwiseAbs().maxCoeff() < 1e-3) break;
  }
  const std::array<double, G> g1 = geom.get();
  double moved = 0;
  for (std::size_t j = 0; j < static_cast<std::size_t>(G); ++j) moved = std::max(moved, std::abs(g1[j] - g0[j]));
  double sum = 0, wsum = 0;
  const std::vector<double>& weight = fit.weights();
  for (std::size_t i = 0; i < samples.size(); ++i) sum += weight[i] * residual[i] * residual[i], wsum += weight[i];
  result.blur = p(Model::S);
  result.contrast = p(Model::K);
  result.width = p(Model::W);
  result.rms = wsum > 0 ? std::sqrt(sum / wsum) / p(Model::L0) : 1.0;
  // The line must really be there: some contrast, most pixels agreeing with the model.
  result.ok = std::isfinite(moved) && p(Model::K) > 0.1 && wsum > 0.5 * static_cast<double>(samples.size());
  if (result.ok) geometry = geom;
  return result;
}

cv::Rect clampRect(const cv::Mat& image, double x0, double y0, double x1, double y1) {
  const int c0 = std::max(0, static_cast<int>(std::floor(x0))), r0 = std::max(0, static_cast<int>(std::floor(y0)));
  const int c1 = std::min(image.cols - 1, static_cast<int>(std::ceil(x1))), r1 = std::min(image.rows - 1, static_cast<int>(std::ceil(y1)));
  return {c0, r0, std::max(0, c1 - c0 + 1), std::max(0, r1 - r0 + 1)};
}

// How far from the line the model needs pixels: the line, its blur, and some sheet on both sides.
double bandHalfWidth(double line_px) { return 0.5 * line_px + 4.0; }

}  // namespace

LineFitResult fitRingLine(const cv::Mat& image, double line_px, const Exclusions& exclude, ImageEllipse& ring) {
  const double band = bandHalfWidth(line_px);
  const Eigen::SelfAdjointEigenSolver<Eigen::Matrix2d> eig(ring.shape);
  const double reach = eig.eigenvalues().cwiseAbs().maxCoeff() + band + 1;
  const cv::Rect box = clampRect(image, ring.centre.x() - reach, ring.centre.y() - reach, ring.centre.x() + reach,
                                 ring.centre.y() + reach);
  std::vector<Sample> samples;
  const PreparedExclusions exclusions(exclude);
  const Eigen::Matrix2d ring_inverse = ring.shape.inverse();
  const ClearOfEllipse off_band(ring, band);
  for (int r = box.y; r < box.y + box.height; ++r)
    for (int c = box.x; c < box.x + box.width; ++c) {
      const Eigen::Vector2d x(c, r);
      if (off_band.clear(ring, x) || std::abs(ellipseDistance(ring, ring_inverse, x)) > band || excluded(x, exclusions)) continue;
      samples.push_back({x, image.at<float>(r, c)});
    }
  RingGeometry geometry(ring);
  const ImageEllipse start = ring;
  LineFitResult fit = fitModel(samples, line_px, ring.centre, std::max(1.0, ring.meanRadius()), geometry);
  if (!fit.ok) return fit;
  const double moved = (geometry.e.centre - start.centre).norm();
  const double grew = std::abs(geometry.e.meanRadius() - start.meanRadius());
  if (moved > 1.5 || grew > 1.5) {
    fit.ok = false;
    return fit;
  }
  ring = geometry.e;
  return fit;
}

LineFitResult fitStraightLine(const cv::Mat& image, double line_px, const Eigen::Vector2d& mid, double half_length,
                              const Exclusions& exclude, ImageLine& line) {
  const double band = bandHalfWidth(line_px);
  const Eigen::Vector2d along(-line.normal.y(), line.normal.x());
  const double reach = half_length + band + 1;
  const cv::Rect box = clampRect(image, mid.x() - reach, mid.y() - reach, mid.x() + reach, mid.y() + reach);
  std::vector<Sample> samples;
  const PreparedExclusions exclusions(exclude);
  for (int r = box.y; r < box.y + box.height; ++r)
    for (int c = box.x; c < box.x + box.width; ++c) {
      const Eigen::Vector2d x(c, r);
      if (std::abs(line.distance(x)) > band || std::abs(along.dot(x - mid)) > half_length || excluded(x, exclusions)) continue;
      samples.push_back({x, image.at<float>(r, c)});
    }
  StraightGeometry geometry{line, mid};
  const ImageLine start = line;
  LineFitResult fit = fitModel(samples, line_px, mid, std::max(1.0, half_length), geometry);
  if (!fit.ok) return fit;
  if (std::abs(geometry.l.distance(mid) - start.distance(mid)) > 1.5 || geometry.l.normal.dot(start.normal) < 0.98) {
    fit.ok = false;
    return fit;
  }
  line = geometry.l;
  return fit;
}

}  // namespace stampscan::registration::detail
