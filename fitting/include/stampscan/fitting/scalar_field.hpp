// The scalar attribute (thickness strain) carried onto the surface (paper Sec. 5).
#pragma once

#include "stampscan/fitting/cloud.hpp"

#include <optional>
#include <string>
#include <vector>

namespace stampscan::fitting {

enum class ScalarFieldType {
  // The paper's map, Eqs. (15)-(16): Shepard's interpolant with the piecewise, locally supported
  // weight of Eq. (16). It interpolates the data, so it reproduces their noise and oscillates
  // between samples (the paper's Fig. 8 and Fig. 9 show this).
  Shepard,
  // Default: the value at P* of a linear field c0 + g.t fitted by weighted least squares in the
  // tangent plane with the same weights as the surface - the weighted combination of local
  // hyperplanes of Eq. (17), made smooth by fitting it rather than interpolating.
  Smooth,
};

ScalarFieldType parseScalarFieldType(const std::string& name);  // "shepard" | "smooth"
std::string toString(ScalarFieldType type);

// One neighbour's contribution: its position, value, and the surface fit's weight for it.
struct ScalarSample {
  Vec3 position;
  double value;
  double weight;
};

// Eqs. (15)-(16) at x with support radius R. Returns NaN when no sample lies within R.
double shepardScalar(const Vec3& x, const std::vector<ScalarSample>& samples, double R);
// A linear field in the tangent plane through x: value at x and gradient (in the plane).
struct LinearScalar {
  double value;
  Vec3 gradient;
};
// Weighted least-squares fit of c0 + g.t in the plane through x with unit normal n; the weighted
// mean with zero gradient when the samples do not span the plane. Nothing when the weights sum to 0.
std::optional<LinearScalar> fitTangentLinear(const Vec3& x, const Vec3& n, const std::vector<ScalarSample>& samples);
// The value of that fit at x; NaN when the weights sum to zero.
double smoothScalar(const Vec3& x, const Vec3& n, const std::vector<ScalarSample>& samples);

// A polynomial of degree 1 (c0 + c.t) or 2 (and the three quadratic terms) in the tangent plane
// through x with unit normal n, fitted by weighted least squares: the Eq. (17) hyperplane, and a
// quadric where the attribute bends faster than the samples' spacing (a strain band across a die
// radius). The value at x is a weighted sum of the samples' values, sum_i l_i c_i; `amplification`
// is sum_i |l_i|, the fit's gain on the samples' noise (1 for a weighted mean; it grows where x
// lies off the samples that carry weight). `scale` (a bandwidth) conditions the tangent coordinates.
struct LocalPolynomial {
  double value;
  double amplification;
};
// Nothing when the samples do not determine the polynomial (too few, or not spread in both
// tangent directions).
std::optional<LocalPolynomial> fitTangentPolynomial(const Vec3& x, const Vec3& n, const std::vector<ScalarSample>& samples,
                                                    int degree, double scale);

}  // namespace stampscan::fitting
