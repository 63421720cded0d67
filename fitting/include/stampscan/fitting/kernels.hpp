// Distance kernels of the WLS fit (paper: "Weighted Least Squares for Visualization of Scanned Point
// Clouds"; equation numbers refer to it).
#pragma once

#include <string>

namespace stampscan::fitting {

enum class KernelType {
  Gaussian,  // Eq. (3): w = exp(-r^2 / h^2), infinite support
  Cubic,     // Eq. (5): w = 2 r^3/h^3 - 3 r^2/h^2 + 1 for r < h, else 0
};

// Eq. (3) with r from Eq. (4) (or the data-to-data distance of Eq. (11), which has the same form, Eq. (10)).
double gaussianWeight(double r, double h);
// Same, from the squared distance (saves a square root in hot loops).
inline double gaussianWeightSq(double r_sq, double h_sq);
// Eq. (5): compactly supported cubic, C1 at r = h.
double cubicWeight(double r, double h);
double kernelWeight(KernelType type, double r, double h);

// Beyond this multiple of h a Gaussian weight is below exp(-6.25) ~ 0.2 % and is cut off, so that a
// neighbourhood query can be bounded. (The cubic kernel has support h.)
inline constexpr double kGaussianCutoff = 2.5;
// Support radius of a kernel with bandwidth h.
double kernelSupport(KernelType type, double h);

// Eq. (16): the piecewise, locally supported weight of the scalar interpolant; r^-2 near the point
// (which makes Eq. (15) interpolate), a quadratic that reaches 0 with zero slope at r = R, and 0 beyond.
double scalarShepardWeight(double r, double R);

KernelType parseKernelType(const std::string& name);  // "gaussian" | "cubic"; throws std::invalid_argument
std::string toString(KernelType type);

}  // namespace stampscan::fitting

#include <cmath>
inline double stampscan::fitting::gaussianWeightSq(double r_sq, double h_sq) { return std::exp(-r_sq / h_sq); }
