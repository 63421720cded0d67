// The kernels of Eqs. (3)-(5) and the scalar weight of Eq. (16).
#include "stampscan/fitting/kernels.hpp"

#include <gtest/gtest.h>

#include <cmath>

using namespace stampscan::fitting;

TEST(Kernels, GaussianEq3) {
  EXPECT_DOUBLE_EQ(gaussianWeight(0.0, 2.0), 1.0);
  EXPECT_NEAR(gaussianWeight(2.0, 2.0), std::exp(-1.0), 1e-15);
  EXPECT_NEAR(gaussianWeight(1.0, 2.0), std::exp(-0.25), 1e-15);
  EXPECT_NEAR(gaussianWeightSq(4.0, 4.0), std::exp(-1.0), 1e-15);
  EXPECT_LT(gaussianWeight(kGaussianCutoff * 3.0, 3.0), 0.002);
}

TEST(Kernels, CubicEq5IsC1AndCompact) {
  const double h = 1.5;
  EXPECT_DOUBLE_EQ(cubicWeight(0.0, h), 1.0);
  EXPECT_DOUBLE_EQ(cubicWeight(h, h), 0.0);
  EXPECT_DOUBLE_EQ(cubicWeight(2 * h, h), 0.0);
  EXPECT_NEAR(cubicWeight(0.5 * h, h), 0.5, 1e-15);  // 2/8 - 3/4 + 1
  // Zero slope at both ends; monotone in between.
  const double e = 1e-6;
  EXPECT_NEAR((cubicWeight(e, h) - cubicWeight(0, h)) / e, 0.0, 1e-5);
  EXPECT_NEAR((cubicWeight(h, h) - cubicWeight(h - e, h)) / e, 0.0, 1e-5);
  for (double r = 0; r < h; r += 0.01) EXPECT_GE(cubicWeight(r, h), cubicWeight(r + 0.01, h));
  EXPECT_EQ(kernelSupport(KernelType::Cubic, h), h);
}

TEST(Kernels, ScalarWeightEq16IsContinuousAndLocal) {
  const double R = 3.0;
  EXPECT_DOUBLE_EQ(scalarShepardWeight(R + 0.1, R), 0.0);
  EXPECT_NEAR(scalarShepardWeight(R, R), 0.0, 1e-15);
  // The two pieces meet at R/3: (R/3)^-2 = 81/(4R^4)(R/3 - R)^2.
  EXPECT_NEAR(scalarShepardWeight(R / 3 - 1e-9, R), scalarShepardWeight(R / 3 + 1e-9, R), 1e-6);
  EXPECT_NEAR(scalarShepardWeight(0.5, R), 4.0, 1e-12);
  EXPECT_TRUE(std::isinf(scalarShepardWeight(0.0, R)));
}

TEST(Kernels, ParseNames) {
  EXPECT_EQ(parseKernelType("gaussian"), KernelType::Gaussian);
  EXPECT_EQ(parseKernelType("cubic"), KernelType::Cubic);
  EXPECT_THROW(parseKernelType("tricube"), std::invalid_argument);
}
