// The virtual CMM's speed profile against the closed forms: trapezoid and triangle cases,
// continuity, limits respected, distance covered exactly.
#include "ipp_test_support.hpp"
#include "stampscan/sim/trapezoid_move.hpp"

#include <gtest/gtest.h>

#include <stdexcept>

namespace stampscan::sim {
namespace {

void expectConsistent(const TrapezoidMove& m, double max_speed) {
  EXPECT_LE(m.peak_speed, max_speed + 1e-12);
  EXPECT_NEAR(m.distanceAt(m.duration()), m.distance, 1e-12);
  EXPECT_EQ(m.distanceAt(0), 0);
  EXPECT_EQ(m.distanceAt(-1), 0);
  EXPECT_EQ(m.distanceAt(m.duration() + 1), m.distance);
  double previous = 0;
  const int steps = 2000;
  for (int i = 1; i <= steps; ++i) {
    const double t = m.duration() * i / steps;
    const double s = m.distanceAt(t);
    EXPECT_GE(s, previous - 1e-12) << "t=" << t;  // never backwards
    // The mean speed over a step never exceeds the limit, and the speed never jumps by more than
    // the acceleration allows.
    EXPECT_LE((s - previous) / (m.duration() / steps), max_speed * (1 + 1e-9)) << "t=" << t;
    EXPECT_LE(m.speedAt(t), max_speed + 1e-9);
    previous = s;
  }
}

TEST(TrapezoidMove, LongMoveCruisesAtTheLimit) {
  const TrapezoidMove m = planTrapezoid(300, 500, 4000);
  EXPECT_DOUBLE_EQ(m.peak_speed, 500);
  EXPECT_DOUBLE_EQ(m.accel_time, 0.125);
  EXPECT_NEAR(m.duration(), test::trapezoidSeconds(300, 500, 4000), 1e-12);
  EXPECT_NEAR(m.distanceAt(0.125), 31.25, 1e-12);                 // end of the ramp: v^2 / 2a
  EXPECT_NEAR(m.distanceAt(m.duration() - 0.125), 300 - 31.25, 1e-9);
  EXPECT_DOUBLE_EQ(m.speedAt(0.3), 500);
  expectConsistent(m, 500);
}

TEST(TrapezoidMove, ShortMoveIsATriangle) {
  const TrapezoidMove m = planTrapezoid(10, 500, 4000);
  EXPECT_NEAR(m.peak_speed, 200, 1e-12);  // sqrt(d a)
  EXPECT_EQ(m.cruise_time, 0);
  EXPECT_NEAR(m.duration(), test::trapezoidSeconds(10, 500, 4000), 1e-12);
  EXPECT_NEAR(m.distanceAt(m.duration() / 2), 5, 1e-12);
  expectConsistent(m, 500);
}

TEST(TrapezoidMove, ZeroDistanceTakesNoTime) {
  const TrapezoidMove m = planTrapezoid(0, 500, 4000);
  EXPECT_EQ(m.duration(), 0);
  EXPECT_EQ(m.distanceAt(1), 0);
}

TEST(TrapezoidMove, RejectsNonsense) {
  EXPECT_THROW(planTrapezoid(-1, 500, 4000), std::invalid_argument);
  EXPECT_THROW(planTrapezoid(1, 0, 4000), std::invalid_argument);
  EXPECT_THROW(planTrapezoid(1, 500, -1), std::invalid_argument);
  EXPECT_THROW(planTrapezoid(std::nan(""), 500, 4000), std::invalid_argument);
}

}  // namespace
}  // namespace stampscan::sim
