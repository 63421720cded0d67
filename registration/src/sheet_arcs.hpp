// Internal to registration/: distances on a curved sheet from their tangent-plane chords, shared by
// the laser and the stereo paths. A printed element's axes are lengths on the sheet; measured in a
// plane they come out short where the sheet bends, and its strains with them.
#pragma once

#include <Eigen/Core>


namespace stampscan::registration::detail {

// A point on a curved sheet w = u^T K u / 2, given by its tangent-plane offset `u` from the centre
// where the sheet's second derivatives are K (`curvature`, 1/mm), in the sheet's own coordinates:
// its geodesic polar coordinates there, the distance along the sheet in the direction the geodesic
// leaves the centre. A geodesic from the centre with unit direction v bends as
// u(s) = s v - s^3 (v^T K v) K v / 6 + ..., so to third order the sheet's point is
// u + (u^T K u) K u / 6: on a cylinder the unrolled sheet, on a sphere the great circle's arc
// s (1 + k^2 s^2 / 6). Distances on the sheet, and with them the strains, do not come out short
// where it bends.
Eigen::Vector2d chordToArc(const Eigen::Vector2d& u, const Eigen::Matrix2d& curvature);


}  // namespace stampscan::registration::detail
