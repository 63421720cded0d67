#include "stampscan/registration/stereo_squares.hpp"

#include "image_line_fit.hpp"
#include "laser_raster.hpp"
#include "stereo_common.hpp"
#include "stampscan/fitting/quadric_patch.hpp"

#include <Eigen/Dense>
#include <opencv2/imgproc.hpp>
#include <tbb/parallel_for.h>

#include <algorithm>
#include <cmath>
#include <limits>
#include <optional>

namespace stampscan::registration {

namespace {

// Shoelace area of a closed polygon; positive when its points run counter-clockwise (x right, y up).
template <typename Points>
double signedArea(const Points& p) {
  double a = 0;
  for (std::size_t i = 0; i < p.size(); ++i) {
    const auto& u = p[i];
    const auto& v = p[(i + 1) % p.size()];
    a += u.x() * v.y() - v.x() * u.y();
  }
  return 0.5 * a;
}

// The deformation gradient F of a cell whose corners `q` (about their centroid) were printed at
// `square` (centred, sum s s^T = pitch^2 I): q = F s in the least-squares sense. `misfit`, when
// asked, is the corners' RMS distance from that affine image.
Eigen::Matrix2d deformationGradient(const std::array<Eigen::Vector2d, 4>& q, const std::array<Eigen::Vector2d, 4>& square,
                                    double pitch, double* misfit) {
  Eigen::Matrix2d F = Eigen::Matrix2d::Zero();
  for (std::size_t i = 0; i < 4; ++i) F += q[i] * square[i].transpose();
  F /= pitch * pitch;
  if (misfit) {
    double sum = 0;
    for (std::size_t i = 0; i < 4; ++i) sum += 0.25 * (q[i] - F * square[i]).squaredNorm();
    *misfit = std::sqrt(sum);
  }
  return F;
}

// The cell's centre from the nodes around it. The centroid of its four nodes is off the centre
// wherever the map from the blank to the part is not affine across the cell: towards the inside of
// a bend, and along a strain gradient (up to 0.05 mm on the pan's walls). The nodes within reach,
// put on the printed lattice through the cell's own F (their material offsets, in pitches, are
// odd halves), give that map to second order, X(s) = c + A s + s^T H s terms; its value at the
// printed centre is c. Empty when the nodes around do not pin the quadratic down.
std::optional<Vec3> centreOnLattice(const std::vector<Vec3>& nodes, const Vec3& centroid, const Eigen::Matrix3d& frame,
                                    const Eigen::Matrix2d& F, double pitch) {
  const Eigen::Matrix2d to_material = F.inverse() / pitch;
  Eigen::Matrix<double, 6, 6> normal = Eigen::Matrix<double, 6, 6>::Zero();
  Eigen::Matrix<double, 6, 3> rhs = Eigen::Matrix<double, 6, 3>::Zero();
  for (const Vec3& X : nodes) {
    if ((X - centroid).norm() > 2.3 * pitch) continue;
    const Vec3 local = frame.transpose() * (X - centroid);
    const Eigen::Vector2d s = to_material * local.head<2>();
    const Eigen::Vector2d lattice(std::round(s.x() - 0.5) + 0.5, std::round(s.y() - 0.5) + 0.5);
    if ((s - lattice).norm() > 0.25 || lattice.cwiseAbs().maxCoeff() > 1.6) continue;
    Eigen::Matrix<double, 6, 1> phi;
    phi << 1, lattice.x(), lattice.y(), lattice.x() * lattice.x(), lattice.x() * lattice.y(), lattice.y() * lattice.y();
    normal += phi * phi.transpose();
    rhs += phi * local.transpose();
  }
  const Eigen::ColPivHouseholderQR<Eigen::Matrix<double, 6, 6>> qr(normal);
  if (qr.rank() < 6) return std::nullopt;
  const Eigen::Matrix<double, 6, 3> coefficients = qr.solve(rhs);
  return centroid + frame * coefficients.row(0).transpose();
}

// The interior's outline as a quadrilateral: the coarsest polygon approximation with four corners.
std::optional<std::array<Eigen::Vector2d, 4>> quadrilateralOf(const std::vector<cv::Point>& hull) {
  const double perimeter = cv::arcLength(hull, true);
  for (double share = 0.01; share <= 0.1; share += 0.01) {
    std::vector<cv::Point> approx;
    cv::approxPolyDP(hull, approx, share * perimeter, true);
    if (approx.size() < 4) return std::nullopt;
    if (approx.size() == 4) {
      std::array<Eigen::Vector2d, 4> q;
      for (std::size_t i = 0; i < 4; ++i) q[i] = Eigen::Vector2d(approx[i].x, approx[i].y);
      return q;
    }
  }
  return std::nullopt;
}

std::optional<Eigen::Vector2d> intersect(const detail::ImageLine& a, const detail::ImageLine& b) {
  Eigen::Matrix2d A;
  A << a.normal.transpose(), b.normal.transpose();
  if (std::abs(A.determinant()) < 0.2) return std::nullopt;  // nearly parallel: not adjacent sides
  return A.inverse() * Eigen::Vector2d(a.offset, b.offset);
}

}  // namespace

std::vector<ImageCell> detectImageCells(const cv::Mat& image, double expected_pitch_px, const SquareDetectionParams& params) {
  cv::Mat I;
  image.convertTo(I, CV_32F);
  const double line_px = expected_pitch_px * params.line_width / params.pitch;
  const double side_px = expected_pitch_px - line_px;  // the interior's side before forming
  const std::vector<detail::ImageInterior> interiors =
      detail::findImageInteriors(I, side_px * side_px, line_px, params.ink_ratio, 0.85);
  std::vector<std::optional<ImageCell>> cells(interiors.size());
  tbb::parallel_for(std::size_t{0}, interiors.size(), [&](std::size_t k) {
    const detail::ImageInterior& in = interiors[k];
    const auto corners = quadrilateralOf(in.hull);
    if (!corners) return;
    // Each side's line: start from the interior's edge moved out by half the line, fit the model
    // to the middle 92 % of the interior's side (the crossing lines at the nodes begin at its
    // corners and stay out). On a cell foreshortened by a steep wall every pixel of the line counts:
    // the middle 60 % gave the pan's 60-degree walls 0.0081 thickness strain RMS, 92 % gives 0.0060
    // (the whole pan 0.0029 -> 0.0024, its floor a little better too).
    // A line's width in the image is the printed width times the cell's stretch across it: the
    // interior's area over the side's length. (On a cell foreshortened by a steep wall the sides
    // along the slope shrink while the lines across the slope narrow, and the other way round.)
    const double area = std::abs(signedArea(*corners));
    std::array<detail::ImageLine, 4> lines;
    double blur = 0;
    for (std::size_t i = 0; i < 4; ++i) {
      const Eigen::Vector2d a = (*corners)[i], b = (*corners)[(i + 1) % 4];
      const double length = (b - a).norm();
      if (length < 0.3 * side_px) return;
      const Eigen::Vector2d along = (b - a) / length;
      Eigen::Vector2d normal(-along.y(), along.x());
      const Eigen::Vector2d mid = 0.5 * (a + b);
      if (normal.dot(mid - in.centroid) < 0) normal = -normal;
      const double width = line_px * area / (side_px * length);
      const Eigen::Vector2d on_line = mid + (0.5 * width + 0.5) * normal;
      detail::ImageLine line{normal, normal.dot(on_line)};
      const detail::LineFitResult fit = detail::fitStraightLine(I, width, on_line, 0.46 * length, {}, line);
      if (!fit.ok) return;
      lines[i] = line;
      blur += 0.25 * fit.blur;
    }
    ImageCell cell;
    for (std::size_t i = 0; i < 4; ++i) {
      const auto node = intersect(lines[(i + 3) % 4], lines[i]);  // the corner between side i-1 and side i
      if (!node || (*node - (*corners)[i]).norm() > 0.3 * side_px) return;
      cell.nodes[i] = *node;
      cell.centre += 0.25 * *node;
    }
    cell.blur = blur;
    cells[k] = cell;
  });
  std::vector<ImageCell> out;
  for (auto& c : cells)
    if (c) out.push_back(*c);
  return out;
}

namespace {

// The printed square's corners about its centre, counter-clockwise.
std::array<Eigen::Vector2d, 4> printedSquare(double pitch) {
  const double half = 0.5 * pitch;
  return {Eigen::Vector2d(-half, -half), Eigen::Vector2d(half, -half), Eigen::Vector2d(half, half),
          Eigen::Vector2d(-half, half)};
}

// A matched cell's four nodes in the machine frame. Both images go round the cell the same way, so
// the same node is one of the four cyclic shifts: the one whose rays meet best, within 0.2 mm for
// its worst node. Nothing when none does.
std::optional<std::array<Vec3, 4>> triangulateNodes(const ImageCell& L, const ImageCell& R, const StereoRig& rig,
                                                    const detail::PairPoses& poses) {
  const std::vector<Eigen::Vector2d> ln = detail::normalised(std::vector<Eigen::Vector2d>(L.nodes.begin(), L.nodes.end()), rig.left);
  const std::vector<Eigen::Vector2d> rn = detail::normalised(std::vector<Eigen::Vector2d>(R.nodes.begin(), R.nodes.end()), rig.right);
  const Vec3 o1 = poses.machine_from_left.translation(), o2 = poses.machine_from_right.translation();
  std::optional<std::array<Vec3, 4>> nodes;
  double best_gap = 0.2;  // mm, for the worst node
  for (std::size_t shift = 0; shift < 4; ++shift) {
    std::array<Vec3, 4> X;
    double worst = 0;
    for (std::size_t i = 0; i < 4; ++i) {
      const Vec3 d1 = (poses.machine_from_left.linear() * Vec3(ln[i].x(), ln[i].y(), 1)).normalized();
      const std::size_t j = (i + shift) % 4;
      const Vec3 d2 = (poses.machine_from_right.linear() * Vec3(rn[j].x(), rn[j].y(), 1)).normalized();
      double gap = 0;
      X[i] = detail::midpoint(o1, d1, o2, d2, &gap);
      worst = std::max(worst, gap);
    }
    if (worst < best_gap) best_gap = worst, nodes = X;
  }
  return nodes;
}

// The element of a cell from its four nodes: the cell's plane through its corners (normal from the
// diagonals, facing the cameras), the corners in it about their mean (`corners`), and the strain of
// the deformation gradient that takes the printed square onto them. Nothing for a twisted cell or
// one that is no parallelogram.
std::optional<GridElement> cellElement(const std::array<Vec3, 4>& nodes, const Vec3& eyes, const SquareDetectionParams& params,
                                       std::array<Eigen::Vector2d, 4>& corners) {
  Vec3 centre = Vec3::Zero();
  for (const Vec3& X : nodes) centre += 0.25 * X;
  Vec3 normal = (nodes[2] - nodes[0]).cross(nodes[3] - nodes[1]).normalized();
  if (normal.dot(eyes - centre) < 0) normal = -normal;
  const Eigen::Matrix3d frame = fitting::frameAround(normal);
  // Four corners of a cell on a smooth sheet lie nearly in a plane; a cell twisted over a doubly
  // curved corner, or a wrong match, does not.
  double twist = 0;
  for (const Vec3& X : nodes) twist = std::max(twist, std::abs(normal.dot(X - centre)));
  if (twist > 0.1) return std::nullopt;
  std::array<Eigen::Vector2d, 4> q;
  for (std::size_t i = 0; i < 4; ++i) q[i] = {frame.col(0).dot(nodes[i] - centre), frame.col(1).dot(nodes[i] - centre)};
  if (signedArea(q) < 0) std::swap(q[1], q[3]);  // the same cycle, run the other way
  Eigen::Vector2d t = Eigen::Vector2d::Zero();
  for (const auto& x : q) t += 0.25 * x;
  for (auto& x : q) x -= t;
  double misfit = 0;
  const Eigen::Matrix2d F = deformationGradient(q, printedSquare(params.pitch), params.pitch, &misfit);
  GridElement g;
  if (misfit > 0.03 || !detail::elementFromStretch(F * F.transpose(), frame, params, g)) return std::nullopt;
  g.position = centre + t.x() * frame.col(0) + t.y() * frame.col(1);
  g.fit_rms = misfit;
  corners = q;
  return g;
}

// The four nodes span a chord plane: where the sheet bends, the cell's centre on the surface lies
// off it (0.03 mm on a 60 mm dome, 0.4 mm over a 4 mm punch radius), and its sides are arcs longer
// than the chords between the nodes (1 % over a 5 mm radius). A quadric height field through the
// nodes of the cell and its neighbours gives the surface there and its curvature. False when the
// cell does not sit with its neighbours.
bool bendOntoSurface(GridElement& g, const std::array<Eigen::Vector2d, 4>& corners, const std::vector<Vec3>& all_nodes,
                     const SquareDetectionParams& params) {
  fitting::QuadricPatch::Sums sums(fitting::frameAround(g.normal), g.position, params.pitch);
  for (const Vec3& X : all_nodes)
    if ((X - g.position).norm() < 2.3 * params.pitch) sums.add(X, 1.0);
  if (sums.count() < 12) return true;  // too few neighbours to tell: the chord plane's element stands
  const auto patch = fitting::QuadricPatch::fit(sums);
  const double offset = patch ? patch->heightAtOrigin() : std::numeric_limits<double>::quiet_NaN();
  // Over a 4 mm punch radius the offset is about 0.25 mm; more means the cell does not sit with its
  // neighbours (a wrong match, or a cell over a doubly curved corner): no element.
  if (!std::isfinite(offset) || std::abs(offset) > 0.3) return false;
  const auto square = printedSquare(params.pitch);
  const Eigen::Matrix3d frame = fitting::frameAround(g.normal);
  const std::optional<Vec3> centre =
      centreOnLattice(all_nodes, g.position, frame, deformationGradient(corners, square, params.pitch, nullptr), params.pitch);
  g.position = centre ? *centre : Vec3(g.position + offset * g.normal);
  // Each node's distance from the centre as the arc of the normal section through it.
  const Eigen::Matrix2d K = patch->hessianAtOrigin();
  std::array<Eigen::Vector2d, 4> arcs = corners;
  for (auto& x : arcs) x = detail::chordToArc(x, K);
  const Eigen::Matrix2d F = deformationGradient(arcs, square, params.pitch, nullptr);
  GridElement bent = g;
  if (!detail::elementFromStretch(F * F.transpose(), frame, params, bent)) return false;
  g = bent;
  return true;
}

}  // namespace

StereoCellImages detectStereoCells(const cv::Mat& left, const cv::Mat& right, double expected_pitch_px,
                                   const SquareDetectionParams& params) {
  auto [l, r] = detail::detectInBoth(
      left, right, [&](const cv::Mat& image) { return detectImageCells(image, expected_pitch_px, params); });
  return {std::move(l), std::move(r)};
}

std::vector<GridElement> measureStereoSquares(const StereoCellImages& found, const StereoViewPose& input,
                                              const SquareDetectionParams& params, StereoStats* stats) {
  StereoStats local;
  StereoStats& st = stats ? *stats : local;
  const StereoRig& rig = input.rig;
  const detail::PairPoses poses = detail::pairPoses(rig, input.machine_from_head, input.prior);
  if (poses.prior_depth <= 0) return {};
  const double pitch_px = pixelsAtDepth(rig, params.pitch, poses.prior_depth);
  // Matched within half a pitch, as for rings.
  const std::vector<ImageCell>& left = found.left;
  const std::vector<ImageCell>& right = found.right;
  const std::vector<detail::StereoMatch> matches = detail::matchFound(left, right, rig, poses, input.prior, 0.5 * pitch_px, st);

  const Vec3 eyes = 0.5 * (poses.machine_from_left.translation() + poses.machine_from_right.translation());
  std::vector<GridElement> out;
  std::vector<std::array<Eigen::Vector2d, 4>> corners;  // each element's nodes about its centre, in its plane
  std::vector<Vec3> all_nodes;      // every cell's triangulated nodes, for the surface at each centre
  for (const detail::StereoMatch& m : matches) {
    const std::optional<std::array<Vec3, 4>> nodes = triangulateNodes(left[m.left], right[m.right], rig, poses);
    std::array<Eigen::Vector2d, 4> q;
    std::optional<GridElement> g = nodes ? cellElement(*nodes, eyes, params, q) : std::nullopt;
    if (!g) {
      ++st.rejected_fit;
      continue;
    }
    g->edge_points = 8;  // two images' four nodes
    g->source = Source::Stereo;
    g->view = input.index;
    // F from four corners half a pitch out on each axis: a quadratic strain along a side enters as
    // (pitch / 2)^2 / 6, across it as (pitch / 2)^2 / 2; their mean for a cell however it is turned.
    g->gauge_mm2 = params.pitch * params.pitch / 12;
    out.push_back(*g);
    corners.push_back(q);
    all_nodes.insert(all_nodes.end(), nodes->begin(), nodes->end());
    ++st.matched;
  }
  std::vector<GridElement> kept;
  for (std::size_t k = 0; k < out.size(); ++k) {
    if (bendOntoSurface(out[k], corners[k], all_nodes, params)) kept.push_back(out[k]);
    else --st.matched, ++st.rejected_fit;
  }
  return kept;
}

}  // namespace stampscan::registration
