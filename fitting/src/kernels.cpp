#include "stampscan/fitting/kernels.hpp"

#include <cmath>
#include <limits>
#include <stdexcept>

namespace stampscan::fitting {

double gaussianWeight(double r, double h) { return std::exp(-(r * r) / (h * h)); }  // Eq. (3)

double cubicWeight(double r, double h) {  // Eq. (5)
  if (r >= h) return 0.0;
  const double t = r / h;
  return 2.0 * t * t * t - 3.0 * t * t + 1.0;
}

double kernelWeight(KernelType type, double r, double h) {
  return type == KernelType::Gaussian ? gaussianWeight(r, h) : cubicWeight(r, h);
}

double kernelSupport(KernelType type, double h) { return type == KernelType::Gaussian ? kGaussianCutoff * h : h; }

double scalarShepardWeight(double r, double R) {  // Eq. (16)
  if (r > R) return 0.0;
  if (r > R / 3.0) {
    // 81/(4R^4) r^2 - 81/(2R^3) r + 81/(4R^2) = 81/(4R^4) (r - R)^2: equals (R/3)^-2 at r = R/3.
    const double d = r - R;
    return 81.0 / (4.0 * R * R * R * R) * d * d;
  }
  if (r <= 0.0) return std::numeric_limits<double>::infinity();
  return 1.0 / (r * r);
}

KernelType parseKernelType(const std::string& name) {
  if (name == "gaussian") return KernelType::Gaussian;
  if (name == "cubic") return KernelType::Cubic;
  throw std::invalid_argument("unknown kernel '" + name + "' (expected gaussian or cubic)");
}

std::string toString(KernelType type) { return type == KernelType::Gaussian ? "gaussian" : "cubic"; }

}  // namespace stampscan::fitting
