// Internal to registration/: the centre line of a printed line in a camera image, found by fitting a
// model of the blurred line to the pixels around it.
//
// Why a model: a printed line 0.15 mm wide is only two or three pixels wide in the stereo images. A
// threshold (the half-level edge) moves with the blur and the contrast, and it moves the same way on
// both sides of a ring, so the ring grows or shrinks with the focus: about 1 % of its radius at the
// cameras' nominal blur, worse as it grows. The blurred line's profile across it is symmetric about
// its centre line whatever the blur, so a fit of that profile puts the line where it was printed.
//
// The model of the image near the line, at pixel x a signed distance d(x) from the centre line
// (for a ring, the affine image of a circle, d is exact on the curve and to first order off it):
//   I(x) = L(x) * (1 - k * P(d + s^2 c / 2)),  P(d) = Phi((d + w/2) / s) - Phi((d - w/2) / s)
// the sheet's level L (a plane over the patch: the ring light falls off), the ink's contrast k, the
// line's width w and its blur s (optics plus the pixel's own box); c is the line's curvature, for
// the blur draws a curved line's profile inwards by s^2 c / 2 (0.1 % of a ring's radius). A ring's line is the affine image
// of the printed annulus, so its width varies around it: w is the width at the ring's mean radius,
// scaled at each pixel. Levenberg-Marquardt over the geometry and the six photometric values, with
// Tukey weights so a speck or an undetected neighbour's line does not pull. The model must fit: the
// pixels a neighbour's line reaches are left out on one side only, and with a wrong profile that
// lopsided sample would move the line.
#pragma once

#include <Eigen/Core>
#include <opencv2/core.hpp>

#include <vector>

namespace stampscan::registration::detail {

// A ring's line in the image: the unit circle mapped by a symmetric positive definite M and moved to
// the centre (every ellipse is one; unlike axes and an angle, nothing degenerates for a circle),
// then moved along its normal by a third harmonic h(t) = a cos 3t + b sin 3t.
//
// Why the harmonic: a printed circle is an ellipse on the sheet only where the sheet is flat and
// strained evenly. Bent over a radius it leaves its plane, and a camera that sees it obliquely sees
// that as a third-harmonic wobble (the height varies as cos 2t, seen sideways: cos t cos 2t); a
// strain gradient across it does the same. On the pan's walls that is 0.1-0.2 px, and an ellipse
// fitted through it is off by about 0.7 % in either axis, differently in each camera.
struct ImageEllipse {
  Eigen::Vector2d centre = Eigen::Vector2d::Zero();
  Eigen::Matrix2d shape = Eigen::Matrix2d::Identity();  // M: x = centre + M (cos t, sin t)
  Eigen::Vector2d third = Eigen::Vector2d::Zero();      // (a, b) of h(t), px
  Eigen::Vector2d point(double t) const;
  // Signed distance of x from the curve, to first order (exact for a circle): positive outside.
  double distance(const Eigen::Vector2d& x) const;
  double meanRadius() const;  // sqrt(det M), of the ellipse
};

// A straight line in the image: the points x with normal . x = offset (normal of unit length).
struct ImageLine {
  Eigen::Vector2d normal = Eigen::Vector2d::UnitX();
  double offset = 0;
  double distance(const Eigen::Vector2d& x) const { return normal.dot(x) - offset; }
};

struct LineFitResult {
  bool ok = false;
  double blur = 0;       // s, px
  double contrast = 0;   // k
  double width = 0;      // w, px
  double rms = 0;        // of the weighted residuals, in units of the sheet level
  std::size_t pixels = 0, iterations = 0;
};

// Pixels within `reach` of any of these curves are left out of a fit: a neighbour's line that
// touches or runs alongside would pull the fitted line towards it.
struct Exclusions {
  std::vector<ImageEllipse> rings;
  std::vector<ImageLine> lines;
  double reach = 0;
};

// Refines `ring` (the line's centre, initially within about a pixel) in `image` (CV_32F). `line_px`
// is the printed line's expected width in pixels (a start: the fit finds it). Not ok when the fit
// fails, the line moves more than a pixel and a half, or the line is not there (no contrast).
LineFitResult fitRingLine(const cv::Mat& image, double line_px, const Exclusions& exclude, ImageEllipse& ring);

// Refines the straight line through the band of pixels within `half_length` of `mid` along it (a
// square grid's line between two nodes: keep the crossing lines at the nodes out of the band).
LineFitResult fitStraightLine(const cv::Mat& image, double line_px, const Eigen::Vector2d& mid, double half_length,
                              const Exclusions& exclude, ImageLine& line);

}  // namespace stampscan::registration::detail
